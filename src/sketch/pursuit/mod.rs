//! Sketch pursuit, CZ06 Step 1 (§4.1.2, Eq. 24): the undirected sketch S and the orientation
//! field Θ, greedily. From S = ∅ and Θ diffused without a sketch, the birth of the primitive
//! with the largest energy drop δ starts a curve, which is extended at either end by the best
//! of the candidates STEP px ahead turning −15°, 0 or +15° while that drop is positive; then
//! back to births, until no birth lowers the energy. Θ is diffused again with the sketch
//! clamped every few curves. By default a birth is ranked without λ_NC and the curve pays
//! λ_NC when it is scored whole (`birth_lookahead`): the paper's literal rule, where the
//! first primitive alone must beat λ_NC, never starts a curve along a seam, whose windows
//! each gain little.
//!
//! The energy is E = E1 + E2 + E3 of Eq. 19-22 over the hair,
//!
//! ```text
//! Σ (∇_θ I_H)²/2σθ² + Σ_edges (1 − cos 2Δθ)/2λθ² − Σ_nsk log p_nsk(ρ) − Σ_sk log p_sk(ρ)
//!     + λ_NC N_C + Σ_consecutive (1 − cos 2Δaxis)/4λθ²
//! ```
//!
//! (an edge between two sketch pixels costs nothing; Λ_sk in the contrast terms is the
//! pixels stream lines paint, see `contrast_all`). Adding a primitive fixes the pixels of its
//! window that no primitive took before to its sides' orientations.
//!
//! Scoring. The paper keeps Θ+ ≈ Θ around a new primitive; taken literally (the window's
//! border edges then cost the mismatch between the primitive and a field diffused without
//! it) that rejects exactly the primitives the sketch is for: at an orientation seam Θ∅ is
//! blurred over a few pixels, and a primitive with the two true orientations clashes with
//! the blur around it (on `coif synth` fringe every seam window scored below zero before
//! λ_NC). So candidates are ranked by the paper's approximation (the border edges left as
//! they are: δ = the E1, contrast and inner-edge terms of the window, linear in oriented box
//! sums, Eq. 26-27), and the best few are then scored exactly: the primitive is painted and
//! the free pixels within 6 px of its window relaxed by a few Gauss-Seidel sweeps (the
//! diffusion's own update), and δ is the exact drop of E. An accepted primitive keeps that
//! relaxed field, so every recorded energy is exact and falls with each accepted curve.
//!
//! Births are screened at every position of a lattice by the WGSL pass `cz_window_sums`
//! (the ranking score, best kind and variant per position); the best positions are then
//! scored exactly here, lazily (a score stays valid until a primitive changes pixels near
//! it). The heap, the tracing and the bookkeeping are light, branchy and sequential: they
//! stay on the CPU.
//!
//! Curves live on the lattice `.czs` stores: the start rounded to integer pixel coordinates
//! (sketch coordinates; a pixel's centre is at +0.5), axes on 24 steps of 15°, consecutive
//! axes differing by −1, 0 or +1 step, each centre STEP px from the previous one along its
//! own axis ([`chain`]); side angles the dictionary {0, π/3, π/2, 2π/3} refined by
//! (k − 8)·3.75°, k in 0..16, toward the orientation that fits the window best (the
//! tensor's closed form; off with `refine_sides`). A traced curve is translated so its start
//! is an integer and scored again as placed before it is kept.
//!
//! The contrast priors p_sk / p_nsk are fitted first to the hair's ρ split at a quantile,
//! and (by default) refitted once from the first pursuit's sketch, after which the pursuit
//! runs again from S = ∅ with them.

use super::format::{cos15, sin15};
use super::prim::{self, Side};
use super::rho;
use super::theta::{self, Field, ThetaParams};
use super::{Curve, Kind, Primitive, RhoPrior, AXIS_QUANTUM, AXIS_STEPS, STEP};
use crate::analyze::orient::GrayImage;
use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::stages::cz_theta_gs::{FIXED, FREE, OFF};
use crate::stages::cz_window_sums as ws;
use std::collections::{BinaryHeap, VecDeque};
use std::time::Instant;

mod grow;
mod params;
mod place;
mod score;
pub use params::{Pursuit, PursuitParams, PursuitStats};

