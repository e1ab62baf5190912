//! Hair segmentation from strokes (C13 §2.1 uses Paint Selection; this is its GrabCut core):
//! colour GMMs for hair (pixels under the direction strokes) and background (background
//! strokes, else the image border), an edge-aware graph cut on the 8-connected pixel grid,
//! re-estimated a few rounds, then holes filled and islands away from the strokes dropped.
//! Graph cuts are sequential, so this stage stays on the CPU.

use crate::annot::{StrokeKind, Strokes};
use crate::error::{Error, Result};
use crate::maxflow::Graph;
use image::{GrayImage, RgbImage};

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SegmentParams {
    /// Pixels within this distance of a stroke are taken as sure (px).
    pub brush_radius: f32,
    /// Image border width used as background samples without background strokes (px).
    pub border: u32,
    /// Gaussians per colour model.
    pub components: usize,
    /// Rounds of graph cut and model re-estimation.
    pub iterations: usize,
    /// Weight of the edge-aware smoothness term (GrabCut's gamma).
    pub smoothness: f32,
    /// Holes smaller than this share of the hair area are filled.
    pub max_hole_share: f32,
    /// Weight of the uniform "any other colour" part of the background model.
    pub outlier: f64,
    /// Scale of the texture feature against the colour channels.
    pub texture_weight: f64,
}

impl Default for SegmentParams {
    fn default() -> Self {
        SegmentParams {
            brush_radius: 4.0,
            border: 3,
            components: 5,
            iterations: 3,
            smoothness: 50.0,
            max_hole_share: 0.02,
            outlier: 0.05,
            texture_weight: 4.0,
        }
    }
}

/// Features per pixel: R, G, B in [0, 1] and a texture energy. Colour alone cannot tell
/// light strands from skin of the same tone; hair is textured, skin is smooth.
const D: usize = 4;
type Feat = [f64; D];

/// A Gaussian mixture over the features (full covariance).
struct Gmm {
    weight: Vec<f64>,
    mean: Vec<Feat>,
    /// Inverse covariance and log normaliser per component.
    inv: Vec<[Feat; D]>,
    log_norm: Vec<f64>,
}

/// Inverse and determinant by Gauss-Jordan elimination with partial pivoting.
fn inverse(m: &[Feat; D]) -> ([Feat; D], f64) {
    let mut a = *m;
    let mut r = [[0.0; D]; D];
    for (i, row) in r.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    let mut det = 1.0;
    for c in 0..D {
        let piv = (c..D)
            .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
            .unwrap();
        if piv != c {
            a.swap(piv, c);
            r.swap(piv, c);
            det = -det;
        }
        let d = a[c][c];
        det *= d;
        for k in 0..D {
            a[c][k] /= d;
            r[c][k] /= d;
        }
        for row in 0..D {
            if row != c {
                let f = a[row][c];
                for k in 0..D {
                    a[row][k] -= f * a[c][k];
                    r[row][k] -= f * r[c][k];
                }
            }
        }
    }
    (r, det)
}

