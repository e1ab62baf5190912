//! Nondirectional 2-D hair tracing on a refined orientation map (C13 §2.1, "Nondirectional
//! Hair Tracing").
//!
//! The tracer follows Chai et al. 2012: seeds at confident pixels, bidirectional tracing with a
//! health budget, an occupancy band so that curves do not pile up. As C13 prescribes, the next
//! direction at each vertex is chosen by arc sampling (Tan et al. 2008, Beeler et al. 2012)
//! instead of C12's re-centering: a fan of circular arcs of different curvatures leaves the
//! vertex along the current direction, each is scored by how well the orientation map agrees
//! with the arc's tangent along it (weighted by confidence), and the step follows the best.
//! Judging a whole arc instead of one pixel makes the choice robust to the stripy confidence of
//! strand images, where the pixels between strands carry little information.
//!
//! The curves are undirected: their vertex order is whatever tracing produced; see
//! [`crate::analyze::resolve`] for the growth direction. Everything here is sequential and
//! deterministic (seed order is by confidence, ties by pixel index).
//!
//! Coordinates: pixel (i, j) has its centre at (i + 0.5, j + 0.5), x right, y down; angles
//! are measured from +x towards +y, as in the orientation map.

use crate::base::filter::box_mean;

/// Tracing parameters. Lengths are in pixels.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TraceParams {
    /// Step length along a curve.
    pub step: f32,
    /// Seed threshold as a fraction of the 99th-percentile confidence over the hair.
    pub seed_conf: f32,
    /// Health points: a curve stops after this many bad steps not paid back by good ones.
    pub health: u32,
    /// A step whose local confidence (fraction of the 99th percentile, averaged over 5x5
    /// pixels) is below this costs a health point.
    pub low_conf: f32,
    /// A step turning by more than this (degrees) costs a health point.
    pub max_bend_deg: f32,
    /// Curves shorter than this are dropped.
    pub min_len: f32,
    /// Vertex spacing of the returned curves.
    pub spacing: f32,
    /// A curve stops when it comes closer than this to an accepted curve, and no seed is
    /// taken that close to one, so no two curves run on top of each other.
    pub min_separation: f32,
    /// At most this many curves are returned (the most confident seeds go first).
    pub max_curves: usize,
    /// Curves are cut at every apex (topmost point, y smallest) from which they descend by at
    /// least this much on both sides; 0 disables the cut. Why: where hair is parted, the
    /// orientation is continuous across the part while the growth direction flips, and on
    /// images where the part shows no scalp the tracer runs straight across it, making one
    /// curve of two strands with opposite directions, which no flag s_i can resolve. Hair
    /// falls away from a part on both sides, so such a curve peaks at the part. Cutting any
    /// other arch (a swept strand) only costs the resolution a little continuity: both pieces
    /// still follow the same neighbours. 1 px by default: at a side part the tracer overshoots
    /// onto the narrow side by only 10-30 px of nearly level hair, which falls by 1-3 px
    /// there; a 6 px drop missed those, 1 px lifts the synthetic side parts from 96.8-97.5%
    /// to 98.1-98.6% of curve length resolved the true way (`tests/it/analyze.rs`). The cost:
    /// the tight arcs round a whorl are cut as well, and on the synthetic whorl (seed 1) two
    /// short pieces near its centre then resolve the wrong way (98.3% instead of 100%).
    pub apex_drop: f32,
}

impl Default for TraceParams {
    fn default() -> Self {
        TraceParams {
            step: 2.0,
            seed_conf: 0.2,
            health: 5,
            low_conf: 0.05,
            max_bend_deg: 20.0,
            min_len: 20.0,
            spacing: 2.0,
            min_separation: 4.0,
            max_curves: 20_000,
            apex_drop: 1.0,
        }
    }
}

/// A 2-D curve of equally spaced vertices (pixel coordinates, x right, y down).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Curve {
    pub points: Vec<[f32; 2]>,
}