/// Primitive centres of a curve from its start and its axes in 15° steps: each centre is
/// the previous one plus STEP along its own axis, in f64 with exact 15° cosines, then
/// rounded to f32 (the `.czs` lattice: a file storing the start and the turns gives these
/// centres back bit for bit).
pub fn chain(start: [f32; 2], axes: &[i32]) -> Vec<[f32; 2]> {
    let (mut x, mut y) = (start[0] as f64, start[1] as f64);
    axes.iter()
        .enumerate()
        .map(|(k, &a)| {
            if k > 0 {
                x += STEP as f64 * cos15(a as i64);
                y += STEP as f64 * sin15(a as i64);
            }
            [x as f32, y as f32]
        })
        .collect()
}

/// The side-angle dictionary of CZ06 §2.1 (`format::SIDE_DICTIONARY_DEG`) in 3.75° units.
const DICT_FINE: [i32; 4] = [0, 16, 24, 32];
/// Refinement codes are 0..16, offsets (code − 8)·3.75°.
const NO_REFINE: u8 = 8;

/// A side angle in radians from its dictionary index and refinement code (the `.czs`
/// decoding: degrees in f64, then f32).
pub fn side_angle(dict: u8, code: u8) -> f32 {
    super::format::side_radians(dict, code)
}

/// The 4-neighbours of pixel i = y·w + x that lie inside the w × h image (left, right, up,
/// down).
fn nbrs4(i: usize, x: usize, y: usize, w: usize, h: usize) -> [Option<usize>; 4] {
    [
        (x > 0).then(|| i - 1),
        (x + 1 < w).then(|| i + 1),
        (y > 0).then(|| i - w),
        (y + 1 < h).then(|| i + w),
    ]
}

/// E3's cost between consecutive primitives whose axes differ by `d` steps, e²/2λθ² with
/// e² = ½(1 − cos 2Δ) (Eq. 22-23), for λθ = 1 (the pursuit scales it by 1/λθ²).
pub fn turn_cost(d: i32) -> f32 {
    0.25 * (1.0 - (2.0 * d as f32 * AXIS_QUANTUM).cos())
}

/// A candidate primitive: kind, centre, axis in 15° steps, and per side the dictionary
/// index and refinement code of its angle.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Cand {
    kind: Kind,
    x: f32,
    y: f32,
    axis: i32,
    dict: [u8; 2],
    code: [u8; 2],
}

impl Cand {
    fn prim(&self) -> Primitive {
        let hair = self.kind.hair_sides();
        Primitive {
            shift: 0.0,
            x: self.x,
            y: self.y,
            axis: self.axis.rem_euclid(AXIS_STEPS as i32) as f32 * AXIS_QUANTUM,
            rho: 0.0,
            side: [0, 1].map(|s| {
                if hair[s] {
                    side_angle(self.dict[s], self.code[s])
                } else {
                    0.0
                }
            }),
        }
    }
}

/// Dictionary pairs a kind may take. An occluding line keeps which of its sides runs along
/// it (`along_left`).
fn variants(kind: Kind, along_left: Option<bool>) -> Vec<[u8; 2]> {
    match kind {
        Kind::Boundary | Kind::Stream => vec![[0, 0]],
        Kind::Source => (1..4).map(|d| [d, 0]).collect(),
        Kind::Dividing => (1..4).map(|d| [d, d]).collect(),
        Kind::Occluding => {
            let mut v = Vec::new();
            for d in 1..4 {
                if along_left != Some(false) {
                    v.push([0, d]);
                }
                if along_left != Some(true) {
                    v.push([d, 0]);
                }
            }
            v
        }
    }
}

/// log p(ρ) tabulated for speed, linear between 4096 samples up to the largest ρ the
/// image can give (the exact mixture beyond). The energy and every δ use the same table.
#[derive(Clone, Debug)]
struct Lut {
    step: f32,
    v: Vec<f32>,
    prior: RhoPrior,
}

impl Lut {
    fn new(prior: RhoPrior, max: f32) -> Lut {
        let n = 4096;
        let step = (max.max(1e-6) * 1.001) / (n - 1) as f32;
        Lut {
            step,
            v: (0..n).map(|i| prior.log_density(i as f32 * step)).collect(),
            prior,
        }
    }

    #[inline]
    fn at(&self, r: f32) -> f32 {
        let t = r / self.step;
        let i = t as usize;
        if i + 1 >= self.v.len() {
            return self.prior.log_density(r);
        }
        let f = t - i as f32;
        self.v[i] + f * (self.v[i + 1] - self.v[i])
    }
}

/// A window's pixels with their sides, and per side (left, right) how many of them are hair
/// and how many the window has in all (outside the image included).
struct Win {
    px: Vec<(u32, Side)>,
    hair: [u32; 2],
    total: [u32; 2],
}

