//! White noise on the hair, the start of CZ06's texture synthesis (§3.2): an integer hash of
//! (seed, pixel), so both backends give the same bits. See `wgsl/cz_noise.wgsl`; the host is
//! `crate::sketch::texture`.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "cz_noise",
    wgsl: include_str!("../../wgsl/cz_noise.wgsl"),
    bindings: &[Bind::Uniform, Bind::Read, Bind::ReadWrite],
    cpu: cz_noise_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub seed_lo: u32,
    pub seed_hi: u32,
    /// Half-width of the uniform distribution.
    pub amp: f32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

impl Config {
    pub fn new(width: u32, height: u32, seed: u64, amp: f32) -> Config {
        Config {
            width,
            height,
            seed_lo: seed as u32,
            seed_hi: (seed >> 32) as u32,
            amp,
            ..Default::default()
        }
    }
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    use crate::gpu::engine::groups;
    [groups(cfg.width, 8), groups(cfg.height, 8), 1]
}

fn lowbias32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// The noise at pixel index `i` (uniform in [−amp, amp)), as the pass computes it.
pub fn noise_at(cfg: &Config, i: u32) -> f32 {
    let h = lowbias32(cfg.seed_lo ^ lowbias32(cfg.seed_hi ^ lowbias32(i)));
    // 24 bits: exact in f32, so u, 2u − 1 and the product are the same on both sides.
    let u = (h >> 8) as f32 * (1.0 / 16_777_216.0);
    cfg.amp * (2.0 * u - 1.0)
}

fn cz_noise_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let flags = b[1].get::<u32>();
    let flags: &[u32] = &flags;
    let mut out = b[2].get_mut::<f32>();
    let w = cfg.width as usize;
    out[..w * cfg.height as usize]
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let i = y * w + x;
                *o = if flags[i] != 0 {
                    noise_at(&cfg, i as u32)
                } else {
                    0.0
                };
            }
        });
}
