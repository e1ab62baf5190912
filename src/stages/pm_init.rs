//! PatchMatch field initialisation (random, or upsampled from the coarser level); see
//! `wgsl/pm_init.wgsl`.

use super::pm_common::{hash, pack_xy, rand, unpack_xy, Config, Geom, NONE, SOURCE, TARGET};
use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "pm_init",
    wgsl: include_str!("../../wgsl/pm_init.wgsl"),
    bindings: &[Bind::Uniform, Bind::Read, Bind::Read, Bind::ReadWrite],
    cpu: pm_init_cpu,
};

/// Random draws before the fallback source is taken.
pub const DRAWS: u32 = 16;

fn pm_init_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_flags, g_coarse) = (b[1].get::<u32>(), b[2].get::<u32>());
    let (flags, coarse): (&[u32], &[u32]) = (&g_flags, &g_coarse);
    let mut nnf = b[3].get_mut::<u32>();
    let g = Geom::new(&cfg);
    let (w, h, r) = (cfg.width, cfg.height, cfg.radius);
    let valid =
        |x: i32, y: i32| g.in_source_box(x, y) && flags[(y * g.w + x) as usize] & SOURCE != 0;
    nnf[..(w * h) as usize]
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let y = y as u32;
            for x in 0..w {
                let i = y * w + x;
                if flags[i as usize] & TARGET == 0 {
                    row[x as usize] = NONE;
                    continue;
                }
                let mut cand = NONE;
                if cfg.coarse_width > 0 {
                    let cx = (x / 2).min(cfg.coarse_width - 1);
                    let cy = (y / 2).min(cfg.coarse_height - 1);
                    let pn = coarse[(cy * cfg.coarse_width + cx) as usize];
                    if pn != NONE {
                        let (px, py) = unpack_xy(pn);
                        let sx = 2 * px + x as i32 - 2 * cx as i32;
                        let sy = 2 * py + y as i32 - 2 * cy as i32;
                        if valid(sx, sy) {
                            cand = pack_xy(sx as u32, sy as u32);
                        }
                    }
                }
                if cand == NONE {
                    for k in 0..DRAWS {
                        let h1 = rand(cfg.seed, cfg.pass_id, i, k);
                        let h2 = hash(h1);
                        let sx = r + h1 % (w - 2 * r);
                        let sy = r + h2 % (h - 2 * r);
                        if flags[(sy * w + sx) as usize] & SOURCE != 0 {
                            cand = pack_xy(sx, sy);
                            break;
                        }
                    }
                }
                if cand == NONE {
                    cand = cfg.fallback;
                }
                row[x as usize] = cand;
            }
        });
}
