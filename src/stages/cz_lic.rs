//! Line-integral convolution along Θ, step 1 of CZ06's texture synthesis (§3.2): box weights
//! over an RK2 streamline with a sign-consistent tangent, staying on the hair. See
//! `wgsl/cz_lic.wgsl`; the host is `crate::sketch::texture`.

use super::cz_tex::Domain;
use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "cz_lic",
    wgsl: include_str!("../../wgsl/cz_lic.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: cz_lic_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// RK2 steps each way.
    pub steps: u32,
    /// Step length, px.
    pub h: f32,
}

/// Tangents shorter than this (taps that cancel) end a streamline.
const MIN_LEN: f32 = 1e-3;

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    use crate::gpu::engine::groups;
    [groups(cfg.width, 8), groups(cfg.height, 8), 1]
}

fn norm(t: [f32; 2]) -> f32 {
    (t[0] * t[0] + t[1] * t[1]).sqrt()
}

fn cz_lic_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (flags, tang, src) = (b[1].get::<u32>(), b[2].get::<[f32; 2]>(), b[3].get::<f32>());
    let d = Domain {
        width: cfg.width,
        height: cfg.height,
        flags: &flags,
        tang: &tang,
        src: &src,
    };
    let mut dst = b[4].get_mut::<f32>();
    let w = cfg.width as usize;
    dst[..w * cfg.height as usize]
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                let i = y * w + x;
                if d.flags[i] == 0 {
                    *out = 0.0;
                    continue;
                }
                let p0 = [x as f32 + 0.5, y as f32 + 0.5];
                let (mut sum, mut count) = (d.src[i], 1.0f32);
                for side in 0..2 {
                    let mut p = p0;
                    let mut prev = d.tang[i];
                    if side == 1 {
                        prev = [-prev[0], -prev[1]];
                    }
                    for _ in 0..cfg.steps {
                        let t1 = d.tangent(p, prev);
                        let l1 = norm(t1);
                        if l1 < MIN_LEN {
                            break;
                        }
                        let d1 = [t1[0] / l1, t1[1] / l1];
                        let pm = [p[0] + 0.5 * cfg.h * d1[0], p[1] + 0.5 * cfg.h * d1[1]];
                        if d.pixel(pm).is_none() {
                            break;
                        }
                        let t2 = d.tangent(pm, d1);
                        let l2 = norm(t2);
                        if l2 < MIN_LEN {
                            break;
                        }
                        let d2 = [t2[0] / l2, t2[1] / l2];
                        let pn = [p[0] + cfg.h * d2[0], p[1] + cfg.h * d2[1]];
                        if d.pixel(pn).is_none() {
                            break;
                        }
                        let v = d.value(pn);
                        sum += v[0] / v[1];
                        count += 1.0;
                        p = pn;
                        prev = d2;
                    }
                }
                *out = sum / count;
            }
        });
}
