//! Wexler-style voting of the hole pixels from the field, with the onion-peel mode of the
//! coarsest level; see `wgsl/pm_vote.wgsl`.

use super::pm_common::{pack_rgb, unpack_xy, Config, Geom, HOLE, LAYER_SHIFT, NONE};
use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "pm_vote",
    wgsl: include_str!("../../wgsl/pm_vote.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::ReadWrite,
    ],
    cpu: pm_vote_cpu,
};

struct Ctx<'a> {
    cfg: Config,
    g: Geom,
    flags: &'a [u32],
    cost: &'a [u32],
}

impl Ctx<'_> {
    /// Known pixels of the patch at (x, y) while layer `cfg.layer` is filled.
    fn known_count(&self, x: i32, y: i32) -> u32 {
        let (g, r) = (self.g, self.g.r);
        let mut n = 0;
        for yy in (y - r).max(0)..=(y + r).min(g.h - 1) {
            for xx in (x - r).max(0)..=(x + r).min(g.w - 1) {
                let f = self.flags[(yy * g.w + xx) as usize];
                if f & HOLE == 0 || (f >> LAYER_SHIFT) < self.cfg.layer {
                    n += 1;
                }
            }
        }
        n
    }

    /// (mean SSD per counted pixel, counted pixels) of the patch at q = (x, y).
    fn patch_stats(&self, q: usize, x: i32, y: i32) -> (u32, u32) {
        let mut n = self.g.patch_count(x, y);
        if self.cfg.layer > 0 {
            n = self.known_count(x, y);
            if n == 0 {
                return (u32::MAX, 0);
            }
        }
        (self.cost[q] / n, n)
    }
}

fn pm_vote_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_flags, g_nnf, g_cost) = (b[1].get::<u32>(), b[2].get::<u32>(), b[3].get::<u32>());
    let nnf: &[u32] = &g_nnf;
    let ctx = Ctx {
        cfg,
        g: Geom::new(&cfg),
        flags: &g_flags,
        cost: &g_cost,
    };
    let (w, h, r) = (ctx.g.w, ctx.g.h, ctx.g.r);
    let n = (w * h) as usize;
    // Per-target figures, computed once instead of once per covered hole pixel: the mean
    // SSD m_q and the count it was divided by (NONE-field pixels get u32::MAX).
    let stats: Vec<(u32, u32)> = if cfg.vote_k > 0.0 {
        (0..n)
            .into_par_iter()
            .map(|q| {
                if nnf[q] == NONE {
                    return (u32::MAX, 0);
                }
                ctx.patch_stats(q, (q as i32) % w, (q as i32) / w)
            })
            .collect()
    } else {
        Vec::new()
    };
    // Votes read only source pixels and write only hole pixels (in place on the GPU); here
    // they are gathered first so that the shared read and the writes do not alias.
    let votes: Vec<(usize, [f32; 4])> = {
        let g_rgb = b[4].get::<[f32; 4]>();
        let rgb: &[[f32; 4]] = &g_rgb;
        let (ctx, stats) = (&ctx, &stats);
        (0..h)
            .into_par_iter()
            .flat_map_iter(|y| {
                (0..w).filter_map(move |x| {
                    let i = (y * w + x) as usize;
                    let f = ctx.flags[i];
                    if f & HOLE == 0 || (cfg.layer > 0 && (f >> LAYER_SHIFT) != cfg.layer) {
                        return None;
                    }
                    let (qx0, qx1) = ((x - r).max(0), (x + r).min(w - 1));
                    let (qy0, qy1) = ((y - r).max(0), (y + r).min(h - 1));
                    let mut m_min = u32::MAX;
                    if cfg.vote_k > 0.0 {
                        for qy in qy0..=qy1 {
                            for qx in qx0..=qx1 {
                                let q = (qy * w + qx) as usize;
                                if nnf[q] != NONE {
                                    m_min = m_min.min(stats[q].0);
                                }
                            }
                        }
                    }
                    let mut acc = [0.0f32; 3];
                    let mut wsum = 0.0f32;
                    for qy in qy0..=qy1 {
                        for qx in qx0..=qx1 {
                            let q = (qy * w + qx) as usize;
                            let s = nnf[q];
                            if s == NONE {
                                continue;
                            }
                            let mut wt = 1.0f32;
                            if cfg.vote_k > 0.0 {
                                let (m, cnt) = stats[q];
                                if cnt == 0 {
                                    continue;
                                }
                                wt = (-cfg.vote_k * (m - m_min) as f32).exp();
                                if cfg.layer > 0 {
                                    wt *= cnt as f32 / ctx.g.patch_count(qx, qy) as f32;
                                }
                            }
                            let (sx, sy) = unpack_xy(s);
                            let c = rgb[((sy + y - qy) * w + sx + x - qx) as usize];
                            for k in 0..3 {
                                acc[k] += wt * c[k];
                            }
                            wsum += wt;
                        }
                    }
                    (wsum > 0.0).then(|| {
                        let c = acc.map(|a| a / wsum);
                        (i, [c[0], c[1], c[2], 1.0])
                    })
                })
            })
            .collect()
    };
    let mut rgb = b[4].get_mut::<[f32; 4]>();
    let mut px = b[5].get_mut::<u32>();
    for (i, c) in votes {
        rgb[i] = c;
        px[i] = pack_rgb([c[0], c[1], c[2]]);
    }
}
