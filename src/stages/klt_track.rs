//! Pyramidal Lucas–Kanade, one invocation per feature (`crate::video::features::track`).
//! Points are `[x, y, status, residual]` (status 1 tracked, 0 lost); see the shader's header
//! for when a feature is lost.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "klt_track",
    wgsl: include_str!("../../wgsl/klt_track.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: klt_track_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub n_points: u32,
    pub levels: u32,
    /// Level-0 size of both pyramids.
    pub width: u32,
    pub height: u32,
    /// Window half size: the patch is (2 win + 1)².
    pub win: u32,
    pub iters: u32,
    /// Stop a level's iterations once an update is shorter than this (level pixels).
    pub eps: f32,
    pub min_eig: f32,
    /// Lost when λmin < min_iso·λmax at level 0 (edges, stripes).
    pub min_iso: f32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [crate::gpu::engine::groups(cfg.n_points, 64), 1, 1]
}

#[derive(Clone, Copy)]
struct Level {
    w: u32,
    h: u32,
    off: u32,
}

fn level(cfg: &Config, l: u32) -> Level {
    let mut lv = Level {
        w: cfg.width,
        h: cfg.height,
        off: 0,
    };
    for _ in 0..l {
        lv.off += lv.w * lv.h;
        lv.w = lv.w.div_ceil(2);
        lv.h = lv.h.div_ceil(2);
    }
    lv
}

/// Bilinear sample at (x, y), clamp-to-edge.
fn sample(pyr: &[f32], lv: Level, p: [f32; 2]) -> f32 {
    let x = p[0].clamp(0.0, (lv.w - 1) as f32);
    let y = p[1].clamp(0.0, (lv.h - 1) as f32);
    let (x0, y0) = (x.floor(), y.floor());
    let (ix0, iy0) = (x0 as u32, y0 as u32);
    let (ix1, iy1) = ((ix0 + 1).min(lv.w - 1), (iy0 + 1).min(lv.h - 1));
    let (fx, fy) = (x - x0, y - y0);
    let at = |ix: u32, iy: u32| pyr[(lv.off + iy * lv.w + ix) as usize];
    let top = (1.0 - fx) * at(ix0, iy0) + fx * at(ix1, iy0);
    let bot = (1.0 - fx) * at(ix0, iy1) + fx * at(ix1, iy1);
    (1.0 - fy) * top + fy * bot
}

fn grad(pyr: &[f32], lv: Level, q: [f32; 2]) -> [f32; 2] {
    [
        0.5 * (sample(pyr, lv, [q[0] + 1.0, q[1]]) - sample(pyr, lv, [q[0] - 1.0, q[1]])),
        0.5 * (sample(pyr, lv, [q[0], q[1] + 1.0]) - sample(pyr, lv, [q[0], q[1] - 1.0])),
    ]
}

/// Gaussian window weight of sigma win/2, as in `klt_score`.
fn window_weight(cfg: &Config, dx: i32, dy: i32) -> f32 {
    (-2.0 / (cfg.win * cfg.win) as f32 * (dx * dx + dy * dy) as f32).exp()
}

fn finite(v: f32) -> bool {
    v.abs() <= 3.0e38
}

