//! Gabor filter bank with argmax orientation and variance confidence (C13 §2.1, Chai 2012).
//!
//! The GPU filters directly (one texel load feeds all orientations); the CPU mirror takes the
//! same bindings and computes the same responses by FFT, which on a CPU is 10-50x cheaper than
//! the 17x17x32 direct bank. The per-pixel reduction is shared code in both: see
//! [`orient_from_responses`], which reads like the end of `wgsl/gabor.wgsl`.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;
use rustfft::num_complex::Complex32;
use rustfft::{Fft, FftPlanner};
use std::f32::consts::PI;
use std::sync::{Arc, Mutex};

pub const STAGE: StageDef = StageDef {
    name: "gabor",
    wgsl: include_str!("../../wgsl/gabor.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::ReadWrite,
        Bind::ReadWrite,
    ],
    cpu: gabor_cpu,
};

/// Orientations the shader's accumulator array holds.
pub const MAX_ORIENT: u32 = 64;
/// Floats in the shader's uniform weight array (64 KiB).
pub const WEIGHT_CAPACITY: usize = 16384;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub half: u32,
    pub n_orient: u32,
    pub min_response: f32,
    pub min_contrast: f32,
    pub final_pass: u32,
    pub _pad2: u32,
}

/// The kernel of C13/DESIGN.md for strand orientation θ: with t = (cos θ, sin θ) along the
/// strand and n = (-sin θ, cos θ) across it, u = d·n, v = d·t,
/// K(d) = exp(-½(u²/σx² + v²/σy²)) cos(2πu/λ). σx runs across the strand, σy along it, so
/// θ_i = πi/N is directly the strand orientation (x right, y down).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Kernel {
    pub sigma_x: f32,
    pub sigma_y: f32,
    pub lambda: f32,
    pub ksize: u32,
    pub n_orient: u32,
}

impl Kernel {
    pub fn half(&self) -> u32 {
        self.ksize / 2
    }

    pub fn n_pairs(&self) -> u32 {
        let k = 2 * self.half() + 1;
        (k * k).div_ceil(2)
    }

    pub fn weight(&self, o: u32, dx: i32, dy: i32) -> f32 {
        let th = PI * o as f32 / self.n_orient as f32;
        let (s, c) = (th.sin() as f64, th.cos() as f64);
        let (dx, dy) = (dx as f64, dy as f64);
        let u = -dx * s + dy * c;
        let v = dx * c + dy * s;
        let sx = self.sigma_x as f64;
        let sy = self.sigma_y as f64;
        let g = (-0.5 * (u * u / (sx * sx) + v * v / (sy * sy))).exp();
        (g * (2.0 * std::f64::consts::PI * u / self.lambda as f64).cos()) as f32
    }

    /// Weights in the shader's layout: `w[j * n_orient + o]` for pair j (centre halved).
    pub fn pair_weights(&self) -> Vec<f32> {
        let (np, no) = (self.n_pairs(), self.n_orient);
        let mut w = vec![0.0; (np * no) as usize];
        for j in 0..np {
            let (dx, dy) = pair_offset(self.half(), j);
            for o in 0..no {
                let k = self.weight(o, dx, dy);
                w[(j * no + o) as usize] = if j == 0 { 0.5 * k } else { k };
            }
        }
        w
    }

    /// The shader's `override` values for this kernel.
    pub fn constants(&self) -> [(&'static str, f64); 3] {
        [
            ("N_ORIENT", self.n_orient as f64),
            ("N_VEC", (self.n_orient / 4) as f64),
            ("N_PAIRS", self.n_pairs() as f64),
        ]
    }

    /// [`Self::pair_weights`] padded to the shader's fixed uniform array.
    pub fn pair_weights_padded(&self) -> Vec<f32> {
        let mut w = self.pair_weights();
        w.resize(WEIGHT_CAPACITY.max(w.len()), 0.0);
        w
    }
}

/// Offset of pair j; mirrors `pair_offset` in the shader.
pub fn pair_offset(half: u32, j: u32) -> (i32, i32) {
    if j == 0 {
        return (0, 0);
    }
    let idx = j - 1;
    if idx < half {
        return (idx as i32 + 1, 0);
    }
    let r = idx - half;
    let w = 2 * half + 1;
    ((r % w) as i32 - half as i32, (r / w) as i32 + 1)
}

/// Pixels one invocation computes along x (`PX` in the shader).
pub const PX: u32 = 2;

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [
        crate::gpu::engine::groups(cfg.width.div_ceil(PX), 8),
        crate::gpu::engine::groups(cfg.height, 8),
        1,
    ]
}

fn ang_dist(a: f32, b: f32) -> f32 {
    let d = (a - b).abs() % PI;
    d.min(PI - d)
}

