//! Vertical half of the local linear fit of the double-angle field and the per-pixel solve:
//! θ = ½ atan2 of the fit's intercept, NaN off the mask (the shader explains why a fit).

use super::orient_moments::PLANES;
use super::orient_resolve::resolve_theta;
use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "orient_fit",
    wgsl: include_str!("../../wgsl/orient_fit.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::ReadWrite,
    ],
    cpu: orient_fit_cpu,
};

/// Outputs per invocation down the column; the shader's constant.
pub const OUT_PER_INV: u32 = 4;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub radius: u32,
    pub seg_len: u32,
    /// Added to the slope terms' normalised second moments (in sigmas²).
    pub ridge: f32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [
        crate::gpu::engine::groups(cfg.width, 8),
        crate::gpu::engine::groups(cfg.height.div_ceil(OUT_PER_INV), 8),
        1,
    ]
}

/// θ from the twelve window sums (m00 m10 m20 m01 m11 m02, rx0 rx1 rx2, ry0 ry1 ry2), as
/// the shader: 0 for an empty window.
pub fn solve(m: &[f32; 12], ridge: f32) -> f32 {
    if m[0] <= 0.0 {
        return 0.0;
    }
    let a = m[1] / m[0];
    let b = m[3] / m[0];
    let c = m[2] / m[0] + ridge;
    let d = m[4] / m[0];
    let e = m[5] / m[0] + ridge;
    let c0 = c * e - d * d;
    let c1 = d * b - a * e;
    let c2 = a * d - c * b;
    let ax = c0 * m[6] + c1 * m[7] + c2 * m[8];
    let ay = c0 * m[9] + c1 * m[10] + c2 * m[11];
    resolve_theta(ax, ay)
}

fn orient_fit_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (weights, hm, conf, mask) = (
        b[1].get::<f32>(),
        b[2].get::<f32>(),
        b[3].get::<f32>(),
        b[4].get::<u32>(),
    );
    let (weights, hm, conf, mask): (&[f32], &[f32], &[f32], &[u32]) = (&weights, &hm, &conf, &mask);
    let mut theta = b[5].get_mut::<f32>();
    let mut conf_out = b[6].get_mut::<f32>();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    let n = w * h;
    let r = cfg.radius as i64;
    let [g0, g1, g2] = super::orient_moments::taps(weights, cfg.radius, cfg.seg_len);
    theta[..n]
        .par_chunks_mut(w)
        .zip(conf_out[..n].par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (trow, crow))| {
            for x in 0..w {
                let i = y * w + x;
                if mask[i] == 0 {
                    trow[x] = f32::NAN;
                    crow[x] = 0.0;
                    continue;
                }
                let mut m = [0.0f32; 12];
                for k in 0..g0.len() {
                    let yy = y as i64 + k as i64 - r;
                    if yy < 0 || yy >= h as i64 {
                        continue;
                    }
                    let j = yy as usize * w + x;
                    let p: [f32; PLANES] = std::array::from_fn(|q| hm[q * n + j]);
                    let (a, b, c) = (g0[k], g1[k], g2[k]);
                    m[0] += a * p[0];
                    m[1] += a * p[1];
                    m[2] += a * p[2];
                    m[3] += b * p[0];
                    m[4] += b * p[1];
                    m[5] += c * p[0];
                    m[6] += a * p[3];
                    m[7] += a * p[4];
                    m[8] += b * p[3];
                    m[9] += a * p[5];
                    m[10] += a * p[6];
                    m[11] += b * p[5];
                }
                trow[x] = solve(&m, cfg.ridge);
                crow[x] = conf[i];
            }
        });
}
