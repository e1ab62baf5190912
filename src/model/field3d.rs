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

use crate::error::{Error, Result};
use crate::gpu::engine::{BufProxy, Recording};
use crate::stages::field_cfg::Config;
use crate::stages::{
    field_coarse_rhs, field_dense, field_prolong, field_resid, field_restrict, field_smooth,
};
use rayon::prelude::*;

pub use crate::base::grid::Grid;

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
/// `STALL_WINDOW` cycles; f64 CG then finishes from its iterate.
const STALL_WINDOW: usize = 6;
const STALL_GAIN: f64 = 0.5;

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
            let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
            let cand = [
                (x > 0, i.wrapping_sub(1)),
                (x + 1 < nx, i + 1),
                (y > 0, i.wrapping_sub(nx)),
                (y + 1 < ny, i + nx),
                (z > 0, i.wrapping_sub(nx * ny)),
                (z + 1 < nz, i + nx * ny),
            ];
            for (ok, j) in cand {
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

/// One level of the hierarchy, as the shaders see it.
struct Level {
    dims: [u32; 3],
    /// -1 outside H, else the penalty weight.
    cellw: Vec<f32>,
    /// Weights of the links to the +x, +y, +z neighbour, 3 per cell (0: none).
    links: Vec<f32>,
    /// Finest-level H cells under each cell.
    vol: Vec<f32>,
    /// Finest-level links crossing to the +x, +y, +z neighbour, 3 per cell.
    cross: Vec<f32>,
    sigma: f32,
    cells: usize,
}

impl Level {
    fn len(&self) -> usize {
        self.dims.iter().map(|&d| d as usize).product()
    }

    fn cfg(&self, colour: u32, mode: u32, coarse: Option<&Level>, count: u32) -> Config {
        let c = coarse.map_or([0; 3], |l| l.dims);
        Config {
            nx: self.dims[0],
            ny: self.dims[1],
            nz: self.dims[2],
            colour,
            sigma: self.sigma,
            mode,
            cnx: c[0],
            cny: c[1],
            cnz: c[2],
            count,
        }
    }

    /// The next coarser level: a coarse cell is in H when any child is, with the mean
    /// penalty of the finest H cells under it (the Galerkin value of the penalty for the
    /// mean restriction and constant interpolation), and a Laplacian scaled by a further 1/4
    /// (cells twice as wide) whose links follow the finest ones: two neighbouring blocks are
    /// linked only if finest links cross between them. Why: a plain rediscretisation links every pair of blocks holding H cells, so
    /// sheets of H that the fine level keeps apart (hair above and below an ear, either
    /// side of a thin gap) merge on coarse levels; the coarse correction is then wrong for
    /// them and the cycle stalled or diverged on photos.
    fn coarsen(&self) -> Level {
        let [nx, ny, nz] = self.dims;
        let dims = self.dims.map(|d| d.div_ceil(2));
        let nc: usize = dims.iter().map(|&d| d as usize).product();
        let mut pen_vol = vec![0.0f64; nc];
        let mut vol = vec![0.0f32; nc];
        let mut cross = vec![0.0f32; 3 * nc];
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let i = (x + nx * (y + ny * z)) as usize;
                    if self.cellw[i] < 0.0 {
                        continue;
                    }
                    let ic = (x / 2 + dims[0] * (y / 2 + dims[1] * (z / 2))) as usize;
                    pen_vol[ic] += self.cellw[i] as f64 * self.vol[i] as f64;
                    vol[ic] += self.vol[i];
                    // Only links that leave the block (from an odd coordinate) cross.
                    for (a, c) in [x, y, z].into_iter().enumerate() {
                        if c % 2 == 1 {
                            cross[3 * ic + a] += self.cross[3 * i + a];
                        }
                    }
                }
            }
        }
        let cellw: Vec<f32> = (0..nc)
            .map(|i| {
                if vol[i] > 0.0 {
                    (pen_vol[i] / vol[i] as f64) as f32
                } else {
                    -1.0
                }
            })
            .collect();
        let cells = vol.iter().filter(|&&v| v > 0.0).count();
        // Blocks are linked (weight 1, as full blocks) when finest links cross between them.
        // Weights that follow the crossing count per volume were tried and made the cycle a
        // far worse preconditioner: the prolongation is trilinear and does not see them.
        let links: Vec<f32> = cross.iter().map(|&f| (f > 0.0) as u32 as f32).collect();
        Level {
            dims,
            cellw,
            links,
            vol,
            cross,
            sigma: self.sigma * 0.25,
            cells,
        }
    }

    /// Compact list of H cells and the f32 inverse of `σ² L² + P` over them (f64 Cholesky).
    fn direct_inverse(&self) -> Result<(Vec<u32>, Vec<f32>)> {
        let cells: Vec<u32> = (0..self.len() as u32)
            .filter(|&i| self.cellw[i as usize] >= 0.0)
            .collect();
        let m = cells.len();
        let mut pos = vec![u32::MAX; self.len()];
        for (k, &c) in cells.iter().enumerate() {
            pos[c as usize] = k as u32;
        }
        // Sparse rows of σL over the compact list.
        let [nx, ny, nz] = self.dims.map(|d| d as usize);
        let s = self.sigma as f64;
        let lrows: Vec<Vec<(usize, f64)>> = cells
            .iter()
            .enumerate()
            .map(|(k, &c)| {
                let i = c as usize;
                let cand = neighbours6(i, [nx, ny, nz]);
                let mut row: Vec<(usize, f64)> = cand
                    .iter()
                    .enumerate()
                    .filter(|(_, (ok, j))| *ok && pos[*j] != u32::MAX)
                    .map(|(e, &(_, j))| {
                        (pos[j] as usize, s * self.links[3 * i.min(j) + e / 2] as f64)
                    })
                    .filter(|&(_, w)| w > 0.0)
                    .collect();
                let d: f64 = row.iter().map(|&(_, w)| w).sum();
                row.push((k, -d));
                row
            })
            .collect();
        let mut a = vec![0.0f64; m * m];
        // (σL)² = Σ_k (row k)ᵀ(row k) since L is symmetric.
        for row in &lrows {
            for &(i, vi) in row {
                for &(j, vj) in row {
                    a[i * m + j] += vi * vj;
                }
            }
        }
        for (k, &c) in cells.iter().enumerate() {
            a[k * m + k] += self.cellw[c as usize] as f64;
        }
        let inv = spd_inverse(&mut a, m).ok_or_else(|| {
            Error::Invalid("coarsest field operator is not positive definite".into())
        })?;
        Ok((cells, inv.iter().map(|&x| x as f32).collect()))
    }
}

