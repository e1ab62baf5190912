//! An oracle sketch: a directed sketch traced from a synthetic case's ground truth, on the
//! primitive lattice the pursuit produces (each centre the previous one plus [`STEP`] px along
//! its own axis, axes on [`AXIS_STEPS`] steps, turns of −1, 0 or +1 step, curve starts on
//! integer positions). It stands in for the pursuit and the direction sampler in tests, so
//! that the fill can be measured on its own. Not an estimator: it reads `gt_theta`, `gt_dir`
//! and the mask.
//!
//! - Boundary curves first: walks along the mask edge with the hair on the left, each centre
//!   on the edge (the window's left half over the hair). Each primitive's side angle is the
//!   true orientation just inside relative to the axis, δ in [−90°, 90°): within ±30° of
//!   the edge (5° hysteresis) a side boundary (a) with side angle δ, which may be negative
//!   (the dictionary's 0 refined by ±30°, as `.czs` stores it); beyond, a source/sink (b)
//!   with side angle δ mod 180°. Its label is the true direction.
//! - Seams next: where the true field jumps inside the hair (4-neighbours more than 30°
//!   apart in orientation, or opposite in direction), a walk along the jump: an occluding
//!   line (c) with each side's true orientation as its side angle (in [−30°, 150°)) and
//!   its labels, or a dividing line (d) where the directions leave the line on both sides
//!   and the orientation is continuous (a parting).
//! - Stream lines (e) over the interior, Jobard and Lefer's evenly spaced streamlines on the
//!   lattice: seeds [`OracleParams::spacing`] px from every curve (the deepest hair first),
//!   traced back to their root and then along the growth direction, each step the lattice
//!   turn closest to the true direction; a line stops where no turn is within
//!   [`OracleParams::max_error_deg`] of it (a seam, a parting, a whorl's centre: the lattice
//!   cannot turn tighter than a radius of about 19 px), off the hair, after
//!   [`OracleParams::max_prims`], or when it comes [`OracleParams::stop`] × spacing from
//!   another curve.
//!
//! Walked curves are split where the type or the labels change and after `max_prims`;
//! pieces cut from a walk are re-anchored on an integer start (moving them under a pixel).
//! Curves of fewer than 3 primitives are dropped. ρ of a primitive is the mean |∇I · n| of
//! the luma (not the high band) across the true orientation over its window's hair pixels.
//! Side angles are exact, not quantised. Light sequential work: CPU.

use super::prim::window;
use super::{Curve, Kind, Primitive, AXIS_QUANTUM, AXIS_STEPS, STEP};
use crate::synth::{distance_to, SynthCase};
use std::collections::VecDeque;
use std::f32::consts::PI;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleParams {
    /// Distance between neighbouring stream lines, px at 256² (scaled by the image's
    /// smaller side / 256).
    pub spacing: f32,
    /// A stream line stops this fraction of `spacing` from another curve's centres.
    pub stop: f32,
    /// Longest curve, primitives.
    pub max_prims: usize,
    /// A step is taken only if its axis is within this of the true direction (at the step's
    /// midpoint and end), degrees. The lattice quantum is 15°, so 7.5° is always reachable
    /// on a smooth field; more means the field turns faster than the lattice allows.
    pub max_error_deg: f32,
}

impl Default for OracleParams {
    fn default() -> Self {
        OracleParams {
            spacing: 14.0,
            stop: 0.5,
            max_prims: 40,
            max_error_deg: 20.0,
        }
    }
}

/// [`oracle_sketch_with`] at the default parameters.
pub fn oracle_sketch(case: &SynthCase) -> Vec<Curve> {
    oracle_sketch_with(case, &OracleParams::default())
}

/// The oracle sketch of `case`: boundary curves, then stream lines (see the module docs).
pub fn oracle_sketch_with(case: &SynthCase, p: &OracleParams) -> Vec<Curve> {
    let o = Oracle::new(case, p);
    let mut taken = Vec::new();
    let mut curves = o.boundaries(&mut taken);
    curves.extend(o.seams(&mut taken));
    o.streams(&mut curves);
    curves
}

/// A walked centre's (type, side angles, labels); None where it makes no primitive.
type Class = Option<(Kind, [f32; 2], [i8; 2])>;

/// Unit vector at lattice step k.
fn unit(k: i32) -> [f32; 2] {
    let a = k as f32 * AXIS_QUANTUM;
    [a.cos(), a.sin()]
}

