//! One level of the Gaussian image pyramid for pyramidal Lucas–Kanade: binomial 5-tap
//! filter, every second pixel. All levels share one buffer (see [`Layout`]).

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "klt_pyr_down",
    wgsl: include_str!("../../wgsl/klt_pyr_down.wgsl"),
    bindings: &[Bind::Uniform, Bind::ReadWrite],
    cpu: klt_pyr_down_cpu,
};

const TAPS: [f32; 5] = [0.0625, 0.25, 0.375, 0.25, 0.0625];

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub src_w: u32,
    pub src_h: u32,
    pub dst_w: u32,
    pub dst_h: u32,
    pub src_off: u32,
    pub dst_off: u32,
    pub _pad0: u32,
    pub _pad1: u32,
}

/// Sizes and offsets of the levels of a pyramid stored in one buffer. Level l+1 has
/// ceil(w_l / 2) x ceil(h_l / 2) pixels; `klt_track.wgsl` derives the same numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct Layout {
    /// (width, height, offset in elements) per level, finest first.
    pub levels: Vec<(u32, u32, u32)>,
    /// Elements in the whole buffer.
    pub len: u32,
}

impl Layout {
    pub fn new(width: u32, height: u32, levels: u32) -> Self {
        let (mut w, mut h, mut off) = (width, height, 0u32);
        let mut out = Vec::with_capacity(levels as usize);
        for _ in 0..levels {
            out.push((w, h, off));
            off += w * h;
            w = w.div_ceil(2);
            h = h.div_ceil(2);
        }
        Layout {
            levels: out,
            len: off,
        }
    }

    /// The pass's uniform that fills level `l` (1 ..) from level l-1.
    pub fn config(&self, l: usize) -> Config {
        let (sw, sh, so) = self.levels[l - 1];
        let (dw, dh, doff) = self.levels[l];
        Config {
            src_w: sw,
            src_h: sh,
            dst_w: dw,
            dst_h: dh,
            src_off: so,
            dst_off: doff,
            ..Default::default()
        }
    }
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [
        crate::gpu::engine::groups(cfg.dst_w, 8),
        crate::gpu::engine::groups(cfg.dst_h, 8),
        1,
    ]
}

fn klt_pyr_down_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let mut pyr = b[1].get_mut::<f32>();
    // The destination level lies after the source in the buffer (finest level first).
    let (head, tail) = pyr.split_at_mut(cfg.dst_off as usize);
    let src: &[f32] = &head[cfg.src_off as usize..];
    let (sw, sh) = (cfg.src_w as i32, cfg.src_h as i32);
    tail[..(cfg.dst_w * cfg.dst_h) as usize]
        .par_chunks_mut(cfg.dst_w as usize)
        .enumerate()
        .for_each(|(gy, row)| {
            for (gx, out) in row.iter_mut().enumerate() {
                let mut acc = 0.0f32;
                for (j, tj) in TAPS.iter().enumerate() {
                    let y = (2 * gy as i32 + j as i32 - 2).clamp(0, sh - 1) as u32;
                    let mut r = 0.0f32;
                    for (i, ti) in TAPS.iter().enumerate() {
                        let x = (2 * gx as i32 + i as i32 - 2).clamp(0, sw - 1) as u32;
                        r += ti * src[(y * cfg.src_w + x) as usize];
                    }
                    acc += tj * r;
                }
                *out = acc;
            }
        });
}
