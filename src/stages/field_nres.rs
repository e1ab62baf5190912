//! Normal-equation residual `b - L L v - p v = r2 + L r1` of C13 Eq. (3) from the mixed
//! residual (see `wgsl/field_nres.wgsl`).

use super::field_cfg::{for_h_neighbours, groups3, Config};
use crate::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "field_nres",
    wgsl: include_str!("../../wgsl/field_nres.wgsl"),
    bindings: &[Bind::Uniform, Bind::Read, Bind::Read, Bind::ReadWrite],
    cpu: field_nres_cpu,
};

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    groups3(cfg.nx, cfg.ny, cfg.nz)
}

fn field_nres_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_cellw, g_r) = (b[1].get::<f32>(), b[2].get::<f32>());
    let (cellw, r): (&[f32], &[f32]) = (&g_cellw, &g_r);
    let mut res = b[3].get_mut::<f32>();
    let slab = 3 * (cfg.nx * cfg.ny) as usize;
    res[..3 * cfg.cells()]
        .par_chunks_mut(slab)
        .enumerate()
        .for_each(|(z, out)| {
            let z = z as u32;
            for y in 0..cfg.ny {
                for x in 0..cfg.nx {
                    let i = (x + cfg.nx * (y + cfg.ny * z)) as usize;
                    let o = 3 * (x + cfg.nx * y) as usize;
                    if cellw[i] < 0.0 {
                        out[o..o + 3].fill(0.0);
                        continue;
                    }
                    let (mut s, mut d) = ([0.0f32; 3], 0.0f32);
                    for_h_neighbours(&cfg, cellw, x, y, z, |j| {
                        for c in 0..3 {
                            s[c] += r[6 * j + c];
                        }
                        d += 1.0;
                    });
                    for c in 0..3 {
                        out[o + c] = r[6 * i + 3 + c] + cfg.sigma * (s[c] - d * r[6 * i + c]);
                    }
                }
            }
        });
}
