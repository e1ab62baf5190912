//! One 1D pass of the recursive-filter domain transform (Gastal & Oliveira 2011), per row or
//! per column, in place on several planes (`crate::video::diffuse::spread`).

use crate::gpu::engine::{Bind, CpuBinding, StageDef};

pub const STAGE: StageDef = StageDef {
    name: "dt_filter",
    wgsl: include_str!("../../wgsl/dt_filter.wgsl"),
    bindings: &[Bind::Uniform, Bind::Read, Bind::ReadWrite],
    cpu: dt_filter_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// 0: along rows, 1: along columns.
    pub axis: u32,
    /// Guide channels, each a width*height plane, one after the other.
    pub channels: u32,
    /// Planes filtered together, each width*height, one after the other.
    pub n_planes: u32,
    /// sigma_s / sigma_r.
    pub ratio: f32,
    /// ln a, a = exp(-sqrt(2) / sigma_H) for this iteration.
    pub log_a: f32,
    pub _pad0: u32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    let lines = if cfg.axis == 0 { cfg.height } else { cfg.width };
    [crate::gpu::engine::groups(lines, 64), 1, 1]
}

fn dt_filter_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let guide = b[1].get::<f32>();
    let mut planes = b[2].get_mut::<f32>();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    let (len, lines) = if cfg.axis == 0 { (w, h) } else { (h, w) };
    let index = |line: usize, k: usize| {
        if cfg.axis == 0 {
            line * w + k
        } else {
            k * w + line
        }
    };
    let nc = cfg.channels as usize;
    let weight = |line: usize, k: usize| {
        let (a, b) = (index(line, k - 1), index(line, k));
        let mut s = 0.0f32;
        for c in 0..nc {
            s += (guide[c * w * h + b] - guide[c * w * h + a]).abs();
        }
        ((1.0 + cfg.ratio * s) * cfg.log_a).exp()
    };
    let plane = w * h;
    // Sequential over lines: columns interleave in memory, so a parallel split by line
    // would need strided mutable views; the pass is a few multiply-adds per pixel.
    for line in 0..lines {
        for k in 1..len {
            let wk = weight(line, k);
            let (i, j) = (index(line, k), index(line, k - 1));
            for p in 0..cfg.n_planes as usize {
                let o = p * plane;
                planes[o + i] += wk * (planes[o + j] - planes[o + i]);
            }
        }
        for kk in 1..len {
            let k = len - 1 - kk;
            let wk = weight(line, k + 1);
            let (i, j) = (index(line, k), index(line, k + 1));
            for p in 0..cfg.n_planes as usize {
                let o = p * plane;
                planes[o + i] += wk * (planes[o + j] - planes[o + i]);
            }
        }
    }
}
