//! Cutting traced curves where they cross a parting.
//!
//! A side parting flips the growth direction while the orientation runs on: near the crown
//! the hair on both sides of the part lies almost parallel, so the orientation map is
//! continuous across it and the tracer runs straight through (issue 19: curled or swept side
//! parts). What does show the part is the image itself: the strands of both sides end on one
//! line that runs across them. Inside hair, intensity changes little along the strands and a
//! lot across them; on a line of strand ends it changes along them too, and it does so all
//! along a segment laid across the flow, where scattered strand ends light only a point or
//! two of it. So at each vertex of a traced curve this sums, over a segment of
//! `half_length` px laid across the curve, the squared derivative along the curve and
//! divides it by the squared derivative across it (the texture's own contrast, so the ratio
//! does not depend on how strong the hair's texture is). It does so on each side of the
//! curve and keeps the smaller ratio: a line the curve crosses runs on both sides of it,
//! while a curve that passes just beyond the end of a line sees it on one side only. A curve
//! is cut where that ratio peaks above `threshold`.
//!
//! A cut alone only lets the two pieces be resolved apart, and Eq. (1)'s neighbourhood is
//! isotropic: the curves and strokes just across the part still vote on the narrow side's
//! pieces and, where no stroke is near, turn them the big side's way. So the cuts are also
//! grouped into lines ([`parting_lines`]: at least three, linked within 20 px, within 2.5 px
//! rms of a straight line), and curves on opposite sides of a line do not vote on each other
//! ([`crate::analyze::resolve::resolve_directions_apart`]). Weaker peaks (above
//! `line_threshold`, 0.4) are cut too where they line up with a strong one (above
//! `threshold`, 0.8): a hysteresis, since a part is a line while chance peaks in curls and
//! whorls are scattered. Measured by `cargo bench --bench directions` (`coif synth` at 512²,
//! four styles × three textures × seeds 1-3, the synthesised strokes, the true mask; share
//! of hair pixels ≥ 5 px inside the mask pointing the true way): side part 94.6-98.5% with
//! the step off, 97.2-99.8% with partings from the strong cuts alone, 99.1-99.8% with the
//! hysteresis; mean over the 36 cases 99.02 → 99.65 → 99.85%, whorl and short within 0.03
//! points of the step off. A single threshold of 0.4 or 0.5 instead of the hysteresis gives
//! the side parts the same but costs whorls up to 0.35 points, 0.3 costs one 1.2.
//! A curve that crosses a line where it fades (past its outermost cuts, within
//! [`LINE_END_MARGIN`], with no cut near the crossing) is cut at the crossing as well
//! ([`crossing_cuts`]): since the orientation runs on through partings (its robust guide,
//! 2026-12-04) the bench's side part photo seed 1 went 99.36 → 97.66% without it and is
//! 99.19% with it; the 36 cases' mean 99.73 → 99.80%, worst 97.66 → 98.84%.
//! Tried and not kept: turning the pieces at a cluster of cuts to point away from it (it
//! turned whole patches of short and whorl hair at chance cuts, and ten curves in the
//! middle of the astronaut's curls); the lines turn nothing, they only withhold votes. On the real portraits of the tests (the astronaut, Grace Hopper, three
//! web portraits) the direction field is the same pixel for pixel.
//!
//! CPU: light and sequential per curve; the ratio is read only at the curves' vertices, not
//! over every pixel. With the image's blur it adds 15-30 ms to `coif analyze` on the long
//! case at 512² on two cores (the analysis takes ~1.3 s).

use crate::analyze::resolve::intrinsic;
use crate::analyze::trace::Curve;
use rayon::prelude::*;

/// Parameters of the parting cut.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PartingParams {
    /// Cut where the along/across ratio of squared derivatives peaks above this; 0 disables.
    pub threshold: f32,
    /// Also cut where it peaks above this (at most `threshold`; 0: no such cut) on a straight
    /// run of such peaks that holds a cut above `threshold`.
    pub line_threshold: f32,
    /// Half length of the segment laid across the curve at each vertex, px.
    pub half_length: f32,
    /// σ of the Gaussian the image is smoothed with before differentiating, px.
    pub sigma: f32,
}