/// Double-angle vector and confidence from one pixel's raw responses; mirrors the shader.
pub fn orient_from_responses(acc: &[f32], min_response: f32, min_contrast: f32) -> (f32, f32, f32) {
    let n = acc.len();
    let mut best = 0usize;
    let mut rmax = acc[0].max(0.0);
    let mut rmin = rmax;
    for (o, &v) in acc.iter().enumerate().skip(1) {
        let r = v.max(0.0);
        if r > rmax {
            rmax = r;
            best = o;
        }
        rmin = rmin.min(r);
    }
    if rmax <= min_response || rmax - rmin <= min_contrast * rmax {
        return (0.0, 0.0, 0.0);
    }
    let a = acc[(best + n - 1) % n].max(0.0);
    let c = acc[(best + 1) % n].max(0.0);
    let denom = a - 2.0 * rmax + c;
    let delta = if denom < 0.0 {
        (0.5 * (a - c) / denom).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    let step = PI / n as f32;
    let mut theta = (best as f32 + delta) * step;
    theta -= PI * (theta / PI).floor();
    let (mut num, mut den) = (0.0f32, 0.0f32);
    for (o, &v) in acc.iter().enumerate() {
        let d = ang_dist(o as f32 * step, theta);
        let diff = v.max(0.0) - rmax;
        num += d * d * diff * diff;
        den += d * d;
    }
    let conf = (num / den.max(1e-12)).sqrt();
    (conf * (2.0 * theta).cos(), conf * (2.0 * theta).sin(), conf)
}

/// Smallest 2^a 3^b 5^c >= n: sizes rustfft handles with its fastest radices.
pub fn fft_size(n: usize) -> usize {
    let mut m = n.max(1);
    loop {
        let mut k = m;
        for p in [2, 3, 5] {
            while k.is_multiple_of(p) {
                k /= p;
            }
        }
        if k == 1 {
            return m;
        }
        m += 1;
    }
}

fn transpose(src: &[Complex32], rows: usize, cols: usize) -> Vec<Complex32> {
    let mut out = vec![Complex32::new(0.0, 0.0); rows * cols];
    out.par_chunks_mut(rows).enumerate().for_each(|(c, col)| {
        for (r, o) in col.iter_mut().enumerate() {
            *o = src[r * cols + c];
        }
    });
    out
}

fn fft_rows(data: &mut [Complex32], fft: &Arc<dyn Fft<f32>>) {
    let n = fft.len();
    data.par_chunks_mut(n).for_each_init(
        || vec![Complex32::new(0.0, 0.0); fft.get_inplace_scratch_len()],
        |scratch, row| fft.process_with_scratch(row, scratch),
    );
}

/// 2D FFTs of one size; spectra are kept transposed (nx rows of ny) to skip two transposes.
struct Fft2 {
    nx: usize,
    ny: usize,
    fx: Arc<dyn Fft<f32>>,
    fy: Arc<dyn Fft<f32>>,
    ix: Arc<dyn Fft<f32>>,
    iy: Arc<dyn Fft<f32>>,
}

impl Fft2 {
    fn new(nx: usize, ny: usize) -> Self {
        let mut p = FftPlanner::new();
        Fft2 {
            nx,
            ny,
            fx: p.plan_fft_forward(nx),
            fy: p.plan_fft_forward(ny),
            ix: p.plan_fft_inverse(nx),
            iy: p.plan_fft_inverse(ny),
        }
    }

    fn forward(&self, mut img: Vec<Complex32>) -> Vec<Complex32> {
        fft_rows(&mut img, &self.fx);
        let mut t = transpose(&img, self.ny, self.nx);
        fft_rows(&mut t, &self.fy);
        t
    }

    fn inverse(&self, mut spec: Vec<Complex32>) -> Vec<Complex32> {
        fft_rows(&mut spec, &self.iy);
        let mut img = transpose(&spec, self.nx, self.ny);
        fft_rows(&mut img, &self.ix);
        img
    }
}

type SpectraKey = (usize, usize, u32, usize, u64);
type Spectra = Arc<Vec<Vec<Complex32>>>;

/// The last bank's kernel spectra: the refinement passes filter with the same kernels at
/// the same size, so keeping one set halves the FFTs per pass.
static SPECTRA: Mutex<Option<(SpectraKey, Spectra)>> = Mutex::new(None);

/// Spectra of the kernels packed two per complex transform: Ka + i Kb.
fn kernel_spectra(f: &Fft2, weights: &[f32], half: u32, no: usize) -> Spectra {
    let k = 2 * half as usize + 1;
    let np = (k * k).div_ceil(2);
    let used = &weights[..np * no];
    let hash = used.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, w| {
        (h ^ w.to_bits() as u64).wrapping_mul(0x0100_0000_01b3)
    });
    let key = (f.nx, f.ny, half, no, hash);
    if let Some((k0, s)) = SPECTRA.lock().unwrap().as_ref() {
        if *k0 == key {
            return s.clone();
        }
    }
    let (nx, ny) = (f.nx, f.ny);
    let spectra: Vec<Vec<Complex32>> = (0..no.div_ceil(2))
        .map(|pair| {
            let (oa, ob) = (2 * pair, 2 * pair + 1);
            let mut ker = vec![Complex32::new(0.0, 0.0); nx * ny];
            for j in 0..np {
                let (dx, dy) = pair_offset(half, j as u32);
                let scale = if j == 0 { 2.0 } else { 1.0 };
                let wa = scale * used[j * no + oa];
                let wb = if ob < no {
                    scale * used[j * no + ob]
                } else {
                    0.0
                };
                for (sx, sy) in [(dx, dy), (-dx, -dy)] {
                    let x = sx.rem_euclid(nx as i32) as usize;
                    let y = sy.rem_euclid(ny as i32) as usize;
                    ker[y * nx + x] = Complex32::new(wa, wb);
                }
            }
            f.forward(ker)
        })
        .collect();
    let spectra = Arc::new(spectra);
    *SPECTRA.lock().unwrap() = Some((key, spectra.clone()));
    spectra
}