impl Win {
    /// Every side pixel is hair (and inside the image).
    fn inside(&self) -> bool {
        self.hair == self.total
    }

    /// a, b: hair on the left, not on the right.
    fn at_edge(&self, hair_min: f32, spill: f32) -> bool {
        self.hair[0] as f32 >= hair_min * self.total[0] as f32
            && self.hair[1] as f32 <= spill * self.total[1] as f32
    }
}

/// A window's pixels on an integer centre: offsets in raster order with their sides, and
/// per side how many there are.
struct Stencil {
    px: Vec<(i32, i32, Side)>,
    total: [u32; 2],
}

impl Stencil {
    /// One per axis step, from `prim::window` on a blank image large enough to hold it.
    fn all(dividing: bool) -> Vec<Stencil> {
        let kind = if dividing {
            Kind::Dividing
        } else {
            Kind::Stream
        };
        (0..AXIS_STEPS)
            .map(|a| {
                let c = 16;
                let p = Primitive {
                    shift: 0.0,
                    x: c as f32,
                    y: c as f32,
                    axis: a as f32 * AXIS_QUANTUM,
                    rho: 0.0,
                    side: [0.0; 2],
                };
                let mut st = Stencil {
                    px: Vec::new(),
                    total: [0; 2],
                };
                prim::window(kind, &p, 2 * c, 2 * c, |i, s| {
                    let i = i as i32;
                    st.px.push((
                        i % (2 * c as i32) - c as i32,
                        i / (2 * c as i32) - c as i32,
                        s,
                    ));
                    if let Some(k) = s.index() {
                        st.total[k] += 1;
                    }
                });
                st
            })
            .collect()
    }
}

#[derive(Clone, Copy)]
struct Undo {
    i: u32,
    z: [f32; 2],
    fixed: bool,
    skrho: bool,
}

/// A birth position's exact score and candidate (None: nothing allowed there).
type Birth = Option<(f32, Cand)>;

/// A heap entry: δ at a birth position, scored at `stamp` (PROXY: by the window pass).
#[derive(Clone, Copy, Debug)]
struct Entry {
    delta: f32,
    pos: u32,
    stamp: u32,
}

const PROXY: u32 = u32::MAX;

impl PartialEq for Entry {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == std::cmp::Ordering::Equal
    }
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Entry {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        // Larger δ first; ties to the smaller position, so runs are deterministic.
        self.delta
            .total_cmp(&o.delta)
            .then_with(|| o.pos.cmp(&self.pos))
    }
}

/// Cells of the staleness map, pixels; a change marks the cells within 2 of its own, i.e.
/// every birth position within ≥ 16 px: more than the reach of a position's exact score
/// (its window, ≈ 5 px, plus the relaxed margin and the edges leaving it, 7 px).
const CELL: usize = 8;

/// Free pixels within this many px of a new primitive's window are relaxed when it is
/// scored exactly, by this many Gauss-Seidel sweeps.
const RELAX_MARGIN: usize = 6;
const RELAX_SWEEPS: usize = 6;
/// Candidates scored exactly per birth position and per extension step (the best by the
/// ranking score).
const RELAX_BIRTHS: usize = 3;
const RELAX_EXTENSIONS: usize = 2;
/// Birth positions scored at once per thread when the heap's top needs a score (see
/// `pop_best`): enough work per hand-over that waking the threads does not eat the gain.
const SCORE_AHEAD: usize = 4;

/// The search state of one pursuit.
struct Search<'a> {
    f: &'a Field,
    p: &'a PursuitParams,
    sk: Lut,
    nsk: Lut,
    /// Double-angle field: diffused on free pixels, painted on fixed ones.
    z: Vec<[f32; 2]>,
    fixed: Vec<bool>,
    /// Fixed pixels whose contrast is scored by p_sk (the others by p_nsk).
    skrho: Vec<bool>,
    on: Vec<bool>,
    log: Vec<(Undo, bool)>,
    epoch: u32,
    dirty: Vec<u32>,
    cells_x: usize,
    /// (cos 2θ, sin 2θ) of θ = j·3.75°.
    ztab: Vec<[f32; 2]>,
    nx: u32,
    heap: BinaryHeap<Entry>,
    best_at: Vec<Option<Cand>>,
    /// Window stencils on integer centres, per axis: [other kinds, dividing lines].
    stencils: [Vec<Stencil>; 2],
    /// Scores made ahead of their turn (`pop_best`): the epoch and the best birth.
    memo: Vec<Option<(u32, Birth)>>,
    blacklist: Vec<bool>,
    stats: PursuitStats,
}

