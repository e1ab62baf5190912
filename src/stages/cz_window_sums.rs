//! Oriented box sums over CZ06's primitive windows and the best energy drop of a curve's
//! first primitive at each birth position (Eq. 24, 26-27); see `wgsl/cz_window_sums.wgsl`.
//! The stencils (digital rotated rectangles as row runs) are built here and uploaded, so
//! both sides read the same table; the host is `crate::sketch::pursuit`.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use crate::sketch::prim::{ACROSS, ACROSS_DIVIDING, ALONG, STRIP};
use crate::sketch::AXIS_QUANTUM;
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "cz_window_sums",
    wgsl: include_str!("../../wgsl/cz_window_sums.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::ReadWrite,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::ReadWrite,
    ],
    cpu: cz_window_sums_cpu,
};

/// Per-pixel maps the pass sums, in this order (see the shader's header).
pub const N_MAPS: usize = 9;
pub const MAP_TXX: usize = 0;
pub const MAP_TXY: usize = 1;
pub const MAP_TYY: usize = 2;
pub const MAP_BASE: usize = 3;
pub const MAP_HAIR: usize = 4;
pub const MAP_RING_N: usize = 5;
pub const MAP_RING_C: usize = 6;
pub const MAP_RING_S: usize = 7;
pub const MAP_RING_OLD: usize = 8;
/// First map the ring (outer window) sums need.
const RING_FIRST: usize = MAP_RING_N;
/// Axis orientations the pass scans (axes k and k + 12 share a window).
pub const ORIENTATIONS: u32 = 12;
/// Side angles π/3, π/2, 2π/3 in 15° steps; a code's variant indexes this.
pub const PHI_STEPS: [u32; 3] = [4, 6, 8];
/// δ where no primitive is allowed.
pub const NEG: f32 = -3.0e38;
/// Code where no primitive is allowed.
pub const NO_CODE: u32 = u32::MAX;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// 0: prefix sums of the maps; 1: windows.
    pub mode: u32,
    /// Birth positions every `stride` pixels, at (i·stride + stride/2, j·stride + stride/2).
    pub stride: u32,
    pub nx: u32,
    pub ny: u32,
    pub lambda_nc: f32,
    pub spill: f32,
    pub hair_min: f32,
    /// 1/λθ², the weight of the smoothness terms.
    pub smooth: f32,
    pub _pad1: u32,
    pub _pad2: u32,
}

impl Config {
    /// Birth positions along x and y for `stride`.
    pub fn grid(width: u32, height: u32, stride: u32) -> (u32, u32) {
        (width.div_ceil(stride), height.div_ceil(stride))
    }
}

/// Workgroups: mode 0 runs one invocation per (row, map), mode 1 one per birth position.
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    use crate::gpu::engine::groups;
    if cfg.mode == 0 {
        [groups(cfg.height, 8), groups(N_MAPS as u32, 8), 1]
    } else {
        [groups(cfg.nx, 8), groups(cfg.ny, 8), 1]
    }
}

/// Index of a stencil: orientation k (0..12), shape (0: 7×5, 1: 7×6 dividing), outer (0:
/// the window, 1: one pixel larger each way), side (0 left, 1 right).
pub fn stencil_index(k: u32, shape: u32, outer: u32, side: u32) -> usize {
    (((k * 2 + shape) * 2 + outer) * 2 + side) as usize
}

/// The side a pixel offset falls on, for a window with its centre on a pixel corner: the
/// same arithmetic as `sketch::prim::window`, so the inner stencils are its pixels exactly.
/// None outside the rectangle; Some(2) on a dividing line's strip.
fn classify(k: u32, shape: u32, outer: u32, di: i32, dj: i32) -> Option<u32> {
    let axis = k as f32 * AXIS_QUANTUM;
    let (t, n) = ([axis.cos(), axis.sin()], [axis.sin(), -axis.cos()]);
    let across = if shape == 1 { ACROSS_DIVIDING } else { ACROSS };
    let grow = outer as f32;
    let (ha, hc) = (0.5 * ALONG + grow, 0.5 * across + grow);
    let (dx, dy) = (di as f32 + 0.5, dj as f32 + 0.5);
    let a = dx * t[0] + dy * t[1];
    let c = dx * n[0] + dy * n[1];
    if a.abs() >= ha || c.abs() >= hc {
        return None;
    }
    if shape == 1 && c.abs() < STRIP {
        return Some(2);
    }
    Some(if c >= 0.0 { 0 } else { 1 })
}

