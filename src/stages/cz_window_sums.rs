//! Oriented box sums over CZ06's primitive windows and the best energy drop of a curve's
//! first primitive at each birth position (Eq. 24, 26-27); see `wgsl/cz_window_sums.wgsl`.
//! The stencils (digital rotated rectangles as row runs) are built here and uploaded, so
//! both sides read the same table; the host is `crate::sketch::pursuit`.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
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
pub const N_MAPS: usize = 6;
pub const MAP_TXX: usize = 0;
pub const MAP_TXY: usize = 1;
pub const MAP_TYY: usize = 2;
pub const MAP_BASE: usize = 3;
pub const MAP_LLR: usize = 4;
pub const MAP_HAIR: usize = 5;
/// Axis orientations the pass scans (axes k and k + 12 share a window).
pub const ORIENTATIONS: u32 = 12;
/// Side angles π/3, π/2, 2π/3 in 3.75° units; a code's variant indexes this.
pub const PHI_FINE: [i32; 3] = [16, 24, 32];
/// Orientations of the refined lattice over π: 3.75° units.
pub const FINE: i32 = 48;
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
    /// 1: the contrast term scores every kind's pixels (Eq. 21 as printed); 0: only stream
    /// lines' (see `sketch::pursuit::PursuitParams::contrast_all`).
    pub llr_all: u32,
    /// 1: refine side angles by up to ±30° in 3.75° steps; 0: the pure dictionary.
    pub refine: u32,
    pub _pad1: u32,
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

/// Index of a stencil: orientation k (0..12), shape (0: 7×5, 1: 7×6 dividing), side (0
/// left, 1 right).
pub fn stencil_index(k: u32, shape: u32, side: u32) -> usize {
    ((k * 2 + shape) * 2 + side) as usize
}

/// The side a pixel offset falls on, for a window with its centre on a pixel corner:
/// `sketch::prim::classify`, so the stencils are `prim::window`'s pixels exactly. None
/// outside the rectangle or on a dividing line's strip.
fn classify(k: u32, shape: u32, di: i32, dj: i32) -> Option<u32> {
    let axis = k as f32 * AXIS_QUANTUM;
    let (t, n) = ([axis.cos(), axis.sin()], [axis.sin(), -axis.cos()]);
    let d = [di as f32 + 0.5, dj as f32 + 0.5];
    match crate::sketch::prim::classify(shape == 1, t, n, d)? {
        crate::sketch::prim::Side::Left => Some(0),
        crate::sketch::prim::Side::Right => Some(1),
        crate::sketch::prim::Side::Strip => None,
    }
}