impl<'a> Search<'a> {
    fn new(
        f: &'a Field,
        p: &'a PursuitParams,
        z: Vec<[f32; 2]>,
        prior: (RhoPrior, RhoPrior),
    ) -> Self {
        let n = f.len();
        let max_rho =
            f.gx.iter()
                .zip(&f.gy)
                .map(|(x, y)| x.hypot(*y))
                .fold(0.0f32, f32::max);
        let (w, h) = (f.width as usize, f.height as usize);
        let cells_x = w.div_ceil(CELL);
        let (nx, ny) = ws::Config::grid(f.width, f.height, p.birth_stride);
        Search {
            f,
            p,
            sk: Lut::new(prior.0, max_rho),
            nsk: Lut::new(prior.1, max_rho),
            z,
            fixed: vec![false; n],
            skrho: vec![false; n],
            on: vec![false; n],
            log: Vec::new(),
            epoch: 0,
            dirty: vec![0; cells_x * h.div_ceil(CELL)],
            cells_x,
            ztab: ws::ztab(),
            nx,
            heap: BinaryHeap::new(),
            best_at: vec![None; (nx * ny) as usize],
            stencils: [false, true].map(Stencil::all),
            memo: vec![None; (nx * ny) as usize],
            blacklist: vec![false; (nx * ny) as usize],
            stats: PursuitStats::default(),
        }
    }

    /// (cos 2θ, sin 2θ) of θ = j·3.75°.
    fn z_of(&self, j: i32) -> [f32; 2] {
        self.ztab[j.rem_euclid(ws::FINE) as usize]
    }

    /// The window of a `kind` primitive with axis `a` (15° steps) centred on the integer
    /// corner (x, y), from the stencils made once: where a window sits on whole pixels its
    /// pixel pattern depends on the axis alone. The same window as [`Self::win`] gives.
    fn win_at(&self, kind: Kind, a: i32, x: i32, y: i32) -> Win {
        let st = &self.stencils[(kind == Kind::Dividing) as usize]
            [a.rem_euclid(AXIS_STEPS as i32) as usize];
        let (w, h) = (self.f.width as i32, self.f.height as i32);
        let mut out = Win {
            px: Vec::with_capacity(st.px.len()),
            hair: [0; 2],
            total: st.total,
        };
        for &(dx, dy, s) in &st.px {
            let (i, j) = (x + dx, y + dy);
            if i < 0 || j < 0 || i >= w || j >= h {
                continue;
            }
            let i = (j * w + i) as usize;
            out.px.push((i as u32, s));
            if let Some(k) = s.index() {
                out.hair[k] += self.f.hair[i] as u32;
            }
        }
        out
    }

    fn win(&self, kind: Kind, p: &Primitive) -> Win {
        let (w, h) = (self.f.width, self.f.height);
        let mut out = Win {
            px: Vec::with_capacity(48),
            hair: [0; 2],
            total: [0; 2],
        };
        prim::window(kind, p, w, h, |i, s| {
            out.px.push((i as u32, s));
            if let Some(k) = s.index() {
                out.total[k] += 1;
                out.hair[k] += self.f.hair[i] as u32;
            }
        });
        // Near the border part of the window is outside the image: count its pixels on a
        // copy moved by whole pixels into a blank image (the same pixel pattern).
        let margin = 7.0;
        if p.x < margin || p.y < margin || p.x > w as f32 - margin || p.y > h as f32 - margin {
            let q = Primitive {
                x: p.x - p.x.floor() + 16.0,
                y: p.y - p.y.floor() + 16.0,
                ..*p
            };
            out.total = [0; 2];
            prim::window(kind, &q, 32, 32, |_, s| {
                if let Some(k) = s.index() {
                    out.total[k] += 1;
                }
            });
        }
        out
    }

    /// Marks the staleness cells around pixel i with the current epoch.
    /// Whether a `kind` primitive's pixels have their contrast scored by p_sk.
    fn sk_kind(&self, kind: Kind) -> bool {
        kind == Kind::Stream || self.p.contrast_all
    }

    fn touch(&mut self, i: usize) {
        let w = self.f.width as usize;
        let (cx, cy) = ((i % w) / CELL, (i / w) / CELL);
        let cells_y = self.dirty.len() / self.cells_x;
        for yy in cy.saturating_sub(2)..(cy + 3).min(cells_y) {
            for xx in cx.saturating_sub(2)..(cx + 3).min(self.cells_x) {
                self.dirty[yy * self.cells_x + xx] = self.epoch;
            }
        }
    }