/// The stencil table: (runs as (dy, dx0, dx1, 0), per stencil (first run, runs, pixels,
/// ring weight bits)). A ring weight is the number of 4-neighbour edges from the side's
/// window pixels to pixels outside the window, per pixel of the side's ring (outer minus
/// inner), so ring sums approximate sums over the border edges.
pub fn stencils() -> (Vec<[i32; 4]>, Vec<[u32; 4]>) {
    const R: i32 = 8;
    let mut runs = Vec::new();
    let mut table = vec![[0u32; 4]; stencil_index(ORIENTATIONS, 0, 0, 0)];
    for k in 0..ORIENTATIONS {
        for shape in 0..2 {
            let inner = |di: i32, dj: i32| classify(k, shape, 0, di, dj);
            for outer in 0..2 {
                for side in 0..2 {
                    let first = runs.len() as u32;
                    let mut pixels = 0u32;
                    for dj in -R..=R {
                        let mut run: Option<(i32, i32)> = None;
                        for di in -R..=R {
                            let inside = classify(k, shape, outer, di, dj) == Some(side);
                            if inside {
                                pixels += 1;
                                run = Some(match run {
                                    Some((a, _)) => (a, di + 1),
                                    None => (di, di + 1),
                                });
                            } else if let Some((a, b)) = run.take() {
                                runs.push([dj, a, b, 0]);
                            }
                        }
                        if let Some((a, b)) = run {
                            runs.push([dj, a, b, 0]);
                        }
                    }
                    let weight = if outer == 1 {
                        let mut edges = 0u32;
                        let mut ring = 0u32;
                        for dj in -R..=R {
                            for di in -R..=R {
                                if inner(di, dj) == Some(side) {
                                    for (ei, ej) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                                        edges += inner(di + ei, dj + ej).is_none() as u32;
                                    }
                                } else if inner(di, dj).is_none()
                                    && classify(k, shape, 1, di, dj) == Some(side)
                                {
                                    ring += 1;
                                }
                            }
                        }
                        edges as f32 / ring.max(1) as f32
                    } else {
                        0.0
                    };
                    table[stencil_index(k, shape, outer, side)] =
                        [first, runs.len() as u32 - first, pixels, weight.to_bits()];
                }
            }
        }
    }
    (runs, table)
}

/// (cos, sin) of j·15° for j in 0..24.
pub fn trig() -> Vec<[f32; 2]> {
    (0..24)
        .map(|j| {
            let a = j as f32 * AXIS_QUANTUM;
            [a.cos(), a.sin()]
        })
        .collect()
}

type Sums = [f32; N_MAPS];

/// The candidates of one orientation (at most 18), without a heap allocation.
struct Cands {
    v: [(f32, u32); 24],
    n: usize,
}

impl Default for Cands {
    fn default() -> Self {
        Cands {
            v: [(0.0, 0); 24],
            n: 0,
        }
    }
}

impl Cands {
    fn push(&mut self, c: (f32, u32)) {
        self.v[self.n] = c;
        self.n += 1;
    }
}

fn gain(inner: &Sums, ring: [f32; 4], w: f32, smooth: f32, t: [f32; 2]) -> f32 {
    let (c, s) = (t[0], t[1]);
    let q = c * c * inner[MAP_TXX] + 2.0 * c * s * inner[MAP_TXY] + s * s * inner[MAP_TYY];
    let c2 = c * c - s * s;
    let s2 = 2.0 * c * s;
    let ring_new = 0.5 * (ring[0] - (ring[1] * c2 + ring[2] * s2));
    inner[MAP_BASE] - q - w * (smooth * ring_new - ring[3])
}

fn ring_of(inner: &Sums, outer: &Sums) -> [f32; 4] {
    [
        outer[5] - inner[5],
        outer[6] - inner[6],
        outer[7] - inner[7],
        outer[8] - inner[8],
    ]
}

struct Ctx<'a> {
    cfg: Config,
    prefix: &'a [f32],
    runs: &'a [[i32; 4]],
    stencils: &'a [[u32; 4]],
}