impl Curve {
    /// Polyline length.
    pub fn length(&self) -> f32 {
        polyline_len(&self.points)
    }
}

/// Arc candidates per side of straight (so 2 * ARC_HALF + 1 in all).
const ARC_HALF: i32 = 6;
/// Arc length scored per candidate, in steps: long enough to see past one strand gap.
const ARC_STEPS: f32 = 4.0;
/// Samples per arc.
const ARC_SAMPLES: usize = 8;
/// A curve stops when its heading turns by more than HOOK_TURN within HOOK_STEPS steps.
const HOOK_STEPS: usize = 8;
const HOOK_TURN: f32 = std::f32::consts::FRAC_PI_2;

/// The maps, with derived per-pixel data.
struct Field<'a> {
    theta: &'a [f32],
    /// Confidence as a fraction of the 99th percentile, clamped to [0, 1]; 0 off hair.
    cn: Vec<f32>,
    /// `cn` averaged over 5x5 pixels, for the health rule.
    local: Vec<f32>,
    mask: &'a [u8],
    w: usize,
    h: usize,
}

impl Field<'_> {
    /// Pixel index of a point, if it lies on hair with a valid orientation.
    fn hair_at(&self, p: [f32; 2]) -> Option<usize> {
        if !(p[0] >= 0.0 && p[1] >= 0.0) {
            return None;
        }
        let (x, y) = (p[0] as usize, p[1] as usize);
        if x >= self.w || y >= self.h {
            return None;
        }
        let i = y * self.w + x;
        (self.mask[i] != 0 && self.theta[i].is_finite()).then_some(i)
    }
}