impl Default for PartingParams {
    fn default() -> Self {
        PartingParams {
            threshold: 0.8,
            line_threshold: 0.4,
            half_length: 8.0,
            sigma: 0.8,
        }
    }
}

/// The smoothed image and the hair pixels whose whole derivative stencil is hair.
pub struct PartingImage {
    w: usize,
    h: usize,
    smooth: Vec<f32>,
    inner: Vec<bool>,
}

impl PartingImage {
    /// `gray` W×H in any scale; `mask` W×H, non-zero on hair.
    pub fn new(gray: &[f32], mask: &[u8], w: u32, h: u32, p: &PartingParams) -> Self {
        let (w, h) = (w as usize, h as usize);
        let smooth = blur(gray, w, h, p.sigma);
        // A derivative 1 px either way of a bilinear read touches pixels up to 2 px away:
        // the mask's edge would read as a line of strand ends.
        let hair: Vec<bool> = mask.iter().map(|&m| m != 0).collect();
        let inner =
            crate::base::mask::erode_by(&hair, w, h, &crate::base::mask::disc(2.5, true), false);
        PartingImage {
            w,
            h,
            smooth,
            inner,
        }
    }

    fn at(&self, x: f32, y: f32) -> f32 {
        let (x, y) = (x - 0.5, y - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let clamp = |v: f32, n: usize| (v.max(0.0) as usize).min(n - 1);
        let (xa, xb) = (clamp(x0, self.w), clamp(x0 + 1.0, self.w));
        let (ya, yb) = (clamp(y0, self.h), clamp(y0 + 1.0, self.h));
        let s = &self.smooth;
        let top = s[ya * self.w + xa] * (1.0 - fx) + s[ya * self.w + xb] * fx;
        let bot = s[yb * self.w + xa] * (1.0 - fx) + s[yb * self.w + xb] * fx;
        top * (1.0 - fy) + bot * fy
    }

    fn inner_at(&self, x: f32, y: f32) -> bool {
        x >= 0.0
            && y >= 0.0
            && (x as usize) < self.w
            && (y as usize) < self.h
            && self.inner[y as usize * self.w + x as usize]
    }

    /// The along/across ratio at `q` for the unit tangent `t`: the smaller of the two
    /// half-segments' (each from `q` out to `half_length` on one side), since a line the curve
    /// crosses runs on both sides of it, where a curve that passes beside the end of a line
    /// sees it on one side only. 0 where either half has fewer than half of its samples
    /// inside the hair.
    pub fn ratio(&self, q: [f32; 2], t: [f32; 2], half_length: f32) -> f32 {
        let n = [-t[1], t[0]];
        let k = half_length.max(0.0).floor() as i32;
        let half = |sign: i32| {
            let (mut along, mut across, mut count) = (0.0f64, 0.0f64, 0);
            for s in 0..=k {
                let s = (sign * s) as f32;
                let p = [q[0] + s * n[0], q[1] + s * n[1]];
                if !self.inner_at(p[0], p[1]) {
                    continue;
                }
                let d = |u: [f32; 2]| {
                    0.5 * (self.at(p[0] + u[0], p[1] + u[1]) - self.at(p[0] - u[0], p[1] - u[1]))
                };
                let (dt, dn) = (d(t), d(n));
                along += (dt * dt) as f64;
                across += (dn * dn) as f64;
                count += 1;
            }
            if 2 * count <= k + 1 {
                return 0.0;
            }
            (along / (across + 1e-9 * count as f64)) as f32
        };
        half(-1).min(half(1))
    }
}

/// Separable Gaussian blur, edges clamped.
fn blur(src: &[f32], w: usize, h: usize, sigma: f32) -> Vec<f32> {
    if sigma <= 0.0 {
        return src.to_vec();
    }
    let r = (3.0 * sigma).ceil() as i32;
    let taps: Vec<f32> = (-r..=r)
        .map(|t| (-0.5 * (t as f32 / sigma).powi(2)).exp())
        .collect();
    let sum: f32 = taps.iter().sum();
    let taps: Vec<f32> = taps.iter().map(|t| t / sum).collect();
    let pass = |src: &[f32], horizontal: bool| -> Vec<f32> {
        let mut out = vec![0.0f32; w * h];
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let mut acc = 0.0;
                for (i, tap) in taps.iter().enumerate() {
                    let d = i as i32 - r;
                    let (xx, yy) = if horizontal {
                        ((x as i32 + d).clamp(0, w as i32 - 1) as usize, y)
                    } else {
                        (x, (y as i32 + d).clamp(0, h as i32 - 1) as usize)
                    };
                    acc += tap * src[yy * w + xx];
                }
                *o = acc;
            }
        });
        out
    };
    pass(&pass(src, true), false)
}

