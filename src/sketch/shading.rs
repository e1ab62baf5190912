//! The low band as shading bases (CZ06 Eq. 1): I_L ≈ μ + Σ_i α_i·G(x − x_i, y − y_i; θ_i,
//! σx_i, σy_i), G an unnormalised oriented Gaussian (peak 1), α signed (highlight or
//! shadow), fitted by matching pursuit.
//!
//! The dictionary is a lattice, so that `.czs` stores the geometry exactly: centres at the
//! centres of 4×4 pixel blocks, θ in 8 steps of π/8, σx and σy from [`SIGMAS`] (4..64 px)
//! with σx ≥ σy and at most 3 steps apart. The pursuit runs at ¼ resolution: the residual's
//! correlation with every shape at every block is one FFT product per shape, the best atom
//! is the largest |⟨r, g⟩|/‖g‖ inside the hair, and after each pick the amplitudes of all
//! picked atoms and μ are refitted by least squares (orthogonal matching pursuit). A last
//! least-squares refit at full resolution sets the amplitudes. K is O(10) and the search a
//! few hundred FFTs of ~100² per pick: CPU.

use super::{Base, Shading};
use rustfft::num_complex::Complex32;
use rustfft::FftPlanner;
use std::f32::consts::PI;

/// Default number of bases K_L.
pub const DEFAULT_BASES: usize = 10;
/// Block size of the pursuit's grid and of the centres' lattice, pixels.
pub const COARSE: u32 = 4;
/// Orientations of the σx axis: k·π/8.
pub const THETAS: u32 = 8;
/// Scales σ, pixels: 4·2^(4k/7), k = 0..7 (4 to 64).
pub const SIGMAS: [f32; 8] = [
    4.0, 5.943_977, 8.832_716, 13.125_366, 19.504_22, 28.983_158, 43.068_806, 64.0,
];
/// Largest step between the σ indices of an atom's two axes (an elongation ≤ 4.4).
pub const MAX_ELONGATION_STEPS: usize = 3;
/// Gaussians are cut off beyond this Mahalanobis radius (exp(−12.5) ≈ 4e-6 of the peak).
const CUTOFF2: f32 = 25.0;

/// The lattice position of block `i` along an axis: its centre in sketch coordinates.
pub fn block_centre(i: u32) -> f32 {
    (COARSE * i) as f32 + 0.5 * COARSE as f32
}

/// Orientation of step `k`.
pub fn theta_of(k: u32) -> f32 {
    k as f32 * (PI / THETAS as f32)
}

impl Base {
    /// G at (px, py) in sketch coordinates, without the amplitude; 0 beyond the cut-off.
    pub fn shape_at(&self, px: f32, py: f32) -> f32 {
        let (s, c) = self.theta.sin_cos();
        let (dx, dy) = (px - self.x, py - self.y);
        let a = (dx * c + dy * s) / self.sx;
        let b = (-dx * s + dy * c) / self.sy;
        let d2 = a * a + b * b;
        if d2 < CUTOFF2 {
            (-0.5 * d2).exp()
        } else {
            0.0
        }
    }

    /// Pixel bounds [x0, x1) × [y0, y1) outside which the base is cut off, within w×h.
    fn bounds(&self, w: u32, h: u32) -> (usize, usize, usize, usize) {
        let r = CUTOFF2.sqrt() * self.sx.max(self.sy) + 1.0;
        let lo = |c: f32| (c - r).floor().max(0.0) as usize;
        let hi = |c: f32, n: u32| ((c + r).ceil().max(0.0) as usize).min(n as usize);
        (lo(self.x), hi(self.x, w), lo(self.y), hi(self.y, h))
    }
}

impl Shading {
    /// I_L = μ + Σ α_i G_i on every pixel of a w×h image (pixel centres at +0.5).
    pub fn render(&self, w: u32, h: u32) -> Vec<f32> {
        let mut out = vec![self.mean; w as usize * h as usize];
        for b in &self.bases {
            let (x0, x1, y0, y1) = b.bounds(w, h);
            for y in y0..y1 {
                for x in x0..x1 {
                    out[y * w as usize + x] += b.amp * b.shape_at(x as f32 + 0.5, y as f32 + 0.5);
                }
            }
        }
        out
    }
}

/// One shape of the dictionary: orientation step and σ indices (σx ≥ σy).
#[derive(Clone, Copy, Debug)]
struct Shape {
    theta: u32,
    sx: usize,
    sy: usize,
}

fn shapes() -> Vec<Shape> {
    let mut out = Vec::new();
    for sx in 0..SIGMAS.len() {
        for sy in sx.saturating_sub(MAX_ELONGATION_STEPS)..=sx {
            // A round atom looks the same at every orientation.
            let thetas = if sx == sy { 1 } else { THETAS };
            for theta in 0..thetas {
                out.push(Shape { theta, sx, sy });
            }
        }
    }
    out
}

