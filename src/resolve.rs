//! Growth-direction resolution, C13 Eq. (1)-(2): choose s_i ∈ {-1, 1} per curve to maximise
//! Σ_i P(γ_i), P(γ_i) = Σ_j Σ_{γ_p(q) ∈ N_i(j)} t̂_i(j) · t̂_p(q), with N_i(j) the vertices of
//! resolved curves (user strokes included, weight w_m) within the radius of γ_i(j).
//!
//! The paper's greedy algorithm: a resolved set (the strokes at first), a max-heap of
//! tentative curves keyed by |P| and the ambiguous rest. The heap's top is resolved with
//! s = sign(P) and its neighbours' P updated. Sequential by nature, so on the CPU; the
//! curve-pair sums are computed once, in parallel, through a uniform grid.

use crate::trace::Curve;
use rayon::prelude::*;
use std::collections::BinaryHeap;

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ResolveParams {
    /// Neighbourhood radius (px); 70 in C13.
    pub radius: f32,
    /// Weight of a user stroke's vertices (w_m = 10 in C13).
    pub stroke_weight: f32,
}

impl Default for ResolveParams {
    fn default() -> Self {
        ResolveParams {
            radius: 70.0,
            stroke_weight: 10.0,
        }
    }
}

#[derive(Clone, Debug)]
pub struct Resolved {
    /// Every input curve, its points ordered root→tip.
    pub curves: Vec<Curve>,
    /// Whether each curve was reversed.
    pub flipped: Vec<bool>,
    /// Curves that no stroke reached through resolved neighbours: when the heap ran dry, the
    /// longest of them was resolved along its traced order (its P was 0) and the rest then
    /// by the same rule through it.
    pub unreachable: Vec<usize>,
    /// Curves in the order they were resolved.
    pub order: Vec<usize>,
}

/// Intrinsic unit directions t̃: from the previous to the next vertex (one-sided at ends).
fn tangents(pts: &[[f32; 2]]) -> Vec<[f32; 2]> {
    let n = pts.len();
    (0..n)
        .map(|j| {
            let a = pts[j.saturating_sub(1)];
            let b = pts[(j + 1).min(n - 1)];
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let m = dx.hypot(dy).max(1e-12);
            [dx / m, dy / m]
        })
        .collect()
}

/// Cells per radius: a vertex's neighbourhood spans (2 CELLS + 1)² cells, most of them
/// entirely inside its disc, where a curve's vertices count as one precomputed tangent sum.
const CELLS: i64 = 6;

/// One polyline's vertices in one cell: (polyline, Σ tangent, range into `Grid::verts`).
type CellEntry = (u32, [f32; 2], std::ops::Range<u32>);

/// Vertices bucketed in square cells of radius / CELLS, with per-cell, per-polyline sums of
/// the tangents so fully covered cells cost one product per polyline.
struct Grid {
    cell: f32,
    nx: usize,
    ny: usize,
    /// Per cell: (polyline, Σ tangent, range into `verts`).
    entries: Vec<Vec<CellEntry>>,
    /// Vertex positions and tangents, grouped by cell and polyline.
    verts: Vec<([f32; 2], [f32; 2])>,
}

impl Grid {
    fn new(lines: &[&[[f32; 2]]], tans: &[Vec<[f32; 2]>], cell: f32) -> Self {
        let (mut x1, mut y1) = (0.0f32, 0.0f32);
        for p in lines.iter().flat_map(|l| l.iter()) {
            x1 = x1.max(p[0]);
            y1 = y1.max(p[1]);
        }
        // Image coordinates are >= 0; the grid covers [0, max] (negatives clamp to cell 0).
        let nx = ((x1 / cell) as usize + 2).min(1 << 14);
        let ny = ((y1 / cell) as usize + 2).min(1 << 14);
        let mut keyed: Vec<(usize, u32, [f32; 2], [f32; 2])> = lines
            .iter()
            .enumerate()
            .flat_map(|(li, l)| {
                l.iter().enumerate().map(move |(vi, p)| {
                    (Self::cell_of(cell, nx, ny, *p), li as u32, *p, tans[li][vi])
                })
            })
            .collect();
        keyed.sort_by_key(|k| (k.0, k.1));
        let mut entries = vec![Vec::new(); nx * ny];
        let mut verts = Vec::with_capacity(keyed.len());
        let mut k = 0;
        while k < keyed.len() {
            let (c, l) = (keyed[k].0, keyed[k].1);
            let start = verts.len() as u32;
            let mut sum = [0.0f32; 2];
            while k < keyed.len() && keyed[k].0 == c && keyed[k].1 == l {
                sum[0] += keyed[k].3[0];
                sum[1] += keyed[k].3[1];
                verts.push((keyed[k].2, keyed[k].3));
                k += 1;
            }
            entries[c].push((l, sum, start..verts.len() as u32));
        }
        Grid {
            cell,
            nx,
            ny,
            entries,
            verts,
        }
    }