impl Gmm {
    /// Fits `k` components to `samples` (k-means from spread-out seeds, then covariances).
    fn fit(samples: &[Feat], k: usize) -> Gmm {
        let k = k.clamp(1, samples.len().max(1));
        // Farthest-point seeds: deterministic and spread over the colours present.
        let mut means = vec![samples[0]];
        let d2 = |a: &Feat, b: &Feat| (0..D).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>();
        while means.len() < k {
            let far = samples
                .iter()
                .max_by(|a, b| {
                    let da = means.iter().map(|m| d2(a, m)).fold(f64::MAX, f64::min);
                    let db = means.iter().map(|m| d2(b, m)).fold(f64::MAX, f64::min);
                    da.total_cmp(&db)
                })
                .copied()
                .unwrap();
            means.push(far);
        }
        let mut label = vec![0usize; samples.len()];
        for _ in 0..8 {
            for (s, l) in samples.iter().zip(label.iter_mut()) {
                *l = (0..k)
                    .min_by(|&a, &b| d2(s, &means[a]).total_cmp(&d2(s, &means[b])))
                    .unwrap();
            }
            let mut sum = vec![[0.0; D]; k];
            let mut n = vec![0usize; k];
            for (s, &l) in samples.iter().zip(&label) {
                for c in 0..D {
                    sum[l][c] += s[c];
                }
                n[l] += 1;
            }
            for j in 0..k {
                if n[j] > 0 {
                    for c in 0..D {
                        means[j][c] = sum[j][c] / n[j] as f64;
                    }
                }
            }
        }
        let mut g = Gmm {
            weight: Vec::new(),
            mean: Vec::new(),
            inv: Vec::new(),
            log_norm: Vec::new(),
        };
        for (j, mean) in means.iter().enumerate() {
            let members: Vec<&Feat> = samples
                .iter()
                .zip(&label)
                .filter(|(_, &l)| l == j)
                .map(|(s, _)| s)
                .collect();
            if members.is_empty() {
                continue;
            }
            let mut cov = [[0.0; D]; D];
            for s in &members {
                for a in 0..D {
                    for b in 0..D {
                        cov[a][b] += (s[a] - mean[a]) * (s[b] - mean[b]);
                    }
                }
            }
            for (a, row) in cov.iter_mut().enumerate() {
                for v in row.iter_mut() {
                    *v /= members.len() as f64;
                }
                // Regularise: 8-bit colours never vary by less than a level.
                row[a] += 1e-4;
            }
            let (inv, det) = inverse(&cov);
            g.weight.push(members.len() as f64 / samples.len() as f64);
            g.mean.push(*mean);
            g.inv.push(inv);
            g.log_norm
                .push(-0.5 * (det.max(1e-30).ln() + D as f64 * (2.0 * std::f64::consts::PI).ln()));
        }
        g
    }

    /// −log p(x).
    fn cost(&self, x: &Feat) -> f64 {
        -(self.density(x).max(1e-300)).ln()
    }

    fn density(&self, x: &Feat) -> f64 {
        let mut p = 0.0;
        for j in 0..self.weight.len() {
            let mut d = [0.0; D];
            for c in 0..D {
                d[c] = x[c] - self.mean[j][c];
            }
            let mut q = 0.0;
            for a in 0..D {
                for b in 0..D {
                    q += d[a] * self.inv[j][a][b] * d[b];
                }
            }
            p += self.weight[j] * (self.log_norm[j] - 0.5 * q).exp();
        }
        p
    }
}

fn box_blur(v: &[f64], w: usize, h: usize, r: usize) -> Vec<f64> {
    let mut t = vec![0.0; v.len()];
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (x.saturating_sub(r), (x + r).min(w - 1));
            t[y * w + x] = v[y * w + a..=y * w + b].iter().sum::<f64>() / (b - a + 1) as f64;
        }
    }
    let mut o = vec![0.0; v.len()];
    for y in 0..h {
        let (a, b) = (y.saturating_sub(r), (y + r).min(h - 1));
        for x in 0..w {
            o[y * w + x] = (a..=b).map(|yy| t[yy * w + x]).sum::<f64>() / (b - a + 1) as f64;
        }
    }
    o
}

/// RGB in [0, 1] plus the local RMS of the luma's fine detail (luma minus a 3x3 mean,
/// squared, averaged over 7x7), times `texture_weight`.
fn features(image: &RgbImage, texture_weight: f64) -> Vec<Feat> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let luma: Vec<f64> = image
        .pixels()
        .map(|q| (0.2126 * q[0] as f64 + 0.7152 * q[1] as f64 + 0.0722 * q[2] as f64) / 255.0)
        .collect();
    let mean = box_blur(&luma, w, h, 1);
    let hp: Vec<f64> = luma
        .iter()
        .zip(&mean)
        .map(|(a, b)| (a - b) * (a - b))
        .collect();
    let energy = box_blur(&hp, w, h, 3);
    image
        .pixels()
        .zip(&energy)
        .map(|(q, e)| {
            [
                q[0] as f64 / 255.0,
                q[1] as f64 / 255.0,
                q[2] as f64 / 255.0,
                texture_weight * e.sqrt(),
            ]
        })
        .collect()
}

