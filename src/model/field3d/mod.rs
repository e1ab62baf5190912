//! The 3D hair direction field of C13 Eq. (3): a vector `v_i ∈ R³` per cell of the hair
//! volume H minimising
//!
//! ```text
//!   E(D) = Σ_{i∈H} |Δv_i|² + w_c Σ_{i∈C} |v_i − c_i|²,   w_c = 10,
//! ```
//!
//! where C holds cells with target directions (strand tangents, scalp normals).
//!
//! **Boundary choice.** Δ is the graph Laplacian of H under 6-connectivity,
//! `(L v)_i = Σ_{j ∈ N(i) ∩ H} (v_j − v_i)`: the 7-point stencil with the links that leave H
//! (or the grid) dropped. That is a homogeneous Neumann (no-flux) boundary: the surface of
//! the hair volume is a free boundary, nothing outside H pulls on the field, and a constant
//! field costs nothing. `L` is symmetric, so the normal equations read
//! `(L² + w_c P) v = w_c P c` (P: diagonal 0/1 on C), a bi-Laplacian system whose 25-point
//! stencil is cut near the boundary; the three components decouple.
//!
//! **Duplicates and undetermined parts.** C is a set of cells: several targets for one cell
//! are averaged into one target of weight `w_c`. A connected component of H without any
//! constraint has a one-dimensional family of minimisers (any constant); we return its
//! minimum-norm minimiser, zero (this is also where CG or Jacobi started from zero stay).
//!
//! **Solver.** The system is solved in its equivalent mixed form (introducing `u = L v`):
//!
//! ```text
//!   −u + L v = 0,     L u + P v = P c      ⇔     (L² + P) v = P c,  u = L v,
//! ```
//!
//! by geometric multigrid: collective red-black Gauss-Seidel on each cell's (u_i, v_i) pair
//! as smoother (point smoothing of L² itself smooths poorly, the classic biharmonic issue;
//! the collective update smooths like a Poisson smoother), cell-centred 2x2x2 coarsening
//! with a rediscretised operator (coarse H = cells with an in-H child, Laplacian scaled by
//! 4^-level, penalty = mean of the children's), mean restriction, masked trilinear
//! prolongation, and a dense direct solve on the coarsest level (≤ `max_direct` cells,
//! inverse precomputed on the host in f64). Every heavy step is a WGSL pass with a CPU
//! mirror (`crate::stages::field_*`), so one recording runs on either backend.
//!
//! **Krylov acceleration.** The cycles are not iterated on their own but serve as the
//! preconditioner of GCR (generalised conjugate residuals, the last [`GCR_KEEP`] directions
//! kept) on the normal equations, run on the host in f64: each step sends the current
//! residual r as the right-hand side (0, r) of the mixed form, runs `cycles_per_step`
//! cycles from zero (a fixed linear map, ≈ (L² + P)⁻¹ r), and minimises the residual over
//! the directions so far. Coarse links exist only where finest links cross between blocks
//! (see `Level::coarsen`); what the 2x2x2 blocks still merge is finished by f64 CG from the
//! GCR iterate when GCR stalls. Why: on photos the hair volume is thin and ragged, and the rediscretised coarse
//! operator then misrepresents a few modes; a plain cycle iteration contracted them slowly
//! (60 cycles to 6e-5 on the astronaut) or amplified them (diverged with one more stroke),
//! while GCR's residual never grows and a few Krylov directions remove such isolated modes.
//!
//! [`solve_cg_f64`] (plain CG in f64) and [`jacobi_sweeps_to`] (damped Jacobi) solve the same
//! normal equations on the host, as references for tests and benchmarks.

mod multigrid;
mod reference;
mod shell;

use crate::error::{Error, Result};
use crate::gpu::engine::{BufProxy, Recording};
use crate::stages::field_cfg::Config;
use crate::stages::{
    field_coarse_rhs, field_dense, field_prolong, field_resid, field_restrict, field_smooth,
};
use rayon::prelude::*;

pub use crate::base::grid::Grid;
use multigrid::{hierarchy, Level};
use reference::cg_f64;
pub use reference::{
    jacobi_sweeps_to, solve_cg_f64, JacobiReport, NormalSystem, CG_MAX_ITER, CG_TOL,
};
pub use shell::{test_shell, TestVolume};

