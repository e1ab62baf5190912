//! Masked cell-centred trilinear prolongation of the coarse correction, added to the fine
//! unknowns (see `wgsl/field_prolong.wgsl`).

use super::field_cfg::{for_slabs, groups3, Config};
use crate::gpu::engine::{Bind, CpuBinding, StageDef};

pub const STAGE: StageDef = StageDef {
    name: "field_prolong",
    wgsl: include_str!("../../wgsl/field_prolong.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: field_prolong_cpu,
};

/// One invocation per fine cell.
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    groups3(cfg.nx, cfg.ny, cfg.nz)
}

fn field_prolong_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_wf, g_wc, g_uvc) = (b[1].get::<f32>(), b[2].get::<f32>(), b[3].get::<f32>());
    let (wf, wc, uvc): (&[f32], &[f32], &[f32]) = (&g_wf, &g_wc, &g_uvc);
    let mut uv = b[4].get_mut::<f32>();
    let slab = 6 * (cfg.nx * cfg.ny) as usize;
    let cd = [cfg.cnx as i32, cfg.cny as i32, cfg.cnz as i32];
    for_slabs(&mut uv[..6 * cfg.cells()], slab, |z, out| {
        let z = z as u32;
        for y in 0..cfg.ny {
            for x in 0..cfg.nx {
                let i = (x + cfg.nx * (y + cfg.ny * z)) as usize;
                if wf[i] < 0.0 {
                    continue;
                }
                let p = [(x >> 1) as i32, (y >> 1) as i32, (z >> 1) as i32];
                let o = [
                    (x & 1) as i32 * 2 - 1,
                    (y & 1) as i32 * 2 - 1,
                    (z & 1) as i32 * 2 - 1,
                ];
                let (mut su, mut sv, mut ws) = ([0.0f32; 3], [0.0f32; 3], 0.0f32);
                for c in 0..8u32 {
                    let s = [(c & 1) as i32, ((c >> 1) & 1) as i32, (c >> 2) as i32];
                    let q = [p[0] + s[0] * o[0], p[1] + s[1] * o[1], p[2] + s[2] * o[2]];
                    if (0..3).any(|a| q[a] < 0 || q[a] >= cd[a]) {
                        continue;
                    }
                    let ic =
                        (q[0] as u32 + cfg.cnx * (q[1] as u32 + cfg.cny * q[2] as u32)) as usize;
                    if wc[ic] < 0.0 {
                        continue;
                    }
                    let wa = |sa: i32| if sa == 1 { 0.25f32 } else { 0.75 };
                    let w = wa(s[0]) * wa(s[1]) * wa(s[2]);
                    for k in 0..3 {
                        su[k] += w * uvc[6 * ic + k];
                        sv[k] += w * uvc[6 * ic + 3 + k];
                    }
                    ws += w;
                }
                let ob = 6 * (x + cfg.nx * y) as usize;
                for k in 0..3 {
                    out[ob + k] += su[k] / ws;
                    out[ob + 3 + k] += sv[k] / ws;
                }
            }
        }
    });
}
