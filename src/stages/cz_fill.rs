//! One red-black half-sweep of CZ06's fill-in of the vector field from the sketch (§3.1,
//! Eq. 16-17): nonlinear Gauss-Seidel on the angle, τ_v = arg Σ_{u∈∂v} w(u) e^{iτ_u}, with the
//! growing weight schedule w_v ← w_v + 0.2 (mean_{u∈∂v} w(u) − w_v). The angles are held as
//! unit vectors e^{iτ}, so a pixel costs a weighted sum and a normalisation, no trigonometry.
//! See `wgsl/cz_fill.wgsl`; the host is `crate::sketch::fill`.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "cz_fill",
    wgsl: include_str!("../../wgsl/cz_fill.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::ReadWrite,
        Bind::ReadWrite,
    ],
    cpu: cz_fill_cpu,
};

/// Pixel classes (the `kind` binding).
pub const OFF: u32 = 0;
pub const FREE: u32 = 1;
pub const CLAMPED: u32 = 2;
/// Orientation known, direction free: the vector is `cons` or −`cons`.
pub const AXIS: u32 = 3;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// Which pixels this half-sweep updates: those with (x + y) & 1 == colour.
    pub colour: u32,
    /// 1: the angles are doubled orientations 2θ; 0: directions τ.
    pub doubled: u32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [
        crate::gpu::engine::groups(cfg.width.div_ceil(2), 8),
        crate::gpu::engine::groups(cfg.height, 8),
        1,
    ]
}

/// The first x ≥ `lo` of parity `first`.
fn from(lo: usize, first: usize) -> usize {
    lo + ((lo + first) & 1)
}

/// s / |s|, scaled first so tiny weights do not underflow |s|²; (1, 0) for a zero sum.
pub fn unit(s: [f32; 2]) -> [f32; 2] {
    let m = s[0].abs().max(s[1].abs());
    if m > 0.0 {
        let t = [s[0] / m, s[1] / m];
        let l = (t[0] * t[0] + t[1] * t[1]).sqrt();
        [t[0] / l, t[1] / l]
    } else {
        [1.0, 0.0]
    }
}

fn cz_fill_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_kind, g_cons) = (b[1].get::<u32>(), b[2].get::<[f32; 2]>());
    let (kind, cons): (&[u32], &[[f32; 2]]) = (&g_kind, &g_cons);
    let mut dir = b[3].get_mut::<[f32; 2]>();
    let mut wt = b[4].get_mut::<f32>();
    let mut delta = b[5].get_mut::<f32>();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    // Each row's span of domain pixels: nothing outside it is read or written.
    let span: Vec<(usize, usize)> = kind[..w * h]
        .par_chunks(w)
        .map(|r| match r.iter().position(|&c| c != OFF) {
            Some(lo) => (lo, w - r.iter().rev().position(|&c| c != OFF).unwrap_or(0)),
            None => (0, 0),
        })
        .collect();
    // Only this colour's pixels are written and only the other colour's are read, so the
    // shader updates in place; here the reads come from copies so rows can run in parallel.
    let wt_src = wt[..w * h].to_vec();
    let dir_src = dir[..w * h].to_vec();
    dir[..w * h]
        .par_chunks_mut(w)
        .zip(wt[..w * h].par_chunks_mut(w))
        .zip(delta[..w * h].par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, ((dir_row, wt_row), delta_row))| {
            let (lo, hi) = span[y];
            for x in (from(lo, (y + cfg.colour as usize) & 1)..hi).step_by(2) {
                let i = y * w + x;
                let c = kind[i];
                if c == OFF || c == CLAMPED {
                    continue;
                }
                let (mut s, mut sw, mut n) = ([0.0f32; 2], 0.0f32, 0.0f32);
                let mut gather = |j: usize| {
                    if kind[j] == OFF {
                        return;
                    }
                    n += 1.0;
                    let wu = wt_src[j];
                    if wu > 0.0 {
                        let [c, sn] = dir_src[j];
                        sw += wu;
                        s[0] += wu * c;
                        s[1] += wu * sn;
                    }
                };
                if x > 0 {
                    gather(i - 1);
                }
                if x + 1 < w {
                    gather(i + 1);
                }
                if y > 0 {
                    gather(i - w);
                }
                if y + 1 < h {
                    gather(i + w);
                }
                if n == 0.0 {
                    continue;
                }
                let w_old = wt_row[x];
                let mut d = 0.0f32;
                if sw > 0.0 {
                    let mut e = unit(s);
                    if c == AXIS {
                        e = cons[i];
                        if s[0] * e[0] + s[1] * e[1] < 0.0 {
                            e = [-e[0], -e[1]];
                        }
                    }
                    d = if w_old > 0.0 {
                        let old = dir_row[x];
                        ((e[0] - old[0]).powi(2) + (e[1] - old[1]).powi(2)).sqrt()
                    } else {
                        2.0
                    };
                    dir_row[x] = e;
                }
                delta_row[x] = d;
                wt_row[x] = w_old + 0.2 * (sw / n - w_old);
            }
        });
}
