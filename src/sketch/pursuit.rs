//! Sketch pursuit, CZ06 Step 1 (§4.1.2, Eq. 24): the undirected sketch S and the orientation
//! field Θ, greedily. From S = ∅ and Θ diffused without a sketch, the birth of the primitive
//! with the largest energy drop δ starts a curve, which is extended at either end by the best
//! of the candidates STEP px ahead turning −15°, 0 or +15° while that drop is positive; then
//! back to births, until no birth lowers the energy. Θ+ ≈ Θ while a primitive is scored (the
//! paper's approximation); Θ is diffused again with the sketch clamped every few curves.
//!
//! The energy is E = E1 + E2 + E3 of Eq. 19-22 over the hair:
//!   Σ (∇_θ I_H)²/2σθ² + Σ_edges (1 − cos 2Δθ)/2λθ² − Σ_nsk log p_nsk(ρ) − Σ_sk log p_sk(ρ)
//!   + λ_NC N_C + Σ_consecutive (1 − cos 2Δaxis)/4λθ²
//! (an edge between two sketch pixels costs nothing, Λ_sk the pixels whose flow the
//! sketch paints). Adding a primitive fixes the pixels of its window that no primitive took
//! before to its sides' orientations, so its δ is a sum over those pixels and the edges
//! leaving them. Births are screened on all positions of a lattice by the WGSL pass
//! `cz_window_sums` (oriented box sums of per-pixel maps, δ linear in them, with the window
//! border approximated by a ring); the best candidates are then scored exactly here, pixel
//! by pixel, lazily (a score stays valid until a primitive changes pixels near it), and only
//! exact scores decide. The heap, the tracing and the bookkeeping are light, branchy and
//! sequential: they stay on the CPU.
//!
//! Curves live on the lattice `.czs` stores: the start rounded to integer pixel coordinates
//! (sketch coordinates; a pixel's centre is at +0.5), axes on 24 steps of 15°, consecutive
//! axes differing by −1, 0 or +1 step, centres chained by [`chain`]. A traced curve is
//! translated so its start is an integer and scored again as placed before it is kept.
//!
//! The contrast priors p_sk / p_nsk are fitted first to the hair's ρ split at a quantile,
//! and (by default) refitted once from the first pursuit's sketch, after which the pursuit
//! runs again from S = ∅ with them.

use super::prim::{self, Side};
use super::rho;
use super::theta::{self, Field, ThetaParams};
use super::{Curve, Kind, Primitive, RhoPrior, AXIS_QUANTUM, AXIS_STEPS, STEP};
use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::stages::cz_theta_gs::{FIXED, FREE, OFF};
use crate::stages::cz_window_sums as ws;
use std::collections::{BinaryHeap, VecDeque};
use std::time::Instant;

/// Parameters of the pursuit. The paper publishes none (they were learned from hand sketches
/// it does not release); the defaults are ours, see each field.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PursuitParams {
    /// λ_NC, the cost of a curve (Eq. 22), in units of the per-pixel energies. Default 30
    /// (the reading notes' proposal; see the module tests for the curve counts it gives).
    pub lambda_nc: f32,
    /// Θ is diffused again, and births screened again, after this many new curves. Default 4.
    pub rebuild_every: u32,
    /// Sweeps of a re-diffusion (warm from the current field; the convergence test of
    /// `theta` applies). Default 60.
    pub rebuild_sweeps: u32,
    /// Curves with fewer primitives are dropped. Default 3.
    pub min_prims: usize,
    /// Longest curve, in primitives. Default 120.
    pub max_prims: usize,
    /// Most curves. Default 400.
    pub max_curves: usize,
    /// Births are screened every `birth_stride` px in x and y. Default 2.
    pub birth_stride: u32,
    /// a, b: the share of their non-hair side's pixels that may be hair. Default 0.25.
    pub spill: f32,
    /// a, b: the least share of their hair side's pixels that must be hair. Default 0.5.
    pub hair_min: f32,
    /// Before any sketch, p_sk is fitted to the ρ above this quantile of the hair's ρ and
    /// p_nsk to those below. Default 0.8.
    pub split_quantile: f32,
    /// Refit p_sk and p_nsk from the first pursuit's sketch and pursue again. Default true.
    pub refit: bool,
    /// The diffusion of Θ∅ and of the final Θ.
    pub theta: ThetaParams,
}