/// Traces undirected curves over the hair. `theta` (radians in [0, pi), NaN off hair), `conf`
/// and `mask` (nonzero = hair) are row-major `width * height`. Deterministic.
///
/// # Panics
/// If a map's length is not `width * height`.
pub fn trace_curves(
    theta: &[f32],
    conf: &[f32],
    mask: &[u8],
    width: u32,
    height: u32,
    p: &TraceParams,
) -> Vec<Curve> {
    let (w, h) = (width as usize, height as usize);
    let n = w * h;
    assert!(
        theta.len() == n && conf.len() == n && mask.len() == n,
        "trace_curves: maps must be {w}x{h} = {n} long (theta {}, conf {}, mask {})",
        theta.len(),
        conf.len(),
        mask.len()
    );
    let step = p.step.max(0.25);
    let spacing = p.spacing.max(0.25);
    let is_hair = |i: usize| mask[i] != 0 && theta[i].is_finite() && conf[i].is_finite();

    // Normalising by a high percentile rather than the maximum keeps a few hot pixels from
    // making every threshold meaningless.
    let mut hair_conf: Vec<f32> = (0..n).filter(|&i| is_hair(i)).map(|i| conf[i]).collect();
    if hair_conf.is_empty() {
        return Vec::new();
    }
    let k = ((hair_conf.len() - 1) as f32 * 0.99).round() as usize;
    let (_, &mut p99, _) = hair_conf.select_nth_unstable_by(k, f32::total_cmp);
    let scale = if p99 > 0.0 { 1.0 / p99 } else { 0.0 };
    let cn: Vec<f32> = (0..n)
        .map(|i| {
            if is_hair(i) {
                (conf[i] * scale).clamp(0.0, 1.0)
            } else {
                0.0
            }
        })
        .collect();
    let local = box_mean(&cn, w, h, 2);
    let field = Field {
        theta,
        cn,
        local,
        mask,
        w,
        h,
    };

    // Most confident first: those are the clearest strands, and they claim their band first.
    let mut seeds: Vec<usize> = (0..n)
        .filter(|&i| is_hair(i) && field.cn[i] >= p.seed_conf)
        .collect();
    seeds.sort_by(|&a, &b| field.cn[b].total_cmp(&field.cn[a]).then(a.cmp(&b)));

    // Occupancy of accepted curves: 2 within min_separation / 2 of a vertex (the core a new
    // curve may not enter), 1 within min_separation (where no seed is taken), 0 free. Seeds
    // need the full separation so that a new curve starts clear of the old ones; the core
    // alone stops tracing so that curves in converging flow run on a while before stopping
    // instead of being cut short (and dropped) as soon as they come near.
    let mut owner = vec![0u8; n];
    // Pixels that already started or carried a rejected trace; seeding there again would
    // only repeat the same short trace.
    let mut tried = vec![false; n];
    // Per-trace stamps for the self-overlap check (spirals around a whorl).
    let mut stamp = vec![0u32; n];
    let mut stamp_ord = vec![0i32; n];
    let mut ctx = TraceCtx {
        field: &field,
        p,
        step,
        stamp: &mut stamp,
        stamp_ord: &mut stamp_ord,
        trace_id: 0,
    };

    let mut curves: Vec<Curve> = Vec::new();
    for &s in &seeds {
        if curves.len() >= p.max_curves {
            break;
        }
        if owner[s] != 0 || tried[s] {
            continue;
        }
        tried[s] = true;
        let start = [(s % w) as f32 + 0.5, (s / w) as f32 + 0.5];
        let t0 = theta[s];
        let d0 = [t0.cos(), t0.sin()];
        ctx.trace_id += 1;
        ctx.mark_self(start, 0);
        let fwd = ctx.trace_one(&owner, start, d0, 1);
        let bwd = ctx.trace_one(&owner, start, [-d0[0], -d0[1]], -1);
        let mut pts: Vec<[f32; 2]> = bwd.into_iter().rev().collect();
        pts.push(start);
        pts.extend(fwd);

        if polyline_len(&pts) < p.min_len {
            for q in &pts {
                if let Some(i) = field.hair_at(*q) {
                    tried[i] = true;
                }
            }
            continue;
        }
        // The band covers the whole trace, also pieces dropped below: they were traced
        // already, and seeding there again would only retrace them.
        let full = resample(&pts, spacing);
        for q in &full {
            mark_disk(&mut owner, w, h, *q, p.min_separation, 1);
            mark_disk(&mut owner, w, h, *q, 0.5 * p.min_separation, 2);
        }
        let pieces = if p.apex_drop > 0.0 {
            split_at_apexes(&pts, p.apex_drop)
        } else {
            vec![pts]
        };
        for piece in pieces {
            if curves.len() < p.max_curves && polyline_len(&piece) >= p.min_len {
                curves.push(Curve {
                    points: resample(&piece, spacing),
                });
            }
        }
    }
    curves
}

struct TraceCtx<'a> {
    field: &'a Field<'a>,
    p: &'a TraceParams,
    step: f32,
    stamp: &'a mut [u32],
    stamp_ord: &'a mut [i32],
    trace_id: u32,
}