/// 2-D FFT in place on a row-major p×q (width p) complex array.
struct Fft2 {
    p: usize,
    q: usize,
    row: std::sync::Arc<dyn rustfft::Fft<f32>>,
    col: std::sync::Arc<dyn rustfft::Fft<f32>>,
    irow: std::sync::Arc<dyn rustfft::Fft<f32>>,
    icol: std::sync::Arc<dyn rustfft::Fft<f32>>,
}

impl Fft2 {
    fn new(p: usize, q: usize) -> Self {
        let mut pl = FftPlanner::new();
        Fft2 {
            p,
            q,
            row: pl.plan_fft_forward(p),
            col: pl.plan_fft_forward(q),
            irow: pl.plan_fft_inverse(p),
            icol: pl.plan_fft_inverse(q),
        }
    }

    fn run(&self, data: &mut [Complex32], inverse: bool) {
        let (row, col) = if inverse {
            (&self.irow, &self.icol)
        } else {
            (&self.row, &self.col)
        };
        row.process(data);
        let mut buf = vec![Complex32::default(); self.q];
        for x in 0..self.p {
            for y in 0..self.q {
                buf[y] = data[y * self.p + x];
            }
            col.process(&mut buf);
            for y in 0..self.q {
                data[y * self.p + x] = buf[y];
            }
        }
        if inverse {
            let s = 1.0 / (self.p * self.q) as f32;
            data.iter_mut().for_each(|v| *v *= s);
        }
    }
}

/// The base of `shape` centred on block (i, j), amplitude `amp`.
fn base_of(shape: Shape, i: u32, j: u32, amp: f32) -> Base {
    Base {
        x: block_centre(i),
        y: block_centre(j),
        theta: theta_of(shape.theta),
        sx: SIGMAS[shape.sx],
        sy: SIGMAS[shape.sy],
        amp,
    }
}

/// Solves the symmetric positive (semi)definite system `a x = b` (n×n, row-major) by
/// Cholesky with a small ridge relative to the diagonal, so nearly collinear atoms get
/// bounded amplitudes.
fn solve_spd(a: &[f64], b: &[f64], n: usize) -> Vec<f64> {
    let mut l = vec![0f64; n * n];
    let ridge = 1e-9 * (0..n).map(|i| a[i * n + i]).fold(0.0, f64::max).max(1e-30);
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[i * n + j] + if i == j { ridge } else { 0.0 };
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            l[i * n + j] = if i == j {
                s.max(1e-30).sqrt()
            } else {
                s / l[j * n + j]
            };
        }
    }
    let mut y = vec![0f64; n];
    for i in 0..n {
        let s: f64 = (0..i).map(|k| l[i * n + k] * y[k]).sum();
        y[i] = (b[i] - s) / l[i * n + i];
    }
    let mut x = vec![0f64; n];
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|k| l[k * n + i] * x[k]).sum();
        x[i] = (y[i] - s) / l[i * n + i];
    }
    x
}

/// Weighted least squares of `target` on a constant plus `cols` (each over the same
/// samples, weights `wt`): returns [μ, α_1, ..].
fn least_squares(target: &[f32], wt: &[f32], cols: &[Vec<f32>]) -> Vec<f64> {
    let n = cols.len() + 1;
    let mut a = vec![0f64; n * n];
    let mut b = vec![0f64; n];
    let mut row = vec![0f64; n];
    for s in 0..target.len() {
        let w = wt[s] as f64;
        if w == 0.0 {
            continue;
        }
        row[0] = 1.0;
        for (c, col) in cols.iter().enumerate() {
            row[c + 1] = col[s] as f64;
        }
        for i in 0..n {
            if row[i] == 0.0 {
                continue;
            }
            b[i] += w * row[i] * target[s] as f64;
            for j in 0..=i {
                a[i * n + j] += w * row[i] * row[j];
            }
        }
    }
    for i in 0..n {
        for j in 0..i {
            a[j * n + i] = a[i * n + j];
        }
    }
    solve_spd(&a, &b, n)
}

