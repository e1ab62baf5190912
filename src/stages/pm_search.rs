//! One PatchMatch pass: jump-flood propagation at distance `step` and random search with a
//! shrinking window; see `wgsl/pm_search.wgsl` for why this parallel form.

use super::pm_common::{
    hash, pack_xy, rand, unpack_xy, Config, Geom, TargetPatch, NONE, SOURCE, TARGET,
};
use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "pm_search",
    wgsl: include_str!("../../wgsl/pm_search.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::ReadWrite,
    ],
    cpu: pm_search_cpu,
};

struct Ctx<'a> {
    g: Geom,
    flags: &'a [u32],
    px: &'a [u32],
}

impl Ctx<'_> {
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn consider(
        &self,
        tp: &mut Option<TargetPatch>,
        x: i32,
        y: i32,
        sx: i32,
        sy: i32,
        best: &mut u32,
        bc: &mut u32,
    ) {
        if !self.g.in_source_box(sx, sy) {
            return;
        }
        let cand = pack_xy(sx as u32, sy as u32);
        if cand == *best || self.flags[(sy * self.g.w + sx) as usize] & SOURCE == 0 {
            return;
        }
        // The unpacked target patch is built on the first candidate that needs it.
        let c = if TargetPatch::fits(&self.g) {
            tp.get_or_insert_with(|| TargetPatch::new(&self.g, self.px, x, y))
                .ssd(&self.g, self.px, sx, sy, *bc)
        } else {
            self.g.ssd(self.px, x, y, sx, sy, *bc)
        };
        if c < *bc {
            *best = cand;
            *bc = c;
        }
    }
}

fn pm_search_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_flags, g_px) = (b[1].get::<u32>(), b[2].get::<u32>());
    let (g_nnf, g_cost) = (b[3].get::<u32>(), b[4].get::<u32>());
    let (nnf_in, cost_in): (&[u32], &[u32]) = (&g_nnf, &g_cost);
    let mut nnf_out = b[5].get_mut::<u32>();
    let mut cost_out = b[6].get_mut::<u32>();
    let ctx = Ctx {
        g: Geom::new(&cfg),
        flags: &g_flags,
        px: &g_px,
    };
    let g = ctx.g;
    let n = (g.w * g.h) as usize;
    nnf_out[..n]
        .par_chunks_mut(g.w as usize)
        .zip(cost_out[..n].par_chunks_mut(g.w as usize))
        .enumerate()
        .for_each(|(y, (nrow, crow))| {
            let y = y as i32;
            for x in 0..g.w {
                let i = (y * g.w + x) as usize;
                if ctx.flags[i] & TARGET == 0 {
                    nrow[x as usize] = NONE;
                    crow[x as usize] = 0;
                    continue;
                }
                let (mut best, mut bc) = (nnf_in[i], cost_in[i]);
                let mut tp = None;
                if cfg.step > 0 {
                    let s = cfg.step as i32;
                    for (dx, dy) in [(-s, 0), (s, 0), (0, -s), (0, s)] {
                        let (qx, qy) = (x + dx, y + dy);
                        if qx < 0 || qy < 0 || qx >= g.w || qy >= g.h {
                            continue;
                        }
                        let qn = nnf_in[(qy * g.w + qx) as usize];
                        if qn == NONE {
                            continue;
                        }
                        let (sx, sy) = unpack_xy(qn);
                        ctx.consider(&mut tp, x, y, sx - dx, sy - dy, &mut best, &mut bc);
                    }
                }
                let (cx, cy) = unpack_xy(best);
                let mut rad = cfg.search_radius as i32;
                let mut k = 0;
                while rad >= 1 {
                    let h1 = rand(cfg.seed, cfg.pass_id, i as u32, k);
                    let h2 = hash(h1);
                    let span = (2 * rad + 1) as u32;
                    let sx = (cx + (h1 % span) as i32 - rad).clamp(g.r, g.w - 1 - g.r);
                    let sy = (cy + (h2 % span) as i32 - rad).clamp(g.r, g.h - 1 - g.r);
                    ctx.consider(&mut tp, x, y, sx, sy, &mut best, &mut bc);
                    rad /= 2;
                    k += 1;
                }
                nrow[x as usize] = best;
                crow[x as usize] = bc;
            }
        });
}
