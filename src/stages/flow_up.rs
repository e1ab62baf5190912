//! Doubling a flow field onto the next finer pyramid level (see `wgsl/flow_up.wgsl`).

use crate::gpu::engine::{groups, Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "flow_up",
    wgsl: include_str!("../../wgsl/flow_up.wgsl"),
    bindings: &[Bind::Uniform, Bind::Read, Bind::ReadWrite],
    cpu: flow_up_cpu,
};

/// Same fields as `flow_down::Config`: `src` is the coarse level, `dst` the fine one.
#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub src_w: u32,
    pub src_h: u32,
    pub dst_w: u32,
    pub dst_h: u32,
}

/// One invocation per fine pixel, 8x8 groups.
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [groups(cfg.dst_w, 8), groups(cfg.dst_h, 8), 1]
}

/// WGSL `mix` on two channels.
#[inline]
pub(crate) fn mix2(a: [f32; 2], b: [f32; 2], t: f32) -> [f32; 2] {
    [a[0] * (1.0 - t) + b[0] * t, a[1] * (1.0 - t) + b[1] * t]
}

fn flow_up_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let g_src = b[1].get::<[f32; 2]>();
    let src: &[[f32; 2]] = &g_src;
    let mut dst = b[2].get_mut::<[f32; 2]>();
    let (sw, sh, dw) = (cfg.src_w, cfg.src_h, cfg.dst_w as usize);
    dst[..dw * cfg.dst_h as usize]
        .par_chunks_mut(dw)
        .enumerate()
        .for_each(|(gy, row_out)| {
            let cy = ((gy as f32 - 0.5) * 0.5).clamp(0.0, (sh - 1) as f32);
            let y0 = cy.floor() as u32;
            let fy = cy - y0 as f32;
            let y1 = (y0 + 1).min(sh - 1);
            for (gx, out) in row_out.iter_mut().enumerate() {
                let cx = ((gx as f32 - 0.5) * 0.5).clamp(0.0, (sw - 1) as f32);
                let x0 = cx.floor() as u32;
                let fx = cx - x0 as f32;
                let x1 = (x0 + 1).min(sw - 1);
                let at = |x: u32, y: u32| src[(y * sw + x) as usize];
                let top = mix2(at(x0, y0), at(x1, y0), fx);
                let bot = mix2(at(x0, y1), at(x1, y1), fx);
                let v = mix2(top, bot, fy);
                *out = [2.0 * v[0], 2.0 * v[1]];
            }
        });
}
