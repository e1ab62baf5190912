//! Eq. (6) of C13, one invocation per reference-frame pixel. Pairs with
//! `wgsl/warp_compose.wgsl`; the mirror does the same f32 arithmetic in the same order.
//!
//! W*_i(p) = a·W†_i(p) + (1 − a)·[W*_{i−1}(p) + V_i(p + W*_{i−1}(p))]: the feature warp and
//! the previous warp carried one frame further by the flow, averaged (a = ½ in the paper;
//! a = 0 is flow alone, a = 1 features alone, the two baselines the paper's Fig. 3 shows).
//! Where no feature reaches a pixel (W† ≥ [`UNKNOWN`]) the flow alone carries it.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "warp_compose",
    wgsl: include_str!("../../wgsl/warp_compose.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: warp_compose_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// Weight of the feature warp W†_i.
    pub alpha: f32,
    pub _pad0: u32,
}

/// A W† component of this magnitude or more marks a pixel no feature reaches: there the
/// flow alone carries the warp.
pub const UNKNOWN: f32 = 1e30;

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [
        crate::gpu::engine::groups(cfg.width, 8),
        crate::gpu::engine::groups(cfg.height, 8),
        1,
    ]
}

/// Bilinear sample of an interleaved 2-vector field at `(x, y)`, clamped to the pixel
/// centres at the border; mirrors `wgsl/shared/field_sample.wgsl`.
pub fn sample2(field: &[f32], width: u32, height: u32, x: f32, y: f32) -> [f32; 2] {
    let (w, h) = (width as f32, height as f32);
    let x = x.clamp(0.0, w - 1.0);
    let y = y.clamp(0.0, h - 1.0);
    let (x0, y0) = (x.floor() as u32, y.floor() as u32);
    let x1 = (x0 + 1).min(width - 1);
    let y1 = (y0 + 1).min(height - 1);
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let at = |i: u32| [field[2 * i as usize], field[2 * i as usize + 1]];
    let (a, b) = (at(y0 * width + x0), at(y0 * width + x1));
    let (c, d) = (at(y1 * width + x0), at(y1 * width + x1));
    let mut o = [0.0f32; 2];
    for k in 0..2 {
        let top = a[k] + (b[k] - a[k]) * fx;
        let bot = c[k] + (d[k] - c[k]) * fx;
        o[k] = top + (bot - top) * fy;
    }
    o
}

fn warp_compose_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (wdag, wprev, field) = (b[1].get::<f32>(), b[2].get::<f32>(), b[3].get::<f32>());
    let (wdag, wprev, field): (&[f32], &[f32], &[f32]) = (&wdag, &wprev, &field);
    let mut wout = b[4].get_mut::<f32>();
    let w = cfg.width as usize;
    wout[..2 * w * cfg.height as usize]
        .par_chunks_mut(2 * w)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                let i = y * w + x;
                let prev = [wprev[2 * i], wprev[2 * i + 1]];
                let dag = [wdag[2 * i], wdag[2 * i + 1]];
                let v = sample2(
                    field,
                    cfg.width,
                    cfg.height,
                    x as f32 + prev[0],
                    y as f32 + prev[1],
                );
                let known = dag[0].abs() < UNKNOWN;
                for k in 0..2 {
                    let flowed = prev[k] + v[k];
                    row[2 * x + k] = if known {
                        cfg.alpha * dag[k] + (1.0 - cfg.alpha) * flowed
                    } else {
                        flowed
                    };
                }
            }
        });
}