    /// Paints `win` (pixels not yet taken) with the sides' double-angle vectors `zb` and
    /// sets the relaxed pixels around it; returns the mean ρ on the pixels it fixed.
    fn apply(
        &mut self,
        win: &Win,
        kind: Kind,
        zb: [[f32; 2]; 2],
        relaxed: &[(u32, [f32; 2])],
    ) -> f32 {
        let hair_sides = kind.hair_sides();
        self.epoch += 1;
        let (mut rho, mut n) = (0.0f32, 0u32);
        let mut last_cell = usize::MAX;
        for &(i, s) in &win.px {
            let i = i as usize;
            if self.on[i] {
                continue;
            }
            self.log.push((
                Undo {
                    i: i as u32,
                    z: self.z[i],
                    fixed: self.fixed[i],
                    skrho: self.skrho[i],
                },
                self.on[i],
            ));
            self.on[i] = true;
            if let Some(k) = s.index() {
                if hair_sides[k] && self.f.hair[i] {
                    self.fixed[i] = true;
                    self.skrho[i] = self.sk_kind(kind);
                    self.z[i] = zb[k];
                    rho += self.f.rho(i, zb[k]);
                    n += 1;
                }
            }
            let cell = (i / self.f.width as usize / CELL) * self.cells_x
                + (i % self.f.width as usize) / CELL;
            if cell != last_cell {
                self.touch(i);
                last_cell = cell;
            }
        }
        for &(i, z) in relaxed {
            let i = i as usize;
            self.log.push((
                Undo {
                    i: i as u32,
                    z: self.z[i],
                    fixed: self.fixed[i],
                    skrho: self.skrho[i],
                },
                self.on[i],
            ));
            self.z[i] = z;
            let cell = (i / self.f.width as usize / CELL) * self.cells_x
                + (i % self.f.width as usize) / CELL;
            if cell != last_cell {
                self.touch(i);
                last_cell = cell;
            }
        }
        if n > 0 {
            rho / n as f32
        } else {
            0.0
        }
    }

    /// `curves` with their side refinements and contrasts chosen again by rate and
    /// distortion (`p.bit_cost`, [`super::format::rate_sides`], [`super::format::rate_rho`]),
    /// the field painted again where a side changed, so that Θ, solved next, and the stored
    /// codes agree. Ownership as the painting has it (the fill's).
    fn rate_codes(&mut self, curves: Vec<Curve>) -> Vec<Curve> {
        if self.p.bit_cost <= 0.0 {
            return curves;
        }
        let f = self.f;
        let (w, h) = (f.width, f.height);
        let mut rated = if self.p.refine_sides {
            let sums = super::format::side_sums(&curves, w, h, &f.data, &f.hair);
            super::format::rate_sides(&curves, w, h, &sums, self.p.bit_cost)
        } else {
            curves.clone()
        };
        let mut on = vec![false; f.len()];
        let mut stats: super::format::RhoStats = Vec::with_capacity(rated.len());
        for (c, old) in rated.iter_mut().zip(&curves) {
            let hs = c.kind.hair_sides();
            let mut cs = Vec::with_capacity(c.prims.len());
            for (p, q) in c.prims.iter_mut().zip(&old.prims) {
                let changed = p.side != q.side;
                let z = [0, 1].map(|s| theta::to_z(p.side_angle(s)));
                let (mut n, mut sum, mut sum2) = (0u32, 0.0f64, 0.0f64);
                prim::window(c.kind, p, w, h, |i, side| {
                    if std::mem::replace(&mut on[i], true) {
                        return;
                    }
                    if let Some(k) = side.index() {
                        if hs[k] && f.hair[i] && self.fixed[i] {
                            if changed {
                                self.z[i] = z[k];
                            }
                            let r = f.rho(i, z[k]) as f64;
                            n += 1;
                            sum += r;
                            sum2 += r * r;
                        }
                    }
                });
                let mean = if n > 0 { sum / n as f64 } else { 0.0 };
                if changed && n > 0 {
                    p.rho = mean as f32;
                }
                let var = if n > 0 {
                    (sum2 / n as f64 - mean * mean).max(0.0)
                } else {
                    0.0
                };
                cs.push([n as f32, mean as f32, var as f32]);
            }
            stats.push(cs);
        }
        self.stats.sides_rated = rated
            .iter()
            .zip(&curves)
            .flat_map(|(a, b)| a.prims.iter().zip(&b.prims))
            .filter(|(p, q)| p.side != q.side)
            .count();
        if !self.p.rate_contrast {
            return rated;
        }
        let before: Vec<f32> = rated
            .iter()
            .flat_map(|c| c.prims.iter().map(|p| p.rho))
            .collect();
        rated = super::format::rate_rho(&rated, &stats, self.p.bit_cost);
        self.stats.rho_rated = rated
            .iter()
            .flat_map(|c| &c.prims)
            .zip(&before)
            .filter(|(p, &r)| super::format::quantise_rho(r) != p.rho)
            .count();
        rated
    }