impl Default for PursuitParams {
    fn default() -> Self {
        PursuitParams {
            lambda_nc: 30.0,
            rebuild_every: 4,
            rebuild_sweeps: 60,
            min_prims: 3,
            max_prims: 120,
            max_curves: 400,
            birth_stride: 2,
            spill: 0.25,
            hair_min: 0.5,
            split_quantile: 0.8,
            refit: true,
            theta: ThetaParams::default(),
        }
    }
}

impl PursuitParams {
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("pursuit: {m}")));
        if !(self.lambda_nc.is_finite() && self.lambda_nc >= 0.0) {
            return bad(format!("lambda_nc {} must be a number ≥ 0", self.lambda_nc));
        }
        if self.rebuild_every == 0 {
            return bad("rebuild_every must be at least 1".into());
        }
        if self.rebuild_sweeps == 0 || self.rebuild_sweeps > 100_000 {
            return bad(format!(
                "rebuild_sweeps {} must be in 1..=100000",
                self.rebuild_sweeps
            ));
        }
        if self.min_prims == 0 || self.max_prims < self.min_prims || self.max_prims > 10_000 {
            return bad(format!(
                "need 1 ≤ min_prims ({}) ≤ max_prims ({}) ≤ 10000",
                self.min_prims, self.max_prims
            ));
        }
        if self.max_curves > 100_000 {
            return bad(format!("max_curves {} is over 100000", self.max_curves));
        }
        if !(1..=16).contains(&self.birth_stride) {
            return bad(format!(
                "birth_stride {} must be in 1..=16",
                self.birth_stride
            ));
        }
        for (name, v) in [("spill", self.spill), ("hair_min", self.hair_min)] {
            if !(0.0..=1.0).contains(&v) {
                return bad(format!("{name} {v} must be in [0, 1]"));
            }
        }
        if !(self.split_quantile > 0.0 && self.split_quantile < 1.0) {
            return bad(format!(
                "split_quantile {} must be in (0, 1)",
                self.split_quantile
            ));
        }
        self.theta.validate()
    }
}

/// Counts and times of a pursuit.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PursuitStats {
    /// Pursuits run (2 with the refit).
    pub passes: u32,
    /// Births traced (kept or dropped), over all passes.
    pub births: u32,
    /// Curves dropped for having fewer than `min_prims` primitives.
    pub dropped_short: u32,
    /// Curves dropped because, moved onto the integer start, they no longer lowered E.
    pub dropped_snapped: u32,
    /// Re-diffusions of Θ with the sketch clamped.
    pub rebuilds: u32,
    /// Runs of the `cz_window_sums` pass.
    pub window_runs: u32,
    /// Birth positions scored exactly (all kinds, axes and variants at once).
    pub exact_births: u64,
    /// Sweeps of Θ∅, and of the final Θ.
    pub sweeps_empty: u32,
    pub sweeps_final: u32,
    /// Wall time in the diffusions, the window pass, and the CPU search, seconds.
    pub seconds_theta: f64,
    pub seconds_windows: f64,
    pub seconds_search: f64,
}

/// The result of a pursuit.
#[derive(Clone, Debug)]
pub struct Pursuit {
    /// Undirected curves (dirs all 0: directions are Step 2), on the lattice.
    pub curves: Vec<Curve>,
    /// Θ in [0, π) diffused with the sketch clamped; NaN off the hair.
    pub theta: Vec<f32>,
    /// ρ = |∇⊥Θ I_H| under `theta`; NaN off the hair.
    pub rho: Vec<f32>,
    /// p_sk and p_nsk the final pursuit used.
    pub rho_on: RhoPrior,
    pub rho_off: RhoPrior,
    /// σθ² (Eq. 20).
    pub sigma2: f32,
    /// E(Θ∅, ∅) of the final pursuit, then E after each accepted curve (Fig. 13).
    pub energy_empty: f64,
    pub energy: Vec<f64>,
    /// E with the final Θ.
    pub energy_final: f64,
    pub stats: PursuitStats,
}

