//! Strokes of the 3D portrait, along visible front strands or the ground-truth direction.

use super::grow::StrandVar;
use crate::base::rng::Rng;
use crate::io::annot::{Stroke, StrokeKind, Strokes};
use crate::synth::{checked_prefix, mask_interior, resample};
use glam::Vec3;
use image::GrayImage;
/// What the stroke maker needs to know about the image.
pub(super) struct StrokeCtx<'a> {
    pub(super) proj: &'a [Vec<Vec3>],
    pub(super) mask: &'a GrayImage,
    pub(super) inner: Vec<bool>,
    /// A narrower margin for the strokes beside a parting: the narrow side of a side part
    /// leaves little room, and a user follows the hair closer to its edge there.
    pub(super) inner_near: Vec<bool>,
    pub(super) gt_dir: &'a [f32],
    pub(super) body_depth: &'a [f32],
    pub(super) tol: f32,
    /// Length unit: 1 at 512 px (at least 0.25).
    pub(super) su: f32,
}

impl StrokeCtx<'_> {
    pub(super) fn pix(&self, q: [f32; 2]) -> Option<usize> {
        let (w, h) = (self.mask.width() as usize, self.mask.height() as usize);
        let (x, y) = (q[0].floor(), q[1].floor());
        (x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h)
            .then(|| y as usize * w + x as usize)
    }

    /// A stroke along strand `si`: its longest run of vertices that are visible, well inside
    /// the hair, not foreshortened and within 20° of gt_dir (so on the front layer), cut to
    /// 70-150 px (from the run's start with `from_start`, for the strokes beside a parting,
    /// else at a random offset),
    /// resampled every 10 px and checked against gt_dir. None if under 40 px.
    pub(super) fn along(
        &self,
        si: usize,
        from_start: bool,
        rng: &mut Rng,
    ) -> Option<Vec<[f32; 2]>> {
        let st = &self.proj[si];
        let inner = if from_start {
            &self.inner_near
        } else {
            &self.inner
        };
        let cos20 = 20f32.to_radians().cos();
        let good: Vec<bool> = (0..st.len())
            .map(|i| {
                let q = st[i];
                let Some(k) = self.pix([q.x, q.y]) else {
                    return false;
                };
                let (a, b) = (st[i.saturating_sub(1)], st[(i + 1).min(st.len() - 1)]);
                let (dx, dy) = (b.x - a.x, b.y - a.y);
                let l = dx.hypot(dy);
                inner[k]
                    && q.z >= self.body_depth[k] - self.tol
                    && l > 0.5 * (b - a).length()
                    && l > 1e-3
                    && (dx * self.gt_dir[2 * k] + dy * self.gt_dir[2 * k + 1]) / l > cos20
            })
            .collect();
        let (mut best, mut start) = ((0, 0), 0);
        for i in 0..=good.len() {
            if i == good.len() || !good[i] {
                if i - start > best.1 - best.0 {
                    best = (start, i);
                }
                start = i + 1;
            }
        }
        if best.1 - best.0 < 2 {
            return None;
        }
        let run: Vec<[f32; 2]> = st[best.0..best.1].iter().map(|q| [q.x, q.y]).collect();
        let want = rng.range_f32(70.0, 150.0) * self.su;
        let run = sub_run(&run, want, from_start, rng);
        self.finish(&run)
    }

    pub(super) fn finish(&self, path: &[[f32; 2]]) -> Option<Vec<[f32; 2]>> {
        let (w, h) = (self.mask.width() as usize, self.mask.height() as usize);
        let pts = checked_prefix(
            resample(path, 10.0 * self.su),
            self.mask.as_raw(),
            self.gt_dir,
            w,
            h,
            unit_or_zero,
        );
        let total: f32 = pts
            .windows(2)
            .map(|q| (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]))
            .sum();
        (pts.len() >= 2 && total >= 40.0 * self.su).then_some(pts)
    }
}