    /// Undoes every change after log position `to`.
    fn undo_to(&mut self, to: usize) {
        self.epoch += 1;
        while self.log.len() > to {
            let (u, on) = self.log.pop().expect("log is longer than `to`");
            let i = u.i as usize;
            self.z[i] = u.z;
            self.fixed[i] = u.fixed;
            self.skrho[i] = u.skrho;
            self.on[i] = on;
            self.touch(i);
        }
    }

    /// One pursuit from S = ∅.
    fn run(&mut self, engine: &Engine) -> Result<(Vec<Curve>, f64, Vec<f64>)> {
        let mut curves: Vec<Curve> = Vec::new();
        let e0 = self.energy(&curves);
        let mut energy = Vec::new();
        let mut since = 0;
        self.screen(engine)?;
        let mut t_search = 0.0;
        let mut t_mark = Instant::now();
        while curves.len() < self.p.max_curves {
            let t = Instant::now();
            let best = self.pop_best();
            self.stats.seconds_births += t.elapsed().as_secs_f64();
            let Some((_, birth, pos)) = best else {
                break;
            };
            self.stats.births += 1;
            let t = Instant::now();
            let traced = self.trace(birth);
            self.stats.seconds_traces += t.elapsed().as_secs_f64();
            match traced {
                Some((c, _)) => {
                    curves.push(c);
                    energy.push(self.energy(&curves));
                    since += 1;
                }
                None => self.blacklist[pos as usize] = true,
            }
            if since >= self.p.rebuild_every as usize {
                since = 0;
                t_search += t_mark.elapsed().as_secs_f64();
                self.rediffuse(engine)?;
                self.screen(engine)?;
                t_mark = Instant::now();
            }
        }
        t_search += t_mark.elapsed().as_secs_f64();
        self.stats.seconds_search += t_search;
        Ok((curves, e0, energy))
    }
}

/// λ_NC N_C + λ_B N_B + the turn costs of E3.
fn curve_energy(curves: &[Curve], p: &PursuitParams, smooth: f32) -> f64 {
    let mut e = p.lambda_nc as f64 * curves.len() as f64;
    for c in curves {
        e += p.lambda_b as f64 * c.prims.len() as f64;
        for pair in c.prims.windows(2) {
            let d = (pair[1].axis - pair[0].axis) / AXIS_QUANTUM;
            e += (smooth * turn_cost(d.round() as i32)) as f64;
        }
    }
    e
}

/// Runs `cz_window_sums` on `maps` (N_MAPS × w·h, see the stage) and returns per birth
/// position the best δ (−3e38 where nothing is allowed) and its code.
pub fn window_pass(
    engine: &Engine,
    f: &Field,
    maps: &[f32],
    p: &PursuitParams,
) -> Result<(Vec<f32>, Vec<u32>)> {
    let (w, h) = (f.width, f.height);
    let (nx, ny) = ws::Config::grid(w, h, p.birth_stride);
    let cfg = |mode| ws::Config {
        width: w,
        height: h,
        mode,
        stride: p.birth_stride,
        nx,
        ny,
        lambda_nc: birth_cost(p),
        spill: p.spill,
        hair_min: p.hair_min,
        refine: p.refine_sides as u32,
        llr_all: p.contrast_all as u32,
        ..Default::default()
    };
    let (runs, table) = ws::stencils();
    let mut rec = Recording::default();
    let sentinel = crate::base::sentinel::SENTINEL;
    let mb = rec.upload("coif.cz_window.maps", maps);
    let pb = rec.alloc(
        "coif.cz_window.prefix",
        4 * ws::N_MAPS as u64 * h as u64 * (w as u64 + 1),
        sentinel,
    );
    let rb = rec.upload("coif.cz_window.runs", &runs);
    let sb = rec.upload("coif.cz_window.stencils", &table);
    let tb = rec.upload("coif.cz_window.ztab", &ws::ztab());
    let best = rec.alloc("coif.cz_window.best", 4 * nx as u64 * ny as u64, sentinel);
    let code = rec.alloc("coif.cz_window.code", 4 * nx as u64 * ny as u64, sentinel);
    for mode in [0, 1] {
        let c = cfg(mode);
        let u = rec.uniform("coif.cz_window.cfg", &c);
        rec.dispatch(
            &ws::STAGE,
            ws::workgroups(&c),
            &[u, mb, pb, rb, sb, tb, best, code],
            &[],
        );
    }
    rec.download(best);
    rec.download(code);
    let dl = engine.run(rec)?;
    let n = (nx * ny) as usize;
    Ok((
        dl.get::<f32>(best)[..n].to_vec(),
        dl.get::<u32>(code)[..n].to_vec(),
    ))
}