/// Multigrid cycle shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Cycle {
    V,
    W,
}

/// Parameters of [`solve`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FieldParams {
    /// Constraint weight `w_c` of C13 Eq. (3).
    pub w_c: f32,
    /// Stop when `|b − A v| / |b| ≤ tol` for the normal equations `A v = b`.
    pub tol: f32,
    /// Give up after this many cycles (the report says whether `tol` was reached).
    pub max_cycles: u32,
    /// Smoothing sweeps (both colours) before / after each coarse-grid correction.
    pub pre_sweeps: u32,
    pub post_sweeps: u32,
    pub cycle: Cycle,
    /// Cycles per GCR step: the preconditioner is this many cycles from zero (one engine
    /// run each step, so a few cycles per run also spread the run's fixed cost).
    pub cycles_per_step: u32,
    /// Coarsen until a level has at most this many H cells; it is solved directly.
    pub max_direct: u32,
}

impl Default for FieldParams {
    /// W(3,3) cycles. Why not V(2,2): for smooth modes the collective smoother of the mixed
    /// form has a double eigenvalue near 1 with a Jordan block, so errors the coarse
    /// correction leaves can grow transiently; with 2+2 sweeps the V-cycle diverged on a
    /// 40³ box test, while W(3,3) contracts the residual by ~0.3 per cycle on every test
    /// volume tried (the extra coarse visits cost little in 3D: ~1.33x a V-cycle).
    fn default() -> Self {
        FieldParams {
            w_c: 10.0,
            tol: 1e-5,
            max_cycles: 60,
            pre_sweeps: 3,
            post_sweeps: 3,
            cycle: Cycle::W,
            cycles_per_step: 3,
            max_direct: 512,
        }
    }
}

impl FieldParams {
    pub fn validate(&self) -> Result<()> {
        let bad = |m: &str| Err(Error::Invalid(format!("field params: {m}")));
        if !(self.w_c.is_finite() && self.w_c > 0.0) {
            return bad("w_c must be finite and > 0");
        }
        if !(self.tol.is_finite() && self.tol > 0.0) {
            return bad("tol must be finite and > 0");
        }
        if self.max_cycles == 0 || self.cycles_per_step == 0 {
            return bad("max_cycles and cycles_per_step must be >= 1");
        }
        if self.pre_sweeps + self.post_sweeps == 0 {
            return bad("at least one smoothing sweep per level is needed");
        }
        if !(1..=4096).contains(&self.max_direct) {
            return bad("max_direct must be in 1..=4096 (dense coarsest solve)");
        }
        Ok(())
    }
}

/// One multigrid level.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LevelInfo {
    pub dims: [u32; 3],
    /// Cells of H on this level.
    pub cells: usize,
}

/// What [`solve`] did.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SolveReport {
    /// Multigrid cycles run.
    pub cycles: u32,
    /// Smoothing sweeps (both colours = one sweep) summed over all levels: each counts as a
    /// whole sweep even on coarse levels, a conservative count next to fine-grid Jacobi.
    pub smoothing_sweeps: u64,
    /// Smoothing sweeps on the finest level only.
    pub fine_sweeps: u64,
    /// Sweeps weighted by level size (fine-sweep equivalents of smoothing work).
    pub work_units: f64,
    /// Final `|b − A v| / |b|` of the normal equations (f64, on the host).
    pub rel_residual: f64,
    pub converged: bool,
    /// (cycles, relative residual) after every cycle.
    pub history: Vec<(u32, f64)>,
    pub levels: Vec<LevelInfo>,
    /// Engine runs (one per cycle: each GCR step needs the previous residual).
    pub runs: u32,
    /// H cells zeroed because their connected component has no constraint.
    pub unconstrained_cells: usize,
    /// Set when the multigrid-preconditioned GCR stalled and f64 conjugate gradients
    /// finished from its iterate: their iterations.
    pub fallback_cg_iterations: Option<u64>,
}

/// GCR directions kept for orthogonalisation (older ones are dropped: truncated GCR).
const GCR_KEEP: usize = 12;
/// GCR has stalled when the residual fell by less than `STALL_GAIN` over the last
/// `STALL_WINDOW` steps, or by less than `STEP_STALL_GAIN` over the last step; f64 CG then
/// finishes from its iterate.
const STALL_WINDOW: usize = 6;
const STALL_GAIN: f64 = 0.5;
const STEP_STALL_GAIN: f64 = 0.9;

