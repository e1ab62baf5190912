//! Right-hand side `f2 + σ L f1` of the coarsest level's direct solve (see
//! `wgsl/field_coarse_rhs.wgsl`).

use super::field_cfg::{for_links, Config};
use crate::gpu::engine::{Bind, CpuBinding, StageDef};

pub const STAGE: StageDef = StageDef {
    name: "field_coarse_rhs",
    wgsl: include_str!("../../wgsl/field_coarse_rhs.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::Read,
    ],
    cpu: field_coarse_rhs_cpu,
};

/// One invocation per entry of the compact cell list.
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [crate::gpu::engine::groups(cfg.count, 64), 1, 1]
}

fn field_coarse_rhs_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_cells, g_f, g_links) = (b[1].get::<u32>(), b[2].get::<f32>(), b[4].get::<f32>());
    let (cells, f, links): (&[u32], &[f32], &[f32]) = (&g_cells, &g_f, &g_links);
    let mut g = b[3].get_mut::<f32>();
    // At most a few thousand cells (the coarsest level): on the calling thread.
    g[..3 * cfg.count as usize]
        .chunks_mut(3)
        .enumerate()
        .for_each(|(k, out)| {
            let i = cells[k];
            let (x, y, z) = (i % cfg.nx, (i / cfg.nx) % cfg.ny, i / (cfg.nx * cfg.ny));
            let i = i as usize;
            let (mut s, mut d) = ([0.0f32; 3], 0.0f32);
            for_links(&cfg, links, x, y, z, |j, w| {
                for c in 0..3 {
                    s[c] += w * f[6 * j + c];
                }
                d += w;
            });
            for c in 0..3 {
                out[c] = f[6 * i + 3 + c] + cfg.sigma * (s[c] - d * f[6 * i + c]);
            }
        });
}