fn disc(mark: &mut [bool], w: usize, h: usize, p: [f32; 2], r: f32) {
    let ri = r.ceil() as i64;
    let (cx, cy) = (p[0].floor() as i64, p[1].floor() as i64);
    for y in cy - ri..=cy + ri {
        for x in cx - ri..=cx + ri {
            if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
                let (dx, dy) = (x as f32 + 0.5 - p[0], y as f32 + 0.5 - p[1]);
                if dx * dx + dy * dy <= r * r {
                    mark[y as usize * w + x as usize] = true;
                }
            }
        }
    }
}

/// Marks pixels under the polylines of the given kind, `r` px around them.
fn under_strokes(strokes: &Strokes, kind: StrokeKind, w: usize, h: usize, r: f32) -> Vec<bool> {
    let mut mark = vec![false; w * h];
    for s in strokes.strokes.iter().filter(|s| s.kind == kind) {
        for seg in s.points.windows(2) {
            let (a, b) = (seg[0], seg[1]);
            let n = ((b[0] - a[0]).hypot(b[1] - a[1]) * 2.0).ceil().max(1.0) as usize;
            for k in 0..=n {
                let f = k as f32 / n as f32;
                disc(
                    &mut mark,
                    w,
                    h,
                    [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])],
                    r,
                );
            }
        }
    }
    mark
}