/// Inputs checked and reduced to per-cell arrays.
struct Prepared {
    /// The working hair volume (components without constraints removed).
    inside: Vec<bool>,
    /// Penalty weight per cell (`w_c` on C, else 0).
    pen: Vec<f32>,
    /// `w_c · c_i` per cell, 3 interleaved.
    rhs: Vec<f32>,
    unconstrained: usize,
}

fn prepare(grid: &Grid, h: &[u32], constraints: &[(u32, [f32; 3])], w_c: f32) -> Result<Prepared> {
    let n = grid.len();
    if grid.dims.contains(&0) {
        return Err(Error::Invalid(format!(
            "grid dims {:?} has a zero axis",
            grid.dims
        )));
    }
    // Buffer indices are u32 with 6 floats per cell.
    if n as u64 * 6 > u32::MAX as u64 {
        return Err(Error::Invalid(format!("grid of {n} cells is too large")));
    }
    if h.len() != n {
        return Err(Error::Invalid(format!(
            "hair mask has {} cells, the {:?} grid has {n}",
            h.len(),
            grid.dims
        )));
    }
    if !(w_c.is_finite() && w_c > 0.0) {
        return Err(Error::Invalid(format!(
            "w_c = {w_c} must be finite and > 0"
        )));
    }
    let mut inside: Vec<bool> = h.iter().map(|&m| m != 0).collect();
    if !inside.iter().any(|&b| b) {
        return Err(Error::Invalid("hair volume H is empty".into()));
    }
    if constraints.is_empty() {
        return Err(Error::Invalid(
            "no direction constraints: the field of C13 Eq. (3) is undetermined".into(),
        ));
    }
    let mut sum = vec![[0.0f64; 3]; n];
    let mut count = vec![0u32; n];
    for (k, &(cell, c)) in constraints.iter().enumerate() {
        let i = cell as usize;
        if i >= n {
            return Err(Error::Invalid(format!(
                "constraint {k}: cell {cell} is outside the grid of {n} cells"
            )));
        }
        if !inside[i] {
            return Err(Error::Invalid(format!(
                "constraint {k}: cell {cell} is outside the hair volume"
            )));
        }
        if !c.iter().all(|x| x.is_finite()) {
            return Err(Error::Invalid(format!(
                "constraint {k} at cell {cell}: non-finite target {c:?}"
            )));
        }
        for a in 0..3 {
            sum[i][a] += c[a] as f64;
        }
        count[i] += 1;
    }
    // Flood-fill the components of H; drop those without a constraint.
    let [nx, ny, nz] = grid.dims.map(|d| d as usize);
    let mut seen = vec![false; n];
    let mut unconstrained = 0;
    let mut stack = Vec::new();
    let mut comp = Vec::new();
    for s in 0..n {
        if !inside[s] || seen[s] {
            continue;
        }
        seen[s] = true;
        stack.push(s);
        comp.clear();
        let mut constrained = false;
        while let Some(i) = stack.pop() {
            comp.push(i);
            constrained |= count[i] > 0;
            for (ok, j) in neighbours6(i, [nx, ny, nz]) {
                if ok && inside[j] && !seen[j] {
                    seen[j] = true;
                    stack.push(j);
                }
            }
        }
        if !constrained {
            unconstrained += comp.len();
            for &i in &comp {
                inside[i] = false;
            }
        }
    }
    let mut pen = vec![0.0f32; n];
    let mut rhs = vec![0.0f32; 3 * n];
    for i in 0..n {
        if count[i] > 0 {
            pen[i] = w_c;
            for a in 0..3 {
                rhs[3 * i + a] = (w_c as f64 * sum[i][a] / count[i] as f64) as f32;
            }
        }
    }
    Ok(Prepared {
        inside,
        pen,
        rhs,
        unconstrained,
    })
}

/// GPU-side buffers of one level within a recording.
struct LevelBufs {
    cellw: BufProxy,
    links: BufProxy,
    f: BufProxy,
    uv: BufProxy,
    r: Option<BufProxy>,
    /// Uniforms indexed by `2·mode + colour`.
    cfg: [BufProxy; 4],
    /// Coarsest level: compact cells, inverse, g.
    direct: Option<(BufProxy, BufProxy, BufProxy, Config)>,
}