/// Inverse of a symmetric positive definite matrix by Cholesky (a is overwritten).
fn spd_inverse(a: &mut [f64], m: usize) -> Option<Vec<f64>> {
    for j in 0..m {
        let mut d = a[j * m + j];
        for k in 0..j {
            d -= a[j * m + k] * a[j * m + k];
        }
        if d <= 0.0 || !d.is_finite() {
            return None;
        }
        let d = d.sqrt();
        a[j * m + j] = d;
        for i in j + 1..m {
            let mut s = a[i * m + j];
            for k in 0..j {
                s -= a[i * m + k] * a[j * m + k];
            }
            a[i * m + j] = s / d;
        }
    }
    // Solve L Lᵀ X = I column by column (columns in parallel).
    let cols: Vec<Vec<f64>> = (0..m)
        .into_par_iter()
        .map(|c| {
            let mut y = vec![0.0f64; m];
            for i in c..m {
                let mut s = if i == c { 1.0 } else { 0.0 };
                for k in c..i {
                    s -= a[i * m + k] * y[k];
                }
                y[i] = s / a[i * m + i];
            }
            for i in (0..m).rev() {
                let mut s = y[i];
                for k in i + 1..m {
                    s -= a[k * m + i] * y[k];
                }
                y[i] = s / a[i * m + i];
            }
            y
        })
        .collect();
    let mut inv = vec![0.0f64; m * m];
    for (c, col) in cols.iter().enumerate() {
        for (r, &v) in col.iter().enumerate() {
            inv[r * m + c] = v;
        }
    }
    Some(inv)
}