/// Connected components (4-connected) of `on`; returns labels (0 = off) and sizes.
fn components(on: &[bool], w: usize, h: usize) -> (Vec<u32>, Vec<usize>) {
    let mut label = vec![0u32; w * h];
    let mut sizes = vec![0usize];
    let mut stack = Vec::new();
    for start in 0..w * h {
        if !on[start] || label[start] != 0 {
            continue;
        }
        let id = sizes.len() as u32;
        sizes.push(0);
        label[start] = id;
        stack.push(start);
        while let Some(i) = stack.pop() {
            sizes[id as usize] += 1;
            let (x, y) = (i % w, i / w);
            let mut visit = |j: usize| {
                if on[j] && label[j] == 0 {
                    label[j] = id;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
            }
        }
    }
    (label, sizes)
}

/// Segments the hair: 255 on hair, 0 elsewhere.
pub fn segment(image: &RgbImage, strokes: &Strokes, p: &SegmentParams) -> Result<GrayImage> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let px = features(image, p.texture_weight);
    let fg_seed = under_strokes(strokes, StrokeKind::Direction, w, h, p.brush_radius);
    if !fg_seed.contains(&true) {
        return Err(Error::Invalid(
            "segmentation needs at least one direction stroke on the image".into(),
        ));
    }
    let mut bg_seed = under_strokes(strokes, StrokeKind::Background, w, h, p.brush_radius);
    if !bg_seed.contains(&true) {
        let b = p.border as usize;
        for y in 0..h {
            for x in 0..w {
                if x < b || y < b || x + b >= w || y + b >= h {
                    bg_seed[y * w + x] = true;
                }
            }
        }
    }
    for i in 0..w * h {
        // A hair stroke wins over the border where both claim a pixel.
        if fg_seed[i] {
            bg_seed[i] = false;
        }
    }
    // GrabCut's beta: the inverse of twice the mean squared neighbour difference.
    let nbrs: [(i64, i64, f64); 4] = [
        (1, 0, 1.0),
        (0, 1, 1.0),
        (1, 1, 0.5f64.sqrt()),
        (-1, 1, 0.5f64.sqrt()),
    ];
    let (mut sum, mut cnt) = (0.0, 0usize);
    for y in 0..h {
        for x in 0..w {
            for &(dx, dy, _) in &nbrs {
                let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                if xx >= 0 && yy >= 0 && (xx as usize) < w && (yy as usize) < h {
                    let (a, b) = (px[y * w + x], px[yy as usize * w + xx as usize]);
                    sum += (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>();
                    cnt += 1;
                }
            }
        }
    }
    let beta = 1.0 / (2.0 * (sum / cnt.max(1) as f64)).max(1e-12);
    let mut hair: Vec<bool> = fg_seed.clone();
    // As GrabCut starts from "outside the box is background": the first background model
    // takes every pixel away from the strokes, so skin and clothes, which no stroke samples,
    // are in it; the hair in it is outweighed by the sharper hair model from the strokes.
    let near = under_strokes(strokes, StrokeKind::Direction, w, h, 4.0 * p.brush_radius);
    let mut bg_samples: Vec<Feat> = (0..w * h)
        .filter(|&i| bg_seed[i] || !near[i])
        .map(|i| px[i])
        .collect();
    for round in 0..p.iterations.max(1) {
        let fg_samples: Vec<Feat> = (0..w * h).filter(|&i| hair[i]).map(|i| px[i]).collect();
        if round > 0 {
            bg_samples = (0..w * h).filter(|&i| !hair[i]).map(|i| px[i]).collect();
        }
        // Subsample for speed; the models need thousands of samples, not millions.
        let thin = |v: &[Feat]| -> Vec<Feat> {
            let step = (v.len() / 4000).max(1);
            v.iter().step_by(step).copied().collect()
        };
        let fg = Gmm::fit(&thin(&fg_samples), p.components);
        let bg = Gmm::fit(&thin(&bg_samples), p.components);
        let mut g = Graph::new(w * h);
        let hard = 1e9f32;
        for i in 0..w * h {
            if fg_seed[i] {
                g.add_terminal(i, hard, 0.0);
            } else if bg_seed[i] {
                g.add_terminal(i, 0.0, hard);
            } else {
                // Source side = hair: cutting the source link costs the hair likelihood.
                // The background also takes any colour the hair model explains poorly (a
                // uniform outlier term), so skin, which neither the strokes nor the border
                // sample, does not become hair.
                let pb = (1.0 - p.outlier) * bg.density(&px[i]) + p.outlier;
                let cb = -(pb.max(1e-300)).ln();
                g.add_terminal(i, cb as f32, fg.cost(&px[i]) as f32);
            }
        }
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                for &(dx, dy, inv_dist) in &nbrs {
                    let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                    if xx >= 0 && yy >= 0 && (xx as usize) < w && (yy as usize) < h {
                        let j = yy as usize * w + xx as usize;
                        let d2: f64 = (0..3).map(|c| (px[i][c] - px[j][c]).powi(2)).sum();
                        let wgt = (p.smoothness as f64 * inv_dist * (-beta * d2).exp()) as f32;
                        g.add_edge(i, j, wgt, wgt);
                    }
                }
            }
        }
        hair = g.min_cut();
    }
    // Keep the hair regions that touch a direction stroke; fill small holes.
    let (label, _) = components(&hair, w, h);
    let mut keep = vec![false; label.len() + 1];
    for i in 0..w * h {
        if fg_seed[i] {
            keep[label[i] as usize] = true;
        }
    }
    let mut out: Vec<bool> = (0..w * h)
        .map(|i| label[i] != 0 && keep[label[i] as usize])
        .collect();
    let area = out.iter().filter(|&&v| v).count();
    let holes: Vec<bool> = out.iter().map(|&v| !v).collect();
    let (hl, hs) = components(&holes, w, h);
    let mut touches_border = vec![false; hs.len()];
    for y in 0..h {
        for x in 0..w {
            if x == 0 || y == 0 || x + 1 == w || y + 1 == h {
                touches_border[hl[y * w + x] as usize] = true;
            }
        }
    }
    for i in 0..w * h {
        let c = hl[i] as usize;
        if c != 0 && !touches_border[c] && (hs[c] as f32) < p.max_hole_share * area as f32 {
            out[i] = true;
        }
    }
    Ok(GrayImage::from_fn(w as u32, h as u32, |x, y| {
        image::Luma([if out[y as usize * w + x as usize] {
            255
        } else {
            0
        }])
    }))
}
