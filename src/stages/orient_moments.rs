//! Horizontal half of the local linear fit of the double-angle field: Gaussian moments
//! along x of the weight |(dx, dy)| and of the weighted vectors (see `orient_fit`),
//! optionally reweighted by their agreement with a previous fit (the shader says how).

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "orient_moments",
    wgsl: include_str!("../../wgsl/orient_moments.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: orient_moments_cpu,
};

/// Outputs per invocation along the row; the shader's constant.
pub const OUT_PER_INV: u32 = 4;
/// Zeros on each side of a weight segment (at least `OUT_PER_INV` - 1).
pub const PAD: usize = 4;
/// Planes written: Σ g w, Σ g u w, Σ g u² w, Σ g dx, Σ g u dx, Σ g dy, Σ g u dy.
pub const PLANES: usize = 7;

#[derive(Clone, Copy, Debug, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub radius: u32,
    pub seg_len: u32,
    /// 1: divide each weight by 1 + (Δ/delta)², Δ its angle to the guide θ.
    pub robust: u32,
    /// Radians of θ.
    pub delta: f32,
    /// Each sample's weight w is first raised to this power (its vector scaled by w^(power-1)):
    /// 1 leaves it, below 1 flattens the weights so a few very strong lines lose their say.
    pub power: f32,
    pub _pad1: u32,
}

impl Default for Config {
    /// Zero sizes, not robust, weights as given (power 1).
    fn default() -> Self {
        Config {
            width: 0,
            height: 0,
            radius: 0,
            seg_len: 0,
            robust: 0,
            delta: 0.0,
            power: 1.0,
            _pad1: 0,
        }
    }
}

/// A sample's double-angle vector after the weight's power and the robust reweighting
/// (unchanged when both are off).
fn reweight(cfg: &Config, vx: f32, vy: f32, guide: f32) -> (f32, f32) {
    let mut w = (vx * vx + vy * vy).sqrt();
    let (mut vx, mut vy) = (vx, vy);
    if cfg.power != 1.0 && w > 0.0 {
        let k = w.powf(cfg.power - 1.0);
        (vx, vy) = (vx * k, vy * k);
        w = (vx * vx + vy * vy).sqrt();
    }
    if cfg.robust != 1 || w <= 0.0 {
        return (vx, vy);
    }
    let c = ((vx * (2.0 * guide).cos() + vy * (2.0 * guide).sin()) / w).clamp(-1.0, 1.0);
    let d = 0.5 * c.acos() / cfg.delta;
    let k = 1.0 / (1.0 + d * d);
    (vx * k, vy * k)
}

/// The taps g, g·u, g·u² (u = t / sigma, g the normalised Gaussian, radius ceil(3 sigma)),
/// each padded with [`PAD`] zeros both sides: (radius, segment length, weights).
pub fn fit_weights(sigma: f32) -> (u32, u32, Vec<f32>) {
    let radius = (3.0 * sigma).ceil().max(1.0) as u32;
    let r = radius as i32;
    let g: Vec<f64> = (-r..=r)
        .map(|t| (-0.5 * (t as f64 / sigma as f64).powi(2)).exp())
        .collect();
    let sum: f64 = g.iter().sum();
    let seg = g.len() + 2 * PAD;
    let mut w = vec![0.0f32; 3 * seg];
    for (k, gk) in g.iter().enumerate() {
        let u = (k as f64 - r as f64) / sigma as f64;
        for p in 0..3 {
            w[p * seg + PAD + k] = (gk / sum * u.powi(p as i32)) as f32;
        }
    }
    (radius, seg as u32, w)
}

/// The three unpadded tap segments (g, g·u, g·u²) of [`fit_weights`]' buffer.
pub fn taps(weights: &[f32], radius: u32, seg_len: u32) -> [&[f32]; 3] {
    let (taps, l) = (2 * radius as usize + 1, seg_len as usize);
    std::array::from_fn(|p| &weights[p * l + PAD..p * l + PAD + taps])
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [
        crate::gpu::engine::groups(cfg.width.div_ceil(OUT_PER_INV), 8),
        crate::gpu::engine::groups(cfg.height, 8),
        1,
    ]
}

fn orient_moments_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    // Plain slices: the RefCell guards are not Sync, the data is.
    let (weights, dx, dy, guide) = (
        b[1].get::<f32>(),
        b[2].get::<f32>(),
        b[3].get::<f32>(),
        b[4].get::<f32>(),
    );
    let (weights, dx, dy, guide): (&[f32], &[f32], &[f32], &[f32]) = (&weights, &dx, &dy, &guide);
    let mut out = b[5].get_mut::<f32>();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    let n = w * h;
    let r = cfg.radius as i64;
    let [g0, g1, g2] = taps(weights, cfg.radius, cfg.seg_len);
    // Row-major planes, computed row by row and scattered: the planes are n apart, so a
    // row of output touches seven disjoint slices. Each sample is reweighted once per row
    // (the shader does it once per load), not once per tap.
    let rows: Vec<Vec<[f32; PLANES]>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let row = y * w..(y + 1) * w;
            let v: Vec<(f32, f32, f32)> = row
                .map(|i| {
                    let g = if cfg.robust == 1 { guide[i] } else { 0.0 };
                    let (vx, vy) = reweight(&cfg, dx[i], dy[i], g);
                    (vx, vy, (vx * vx + vy * vy).sqrt())
                })
                .collect();
            (0..w)
                .map(|x| {
                    let mut s = [0.0f32; PLANES];
                    for k in 0..g0.len() {
                        let xx = x as i64 + k as i64 - r;
                        if xx < 0 || xx >= w as i64 {
                            continue;
                        }
                        let (vx, vy, m) = v[xx as usize];
                        s[0] += g0[k] * m;
                        s[1] += g1[k] * m;
                        s[2] += g2[k] * m;
                        s[3] += g0[k] * vx;
                        s[4] += g1[k] * vx;
                        s[5] += g0[k] * vy;
                        s[6] += g1[k] * vy;
                    }
                    s
                })
                .collect()
        })
        .collect();
    for (y, row) in rows.iter().enumerate() {
        for (x, s) in row.iter().enumerate() {
            for (q, v) in s.iter().enumerate() {
                out[q * n + y * w + x] = *v;
            }
        }
    }
}