/// One feature, as one shader invocation.
fn track_one(cfg: &Config, tmpl: &[f32], tgt: &[f32], tp: [f32; 4], gs: [f32; 4]) -> [f32; 4] {
    let lost = [
        f32::from_bits(0x7fc0_0000),
        f32::from_bits(0x7fc0_0000),
        0.0,
        0.0,
    ];
    if tp[2] == 0.0
        || gs[2] == 0.0
        || !finite(tp[0])
        || !finite(tp[1])
        || !finite(gs[0])
        || !finite(gs[1])
    {
        return lost;
    }
    let r = cfg.win as i32;
    let mut n = 0.0f32;
    for dy in -r..=r {
        for dx in -r..=r {
            n += window_weight(cfg, dx, dy);
        }
    }
    let top = cfg.levels - 1;
    let scale = (1u32 << top) as f32;
    let mut g = [(gs[0] - tp[0]) / scale, (gs[1] - tp[1]) / scale];
    let mut result = [0.0f32; 2];
    for li in 0..=top {
        let l = top - li;
        let lv = level(cfg, l);
        let s = (1u32 << l) as f32;
        let c = [tp[0] / s, tp[1] / s];
        let (mut gxx, mut gxy, mut gyy) = (0.0f32, 0.0f32, 0.0f32);
        for dy in -r..=r {
            for dx in -r..=r {
                let d = grad(tmpl, lv, [c[0] + dx as f32, c[1] + dy as f32]);
                let wt = window_weight(cfg, dx, dy);
                gxx += wt * d[0] * d[0];
                gxy += wt * d[0] * d[1];
                gyy += wt * d[1] * d[1];
            }
        }
        let h = 0.5 * (gxx - gyy) / n;
        let root = (h * h + (gxy / n) * (gxy / n)).sqrt();
        let lam_min = 0.5 * (gxx + gyy) / n - root;
        let lam_max = 0.5 * (gxx + gyy) / n + root;
        // A NaN eigenvalue counts as flat, as in the shader's `!(a >= b)`.
        if l == 0 && (lam_min.is_nan() || lam_min < cfg.min_eig || lam_min < cfg.min_iso * lam_max)
        {
            return lost;
        }
        let det = gxx * gyy - gxy * gxy;
        let mut v = [0.0f32; 2];
        if lam_min > 0.0 && det > 0.0 {
            for _ in 0..cfg.iters {
                let (mut bx, mut by) = (0.0f32, 0.0f32);
                for dy in -r..=r {
                    for dx in -r..=r {
                        let q = [c[0] + dx as f32, c[1] + dy as f32];
                        let d = grad(tmpl, lv, q);
                        let diff = window_weight(cfg, dx, dy)
                            * (sample(tmpl, lv, q)
                                - sample(tgt, lv, [q[0] + g[0] + v[0], q[1] + g[1] + v[1]]));
                        bx += diff * d[0];
                        by += diff * d[1];
                    }
                }
                let step = [(gyy * bx - gxy * by) / det, (gxx * by - gxy * bx) / det];
                v = [v[0] + step[0], v[1] + step[1]];
                let len = (step[0] * step[0] + step[1] * step[1]).sqrt();
                if len.is_nan() || len < cfg.eps {
                    break;
                }
            }
        }
        if l > 0 {
            g = [2.0 * (g[0] + v[0]), 2.0 * (g[1] + v[1])];
        } else {
            result = [c[0] + g[0] + v[0], c[1] + g[1] + v[1]];
        }
    }
    let w = r as f32;
    let (xmax, ymax) = ((cfg.width - 1) as f32 - w, (cfg.height - 1) as f32 - w);
    if !finite(result[0])
        || !finite(result[1])
        || result[0] < w
        || result[1] < w
        || result[0] > xmax
        || result[1] > ymax
    {
        return lost;
    }
    let lv0 = level(cfg, 0);
    let mut res = 0.0f32;
    for dy in -r..=r {
        for dx in -r..=r {
            let (ox, oy) = (dx as f32, dy as f32);
            res += window_weight(cfg, dx, dy)
                * (sample(tmpl, lv0, [tp[0] + ox, tp[1] + oy])
                    - sample(tgt, lv0, [result[0] + ox, result[1] + oy]))
                .abs();
        }
    }
    [result[0], result[1], 1.0, res / n]
}

fn klt_track_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_tmpl, g_tp, g_tgt, g_gs) = (
        b[1].get::<f32>(),
        b[2].get::<[f32; 4]>(),
        b[3].get::<f32>(),
        b[4].get::<[f32; 4]>(),
    );
    // Plain slices: the RefCell guards are not Sync, the data is.
    let (tmpl, tgt): (&[f32], &[f32]) = (&g_tmpl, &g_tgt);
    let (tp, gs): (&[[f32; 4]], &[[f32; 4]]) = (&g_tp, &g_gs);
    let mut out = b[5].get_mut::<[f32; 4]>();
    out[..cfg.n_points as usize]
        .par_iter_mut()
        .enumerate()
        .for_each(|(i, o)| *o = track_one(&cfg, tmpl, tgt, tp[i], gs[i]));
}