/// Counts of the work a recording does.
#[derive(Default)]
struct Tally {
    sweeps: u64,
    fine_sweeps: u64,
    work: f64,
}

struct Solver<'a> {
    levels: &'a [Level],
    direct: &'a (Vec<u32>, Vec<f32>),
    params: &'a FieldParams,
}

impl Solver<'_> {
    fn buffers(&self, rec: &mut Recording, f0: &[f32], uv0: &[f32]) -> Vec<LevelBufs> {
        let last = self.levels.len() - 1;
        self.levels
            .iter()
            .enumerate()
            .map(|(l, lev)| {
                let coarse = self.levels.get(l + 1);
                let count = if l == last {
                    self.direct.0.len() as u32
                } else {
                    0
                };
                let cfg = [0u32, 1, 2, 3]
                    .map(|k| rec.uniform("field.cfg", &lev.cfg(k & 1, k >> 1, coarse, count)));
                let n6 = 6 * lev.len() as u64 * 4;
                let (f, uv) = if l == 0 {
                    (rec.upload("field.f", f0), rec.upload("field.uv", uv0))
                } else {
                    (rec.alloc("field.f", n6, 0), rec.alloc("field.uv", n6, 0))
                };
                let r = (l < last || l == 0).then(|| rec.alloc("field.r", n6, 0));
                let direct = (l == last).then(|| {
                    let cells = rec.upload("field.cells", &self.direct.0);
                    let inv = rec.upload("field.inv", &self.direct.1);
                    let g = rec.alloc("field.g", 12 * count as u64, 0);
                    (cells, inv, g, lev.cfg(0, 0, None, count))
                });
                LevelBufs {
                    cellw: rec.upload("field.cellw", &lev.cellw),
                    links: rec.upload("field.links", &lev.links),
                    f,
                    uv,
                    r,
                    cfg,
                    direct,
                }
            })
            .collect()
    }

    fn sweep(
        &self,
        rec: &mut Recording,
        b: &LevelBufs,
        l: usize,
        colours: [u32; 2],
        t: &mut Tally,
    ) {
        let lev = &self.levels[l];
        let cfg = lev.cfg(0, 0, None, 0);
        for c in colours {
            rec.dispatch(
                &field_smooth::STAGE,
                field_smooth::workgroups(&cfg),
                &[b.cfg[c as usize], b.cellw, b.f, b.uv, b.links],
                &[],
            );
        }
        t.sweeps += 1;
        if l == 0 {
            t.fine_sweeps += 1;
        }
        t.work += lev.len() as f64 / self.levels[0].len() as f64;
    }

    /// Records one cycle on level `l` (V or W by the params).
    fn cycle(&self, rec: &mut Recording, bufs: &[LevelBufs], l: usize, t: &mut Tally) {
        let b = &bufs[l];
        let lev = &self.levels[l];
        if l + 1 == self.levels.len() {
            let (cells, inv, g, cfg) = b.direct.expect("coarsest level has the direct solve");
            rec.dispatch(
                &field_coarse_rhs::STAGE,
                field_coarse_rhs::workgroups(&cfg),
                &[b.cfg[0], cells, b.f, g, b.links],
                &[],
            );
            rec.dispatch(
                &field_dense::STAGE,
                field_dense::workgroups(&cfg),
                &[b.cfg[0], cells, inv, g, b.uv],
                &[],
            );
            // u = σ L v − f1 from the solved v (mode 1, both colours).
            for k in [2, 3] {
                rec.dispatch(
                    &field_smooth::STAGE,
                    field_smooth::workgroups(&cfg),
                    &[b.cfg[k], b.cellw, b.f, b.uv, b.links],
                    &[],
                );
            }
            return;
        }
        let cfg = lev.cfg(0, 0, Some(&self.levels[l + 1]), 0);
        for _ in 0..self.params.pre_sweeps {
            self.sweep(rec, b, l, [0, 1], t);
        }
        let r = b.r.expect("non-coarsest levels have a residual buffer");
        let c = &bufs[l + 1];
        rec.dispatch(
            &field_resid::STAGE,
            field_resid::workgroups(&cfg),
            &[b.cfg[0], b.cellw, b.f, b.uv, r, b.links],
            &[],
        );
        rec.dispatch(
            &field_restrict::STAGE,
            field_restrict::workgroups(&cfg),
            &[b.cfg[0], b.cellw, c.cellw, r, c.f, c.uv],
            &[],
        );
        let gamma = match self.params.cycle {
            Cycle::V => 1,
            Cycle::W => 2,
        };
        for _ in 0..gamma {
            self.cycle(rec, bufs, l + 1, t);
        }
        rec.dispatch(
            &field_prolong::STAGE,
            field_prolong::workgroups(&cfg),
            &[b.cfg[0], b.cellw, c.cellw, c.uv, b.uv],
            &[],
        );
        for _ in 0..self.params.post_sweeps {
            // Reverse colour order keeps the cycle symmetric.
            self.sweep(rec, b, l, [1, 0], t);
        }
    }
}

