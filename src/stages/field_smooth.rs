//! One red-black half-sweep of collective Gauss-Seidel on the mixed form of C13 Eq. (3)
//! (see `wgsl/field_smooth.wgsl`).

use super::field_cfg::{for_links, groups3, Config};
use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "field_smooth",
    wgsl: include_str!("../../wgsl/field_smooth.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::Read,
    ],
    cpu: field_smooth_cpu,
};

/// Threads cover half of x (one colour).
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    groups3(cfg.nx.div_ceil(2), cfg.ny, cfg.nz)
}

/// The 2x2 collective update of one cell with penalty `p`, linked neighbours of total weight
/// `d` whose weighted u and v sum to `su`, `sv`; `mode` 1 keeps `v` and solves the u row only.
#[inline]
fn relax_cell(
    cfg: &Config,
    (p, d): (f32, f32),
    (su, sv): ([f32; 3], [f32; 3]),
    f: &[f32],
    old_v: [f32; 3],
) -> [f32; 6] {
    let (sigma, mode) = (cfg.sigma, cfg.mode);
    let sd = sigma * d;
    let mut out = [0.0f32; 6];
    for c in 0..3 {
        let g1 = f[c] - sigma * sv[c];
        let g2 = f[3 + c] - sigma * su[c];
        let (u, v) = if mode == 1 {
            (-g1 - sd * old_v[c], old_v[c])
        } else {
            let det = -p - sd * sd;
            if det != 0.0 {
                ((p * g1 + sd * g2) / det, (sd * g1 - g2) / det)
            } else {
                (-g1, 0.0)
            }
        };
        out[c] = u;
        out[3 + c] = v;
    }
    out
}

fn field_smooth_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_cellw, g_f) = (b[1].get::<f32>(), b[2].get::<f32>());
    let (cellw, f): (&[f32], &[f32]) = (&g_cellw, &g_f);
    let g_links = b[4].get::<f32>();
    let links: &[f32] = &g_links;
    let mut uv = b[3].get_mut::<f32>();
    // Cells of one colour read only the other colour: relax from a snapshot.
    let old = uv[..6 * cfg.cells()].to_vec();
    let slab = 6 * (cfg.nx * cfg.ny) as usize;
    uv[..6 * cfg.cells()]
        .par_chunks_mut(slab)
        .enumerate()
        .for_each(|(z, out)| {
            let z = z as u32;
            for y in 0..cfg.ny {
                let x0 = (y + z + cfg.colour) & 1;
                for x in (x0..cfg.nx).step_by(2) {
                    let i = (x + cfg.nx * (y + cfg.ny * z)) as usize;
                    let p = cellw[i];
                    if p < 0.0 {
                        continue;
                    }
                    let (mut su, mut sv, mut d) = ([0.0f32; 3], [0.0f32; 3], 0.0f32);
                    for_links(&cfg, links, x, y, z, |j, w| {
                        for c in 0..3 {
                            su[c] += w * old[6 * j + c];
                            sv[c] += w * old[6 * j + 3 + c];
                        }
                        d += w;
                    });
                    let old_v = [old[6 * i + 3], old[6 * i + 4], old[6 * i + 5]];
                    let r = relax_cell(&cfg, (p, d), (su, sv), &f[6 * i..6 * i + 6], old_v);
                    let o = 6 * (x + cfg.nx * y) as usize;
                    out[o..o + 6].copy_from_slice(&r);
                }
            }
        });
}