/// 4-6 direction strokes along visible front strands (root → tip), well inside the hair,
/// agreeing with gt_dir, spread out. With a parting, first one on each side starting just
/// beside it at the top (`anchors`), drawn away from it, as a user would: that is what
/// decides the growth direction of the curves meeting at the parting.
#[allow(clippy::too_many_arguments)]
pub(super) fn make_strokes(
    proj: &[Vec<Vec3>],
    vars: &[StrandVar],
    anchors: Option<[[f32; 2]; 2]>,
    mask: &GrayImage,
    gt_dir: &[f32],
    body_depth: &[f32],
    tol: f32,
    sc: f32,
    rng: &mut Rng,
) -> Strokes {
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    let ctx = StrokeCtx {
        proj,
        mask,
        // As `crate::synth` from 256² up; smaller images (whose hair is only a few dozen
        // pixels across) get proportionally smaller margins and strokes.
        inner: mask_interior(mask, 7.0 * (1.2 * sc).clamp(0.36, 0.6).max(sc)),
        inner_near: mask_interior(mask, 0.35 * 7.0 * (1.2 * sc).clamp(0.36, 0.6).max(sc)),
        gt_dir,
        body_depth,
        tol,
        su: sc.max(0.25),
    };
    let su = ctx.su;
    let mut chosen: Vec<Vec<[f32; 2]>> = Vec::new();
    if let Some(anchors) = anchors {
        for (side, a) in [(-1.0f32, anchors[0]), (1.0, anchors[1])] {
            // Strands of that side rooted nearest the anchor, followed from their start.
            let mut near: Vec<(f32, usize)> = (0..proj.len())
                .filter(|&si| vars[si].side == side)
                .map(|si| ((proj[si][0].x - a[0]).hypot(proj[si][0].y - a[1]), si))
                .collect();
            near.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            let best = near
                .iter()
                .take(150)
                .filter_map(|&(_, si)| ctx.along(si, true, rng))
                .filter(|pts| pts.iter().all(|q| (q[0] - a[0]) * side >= -2.0))
                .min_by(|x, y| {
                    let d = |p: &[[f32; 2]]| (p[0][0] - a[0]).hypot(p[0][1] - a[1]);
                    d(x).total_cmp(&d(y))
                });
            chosen.extend(best);
        }
    }

    // Candidates for the rest, from strands in random order.
    let mut order: Vec<usize> = (0..proj.len()).collect();
    for i in (1..order.len()).rev() {
        order.swap(i, rng.below(i as u32 + 1) as usize);
    }
    let mut cands: Vec<Vec<[f32; 2]>> = Vec::new();
    for &si in &order {
        if cands.len() >= 300 {
            break;
        }
        cands.extend(ctx.along(si, false, rng));
    }
    // Short hair has no strand long enough for a stroke: follow the front-most strands'
    // image direction instead (what a user tracing the visible hair would draw).
    let mut tries = 0;
    while cands.len() < 12 && tries < 3000 {
        tries += 1;
        let q = [rng.range_f32(0.0, w as f32), rng.range_f32(0.0, h as f32)];
        if ctx.pix(q).is_none_or(|k| !ctx.inner[k]) {
            continue;
        }
        let len = rng.range_f32(70.0, 150.0) * su;
        let back = len * rng.range_f32(0.3, 0.6);
        let mut path = trace_dir(q, -1.0, back, gt_dir, &ctx.inner, w, h);
        path.reverse();
        path.push(q);
        path.extend(trace_dir(q, 1.0, len - back, gt_dir, &ctx.inner, w, h));
        cands.extend(ctx.finish(&path));
    }
    // Prefer the longer half when there is a choice: short strokes say little.
    let arc = |p: &[[f32; 2]]| -> f32 {
        p.windows(2)
            .map(|q| (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]))
            .sum()
    };
    let long: Vec<Vec<[f32; 2]>> = cands
        .iter()
        .filter(|p| arc(p) >= 55.0 * su)
        .cloned()
        .collect();
    if long.len() >= 12 {
        cands = long;
    }
    let want = 4 + rng.below(3) as usize;
    let mut used: Vec<[f32; 2]> = chosen.iter().flatten().copied().collect();
    while chosen.len() < want && !cands.is_empty() {
        // Farthest from what is already drawn, with a little randomness.
        let best = cands
            .iter()
            .enumerate()
            .map(|(i, pts)| {
                let d = pts
                    .iter()
                    .flat_map(|p| used.iter().map(move |q| (p[0] - q[0]).hypot(p[1] - q[1])))
                    .fold(f32::INFINITY, f32::min);
                let d = if d.is_finite() { d } else { 1e9 };
                (i, d * rng.range_f32(0.8, 1.0))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((i, _)) = best else { break };
        let pts = cands.swap_remove(i);
        used.extend(pts.iter().copied());
        chosen.push(pts);
    }
    Strokes::new(
        chosen
            .into_iter()
            .map(|points| Stroke::new(StrokeKind::Direction, points))
            .collect(),
    )
}

/// Follows gt_dir (nearest pixel, half-pixel steps) from `start` for up to `len` px, with
/// `sign` -1 against the growth direction; stops leaving `inner` or where the direction
/// jumps (a parting). Returns the points after `start`.
pub(super) fn trace_dir(
    start: [f32; 2],
    sign: f32,
    len: f32,
    gt_dir: &[f32],
    inner: &[bool],
    w: usize,
    h: usize,
) -> Vec<[f32; 2]> {
    let at = |q: [f32; 2]| -> Option<[f32; 2]> {
        let (x, y) = (q[0].floor(), q[1].floor());
        if x < 0.0 || y < 0.0 || x as usize >= w || y as usize >= h {
            return None;
        }
        let k = y as usize * w + x as usize;
        (inner[k] && gt_dir[2 * k].is_finite())
            .then(|| [sign * gt_dir[2 * k], sign * gt_dir[2 * k + 1]])
    };
    let mut out = Vec::new();
    let mut p = start;
    let Some(mut prev) = at(p) else {
        return out;
    };
    let mut travelled = 0.0;
    while travelled < len {
        let Some(d) = at(p) else { break };
        if d[0] * prev[0] + d[1] * prev[1] < 0.9 {
            break;
        }
        // Midpoint step, so curved hair is followed without drifting outwards.
        let Some(d2) = at([p[0] + 0.25 * d[0], p[1] + 0.25 * d[1]]) else {
            break;
        };
        let q = [p[0] + 0.5 * d2[0], p[1] + 0.5 * d2[1]];
        if at(q).is_none() {
            break;
        }
        out.push(q);
        travelled += 0.5;
        p = q;
        prev = d;
    }
    out
}

/// A piece of about `len` px of arc length from a polyline, from its start or at a random
/// offset.
pub(super) fn sub_run(
    path: &[[f32; 2]],
    len: f32,
    from_start: bool,
    rng: &mut Rng,
) -> Vec<[f32; 2]> {
    let mut arc = vec![0.0f32];
    for q in path.windows(2) {
        arc.push(arc.last().unwrap() + (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]));
    }
    let total = *arc.last().unwrap();
    if total <= len {
        return path.to_vec();
    }
    let off = if from_start {
        0.0
    } else {
        rng.range_f32(0.0, total - len)
    };
    path.iter()
        .zip(&arc)
        .filter(|(_, &a)| a >= off && a <= off + len)
        .map(|(p, _)| *p)
        .collect()
}

/// `v` scaled to unit length; ~0 for a (near-)zero `v`, whose segment then never agrees.
fn unit_or_zero(v: [f32; 2]) -> [f32; 2] {
    let l = v[0].hypot(v[1]).max(1e-6);
    [v[0] / l, v[1] / l]
}