/// Peaks of the ratio closer than this along a curve, px, are one line.
const PEAK_GAP: f32 = 6.0;

/// What [`cut_at_partings`] found and did.
pub struct Parted {
    /// The pieces: the curves cut at `cuts`; each piece shares the vertex it was cut at with
    /// the next, and pieces of one vertex are dropped.
    pub pieces: Vec<Curve>,
    /// The points cut at.
    pub cuts: Vec<[f32; 2]>,
    /// The straight runs of cuts ([`parting_lines`]).
    pub lines: Vec<PartingLine>,
}

/// `curves` cut where they cross a line of strand ends. The candidates are the vertices where
/// the along/across ratio (module docs) is the largest within [`PEAK_GAP`] along the curve
/// and at least `p.line_threshold`; a candidate is cut if its ratio is at least
/// `p.threshold`, or if it lies on a straight run of candidates with at least one such
/// strong cut ([`parting_lines`]): a hysteresis, since a part shows as a line, where
/// weaker peaks scattered over curls or whorls do not line up.
pub fn cut_at_partings(curves: &[Curve], img: &PartingImage, p: &PartingParams) -> Parted {
    if p.threshold.is_nan() || p.threshold <= 0.0 {
        return Parted {
            pieces: curves.to_vec(),
            cuts: Vec::new(),
            lines: Vec::new(),
        };
    }
    let weak = if p.line_threshold > 0.0 {
        p.line_threshold.min(p.threshold)
    } else {
        p.threshold
    };
    // Candidates per curve: (vertex, ratio), in order along the curve.
    let candidates: Vec<Vec<(usize, f32)>> = curves
        .par_iter()
        .map(|c| {
            let pts = &c.points;
            let m = pts.len();
            if m < 5 {
                return Vec::new();
            }
            let tan = intrinsic(pts);
            let r: Vec<f32> = (0..m)
                .map(|i| img.ratio(pts[i], tan[i], p.half_length))
                .collect();
            // Arc length at each vertex: peaks are compared within `PEAK_GAP` px, so the
            // two edges of a wide line of scalp make one cut, not a sliver between two.
            let mut arc = vec![0.0f32; m];
            for i in 1..m {
                arc[i] = arc[i - 1] + (pts[i][0] - pts[i - 1][0]).hypot(pts[i][1] - pts[i - 1][1]);
            }
            let mut at = Vec::new();
            // The two end vertices on each side are never cut: a piece of one segment says
            // little about its direction.
            for i in 2..m - 2 {
                if r[i] < weak {
                    continue;
                }
                // Arc length grows along the curve, so the vertices within the gap are one
                // contiguous run around i.
                let lo = arc.partition_point(|&a| a < arc[i] - PEAK_GAP);
                let hi = arc.partition_point(|&a| a <= arc[i] + PEAK_GAP);
                let peak = (lo..hi)
                    .filter(|&j| j != i)
                    .all(|j| r[j] < r[i] || (r[j] == r[i] && j > i));
                if peak {
                    at.push((i, r[i]));
                }
            }
            at
        })
        .collect();
    let flat: Vec<([f32; 2], bool)> = candidates
        .iter()
        .zip(curves)
        .flat_map(|(cs, c)| cs.iter().map(|&(i, r)| (c.points[i], r >= p.threshold)))
        .collect();
    let (lines, on_line) = lines_of(&flat);
    let mut parted = Parted {
        pieces: Vec::new(),
        cuts: Vec::new(),
        lines,
    };
    let mut k = 0;
    for (c, cs) in curves.iter().zip(&candidates) {
        let pts = &c.points;
        let mut at: Vec<usize> = Vec::new();
        for &(i, r) in cs {
            if r >= p.threshold || on_line[k] {
                at.push(i);
            }
            k += 1;
        }
        crossing_cuts(pts, &parted.lines, &mut at);
        let mut start = 0usize;
        for i in at {
            parted.pieces.push(Curve {
                points: pts[start..=i].to_vec(),
            });
            parted.cuts.push(pts[i]);
            start = i;
        }
        parted.pieces.push(Curve {
            points: pts[start..].to_vec(),
        });
    }
    parted.pieces.retain(|c| c.points.len() >= 2);
    parted
}