fn lattice(a: f32) -> i32 {
    ((a / AXIS_QUANTUM).round() as i32).rem_euclid(AXIS_STEPS as i32)
}

fn axis_of(k: i32) -> f32 {
    k.rem_euclid(AXIS_STEPS as i32) as f32 * AXIS_QUANTUM
}

/// Angle between two unit vectors, radians.
fn angle(a: [f32; 2], b: [f32; 2]) -> f32 {
    (a[0] * b[0] + a[1] * b[1]).clamp(-1.0, 1.0).acos()
}

struct Oracle<'a> {
    case: &'a SynthCase,
    w: usize,
    h: usize,
    hair: Vec<bool>,
    /// Signed distance to the mask edge at pixel centres, px: negative on hair; outside
    /// the image counts as non-hair.
    sd: Vec<f32>,
    luma: Vec<f32>,
    spacing: f32,
    p: OracleParams,
}

impl<'a> Oracle<'a> {
    fn new(case: &'a SynthCase, p: &OracleParams) -> Oracle<'a> {
        let (w, h) = (case.width as usize, case.height as usize);
        let hair: Vec<bool> = case.mask.as_raw().iter().map(|&v| v > 127).collect();
        // Distances on a grid padded by one non-hair pixel all round.
        let (pw, ph) = (w + 2, h + 2);
        let mut padded = vec![false; pw * ph];
        for y in 0..h {
            for x in 0..w {
                padded[(y + 1) * pw + x + 1] = hair[y * w + x];
            }
        }
        let not: Vec<bool> = padded.iter().map(|&b| !b).collect();
        let to_out = distance_to(&not, pw, ph);
        let to_in = distance_to(&padded, pw, ph);
        let mut sd = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let k = (y + 1) * pw + x + 1;
                // The edge lies half a pixel from the centres on either side of it.
                sd[y * w + x] = if hair[y * w + x] {
                    -(to_out[k] - 0.5)
                } else {
                    to_in[k] - 0.5
                };
            }
        }
        let luma = case
            .image
            .pixels()
            .map(|q| 0.299 * q[0] as f32 + 0.587 * q[1] as f32 + 0.114 * q[2] as f32)
            .collect();
        let spacing = p.spacing * (w.min(h) as f32 / 256.0).max(0.25);
        Oracle {
            case,
            w,
            h,
            hair,
            sd,
            luma,
            spacing,
            p: *p,
        }
    }

    fn pixel(&self, q: [f32; 2]) -> Option<usize> {
        let (x, y) = (q[0].floor(), q[1].floor());
        (x >= 0.0 && y >= 0.0 && (x as usize) < self.w && (y as usize) < self.h)
            .then(|| y as usize * self.w + x as usize)
    }

    fn hair_at(&self, q: [f32; 2]) -> Option<usize> {
        self.pixel(q).filter(|&k| self.hair[k])
    }

    fn gt_dir(&self, k: usize) -> [f32; 2] {
        [self.case.gt_dir[2 * k], self.case.gt_dir[2 * k + 1]]
    }

    /// The signed distance, bilinear between pixel centres (clamped at the image border).
    fn sd_at(&self, q: [f32; 2]) -> f32 {
        let fx = (q[0] - 0.5).clamp(0.0, (self.w - 1) as f32);
        let fy = (q[1] - 0.5).clamp(0.0, (self.h - 1) as f32);
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.w - 1), (y0 + 1).min(self.h - 1));
        let (tx, ty) = (fx - x0 as f32, fy - y0 as f32);
        let v = |x: usize, y: usize| self.sd[y * self.w + x];
        (1.0 - ty) * ((1.0 - tx) * v(x0, y0) + tx * v(x1, y0))
            + ty * ((1.0 - tx) * v(x0, y1) + tx * v(x1, y1))
    }

    /// Outward unit normal of the edge (the signed distance's gradient).
    fn outward(&self, q: [f32; 2]) -> [f32; 2] {
        let gx = self.sd_at([q[0] + 1.0, q[1]]) - self.sd_at([q[0] - 1.0, q[1]]);
        let gy = self.sd_at([q[0], q[1] + 1.0]) - self.sd_at([q[0], q[1] - 1.0]);
        let n = gx.hypot(gy);
        if n > 1e-6 {
            [gx / n, gy / n]
        } else {
            [0.0, -1.0]
        }
    }

    /// Mean |∇I · n| across the true orientation over the hair pixels of the window's flow
    /// sides (central differences of the luma, gray units).
    fn rho(&self, kind: Kind, prim: &Primitive) -> f32 {
        let (w, h) = (self.w, self.h);
        let hair_sides = kind.hair_sides();
        let (mut sum, mut n) = (0.0f32, 0usize);
        window(kind, prim, w as u32, h as u32, |k, side| {
            let Some(s) = side.index() else { return };
            if !hair_sides[s] || !self.hair[k] {
                return;
            }
            let (x, y) = (k % w, k / w);
            if x == 0 || y == 0 || x + 1 == w || y + 1 == h {
                return;
            }
            let gx = 0.5 * (self.luma[k + 1] - self.luma[k - 1]);
            let gy = 0.5 * (self.luma[k + w] - self.luma[k - w]);
            let t = self.case.gt_theta[k];
            sum += (-gx * t.sin() + gy * t.cos()).abs();
            n += 1;
        });
        if n == 0 {
            0.0
        } else {
            sum / n as f32
        }
    }

    // -------------------------------------------------------------------------------------
    // Walks along a line: the mask edge, or a seam of the true field.

    /// Lattice steps from `start` (axis step `k`), each the turn that keeps `off` (the
    /// distance from the line followed, px) smallest at the step's end and midpoint. Stops
    /// where that exceeds 1.5 px, where `keep` refuses the next centre, within 3 px of
    /// `others` or of its own earlier centres (a closed loop), or after `max` centres.
    fn walk(
        &self,
        start: [f32; 2],
        k: i32,
        off: &dyn Fn([f32; 2]) -> f32,
        keep: &dyn Fn([f32; 2]) -> bool,
        others: &[[f32; 2]],
        max: usize,
    ) -> Vec<([f32; 2], i32)> {
        let (mut c, mut k) = (start, k);
        let mut out = vec![(c, k)];
        while out.len() < max {
            let (k2, c2, score) = (-1..=1)
                .map(|dk| {
                    let k2 = k + dk;
                    let u = unit(k2);
                    let c2 = [c[0] + STEP * u[0], c[1] + STEP * u[1]];
                    let mid = [c[0] + 0.5 * STEP * u[0], c[1] + 0.5 * STEP * u[1]];
                    (k2, c2, off(c2).max(off(mid)))
                })
                .min_by(|a, b| a.2.total_cmp(&b.2))
                .unwrap();
            if score > 1.5 || !keep(c2) {
                break;
            }
            let own = out.len().saturating_sub(2);
            if near(c2, others.iter().copied()) || near(c2, out[..own].iter().map(|o| o.0)) {
                break;
            }
            k = k2;
            c = c2;
            out.push((c, k));
        }
        out
    }

    /// Marks `set` pixels within 4 px of the centres visited.
    fn mark(&self, visited: &mut [bool], centres: impl Iterator<Item = [f32; 2]>) {
        let (w, h) = (self.w, self.h);
        let r = 4.0f32;
        for c in centres {
            let (x0, x1) = (
                (c[0] - r).max(0.0) as usize,
                ((c[0] + r).max(0.0) as usize).min(w - 1),
            );
            let (y0, y1) = (
                (c[1] - r).max(0.0) as usize,
                ((c[1] + r).max(0.0) as usize).min(h - 1),
            );
            for y in y0..=y1 {
                for x in x0..=x1 {
                    if (x as f32 + 0.5 - c[0]).hypot(y as f32 + 0.5 - c[1]) <= r {
                        visited[y * w + x] = true;
                    }
                }
            }
        }
    }

    /// The hair pixel nearest `c` along `n` at one of `ds` px (in that order of preference).
    fn probe(&self, c: [f32; 2], n: [f32; 2], ds: &[f32]) -> Option<usize> {
        ds.iter()
            .find_map(|&d| self.hair_at([c[0] + d * n[0], c[1] + d * n[1]]))
    }

    /// Curves from a walked chain and each centre's (type, side angles, labels): runs of one
    /// type and label pair, cut at [`OracleParams::max_prims`], of ≥ 3 primitives.
    fn split(&self, chain: &[([f32; 2], i32)], class: &[Class]) -> Vec<Curve> {
        let mut curves = Vec::new();
        let mut run: Vec<Primitive> = Vec::new();
        let mut cur: Option<(Kind, [i8; 2])> = None;
        let mut flush = |run: &mut Vec<Primitive>, cur: Option<(Kind, [i8; 2])>| {
            if let Some((kind, dirs)) = cur {
                if run.len() >= 3 {
                    let mut prims = snap(std::mem::take(run));
                    for p in prims.iter_mut() {
                        p.rho = self.rho(kind, p);
                    }
                    curves.push(Curve { kind, prims, dirs });
                }
            }
            run.clear();
        };
        for (&(c, k), cl) in chain.iter().zip(class) {
            let key = cl.map(|(kind, _, dirs)| (kind, dirs));
            if key != cur || run.len() >= self.p.max_prims {
                flush(&mut run, cur);
                cur = key;
            }
            if let Some((_, side, _)) = cl {
                run.push(Primitive {
                    shift: 0.0,
                    x: c[0],
                    y: c[1],
                    axis: axis_of(k),
                    rho: 0.0,
                    side: *side,
                });
            }
        }
        flush(&mut run, cur);
        curves
    }

    // -------------------------------------------------------------------------------------
    // Boundaries.

    fn boundaries(&self, taken: &mut Vec<[f32; 2]>) -> Vec<Curve> {
        let (w, h) = (self.w, self.h);
        let edge: Vec<bool> = (0..w * h)
            .map(|k| {
                let (x, y) = (k % w, k / w);
                self.hair[k]
                    && (x == 0
                        || y == 0
                        || x + 1 == w
                        || y + 1 == h
                        || !self.hair[k - 1]
                        || !self.hair[k + 1]
                        || !self.hair[k - w]
                        || !self.hair[k + w])
            })
            .collect();
        let mut visited = vec![false; w * h];
        let mut curves = Vec::new();
        let mut order = 0usize;
        let mut next: Option<usize> = None;
        let off = |q: [f32; 2]| self.sd_at(q).abs();
        let keep = |q: [f32; 2]| q[0] >= 0.0 && q[1] >= 0.0 && q[0] <= w as f32 && q[1] <= h as f32;
        loop {
            // Continue where the last walk stopped (a corner it could not turn), else the
            // next edge pixel in raster order.
            let e = match next.take() {
                Some(e) => e,
                None => {
                    while order < w * h && (!edge[order] || visited[order]) {
                        order += 1;
                    }
                    if order == w * h {
                        break;
                    }
                    order
                }
            };
            let (ex, ey) = ((e % w) as f32, (e / w) as f32);
            // The pixel corner nearest the edge: curve starts are integer positions.
            let start = [
                [ex, ey],
                [ex + 1.0, ey],
                [ex, ey + 1.0],
                [ex + 1.0, ey + 1.0],
            ]
            .into_iter()
            .min_by(|a, b| off(*a).total_cmp(&off(*b)))
            .unwrap();
            let g = self.outward(start);
            // Left normal (sin a, −cos a) = −g  ⇒  a = atan2(−g_x, g_y).
            let k = lattice((-g[0]).atan2(g[1]));
            let chain = self.walk(start, k, &off, &keep, taken, 1000);
            visited[e] = true;
            self.mark(&mut visited, chain.iter().map(|c| c.0));
            let end = chain.last().unwrap().0;
            next = self.nearest_in(&edge, &visited, end, 8.0);
            if chain.len() < 3 {
                continue;
            }
            taken.extend(chain.iter().map(|c| c.0));
            let class = self.classify_edge(&chain);
            curves.extend(self.split(&chain, &class));
        }
        curves
    }

    /// The `set` pixel not yet visited nearest `q`, within `r` px.
    fn nearest_in(&self, set: &[bool], visited: &[bool], q: [f32; 2], r: f32) -> Option<usize> {
        let (w, h) = (self.w as i64, self.h as i64);
        let (cx, cy) = (q[0].floor() as i64, q[1].floor() as i64);
        let ri = r.ceil() as i64;
        let mut best: Option<(f32, usize)> = None;
        for y in (cy - ri).max(0)..=(cy + ri).min(h - 1) {
            for x in (cx - ri).max(0)..=(cx + ri).min(w - 1) {
                let k = (y * w + x) as usize;
                if !set[k] || visited[k] {
                    continue;
                }
                let d = (x as f32 + 0.5 - q[0]).hypot(y as f32 + 0.5 - q[1]);
                if d <= r && best.is_none_or(|b| d < b.0) {
                    best = Some((d, k));
                }
            }
        }
        best.map(|b| b.1)
    }

    /// Each edge centre's type, side angle and label from the true flow just inside: the
    /// deviation δ of the flow from the axis, taken in [−90°, 90°), makes a side boundary
    /// while |δ| ≤ 30° (side angle δ, which may be negative: the dictionary's 0 refined by
    /// ±30°) and a source/sink beyond (side angle δ mod 180°), with 5° of hysteresis so
    /// the type does not flicker; the label says whether hair grows along the flow vector.
    fn classify_edge(&self, chain: &[([f32; 2], i32)]) -> Vec<Class> {
        let mut prev: Option<Kind> = None;
        chain
            .iter()
            .map(|&(c, k)| {
                let axis = axis_of(k);
                let nl = [axis.sin(), -axis.cos()];
                let px = self.probe(c, nl, &[1.5, 0.5, 2.5, 3.5])?;
                let theta = self.case.gt_theta[px];
                let delta = (axis - theta + 0.5 * PI).rem_euclid(PI) - 0.5 * PI;
                let limit = match prev {
                    Some(Kind::Boundary) => 35f32,
                    Some(_) => 25.0,
                    None => 30.0,
                }
                .to_radians();
                let (kind, side) = if delta.abs() <= limit {
                    (Kind::Boundary, delta)
                } else {
                    (Kind::Source, delta.rem_euclid(PI))
                };
                prev = Some(kind);
                let flow = axis - side;
                let g = self.gt_dir(px);
                let label = if flow.cos() * g[0] + flow.sin() * g[1] >= 0.0 {
                    1
                } else {
                    -1
                };
                Some((kind, [side, 0.0], [label, 0]))
            })
            .collect()
    }

    // -------------------------------------------------------------------------------------
    // Seams: where the true field jumps inside the hair.

    fn seams(&self, taken: &mut Vec<[f32; 2]>) -> Vec<Curve> {
        let (w, h) = (self.w, self.h);
        // Both pixels of every 4-neighbour pair whose orientations differ by more than 30° or
        // whose directions oppose: a band two pixels wide along each seam.
        let mut jump = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let k = y * w + x;
                if !self.hair[k] {
                    continue;
                }
                for j in [(x + 1 < w).then(|| k + 1), (y + 1 < h).then(|| k + w)]
                    .into_iter()
                    .flatten()
                {
                    if !self.hair[j] {
                        continue;
                    }
                    let (a, b) = (self.gt_dir(k), self.gt_dir(j));
                    let dot = a[0] * b[0] + a[1] * b[1];
                    if dot.abs() < 30f32.to_radians().cos() || dot < 0.0 {
                        jump[k] = true;
                        jump[j] = true;
                    }
                }
            }
        }
        let dist = distance_to(&jump, w, h);
        let off = |q: [f32; 2]| {
            // Bilinear between pixel centres, like the signed distance.
            let fx = (q[0] - 0.5).clamp(0.0, (w - 1) as f32);
            let fy = (q[1] - 0.5).clamp(0.0, (h - 1) as f32);
            let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
            let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
            let (tx, ty) = (fx - x0 as f32, fy - y0 as f32);
            let v = |x: usize, y: usize| dist[y * w + x].min(1e6);
            (1.0 - ty) * ((1.0 - tx) * v(x0, y0) + tx * v(x1, y0))
                + ty * ((1.0 - tx) * v(x0, y1) + tx * v(x1, y1))
        };
        let keep = |q: [f32; 2]| self.hair_at(q).is_some() && -self.sd_at(q) >= 1.0;
        let mut visited = vec![false; w * h];
        let mut curves = Vec::new();
        for e in 0..w * h {
            if !jump[e] || visited[e] {
                continue;
            }
            visited[e] = true;
            let seed = [(e % w) as f32 + 0.5, (e / w) as f32 + 0.5];
            // The seam's direction: the principal axis of the band's pixels nearby.
            let (mut sxx, mut sxy, mut syy, mut n) = (0.0f32, 0.0f32, 0.0f32, 0);
            let (ex, ey) = ((e % w) as i64, (e / w) as i64);
            for y in (ey - 4).max(0)..=(ey + 4).min(h as i64 - 1) {
                for x in (ex - 4).max(0)..=(ex + 4).min(w as i64 - 1) {
                    if jump[y as usize * w + x as usize] {
                        let (dx, dy) = ((x - ex) as f32, (y - ey) as f32);
                        sxx += dx * dx;
                        sxy += dx * dy;
                        syy += dy * dy;
                        n += 1;
                    }
                }
            }
            if n < 4 {
                continue;
            }
            let phi = 0.5 * (2.0 * sxy).atan2(sxx - syy);
            // Back to one end, then from there (rounded: starts are integers) the other way.
            let back = self.walk(seed, lattice(phi) + 12, &off, &keep, taken, 1000);
            let (end, k_end) = *back.last().unwrap();
            let start = [end[0].round(), end[1].round()];
            let chain = self.walk(start, k_end + 12, &off, &keep, taken, 1000);
            self.mark(&mut visited, back.iter().chain(chain.iter()).map(|c| c.0));
            if chain.len() < 3 {
                continue;
            }
            let class = self.classify_seam(&chain);
            let found = self.split(&chain, &class);
            for c in &found {
                taken.extend(c.prims.iter().map(|p| [p.x, p.y]));
            }
            curves.extend(found);
        }
        curves
    }

    /// Each seam centre's type, side angles and labels from the true flow a little way to
    /// either side: an orientation jump of more than 30° makes an occluding line, opposite
    /// directions leaving the line on both sides a dividing line (labels fixed outward);
    /// anything else an occluding line with its labels. Side angles of an occluding line
    /// are taken in [−30°, 150°) (the dictionary's 0, 60, 90, 120 refined by ±30°).
    fn classify_seam(&self, chain: &[([f32; 2], i32)]) -> Vec<Class> {
        chain
            .iter()
            .map(|&(c, k)| {
                let axis = axis_of(k);
                let nl = [axis.sin(), -axis.cos()];
                let nr = [-nl[0], -nl[1]];
                let ds = [2.5, 2.0, 3.0, 3.5];
                let (pl, pr) = (self.probe(c, nl, &ds)?, self.probe(c, nr, &ds)?);
                let (gl, gr) = (self.gt_dir(pl), self.gt_dir(pr));
                let (tl, tr) = (gl[1].atan2(gl[0]), gr[1].atan2(gr[0]));
                let dot = gl[0] * gr[0] + gl[1] * gr[1];
                if dot.abs() >= 30f32.to_radians().cos() && dot < 0.0 {
                    let sl = (axis - tl).rem_euclid(2.0 * PI);
                    let sr = (tr - axis).rem_euclid(2.0 * PI);
                    if sl < PI && sr < PI {
                        return Some((Kind::Dividing, [sl, sr], [1, 1]));
                    }
                }
                if dot.abs() >= 30f32.to_radians().cos() && dot > 0.0 {
                    return None;
                }
                let wrap = |a: f32| (a + PI / 6.0).rem_euclid(PI) - PI / 6.0;
                let (sl, sr) = (wrap(axis - tl), wrap(tr - axis));
                let label = |flow: f32, g: [f32; 2]| -> i8 {
                    if flow.cos() * g[0] + flow.sin() * g[1] >= 0.0 {
                        1
                    } else {
                        -1
                    }
                };
                Some((
                    Kind::Occluding,
                    [sl, sr],
                    [label(axis - sl, gl), label(axis + sr, gr)],
                ))
            })
            .collect()
    }

    // -------------------------------------------------------------------------------------
    // Stream lines.

    fn streams(&self, curves: &mut Vec<Curve>) {
        let (w, h) = (self.w, self.h);
        let mut grid = Grid::new(w, h, self.spacing);
        for c in curves.iter() {
            for p in &c.prims {
                grid.add([p.x, p.y], usize::MAX);
            }
        }
        // Fallback seeds: the hair on a grid, deepest first.
        let depth = |k: usize| -self.sd[k];
        let step = (self.spacing / 3.0).max(1.0) as usize;
        let mut fallback: Vec<usize> = (0..h)
            .step_by(step)
            .flat_map(|y| (0..w).step_by(step).map(move |x| y * w + x))
            .filter(|&k| self.hair[k] && depth(k) >= 2.0)
            .collect();
        fallback.sort_by(|&a, &b| depth(b).total_cmp(&depth(a)).then(a.cmp(&b)));
        let mut fallback = fallback.into_iter();
        let mut queue: VecDeque<[f32; 2]> = VecDeque::new();
        loop {
            let seed = match queue.pop_front() {
                Some(s) => s,
                None => match fallback.next() {
                    Some(k) => [(k % w) as f32 + 0.5, (k / w) as f32 + 0.5],
                    None => break,
                },
            };
            if self.hair_at(seed).is_none()
                || -self.sd_at(seed) < 2.0
                || grid.nearest(seed, self.spacing) < 0.9 * self.spacing
            {
                continue;
            }
            let id = curves.len();
            let Some(prims) = self.stream_from(seed, &grid, id) else {
                continue;
            };
            for p in &prims {
                grid.add([p.x, p.y], id);
                let n = [p.axis.sin(), -p.axis.cos()];
                for s in [-1.0, 1.0] {
                    queue.push_back([p.x + s * self.spacing * n[0], p.y + s * self.spacing * n[1]]);
                }
            }
            curves.push(Curve {
                kind: Kind::Stream,
                prims,
                dirs: [1, 1],
            });
        }
    }

    /// The stream line through `seed`: traced back to its root, which is rounded to an
    /// integer start, then forward along the growth direction.
    fn stream_from(&self, seed: [f32; 2], grid: &Grid, id: usize) -> Option<Vec<Primitive>> {
        let back = self.trace(seed, -1.0, grid, id);
        let root = back.last().map_or(seed, |b| b.0);
        for start in [root, seed] {
            let start = [start[0].round(), start[1].round()];
            let fwd = self.trace(start, 1.0, grid, id);
            if fwd.len() >= 3 {
                let prims: Vec<Primitive> = fwd
                    .iter()
                    .map(|&(c, k)| {
                        let mut p = Primitive {
                            shift: 0.0,
                            x: c[0],
                            y: c[1],
                            axis: axis_of(k),
                            rho: 0.0,
                            side: [0.0; 2],
                        };
                        p.rho = self.rho(Kind::Stream, &p);
                        p
                    })
                    .collect();
                return Some(prims);
            }
        }
        None
    }

    /// Lattice steps from `start` along `sign` × the growth direction.
    fn trace(&self, start: [f32; 2], sign: f32, grid: &Grid, id: usize) -> Vec<([f32; 2], i32)> {
        let max_err = self.p.max_error_deg.to_radians();
        let stop = self.p.stop * self.spacing;
        let dir_at = |q: [f32; 2]| {
            self.hair_at(q).map(|k| {
                let g = self.gt_dir(k);
                [sign * g[0], sign * g[1]]
            })
        };
        let Some(g0) = dir_at(start) else {
            return Vec::new();
        };
        if grid.nearest_other(start, stop, id) < stop {
            return Vec::new();
        }
        let mut k = lattice(g0[1].atan2(g0[0]));
        let mut c = start;
        let mut out = vec![(c, k)];
        while out.len() < self.p.max_prims {
            let mut best: Option<(i32, [f32; 2], f32)> = None;
            for dk in -1..=1 {
                let k2 = k + dk;
                let u = unit(k2);
                let c2 = [c[0] + STEP * u[0], c[1] + STEP * u[1]];
                let mid = [c[0] + 0.5 * STEP * u[0], c[1] + 0.5 * STEP * u[1]];
                let (Some(gm), Some(ge)) = (dir_at(mid), dir_at(c2)) else {
                    continue;
                };
                let err = angle(u, gm).max(angle(u, ge));
                if best.is_none_or(|b| err < b.2) {
                    best = Some((k2, c2, err));
                }
            }
            let Some((k2, c2, err)) = best else { break };
            if err > max_err || -self.sd_at(c2) < 1.0 {
                break;
            }
            if grid.nearest_other(c2, stop, id) < stop {
                break;
            }
            // A loop (round a whorl): stop before running over its own start.
            if out
                .iter()
                .take(out.len().saturating_sub(2))
                .any(|o| (o.0[0] - c2[0]).hypot(o.0[1] - c2[1]) < stop)
            {
                break;
            }
            k = k2;
            c = c2;
            out.push((c, k));
        }
        out
    }
}

