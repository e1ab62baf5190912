//! Host f64 references: the same normal equations, matrix-free, solved by CG or damped Jacobi.

use super::{dot, neighbours6, prepare, Prepared};
use crate::base::grid::Grid;
use crate::error::Result;
use rayon::prelude::*;

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

    pub(super) fn from_prepared(grid: &Grid, prep: &Prepared) -> Self {
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
pub(super) fn cg_f64(
    sys: &NormalSystem,
    x0: &[f64],
    tol: f64,
    max_iter: u64,
) -> (Vec<f64>, u64, f64) {
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