/// Adds to `at` (sorted vertex indices of `pts` already cut) a cut where the polyline crosses
/// one of `lines` beside it (within its cuts' extent plus [`LINE_END_MARGIN`]) with no cut
/// within [`PEAK_GAP`] of the crossing: a line's own cuts are peaks of the ratio, and where
/// the line fades (near the hairline, in a soft texture) a curve can cross it with no peak
/// above the line threshold, then carry one direction to both sides. Cut at the vertex
/// nearer the line; never at the two end vertices on each side, as for the peaks.
fn crossing_cuts(pts: &[[f32; 2]], lines: &[PartingLine], at: &mut Vec<usize>) {
    let m = pts.len();
    if m < 5 || lines.is_empty() {
        return;
    }
    let mut arc = vec![0.0f32; m];
    for i in 1..m {
        arc[i] = arc[i - 1] + (pts[i][0] - pts[i - 1][0]).hypot(pts[i][1] - pts[i - 1][1]);
    }
    for l in lines {
        let n = [-l.along[1], l.along[0]];
        let uv = |q: [f32; 2]| {
            let d = [q[0] - l.centre[0], q[1] - l.centre[1]];
            (
                d[0] * l.along[0] + d[1] * l.along[1],
                d[0] * n[0] + d[1] * n[1],
            )
        };
        for j in 0..m - 1 {
            let ((ua, va), (ub, vb)) = (uv(pts[j]), uv(pts[j + 1]));
            if (va > 0.0) == (vb > 0.0) {
                continue;
            }
            // Where the segment meets the line, along it.
            let t = va / (va - vb);
            let u = ua + t * (ub - ua);
            if u < l.extent[0] - LINE_END_MARGIN || u > l.extent[1] + LINE_END_MARGIN {
                continue;
            }
            let i = if va.abs() <= vb.abs() { j } else { j + 1 };
            if i < 2 || i >= m - 2 || at.iter().any(|&c| (arc[c] - arc[i]).abs() <= PEAK_GAP) {
                continue;
            }
            let pos = at.partition_point(|&c| c < i);
            at.insert(pos, i);
        }
    }
}

/// Cuts closer than this to one another join one line, px.
const LINE_LINK: f32 = 20.0;
/// A line of cuts: at least this many.
const LINE_MIN_CUTS: usize = 3;
/// A line of cuts: at most this far (rms, px) from their best-fitting straight line.
const LINE_MAX_SPREAD: f32 = 2.5;
/// The band of a line where a curve is given a side: this far beyond its end cuts, px.
const LINE_END_MARGIN: f32 = 10.0;
/// Vertices nearer a line than this take no side (a piece that ends on the line), px.
const LINE_ON: f32 = 1.5;
/// At most this many lines are kept (the most cuts first): sides are bits of a `u64`.
pub const MAX_LINES: usize = 32;

/// A parting found as a straight run of cuts: the hair on its two sides grows away from it,
/// so curves on opposite sides of it say nothing of each other's direction.
#[derive(Clone, Debug, PartialEq)]
pub struct PartingLine {
    /// Mean of the cuts.
    pub centre: [f32; 2],
    /// Unit direction along the line (the cuts' major axis).
    pub along: [f32; 2],
    /// The cuts' extent along `along` from `centre`, px.
    pub extent: [f32; 2],
    /// Cuts on the line.
    pub cuts: usize,
}

impl PartingLine {
    /// The line's two end points.
    pub fn ends(&self) -> [[f32; 2]; 2] {
        self.extent.map(|s| {
            [
                self.centre[0] + s * self.along[0],
                self.centre[1] + s * self.along[1],
            ]
        })
    }