/// Solves C13 Eq. (3) for the 3D direction field over H by multigrid on `engine`.
/// Returns the field (3 floats per grid cell, interleaved, zero outside H) and a report.
/// `constraints` are (cell index, target) pairs; the cells must lie in H.
pub fn solve(
    engine: &crate::Engine,
    grid: &Grid,
    h: &[u32],
    constraints: &[(u32, [f32; 3])],
    p: &FieldParams,
) -> Result<(Vec<f32>, SolveReport)> {
    p.validate()?;
    let prep = prepare(grid, h, constraints, p.w_c)?;
    let n = grid.len();
    let levels = hierarchy(grid, &prep, p.max_direct as usize);
    let direct = levels
        .last()
        .expect("one level at least")
        .direct_inverse()?;
    let solver = Solver {
        levels: &levels,
        direct: &direct,
        params: p,
    };
    let sys = NormalSystem::from_prepared(grid, &prep);
    let mut report = SolveReport {
        cycles: 0,
        smoothing_sweeps: 0,
        fine_sweeps: 0,
        work_units: 0.0,
        rel_residual: 1.0,
        converged: false,
        history: vec![(0, 1.0)],
        levels: levels
            .iter()
            .map(|l| LevelInfo {
                dims: l.dims,
                cells: l.cells,
            })
            .collect(),
        runs: 0,
        unconstrained_cells: prep.unconstrained,
        fallback_cg_iterations: None,
    };
    let m = 3 * sys.len();
    let bnorm = dot(&sys.b, &sys.b).sqrt();
    let mut x = vec![0.0f64; m];
    let mut r = sys.b.clone();
    if bnorm == 0.0 {
        report.rel_residual = 0.0;
        report.converged = true;
        return Ok((vec![0.0; 3 * n], report));
    }
    // GCR directions kept for orthogonalisation: (z_k, A z_k / |A z_k|).
    let mut dirs: Vec<(Vec<f64>, Vec<f64>)> = Vec::new();
    let (mut f0, uv0) = (vec![0.0f32; 6 * n], vec![0.0f32; 6 * n]);
    let mut scratch = vec![0.0f64; m];
    let tol = p.tol as f64;
    while report.cycles < p.max_cycles {
        // Preconditioner: `cycles_per_step` multigrid cycles from zero on the mixed form with
        // right-hand side (0, r), a fixed linear map ≈ (L² + P)⁻¹ r.
        for (k, &c) in sys.cells.iter().enumerate() {
            let c = c as usize;
            for a in 0..3 {
                f0[6 * c + 3 + a] = r[3 * k + a] as f32;
            }
        }
        let mut rec = Recording::default();
        let bufs = solver.buffers(&mut rec, &f0, &uv0);
        let mut t = Tally::default();
        for _ in 0..p.cycles_per_step {
            solver.cycle(&mut rec, &bufs, 0, &mut t);
        }
        rec.download(bufs[0].uv);
        let uv = engine.run(rec)?.get::<f32>(bufs[0].uv);
        report.runs += 1;
        report.cycles += p.cycles_per_step;
        report.smoothing_sweeps += t.sweeps;
        report.fine_sweeps += t.fine_sweeps;
        report.work_units += t.work;
        let mut z: Vec<f64> = sys
            .cells
            .iter()
            .flat_map(|&c| {
                let c = 6 * c as usize + 3;
                [uv[c] as f64, uv[c + 1] as f64, uv[c + 2] as f64]
            })
            .collect();
        if z.iter().any(|v| !v.is_finite()) {
            return Err(Error::Gpu(
                "direction field: the multigrid cycle produced NaN or infinity".into(),
            ));
        }
        let mut w = vec![0.0f64; m];
        sys.apply(&z, &mut scratch, &mut w);
        // Orthogonalise A z against the kept directions (modified Gram-Schmidt).
        for (zk, wk) in &dirs {
            let beta = dot(&w, wk);
            w.par_iter_mut().zip(wk).for_each(|(w, q)| *w -= beta * q);
            z.par_iter_mut().zip(zk).for_each(|(z, q)| *z -= beta * q);
        }
        let wn = dot(&w, &w).sqrt();
        if wn.is_nan() || wn <= 0.0 {
            break;
        }
        w.iter_mut().for_each(|v| *v /= wn);
        z.iter_mut().for_each(|v| *v /= wn);
        let alpha = dot(&r, &w);
        x.par_iter_mut().zip(&z).for_each(|(x, z)| *x += alpha * z);
        r.par_iter_mut().zip(&w).for_each(|(r, w)| *r -= alpha * w);
        if dirs.len() == GCR_KEEP {
            dirs.remove(0);
        }
        dirs.push((z, w));
        let rel = dot(&r, &r).sqrt() / bnorm;
        report.rel_residual = rel;
        report.history.push((report.cycles, rel));
        if rel <= tol {
            report.converged = true;
            break;
        }
        // Stalled: the residual left lives where the coarse levels cannot see it.
        let h = &report.history;
        if h.len() > STALL_WINDOW && rel > STALL_GAIN * h[h.len() - 1 - STALL_WINDOW].1 {
            break;
        }
        if rel > STEP_STALL_GAIN * h[h.len() - 2].1 {
            break;
        }
    }
    if !report.converged {
        // A coarse cell holds all H cells of its 2x2x2 block, so two slivers of H that one
        // block joins (hair over and under an ear) stay merged on the coarse levels and the
        // cycle cannot correct their smooth modes. Plain CG from where GCR stopped is slow
        // for those few modes but certain.
        log::info!(
            "direction field: multigrid-preconditioned GCR stalled at relative residual \
             {:.2e} after {} cycles; finishing by conjugate gradients",
            report.rel_residual,
            report.cycles
        );
        let (xc, it, rel) = cg_f64(&sys, &x, tol, CG_MAX_ITER);
        report.fallback_cg_iterations = Some(it);
        report.rel_residual = rel;
        report.converged = rel <= tol;
        report.history.push((report.cycles, rel));
        x = xc;
    }
    Ok((sys.scatter(&x).iter().map(|&v| v as f32).collect(), report))
}