/// Fits μ and `k` bases to the low band `low` (w×h, L*) inside `hair` by matching pursuit
/// (see the module docs). Bases are picked greedily, so the first k of a fit with more
/// bases are the bases of this one; the amplitudes are then refitted by least squares over
/// the hair at full resolution. No hair gives μ = 0 and no bases.
pub fn fit(low: &[f32], hair: &[bool], w: u32, h: u32, k: usize) -> Shading {
    let n = w as usize * h as usize;
    assert_eq!(low.len(), n, "low band size");
    assert_eq!(hair.len(), n, "hair mask size");
    let count = hair.iter().filter(|&&m| m).count();
    if count == 0 {
        return Shading::default();
    }
    let mean = (0..n)
        .filter(|&i| hair[i])
        .map(|i| low[i] as f64)
        .sum::<f64>()
        / count as f64;
    if k == 0 {
        return Shading {
            mean: mean as f32,
            bases: Vec::new(),
        };
    }

    // The ¼-resolution grid: per block, the hair pixel count (the weight) and the mean.
    let (wc, hc) = (w.div_ceil(COARSE) as usize, h.div_ceil(COARSE) as usize);
    let mut wt = vec![0f32; wc * hc];
    let mut target = vec![0f32; wc * hc];
    for y in 0..h as usize {
        for x in 0..w as usize {
            let i = y * w as usize + x;
            if hair[i] {
                let c = (y / COARSE as usize) * wc + x / COARSE as usize;
                wt[c] += 1.0;
                target[c] += low[i];
            }
        }
    }
    for c in 0..wc * hc {
        if wt[c] > 0.0 {
            target[c] /= wt[c];
        }
    }

    // Padding for linear (not circular) correlation with the widest kernel.
    let shapes = shapes();
    let rmax = (CUTOFF2.sqrt() * SIGMAS[SIGMAS.len() - 1] / COARSE as f32).ceil() as usize;
    let (p, q) = (wc + rmax, hc + rmax);
    let fft = Fft2::new(p, q);
    let kernel = |s: Shape, square: bool| -> Vec<Complex32> {
        let b = base_of(s, 0, 0, 1.0);
        let mut g = vec![Complex32::default(); p * q];
        let r = rmax as i64;
        for dy in -r..=r {
            for dx in -r..=r {
                let v = b.shape_at(
                    b.x + (dx * COARSE as i64) as f32,
                    b.y + (dy * COARSE as i64) as f32,
                );
                if v != 0.0 {
                    let (x, y) = (dx.rem_euclid(p as i64), dy.rem_euclid(q as i64));
                    g[y as usize * p + x as usize].re += if square { v * v } else { v };
                }
            }
        }
        fft.run(&mut g, false);
        g
    };
    let embed = |v: &[f32]| -> Vec<Complex32> {
        let mut a = vec![Complex32::default(); p * q];
        for y in 0..hc {
            for x in 0..wc {
                a[y * p + x].re = v[y * wc + x];
            }
        }
        fft.run(&mut a, false);
        a
    };
    // G is point-symmetric, so correlation with it is convolution: IFFT(F(r)·F(g)).
    let conv = |f: &[Complex32], g: &[Complex32]| -> Vec<f32> {
        let mut c: Vec<Complex32> = f.iter().zip(g).map(|(a, b)| a * b).collect();
        fft.run(&mut c, true);
        let mut out = vec![0f32; wc * hc];
        for y in 0..hc {
            for x in 0..wc {
                out[y * wc + x] = c[y * p + x].re;
            }
        }
        out
    };
    let fw = embed(&wt);
    let kernels: Vec<Vec<Complex32>> = shapes.iter().map(|&s| kernel(s, false)).collect();
    // ‖g⊥‖² over the hair for an atom at each block, g⊥ = g less its mean over the hair:
    // the residual never has a mean (μ is refitted with the amplitudes), so the constant
    // part of an atom explains nothing and must not raise its score.
    let total: f32 = wt.iter().sum();
    let norms: Vec<Vec<f32>> = shapes
        .iter()
        .enumerate()
        .map(|(si, &s)| {
            let sums = conv(&fw, &kernels[si]);
            let mut nn = conv(&fw, &kernel(s, true));
            for (v, s) in nn.iter_mut().zip(&sums) {
                // An atom nearly constant over the hair is nearly the mean: its
                // remainder is round-off, so it is left out (norm 0).
                let proj = *v - s * s / total;
                *v = if proj > 1e-3 * *v { proj } else { 0.0 };
            }
            nn
        })
        .collect();

    let atom_values = |s: Shape, i: u32, j: u32| -> Vec<f32> {
        let b = base_of(s, i, j, 1.0);
        let mut v = vec![0f32; wc * hc];
        for y in 0..hc {
            for x in 0..wc {
                v[y * wc + x] = b.shape_at(block_centre(x as u32), block_centre(y as u32));
            }
        }
        v
    };

    let mut picked: Vec<(Shape, u32, u32)> = Vec::new();
    let mut cols: Vec<Vec<f32>> = Vec::new();
    let mut resid: Vec<f32> = target.iter().map(|t| t - mean as f32).collect();
    for _ in 0..k {
        let fr = embed(
            &resid
                .iter()
                .zip(&wt)
                .map(|(r, w)| r * w)
                .collect::<Vec<f32>>(),
        );
        let mut best: Option<(f32, Shape, u32, u32)> = None;
        for (si, &s) in shapes.iter().enumerate() {
            let corr = conv(&fr, &kernels[si]);
            for c in 0..wc * hc {
                let nn = norms[si][c];
                // Centres on hair blocks only.
                if wt[c] == 0.0 || nn <= 0.0 {
                    continue;
                }
                let score = corr[c].abs() / nn.sqrt();
                let (i, j) = ((c % wc) as u32, (c / wc) as u32);
                if best.is_none_or(|b| score > b.0)
                    && !picked.iter().any(|&(ps, pi, pj)| {
                        (ps.theta, ps.sx, ps.sy, pi, pj) == (s.theta, s.sx, s.sy, i, j)
                    })
                {
                    best = Some((score, s, i, j));
                }
            }
        }
        let Some((_, s, i, j)) = best else { break };
        picked.push((s, i, j));
        cols.push(atom_values(s, i, j));
        // Orthogonal pursuit: refit μ and every amplitude, then the residual.
        let sol = least_squares(&target, &wt, &cols);
        for c in 0..wc * hc {
            let mut m = sol[0] as f32;
            for (a, col) in sol[1..].iter().zip(&cols) {
                m += *a as f32 * col[c];
            }
            resid[c] = target[c] - m;
        }
    }

    // Final amplitudes at full resolution over the hair pixels.
    let mut bases: Vec<Base> = picked
        .iter()
        .map(|&(s, i, j)| base_of(s, i, j, 0.0))
        .collect();
    let idx: Vec<usize> = (0..n).filter(|&i| hair[i]).collect();
    let tgt: Vec<f32> = idx.iter().map(|&i| low[i]).collect();
    let ones = vec![1f32; idx.len()];
    let full_cols: Vec<Vec<f32>> = bases
        .iter()
        .map(|b| {
            idx.iter()
                .map(|&i| {
                    let (x, y) = (i % w as usize, i / w as usize);
                    b.shape_at(x as f32 + 0.5, y as f32 + 0.5)
                })
                .collect()
        })
        .collect();
    let sol = least_squares(&tgt, &ones, &full_cols);
    for (b, a) in bases.iter_mut().zip(&sol[1..]) {
        b.amp = *a as f32;
    }
    Shading {
        mean: sol[0] as f32,
        bases,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rms_in(a: &[f32], b: &[f32], m: &[bool]) -> f64 {
        let (mut s, mut c) = (0f64, 0usize);
        for i in 0..a.len() {
            if m[i] {
                s += ((a[i] - b[i]) as f64).powi(2);
                c += 1;
            }
        }
        (s / c as f64).sqrt()
    }

    #[test]
    fn recovers_lattice_bases() {
        // Two bases on the lattice, one a shadow: the pursuit finds them and the refit gives
        // their amplitudes.
        let (w, h) = (96u32, 80u32);
        let truth = Shading {
            mean: 40.0,
            bases: vec![
                base_of(
                    Shape {
                        theta: 2,
                        sx: 4,
                        sy: 2,
                    },
                    8,
                    9,
                    20.0,
                ),
                base_of(
                    Shape {
                        theta: 0,
                        sx: 1,
                        sy: 1,
                    },
                    17,
                    6,
                    -12.0,
                ),
            ],
        };
        let low = truth.render(w, h);
        let hair: Vec<bool> = (0..w * h).map(|i| i % w > 4).collect();
        let got = fit(&low, &hair, w, h, 2);
        assert_eq!(got.bases.len(), 2);
        let err = rms_in(&got.render(w, h), &low, &hair);
        assert!(err < 0.05, "rms {err}: {got:?}");
        for t in &truth.bases {
            assert!(
                got.bases
                    .iter()
                    .any(|b| (b.x, b.y, b.sx, b.sy) == (t.x, t.y, t.sx, t.sy)
                        && (b.amp - t.amp).abs() < 0.05),
                "{t:?} not in {got:?}"
            );
        }
    }

    #[test]
    fn more_bases_fit_no_worse() {
        let (w, h) = (64u32, 48u32);
        let low: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                50.0 + 10.0 * (x / 9.0).sin() * (y / 13.0).cos() + 0.1 * x
            })
            .collect();
        let hair: Vec<bool> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32 - 30.0, (i / w) as f32 - 24.0);
                x * x + y * y < 22.0 * 22.0
            })
            .collect();
        let mut last = f64::INFINITY;
        for k in [0, 1, 3, 6] {
            let s = fit(&low, &hair, w, h, k);
            assert_eq!(s.bases.len(), k);
            let e = rms_in(&s.render(w, h), &low, &hair);
            assert!(e <= last + 1e-6, "k {k}: {e} > {last}");
            last = e;
        }
    }
}
