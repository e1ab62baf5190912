//! Coarsest-level direct solve `v = A⁻¹ g` with a host-computed dense inverse (see
//! `wgsl/field_dense.wgsl`).

use super::field_cfg::Config;
use crate::gpu::engine::{Bind, CpuBinding, StageDef};

pub const STAGE: StageDef = StageDef {
    name: "field_dense",
    wgsl: include_str!("../../wgsl/field_dense.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: field_dense_cpu,
};

/// One invocation per row.
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [crate::gpu::engine::groups(cfg.count, 64), 1, 1]
}

fn field_dense_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    use rayon::prelude::*;
    let cfg: Config = b[0].uniform();
    let (g_cells, g_inv, g_g) = (b[1].get::<u32>(), b[2].get::<f32>(), b[3].get::<f32>());
    let (cells, inv, g): (&[u32], &[f32], &[f32]) = (&g_cells, &g_inv, &g_g);
    let n = cfg.count as usize;
    let row = |r: usize| {
        let mut s = [0.0f32; 3];
        for k in 0..n {
            let a = inv[r * n + k];
            for c in 0..3 {
                s[c] += a * g[3 * k + c];
            }
        }
        s
    };
    // The default coarsest level (≤ 512 cells) is done faster on the calling thread.
    let rows: Vec<[f32; 3]> = if n * n < 1 << 20 {
        (0..n).map(row).collect()
    } else {
        (0..n).into_par_iter().map(row).collect()
    };
    let mut uv = b[4].get_mut::<f32>();
    for (r, s) in rows.iter().enumerate() {
        let base = 6 * cells[r] as usize;
        uv[base + 3..base + 6].copy_from_slice(s);
    }
}