/// Builds the level hierarchy from the prepared fine problem.
fn hierarchy(grid: &Grid, prep: &Prepared, max_direct: usize) -> Vec<Level> {
    let cellw: Vec<f32> = prep
        .inside
        .iter()
        .zip(&prep.pen)
        .map(|(&b, &p)| if b { p } else { -1.0 })
        .collect();
    let cells = prep.inside.iter().filter(|&&b| b).count();
    let dims = grid.dims.map(|d| d as usize);
    let mut links = vec![0.0f32; 3 * prep.inside.len()];
    for (i, &inside) in prep.inside.iter().enumerate() {
        if inside {
            for (e, (ok, j)) in neighbours6(i, dims).into_iter().enumerate() {
                // The +x, +y, +z entries (odd e) own the link.
                if e % 2 == 1 && ok && prep.inside[j] {
                    links[3 * i + e / 2] = 1.0;
                }
            }
        }
    }
    let vol = prep.inside.iter().map(|&b| b as u32 as f32).collect();
    let mut levels = vec![Level {
        dims: grid.dims,
        cellw,
        cross: links.clone(),
        links,
        vol,
        sigma: 1.0,
        cells,
    }];
    loop {
        let l = levels.last().expect("at least the fine level");
        if l.cells <= max_direct || l.dims.iter().all(|&d| d == 1) {
            break;
        }
        let c = l.coarsen();
        levels.push(c);
    }
    levels
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

// ---------------------------------------------------------------------------------------------
// Host references in f64: the same normal equations, matrix-free over the compact H.
// ---------------------------------------------------------------------------------------------

/// The normal equations `(L² + P) v = b` of C13 Eq. (3) over the compact list of H cells.
pub struct NormalSystem {
    /// Grid index of each compact cell.
    pub cells: Vec<u32>,
    /// Compact indices of the in-H 6-neighbours (`u32::MAX` = none).
    pub nb: Vec<[u32; 6]>,
    /// Penalty weight per compact cell.
    pub pen: Vec<f64>,
    /// Right-hand side `w_c c_i`, 3 interleaved per compact cell.
    pub b: Vec<f64>,
    /// Grid size, for scattering back.
    pub grid_len: usize,
}

impl NormalSystem {
    /// Checks the inputs like [`solve`] and builds the system (same duplicate averaging and
    /// the same removal of unconstrained components).
    pub fn new(grid: &Grid, h: &[u32], constraints: &[(u32, [f32; 3])], w_c: f32) -> Result<Self> {
        Ok(Self::from_prepared(
            grid,
            &prepare(grid, h, constraints, w_c)?,
        ))
    }

    fn from_prepared(grid: &Grid, prep: &Prepared) -> Self {
        let n = grid.len();
        let cells: Vec<u32> = (0..n as u32).filter(|&i| prep.inside[i as usize]).collect();
        let mut pos = vec![u32::MAX; n];
        for (k, &c) in cells.iter().enumerate() {
            pos[c as usize] = k as u32;
        }
        let [nx, ny, nz] = grid.dims.map(|d| d as usize);
        let nb = cells
            .iter()
            .map(|&c| {
                let i = c as usize;
                let cand = neighbours6(i, [nx, ny, nz]);
                cand.map(|(ok, j)| if ok { pos[j] } else { u32::MAX })
            })
            .collect();
        let pen = cells.iter().map(|&c| prep.pen[c as usize] as f64).collect();
        let b = cells
            .iter()
            .flat_map(|&c| (0..3).map(move |a| (c as usize, a)))
            .map(|(c, a)| prep.rhs[3 * c + a] as f64)
            .collect();
        NormalSystem {
            cells,
            nb,
            pen,
            b,
            grid_len: n,
        }
    }

    pub fn len(&self) -> usize {
        self.cells.len()
    }

    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    fn degree(&self, i: usize) -> f64 {
        self.nb[i].iter().filter(|&&j| j != u32::MAX).count() as f64
    }

    /// `w = L x` (3 interleaved components).
    fn lap(&self, x: &[f64], w: &mut [f64]) {
        w.par_chunks_mut(3).enumerate().for_each(|(i, out)| {
            let mut s = [0.0f64; 3];
            let mut d = 0.0;
            for &j in &self.nb[i] {
                if j != u32::MAX {
                    let j = j as usize;
                    for a in 0..3 {
                        s[a] += x[3 * j + a];
                    }
                    d += 1.0;
                }
            }
            for a in 0..3 {
                out[a] = s[a] - d * x[3 * i + a];
            }
        });
    }

    /// `y = (L² + P) x`, with `w` as scratch for `L x`.
    pub fn apply(&self, x: &[f64], w: &mut [f64], y: &mut [f64]) {
        self.lap(x, w);
        self.lap(w, y);
        y.par_chunks_mut(3).enumerate().for_each(|(i, out)| {
            for a in 0..3 {
                out[a] += self.pen[i] * x[3 * i + a];
            }
        });
    }

    /// Scatters a compact solution to the grid (3 interleaved, zero outside H).
    pub fn scatter(&self, x: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0f64; 3 * self.grid_len];
        for (k, &c) in self.cells.iter().enumerate() {
            out[3 * c as usize..3 * c as usize + 3].copy_from_slice(&x[3 * k..3 * k + 3]);
        }
        out
    }

    /// Relative residual `|b − A x| / |b|` in f64, `x` in grid layout (3 per cell).
    pub fn rel_residual_grid(&self, x_grid: &[f64]) -> f64 {
        let x: Vec<f64> = self
            .cells
            .iter()
            .flat_map(|&c| (0..3).map(move |a| x_grid[3 * c as usize + a]))
            .collect();
        let (mut w, mut y) = (vec![0.0; x.len()], vec![0.0; x.len()]);
        self.apply(&x, &mut w, &mut y);
        let r: Vec<f64> = self.b.iter().zip(&y).map(|(b, y)| b - y).collect();
        dot(&r, &r).sqrt() / dot(&self.b, &self.b).sqrt()
    }
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

/// Relative residual reached by [`solve_cg_f64`].
pub const CG_TOL: f64 = 1e-10;
/// Iteration cap of [`solve_cg_f64`].
pub const CG_MAX_ITER: u64 = 200_000;

/// Plain (unpreconditioned) matrix-free conjugate gradients in f64 on the normal equations
/// `(L² + w_c P) v = w_c P c` of C13 Eq. (3), from zero to relative residual [`CG_TOL`]:
/// the independent reference for [`solve`]. Returns the field in grid layout (3 per cell)
/// and the iterations used.
pub fn solve_cg_f64(
    grid: &Grid,
    h: &[u32],
    constraints: &[(u32, [f32; 3])],
    w_c: f32,
) -> Result<(Vec<f64>, u64)> {
    let sys = NormalSystem::new(grid, h, constraints, w_c)?;
    let (x, it, _) = cg_f64(&sys, &vec![0.0; 3 * sys.len()], CG_TOL, CG_MAX_ITER);
    Ok((sys.scatter(&x), it))
}

/// Unpreconditioned CG on `sys` from `x0` (compact) to relative residual `tol` or
/// `max_iter` iterations: the compact solution, the iterations and the relative residual.
fn cg_f64(sys: &NormalSystem, x0: &[f64], tol: f64, max_iter: u64) -> (Vec<f64>, u64, f64) {
    let m = 3 * sys.len();
    let mut x = x0.to_vec();
    let (mut w, mut ap) = (vec![0.0f64; m], vec![0.0f64; m]);
    sys.apply(&x, &mut w, &mut ap);
    let mut r: Vec<f64> = sys.b.iter().zip(&ap).map(|(b, a)| b - a).collect();
    let mut p = r.clone();
    let bnorm = dot(&sys.b, &sys.b).sqrt();
    let mut rr = dot(&r, &r);
    let mut it = 0;
    while it < max_iter && rr.sqrt() > tol * bnorm {
        sys.apply(&p, &mut w, &mut ap);
        let alpha = rr / dot(&p, &ap);
        x.par_iter_mut().zip(&p).for_each(|(x, p)| *x += alpha * p);
        r.par_iter_mut().zip(&ap).for_each(|(r, a)| *r -= alpha * a);
        let rr_new = dot(&r, &r);
        let beta = rr_new / rr;
        rr = rr_new;
        p.par_iter_mut()
            .zip(&r)
            .for_each(|(p, r)| *p = r + beta * *p);
        it += 1;
    }
    (x, it, rr.sqrt() / bnorm.max(f64::MIN_POSITIVE))
}

/// Outcome of [`jacobi_sweeps_to`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct JacobiReport {
    /// Sweeps actually run.
    pub sweeps_run: u64,
    /// Whether `tol` was reached within the cap.
    pub reached: bool,
    /// Relative residual after `sweeps_run` sweeps.
    pub rel_residual: f64,
    /// Damping factor used: 1.9 / (∞-norm bound of D⁻¹A), so every mode contracts.
    pub omega: f64,
    /// Per-sweep residual contraction over the last quarter of the run.
    pub rate: f64,
    /// Sweeps needed for `tol`: exact when reached, else `sweeps_run` plus the sweeps the
    /// measured rate needs for the rest. The measured rate still includes faster modes that
    /// have not died out, so the extrapolation underestimates the true count.
    pub sweeps_to_tol: f64,
}

