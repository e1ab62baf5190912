//! The joint search of refinement (C13 §2.2, Eq. 4-5): the vertices of S bucketed by grid
//! cell, and for a candidate ξ* the joint strand ξ' of least E_c over every pair
//! (ξ(i), ξ*(j)) within the search radius. Exact: every bound that skips a vertex, a cell,
//! a row, a slab or the whole search cube is the test the loop would make on each vertex it
//! skips (the tests compare against exhaustive evaluation, energies to the bit).

use super::V3;
use crate::base::grid::Grid;
use crate::error::{Error, Result};
use crate::hair::strands::StrandSet;
use rayon::prelude::*;

/// The chosen cut-and-connect of one candidate: ξ = strand `s` cut at vertex `i`, ξ* joined
/// from its vertex `j`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Joint {
    pub(super) s: u32,
    pub(super) i: u32,
    pub(super) j: u32,
}

/// Vertices of S bucketed by grid cell (CSR), with per-vertex strand, index within the strand
/// and density prefix sums along the strand.
pub(super) struct VertexIndex {
    cell_start: Vec<u32>,
    /// Global vertex ids, bucket after bucket, by increasing density prefix within a bucket.
    ids: Vec<u32>,
    /// Parallel to `ids`: Σ ρ over the vertices before each one in its strand, and its
    /// position. The search reads a bucket front to back: stored in bucket order, not looked
    /// up through the ids (random reads over the whole set were most of its time).
    prefix_sorted: Vec<u64>,
    points_sorted: Vec<V3>,
    strand_of: Vec<u32>,
    /// |ξ(k−1) − 2ξ(k) + ξ(k+1)| at every vertex with both neighbours (0 at the ends): the
    /// Laplacian terms of Eq. (5) that lie wholly on ξ, computed once per iteration.
    lap: Vec<f32>,
    /// Per cell, the least `rho_prefix` of its bucket (saturated to u32; u32::MAX when empty).
    cell_min: Vec<u32>,
    /// Per cell, the least `cell_min` over the cells within `reach` of it along x, then over
    /// the x-y square, then over the cube: lower bounds on the density term of every joint
    /// a candidate vertex in that cell can make with a row, a slab, or all of its search cube.
    near_min: [Vec<u32>; 3],
}