impl TraceCtx<'_> {
    /// Stamps a 3x3 block around `q` with the current trace and the vertex ordinal.
    fn mark_self(&mut self, q: [f32; 2], ord: i32) {
        let (w, h) = (self.field.w as i64, self.field.h as i64);
        let (cx, cy) = (q[0].floor() as i64, q[1].floor() as i64);
        for y in cy - 1..=cy + 1 {
            for x in cx - 1..=cx + 1 {
                if x >= 0 && y >= 0 && x < w && y < h {
                    let i = (y * w + x) as usize;
                    self.stamp[i] = self.trace_id;
                    self.stamp_ord[i] = ord;
                }
            }
        }
    }

    /// Traces from `start` along `dir` (unit) until health runs out, the mask ends, another
    /// curve's band or this curve's own earlier part is reached. Returns the new vertices,
    /// without `start`. `sign` orders the ordinals (+1 forward, -1 backward).
    fn trace_one(
        &mut self,
        owner: &[u8],
        start: [f32; 2],
        dir: [f32; 2],
        sign: i32,
    ) -> Vec<[f32; 2]> {
        let f = self.field;
        let p = self.p;
        let step = self.step;
        let max_bend = p.max_bend_deg.to_radians();
        // Candidate curvatures reach a little past the bend limit, so that a truly sharp turn
        // is followed (and paid for in health) rather than missed.
        let k_max = 1.5 * max_bend / step;
        let arc_len = ARC_STEPS * step;
        // Vertices of the own trace closer than this many ordinals are neighbours, not a loop.
        let window = ((p.min_separation + 3.0) / step).ceil() as i32 + 2;
        let max_vertices = (4 * (f.w + f.h)) as f32 / step;

        let mut out: Vec<[f32; 2]> = Vec::new();
        let mut last_good = 0usize;
        let mut health = p.health as i32;
        let mut pos = start;
        let mut phi = dir[1].atan2(dir[0]);
        let mut headings = vec![phi];
        while (out.len() as f32) < max_vertices {
            // Arc sampling: the best-agreeing arc, straight ones preferred on ties.
            let mut best_k = 0.0f32;
            let mut best_s = f32::NEG_INFINITY;
            for a in 0..=2 * ARC_HALF {
                // 0, +1, -1, +2, -2, ... so that ties keep the least curved arc.
                let m = (a + 1) / 2 * if a % 2 == 1 { 1 } else { -1 };
                let kappa = k_max * m as f32 / ARC_HALF as f32;
                let s = arc_score(f, pos, phi, kappa, arc_len);
                if s > best_s + 1e-6 {
                    best_s = s;
                    best_k = kappa;
                }
            }
            let next = arc_point(pos, phi, best_k, step);
            let turn = best_k * step;
            let Some(i) = f.hair_at(next) else { break };
            if owner[i] == 2 {
                break;
            }
            let ord = sign * (out.len() as i32 + 1);
            if self.stamp[i] == self.trace_id && (ord - self.stamp_ord[i]).abs() > window {
                break;
            }
            // The heading must also agree with the map where the step lands: arcs are chosen
            // relative to each other, so near the mask edge or a singular point the best of
            // them can still run across the strands (and, turn after turn, into a hook).
            let heading = phi + turn;
            let off = {
                let d = (f.theta[i] - heading).rem_euclid(std::f32::consts::PI);
                d.min(std::f32::consts::PI - d)
            };
            let good = best_s > 0.0
                && f.local[i] >= p.low_conf
                && turn.abs() <= max_bend
                && off <= max_bend;
            if good {
                health = (health + 1).min(p.health as i32);
            } else {
                health -= 1;
            }
            if health <= 0 {
                break;
            }
            out.push(next);
            if good {
                last_good = out.len();
            }
            self.mark_self(next, ord);
            pos = next;
            phi = heading;
            // No hooks: strands do not turn back on themselves within a few steps, and a
            // U-turn would make one curve carry two opposite growth directions.
            headings.push(phi);
            if headings.len() > HOOK_STEPS
                && (phi - headings[headings.len() - 1 - HOOK_STEPS]).abs() > HOOK_TURN
            {
                break;
            }
        }
        // The tail since the last good step was only tolerated on credit; it is not trusted.
        out.truncate(last_good);
        out
    }
}

/// Point at arc length `s` along the circular arc leaving `p` at angle `phi` with curvature
/// `kappa` (turning towards +y for positive kappa).
fn arc_point(p: [f32; 2], phi: f32, kappa: f32, s: f32) -> [f32; 2] {
    if kappa.abs() < 1e-6 {
        return [p[0] + s * phi.cos(), p[1] + s * phi.sin()];
    }
    let a = phi + kappa * s;
    [
        p[0] + (a.sin() - phi.sin()) / kappa,
        p[1] + (phi.cos() - a.cos()) / kappa,
    ]
}

