//! Residual of the mixed form of C13 Eq. (3) on one level (see `wgsl/field_resid.wgsl`).

use super::field_cfg::{for_links, for_slabs, groups3, Config};
use crate::gpu::engine::{Bind, CpuBinding, StageDef};

pub const STAGE: StageDef = StageDef {
    name: "field_resid",
    wgsl: include_str!("../../wgsl/field_resid.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::Read,
    ],
    cpu: field_resid_cpu,
};

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    groups3(cfg.nx, cfg.ny, cfg.nz)
}

fn field_resid_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_cellw, g_f, g_uv) = (b[1].get::<f32>(), b[2].get::<f32>(), b[3].get::<f32>());
    let (cellw, f, uv): (&[f32], &[f32], &[f32]) = (&g_cellw, &g_f, &g_uv);
    let g_links = b[5].get::<f32>();
    let links: &[f32] = &g_links;
    let mut r = b[4].get_mut::<f32>();
    let slab = 6 * (cfg.nx * cfg.ny) as usize;
    for_slabs(&mut r[..6 * cfg.cells()], slab, |z, out| {
        let z = z as u32;
        for y in 0..cfg.ny {
            for x in 0..cfg.nx {
                let i = (x + cfg.nx * (y + cfg.ny * z)) as usize;
                let o = 6 * (x + cfg.nx * y) as usize;
                let p = cellw[i];
                if p < 0.0 {
                    out[o..o + 6].fill(0.0);
                    continue;
                }
                let (mut su, mut sv, mut d) = ([0.0f32; 3], [0.0f32; 3], 0.0f32);
                for_links(&cfg, links, x, y, z, |j, w| {
                    for c in 0..3 {
                        su[c] += w * uv[6 * j + c];
                        sv[c] += w * uv[6 * j + 3 + c];
                    }
                    d += w;
                });
                for c in 0..3 {
                    let (u, v) = (uv[6 * i + c], uv[6 * i + 3 + c]);
                    out[o + c] = f[6 * i + c] - (cfg.sigma * (sv[c] - d * v) - u);
                    out[o + 3 + c] = f[6 * i + 3 + c] - (cfg.sigma * (su[c] - d * u) + p * v);
                }
            }
        }
    });
}
