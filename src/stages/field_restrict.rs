//! Mean restriction of the mixed residual to the next coarser level, zeroing the coarse
//! unknowns (see `wgsl/field_restrict.wgsl`).

use super::field_cfg::{for_slabs, groups3, Config};
use crate::gpu::engine::{Bind, CpuBinding, StageDef};

pub const STAGE: StageDef = StageDef {
    name: "field_restrict",
    wgsl: include_str!("../../wgsl/field_restrict.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::ReadWrite,
    ],
    cpu: field_restrict_cpu,
};

/// One invocation per coarse cell.
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    groups3(cfg.cnx, cfg.cny, cfg.cnz)
}

fn field_restrict_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_wf, g_wc, g_r) = (b[1].get::<f32>(), b[2].get::<f32>(), b[3].get::<f32>());
    let (wf, wc, r): (&[f32], &[f32], &[f32]) = (&g_wf, &g_wc, &g_r);
    let mut fc = b[4].get_mut::<f32>();
    let mut uvc = b[5].get_mut::<f32>();
    let nc = (cfg.cnx * cfg.cny * cfg.cnz) as usize;
    let slab = 6 * (cfg.cnx * cfg.cny) as usize;
    uvc[..6 * nc].fill(0.0);
    for_slabs(&mut fc[..6 * nc], slab, |cz, out| {
        let cz = cz as u32;
        for cy in 0..cfg.cny {
            for cx in 0..cfg.cnx {
                let ic = (cx + cfg.cnx * (cy + cfg.cny * cz)) as usize;
                let o = 6 * (cx + cfg.cnx * cy) as usize;
                let mut s = [0.0f32; 6];
                if wc[ic] >= 0.0 {
                    let mut n = 0.0f32;
                    for c in 0..8u32 {
                        let x = 2 * cx + (c & 1);
                        let y = 2 * cy + ((c >> 1) & 1);
                        let z = 2 * cz + (c >> 2);
                        if x < cfg.nx && y < cfg.ny && z < cfg.nz {
                            let i = (x + cfg.nx * (y + cfg.ny * z)) as usize;
                            if wf[i] >= 0.0 {
                                for (k, sk) in s.iter_mut().enumerate() {
                                    *sk += r[6 * i + k];
                                }
                                n += 1.0;
                            }
                        }
                    }
                    for sk in s.iter_mut() {
                        *sk /= n;
                    }
                }
                out[o..o + 6].copy_from_slice(&s);
            }
        }
    });
}