/// Confidence-weighted agreement of the orientation map with an arc's tangent:
/// sum of c * cos(2 (theta - tangent)) over samples, so misaligned confident pixels count
/// against the arc, and off-hair samples count as strongly against it.
fn arc_score(f: &Field, p: [f32; 2], phi: f32, kappa: f32, len: f32) -> f32 {
    let mut score = 0.0;
    for k in 1..=ARC_SAMPLES {
        let s = len * k as f32 / ARC_SAMPLES as f32;
        let q = arc_point(p, phi, kappa, s);
        match f.hair_at(q) {
            Some(i) => {
                let d = 2.0 * (f.theta[i] - (phi + kappa * s));
                score += f.cn[i] * d.cos();
            }
            // Leaving the hair is the worst possible agreement.
            None => score -= 1.0,
        }
    }
    score
}

/// Raises `grid` to at least `level` on the pixels whose centres lie within `r` of `c`.
fn mark_disk(grid: &mut [u8], w: usize, h: usize, c: [f32; 2], r: f32, level: u8) {
    let r2 = r * r;
    let (x0, x1) = ((c[0] - r).floor().max(0.0), (c[0] + r).ceil());
    let (y0, y1) = ((c[1] - r).floor().max(0.0), (c[1] + r).ceil());
    let (x0, y0) = (x0 as usize, y0 as usize);
    let (x1, y1) = ((x1 as usize).min(w - 1), (y1 as usize).min(h - 1));
    for y in y0..=y1 {
        let dy = y as f32 + 0.5 - c[1];
        for x in x0..=x1 {
            let dx = x as f32 + 0.5 - c[0];
            if dx * dx + dy * dy <= r2 {
                let g = &mut grid[y * w + x];
                *g = (*g).max(level);
            }
        }
    }
}

/// Cuts a polyline at its apexes: local minima of y preceded by a rise and followed by a
/// descent of at least `drop` (hysteresis, so wiggles smaller than `drop` are no apexes).
/// The apex vertex ends the first piece; the next one starts one vertex later, so that the
/// pieces share no vertex.
fn split_at_apexes(pts: &[[f32; 2]], drop: f32) -> Vec<Vec<[f32; 2]>> {
    #[derive(PartialEq)]
    enum Seek {
        Start,
        /// Rising (y falling) by at least `drop` since the last low point: the next turn
        /// with a descent of `drop` is an apex.
        Apex,
        /// Descending: waiting for a rise of `drop` before looking for an apex again.
        Bottom,
    }
    let mut cuts = Vec::new();
    let mut state = Seek::Start;
    let y0 = pts.first().map_or(0.0, |p| p[1]);
    let (mut mx, mut mn, mut mn_i) = (y0, y0, 0usize);
    for (j, q) in pts.iter().enumerate() {
        let v = q[1];
        if v > mx {
            mx = v;
        }
        if v < mn {
            mn = v;
            mn_i = j;
        }
        match state {
            Seek::Start | Seek::Bottom if mx - v >= drop => {
                state = Seek::Apex;
                // The apex search starts here: the lowest point of the rise so far.
                (mn, mn_i) = (v, j);
            }
            Seek::Start if v - mn >= drop => {
                state = Seek::Bottom;
                mx = v;
            }
            Seek::Apex if v - mn >= drop => {
                cuts.push(mn_i);
                state = Seek::Bottom;
                mx = v;
            }
            _ => {}
        }
    }
    let mut out = Vec::with_capacity(cuts.len() + 1);
    let mut start = 0;
    for c in cuts {
        out.push(pts[start..=c].to_vec());
        start = c + 1;
    }
    out.push(pts[start..].to_vec());
    out
}

pub(crate) fn polyline_len(pts: &[[f32; 2]]) -> f32 {
    pts.windows(2)
        .map(|s| (s[1][0] - s[0][0]).hypot(s[1][1] - s[0][1]))
        .sum()
}

