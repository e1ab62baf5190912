//! One red-black half-sweep of collective Gauss-Seidel on the mixed form of C13 Eq. (3)
//! (see `wgsl/field_smooth.wgsl`).

use super::field_cfg::{groups3, Config, MIN_TASK_CELLS, SERIAL_CELLS};
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
    // In place, as the shader: cells of this colour read only cells of the other colour
    // (their 6-neighbours) and their own v, and write only themselves, so no cell read is
    // written in this half-sweep and the order of the updates does not matter. The z-slabs
    // of one parity are relaxed in parallel while those of the other parity (the -z and +z
    // neighbours) are only read; then the other parity. (A snapshot copy of uv per half-sweep
    // cost more than the relaxation on the 80³ fine level: a 7 MB memmove and fresh pages.)
    let slab = 6 * (cfg.nx * cfg.ny) as usize;
    let cells = cfg.cells();
    for parity in 0..2usize {
        let mut work: Vec<(u32, &mut [f32])> = Vec::new();
        let mut held: Vec<&[f32]> = vec![&[]; cfg.nz as usize];
        for (z, s) in uv[..6 * cells].chunks_mut(slab).enumerate() {
            if z % 2 == parity {
                work.push((z as u32, s));
            } else {
                held[z] = s;
            }
        }
        let relax = |(z, out): (u32, &mut [f32])| {
            let below = if z > 0 { held[z as usize - 1] } else { &[] };
            let above = held.get(z as usize + 1).copied().unwrap_or(&[]);
            relax_slab(&cfg, (cellw, f, links), z, out, (below, above));
        };
        if cells < SERIAL_CELLS {
            work.into_iter().for_each(relax);
        } else {
            let min = MIN_TASK_CELLS.div_ceil(slab / 6).max(1);
            work.into_par_iter().with_min_len(min).for_each(relax);
        }
    }
}

/// Relaxes the cells of `cfg.colour` in slab `z` (`out`, 6 floats per cell), reading the
/// neighbouring slabs `below` (z - 1) and `above` (z + 1). Neighbours are visited in the
/// shader's order (-x, +x, -y, +y, -z, +z; see
/// [`for_links`](super::field_cfg::for_links)) so the sums round alike.
fn relax_slab(
    cfg: &Config,
    (cellw, f, links): (&[f32], &[f32], &[f32]),
    z: u32,
    out: &mut [f32],
    (below, above): (&[f32], &[f32]),
) {
    let (nx, ny, nz) = (cfg.nx, cfg.ny, cfg.nz);
    let sy = nx as usize;
    let sz = (nx * ny) as usize;
    for y in 0..ny {
        let x0 = (y + z + cfg.colour) & 1;
        for x in (x0..nx).step_by(2) {
            let i = (x + nx * (y + ny * z)) as usize;
            let p = cellw[i];
            if p < 0.0 {
                continue;
            }
            // Local index of the cell in its slab.
            let k = (x + nx * y) as usize;
            let (mut su, mut sv, mut d) = ([0.0f32; 3], [0.0f32; 3], 0.0f32);
            let mut add = |src: &[f32], kj: usize, w: f32| {
                if w > 0.0 {
                    let n = &src[6 * kj..6 * kj + 6];
                    for c in 0..3 {
                        su[c] += w * n[c];
                        sv[c] += w * n[3 + c];
                    }
                    d += w;
                }
            };
            if x > 0 {
                add(out, k - 1, links[3 * (i - 1)]);
            }
            if x + 1 < nx {
                add(out, k + 1, links[3 * i]);
            }
            if y > 0 {
                add(out, k - sy, links[3 * (i - sy) + 1]);
            }
            if y + 1 < ny {
                add(out, k + sy, links[3 * i + 1]);
            }
            if z > 0 {
                add(below, k, links[3 * (i - sz) + 2]);
            }
            if z + 1 < nz {
                add(above, k, links[3 * i + 2]);
            }
            let o = 6 * k;
            let old_v = [out[o + 3], out[o + 4], out[o + 5]];
            let r = relax_cell(cfg, (p, d), (su, sv), &f[6 * i..6 * i + 6], old_v);
            out[o..o + 6].copy_from_slice(&r);
        }
    }
}
