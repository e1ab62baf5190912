//! Growth-direction resolution of undirected 2-D curves (C13 §2.1, "Resolving Directional
//! Ambiguity", Eq. (1)-(2)).
//!
//! Each curve γ_i has intrinsic directions t̃_i(j) (unit, from γ_i(j-1) to γ_i(j+1); one-sided
//! at the two ends) and an unknown flag s_i ∈ {-1, 1}, so t̂_i(j) = s_i t̃_i(j). User strokes
//! are "represented in the same way" (resampled to the curves' vertex spacing) but, since
//! their order is known, the flag is replaced by the global weight w_m: t̂ = w_m t̃, i.e. each
//! stroke vertex counts w_m times in P. The score of Eq. (1) is
//!
//!   P(γ_i) = Σ_j Σ_{γ_p(q) ∈ N_i(j)} t̂_i(j) · t̂_p(q),
//!
//! with N_i(j) the vertices of *other, already resolved* curves (strokes included) within
//! `radius` of γ_i(j). Eq. (2) is maximised greedily, as in the paper: the resolved set starts
//! as the strokes; every ambiguous curve with a vertex within `radius` of a resolved vertex
//! becomes tentative, in a max-heap keyed by |P|; the top is popped, given the s that makes P
//! non-negative (s = +1, the traced order, when P = 0) and resolved, and the P of the
//! tentative curves near it is updated. The heap is lazy: every update pushes a new entry with
//! a version stamp and stale entries are skipped when popped. Ties pop the lower curve index
//! first, so the result is deterministic.
//!
//! Unreachable curves: when the heap runs dry while ambiguous curves remain, those curves have
//! no chain of neighbours to any stroke. They are all listed in [`Resolved::unreachable`]. The
//! algorithm then goes on with a seed: the largest remaining curve (most vertices, then lowest
//! index) is resolved *keeping its traced order* (s = +1, there is no evidence either way),
//! after which its neighbours become tentative and are resolved by the same rule as above;
//! this repeats until every curve is resolved. So an unreachable curve is resolved consistently
//! with its own neighbourhood, but each such group's overall direction is arbitrary; callers
//! that need certainty should ask the user for a stroke there.
//!
//! One departure ([`resolve_directions_apart`]): curves and strokes on opposite sides of a
//! parting line found among the traced curves' cuts ([`crate::analyze::parting`]) do not
//! vote on each other, since hair grows away from a part on both sides.
//!
//! Cost: every (resolved vertex, unresolved vertex) pair within `radius` contributes once, when
//! the first of the two is resolved. Unresolved vertices live in a uniform grid (the spatial
//! index) of cells `radius / 3` wide, grouped per (cell, curve) with a pre-summed direction.
//! A newly resolved curve's vertices are grouped by the same cells; a target cell wholly
//! within the radius of a whole group costs one dot product per curve crossing it, one wholly
//! within the radius of a single vertex likewise, and only cells cut by a vertex's disc rim
//! are checked vertex by vertex (in a branch-free, vectorisable loop). Coarse cells won in
//! measurements: fewer, larger groups and longer vectorised loops beat tighter rims.