/// Primitive centres of a curve from its start and its axes in lattice steps (unwrapped:
/// consecutive ones differ by −1, 0 or +1): c_{i+1} = c_i + STEP (cos m, sin m) with m the
/// mean of the two axes, a_i + ½ (a_{i+1} − a_i) steps. f32 arithmetic in this order, so a
/// file storing the start and the turns gives back these centres bit for bit.
pub fn chain(start: [f32; 2], axes: &[i32]) -> Vec<[f32; 2]> {
    let mut out = Vec::with_capacity(axes.len());
    let mut c = start;
    for (i, &a) in axes.iter().enumerate() {
        if i > 0 {
            let prev = axes[i - 1];
            let m = (prev as f32 + 0.5 * (a - prev) as f32) * AXIS_QUANTUM;
            c = [c[0] + STEP * m.cos(), c[1] + STEP * m.sin()];
        }
        out.push(c);
    }
    out
}

/// E3's cost between consecutive primitives whose axes differ by `d` steps, e²/2λθ² with
/// e² = ½(1 − cos 2Δ) (Eq. 22-23), for λθ = 1 (the pursuit scales it by 1/λθ²).
pub fn turn_cost(d: i32) -> f32 {
    0.25 * (1.0 - (2.0 * d as f32 * AXIS_QUANTUM).cos())
}

/// Side angles of the dictionary (π/3, π/2, 2π/3) in lattice steps.
const PHI: [i32; 3] = [4, 6, 8];

/// A candidate primitive: kind, centre, axis and side angles in lattice steps.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Cand {
    kind: Kind,
    x: f32,
    y: f32,
    axis: i32,
    sides: [i32; 2],
}

impl Cand {
    fn prim(&self) -> Primitive {
        Primitive {
            x: self.x,
            y: self.y,
            axis: self.axis.rem_euclid(AXIS_STEPS as i32) as f32 * AXIS_QUANTUM,
            rho: 0.0,
            side: self.sides.map(|s| s as f32 * AXIS_QUANTUM),
        }
    }
}