    /// Which side of the line `pts` lie on, within `reach` px of it and beside it (along the
    /// line within its cuts' extent plus a margin): 1 or -1 when every such vertex off the line
    /// is on one side, 0 when none is or when they lie on both (a curve crossing the line).
    pub fn side(&self, pts: &[[f32; 2]], reach: f32) -> i8 {
        let n = [-self.along[1], self.along[0]];
        let (mut pos, mut neg) = (false, false);
        for q in pts {
            let d = [q[0] - self.centre[0], q[1] - self.centre[1]];
            let u = d[0] * self.along[0] + d[1] * self.along[1];
            let v = d[0] * n[0] + d[1] * n[1];
            let beside =
                u >= self.extent[0] - LINE_END_MARGIN && u <= self.extent[1] + LINE_END_MARGIN;
            if !beside || v.abs() > reach || v.abs() < LINE_ON {
                continue;
            }
            pos |= v > 0.0;
            neg |= v < 0.0;
        }
        match (pos, neg) {
            (true, false) => 1,
            (false, true) => -1,
            _ => 0,
        }
    }
}

/// Straight runs of cuts: cuts within [`LINE_LINK`] of one another join (single linkage),
/// and a group of at least [`LINE_MIN_CUTS`] lying within [`LINE_MAX_SPREAD`] (rms) of its
/// best straight line is a parting. Scattered cuts in curls or whorls make no line. At most
/// [`MAX_LINES`], the most cuts first. Deterministic.
pub fn parting_lines(cuts: &[[f32; 2]]) -> Vec<PartingLine> {
    let flat: Vec<([f32; 2], bool)> = cuts.iter().map(|&q| (q, true)).collect();
    lines_of(&flat).0
}