/// Deterministic parallel dot product (fixed chunks, summed in order).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.par_chunks(1 << 13)
        .zip(b.par_chunks(1 << 13))
        .map(|(x, y)| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>())
        .collect::<Vec<f64>>()
        .iter()
        .sum()
}

/// The six face neighbours of linear cell `i` in a grid of `dims`, each with whether it
/// lies inside the grid (the index is meaningless when it does not).
fn neighbours6(i: usize, [nx, ny, nz]: [usize; 3]) -> [(bool, usize); 6] {
    let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
    [
        (x > 0, i.wrapping_sub(1)),
        (x + 1 < nx, i + 1),
        (y > 0, i.wrapping_sub(nx)),
        (y + 1 < ny, i + nx),
        (z > 0, i.wrapping_sub(nx * ny)),
        (z + 1 < nz, i + nx * ny),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbours6_flags_the_grid_faces() {
        let dims = [3, 2, 2];
        // Cell (0, 1, 1) = 9: no -x, +x is 10, -y is 6, no +y, -z is 3, no +z.
        let n = neighbours6(9, dims);
        let inside: Vec<usize> = n.iter().filter(|(ok, _)| *ok).map(|(_, j)| *j).collect();
        assert_eq!(inside, [10, 6, 3]);
        assert!(neighbours6(13, [3, 3, 3]).iter().all(|(ok, _)| *ok));
    }
}