use crate::analyze::parting::{PartingLine, MAX_LINES};
use crate::analyze::trace::Curve;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Resolution parameters.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ResolveParams {
    /// Neighbourhood radius of Eq. (1), pixels (70 in the paper).
    pub radius: f32,
    /// Weight w_m of user strokes (10 in the paper).
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

/// Directed curves.
#[derive(Clone, Debug, PartialEq)]
pub struct Resolved {
    /// Every input curve, same indices, points reordered root -> tip.
    pub curves: Vec<Curve>,
    /// Whether curve i was reversed relative to its input order.
    pub flipped: Vec<bool>,
    /// Curves (ascending) that had no resolved neighbour within the radius when the heap ran
    /// dry: not connected to any stroke. They were resolved afterwards from seeds (the largest
    /// remaining curve keeps its traced order) and their neighbours; see the module doc.
    pub unreachable: Vec<usize>,
    /// Curve indices in the order they were resolved.
    pub order: Vec<usize>,
}

/// Resolves the growth direction of `curves` from direction `strokes` (points root -> tip).
/// Curves with fewer than two vertices have no direction; they are resolved (kept as they
/// are) without influencing anything. Deterministic.
pub fn resolve_directions(
    curves: &[Curve],
    strokes: &[Vec<[f32; 2]>],
    p: &ResolveParams,
) -> Resolved {
    resolve_directions_apart(curves, strokes, &[], p)
}

/// The sides of `lines` that `pts` lie on within `reach`, as bits: line k sets bit 2k for
/// side 1 and bit 2k + 1 for side -1 ([`PartingLine::side`]).
fn side_bits(pts: &[[f32; 2]], lines: &[PartingLine], reach: f32) -> u64 {
    let mut bits = 0u64;
    for (k, l) in lines.iter().take(MAX_LINES).enumerate() {
        match l.side(pts, reach) {
            1 => bits |= 1 << (2 * k),
            -1 => bits |= 1 << (2 * k + 1),
            _ => {}
        }
    }
    bits
}

/// Whether two side sets lie on opposite sides of some line.
fn apart(a: u64, b: u64) -> bool {
    const POS: u64 = 0x5555_5555_5555_5555;
    let (pa, na) = (a & POS, (a >> 1) & POS);
    let (pb, nb) = (b & POS, (b >> 1) & POS);
    (pa & nb) | (na & pb) != 0
}

/// [`resolve_directions`] where curves (and strokes) on opposite sides of a detected parting
/// (`lines`, from [`crate::analyze::parting::parting_lines`]) do not vote on each other in
/// Eq. (1): hair grows away from a part on both sides, so a neighbour across it is evidence
/// for the wrong direction, however near. A curve crossing a line (not cut there) votes with
/// both sides, as does every curve beyond the line's ends or farther than the radius.
pub fn resolve_directions_apart(
    curves: &[Curve],
    strokes: &[Vec<[f32; 2]>],
    lines: &[PartingLine],
    p: &ResolveParams,
) -> Resolved {
    let n = curves.len();
    let radius = if p.radius.is_finite() && p.radius > 0.0 {
        p.radius
    } else {
        0.0
    };
    let tangents: Vec<Vec<[f32; 2]>> = curves.iter().map(|c| intrinsic(&c.points)).collect();

    // Strokes are resampled to the curves' spacing, so that w_m means the same per unit
    // length as one curve's vertices.
    let (mut seg_len, mut segs) = (0.0f64, 0usize);
    for c in curves {
        seg_len += crate::analyze::trace::polyline_len(&c.points) as f64;
        segs += c.points.len().saturating_sub(1);
    }
    let spacing = if segs > 0 && seg_len > 0.0 {
        (seg_len / segs as f64) as f32
    } else {
        2.0
    };

    let grid = Grid::new(curves, &tangents, radius);
    let sides: Vec<u64> = curves
        .iter()
        .map(|c| side_bits(&c.points, lines, radius))
        .collect();
    let mut st = State {
        grid,
        sides,
        from: 0,
        r2: radius * radius,
        p_score: vec![0.0; n],
        status: vec![Status::Ambiguous; n],
        version: vec![0; n],
        touched: Vec::new(),
        touch_mark: vec![false; n],
        heap: BinaryHeap::new(),
        dots: Vec::new(),
        hits: Vec::new(),
    };

    for s in strokes {
        let pts = crate::analyze::trace::resample(s, spacing);
        let t = intrinsic(&pts);
        let t: Vec<[f32; 2]> = t
            .iter()
            .map(|d| [d[0] * p.stroke_weight, d[1] * p.stroke_weight])
            .collect();
        st.from = side_bits(&pts, lines, radius);
        st.push_resolved(&pts, &t);
    }
    st.enqueue_touched();

    let mut flipped = vec![false; n];
    let mut order = Vec::with_capacity(n);
    let mut unreachable: Option<Vec<usize>> = None;
    let mut remaining = n;
    while remaining > 0 {
        let i = match st.pop() {
            Some(i) => i,
            None => {
                // Nothing reaches the rest from the resolved set: report and seed.
                let rest: Vec<usize> = (0..n)
                    .filter(|&i| st.status[i] == Status::Ambiguous)
                    .collect();
                let seed = *rest
                    .iter()
                    .max_by(|&&a, &&b| {
                        curves[a]
                            .points
                            .len()
                            .cmp(&curves[b].points.len())
                            .then(b.cmp(&a))
                    })
                    .expect("remaining > 0 means an ambiguous curve is left");
                unreachable.get_or_insert(rest);
                // The seed keeps its traced order: P is 0 for it, so the rule gives s = +1.
                st.p_score[seed] = 0.0;
                seed
            }
        };
        let s = if st.p_score[i] >= 0.0 { 1.0 } else { -1.0 };
        flipped[i] = s < 0.0;
        st.status[i] = Status::Resolved;
        order.push(i);
        remaining -= 1;
        let t: Vec<[f32; 2]> = tangents[i].iter().map(|d| [s * d[0], s * d[1]]).collect();
        st.from = st.sides[i];
        st.push_resolved(&curves[i].points, &t);
        st.enqueue_touched();
    }

    let curves_out = curves
        .iter()
        .zip(&flipped)
        .map(|(c, &f)| {
            let mut points = c.points.clone();
            if f {
                points.reverse();
            }
            Curve { points }
        })
        .collect();
    Resolved {
        curves: curves_out,
        flipped,
        unreachable: unreachable.unwrap_or_default(),
        order,
    }
}

/// Unit intrinsic directions t̃: γ(j-1) -> γ(j+1), one-sided at the ends; zero where the
/// curve has no extent.
pub(crate) fn intrinsic(pts: &[[f32; 2]]) -> Vec<[f32; 2]> {
    let m = pts.len();
    (0..m)
        .map(|j| {
            if m < 2 {
                return [0.0, 0.0];
            }
            let a = pts[j.saturating_sub(1)];
            let b = pts[(j + 1).min(m - 1)];
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let l = dx.hypot(dy);
            if l > 0.0 {
                [dx / l, dy / l]
            } else {
                [0.0, 0.0]
            }
        })
        .collect()
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Status {
    Ambiguous,
    Tentative,
    Resolved,
}

/// A lazy heap entry: |P| at push time, the curve, and its version then.
struct Entry {
    prio: f64,
    curve: usize,
    version: u32,
}

impl PartialEq for Entry {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        // Max-heap on priority; on ties the lower curve index is "greater", so it pops first.
        self.prio
            .total_cmp(&o.prio)
            .then(o.curve.cmp(&self.curve))
            .then(self.version.cmp(&o.version))
    }
}

/// The vertices of one curve inside one cell, with their directions pre-summed.
#[derive(Clone, Copy)]
struct Run {
    curve: u32,
    start: u32,
    end: u32,
    sum: [f32; 2],
}

/// Uniform grid over the unresolved-curve vertices, grouped by (cell, curve).
struct Grid {
    x0: f32,
    y0: f32,
    cell: f32,
    nx: usize,
    ny: usize,
    /// Runs of cell c: runs[cell_runs[c]..cell_runs[c + 1]].
    cell_runs: Vec<u32>,
    runs: Vec<Run>,
    /// Vertex positions and intrinsic directions, in run order; separate arrays so that the
    /// rim loop vectorises.
    px: Vec<f32>,
    py: Vec<f32>,
    tx: Vec<f32>,
    ty: Vec<f32>,
}

impl Grid {
    fn new(curves: &[Curve], tangents: &[Vec<[f32; 2]>], radius: f32) -> Grid {
        let (mut x0, mut y0) = (f32::INFINITY, f32::INFINITY);
        let (mut x1, mut y1) = (f32::NEG_INFINITY, f32::NEG_INFINITY);
        for q in curves.iter().flat_map(|c| &c.points) {
            x0 = x0.min(q[0]);
            y0 = y0.min(q[1]);
            x1 = x1.max(q[0]);
            y1 = y1.max(q[1]);
        }
        if !(x0 <= x1 && y0 <= y1) {
            (x0, y0, x1, y1) = (0.0, 0.0, 0.0, 0.0);
        }
        // Three cells per radius (measured: 8 per radius was 2x slower, see the module doc).
        let cell = (radius / 3.0).max(1.0);
        // Cap the grid for degenerate inputs (a few far-flung points): coarser cells only cost
        // more per-vertex checks, never correctness.
        let span = (x1 - x0).max(y1 - y0);
        let cell = cell.max(span / 2048.0);
        let nx = ((x1 - x0) / cell) as usize + 1;
        let ny = ((y1 - y0) / cell) as usize + 1;

        let mut items: Vec<(u32, u32, u32)> = Vec::new();
        for (i, c) in curves.iter().enumerate() {
            for (j, q) in c.points.iter().enumerate() {
                let cx = (((q[0] - x0) / cell) as usize).min(nx - 1);
                let cy = (((q[1] - y0) / cell) as usize).min(ny - 1);
                items.push(((cy * nx + cx) as u32, i as u32, j as u32));
            }
        }
        items.sort_unstable();
        let mut cell_runs = vec![0u32; nx * ny + 1];
        let mut runs: Vec<Run> = Vec::new();
        let m = items.len();
        let (mut px, mut py) = (Vec::with_capacity(m), Vec::with_capacity(m));
        let (mut tx, mut ty) = (Vec::with_capacity(m), Vec::with_capacity(m));
        for (k, &(c, i, j)) in items.iter().enumerate() {
            let t = tangents[i as usize][j as usize];
            let new_run = k == 0 || items[k - 1].0 != c || items[k - 1].1 != i;
            if new_run {
                runs.push(Run {
                    curve: i,
                    start: k as u32,
                    end: k as u32,
                    sum: [0.0, 0.0],
                });
                cell_runs[c as usize + 1] += 1;
            }
            let r = runs.last_mut().expect("a run was just pushed");
            r.end += 1;
            r.sum[0] += t[0];
            r.sum[1] += t[1];
            let q = curves[i as usize].points[j as usize];
            px.push(q[0]);
            py.push(q[1]);
            tx.push(t[0]);
            ty.push(t[1]);
        }
        for c in 0..nx * ny {
            cell_runs[c + 1] += cell_runs[c];
        }
        Grid {
            x0,
            y0,
            cell,
            nx,
            ny,
            cell_runs,
            runs,
            px,
            py,
            tx,
            ty,
        }
    }
}

struct State {
    grid: Grid,
    /// Each curve's sides of the parting lines ([`side_bits`]).
    sides: Vec<u64>,
    /// The sides of what `push_resolved` is adding: it skips curves [`apart`] from it.
    from: u64,
    r2: f32,
    /// P of each curve with s = +1 (its traced order), accumulated over resolved neighbours.
    p_score: Vec<f64>,
    status: Vec<Status>,
    version: Vec<u32>,
    /// Unresolved curves whose P changed (or that gained a resolved neighbour) since the last
    /// `enqueue_touched`.
    touched: Vec<usize>,
    touch_mark: Vec<bool>,
    heap: BinaryHeap<Entry>,
    /// Per-vertex scratch of one rim cell: summed dot products and hit counts.
    dots: Vec<f32>,
    hits: Vec<f32>,
}

impl State {
    /// Adds newly resolved vertices `pts` with directed tangents `t` to the P of every
    /// unresolved curve with a vertex within the radius. The vertices are grouped by grid
    /// cell first: a target cell within the radius of the whole group's bounding box takes
    /// one dot product per run with the group's summed direction; only the others are
    /// resolved vertex by vertex.
    fn push_resolved(&mut self, pts: &[[f32; 2]], t: &[[f32; 2]]) {
        if self.grid.runs.is_empty() || pts.is_empty() {
            return;
        }
        let cell = self.grid.cell;
        let (gx0, gy0) = (self.grid.x0, self.grid.y0);
        let mut order: Vec<(i64, i64, usize)> = pts
            .iter()
            .enumerate()
            .map(|(k, q)| {
                (
                    ((q[1] - gy0) / cell).floor() as i64,
                    ((q[0] - gx0) / cell).floor() as i64,
                    k,
                )
            })
            .collect();
        order.sort_unstable();
        let mut a = 0;
        while a < order.len() {
            let mut b = a + 1;
            while b < order.len() && order[b].0 == order[a].0 && order[b].1 == order[a].1 {
                b += 1;
            }
            let group: Vec<usize> = order[a..b].iter().map(|o| o.2).collect();
            self.push_group(pts, t, &group);
            a = b;
        }
    }

    fn push_group(&mut self, pts: &[[f32; 2]], t: &[[f32; 2]], group: &[usize]) {
        let g = &self.grid;
        let r2 = self.r2;
        let r = r2.sqrt();
        let (mut bx0, mut by0) = (f32::INFINITY, f32::INFINITY);
        let (mut bx1, mut by1) = (f32::NEG_INFINITY, f32::NEG_INFINITY);
        let mut sum = [0.0f32; 2];
        for &k in group {
            let q = pts[k];
            bx0 = bx0.min(q[0]);
            by0 = by0.min(q[1]);
            bx1 = bx1.max(q[0]);
            by1 = by1.max(q[1]);
            sum[0] += t[k][0];
            sum[1] += t[k][1];
        }
        let fx0 = ((bx0 - r - g.x0) / g.cell).floor();
        let fx1 = ((bx1 + r - g.x0) / g.cell).floor();
        let fy0 = ((by0 - r - g.y0) / g.cell).floor();
        let fy1 = ((by1 + r - g.y0) / g.cell).floor();
        if fx1 < 0.0 || fy1 < 0.0 || fx0 >= g.nx as f32 || fy0 >= g.ny as f32 {
            return;
        }
        let cx0 = fx0.max(0.0) as usize;
        let cy0 = fy0.max(0.0) as usize;
        let cx1 = (fx1 as usize).min(g.nx - 1);
        let cy1 = (fy1 as usize).min(g.ny - 1);
        // Squared distances between two intervals: nearest and farthest.
        let near = |a0: f32, a1: f32, b0: f32, b1: f32| (b0 - a1).max(a0 - b1).max(0.0);
        let far = |a0: f32, a1: f32, b0: f32, b1: f32| (b1 - a0).abs().max((a1 - b0).abs());
        for cy in cy0..=cy1 {
            let ya = g.y0 + cy as f32 * g.cell;
            let yb = ya + g.cell;
            let (ny_, fy_) = (near(by0, by1, ya, yb), far(by0, by1, ya, yb));
            for cx in cx0..=cx1 {
                let c = cy * g.nx + cx;
                let (ra, rb) = (g.cell_runs[c] as usize, g.cell_runs[c + 1] as usize);
                if ra == rb {
                    continue;
                }
                let xa = g.x0 + cx as f32 * g.cell;
                let xb = xa + g.cell;
                let nx_ = near(bx0, bx1, xa, xb);
                if nx_ * nx_ + ny_ * ny_ > r2 {
                    continue;
                }
                let fx_ = far(bx0, bx1, xa, xb);
                // The last cell row/column may hold points clamped onto it, so only interior
                // cells take the whole-cell shortcut.
                let whole = fx_ * fx_ + fy_ * fy_ <= r2 && cx + 1 < g.nx && cy + 1 < g.ny;
                if whole {
                    for run in &g.runs[ra..rb] {
                        let i = run.curve as usize;
                        if self.status[i] == Status::Resolved || apart(self.from, self.sides[i]) {
                            continue;
                        }
                        let s = run.sum;
                        self.p_score[i] += (sum[0] * s[0] + sum[1] * s[1]) as f64;
                        if !self.touch_mark[i] {
                            self.touch_mark[i] = true;
                            self.touched.push(i);
                        }
                    }
                    continue;
                }
                // A rim cell of the group: classify it per vertex of the group, as most of
                // them still see it wholly inside or outside their own disc.
                let (va, vb) = (g.runs[ra].start as usize, g.runs[rb - 1].end as usize);
                let mut whole_sum = [0.0f32; 2];
                let mut any_whole = false;
                let mut any_partial = false;
                for &k in group {
                    let (q, d) = (pts[k], t[k]);
                    let dxn = (xa - q[0]).max(q[0] - xb).max(0.0);
                    let dyn_ = (ya - q[1]).max(q[1] - yb).max(0.0);
                    if dxn * dxn + dyn_ * dyn_ > r2 {
                        continue;
                    }
                    let dxf = (q[0] - xa).abs().max((q[0] - xb).abs());
                    let dyf = (q[1] - ya).abs().max((q[1] - yb).abs());
                    if dxf * dxf + dyf * dyf <= r2 && cx + 1 < g.nx && cy + 1 < g.ny {
                        whole_sum[0] += d[0];
                        whole_sum[1] += d[1];
                        any_whole = true;
                        continue;
                    }
                    if !any_partial {
                        any_partial = true;
                        self.dots.clear();
                        self.dots.resize(vb - va, 0.0);
                        self.hits.clear();
                        self.hits.resize(vb - va, 0.0);
                    }
                    let (vx, vy) = (&g.px[va..vb], &g.py[va..vb]);
                    let (wx, wy) = (&g.tx[va..vb], &g.ty[va..vb]);
                    let (dots, hits) = (&mut self.dots[..], &mut self.hits[..]);
                    for m in 0..vx.len() {
                        let (dx, dy) = (vx[m] - q[0], vy[m] - q[1]);
                        // Branch-free so that the loop vectorises.
                        let inside = (dx * dx + dy * dy <= r2) as u32 as f32;
                        dots[m] += inside * (d[0] * wx[m] + d[1] * wy[m]);
                        hits[m] += inside;
                    }
                }
                if !any_partial && !any_whole {
                    continue;
                }
                for run in &g.runs[ra..rb] {
                    let i = run.curve as usize;
                    if self.status[i] == Status::Resolved || apart(self.from, self.sides[i]) {
                        continue;
                    }
                    let s = run.sum;
                    let mut dot = (whole_sum[0] * s[0] + whole_sum[1] * s[1]) as f64;
                    let mut near = any_whole;
                    if any_partial {
                        let (a, b) = (run.start as usize - va, run.end as usize - va);
                        dot += self.dots[a..b].iter().sum::<f32>() as f64;
                        near |= self.hits[a..b].iter().any(|&h| h > 0.0);
                    }
                    if !near {
                        continue;
                    }
                    self.p_score[i] += dot;
                    if !self.touch_mark[i] {
                        self.touch_mark[i] = true;
                        self.touched.push(i);
                    }
                }
            }
        }
    }

    /// Moves touched ambiguous curves to the heap and re-keys touched tentative ones.
    fn enqueue_touched(&mut self) {
        // Sorted so that the heap's contents, and hence tie-breaking, never depend on the
        // order in which neighbours were visited.
        self.touched.sort_unstable();
        for &i in &self.touched {
            self.touch_mark[i] = false;
            if self.status[i] == Status::Resolved {
                continue;
            }
            self.status[i] = Status::Tentative;
            self.version[i] = self.version[i].wrapping_add(1);
            self.heap.push(Entry {
                prio: self.p_score[i].abs(),
                curve: i,
                version: self.version[i],
            });
        }
        self.touched.clear();
    }

    /// The tentative curve with the largest |P|, skipping stale entries.
    fn pop(&mut self) -> Option<usize> {
        while let Some(e) = self.heap.pop() {
            if self.status[e.curve] == Status::Tentative && self.version[e.curve] == e.version {
                return Some(e.curve);
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::Rng;

    fn line(x0: f32, y0: f32, dx: f32, dy: f32, n: usize) -> Curve {
        Curve {
            points: (0..n)
                .map(|k| [x0 + dx * k as f32, y0 + dy * k as f32])
                .collect(),
        }
    }

    /// The greedy of the paper written the obvious way: P recomputed from scratch over all
    /// resolved vertices for every ambiguous curve at every step.
    fn naive(curves: &[Curve], strokes: &[Vec<[f32; 2]>], p: &ResolveParams) -> Vec<bool> {
        let r2 = p.radius * p.radius;
        let tangents: Vec<Vec<[f32; 2]>> = curves.iter().map(|c| intrinsic(&c.points)).collect();
        let mut resolved: Vec<([f32; 2], [f32; 2])> = Vec::new();
        for s in strokes {
            let pts = crate::analyze::trace::resample(s, 2.0);
            for (q, d) in pts.iter().zip(intrinsic(&pts)) {
                resolved.push((*q, [d[0] * p.stroke_weight, d[1] * p.stroke_weight]));
            }
        }
        let n = curves.len();
        let mut done = vec![false; n];
        let mut flipped = vec![false; n];
        for _ in 0..n {
            let mut best: Option<(f64, usize)> = None;
            for i in (0..n).filter(|&i| !done[i]) {
                let (mut pi, mut near) = (0.0f64, false);
                for (q, d) in curves[i].points.iter().zip(&tangents[i]) {
                    for (v, t) in &resolved {
                        if (v[0] - q[0]).powi(2) + (v[1] - q[1]).powi(2) <= r2 {
                            pi += (d[0] * t[0] + d[1] * t[1]) as f64;
                            near = true;
                        }
                    }
                }
                if near && best.is_none_or(|(b, _)| pi.abs() > b + 1e-6) {
                    best = Some((pi.abs(), i));
                }
                if near && best.unwrap().1 == i {
                    flipped[i] = pi < 0.0;
                }
            }
            let Some((_, i)) = best else { break };
            done[i] = true;
            let s = if flipped[i] { -1.0 } else { 1.0 };
            for (q, d) in curves[i].points.iter().zip(&tangents[i]) {
                resolved.push((*q, [s * d[0], s * d[1]]));
            }
        }
        flipped
    }

    #[test]
    fn a_stroke_orients_a_parallel_curve_and_its_chain() {
        // Stroke pointing down; curves traced upwards next to it, then a chain of curves each
        // within the radius of the previous one only.
        let stroke = vec![[0.0, 0.0], [0.0, 40.0]];
        let curves: Vec<Curve> = (0..5)
            .map(|k| line(10.0 + 50.0 * k as f32, 40.0, 0.0, -2.0, 21))
            .collect();
        let p = ResolveParams::default();
        let r = resolve_directions(&curves, &[stroke], &p);
        assert!(r.flipped.iter().all(|&f| f), "{:?}", r.flipped);
        assert_eq!(r.order, vec![0, 1, 2, 3, 4]);
        assert!(r.unreachable.is_empty());
        for c in &r.curves {
            assert!(
                c.points[0][1] < c.points[c.points.len() - 1][1],
                "not root -> tip"
            );
        }
    }

    #[test]
    fn curves_across_a_parting_do_not_vote() {
        // A vertical part at x = 50, y 0-40. Right of it, strands and a stroke grow right
        // (away from it). Left of it, one strand traced rightwards (towards the part) and, 40
        // px below it and beyond the part's end, a stroke growing left.
        let mut curves = vec![line(10.0, 20.0, 2.0, 0.0, 20)];
        for y in [10.0, 20.0, 30.0] {
            curves.push(line(52.0, y, 2.0, 0.0, 24));
        }
        let right = (0..20)
            .map(|k| [55.0 + 2.0 * k as f32, 15.0])
            .collect::<Vec<_>>();
        let left = (0..20)
            .map(|k| [45.0 - 2.0 * k as f32, 60.0])
            .collect::<Vec<_>>();
        let strokes = vec![right, left];
        let p = ResolveParams::default();
        // Voting across the part, the near right side wins: the left strand points at it.
        let r = resolve_directions(&curves, &strokes, &p);
        assert!(!r.flipped[0]);
        let lines =
            crate::analyze::parting::parting_lines(&[[50.0, 0.0], [50.0, 20.0], [50.0, 40.0]]);
        let r = resolve_directions_apart(&curves, &strokes, &lines, &p);
        assert!(r.flipped[0], "the left strand grows away from the part");
        assert!(r.flipped[1..].iter().all(|&f| !f));
        assert!(apart(
            side_bits(&curves[0].points, &lines, 70.0),
            side_bits(&curves[1].points, &lines, 70.0)
        ));
    }

    #[test]
    fn far_curves_are_reported_unreachable_and_resolved_among_themselves() {
        let stroke = vec![[0.0, 0.0], [0.0, 40.0]];
        let curves = vec![
            line(10.0, 0.0, 0.0, 2.0, 21),    // next to the stroke, same way
            line(500.0, 40.0, 0.0, -2.0, 30), // far away: the seed (largest), kept as traced
            line(520.0, 0.0, 0.0, 2.0, 21),   // next to the seed, opposite: flipped
            line(900.0, 0.0, 0.0, 2.0, 5),    // isolated: seeded on its own
        ];
        let r = resolve_directions(&curves, &[stroke], &ResolveParams::default());
        assert_eq!(r.unreachable, vec![1, 2, 3]);
        assert_eq!(r.order, vec![0, 1, 2, 3]);
        assert_eq!(r.flipped, vec![false, false, true, false]);
    }

    #[test]
    fn no_strokes_means_everything_is_unreachable_but_consistent() {
        let curves = vec![line(0.0, 0.0, 0.0, 2.0, 10), line(5.0, 18.0, 0.0, -2.0, 30)];
        let r = resolve_directions(&curves, &[], &ResolveParams::default());
        assert_eq!(r.unreachable, vec![0, 1]);
        assert_eq!(r.order, vec![1, 0]);
        assert_eq!(r.flipped, vec![true, false]);
    }

    #[test]
    fn stroke_weight_counts_each_stroke_vertex_w_m_times() {
        // C0 (11 vertices, traced down) has a down stroke S 10 px away (11 vertices) and the
        // long curve C1 25 px away, which an up stroke resolves first. C0 sees 11 * 11 stroke
        // pairs weighted w_m against about 11 * 17 pairs of C1: w_m = 10 lets the stroke win,
        // w_m = 1 does not.
        let s = vec![[0.0, 0.0], [0.0, 20.0]];
        let s2 = vec![[60.0, 100.0], [60.0, -100.0]];
        let curves = vec![
            line(10.0, 0.0, 0.0, 2.0, 11),
            line(35.0, 100.0, 0.0, -2.0, 101),
        ];
        for (w_m, follows_stroke) in [(10.0, true), (1.0, false)] {
            let p = ResolveParams {
                radius: 30.0,
                stroke_weight: w_m,
            };
            let r = resolve_directions(&curves, &[s.clone(), s2.clone()], &p);
            assert_eq!(r.order, vec![1, 0], "w_m {w_m}");
            assert!(!r.flipped[1], "w_m {w_m}");
            assert_eq!(r.flipped[0], !follows_stroke, "w_m {w_m}");
        }
    }

    #[test]
    fn grid_greedy_matches_the_naive_greedy() {
        for seed in 1..=4u64 {
            let mut rng = Rng::new(seed);
            let curves: Vec<Curve> = (0..60)
                .map(|_| {
                    let (x, y) = (rng.range_f32(0.0, 300.0), rng.range_f32(0.0, 300.0));
                    let a = rng.range_f32(0.0, std::f32::consts::TAU);
                    let bend = rng.range_f32(-0.05, 0.05);
                    let n = 5 + rng.below(30) as usize;
                    let mut pts = vec![[x, y]];
                    for k in 1..n {
                        let t = a + bend * k as f32;
                        let q = pts[k - 1];
                        pts.push([q[0] + 2.0 * t.cos(), q[1] + 2.0 * t.sin()]);
                    }
                    Curve { points: pts }
                })
                .collect();
            let strokes = vec![vec![[150.0, 100.0], [160.0, 140.0], [150.0, 180.0]]];
            let p = ResolveParams {
                radius: 40.0,
                ..Default::default()
            };
            let fast = resolve_directions(&curves, &strokes, &p);
            let slow = naive(&curves, &strokes, &p);
            let reached: Vec<usize> = (0..curves.len())
                .filter(|i| !fast.unreachable.contains(i))
                .collect();
            assert!(
                reached.len() > 20,
                "seed {seed}: only {} reached",
                reached.len()
            );
            for &i in &reached {
                assert_eq!(fast.flipped[i], slow[i], "seed {seed}, curve {i}");
            }
        }
    }
}