/// [`parting_lines`] over candidates `(point, strong)`, where a line needs a strong one;
/// also whether each candidate lies on a kept line.
fn lines_of(cands: &[([f32; 2], bool)]) -> (Vec<PartingLine>, Vec<bool>) {
    let n = cands.len();
    // Union-find over the pairs within the link distance; candidates are few (tens).
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (cands[i].0, cands[j].0);
            if (a[0] - b[0]).hypot(a[1] - b[1]) <= LINE_LINK {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut groups: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for i in 0..n {
        let r = root(&mut parent, i);
        groups.entry(r).or_default().push(i);
    }
    let mut lines: Vec<(PartingLine, Vec<usize>)> = groups
        .into_values()
        .filter(|g| g.len() >= LINE_MIN_CUTS && g.iter().any(|&i| cands[i].1))
        .filter_map(|g| {
            let m = g.len() as f64;
            let cx = g.iter().map(|&i| cands[i].0[0] as f64).sum::<f64>() / m;
            let cy = g.iter().map(|&i| cands[i].0[1] as f64).sum::<f64>() / m;
            let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
            for &i in &g {
                let (dx, dy) = (cands[i].0[0] as f64 - cx, cands[i].0[1] as f64 - cy);
                sxx += dx * dx;
                sxy += dx * dy;
                syy += dy * dy;
            }
            // Principal axes of the 2x2 scatter: the smaller eigenvalue is the spread across.
            let half_tr = 0.5 * (sxx + syy);
            let disc = (0.25 * (sxx - syy).powi(2) + sxy * sxy).sqrt();
            let across = ((half_tr - disc).max(0.0) / m).sqrt();
            if across > LINE_MAX_SPREAD as f64 {
                return None;
            }
            let a = 0.5 * (2.0 * sxy).atan2(sxx - syy);
            let along = [a.cos() as f32, a.sin() as f32];
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for &i in &g {
                let q = cands[i].0;
                let u = (q[0] - cx as f32) * along[0] + (q[1] - cy as f32) * along[1];
                lo = lo.min(u);
                hi = hi.max(u);
            }
            let line = PartingLine {
                centre: [cx as f32, cy as f32],
                along,
                extent: [lo, hi],
                cuts: g.len(),
            };
            Some((line, g))
        })
        .collect();
    // Stable: equal counts keep the groups' order (by their lowest candidate).
    lines.sort_by_key(|l| std::cmp::Reverse(l.0.cuts));
    lines.truncate(MAX_LINES);
    let mut on_line = vec![false; n];
    for (_, g) in &lines {
        for &i in g {
            on_line[i] = true;
        }
    }
    (lines.into_iter().map(|(l, _)| l).collect(), on_line)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Horizontal strands (a stripe every 3 px) over `w`×`h`; with `part`, every strand in
    /// rows up to `part_rows` stops 1 px short of column `part` on both sides (a line of
    /// strand ends).
    fn strands_to(w: usize, h: usize, part: Option<usize>, part_rows: usize) -> Vec<f32> {
        let mut g = vec![0.2f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let on = y % 3 == 1;
                let gap = y < part_rows && part.is_some_and(|p| x.abs_diff(p) <= 1);
                if on && !gap {
                    g[y * w + x] = 0.8;
                }
            }
        }
        g
    }

    fn strands(w: usize, h: usize, part: Option<usize>) -> Vec<f32> {
        strands_to(w, h, part, h)
    }

    fn line(y: f32, w: usize) -> Curve {
        Curve {
            points: (0..w / 2).map(|k| [1.0 + 2.0 * k as f32, y]).collect(),
        }
    }

    #[test]
    fn a_line_of_strand_ends_cuts_and_plain_strands_do_not() {
        let (w, h) = (80usize, 48usize);
        let mask = vec![1u8; w * h];
        let p = PartingParams::default();
        let curve = line(24.5, w);
        let plain = PartingImage::new(&strands(w, h, None), &mask, w as u32, h as u32, &p);
        let Parted {
            pieces: out, cuts, ..
        } = cut_at_partings(std::slice::from_ref(&curve), &plain, &p);
        assert_eq!((out.len(), cuts.len()), (1, 0));
        let parted = PartingImage::new(&strands(w, h, Some(40)), &mask, w as u32, h as u32, &p);
        let Parted {
            pieces: out, cuts, ..
        } = cut_at_partings(std::slice::from_ref(&curve), &parted, &p);
        assert_eq!(cuts.len(), 1, "{out:?}");
        // Cut at the part, within a vertex (2 px), and nothing lost.
        let at = out[0].points.last().unwrap()[0];
        assert!((at - 40.5).abs() <= 2.0, "cut at x {at}");
        assert_eq!(out[0].points.last(), out[1].points.first());
        assert_eq!(
            out[0].points.len() + out[1].points.len() - 1,
            curve.points.len()
        );
        // Disabled: untouched.
        let off = PartingParams {
            threshold: 0.0,
            ..p
        };
        assert!(cut_at_partings(&[curve], &parted, &off).cuts.is_empty());
    }

    #[test]
    fn a_curve_beside_the_end_of_a_part_is_not_cut() {
        // The part runs down to row 24; a curve 5.5 px below its end sees it on one side
        // only, one 10 px above it on both.
        let (w, h) = (80usize, 64usize);
        let mask = vec![1u8; w * h];
        let p = PartingParams::default();
        let img = PartingImage::new(
            &strands_to(w, h, Some(40), 24),
            &mask,
            w as u32,
            h as u32,
            &p,
        );
        assert_eq!(cut_at_partings(&[line(13.5, w)], &img, &p).cuts.len(), 1);
        assert!(cut_at_partings(&[line(29.5, w)], &img, &p).cuts.is_empty());
    }

    #[test]
    fn cuts_in_a_row_make_a_line_and_scattered_ones_do_not() {
        let row: Vec<[f32; 2]> = (0..6)
            .map(|k| [40.0 + 0.3 * k as f32, 10.0 + 8.0 * k as f32])
            .collect();
        let lines = parting_lines(&row);
        assert_eq!(lines.len(), 1);
        let l = &lines[0];
        assert_eq!(l.cuts, 6);
        assert!(l.along[1].abs() > 0.99, "{l:?}");
        assert!((l.extent[1] - l.extent[0] - 40.0).abs() < 0.5, "{l:?}");
        // Two are not a line; neither are cuts linked in a zigzag wider than the spread.
        assert!(parting_lines(&row[..2]).is_empty());
        let zigzag: Vec<[f32; 2]> = (0..6)
            .map(|k| [40.0 + 12.0 * (k % 2) as f32, 10.0 + 8.0 * k as f32])
            .collect();
        assert!(parting_lines(&zigzag).is_empty());
        // A line needs a strong cut: the same row of weak candidates makes none.
        let weak: Vec<([f32; 2], bool)> = row.iter().map(|&q| (q, false)).collect();
        let (lines, on) = lines_of(&weak);
        assert!(lines.is_empty() && on.iter().all(|&o| !o));
        let mut one = weak.clone();
        one[3].1 = true;
        let (lines, on) = lines_of(&one);
        assert_eq!(lines.len(), 1);
        assert!(on.iter().all(|&o| o));
    }

    #[test]
    fn a_line_tells_the_sides_of_the_curves_beside_it() {
        // A vertical part at x = 50 from y = 10 to 50.
        let l = &parting_lines(&[[50.0, 10.0], [50.0, 30.0], [50.0, 50.0], [50.0, 20.0]])[0];
        let h = |x0: f32, x1: f32, y: f32| -> Vec<[f32; 2]> {
            (0..=10)
                .map(|k| [x0 + (x1 - x0) * k as f32 / 10.0, y])
                .collect()
        };
        let left = l.side(&h(10.0, 50.0, 30.0), 70.0);
        let right = l.side(&h(50.0, 90.0, 30.0), 70.0);
        assert!(left != 0 && right == -left, "{left} {right}");
        // Crossing it, beyond its end, or out of reach: no side.
        assert_eq!(l.side(&h(10.0, 90.0, 30.0), 70.0), 0);
        assert_eq!(l.side(&h(10.0, 48.0, 75.0), 70.0), 0);
        assert_eq!(l.side(&h(0.0, 10.0, 30.0), 30.0), 0);
    }

    #[test]
    fn a_curve_crossing_a_line_where_it_fades_is_cut_there() {
        // A vertical part at x = 50 whose cuts run from y = 10 to 50.
        let lines = parting_lines(&[[50.0, 10.0], [50.0, 30.0], [50.0, 50.0], [50.0, 20.0]]);
        let h =
            |y: f32| -> Vec<[f32; 2]> { (0..=40).map(|k| [10.0 + 2.0 * k as f32, y]).collect() };
        // Within the margin past the last cut: cut at the vertex on the line (x = 50).
        let mut at = Vec::new();
        crossing_cuts(&h(55.0), &lines, &mut at);
        assert_eq!(at, vec![20]);
        // Already cut near the crossing (a peak 4 px off): no second cut.
        let mut at = vec![18];
        crossing_cuts(&h(30.0), &lines, &mut at);
        assert_eq!(at, vec![18]);
        // A cut elsewhere on the curve stays, and the crossing joins it in order.
        let mut at = vec![35];
        crossing_cuts(&h(30.0), &lines, &mut at);
        assert_eq!(at, vec![20, 35]);
        // Beyond the margin, or a curve that stays on one side: no cut.
        for (pts, what) in [
            (h(50.0 + LINE_END_MARGIN + 1.0), "beyond the margin"),
            (
                (0..=15).map(|k| [10.0 + 2.0 * k as f32, 30.0]).collect(),
                "one side",
            ),
        ] {
            let mut at = Vec::new();
            crossing_cuts(&pts, &lines, &mut at);
            assert!(at.is_empty(), "{what}: {at:?}");
        }
    }

    #[test]
    fn the_mask_edge_is_not_a_parting() {
        // Strands that stop where the hair stops: the edge is excluded from the ratio.
        let (w, h) = (80usize, 48usize);
        let mask: Vec<u8> = (0..w * h).map(|i| (i % w < 40) as u8).collect();
        let g = strands(w, h, None);
        let mut g2 = g.clone();
        for (i, v) in g2.iter_mut().enumerate() {
            if i % w >= 40 {
                *v = 0.5;
            }
        }
        let p = PartingParams::default();
        let img = PartingImage::new(&g2, &mask, w as u32, h as u32, &p);
        let c = Curve {
            points: (0..19).map(|k| [1.0 + 2.0 * k as f32, 24.5]).collect(),
        };
        assert!(cut_at_partings(&[c], &img, &p).cuts.is_empty());
    }
}