/// Damped Jacobi on the normal equations of C13 Eq. (3) (host, f64) from zero, until the
/// relative residual reaches `tol` or `cap` sweeps; see [`JacobiReport`].
pub fn jacobi_sweeps_to(
    grid: &Grid,
    h: &[u32],
    constraints: &[(u32, [f32; 3])],
    w_c: f32,
    tol: f64,
    cap: u64,
) -> Result<JacobiReport> {
    let sys = NormalSystem::new(grid, h, constraints, w_c)?;
    let n = sys.len();
    let deg: Vec<f64> = (0..n).map(|i| sys.degree(i)).collect();
    let diag: Vec<f64> = (0..n)
        .map(|i| deg[i] * deg[i] + deg[i] + sys.pen[i])
        .collect();
    // |A| row sums ≤ Σ_k |L_ik| Σ_j |L_kj| + p_i = Σ_k |L_ik| 2 d_k + p_i bound λ_max(D⁻¹A).
    let bound = (0..n)
        .map(|i| {
            let mut s = deg[i] * 2.0 * deg[i] + sys.pen[i];
            for &j in &sys.nb[i] {
                if j != u32::MAX {
                    s += 2.0 * deg[j as usize];
                }
            }
            s / diag[i]
        })
        .fold(0.0f64, f64::max);
    let omega = 1.9 / bound;
    let m = 3 * n;
    let mut x = vec![0.0f64; m];
    let (mut w, mut ax) = (vec![0.0f64; m], vec![0.0f64; m]);
    let bnorm = dot(&sys.b, &sys.b).sqrt();
    let mut hist: Vec<f64> = Vec::new();
    let mut k = 0u64;
    loop {
        sys.apply(&x, &mut w, &mut ax);
        // ax <- r = b − A x
        ax.par_iter_mut().zip(&sys.b).for_each(|(a, b)| *a = b - *a);
        let rel = dot(&ax, &ax).sqrt() / bnorm;
        hist.push(rel);
        if rel <= tol || k >= cap {
            break;
        }
        x.par_chunks_mut(3)
            .zip(ax.par_chunks(3))
            .zip(diag.par_iter())
            .for_each(|((x, r), d)| {
                for a in 0..3 {
                    x[a] += omega * r[a] / d;
                }
            });
        k += 1;
    }
    let rel = *hist.last().expect("one residual at least");
    let q = (k / 4).max(1).min(k);
    let rate = if k > 0 {
        (rel / hist[(k - q) as usize]).powf(1.0 / q as f64)
    } else {
        0.0
    };
    let reached = rel <= tol;
    let sweeps_to_tol = if reached {
        k as f64
    } else if rate < 1.0 && rate > 0.0 {
        k as f64 + (tol / rel).ln() / rate.ln()
    } else {
        f64::INFINITY
    };
    Ok(JacobiReport {
        sweeps_run: k,
        reached,
        rel_residual: rel,
        omega,
        rate,
        sweeps_to_tol,
    })
}