/// The stencil table: (runs as (dy, dx0, dx1, 0), per stencil (first run, runs, pixels, 0)).
pub fn stencils() -> (Vec<[i32; 4]>, Vec<[u32; 4]>) {
    const R: i32 = 6;
    let mut runs = Vec::new();
    let mut table = vec![[0u32; 4]; stencil_index(ORIENTATIONS, 0, 0)];
    for k in 0..ORIENTATIONS {
        for shape in 0..2 {
            for side in 0..2 {
                let first = runs.len() as u32;
                let mut pixels = 0u32;
                for dj in -R..=R {
                    let mut run: Option<(i32, i32)> = None;
                    for di in -R..=R {
                        if classify(k, shape, di, dj) == Some(side) {
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
                table[stencil_index(k, shape, side)] =
                    [first, runs.len() as u32 - first, pixels, 0];
            }
        }
    }
    (runs, table)
}

/// (cos 2θ, sin 2θ) of θ = j·3.75° for j in 0..48.
pub fn ztab() -> Vec<[f32; 2]> {
    (0..FINE)
        .map(|j| {
            let a = j as f32 * (std::f32::consts::PI / 24.0);
            [a.cos(), a.sin()]
        })
        .collect()
}

type Sums = [f32; N_MAPS];

/// A side's gain as K + G·z and the orientation maximising it, in 3.75° units.
#[derive(Clone, Copy)]
struct SideFit {
    k: f32,
    g: [f32; 2],
    jstar: f32,
}

fn side_fit(inner: &Sums, llr: bool) -> SideFit {
    let mut k = inner[MAP_BASE] - 0.5 * (inner[MAP_TXX] + inner[MAP_TYY]);
    if llr {
        k += inner[MAP_LLR];
    }
    let g = [-0.5 * (inner[MAP_TXX] - inner[MAP_TYY]), -inner[MAP_TXY]];
    SideFit {
        k,
        g,
        jstar: g[1].atan2(g[0]) * (24.0 / std::f32::consts::PI),
    }
}

/// (gain, r + 8) of a side painting dictionary orientation `base` (3.75° units) refined by
/// sign·r; sign −1 on a left side, +1 on a right side.
fn side_gain(f: &SideFit, base: i32, sign: i32, refine: bool, ztab: &[[f32; 2]]) -> (f32, u32) {
    let mut r = 0i32;
    if refine {
        let mut o = f.jstar - base as f32;
        o -= 48.0 * ((o + 24.0) / 48.0).floor();
        r = ((sign as f32 * o + 0.5).floor() as i32).clamp(-8, 7);
    }
    let j = ((base + sign * r) % FINE + FINE) % FINE;
    let z = ztab[j as usize];
    (f.k + (f.g[0] * z[0] + f.g[1] * z[1]), (r + 8) as u32)
}

fn code_of(axis: u32, kind: u32, variant: u32, l: (f32, u32), r: (f32, u32)) -> u32 {
    axis | (kind << 5) | (variant << 8) | (l.1 << 11) | (r.1 << 15)
}

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

struct Ctx<'a> {
    cfg: Config,
    /// The prefix sums with the maps interleaved: entry (y, x) is `[f32; N_MAPS]`, so one
    /// box-sum row reads two adjacent records instead of 2·N_MAPS scattered floats.
    prefix: &'a [[f32; N_MAPS]],
    runs: &'a [[i32; 4]],
    stencils: &'a [[u32; 4]],
    ztab: &'a [[f32; 2]],
    /// The box every stencil's runs lie in, relative to the centre: [y0, y1] inclusive,
    /// [x0, x1) half-open.
    reach: [i32; 4],
}

impl Ctx<'_> {
    fn box_sums(&self, st: usize, cx: i32, cy: i32) -> Sums {
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
            let row = y as usize * (w as usize + 1);
            let (pb, pa) = (&self.prefix[row + xb], &self.prefix[row + xa]);
            for (m, a) in acc.iter_mut().enumerate() {
                *a += pb[m] - pa[m];
            }
        }
        acc
    }

    fn pixels(&self, st: usize) -> f32 {
        self.stencils[st][2] as f32
    }

    /// The hair pixels in the box [cx + x0, cx + x1) × [cy + y0, cy + y1] that holds every
    /// stencil (`reach`), exact: the hair map's prefix sums are integers below 2^24.
    fn hair_near(&self, cx: i32, cy: i32) -> f32 {
        let (w, h) = (self.cfg.width as i32, self.cfg.height as i32);
        let [y0, y1, x0, x1] = self.reach;
        let xa = (cx + x0).clamp(0, w) as usize;
        let xb = (cx + x1).clamp(0, w) as usize;
        let mut n = 0.0f32;
        for y in (cy + y0).max(0)..=(cy + y1).min(h - 1) {
            let row = y as usize * (w as usize + 1);
            n += self.prefix[row + xb][MAP_HAIR] - self.prefix[row + xa][MAP_HAIR];
        }
        n
    }

    fn position(&self, gx: u32, gy: u32) -> (f32, u32) {
        let cfg = &self.cfg;
        let cx = (gx * cfg.stride + cfg.stride / 2) as i32;
        let cy = (gy * cfg.stride + cfg.stride / 2) as i32;
        // Without hair under any window no kind is allowed here (every rule below asks for
        // some): the answer the full scan gives, without the scan. Most of a portrait's
        // positions are such.
        if cfg.hair_min > 0.0 && self.hair_near(cx, cy) == 0.0 {
            return (NEG, NO_CODE);
        }
        let si = stencil_index;
        let refine = cfg.refine == 1;
        let zt = self.ztab;
        let gain = |f: &SideFit, base: i32, sign: i32| side_gain(f, base, sign, refine, zt);
        let none = (0.0f32, 8u32);
        let mut top = NEG;
        let mut top_code = NO_CODE;
        for k in 0..ORIENTATIONS {
            let a = 4 * k as i32;
            let il = self.box_sums(si(k, 0, 0), cx, cy);
            let ir = self.box_sums(si(k, 0, 1), cx, cy);
            let all = cfg.llr_all == 1;
            let (fl, fr) = (side_fit(&il, all), side_fit(&ir, all));
            let (nl, nr) = (self.pixels(si(k, 0, 0)), self.pixels(si(k, 0, 1)));
            let mut cand = Cands::default();
            if il[MAP_HAIR] >= nl - 0.5 && ir[MAP_HAIR] >= nr - 0.5 {
                let le = gain(&side_fit(&il, true), a, -1);
                let re = gain(&side_fit(&ir, true), a, 1);
                cand.push((le.0 + re.0, code_of(k, 4, 0, le, re)));
                let (l0, r0) = (gain(&fl, a, -1), gain(&fr, a, 1));
                for (f, &p) in PHI_FINE.iter().enumerate() {
                    let f = f as u32;
                    let r1 = gain(&fr, a + p, 1);
                    cand.push((l0.0 + r1.0, code_of(k, 2, f, l0, r1)));
                    let l1 = gain(&fl, a - p, -1);
                    cand.push((l1.0 + r0.0, code_of(k, 2, 3 + f, l1, r0)));
                }
            }
            if il[MAP_HAIR] >= cfg.hair_min * nl && ir[MAP_HAIR] <= cfg.spill * nr {
                let l0 = gain(&fl, a, -1);
                cand.push((l0.0, code_of(k, 0, 0, l0, none)));
                for (f, &p) in PHI_FINE.iter().enumerate() {
                    let l1 = gain(&fl, a - p, -1);
                    cand.push((l1.0, code_of(k, 1, f as u32, l1, none)));
                }
            }
            if ir[MAP_HAIR] >= cfg.hair_min * nr && il[MAP_HAIR] <= cfg.spill * nl {
                let l0 = gain(&fr, a, -1);
                cand.push((l0.0, code_of(k + 12, 0, 0, l0, none)));
                for (f, &p) in PHI_FINE.iter().enumerate() {
                    let l1 = gain(&fr, a - p, -1);
                    cand.push((l1.0, code_of(k + 12, 1, f as u32, l1, none)));
                }
            }
            let jl = self.box_sums(si(k, 1, 0), cx, cy);
            let jr = self.box_sums(si(k, 1, 1), cx, cy);
            let (ml, mr) = (self.pixels(si(k, 1, 0)), self.pixels(si(k, 1, 1)));
            if jl[MAP_HAIR] >= ml - 0.5 && jr[MAP_HAIR] >= mr - 0.5 {
                let (gl, gr) = (side_fit(&jl, all), side_fit(&jr, all));
                for (f, &p) in PHI_FINE.iter().enumerate() {
                    let (l1, r1) = (gain(&gl, a - p, -1), gain(&gr, a + p, 1));
                    cand.push((l1.0 + r1.0, code_of(k, 3, f as u32, l1, r1)));
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
    let (g_prefix, g_runs, g_st, g_ztab) = (
        b[2].get::<f32>(),
        b[3].get::<[i32; 4]>(),
        b[4].get::<[u32; 4]>(),
        b[5].get::<[f32; 2]>(),
    );
    // The shader reads the map-major buffer as it is; the mirror interleaves a copy (the
    // same floats, summed in the same order, so the same results).
    let plane = h * (w + 1);
    let mut prefix = vec![[0.0f32; N_MAPS]; plane];
    let src_all: &[f32] = &g_prefix[..N_MAPS * plane];
    prefix
        .par_chunks_mut(w + 1)
        .enumerate()
        .for_each(|(y, row)| {
            for (m, src) in src_all.chunks(plane).enumerate() {
                for (o, &v) in row.iter_mut().zip(&src[y * (w + 1)..][..w + 1]) {
                    o[m] = v;
                }
            }
        });
    let mut reach = [i32::MAX, i32::MIN, i32::MAX, i32::MIN];
    for e in g_st.iter() {
        for r in &g_runs[e[0] as usize..(e[0] + e[1]) as usize] {
            reach = [
                reach[0].min(r[0]),
                reach[1].max(r[0]),
                reach[2].min(r[1]),
                reach[3].max(r[2]),
            ];
        }
    }
    let ctx = Ctx {
        cfg,
        prefix: &prefix,
        runs: &g_runs,
        stencils: &g_st,
        ztab: &g_ztab,
        reach,
    };
    let (nx, ny) = (cfg.nx as usize, cfg.ny as usize);
    let out: Vec<(f32, u32)> = (0..nx * ny)
        .into_par_iter()
        .map(|o| ctx.position((o % nx) as u32, (o / nx) as u32))
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

    /// The stencils are `prim::window`'s pixels, sides included, at every orientation.
    #[test]
    fn inner_stencils_are_the_windows() {
        let (runs, table) = stencils();
        for k in 0..ORIENTATIONS {
            for (shape, kind) in [(0, Kind::Stream), (1, Kind::Dividing)] {
                let p = Primitive {
                    shift: 0.0,
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
                    let e = table[stencil_index(k, shape, side)];
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