/// Whether any of `pts` lies within 3 px of `q`.
fn near(q: [f32; 2], mut pts: impl Iterator<Item = [f32; 2]>) -> bool {
    pts.any(|o| (o[0] - q[0]).hypot(o[1] - q[1]) < 3.0)
}

/// Re-anchors a piece cut out of a chain on the lattice: its first centre rounded to integers,
/// the others following by [`STEP`] along the axes (moves each by under a pixel).
fn snap(ps: Vec<Primitive>) -> Vec<Primitive> {
    let mut out: Vec<Primitive> = Vec::with_capacity(ps.len());
    for (i, p) in ps.into_iter().enumerate() {
        let mut q = p;
        if i == 0 {
            q.x = p.x.round();
            q.y = p.y.round();
        } else {
            let prev = out[i - 1];
            let t = q.tangent();
            q.x = prev.x + STEP * t[0];
            q.y = prev.y + STEP * t[1];
        }
        out.push(q);
    }
    out
}

/// Primitive centres in square cells, for nearest-centre queries.
struct Grid {
    cell: f32,
    nx: usize,
    ny: usize,
    cells: Vec<Vec<([f32; 2], usize)>>,
}

impl Grid {
    fn new(w: usize, h: usize, cell: f32) -> Grid {
        let nx = (w as f32 / cell).ceil() as usize + 1;
        let ny = (h as f32 / cell).ceil() as usize + 1;
        Grid {
            cell,
            nx,
            ny,
            cells: vec![Vec::new(); nx * ny],
        }
    }