// ---------------------------------------------------------------------------------------------
// A synthetic hair-like volume for tests and benchmarks.
// ---------------------------------------------------------------------------------------------

/// A test problem: grid, hair mask and constraints.
pub struct TestVolume {
    pub grid: Grid,
    pub h: Vec<u32>,
    pub constraints: Vec<(u32, [f32; 3])>,
}

/// A hair-like volume in an `n³` grid: the shell between two ellipsoids around a head
/// (centre slightly above the grid centre in image rows), with the face (lower front) and
/// everything below the neck cut away. Constraints as C13 §3 builds them: on the front
/// boundary (the H cell nearest the camera in each column) the tangent of a smooth, mostly
/// downward-flowing field projected onto the outer surface, and on every third cell touching
/// the inner (scalp) ellipsoid its outward normal.
pub fn test_shell(n: u32) -> TestVolume {
    let nf = n as f32;
    let c = [0.5 * nf, 0.45 * nf, 0.5 * nf];
    let ro = [0.44 * nf, 0.42 * nf, 0.42 * nf];
    let ri = [0.28 * nf, 0.29 * nf, 0.27 * nf];
    let grid = Grid {
        dims: [n; 3],
        origin: [0.0; 3],
        cell: 1.0,
    };
    let ell =
        |p: [f32; 3], r: [f32; 3]| -> f32 { (0..3).map(|a| ((p[a] - c[a]) / r[a]).powi(2)).sum() };
    let centre = |x: u32, y: u32, z: u32| [x as f32 + 0.5, y as f32 + 0.5, z as f32 + 0.5];
    let in_h = |p: [f32; 3]| -> bool {
        let (dy, dz) = (p[1] - c[1], p[2] - c[2]);
        let face = dz > 0.12 * nf && dy > -0.08 * nf;
        let below = dy > 0.3 * nf;
        ell(p, ro) <= 1.0 && ell(p, ri) > 1.0 && !face && !below
    };
    let mut h = vec![0u32; grid.len()];
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                h[grid.index(x, y, z)] = in_h(centre(x, y, z)) as u32;
            }
        }
    }
    let normalise = |v: [f32; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    };
    let grad = |p: [f32; 3], r: [f32; 3]| {
        normalise([
            (p[0] - c[0]) / (r[0] * r[0]),
            (p[1] - c[1]) / (r[1] * r[1]),
            (p[2] - c[2]) / (r[2] * r[2]),
        ])
    };
    let mut constraints = Vec::new();
    // Front boundary: largest depth (z) in each (x, y) column.
    for y in 0..n {
        for x in 0..n {
            let Some(z) = (0..n).rev().find(|&z| h[grid.index(x, y, z)] != 0) else {
                continue;
            };
            let p = centre(x, y, z);
            let q = [(p[0] - c[0]) / nf, (p[1] - c[1]) / nf];
            // Downward flow (+y is down in volume space) with a gentle parting swirl.
            let t0 = [2.0 * q[0] + 0.3 * (6.0 * q[1]).sin(), 1.0, 0.4 * q[1]];
            let nrm = grad(p, ro);
            let d = t0[0] * nrm[0] + t0[1] * nrm[1] + t0[2] * nrm[2];
            let t = [t0[0] - d * nrm[0], t0[1] - d * nrm[1], t0[2] - d * nrm[2]];
            constraints.push((grid.index(x, y, z) as u32, normalise(t)));
        }
    }
    // Scalp normals: cells with a 6-neighbour inside the inner ellipsoid.
    for z in 1..n - 1 {
        for y in 1..n - 1 {
            for x in 1..n - 1 {
                let i = grid.index(x, y, z);
                if h[i] == 0 || (x + y + z) % 3 != 0 {
                    continue;
                }
                let touches = [
                    (x - 1, y, z),
                    (x + 1, y, z),
                    (x, y - 1, z),
                    (x, y + 1, z),
                    (x, y, z - 1),
                    (x, y, z + 1),
                ]
                .iter()
                .any(|&(a, b, d)| ell(centre(a, b, d), ri) <= 1.0);
                if touches {
                    constraints.push((i as u32, grad(centre(x, y, z), ri)));
                }
            }
        }
    }
    TestVolume {
        grid,
        h,
        constraints,
    }
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
    fn coarse_links_follow_fine_connectivity() {
        // Two slabs of H, x in 0..=2 and 4..=7, apart at x = 3. Block x 1 (cells 2, 3) holds
        // the end of the first slab, block 2 (cells 4, 5) the start of the second: no fine
        // link crosses between them, so the coarse level must not link them either.
        let grid = Grid {
            dims: [8, 4, 4],
            origin: [0.0; 3],
            cell: 1.0,
        };
        let h: Vec<u32> = (0..grid.len()).map(|i| (i % 8 != 3) as u32).collect();
        let cons = [(0u32, [1.0, 0.0, 0.0]), (7u32, [1.0, 0.0, 0.0])];
        let prep = prepare(&grid, &h, &cons, 10.0).unwrap();
        let levels = hierarchy(&grid, &prep, 1);
        let c = &levels[1];
        assert_eq!(c.dims, [4, 2, 2]);
        for row in (0..16).step_by(4) {
            let x_links: Vec<f32> = (0..4).map(|x| c.links[3 * (row + x)]).collect();
            assert_eq!(x_links, [1.0, 0.0, 1.0, 0.0], "row {row}");
        }
        // Volumes and penalty: block 1 holds 4 of its 8 cells, block 0 all 8.
        assert_eq!(c.vol[1], 4.0);
        assert_eq!(c.vol[0], 8.0);
    }
}