impl Ctx<'_> {
    fn box_sums(&self, st: usize, cx: i32, cy: i32, m0: usize) -> Sums {
        let mut acc = [0.0f32; N_MAPS];
        let e = self.stencils[st];
        let (w, h) = (self.cfg.width as i32, self.cfg.height as usize);
        for q in 0..e[1] {
            let r = self.runs[(e[0] + q) as usize];
            let y = cy + r[0];
            if y < 0 || y >= h as i32 {
                continue;
            }
            let xa = (cx + r[1]).clamp(0, w) as usize;
            let xb = (cx + r[2]).clamp(0, w) as usize;
            if xb <= xa {
                continue;
            }
            for (m, a) in acc.iter_mut().enumerate().skip(m0) {
                let row = (m * h + y as usize) * (w as usize + 1);
                *a += self.prefix[row + xb] - self.prefix[row + xa];
            }
        }
        acc
    }

    fn weight(&self, st: usize) -> f32 {
        f32::from_bits(self.stencils[st][3])
    }

    fn pixels(&self, st: usize) -> f32 {
        self.stencils[st][2] as f32
    }

    fn position(&self, gx: u32, gy: u32, trig: &[[f32; 2]]) -> (f32, u32) {
        let cfg = &self.cfg;
        let cx = (gx * cfg.stride + cfg.stride / 2) as i32;
        let cy = (gy * cfg.stride + cfg.stride / 2) as i32;
        let si = stencil_index;
        let mut top = NEG;
        let mut top_code = NO_CODE;
        for k in 0..ORIENTATIONS {
            let t0 = trig[k as usize];
            let il = self.box_sums(si(k, 0, 0, 0), cx, cy, 0);
            let ir = self.box_sums(si(k, 0, 0, 1), cx, cy, 0);
            let rl = ring_of(&il, &self.box_sums(si(k, 0, 1, 0), cx, cy, RING_FIRST));
            let rr = ring_of(&ir, &self.box_sums(si(k, 0, 1, 1), cx, cy, RING_FIRST));
            let (wl, wr) = (self.weight(si(k, 0, 1, 0)), self.weight(si(k, 0, 1, 1)));
            let (nl, nr) = (self.pixels(si(k, 0, 0, 0)), self.pixels(si(k, 0, 0, 1)));
            let mut cand = Cands::default();
            if il[MAP_HAIR] >= nl - 0.5 && ir[MAP_HAIR] >= nr - 0.5 {
                cand.push((
                    gain(&il, rl, wl, cfg.smooth, t0) + gain(&ir, rr, wr, cfg.smooth, t0),
                    k | (4 << 5),
                ));
                for (f, &p) in PHI_STEPS.iter().enumerate() {
                    let f = f as u32;
                    cand.push((
                        gain(&il, rl, wl, cfg.smooth, t0)
                            + gain(&ir, rr, wr, cfg.smooth, trig[((k + p) % 24) as usize]),
                        k | (2 << 5) | (f << 8),
                    ));
                    cand.push((
                        gain(&il, rl, wl, cfg.smooth, trig[((k + 24 - p) % 24) as usize])
                            + gain(&ir, rr, wr, cfg.smooth, t0),
                        k | (2 << 5) | ((3 + f) << 8),
                    ));
                }
            }
            if il[MAP_HAIR] >= cfg.hair_min * nl && ir[MAP_HAIR] <= cfg.spill * nr {
                cand.push((gain(&il, rl, wl, cfg.smooth, t0), k));
                for (f, &p) in PHI_STEPS.iter().enumerate() {
                    cand.push((
                        gain(&il, rl, wl, cfg.smooth, trig[((k + 24 - p) % 24) as usize]),
                        k | (1 << 5) | ((f as u32) << 8),
                    ));
                }
            }
            if ir[MAP_HAIR] >= cfg.hair_min * nr && il[MAP_HAIR] <= cfg.spill * nl {
                cand.push((gain(&ir, rr, wr, cfg.smooth, t0), k + 12));
                for (f, &p) in PHI_STEPS.iter().enumerate() {
                    cand.push((
                        gain(&ir, rr, wr, cfg.smooth, trig[((k + 24 - p) % 24) as usize]),
                        (k + 12) | (1 << 5) | ((f as u32) << 8),
                    ));
                }
            }
            let jl = self.box_sums(si(k, 1, 0, 0), cx, cy, 0);
            let jr = self.box_sums(si(k, 1, 0, 1), cx, cy, 0);
            let (ml, mr) = (self.pixels(si(k, 1, 0, 0)), self.pixels(si(k, 1, 0, 1)));
            if jl[MAP_HAIR] >= ml - 0.5 && jr[MAP_HAIR] >= mr - 0.5 {
                let sl = ring_of(&jl, &self.box_sums(si(k, 1, 1, 0), cx, cy, RING_FIRST));
                let sr = ring_of(&jr, &self.box_sums(si(k, 1, 1, 1), cx, cy, RING_FIRST));
                let (vl, vr) = (self.weight(si(k, 1, 1, 0)), self.weight(si(k, 1, 1, 1)));
                for (f, &p) in PHI_STEPS.iter().enumerate() {
                    cand.push((
                        gain(&jl, sl, vl, cfg.smooth, trig[((k + 24 - p) % 24) as usize])
                            + gain(&jr, sr, vr, cfg.smooth, trig[((k + p) % 24) as usize]),
                        k | (3 << 5) | ((f as u32) << 8),
                    ));
                }
            }
            for &(g, c) in &cand.v[..cand.n] {
                let d = g - cfg.lambda_nc;
                if d > top {
                    top = d;
                    top_code = c;
                }
            }
        }
        (top, top_code)
    }
}

