//! 2D hair tracing on the refined orientation map (C13 §2.1 after Chai et al. 2012), with
//! arc sampling (Tan et al. 2008, Beeler et al. 2012) choosing the next direction.
//!
//! Sequential and branchy (each curve depends on the occupancy left by the previous ones),
//! so it stays on the CPU.

use rayon::prelude::*;

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct TraceParams {
    /// Step length (px).
    pub step: f32,
    /// Seeds need a confidence of at least this share of the 99th percentile.
    pub seed_conf: f32,
    /// Health points: lost on a low-confidence or over-bent step, regained on a good one.
    pub health: u32,
    /// A step onto confidence below this share of the 99th percentile costs a point.
    pub low_conf: f32,
    /// A step that turns more than this costs a point (degrees).
    pub max_bend_deg: f32,
    /// Shorter curves are dropped (px).
    pub min_len: f32,
    /// Vertex spacing after resampling (px).
    pub spacing: f32,
    /// Curves keep at least this far apart (px).
    pub min_separation: f32,
    /// Length of the arcs sampled ahead of each step (px).
    pub arc_len: f32,
    /// Largest curvature tried by arc sampling (1/px).
    pub max_curvature: f32,
    pub max_curves: usize,
    /// Longest curve (px); keeps a runaway loop bounded.
    pub max_len: f32,
}

impl Default for TraceParams {
    fn default() -> Self {
        TraceParams {
            step: 2.0,
            seed_conf: 0.2,
            health: 5,
            low_conf: 0.05,
            max_bend_deg: 30.0,
            min_len: 20.0,
            spacing: 2.0,
            min_separation: 4.0,
            arc_len: 6.0,
            max_curvature: 0.12,
            max_curves: 20_000,
            max_len: 2000.0,
        }
    }
}

/// A polyline with equally spaced vertices (pixel coordinates, x right, y down).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Curve {
    pub points: Vec<[f32; 2]>,
}

impl Curve {
    pub fn length(&self) -> f32 {
        self.points
            .windows(2)
            .map(|s| (s[1][0] - s[0][0]).hypot(s[1][1] - s[0][1]))
            .sum()
    }
}

struct Maps<'a> {
    theta: &'a [f32],
    conf: &'a [f32],
    mask: &'a [u8],
    w: usize,
    h: usize,
}

impl Maps<'_> {
    fn index(&self, p: [f32; 2]) -> Option<usize> {
        let (x, y) = (p[0].floor(), p[1].floor());
        if x < 0.0 || y < 0.0 || x >= self.w as f32 || y >= self.h as f32 {
            return None;
        }
        let i = y as usize * self.w + x as usize;
        (self.mask[i] != 0 && self.theta[i].is_finite()).then_some(i)
    }
}

/// Resamples a polyline to vertices `spacing` apart along its length.
pub fn resample(pts: &[[f32; 2]], spacing: f32) -> Vec<[f32; 2]> {
    if pts.len() < 2 {
        return pts.to_vec();
    }
    let mut out = vec![pts[0]];
    let mut carry = 0.0f32;
    for s in pts.windows(2) {
        let (a, b) = (s[0], s[1]);
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let mut t = spacing - carry;
        while t <= len {
            let f = t / len;
            out.push([a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])]);
            t += spacing;
        }
        carry = len - (t - spacing);
    }
    out
}

/// Best direction at `p` heading roughly along `d`: the start tangent of the sampled arc
/// whose points agree most with the orientation map (agreement cos² weighted by confidence).
fn arc_sample(m: &Maps, p: [f32; 2], d: [f32; 2], prm: &TraceParams) -> [f32; 2] {
    const N_ARCS: i32 = 9;
    let heading = d[1].atan2(d[0]);
    let (mut best, mut best_score) = (d, f32::MIN);
    let n_samples = prm.arc_len.ceil().max(2.0) as i32;
    for k in -N_ARCS / 2..=N_ARCS / 2 {
        let kappa = prm.max_curvature * k as f32 / (N_ARCS / 2) as f32;
        // Mean agreement over the samples on hair: samples past the mask edge neither count
        // for nor against an arc, so curves do not curl along the hair boundary.
        let (mut score, mut on) = (0.0, 0);
        for s in 1..=n_samples {
            let s = s as f32 * prm.arc_len / n_samples as f32;
            // Point and tangent after arc length s along a circle of curvature kappa.
            let ang = heading + kappa * s;
            let q = if kappa.abs() < 1e-6 {
                [p[0] + s * d[0], p[1] + s * d[1]]
            } else {
                let r = 1.0 / kappa;
                [
                    p[0] + r * (ang.sin() - heading.sin()),
                    p[1] - r * (ang.cos() - heading.cos()),
                ]
            };
            if let Some(i) = m.index(q) {
                let c = (ang - m.theta[i]).cos();
                score += m.conf[i] * c * c;
                on += 1;
            }
        }
        if on == 0 {
            continue;
        }
        let score = score / on as f32;
        if score > best_score {
            best_score = score;
            // Take the mid-step tangent: the arc's direction over the coming step.
            let a = heading + kappa * 0.5 * prm.step;
            best = [a.cos(), a.sin()];
        }
    }
    best
}

