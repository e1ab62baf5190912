//! High-pass over the hair, step 3 of CZ06's texture synthesis (§3.2): the band minus its
//! masked local mean. See `wgsl/cz_hipass.wgsl`; the host is `crate::sketch::texture`.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "cz_hipass",
    wgsl: include_str!("../../wgsl/cz_hipass.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: cz_hipass_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub _pad0: u32,
    pub _pad1: u32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    use crate::gpu::engine::groups;
    [groups(cfg.width, 8), groups(cfg.height, 8), 1]
}

fn cz_hipass_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (flags, src) = (b[1].get::<u32>(), b[2].get::<f32>());
    let (num, den) = (b[3].get::<f32>(), b[4].get::<f32>());
    let (flags, src, num, den): (&[u32], &[f32], &[f32], &[f32]) = (&flags, &src, &num, &den);
    let mut out = b[5].get_mut::<f32>();
    let w = cfg.width as usize;
    out[..w * cfg.height as usize]
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let i = y * w + x;
                let mut v = 0.0;
                // den > 0 on the domain: the pixel itself is in it.
                if flags[i] != 0 && den[i] > 0.0 {
                    v = src[i] - num[i] / den[i];
                }
                *o = v;
            }
        });
}
