//! Halving a 2-channel image for the flow pyramid (see `wgsl/flow_down.wgsl`).

use crate::gpu::engine::{groups, Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "flow_down",
    wgsl: include_str!("../../wgsl/flow_down.wgsl"),
    bindings: &[Bind::Uniform, Bind::Read, Bind::ReadWrite],
    cpu: flow_down_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub src_w: u32,
    pub src_h: u32,
    pub dst_w: u32,
    pub dst_h: u32,
}

impl Config {
    /// The pass from a `w` x `h` level to the next coarser one, `ceil(w/2)` x `ceil(h/2)`.
    pub fn halving(w: u32, h: u32) -> Self {
        Config {
            src_w: w,
            src_h: h,
            dst_w: w.div_ceil(2),
            dst_h: h.div_ceil(2),
        }
    }
}

const TAPS: [f32; 4] = [0.125, 0.375, 0.375, 0.125];

/// One invocation per coarse pixel, 8x8 groups.
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [groups(cfg.dst_w, 8), groups(cfg.dst_h, 8), 1]
}

fn flow_down_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let g_src = b[1].get::<[f32; 2]>();
    let src: &[[f32; 2]] = &g_src;
    let mut dst = b[2].get_mut::<[f32; 2]>();
    let (sw, sh, dw) = (cfg.src_w as i32, cfg.src_h as i32, cfg.dst_w as usize);
    dst[..dw * cfg.dst_h as usize]
        .par_chunks_mut(dw)
        .enumerate()
        .for_each(|(gy, row_out)| {
            for (gx, out) in row_out.iter_mut().enumerate() {
                let (x0, y0) = (2 * gx as i32 - 1, 2 * gy as i32 - 1);
                let mut acc = [0.0f32; 2];
                for (j, &ty) in TAPS.iter().enumerate() {
                    let y = (y0 + j as i32).clamp(0, sh - 1) as usize;
                    let mut row = [0.0f32; 2];
                    for (i, &tx) in TAPS.iter().enumerate() {
                        let x = (x0 + i as i32).clamp(0, sw - 1) as usize;
                        let v = src[y * sw as usize + x];
                        row[0] += tx * v[0];
                        row[1] += tx * v[1];
                    }
                    acc[0] += ty * row[0];
                    acc[1] += ty * row[1];
                }
                *out = acc;
            }
        });
}