    fn cell_of(cell: f32, nx: usize, ny: usize, p: [f32; 2]) -> usize {
        let cx = ((p[0].max(0.0) / cell) as usize).min(nx - 1);
        let cy = ((p[1].max(0.0) / cell) as usize).min(ny - 1);
        cy * nx + cx
    }
}

/// For every curve, Σ over its vertex pairs with each other polyline within the radius of
/// t̃_a · t̃_b, as a sparse row: (other polyline, sum).
///
/// Cell against cell: where every point of one cell is within the radius of every point of
/// the other, the pairs contribute the product of the two cells' tangent sums at once; only
/// cell pairs the radius cuts through are summed vertex by vertex.
fn pair_sums(
    lines: &[&[[f32; 2]]],
    tans: &[Vec<[f32; 2]>],
    n_curves: usize,
    radius: f32,
) -> Vec<Vec<(u32, f32)>> {
    let grid = Grid::new(lines, tans, radius / CELLS as f32);
    let r2 = radius * radius;
    let cs = grid.cell;
    // The cells each curve has vertices in, with the entry index there.
    let mut own: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n_curves];
    for (c, es) in grid.entries.iter().enumerate() {
        for (k, e) in es.iter().enumerate() {
            if (e.0 as usize) < n_curves {
                own[e.0 as usize].push((c as u32, k as u32));
            }
        }
    }
    (0..n_curves)
        .into_par_iter()
        .map_init(
            || {
                (
                    vec![0.0f32; lines.len()],
                    vec![u32::MAX; lines.len()],
                    Vec::<u32>::new(),
                )
            },
            |(acc, stamp, touched), i| {
                let mut add = |l: usize, s: f32| {
                    // Stamps mark the polylines this curve touched, once each.
                    if stamp[l] != i as u32 {
                        stamp[l] = i as u32;
                        acc[l] = 0.0;
                        touched.push(l as u32);
                    }
                    acc[l] += s;
                };
                for &(ci, k) in &own[i] {
                    let (_, ti, ref vi) = grid.entries[ci as usize][k as usize];
                    let (cx, cy) = (
                        (ci as usize % grid.nx) as i64,
                        (ci as usize / grid.nx) as i64,
                    );
                    for gy in (cy - CELLS - 1).max(0)..=(cy + CELLS + 1).min(grid.ny as i64 - 1) {
                        let oy = (gy - cy).abs();
                        // Nearest and farthest gaps between the two cells along y.
                        let (ny_, fy) = ((oy - 1).max(0) as f32 * cs, (oy + 1) as f32 * cs);
                        for gx in (cx - CELLS - 1).max(0)..=(cx + CELLS + 1).min(grid.nx as i64 - 1)
                        {
                            let ox = (gx - cx).abs();
                            let (nx_, fx) = ((ox - 1).max(0) as f32 * cs, (ox + 1) as f32 * cs);
                            if nx_ * nx_ + ny_ * ny_ > r2 {
                                continue;
                            }
                            let inside = fx * fx + fy * fy <= r2;
                            for (l, tl, vl) in &grid.entries[gy as usize * grid.nx + gx as usize] {
                                let l = *l as usize;
                                if l == i {
                                    continue;
                                }
                                let s = if inside {
                                    ti[0] * tl[0] + ti[1] * tl[1]
                                } else {
                                    // The radius cuts through: decide per vertex of this
                                    // curve against the whole cell first.
                                    let (bx0, by0) = (gx as f32 * cs, gy as f32 * cs);
                                    let (bx1, by1) = (bx0 + cs, by0 + cs);
                                    let bs = &grid.verts[vl.start as usize..vl.end as usize];
                                    let mut s = 0.0;
                                    for (pa, ta) in &grid.verts[vi.start as usize..vi.end as usize]
                                    {
                                        let ddx = (bx0 - pa[0]).max(pa[0] - bx1).max(0.0);
                                        let ddy = (by0 - pa[1]).max(pa[1] - by1).max(0.0);
                                        if ddx * ddx + ddy * ddy > r2 {
                                            continue;
                                        }
                                        let fdx = (pa[0] - bx0).abs().max((pa[0] - bx1).abs());
                                        let fdy = (pa[1] - by0).abs().max((pa[1] - by1).abs());
                                        if fdx * fdx + fdy * fdy <= r2 {
                                            s += ta[0] * tl[0] + ta[1] * tl[1];
                                            continue;
                                        }
                                        for (pb, tb) in bs {
                                            let (dx, dy) = (pa[0] - pb[0], pa[1] - pb[1]);
                                            if dx * dx + dy * dy <= r2 {
                                                s += ta[0] * tb[0] + ta[1] * tb[1];
                                            }
                                        }
                                    }
                                    s
                                };
                                add(l, s);
                            }
                        }
                    }
                }
                touched.sort_unstable();
                let row: Vec<(u32, f32)> = touched
                    .iter()
                    .map(|&l| (l, acc[l as usize]))
                    .filter(|e| e.1 != 0.0)
                    .collect();
                touched.clear();
                row
            },
        )
        .collect()
}