fn gabor_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (weights, src) = (b[1].get::<f32>(), b[2].get::<f32>());
    // Plain slices: the RefCell guards are not Sync, the data is.
    let (weights, src): (&[f32], &[f32]) = (&weights, &src);
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    let half = cfg.half as usize;
    let no = cfg.n_orient as usize;
    // Clamp-to-edge padding by `half` makes circular convolution equal the shader's direct
    // filter on the valid region; the FFT size only needs to avoid wrap-around into it.
    let (pw, ph) = (w + 2 * half, h + 2 * half);
    let f = Fft2::new(fft_size(pw), fft_size(ph));
    let (nx, ny) = (f.nx, f.ny);
    let mut padded = vec![Complex32::new(0.0, 0.0); nx * ny];
    padded
        .par_chunks_mut(nx)
        .take(ph)
        .enumerate()
        .for_each(|(y, row)| {
            let sy = (y as i64 - half as i64).clamp(0, h as i64 - 1) as usize;
            for (x, v) in row.iter_mut().take(pw).enumerate() {
                let sx = (x as i64 - half as i64).clamp(0, w as i64 - 1) as usize;
                *v = Complex32::new(src[sy * w + sx], 0.0);
            }
        });
    let spec = f.forward(padded);
    // Two real kernels per complex transform: conv(P, Ka + i Kb) = conv(P, Ka) + i conv(P, Kb).
    let kspecs = kernel_spectra(&f, weights, cfg.half, no);
    let responses: Vec<Vec<f32>> = (0..no.div_ceil(2))
        .flat_map(|pair| {
            let ob = 2 * pair + 1;
            let kspec = &kspecs[pair];
            let prod: Vec<Complex32> = spec
                .par_iter()
                .zip(kspec.par_iter())
                .map(|(a, b)| a * b)
                .collect();
            let out = f.inverse(prod);
            let norm = 1.0 / (nx * ny) as f32;
            let take = |im: bool| -> Vec<f32> {
                let mut r = vec![0.0f32; w * h];
                r.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                    for (x, v) in row.iter_mut().enumerate() {
                        let c = out[(y + half) * nx + x + half];
                        *v = if im { c.im } else { c.re } * norm;
                    }
                });
                r
            };
            let mut v = vec![take(false)];
            if ob < no {
                v.push(take(true));
            }
            v
        })
        .collect();
    let (mask, first_dx, first_dy) = (b[3].get::<u32>(), b[4].get::<f32>(), b[5].get::<f32>());
    let (mask, first_dx, first_dy): (&[u32], &[f32], &[f32]) = (&mask, &first_dx, &first_dy);
    let mut dxo = b[6].get_mut::<f32>();
    let mut dyo = b[7].get_mut::<f32>();
    let mut co = b[8].get_mut::<f32>();
    dxo[..w * h]
        .par_iter_mut()
        .zip(dyo[..w * h].par_iter_mut())
        .zip(co[..w * h].par_iter_mut())
        .enumerate()
        .for_each_init(
            || vec![0.0f32; no],
            |acc, (i, ((dx, dy), c))| {
                for (o, a) in acc.iter_mut().enumerate() {
                    *a = responses[o][i];
                }
                let (x, y, z) = orient_from_responses(acc, cfg.min_response, cfg.min_contrast);
                if cfg.final_pass != 0 {
                    let keep = match (mask[i] != 0, cfg.final_pass) {
                        (false, _) => 0.0,
                        (true, 2) => (first_dx[i] * first_dx[i] + first_dy[i] * first_dy[i]).sqrt(),
                        (true, _) => z,
                    };
                    *dx = keep * first_dx[i];
                    *dy = keep * first_dy[i];
                } else {
                    *dx = x;
                    *dy = y;
                }
                *c = z;
            },
        );
}