    fn index(&self, q: [f32; 2]) -> (i64, i64) {
        (
            (q[0] / self.cell).floor() as i64,
            (q[1] / self.cell).floor() as i64,
        )
    }

    fn add(&mut self, q: [f32; 2], id: usize) {
        let (cx, cy) = self.index(q);
        let cx = cx.clamp(0, self.nx as i64 - 1) as usize;
        let cy = cy.clamp(0, self.ny as i64 - 1) as usize;
        self.cells[cy * self.nx + cx].push((q, id));
    }

    /// Distance to the nearest centre not of curve `id`, searched within `r` (∞ beyond).
    fn nearest_other(&self, q: [f32; 2], r: f32, id: usize) -> f32 {
        let (cx, cy) = self.index(q);
        let span = (r / self.cell).ceil() as i64;
        let mut best = f32::INFINITY;
        for y in cy - span..=cy + span {
            for x in cx - span..=cx + span {
                if x < 0 || y < 0 || x >= self.nx as i64 || y >= self.ny as i64 {
                    continue;
                }
                for &(p, pid) in &self.cells[y as usize * self.nx + x as usize] {
                    if pid != id {
                        best = best.min((p[0] - q[0]).hypot(p[1] - q[1]));
                    }
                }
            }
        }
        best
    }