/// Side variants a kind may take, as side angles in steps. An occluding line keeps which of
/// its sides runs along it (`along_left`).
fn variants(kind: Kind, along_left: Option<bool>) -> Vec<[i32; 2]> {
    match kind {
        Kind::Boundary | Kind::Stream => vec![[0, 0]],
        Kind::Source => PHI.iter().map(|&p| [p, 0]).collect(),
        Kind::Dividing => PHI.iter().map(|&p| [p, p]).collect(),
        Kind::Occluding => {
            let mut v = Vec::new();
            for &p in &PHI {
                if along_left != Some(false) {
                    v.push([0, p]);
                }
                if along_left != Some(true) {
                    v.push([p, 0]);
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

#[derive(Clone, Copy)]
struct Undo {
    i: u32,
    z: [f32; 2],
    fixed: bool,
}

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
/// every birth position within ≥ 16 px, more than a window's reach (≈ 5 px) plus the edges
/// leaving it plus the window of a position scored there (≈ 5 px).
const CELL: usize = 8;

/// The search state of one pursuit.
struct Search<'a> {
    f: &'a Field,
    p: &'a PursuitParams,
    sk: Lut,
    nsk: Lut,
    /// Double-angle field: diffused on free pixels, painted on fixed ones.
    z: Vec<[f32; 2]>,
    fixed: Vec<bool>,
    on: Vec<bool>,
    log: Vec<(Undo, bool)>,
    epoch: u32,
    dirty: Vec<u32>,
    cells_x: usize,
    mark: Vec<u32>,
    gen: u32,
    /// (cos, sin) of j·15°.
    trig: Vec<[f32; 2]>,
    nx: u32,
    heap: BinaryHeap<Entry>,
    best_at: Vec<Option<Cand>>,
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
            on: vec![false; n],
            log: Vec::new(),
            epoch: 0,
            dirty: vec![0; cells_x * h.div_ceil(CELL)],
            cells_x,
            mark: vec![0; n],
            gen: 0,
            trig: ws::trig(),
            nx,
            heap: BinaryHeap::new(),
            best_at: vec![None; (nx * ny) as usize],
            blacklist: vec![false; (nx * ny) as usize],
            stats: PursuitStats::default(),
        }
    }

    /// (cos 2θ, sin 2θ) of θ = j·15°.
    fn z_of(&self, j: i32) -> [f32; 2] {
        self.trig[(2 * j).rem_euclid(24) as usize]
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

    /// Exact δ (before λ_NC or the turn cost) of painting `win` as a `kind` primitive with
    /// axis `a` and side angles `sides` (steps), Θ elsewhere unchanged.
    fn delta(&mut self, win: &Win, kind: Kind, a: i32, sides: [i32; 2]) -> f32 {
        let f = self.f;
        let hair_sides = kind.hair_sides();
        let zb = [self.z_of(a - sides[0]), self.z_of(a + sides[1])];
        self.gen = self.gen.wrapping_add(1);
        let gen = self.gen;
        for &(i, s) in &win.px {
            let i = i as usize;
            if let Some(k) = s.index() {
                if hair_sides[k] && f.hair[i] && !self.on[i] {
                    self.mark[i] = gen;
                }
            }
        }
        let (w, h) = (f.width as usize, f.height as usize);
        let mut d = 0.0f32;
        for &(i, s) in &win.px {
            let i = i as usize;
            if self.mark[i] != gen {
                continue;
            }
            let zn = zb[s.index().expect("marked pixels lie on a side")];
            let zo = self.z[i];
            d += f.e1(i, zo) - f.e1(i, zn);
            d += self.sk.at(f.rho(i, zn)) - self.nsk.at(f.rho(i, zo));
            let (x, y) = (i % w, i / w);
            let nbrs = [
                (x > 0).then(|| i - 1),
                (x + 1 < w).then(|| i + 1),
                (y > 0).then(|| i - w),
                (y + 1 < h).then(|| i + w),
            ];
            for j in nbrs.into_iter().flatten() {
                if !f.hair[j] {
                    continue;
                }
                let zj = self.z[j];
                let old = f.edge(zj, zo);
                if self.mark[j] == gen {
                    // Both ends join the sketch: the edge stops costing; count it once.
                    if j > i {
                        d += old;
                    }
                } else {
                    let new = if self.fixed[j] { 0.0 } else { f.edge(zj, zn) };
                    d += old - new;
                }
            }
        }
        d
    }

    /// Marks the staleness cells around pixel i with the current epoch.
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

    /// Paints `win` (pixels not yet taken); returns the mean ρ on the pixels it fixed.
    fn apply(&mut self, win: &Win, kind: Kind, a: i32, sides: [i32; 2]) -> f32 {
        let hair_sides = kind.hair_sides();
        let zb = [self.z_of(a - sides[0]), self.z_of(a + sides[1])];
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
                },
                self.on[i],
            ));
            self.on[i] = true;
            if let Some(k) = s.index() {
                if hair_sides[k] && self.f.hair[i] {
                    self.fixed[i] = true;
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
        if n > 0 {
            rho / n as f32
        } else {
            0.0
        }
    }

    /// Undoes every change after log position `to`.
    fn undo_to(&mut self, to: usize) {
        self.epoch += 1;
        while self.log.len() > to {
            let (u, on) = self.log.pop().expect("log is longer than `to`");
            let i = u.i as usize;
            self.z[i] = u.z;
            self.fixed[i] = u.fixed;
            self.on[i] = on;
            self.touch(i);
        }
    }

    /// The exact best birth at integer corner (x, y): δ − λ_NC over every kind, axis and
    /// side variant the mask allows there.
    fn best_birth(&mut self, x: i32, y: i32) -> Option<(f32, Cand)> {
        let mut best: Option<(f32, Cand)> = None;
        let (hair_min, spill, lambda) = (self.p.hair_min, self.p.spill, self.p.lambda_nc);
        let consider = |d: f32, c: Cand, best: &mut Option<(f32, Cand)>| {
            if best.is_none_or(|(b, _)| d > b) {
                *best = Some((d, c));
            }
        };
        for a in 0..AXIS_STEPS as i32 {
            let mk = |kind, sides| Cand {
                kind,
                x: x as f32,
                y: y as f32,
                axis: a,
                sides,
            };
            let w5 = self.win(Kind::Stream, &mk(Kind::Stream, [0, 0]).prim());
            if w5.at_edge(hair_min, spill) {
                for kind in [Kind::Boundary, Kind::Source] {
                    for s in variants(kind, None) {
                        let d = self.delta(&w5, kind, a, s) - lambda;
                        consider(d, mk(kind, s), &mut best);
                    }
                }
            }
            // c, d, e look the same from either end: half the axes suffice.
            if a >= AXIS_STEPS as i32 / 2 {
                continue;
            }
            if w5.inside() {
                for kind in [Kind::Stream, Kind::Occluding] {
                    for s in variants(kind, None) {
                        let d = self.delta(&w5, kind, a, s) - lambda;
                        consider(d, mk(kind, s), &mut best);
                    }
                }
            }
            let w6 = self.win(Kind::Dividing, &mk(Kind::Dividing, [0, 0]).prim());
            if w6.inside() {
                for s in variants(Kind::Dividing, None) {
                    let d = self.delta(&w6, Kind::Dividing, a, s) - lambda;
                    consider(d, mk(Kind::Dividing, s), &mut best);
                }
            }
        }
        self.stats.exact_births += 1;
        best
    }

    /// Whether the mask allows `kind` with this window.
    fn allowed(&self, kind: Kind, w: &Win) -> bool {
        match kind {
            Kind::Boundary | Kind::Source => w.at_edge(self.p.hair_min, self.p.spill),
            _ => w.inside(),
        }
    }

    fn corner(&self, pos: u32) -> (i32, i32) {
        let s = self.p.birth_stride;
        (
            ((pos % self.nx) * s + s / 2) as i32,
            ((pos / self.nx) * s + s / 2) as i32,
        )
    }

    fn fresh(&self, e: &Entry) -> bool {
        if e.stamp == PROXY {
            return false;
        }
        let (x, y) = self.corner(e.pos);
        let w = self.f.width as usize;
        let h = self.f.height as usize;
        let (cx, cy) = (
            (x as usize).min(w - 1) / CELL,
            (y as usize).min(h - 1) / CELL,
        );
        self.dirty[cy * self.cells_x + cx] <= e.stamp
    }

    /// The best birth by exact δ (lazily: stale scores are refreshed until the top is
    /// fresh); None when no position has a positive score.
    fn pop_best(&mut self) -> Option<(f32, Cand, u32)> {
        while let Some(e) = self.heap.pop() {
            if e.delta <= 0.0 {
                return None;
            }
            if self.blacklist[e.pos as usize] {
                continue;
            }
            if self.fresh(&e) {
                let c = self.best_at[e.pos as usize].expect("fresh entries were scored");
                return Some((e.delta, c, e.pos));
            }
            let (x, y) = self.corner(e.pos);
            if let Some((d, c)) = self.best_birth(x, y) {
                self.best_at[e.pos as usize] = Some(c);
                self.heap.push(Entry {
                    delta: d,
                    pos: e.pos,
                    stamp: self.epoch,
                });
            }
        }
        None
    }

    /// The best extension of a curve at either end: (δ − turn cost, candidate, at the end).
    fn best_extension(&mut self, curve: &VecDeque<Cand>) -> Option<(f32, Cand, bool)> {
        let (w, h) = (self.f.width as f32, self.f.height as f32);
        let first = curve[0];
        let along_left = (first.kind == Kind::Occluding).then_some(first.sides[0] == 0);
        let vars = variants(first.kind, along_left);
        let mut best: Option<(f32, Cand, bool)> = None;
        for at_end in [true, false] {
            let end = if at_end {
                *curve.back().expect("a curve has a primitive")
            } else {
                first
            };
            for turn in -1..=1 {
                // Ahead: the new axis is end + turn and the step follows the mean axis;
                // behind: the new primitive's axis turns into the end's.
                let (axis, m, sign) = if at_end {
                    (end.axis + turn, end.axis as f32 + 0.5 * turn as f32, 1.0)
                } else {
                    (end.axis - turn, end.axis as f32 - 0.5 * turn as f32, -1.0)
                };
                let m = m * AXIS_QUANTUM;
                let (x, y) = (end.x + sign * STEP * m.cos(), end.y + sign * STEP * m.sin());
                if !(0.0..=w).contains(&x) || !(0.0..=h).contains(&y) {
                    continue;
                }
                let c0 = Cand {
                    kind: first.kind,
                    x,
                    y,
                    axis,
                    sides: vars[0],
                };
                let win = self.win(first.kind, &c0.prim());
                if !self.allowed(first.kind, &win) {
                    continue;
                }
                for &s in &vars {
                    let d = self.delta(&win, first.kind, axis, s) - self.f.smooth * turn_cost(turn);
                    if best.as_ref().is_none_or(|b| d > b.0) {
                        best = Some((d, Cand { sides: s, ..c0 }, at_end));
                    }
                }
            }
        }
        best
    }

    /// Traces a curve from a birth, then places it on the lattice and scores it as placed.
    /// Returns the kept curve and its δ, or None (the state is then as before).
    fn trace(&mut self, birth: Cand) -> Option<(Curve, f32)> {
        let mark = self.log.len();
        let mut curve = VecDeque::from([birth]);
        let w0 = self.win(birth.kind, &birth.prim());
        self.apply(&w0, birth.kind, birth.axis, birth.sides);
        while curve.len() < self.p.max_prims {
            let Some((d, c, at_end)) = self.best_extension(&curve) else {
                break;
            };
            if d <= 0.0 {
                break;
            }
            let win = self.win(c.kind, &c.prim());
            self.apply(&win, c.kind, c.axis, c.sides);
            if at_end {
                curve.push_back(c);
            } else {
                curve.push_front(c);
            }
        }
        self.undo_to(mark);
        if curve.len() < self.p.min_prims {
            self.stats.dropped_short += 1;
            return None;
        }
        // On the lattice: integer start, centres chained from it.
        let axes: Vec<i32> = curve.iter().map(|c| c.axis).collect();
        let start = [curve[0].x.round(), curve[0].y.round()];
        let centres = chain(start, &axes);
        let mut prims = Vec::with_capacity(curve.len());
        let mut delta = -self.p.lambda_nc;
        for (k, (c, xy)) in curve.iter().zip(&centres).enumerate() {
            let c = Cand {
                x: xy[0],
                y: xy[1],
                ..*c
            };
            let win = self.win(c.kind, &c.prim());
            delta += self.delta(&win, c.kind, c.axis, c.sides);
            if k > 0 {
                delta -= self.f.smooth * turn_cost(c.axis - axes[k - 1]);
            }
            let rho = self.apply(&win, c.kind, c.axis, c.sides);
            prims.push(Primitive { rho, ..c.prim() });
        }
        if delta <= 0.0 {
            self.undo_to(mark);
            self.stats.dropped_snapped += 1;
            return None;
        }
        // Accepted: nothing of it will be undone.
        self.log.clear();
        Some((
            Curve {
                kind: birth.kind,
                prims,
                dirs: [0, 0],
            },
            delta,
        ))
    }

    /// The per-pixel maps of the window pass for the current state.
    fn maps(&self) -> Vec<f32> {
        let f = self.f;
        let n = f.len();
        let (w, h) = (f.width as usize, f.height as usize);
        let mut m = vec![0.0f32; ws::N_MAPS * n];
        let k = 1.0 / (2.0 * f.sigma2);
        for i in 0..n {
            if !f.hair[i] {
                continue;
            }
            let (x, y) = (i % w, i / w);
            let zi = self.z[i];
            let (mut sm, mut deg) = (0.0f32, 0u32);
            for j in [
                (x > 0).then(|| i - 1),
                (x + 1 < w).then(|| i + 1),
                (y > 0).then(|| i - w),
                (y + 1 < h).then(|| i + w),
            ]
            .into_iter()
            .flatten()
            {
                if !f.hair[j] {
                    continue;
                }
                deg += 1;
                if !(self.fixed[i] && self.fixed[j]) {
                    sm += f.edge(zi, self.z[j]);
                }
            }
            if !self.on[i] {
                let (gx, gy) = (f.gx[i], f.gy[i]);
                m[ws::MAP_TXX * n + i] = gx * gx * k;
                m[ws::MAP_TXY * n + i] = gx * gy * k;
                m[ws::MAP_TYY * n + i] = gy * gy * k;
                let r = f.rho(i, zi);
                m[ws::MAP_BASE * n + i] = f.e1(i, zi) + 0.5 * sm + self.sk.at(r) - self.nsk.at(r);
            }
            m[ws::MAP_HAIR * n + i] = 1.0;
            if !self.fixed[i] {
                m[ws::MAP_RING_N * n + i] = 1.0;
                m[ws::MAP_RING_C * n + i] = zi[0];
                m[ws::MAP_RING_S * n + i] = zi[1];
            }
            if deg > 0 {
                m[ws::MAP_RING_OLD * n + i] = 0.5 * sm / deg as f32;
            }
        }
        m
    }

    /// Screens every birth position with the window pass and refills the heap.
    fn screen(&mut self, engine: &Engine) -> Result<()> {
        let t = Instant::now();
        let (best, _code) = window_pass(engine, self.f, &self.maps(), self.p)?;
        self.stats.window_runs += 1;
        self.stats.seconds_windows += t.elapsed().as_secs_f64();
        self.heap.clear();
        for (pos, &d) in best.iter().enumerate() {
            if d > 0.0 && !self.blacklist[pos] {
                self.heap.push(Entry {
                    delta: d,
                    pos: pos as u32,
                    stamp: PROXY,
                });
            }
        }
        Ok(())
    }

    /// Diffuses Θ again with the sketch clamped, warm from the current field.
    fn rediffuse(&mut self, engine: &Engine) -> Result<()> {
        let t = Instant::now();
        let fl = self.flags();
        let solved = theta::solve(
            engine,
            self.f,
            &fl,
            self.z.clone(),
            self.p.rebuild_sweeps,
            &self.p.theta,
        )?;
        for (i, &f) in fl.iter().enumerate() {
            if f == FREE {
                self.z[i] = solved.z[i];
            }
        }
        self.stats.rebuilds += 1;
        self.stats.seconds_theta += t.elapsed().as_secs_f64();
        Ok(())
    }

    fn flags(&self) -> Vec<u32> {
        (0..self.f.len())
            .map(|i| {
                if !self.f.hair[i] {
                    OFF
                } else if self.fixed[i] {
                    FIXED
                } else {
                    FREE
                }
            })
            .collect()
    }

    /// E of Eq. 19 for the current state and `curves`.
    fn energy(&self, curves: &[Curve]) -> f64 {
        let f = self.f;
        let (w, h) = (f.width as usize, f.height as usize);
        let mut e = 0.0f64;
        for i in 0..f.len() {
            if !f.hair[i] {
                continue;
            }
            let zi = self.z[i];
            let r = f.rho(i, zi);
            e += f.e1(i, zi) as f64;
            e -= if self.fixed[i] {
                self.sk.at(r)
            } else {
                self.nsk.at(r)
            } as f64;
            let (x, y) = (i % w, i / w);
            for j in [(x + 1 < w).then(|| i + 1), (y + 1 < h).then(|| i + w)]
                .into_iter()
                .flatten()
            {
                if f.hair[j] && !(self.fixed[i] && self.fixed[j]) {
                    e += f.edge(zi, self.z[j]) as f64;
                }
            }
        }
        e + curve_energy(curves, self.p.lambda_nc, f.smooth)
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
            let Some((_, birth, pos)) = self.pop_best() else {
                break;
            };
            self.stats.births += 1;
            match self.trace(birth) {
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

/// λ_NC N_C + the turn costs of E3.
fn curve_energy(curves: &[Curve], lambda_nc: f32, smooth: f32) -> f64 {
    let mut e = lambda_nc as f64 * curves.len() as f64;
    for c in curves {
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
        lambda_nc: p.lambda_nc,
        spill: p.spill,
        hair_min: p.hair_min,
        smooth: f.smooth,
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
    let tb = rec.upload("coif.cz_window.trig", &ws::trig());
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

/// Sketch pursuit on a `width` x `height` image: `high` the high band I_H, `hair` the mask,
/// `theta0` the warm start (coif's Gabor orientation, `crate::analyze::orient::orient`,
/// NaN allowed where it has none). σθ² is `p.theta.sigma2` or its maximum-likelihood value
/// under `theta0`.
pub fn pursue(
    engine: &Engine,
    high: &[f32],
    width: u32,
    height: u32,
    hair: &[bool],
    theta0: &[f32],
    p: &PursuitParams,
) -> Result<Pursuit> {
    p.validate()?;
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
    let mut prior = rho::fit_split(&rho_empty, hair, p.split_quantile)?;
    let passes = if p.refit { 2 } else { 1 };
    let mut out = None;
    for pass in 0..passes {
        let mut s = Search::new(&f, p, empty.z.clone(), prior);
        let (curves, e0, energy) = s.run(engine)?;
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
        let st = std::mem::take(&mut s.stats);
        stats.births += st.births;
        stats.dropped_short += st.dropped_short;
        stats.dropped_snapped += st.dropped_snapped;
        stats.rebuilds += st.rebuilds;
        stats.window_runs += st.window_runs;
        stats.exact_births += st.exact_births;
        stats.seconds_theta += st.seconds_theta;
        stats.seconds_windows += st.seconds_windows;
        stats.seconds_search += st.seconds_search;
        stats.sweeps_final = solved.sweeps;
        stats.passes += 1;
        let energy_final = s.energy(&curves);
        let theta = theta::theta_of(&s.z, &fl);
        let rho = rho::rho_field(&f.gx, &f.gy, &theta);
        if pass + 1 < passes {
            let on: Vec<bool> = s.fixed.clone();
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
    out.stats = stats;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chain_steps_along_the_mean_axis() {
        let c = chain([10.0, 20.0], &[0, 0, 1, 0, -1]);
        assert_eq!(c[0], [10.0, 20.0]);
        assert!((c[1][0] - 15.0).abs() < 1e-5 && (c[1][1] - 20.0).abs() < 1e-5);
        // A turn of one step moves along 7.5°.
        let m = 0.5 * AXIS_QUANTUM;
        assert!((c[2][0] - (15.0 + 5.0 * m.cos())).abs() < 1e-5);
        assert!((c[2][1] - (20.0 + 5.0 * m.sin())).abs() < 1e-5);
        for k in 1..c.len() {
            let d = ((c[k][0] - c[k - 1][0]).powi(2) + (c[k][1] - c[k - 1][1]).powi(2)).sqrt();
            assert!((d - STEP).abs() < 1e-4);
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