impl VertexIndex {
    /// `reach`: the search radius in whole cells (see `near_min`).
    pub(super) fn new(
        grid: &Grid,
        strands: &StrandSet,
        off: &[usize],
        density: &[u32],
        reach: u32,
    ) -> Result<Self> {
        let nv = strands.points.len();
        if nv >= u32::MAX as usize || strands.len() >= u32::MAX as usize {
            return Err(Error::Invalid(format!(
                "{nv} vertices are too many for the 32-bit neighbour index"
            )));
        }
        let mut strand_of = vec![0u32; nv];
        let mut rho_prefix = vec![0u64; nv];
        let cells: Vec<u32> = strands
            .points
            .par_iter()
            .with_min_len(4096)
            .map(|&v| grid.cell_of(v).map_or(u32::MAX, |c| c as u32))
            .collect();
        // Per strand, in parallel: its id on each vertex and the density prefix along it.
        let mut per_strand = Vec::with_capacity(off.len().saturating_sub(1));
        let (mut so, mut rp) = (strand_of.as_mut_slice(), rho_prefix.as_mut_slice());
        for w in off.windows(2) {
            let (a, b) = std::mem::take(&mut so).split_at_mut(w[1] - w[0]);
            let (c, d) = std::mem::take(&mut rp).split_at_mut(w[1] - w[0]);
            per_strand.push((w[0], a, c));
            (so, rp) = (b, d);
        }
        per_strand
            .par_iter_mut()
            .enumerate()
            .with_min_len(256)
            .for_each(|(s, (start, so, rp))| {
                let mut acc = 0u64;
                for (k, (so, rp)) in so.iter_mut().zip(rp.iter_mut()).enumerate() {
                    *so = s as u32;
                    *rp = acc;
                    let c = cells[*start + k];
                    if c != u32::MAX {
                        acc += density[c as usize] as u64;
                    }
                }
            });
        drop(per_strand);
        let pts = &strands.points;
        let mut lap = vec![0.0f32; nv];
        lap.par_iter_mut()
            .enumerate()
            .with_min_len(4096)
            .for_each(|(g, l)| {
                let s = strand_of[g] as usize;
                if g > off[s] && g + 1 < off[s + 1] {
                    *l = lap_norm(pts[g - 1], pts[g], pts[g + 1]);
                }
            });
        let mut counts = vec![0u32; grid.len() + 1];
        for w in off.windows(2) {
            // The root is never a joint (it must stay the strand's first vertex).
            for &c in &cells[w[0] + 1..w[1]] {
                if c != u32::MAX {
                    counts[c as usize + 1] += 1;
                }
            }
        }
        for c in 0..grid.len() {
            counts[c + 1] += counts[c];
        }
        // (density prefix, vertex id) in bucket order: the sort below reads its keys in place.
        let mut fill = counts.clone();
        let mut entries = vec![(0u64, 0u32); counts[grid.len()] as usize];
        for w in off.windows(2) {
            for g in w[0] + 1..w[1] {
                let c = cells[g];
                if c != u32::MAX {
                    let c = c as usize;
                    entries[fill[c] as usize] = (rho_prefix[g], g as u32);
                    fill[c] += 1;
                }
            }
        }
        // Cheapest density first within a bucket, so the E_c bound of the search can end a
        // bucket at its first vertex that cannot win (ties: lower id first, deterministic).
        // Buckets are disjoint: sorted in parallel.
        let mut buckets: Vec<&mut [(u64, u32)]> = Vec::with_capacity(grid.len());
        let mut rest = entries.as_mut_slice();
        for c in 0..grid.len() {
            let (b, r) = rest.split_at_mut((counts[c + 1] - counts[c]) as usize);
            if b.len() > 1 {
                buckets.push(b);
            }
            rest = r;
        }
        buckets
            .par_iter_mut()
            .with_min_len(256)
            .for_each(|b| b.sort_unstable());
        let cell_min: Vec<u32> = (0..grid.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|c| {
                if counts[c + 1] > counts[c] {
                    entries[counts[c] as usize].0.min(u32::MAX as u64 - 1) as u32
                } else {
                    u32::MAX
                }
            })
            .collect();
        let near_min = cube_min(grid.dims, &cell_min, reach);
        let ids: Vec<u32> = entries.par_iter().map(|e| e.1).collect();
        let prefix_sorted = entries.par_iter().map(|e| e.0).collect();
        drop(entries);
        let points_sorted = ids.par_iter().map(|&g| pts[g as usize]).collect();
        Ok(VertexIndex {
            cell_start: counts,
            ids,
            prefix_sorted,
            points_sorted,
            strand_of,
            lap,
            cell_min,
            near_min,
        })
    }

    /// The range of cell `c`'s bucket in `ids` and the arrays parallel to it.
    fn bucket(&self, c: usize) -> std::ops::Range<usize> {
        self.cell_start[c] as usize..self.cell_start[c + 1] as usize
    }
}

pub(super) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(super) fn len3(a: V3) -> f32 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

pub(super) fn mid(a: V3, b: V3) -> V3 {
    [
        (a[0] + b[0]) * 0.5,
        (a[1] + b[1]) * 0.5,
        (a[2] + b[2]) * 0.5,
    ]
}

/// |a − 2b + c|, the Laplacian term of Eq. (5) (one rounding order everywhere, so the terms
/// precomputed on ξ and on the candidate equal those computed at the joint).
#[inline]
fn lap_norm(a: V3, b: V3, c: V3) -> f32 {
    len3([
        a[0] - 2.0 * b[0] + c[0],
        a[1] - 2.0 * b[1] + c[1],
        a[2] - 2.0 * b[2] + c[2],
    ])
}

/// The minimum of `v` over the cells within `r` of each cell (clipped at the grid's faces)
/// along x, then over the x-y square, then over the cube: three separable passes.
fn cube_min(dims: [u32; 3], v: &[u32], r: u32) -> [Vec<u32>; 3] {
    let [nx, ny, nz] = dims.map(|d| d as usize);
    let r = r as usize;
    let pass = |a: &[u32], stride: usize, n: usize| -> Vec<u32> {
        (0..a.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|c| {
                let k = (c / stride) % n;
                let base = c - k * stride;
                let (lo, hi) = (k.saturating_sub(r), (k + r).min(n - 1));
                (lo..=hi)
                    .map(|t| a[base + t * stride])
                    .min()
                    .unwrap_or(u32::MAX)
            })
            .collect()
    };
    let x = pass(v, 1, nx);
    let xy = pass(&x, nx, ny);
    let xyz = pass(&xy, nx * ny, nz);
    [x, xy, xyz]
}