    fn nearest(&self, q: [f32; 2], r: f32) -> f32 {
        self.nearest_other(q, r, usize::MAX - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{synth, Style, SynthParams};

    #[test]
    fn curves_sit_on_the_lattice_and_follow_the_truth() {
        let case = synth(&SynthParams {
            style: Style::Long,
            seed: 1,
            width: 256,
            height: 256,
        });
        let curves = oracle_sketch(&case);
        let n_b = curves.iter().filter(|c| c.kind != Kind::Stream).count();
        println!("{} curves, {n_b} on the edge", curves.len());
        assert!(n_b > 0 && curves.len() > n_b);
        for c in &curves {
            assert!(c.prims.len() >= 3);
            let s = c.prims[0];
            assert_eq!(
                (s.x, s.y),
                (s.x.round(), s.y.round()),
                "start off the integers"
            );
            for p in &c.prims {
                let q = p.axis / AXIS_QUANTUM;
                assert!((q - q.round()).abs() < 1e-4 && (0.0..2.0 * PI).contains(&p.axis));
                assert!(p.rho.is_finite() && p.rho >= 0.0);
            }
            for pair in c.prims.windows(2) {
                // Each centre is the previous one plus STEP along its own (new) axis, as
                // `.czs` rebuilds them.
                let (a, b) = (pair[0], pair[1]);
                let t = b.tangent();
                assert!((b.x - a.x - STEP * t[0]).abs() < 1e-3);
                assert!((b.y - a.y - STEP * t[1]).abs() < 1e-3);
                let turn = ((b.axis - a.axis) / AXIS_QUANTUM).round() as i32;
                assert!([-1, 0, 1, 23, -23].contains(&turn), "turn {turn}");
            }
            match c.kind {
                Kind::Stream => {
                    assert_eq!(c.dirs, [1, 1]);
                    // The axis follows the true growth direction within 20°.
                    for p in &c.prims {
                        let k = p.y as usize * 256 + p.x as usize;
                        let g = [case.gt_dir[2 * k], case.gt_dir[2 * k + 1]];
                        assert!(angle(p.tangent(), g) < 20f32.to_radians() + 1e-3);
                    }
                }
                Kind::Boundary | Kind::Source => assert!(c.dirs[0] != 0 && c.dirs[1] == 0),
                Kind::Occluding => assert!(c.dirs[0] != 0 && c.dirs[1] != 0),
                Kind::Dividing => assert_eq!(c.dirs, [1, 1]),
            }
        }
    }
}