fn cz_window_sums_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    if cfg.mode == 0 {
        let g_maps = b[1].get::<f32>();
        let maps: &[f32] = &g_maps;
        let mut prefix = b[2].get_mut::<f32>();
        prefix[..N_MAPS * h * (w + 1)]
            .par_chunks_mut(w + 1)
            .enumerate()
            .for_each(|(r, out)| {
                // Row r of the prefix buffer is row r % h of map r / h.
                let src = &maps[(r / h) * w * h + (r % h) * w..][..w];
                let mut acc = 0.0f32;
                out[0] = 0.0;
                for (o, &v) in out[1..].iter_mut().zip(src) {
                    acc += v;
                    *o = acc;
                }
            });
        return;
    }
    let (g_prefix, g_runs, g_st, g_trig) = (
        b[2].get::<f32>(),
        b[3].get::<[i32; 4]>(),
        b[4].get::<[u32; 4]>(),
        b[5].get::<[f32; 2]>(),
    );
    let ctx = Ctx {
        cfg,
        prefix: &g_prefix,
        runs: &g_runs,
        stencils: &g_st,
    };
    let trig: &[[f32; 2]] = &g_trig;
    let (nx, ny) = (cfg.nx as usize, cfg.ny as usize);
    let out: Vec<(f32, u32)> = (0..nx * ny)
        .into_par_iter()
        .map(|o| ctx.position((o % nx) as u32, (o / nx) as u32, trig))
        .collect();
    let mut best = b[6].get_mut::<f32>();
    let mut code = b[7].get_mut::<u32>();
    for (o, (d, c)) in out.into_iter().enumerate() {
        best[o] = d;
        code[o] = c;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sketch::{prim, Kind, Primitive};

    /// The inner stencils are `prim::window`'s pixels, sides included, at every orientation.
    #[test]
    fn inner_stencils_are_the_windows() {
        let (runs, table) = stencils();
        for k in 0..ORIENTATIONS {
            for (shape, kind) in [(0, Kind::Stream), (1, Kind::Dividing)] {
                let p = Primitive {
                    x: 20.0,
                    y: 20.0,
                    axis: k as f32 * AXIS_QUANTUM,
                    rho: 0.0,
                    side: [0.0; 2],
                };
                let mut want = [Vec::new(), Vec::new()];
                prim::window(kind, &p, 40, 40, |i, s| {
                    if let Some(s) = s.index() {
                        want[s].push(i);
                    }
                });
                for side in 0..2u32 {
                    let e = table[stencil_index(k, shape, 0, side)];
                    let mut got = Vec::new();
                    for r in &runs[e[0] as usize..(e[0] + e[1]) as usize] {
                        for di in r[1]..r[2] {
                            got.push(((20 + r[0]) * 40 + 20 + di) as usize);
                        }
                    }
                    got.sort();
                    want[side as usize].sort();
                    assert_eq!(got, want[side as usize], "k {k} shape {shape} side {side}");
                    assert_eq!(e[2] as usize, got.len());
                }
            }
        }
    }
}
