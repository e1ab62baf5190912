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
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [
        crate::gpu::engine::groups(cfg.width.div_ceil(2), 8),
        crate::gpu::engine::groups(cfg.height, 8),
        1,
    ]
}

/// Rows per parallel band of the CPU mirror.
const BAND: usize = 16;

/// The first x ≥ `lo` of parity `first`.
fn from(lo: usize, first: usize) -> usize {
    lo + ((lo + first) & 1)
}

/// s / |s|, scaled first so tiny weights do not underflow |s|²; (1, 0) for a zero sum.
fn normalise(s: [f32; 2]) -> [f32; 2] {
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
    // shader updates in place. Here bands of rows run in parallel, each in place on its own
    // rows; the row above and the row below a band (other bands' rows, read only at the
    // other colour) come from copies taken first.
    let halo = |y: Option<usize>| -> (Vec<[f32; 2]>, Vec<f32>) {
        match y {
            Some(y) if y < h => (dir[y * w..][..w].to_vec(), wt[y * w..][..w].to_vec()),
            _ => (Vec::new(), Vec::new()),
        }
    };
    let halos: Vec<_> = (0..h.div_ceil(BAND))
        .map(|k| (halo((k * BAND).checked_sub(1)), halo(Some((k + 1) * BAND))))
        .collect();
    dir[..w * h]
        .par_chunks_mut(BAND * w)
        .zip(wt[..w * h].par_chunks_mut(BAND * w))
        .zip(delta[..w * h].par_chunks_mut(BAND * w))
        .zip(halos.par_iter())
        .enumerate()
        .for_each(|(k, (((dir_b, wt_b), delta_b), (up, down)))| {
            let (y0, rows) = (k * BAND, dir_b.len() / w);
            // A neighbour's (vector, weight): in the band, or in a halo row.
            let at = |dir_b: &[[f32; 2]], wt_b: &[f32], x: usize, y: usize| {
                if y + 1 == y0 {
                    (up.0[x], up.1[x])
                } else if y == y0 + rows {
                    (down.0[x], down.1[x])
                } else {
                    let l = (y - y0) * w + x;
                    (dir_b[l], wt_b[l])
                }
            };
            for r in 0..rows {
                let y = y0 + r;
                let (lo, hi) = span[y];
                for x in (from(lo, (y + cfg.colour as usize) & 1)..hi).step_by(2) {
                    let i = y * w + x;
                    let c = kind[i];
                    if c == OFF || c == CLAMPED {
                        continue;
                    }
                    let (mut s, mut sw, mut n) = ([0.0f32; 2], 0.0f32, 0.0f32);
                    let nbrs = [
                        (x > 0).then(|| (x - 1, y)),
                        (x + 1 < w).then_some((x + 1, y)),
                        (y > 0).then(|| (x, y - 1)),
                        (y + 1 < h).then_some((x, y + 1)),
                    ];
                    for (xx, yy) in nbrs.into_iter().flatten() {
                        if kind[yy * w + xx] == OFF {
                            continue;
                        }
                        n += 1.0;
                        let (d, wu) = at(dir_b, wt_b, xx, yy);
                        if wu > 0.0 {
                            sw += wu;
                            s[0] += wu * d[0];
                            s[1] += wu * d[1];
                        }
                    }
                    if n == 0.0 {
                        continue;
                    }
                    let l = r * w + x;
                    let w_old = wt_b[l];
                    let mut d = 0.0f32;
                    if sw > 0.0 {
                        let mut e = normalise(s);
                        if c == AXIS {
                            e = cons[i];
                            if s[0] * e[0] + s[1] * e[1] < 0.0 {
                                e = [-e[0], -e[1]];
                            }
                        }
                        d = if w_old > 0.0 {
                            let old = dir_b[l];
                            ((e[0] - old[0]).powi(2) + (e[1] - old[1]).powi(2)).sqrt()
                        } else {
                            2.0
                        };
                        dir_b[l] = e;
                    }
                    delta_b[l] = d;
                    wt_b[l] = w_old + 0.2 * (sw / n - w_old);
                }
            }
        });
}