/// Sketch pursuit: `high` the high band I_H (L* units), `hair` the mask,
/// `theta0` the warm start (coif's Gabor orientation, `crate::analyze::orient::orient`,
/// NaN allowed where it has none). σθ² is `p.theta.sigma2` or its maximum-likelihood value
/// under `theta0`.
pub fn pursue(
    engine: &Engine,
    high: &GrayImage,
    hair: &[bool],
    theta0: &[f32],
    p: &PursuitParams,
) -> Result<Pursuit> {
    p.validate()?;
    let (width, height) = (high.width, high.height);
    let high = &high.data;
    let n = width as usize * height as usize;
    if theta0.len() != n || high.len() != n || hair.len() != n {
        return Err(Error::Invalid(format!(
            "pursuit: the image is {width}x{height} ({n} pixels) but the band has {}, the mask \
             {} and the warm start {} values",
            high.len(),
            hair.len(),
            theta0.len()
        )));
    }
    if !hair.iter().any(|&h| h) {
        return Err(Error::Invalid("pursuit: the hair mask is empty".into()));
    }
    let mut stats = PursuitStats::default();
    let sigma2 = match p.theta.sigma2 {
        Some(s) => s,
        None => {
            let (gx, gy) = theta::gradients(high, width, height, hair);
            theta::sigma2_mle(&gx, &gy, hair, theta0)?
        }
    };
    let f = Field::new(high, width, height, hair, sigma2, p.theta.lambda_theta)?;
    // Θ∅: the diffusion without a sketch.
    let t = Instant::now();
    let fl0 = theta::flags(hair, None);
    let z_init = theta::initial_z(&f, theta0, None, &fl0);
    let empty = theta::solve(engine, &f, &fl0, z_init, p.theta.max_sweeps, &p.theta)?;
    stats.sweeps_empty = empty.sweeps;
    stats.seconds_theta += t.elapsed().as_secs_f64();
    let rho_empty = rho::rho_field(&f.gx, &f.gy, &theta::theta_of(&empty.z, &fl0));
    let mut prior = rho::fit_split(&rho_empty, hair, width, height, p.split_quantile)?;
    let passes = if p.refit { 2 } else { 1 };
    let mut out = None;
    for pass in 0..passes {
        let mut s = Search::new(&f, p, empty.z.clone(), prior);
        let (curves, e0, energy) = s.run(engine)?;
        // Birth order reordered as `.czs` stores it best, with the same painting (every
        // pair of overlapping curves keeps its order).
        let curves = super::format::paint_order(curves, width, height);
        let curves = s.shift_occluding(curves);
        let curves = s.rate_codes(curves);
        // The final Θ: diffused to convergence with the sketch clamped.
        let t = Instant::now();
        let fl = s.flags();
        let solved = theta::solve(engine, &f, &fl, s.z.clone(), p.theta.max_sweeps, &p.theta)?;
        s.stats.seconds_theta += t.elapsed().as_secs_f64();
        for (i, &fv) in fl.iter().enumerate() {
            if fv == FREE {
                s.z[i] = solved.z[i];
            }
        }
        s.stats.passes = 1;
        stats.add(&s.stats);
        stats.sweeps_final = solved.sweeps;
        let energy_final = s.energy(&curves);
        let theta = theta::theta_of(&s.z, &fl);
        let rho = rho::rho_field(&f.gx, &f.gy, &theta);
        if pass + 1 < passes {
            let on: Vec<bool> = (0..s.fixed.len())
                .map(|i| s.fixed[i] && s.skrho[i])
                .collect();
            prior = rho::fit_sets(&rho, hair, &on, prior)?;
        }
        out = Some(Pursuit {
            curves,
            theta,
            rho,
            rho_on: prior.0,
            rho_off: prior.1,
            sigma2,
            energy_empty: e0,
            energy,
            energy_final,
            stats: PursuitStats::default(),
        });
    }
    let mut out = out.expect("at least one pass runs");
    log::debug!(
        "pursuit: {} births traced ({} exact birth scores, {} of them made ahead and used, \
         {:.1} s), {} extension steps and {} placements ({:.1} s traces), {:.1} s \
         diffusion, {:.1} s window pass",
        stats.births,
        stats.exact_births,
        stats.memo_hits,
        stats.seconds_births,
        stats.extensions,
        stats.placements,
        stats.seconds_traces,
        stats.seconds_theta,
        stats.seconds_windows
    );
    out.stats = stats;
    Ok(out)
}

