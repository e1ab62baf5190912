//! Contrast matching across Θ, step 2 of CZ06's texture synthesis (§3.2): mode 0 measures
//! |∇⊥Θ I| (central differences of bilinear samples at ±1 px), mode 2 measures it with the
//! analysis's derivative (the Scharr-smoothed gradient of `sketch::theta::gradients`, the one
//! ρ is defined by), mode 1 scales the band by ρ_s/ρ_cur clamped (both blurred alike). See `wgsl/cz_contrast.wgsl`; the host is `crate::sketch::texture`.

use super::cz_tex::Domain;
use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "cz_contrast",
    wgsl: include_str!("../../wgsl/cz_contrast.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: cz_contrast_cpu,
};

pub const MEASURE: u32 = 0;
pub const GAIN: u32 = 1;
pub const MEASURE_GRADIENT: u32 = 2;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// [`MEASURE`], [`GAIN`] or [`MEASURE_GRADIENT`].
    pub mode: u32,
    pub gain_min: f32,
    pub gain_max: f32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    use crate::gpu::engine::groups;
    [groups(cfg.width, 8), groups(cfg.height, 8), 1]
}

/// |∇⊥Θ src| at pixel i, centre p, across-unit n: central where both sides have domain
/// taps, one-sided with the pixel's own value where one has, 0 where neither has.
pub fn across(d: &Domain, i: usize, p: [f32; 2], n: [f32; 2]) -> f32 {
    let a = d.value([p[0] + n[0], p[1] + n[1]]);
    let b = d.value([p[0] - n[0], p[1] - n[1]]);
    if a[1] > 0.0 && b[1] > 0.0 {
        return (0.5 * (a[0] / a[1] - b[0] / b[1])).abs();
    }
    if a[1] > 0.0 {
        return (a[0] / a[1] - d.src[i]).abs();
    }
    if b[1] > 0.0 {
        return (d.src[i] - b[0] / b[1]).abs();
    }
    0.0
}

/// |∇⊥Θ src| at pixel (x, y) by the analysis's derivative
/// ([`crate::sketch::theta::gradient_at`], taps off the domain replaced by the pixel's own
/// value), projected on n = (−sin Θ, cos Θ).
pub fn across_gradient(d: &Domain, x: usize, y: usize) -> f32 {
    let [sx, sy] =
        crate::sketch::theta::gradient_at(d.src, d.width, d.height, x, y, |j| d.flags[j] != 0);
    let t = d.tang[y * d.width as usize + x];
    (-sx * t[1] + sy * t[0]).abs()
}

fn cz_contrast_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (flags, tang, src) = (b[1].get::<u32>(), b[2].get::<[f32; 2]>(), b[3].get::<f32>());
    let (rho_s, cur_s) = (b[4].get::<f32>(), b[5].get::<f32>());
    let (rho_s, cur_s): (&[f32], &[f32]) = (&rho_s, &cur_s);
    let d = Domain {
        width: cfg.width,
        height: cfg.height,
        flags: &flags,
        tang: &tang,
        src: &src,
    };
    let mut out = b[6].get_mut::<f32>();
    let w = cfg.width as usize;
    out[..w * cfg.height as usize]
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let i = y * w + x;
                if d.flags[i] == 0 {
                    *o = 0.0;
                    continue;
                }
                if cfg.mode == MEASURE {
                    let t = d.tang[i];
                    let n = [-t[1], t[0]];
                    let p = [x as f32 + 0.5, y as f32 + 0.5];
                    *o = across(&d, i, p, n);
                    continue;
                }
                if cfg.mode == MEASURE_GRADIENT {
                    *o = across_gradient(&d, x, y);
                    continue;
                }
                let mut g = cfg.gain_max;
                let cur = cur_s[i];
                if cur > 0.0 {
                    g = (rho_s[i] / cur).clamp(cfg.gain_min, cfg.gain_max);
                }
                *o = d.src[i] * g;
            }
        });
}