/// One direction of a curve from `start`, not including `start`.
fn trace_one_way(
    m: &Maps,
    occ: &[u32],
    start: [f32; 2],
    dir: [f32; 2],
    scale: f32,
    prm: &TraceParams,
) -> Vec<[f32; 2]> {
    let mut out = Vec::new();
    let (mut p, mut d) = (start, dir);
    let mut health = prm.health;
    let cos_bend = prm.max_bend_deg.to_radians().cos();
    let max_steps = (prm.max_len / prm.step) as usize;
    for _ in 0..max_steps {
        let nd = arc_sample(m, p, d, prm);
        let q = [p[0] + prm.step * nd[0], p[1] + prm.step * nd[1]];
        let Some(i) = m.index(q) else { break };
        if occ[i] != 0 {
            break;
        }
        // The orientation at q, signed to continue the heading.
        let t = [m.theta[i].cos(), m.theta[i].sin()];
        let align = t[0] * nd[0] + t[1] * nd[1];
        let bent = nd[0] * d[0] + nd[1] * d[1] < cos_bend || align.abs() < cos_bend;
        let weak = m.conf[i] < prm.low_conf * scale;
        if bent || weak {
            health = health.saturating_sub(1);
            if health == 0 {
                break;
            }
        } else {
            health = (health + 1).min(prm.health);
        }
        out.push(q);
        p = q;
        d = nd;
    }
    out
}

fn mark(occ: &mut [u32], w: usize, h: usize, pts: &[[f32; 2]], r: f32, id: u32) {
    let ri = r.ceil() as i64;
    for p in pts {
        let (cx, cy) = (p[0].floor() as i64, p[1].floor() as i64);
        for y in cy - ri..=cy + ri {
            for x in cx - ri..=cx + ri {
                if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
                    continue;
                }
                let (dx, dy) = (x as f32 + 0.5 - p[0], y as f32 + 0.5 - p[1]);
                if dx * dx + dy * dy <= r * r {
                    occ[y as usize * w + x as usize] = id;
                }
            }
        }
    }
}

/// Traces undirected curves: seeds at high-confidence hair pixels in descending confidence,
/// each traced both ways until its health runs out, it leaves the hair, or it runs into the
/// band another curve occupies. Deterministic for the same maps.
pub fn trace_curves(
    theta: &[f32],
    conf: &[f32],
    mask: &[u8],
    width: u32,
    height: u32,
    prm: &TraceParams,
) -> Vec<Curve> {
    let (w, h) = (width as usize, height as usize);
    let m = Maps {
        theta,
        conf,
        mask,
        w,
        h,
    };
    let on_hair: Vec<f32> = (0..w * h)
        .filter(|&i| mask[i] != 0 && theta[i].is_finite())
        .map(|i| conf[i])
        .collect();
    let scale = crate::vis::percentile(&on_hair, 0.99).max(1e-12);
    // Seeds on a 2 px lattice keep sorting cheap; strong pixels first, index breaks ties.
    let mut seeds: Vec<(f32, usize)> = (0..h)
        .step_by(2)
        .flat_map(|y| (0..w).step_by(2).map(move |x| y * w + x))
        .filter(|&i| mask[i] != 0 && theta[i].is_finite() && conf[i] >= prm.seed_conf * scale)
        .map(|i| (conf[i], i))
        .collect();
    seeds.par_sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut occ = vec![0u32; w * h];
    let mut curves = Vec::new();
    for (_, i) in seeds {
        if curves.len() >= prm.max_curves {
            break;
        }
        if occ[i] != 0 {
            continue;
        }
        let p = [(i % w) as f32 + 0.5, (i / w) as f32 + 0.5];
        let t = [theta[i].cos(), theta[i].sin()];
        let fwd = trace_one_way(&m, &occ, p, t, scale, prm);
        let back = trace_one_way(&m, &occ, p, [-t[0], -t[1]], scale, prm);
        let mut pts: Vec<[f32; 2]> = back.into_iter().rev().collect();
        pts.push(p);
        pts.extend(fwd);
        let pts = resample(&pts, prm.spacing);
        let id = curves.len() as u32 + 1;
        let len = (pts.len().saturating_sub(1)) as f32 * prm.spacing;
        if len < prm.min_len {
            // Occupy the seed alone so the same short run is not traced again.
            mark(&mut occ, w, h, &[p], 1.0, u32::MAX);
            continue;
        }
        mark(&mut occ, w, h, &pts, prm.min_separation, id);
        curves.push(Curve { points: pts });
    }
    curves
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
    #[test]
    fn split_keeps_every_segment() {
        let c = Curve {
            points: (0..25).map(|k| [k as f32, 0.0]).collect(),
        };
        let parts = split_curves(std::slice::from_ref(&c), 10);
        assert_eq!(parts.len(), 3);
        let segs: usize = parts.iter().map(|p| p.points.len() - 1).sum();
        assert_eq!(segs, 24);
        assert!(parts.iter().all(|p| p.points.len() <= 10));
    }

    use super::*;

    #[test]
    fn resample_gives_equal_spacing() {
        let r = resample(&[[0.0, 0.0], [10.0, 0.0], [10.0, 5.0]], 2.0);
        for s in r.windows(2) {
            let d = (s[1][0] - s[0][0]).hypot(s[1][1] - s[0][1]);
            assert!((d - 2.0).abs() < 0.6, "{d}");
        }
        assert_eq!(r.len(), 8);
    }

    #[test]
    fn traces_straight_stripes_as_long_parallel_curves() {
        let (w, h) = (80u32, 60u32);
        let n = (w * h) as usize;
        let theta = vec![0.3f32; n];
        let conf = vec![1.0f32; n];
        let mask = vec![1u8; n];
        let cs = trace_curves(&theta, &conf, &mask, w, h, &TraceParams::default());
        assert!(cs.len() >= 5, "{}", cs.len());
        for c in &cs {
            for s in c.points.windows(3) {
                let a = (s[1][1] - s[0][1]).atan2(s[1][0] - s[0][0]);
                let b = (s[2][1] - s[1][1]).atan2(s[2][0] - s[1][0]);
                assert!((a - b).abs() < 0.1, "a straight field gave a bent curve");
                assert!((a.rem_euclid(std::f32::consts::PI) - 0.3).abs() < 0.1);
            }
        }
    }
}