/// What a birth must pay up front: λ_NC as the paper writes it, nothing with the look-ahead
/// (the curve pays λ_NC when it is finished).
fn birth_cost(p: &PursuitParams) -> f32 {
    if p.birth_lookahead {
        p.lambda_b
    } else {
        p.lambda_nc + p.lambda_b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chain_steps_along_each_axis() {
        let c = chain([10.0, 20.0], &[0, 0, 1, 0, -1, -24]);
        assert_eq!(c[0], [10.0, 20.0]);
        assert_eq!(c[1], [15.0, 20.0]);
        let a = AXIS_QUANTUM as f64;
        assert!((c[2][0] as f64 - (15.0 + 5.0 * a.cos())).abs() < 1e-5);
        assert!((c[2][1] as f64 - (20.0 + 5.0 * a.sin())).abs() < 1e-5);
        for k in 1..c.len() {
            let d = ((c[k][0] - c[k - 1][0]).powi(2) + (c[k][1] - c[k - 1][1]).powi(2)).sqrt();
            assert!((d - STEP).abs() < 1e-4);
        }
        // Axis −24 is axis 0 a turn later: the same step.
        assert!((c[5][0] - c[4][0] - 5.0).abs() < 1e-5);
    }

    #[test]
    fn side_angles_are_the_dictionary_plus_refinement() {
        assert_eq!(side_angle(0, NO_REFINE), 0.0);
        assert!((side_angle(2, NO_REFINE) - std::f32::consts::FRAC_PI_2).abs() < 1e-7);
        assert!((side_angle(0, 0) + 30f32.to_radians()).abs() < 1e-6);
        assert!((side_angle(3, 15) - (120.0f32 + 26.25).to_radians()).abs() < 1e-6);
    }

    #[test]
    fn stencil_windows_are_the_windows() {
        let (w, h) = (23u32, 17u32);
        let n = (w * h) as usize;
        let high: Vec<f32> = (0..n).map(|i| ((i * 7919) % 13) as f32).collect();
        let hair: Vec<bool> = (0..n).map(|i| (i * 31) % 7 != 0).collect();
        let f = Field::new(&high, w, h, &hair, 1.0, 1.0).unwrap();
        let p = PursuitParams::default();
        let prior = RhoPrior {
            weight: [0.5; 2],
            mean: [1.0, 4.0],
            sigma: [1.0; 2],
        };
        let s = Search::new(&f, &p, vec![[1.0, 0.0]; n], (prior, prior));
        for kind in [Kind::Stream, Kind::Dividing, Kind::Boundary] {
            for a in -2..AXIS_STEPS as i32 + 2 {
                for y in 0..=h as i32 {
                    for x in 0..=w as i32 {
                        let c = Cand {
                            kind,
                            x: x as f32,
                            y: y as f32,
                            axis: a,
                            dict: [1, 1],
                            code: [NO_REFINE; 2],
                        };
                        let (u, v) = (s.win_at(kind, a, x, y), s.win(kind, &c.prim()));
                        assert_eq!(u.px, v.px, "{kind:?} axis {a} at ({x}, {y})");
                        assert_eq!((u.hair, u.total), (v.hair, v.total));
                    }
                }
            }
        }
    }

    #[test]
    fn turn_cost_is_e_squared_over_two() {
        assert_eq!(turn_cost(0), 0.0);
        let e2 = 0.5 * (1.0 - (2.0 * AXIS_QUANTUM).cos());
        assert!((turn_cost(1) - 0.5 * e2).abs() < 1e-7);
        assert_eq!(turn_cost(1), turn_cost(-1));
    }

    #[test]
    fn params_validate() {
        assert!(PursuitParams::default().validate().is_ok());
        for bad in [
            PursuitParams {
                lambda_nc: -1.0,
                ..Default::default()
            },
            PursuitParams {
                birth_stride: 0,
                ..Default::default()
            },
            PursuitParams {
                min_prims: 5,
                max_prims: 4,
                ..Default::default()
            },
            PursuitParams {
                split_quantile: 1.0,
                ..Default::default()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