/// Heap entry: |P| first, then the lower curve index (deterministic ties), and a version
/// stamp so stale entries are skipped (lazy priority updates).
#[derive(PartialEq)]
struct Entry {
    key: f32,
    curve: u32,
    version: u32,
}

impl Eq for Entry {}
impl Ord for Entry {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.key
            .total_cmp(&o.key)
            .then_with(|| o.curve.cmp(&self.curve))
    }
}
impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}

pub fn resolve_directions(
    curves: &[Curve],
    strokes: &[Vec<[f32; 2]>],
    p: &ResolveParams,
) -> Resolved {
    let n = curves.len();
    // Polylines 0..n are the curves, n.. the strokes (resampled like the curves so a stroke
    // votes per unit length, times w_m).
    let spacing = curves
        .iter()
        .find(|c| c.points.len() > 1)
        .map_or(2.0, |c| {
            (c.points[1][0] - c.points[0][0]).hypot(c.points[1][1] - c.points[0][1])
        })
        .max(0.5);
    let strokes_rs: Vec<Vec<[f32; 2]>> = strokes
        .iter()
        .map(|s| crate::trace::resample(s, spacing))
        .collect();
    let lines: Vec<&[[f32; 2]]> = curves
        .iter()
        .map(|c| c.points.as_slice())
        .chain(strokes_rs.iter().map(|s| s.as_slice()))
        .collect();
    let tans: Vec<Vec<[f32; 2]>> = lines.iter().map(|l| tangents(l)).collect();
    let sums = pair_sums(&lines, &tans, n, p.radius);
    // P with every curve at s = +1 against the strokes, the initially resolved set.
    let mut score: Vec<f32> = sums
        .iter()
        .map(|row| {
            row.iter()
                .filter(|(l, _)| *l as usize >= n)
                .map(|(_, s)| p.stroke_weight * s)
                .sum()
        })
        .collect();
    let mut version = vec![0u32; n];
    let mut resolved = vec![false; n];
    let mut sign = vec![1.0f32; n];
    let mut heap: BinaryHeap<Entry> = (0..n)
        .filter(|&i| score[i] != 0.0)
        .map(|i| Entry {
            key: score[i].abs(),
            curve: i as u32,
            version: 0,
        })
        .collect();
    let mut order = Vec::with_capacity(n);
    let mut unreachable = Vec::new();
    let mut remaining = n;
    while remaining > 0 {
        let next = loop {
            match heap.pop() {
                Some(e)
                    if !resolved[e.curve as usize] && e.version == version[e.curve as usize] =>
                {
                    break Some(e.curve as usize)
                }
                Some(_) => continue,
                None => break None,
            }
        };
        let i = match next {
            Some(i) => i,
            None => {
                // Nothing resolved reaches the rest: start from the longest ambiguous curve.
                let i = (0..n)
                    .filter(|&i| !resolved[i])
                    .max_by(|&a, &b| {
                        curves[a]
                            .points
                            .len()
                            .cmp(&curves[b].points.len())
                            .then(b.cmp(&a))
                    })
                    .expect("a curve remains");
                unreachable.push(i);
                i
            }
        };
        resolved[i] = true;
        remaining -= 1;
        sign[i] = if score[i] < 0.0 { -1.0 } else { 1.0 };
        order.push(i);
        for &(j, s) in &sums[i] {
            let j = j as usize;
            if j >= n || resolved[j] {
                continue;
            }
            score[j] += sign[i] * s;
            version[j] += 1;
            heap.push(Entry {
                key: score[j].abs(),
                curve: j as u32,
                version: version[j],
            });
        }
    }
    // Every curve resolved after an unreachable seed, through it, is unreachable from the
    // strokes too.
    let mut from_seed = vec![false; n];
    let mut seen_seed = false;
    for &i in &order {
        if unreachable.contains(&i) {
            seen_seed = true;
        }
        from_seed[i] = seen_seed;
    }
    let unreachable: Vec<usize> = order.iter().copied().filter(|&i| from_seed[i]).collect();
    let flipped: Vec<bool> = sign.iter().map(|&s| s < 0.0).collect();
    let curves = curves
        .iter()
        .zip(&flipped)
        .map(|(c, &f)| {
            let mut pts = c.points.clone();
            if f {
                pts.reverse();
            }
            Curve { points: pts }
        })
        .collect();
    Resolved {
        curves,
        flipped,
        unreachable,
        order,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(x0: f32, y0: f32, dx: f32, dy: f32, n: usize) -> Curve {
        Curve {
            points: (0..n)
                .map(|k| [x0 + k as f32 * dx, y0 + k as f32 * dy])
                .collect(),
        }
    }

    #[test]
    fn curves_follow_a_stroke_through_their_neighbours() {
        // Parallel curves 10 px apart, alternately traced the wrong way; one stroke at the
        // top points +x. The chain must carry the direction to curves far beyond 70 px.
        let curves: Vec<Curve> = (0..30)
            .map(|k| {
                let c = line(10.0, 10.0 + 10.0 * k as f32, 2.0, 0.0, 40);
                if k % 2 == 1 {
                    Curve {
                        points: c.points.into_iter().rev().collect(),
                    }
                } else {
                    c
                }
            })
            .collect();
        let stroke = vec![[10.0, 5.0], [80.0, 5.0]];
        let r = resolve_directions(&curves, &[stroke], &ResolveParams::default());
        for c in &r.curves {
            assert!(
                c.points.last().unwrap()[0] > c.points[0][0],
                "a curve points -x"
            );
        }
        assert!(r.unreachable.is_empty());
        for (k, &f) in r.flipped.iter().enumerate() {
            assert_eq!(f, k % 2 == 1);
        }
    }

    #[test]
    fn a_far_curve_is_reported_unreachable_and_still_resolved() {
        let curves = vec![
            line(0.0, 0.0, 2.0, 0.0, 20),
            line(1000.0, 1000.0, 2.0, 0.0, 20),
        ];
        let r = resolve_directions(
            &curves,
            &[vec![[0.0, 5.0], [30.0, 5.0]]],
            &ResolveParams::default(),
        );
        assert_eq!(r.unreachable, vec![1]);
        assert_eq!(r.order.len(), 2);
    }

    #[test]
    fn opposite_strokes_split_the_curves_at_a_part() {
        // Left half flows -x, right half +x (a side part); strokes on each side.
        let mut curves = Vec::new();
        for k in 0..10 {
            curves.push(line(100.0, 10.0 * k as f32, -2.0, 0.0, 30)); // left, traced -x
            curves.push(line(104.0, 10.0 * k as f32 + 5.0, 2.0, 0.0, 30)); // right, +x
        }
        // Trace half of them the wrong way round.
        for c in curves.iter_mut().step_by(3) {
            c.points.reverse();
        }
        let strokes = vec![
            vec![[90.0, 45.0], [40.0, 45.0]],
            vec![[114.0, 45.0], [164.0, 45.0]],
        ];
        let r = resolve_directions(
            &curves,
            &strokes,
            &ResolveParams {
                radius: 30.0,
                ..Default::default()
            },
        );
        for c in &r.curves {
            let right = c.points.iter().map(|p| p[0]).sum::<f32>() / c.points.len() as f32 > 102.0;
            let goes_right = c.points.last().unwrap()[0] > c.points[0][0];
            assert_eq!(right, goes_right);
        }
    }
}