/// Resamples a polyline to vertices `spacing` apart along its length, keeping both ends (the
/// last interval is stretched to the end rather than leaving a short stub).
pub fn resample(pts: &[[f32; 2]], spacing: f32) -> Vec<[f32; 2]> {
    let total = polyline_len(pts);
    if pts.len() < 2 || total <= 0.0 {
        return pts.first().map(|p| vec![*p]).unwrap_or_default();
    }
    let segs = (total / spacing).round().max(1.0) as usize;
    let ds = total / segs as f32;
    let mut out = Vec::with_capacity(segs + 1);
    out.push(pts[0]);
    let mut seg = 0usize;
    let mut seg_start = 0.0f32;
    for k in 1..segs {
        let target = k as f32 * ds;
        loop {
            let (a, b) = (pts[seg], pts[seg + 1]);
            let l = (b[0] - a[0]).hypot(b[1] - a[1]);
            if seg_start + l >= target || seg + 2 >= pts.len() {
                let t = if l > 0.0 {
                    ((target - seg_start) / l).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
                break;
            }
            seg_start += l;
            seg += 1;
        }
    }
    out.push(pts[pts.len() - 1]);
    out
}

/// Splits curves into pieces of at most `max_vertices` vertices of near-equal length.
///
/// A traced curve can run straight through a parting, where the orientation is continuous
/// but the growth direction flips; resolving pieces instead of whole curves lets each side
/// follow its own strokes ("neighbouring curve segments", C13 §2.1). 0 keeps curves whole.
pub fn split_curves(curves: &[Curve], max_vertices: usize) -> Vec<Curve> {
    if max_vertices < 2 {
        return curves.to_vec();
    }
    curves
        .iter()
        .flat_map(|c| {
            let n = c.points.len();
            let pieces = n.div_ceil(max_vertices).max(1);
            let len = n.div_ceil(pieces).max(2);
            // Neighbouring pieces share their end vertex so no segment is lost.
            (0..pieces)
                .map(move |k| (k * len, ((k + 1) * len + 1).min(n)))
                .filter(|(a, b)| b > a && b - a >= 2)
                .map(|(a, b)| Curve {
                    points: c.points[a..b].to_vec(),
                })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A w x h hair field with orientation `f(x, y)` and stripy confidence (strands every
    /// 3 px across `stripe`), like the refined maps of strand images.
    fn field(w: usize, h: usize, f: impl Fn(f32, f32) -> f32) -> (Vec<f32>, Vec<f32>, Vec<u8>) {
        let mut theta = vec![0.0; w * h];
        let mut conf = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let t = f(x as f32 + 0.5, y as f32 + 0.5).rem_euclid(std::f32::consts::PI);
                theta[y * w + x] = t;
                conf[y * w + x] = if x % 3 == 1 { 1.0 } else { 0.2 };
            }
        }
        (theta, conf, vec![1; w * h])
    }

    #[test]
    fn vertical_field_gives_straight_separated_vertical_curves() {
        let (w, h) = (64usize, 96usize);
        let (theta, conf, mask) = field(w, h, |_, _| std::f32::consts::FRAC_PI_2);
        let p = TraceParams::default();
        let curves = trace_curves(&theta, &conf, &mask, w as u32, h as u32, &p);
        assert!(curves.len() >= 8, "{} curves", curves.len());
        for c in &curves {
            let x0 = c.points[0][0];
            for q in &c.points {
                assert!((q[0] - x0).abs() < 0.5, "curve bends: {q:?} from x {x0}");
            }
            assert!(c.length() > 0.8 * h as f32, "length {}", c.length());
        }
        let mut xs: Vec<f32> = curves.iter().map(|c| c.points[0][0]).collect();
        xs.sort_by(f32::total_cmp);
        for pair in xs.windows(2) {
            assert!(pair[1] - pair[0] >= 0.5 * p.min_separation, "{xs:?}");
        }
    }

    #[test]
    fn circular_field_curves_follow_circles() {
        let (w, h) = (128usize, 128usize);
        let (cx, cy) = (64.0f32, 64.0f32);
        let (theta, mut conf, mut mask) = field(w, h, |x, y| {
            (y - cy).atan2(x - cx) + std::f32::consts::FRAC_PI_2
        });
        // A ring, so the centre singularity is not on hair; strands are rings too.
        for y in 0..h {
            for x in 0..w {
                let r = (x as f32 + 0.5 - cx).hypot(y as f32 + 0.5 - cy);
                mask[y * w + x] = u8::from((25.0..60.0).contains(&r));
                conf[y * w + x] = if r as i32 % 3 == 1 { 1.0 } else { 0.2 };
            }
        }
        let p = TraceParams {
            apex_drop: 0.0,
            ..Default::default()
        };
        let curves = trace_curves(&theta, &conf, &mask, w as u32, h as u32, &p);
        assert!(!curves.is_empty());
        for c in &curves {
            let r: Vec<f32> = c
                .points
                .iter()
                .map(|q| (q[0] - cx).hypot(q[1] - cy))
                .collect();
            let (lo, hi) = r
                .iter()
                .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
            assert!(hi - lo < 3.0, "radius drifts {lo}..{hi}");
        }
    }

    #[test]
    fn tracing_stops_at_the_mask_and_drops_short_curves() {
        let (w, h) = (40usize, 40usize);
        let (theta, conf, mut mask) = field(w, h, |_, _| std::f32::consts::FRAC_PI_2);
        for y in 0..h {
            for x in 0..w {
                mask[y * w + x] = u8::from((10..30).contains(&y) && x < 30);
            }
        }
        let p = TraceParams {
            min_len: 10.0,
            ..Default::default()
        };
        let curves = trace_curves(&theta, &conf, &mask, w as u32, h as u32, &p);
        assert!(!curves.is_empty());
        for c in &curves {
            for q in &c.points {
                assert!(
                    q[1] >= 10.0 && q[1] < 30.0 && q[0] < 30.0,
                    "{q:?} off the mask"
                );
            }
        }
        let tiny = TraceParams {
            min_len: 25.0,
            ..Default::default()
        };
        assert!(trace_curves(&theta, &conf, &mask, w as u32, h as u32, &tiny).is_empty());
    }

    #[test]
    fn resample_gives_equal_spacing_and_keeps_ends() {
        let pts = vec![[0.0, 0.0], [3.0, 0.0], [3.0, 7.0]];
        let r = resample(&pts, 2.0);
        assert_eq!(r[0], [0.0, 0.0]);
        assert_eq!(*r.last().unwrap(), [3.0, 7.0]);
        let segs: Vec<f32> = r
            .windows(2)
            .map(|s| (s[1][0] - s[0][0]).hypot(s[1][1] - s[0][1]))
            .collect();
        // Equal along the path; the chord across the corner is shorter.
        assert_eq!(r.len(), 6);
        assert!(segs.iter().filter(|&&s| (s - 2.0).abs() < 1e-4).count() >= 4);
    }

    #[test]
    fn arches_are_cut_at_their_apex_and_nowhere_else() {
        // An arch: up from (0, 20) to (20, 0), down to (40, 20).
        let arch: Vec<[f32; 2]> = (0..=40)
            .map(|i| {
                let x = i as f32;
                [x, (x - 20.0).abs()]
            })
            .collect();
        let pieces = split_at_apexes(&arch, 6.0);
        assert_eq!(pieces.len(), 2);
        assert_eq!(*pieces[0].last().unwrap(), [20.0, 0.0]);
        assert_eq!(pieces[1][0], [21.0, 1.0]);
        // A U (valley) and a shallow wiggle are not cut.
        let valley: Vec<[f32; 2]> = arch.iter().map(|q| [q[0], 20.0 - q[1]]).collect();
        assert_eq!(split_at_apexes(&valley, 6.0).len(), 1);
        let wiggle: Vec<[f32; 2]> = (0..=40)
            .map(|i| [i as f32, (i as f32 * 0.3).sin() * 2.0])
            .collect();
        assert_eq!(split_at_apexes(&wiggle, 6.0).len(), 1);
        // A wave with two crests is cut twice.
        let wave: Vec<[f32; 2]> = (0..=130)
            .map(|i| [i as f32, 10.0 * (i as f32 * 0.1).cos()])
            .collect();
        assert_eq!(split_at_apexes(&wave, 6.0).len(), 3);
    }
}