/// Vertex `k` of the joint strand ξ' of Eq. (4) (0-based: ξ(0..i), the average at i, then
/// ξ*(j+1..)).
#[inline]
fn joint_vertex(xi: &[V3], i: usize, avg: V3, cand: &[V3], j: usize, k: usize) -> V3 {
    if k < i {
        xi[k]
    } else if k == i {
        avg
    } else {
        cand[k - i + j]
    }
}

/// Everything the candidate search reads.
pub(super) struct Scorer<'a> {
    pub(super) grid: &'a Grid,
    pub(super) density: &'a [u32],
    pub(super) strands: &'a StrandSet,
    /// Where each strand of `strands` starts ([`StrandSet::offsets`]).
    pub(super) offsets: &'a [usize],
    pub(super) index: &'a VertexIndex,
    pub(super) radius: f32,
    pub(super) w_rho: f32,
    /// Gaussian weights exp(-d²/2σ_c²) for d = 0..=window (truncated below 1e-4).
    pub(super) weights: Vec<f32>,
}

impl Scorer<'_> {
    fn rho(&self, v: V3) -> u64 {
        self.grid.cell_of(v).map_or(0, |c| self.density[c] as u64)
    }

    /// The lowest-E_c joint of candidate `cand` with j ≤ `seed_at` (the candidate's seed
    /// vertex), if any vertex of S lies within the radius.
    pub(super) fn best_joint(&self, cand: &[V3], seed_at: usize) -> Option<(Joint, f32)> {
        let n = cand.len();
        // suffix[m] = Σ ρ over cand[m..].
        let mut suffix = vec![0u64; n + 1];
        for m in (0..n).rev() {
            suffix[m] = suffix[m + 1] + self.rho(cand[m]);
        }
        // The Laplacian terms that lie wholly on the candidate (0 at its ends, never read).
        let cand_lap: Vec<f32> = (0..n)
            .map(|m| {
                if m >= 1 && m + 1 < n {
                    lap_norm(cand[m - 1], cand[m], cand[m + 1])
                } else {
                    0.0
                }
            })
            .collect();
        let r2 = self.radius * self.radius;
        let win = self.weights.len() as isize - 1;
        let dims = self.grid.dims;
        let mut best: Option<(Joint, f32)> = None;
        // j + 1 must exist: a joint strand has to take something from the candidate; j ≤ the
        // seed, so that the joint strand passes where the seed was drawn (see the module doc).
        // Latest j first: suffix[j + 1] grows as j falls and bounds E_c from below, so once it
        // reaches the best energy no earlier j can win and the search stops.
        for j in (0..n.saturating_sub(1).min(seed_at + 1)).rev() {
            if best.is_some_and(|(_, e)| self.w_rho * suffix[j + 1] as f32 >= e) {
                break;
            }
            let q = cand[j];
            // Whether a least density prefix `v` already loses: no vertex with a prefix of at
            // least `v` passes the bound test the bucket loop makes per vertex (u32::MAX:
            // nothing there at all).
            let sj = suffix[j + 1];
            let loses = |v: u32, best: Option<(Joint, f32)>| {
                v == u32::MAX || best.is_some_and(|(_, e)| self.w_rho * (v as u64 + sj) as f32 >= e)
            };
            // q's cell: the row, slab and cube bounds are taken about it (none outside).
            let qc = self.grid.cell_of(q).map(|c| self.grid.coords(c));
            if qc.is_some_and(|c| {
                loses(
                    self.index.near_min[2][self.grid.index(c[0], c[1], c[2])],
                    best,
                )
            }) {
                continue;
            }
            let lo: [u32; 3] =
                std::array::from_fn(|a| (q[a] - self.radius).floor().max(0.0) as u32);
            let hi: [u32; 3] = std::array::from_fn(|a| {
                ((q[a] + self.radius).floor().max(0.0) as u32).min(dims[a] - 1)
            });
            // Cells whose box lies farther than the radius (with a margin far above f32
            // rounding) hold no vertex that passes the distance test below: skipped, the
            // corners of the search cube (~1/3 of its cells at radius 3).
            let gap = |c: u32, a: usize| {
                let d = (c as f32 - q[a]).max(q[a] - (c + 1) as f32).max(0.0);
                d * d
            };
            let reach = r2 * 1.001 + 1e-3;
            for z in lo[2]..=hi[2] {
                let gz = gap(z, 2);
                if qc.is_some_and(|c| {
                    loses(self.index.near_min[1][self.grid.index(c[0], c[1], z)], best)
                }) {
                    continue;
                }
                for y in lo[1]..=hi[1] {
                    let gzy = gz + gap(y, 1);
                    if gzy > reach
                        || qc.is_some_and(|c| {
                            loses(self.index.near_min[0][self.grid.index(c[0], y, z)], best)
                        })
                    {
                        continue;
                    }
                    for x in lo[0]..=hi[0] {
                        if gzy + gap(x, 0) > reach {
                            continue;
                        }
                        let cell = self.grid.index(x, y, z);
                        // Empty, or its cheapest vertex already loses (buckets are sorted).
                        if loses(self.index.cell_min[cell], best) {
                            continue;
                        }
                        for k in self.index.bucket(cell) {
                            let prefix = self.index.prefix_sorted[k];
                            let bound = prefix + suffix[j + 1];
                            if best.is_some_and(|(_, e)| self.w_rho * bound as f32 >= e) {
                                break;
                            }
                            let p = self.index.points_sorted[k];
                            let dv = sub(p, q);
                            if dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2] > r2 {
                                continue;
                            }
                            let g = self.index.ids[k] as usize;
                            let s = self.index.strand_of[g] as usize;
                            let start = self.offsets[s];
                            let i = g - start;
                            let avg = mid(p, q);
                            // Density term first: it is O(1) with the prefix sums and bounds E_c
                            // from below, so most pairs are rejected before the Laplacian.
                            let dens = prefix + self.rho(avg) + suffix[j + 1];
                            let e_rho = self.w_rho * dens as f32;
                            if best.is_some_and(|(_, e)| e_rho >= e) {
                                continue;
                            }
                            let xi = &self.strands.points[start..self.offsets[s + 1]];
                            let len = i + (n - j);
                            let mut e_s = 0.0f32;
                            for d in -win..=win {
                                let k = i as isize + d;
                                if k < 1 || k as usize + 1 >= len {
                                    continue;
                                }
                                let k = k as usize;
                                // Terms wholly on ξ or wholly on the candidate were computed
                                // once; only the three around the average depend on the pair.
                                let l = if k + 1 < i {
                                    self.index.lap[start + k]
                                } else if k > i + 1 {
                                    cand_lap[k - i + j]
                                } else {
                                    lap_norm(
                                        joint_vertex(xi, i, avg, cand, j, k - 1),
                                        joint_vertex(xi, i, avg, cand, j, k),
                                        joint_vertex(xi, i, avg, cand, j, k + 1),
                                    )
                                };
                                e_s += self.weights[d.unsigned_abs()] * l;
                            }
                            let e = e_s + e_rho;
                            // Strictly lower: ties keep the first found (a fixed order).
                            if best.is_none_or(|(_, b)| e < b) {
                                best = Some((
                                    Joint {
                                        s: s as u32,
                                        i: i as u32,
                                        j: j as u32,
                                    },
                                    e,
                                ));
                            }
                        }
                    }
                }
            }
        }
        best
    }
}

