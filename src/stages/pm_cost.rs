//! Patch distance of each target's current match; see `wgsl/pm_cost.wgsl`.

use super::pm_common::{unpack_xy, Config, Geom, TARGET};
use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "pm_cost",
    wgsl: include_str!("../../wgsl/pm_cost.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: pm_cost_cpu,
};

fn pm_cost_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_flags, g_px, g_nnf) = (b[1].get::<u32>(), b[2].get::<u32>(), b[3].get::<u32>());
    let (flags, px, nnf): (&[u32], &[u32], &[u32]) = (&g_flags, &g_px, &g_nnf);
    let mut cost = b[4].get_mut::<u32>();
    let g = Geom::new(&cfg);
    let w = cfg.width as usize;
    cost[..w * cfg.height as usize]
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, c) in row.iter_mut().enumerate() {
                let i = y * w + x;
                *c = if flags[i] & TARGET == 0 {
                    0
                } else {
                    let (sx, sy) = unpack_xy(nnf[i]);
                    g.ssd(px, x as i32, y as i32, sx, sy, u32::MAX)
                };
            }
        });
}
