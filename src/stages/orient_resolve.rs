//! Orientation θ = ½ atan2 of the double-angle field, NaN off the mask.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;
use std::f32::consts::PI;

pub const STAGE: StageDef = StageDef {
    name: "orient_resolve",
    wgsl: include_str!("../../wgsl/orient_resolve.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::ReadWrite,
    ],
    cpu: orient_resolve_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub _pad0: u32,
    pub _pad1: u32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [
        crate::gpu::engine::groups(cfg.width, 8),
        crate::gpu::engine::groups(cfg.height, 8),
        1,
    ]
}

/// θ in [0, π) from a double-angle vector; 0 for the zero vector.
pub fn resolve_theta(dx: f32, dy: f32) -> f32 {
    if dx == 0.0 && dy == 0.0 {
        return 0.0;
    }
    let mut t = 0.5 * dy.atan2(dx);
    if t < 0.0 {
        t += PI;
    }
    if t >= PI {
        t -= PI;
    }
    t
}

fn orient_resolve_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let n = (cfg.width * cfg.height) as usize;
    let (dx, dy, conf, mask) = (
        b[1].get::<f32>(),
        b[2].get::<f32>(),
        b[3].get::<f32>(),
        b[4].get::<u32>(),
    );
    // Plain slices: the RefCell guards are not Sync, the data is.
    let (dx, dy, conf, mask): (&[f32], &[f32], &[f32], &[u32]) = (&dx, &dy, &conf, &mask);
    let mut theta = b[5].get_mut::<f32>();
    let mut conf_out = b[6].get_mut::<f32>();
    theta[..n]
        .par_iter_mut()
        .zip(conf_out[..n].par_iter_mut())
        .enumerate()
        .for_each(|(i, (t, c))| {
            if mask[i] == 0 {
                *t = f32::NAN;
                *c = 0.0;
            } else {
                *t = resolve_theta(dx[i], dy[i]);
                *c = conf[i];
            }
        });
}