/// The Gaussian weights exp(-d²/2σ_c²) of Eq. (5) for d = 0, 1, … until they fall below 1e-4.
pub(super) fn laplacian_weights(sigma_c: f32) -> Vec<f32> {
    let win = (sigma_c * (2.0 * 1e4f32.ln()).sqrt()).ceil() as usize;
    (0..=win)
        .map(|d| (-((d * d) as f32) / (2.0 * sigma_c * sigma_c)).exp())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::cut_and_connect;
    use super::*;
    use crate::base::rng::Rng;

    /// The search's inputs for `strands` on `grid`: cell densities, offsets and the index.
    fn search_inputs(grid: &Grid, strands: &StrandSet) -> (Vec<u32>, Vec<usize>, VertexIndex) {
        let mut density = vec![0u32; grid.len()];
        for v in &strands.points {
            density[grid.cell_of(*v).unwrap()] += 1;
        }
        let off = strands.offsets();
        let index = VertexIndex::new(grid, strands, &off, &density, 3).unwrap();
        (density, off, index)
    }

    /// A scorer at the default radius, density weight and σ_c.
    fn scorer<'a>(
        grid: &'a Grid,
        strands: &'a StrandSet,
        (density, off, index): &'a (Vec<u32>, Vec<usize>, VertexIndex),
    ) -> Scorer<'a> {
        Scorer {
            grid,
            density,
            strands,
            offsets: off,
            index,
            radius: 3.0,
            w_rho: 0.01,
            weights: laplacian_weights(1.0),
        }
    }

    /// A candidate whose seed lies in an empty region and whose later part runs through
    /// dense cells: the density term of E_c alone would join it past the dense stretch (the
    /// shortest tail), leaving the seed's region empty; the bound keeps j at or before the
    /// seed.
    #[test]
    fn joints_do_not_skip_the_seed() {
        let grid = Grid {
            dims: [26, 12, 12],
            origin: [0.0; 3],
            cell: 1.0,
        };
        let line = |y: f32, x0: f32, x1: f32| -> Vec<V3> {
            let n = ((x1 - x0) / 0.5) as usize;
            (0..=n).map(|k| [x0 + 0.5 * k as f32, y, 6.5]).collect()
        };
        let mut strands = StrandSet::default();
        // One strand along y = 6, and ten along y = 8 up to x = 14 (the dense stretch).
        strands.push(&line(6.5, 0.5, 24.5));
        for _ in 0..10 {
            strands.push(&line(8.5, 0.5, 14.5));
        }
        let inputs = search_inputs(&grid, &strands);
        let scorer = scorer(&grid, &strands, &inputs);
        // The candidate runs along y = 8 (through the dense stretch, then beyond it); its
        // seed is vertex 4.
        let cand = line(8.5, 2.0, 24.0);
        let seed_at = 4;
        let (free, _) = scorer.best_joint(&cand, cand.len()).unwrap();
        assert!(
            free.j as usize > seed_at,
            "without the bound the joint should fall past the seed: {free:?}"
        );
        let (jt, _) = scorer.best_joint(&cand, seed_at).unwrap();
        assert!(jt.j as usize <= seed_at, "{jt:?}");
        // The joint strand passes the seed.
        let xi = strands.strand(jt.s as usize);
        let joined = cut_and_connect(xi, &cand, jt, 2.0, 2);
        let seed = cand[seed_at];
        assert!(
            joined.iter().any(|v| len3(sub(*v, seed)) < 0.75),
            "{joined:?}"
        );
    }

    /// |a − 2b + c|.
    fn lap_len(a: V3, b: V3, c: V3) -> f32 {
        len3([
            a[0] - 2.0 * b[0] + c[0],
            a[1] - 2.0 * b[1] + c[1],
            a[2] - 2.0 * b[2] + c[2],
        ])
    }

    /// E_c of one joint straight from Eq. (4)-(5): the joint strand built vertex by vertex,
    /// every weighted Laplacian term summed in order, plus w_ρ Σ ρ along it.
    fn reference_energy(sc: &Scorer, xi: &[V3], i: usize, cand: &[V3], j: usize) -> f32 {
        let avg = mid(xi[i], cand[j]);
        let len = i + (cand.len() - j);
        let win = sc.weights.len() as isize - 1;
        let mut e_s = 0.0f32;
        for d in -win..=win {
            let k = i as isize + d;
            if k < 1 || k as usize + 1 >= len {
                continue;
            }
            let k = k as usize;
            let a = joint_vertex(xi, i, avg, cand, j, k - 1);
            let b = joint_vertex(xi, i, avg, cand, j, k);
            let c = joint_vertex(xi, i, avg, cand, j, k + 1);
            e_s += sc.weights[d.unsigned_abs()] * lap_len(a, b, c);
        }
        let dens: u64 = (0..len)
            .map(|k| sc.rho(joint_vertex(xi, i, avg, cand, j, k)))
            .sum();
        e_s + sc.w_rho * dens as f32
    }

    /// The search (its density bounds, bucket order and early exits) finds the joint that
    /// exhaustive evaluation of E_c finds, with the same energy to the bit, on random curly
    /// strands and candidates.
    #[test]
    fn the_joint_search_equals_exhaustive_evaluation() {
        let grid = Grid {
            dims: [16, 16, 16],
            origin: [0.0; 3],
            cell: 1.0,
        };
        let mut rng = Rng::new(7);
        let walk = |rng: &mut Rng, n: usize| -> Vec<V3> {
            let mut p = [
                rng.range_f32(4.0, 12.0),
                rng.range_f32(4.0, 12.0),
                rng.range_f32(4.0, 12.0),
            ];
            let mut dir = [0.5f32, 0.0, 0.0];
            (0..n)
                .map(|_| {
                    let v = p;
                    for c in &mut dir {
                        *c += rng.range_f32(-0.2, 0.2);
                    }
                    let l = len3(dir).max(1e-3);
                    for a in 0..3 {
                        p[a] = (p[a] + 0.5 * dir[a] / l).clamp(0.01, 15.99);
                    }
                    v
                })
                .collect()
        };
        let mut strands = StrandSet::default();
        for _ in 0..40 {
            let n = 3 + (rng.next_f32() * 20.0) as usize;
            strands.push(&walk(&mut rng, n));
        }
        let inputs = search_inputs(&grid, &strands);
        let sc = scorer(&grid, &strands, &inputs);
        let mut found = 0;
        for _ in 0..60 {
            let n = 2 + (rng.next_f32() * 16.0) as usize;
            let cand = walk(&mut rng, n);
            let seed_at = (rng.next_f32() * n as f32) as usize;
            let got = sc.best_joint(&cand, seed_at);
            // Exhaustive: every (strand vertex i ≥ 1 within the radius, j ≤ seed, j + 1 < n).
            let mut want: Option<f32> = None;
            for s in 0..strands.len() {
                let xi = strands.strand(s);
                for i in 1..xi.len() {
                    for j in 0..n.saturating_sub(1).min(seed_at + 1) {
                        if len3(sub(xi[i], cand[j])) > sc.radius {
                            continue;
                        }
                        let e = reference_energy(&sc, xi, i, &cand, j);
                        want = Some(want.map_or(e, |w: f32| w.min(e)));
                    }
                }
            }
            match (got, want) {
                (None, None) => {}
                (Some((jt, e)), Some(w)) => {
                    found += 1;
                    assert_eq!(e.to_bits(), w.to_bits(), "{jt:?}: {e} against {w}");
                    let xi = strands.strand(jt.s as usize);
                    let again = reference_energy(&sc, xi, jt.i as usize, &cand, jt.j as usize);
                    assert_eq!(again.to_bits(), e.to_bits(), "{jt:?}");
                }
                (g, w) => panic!("search {g:?} against exhaustive {w:?}"),
            }
        }
        assert!(found > 30, "only {found} candidates had a joint");
    }

    /// The row, slab and cube minima equal a brute-force minimum over the clipped box.
    #[test]
    fn cube_min_is_the_minimum_over_the_clipped_box() {
        let dims = [7u32, 5, 6];
        let n = (dims[0] * dims[1] * dims[2]) as usize;
        let mut rng = Rng::new(5);
        let v: Vec<u32> = (0..n)
            .map(|_| {
                if rng.below(4) == 0 {
                    u32::MAX
                } else {
                    rng.below(1000)
                }
            })
            .collect();
        let r = 2i64;
        let [x, xy, xyz] = cube_min(dims, &v, r as u32);
        let at = |p: [i64; 3]| v[(p[0] + 7 * (p[1] + 5 * p[2])) as usize];
        for c in 0..n {
            let p = [(c % 7) as i64, ((c / 7) % 5) as i64, (c / 35) as i64];
            let mut m = [u32::MAX; 3];
            for dz in -r..=r {
                for dy in -r..=r {
                    for dx in -r..=r {
                        let q = [p[0] + dx, p[1] + dy, p[2] + dz];
                        if (0..3).any(|a| q[a] < 0 || q[a] >= dims[a] as i64) {
                            continue;
                        }
                        let val = at(q);
                        if dy == 0 && dz == 0 {
                            m[0] = m[0].min(val);
                        }
                        if dz == 0 {
                            m[1] = m[1].min(val);
                        }
                        m[2] = m[2].min(val);
                    }
                }
            }
            assert_eq!([x[c], xy[c], xyz[c]], m, "cell {p:?}");
        }
    }
}
