//! Whorls in the orientation field: where the hair turns once around a point (a crown),
//! no smoothing window resolves it. Within a few pixels of the centre the Gabor bank sees
//! strands of every direction at once and the local linear fit is a plane through a field
//! that winds; on the synthetic whorl 2% of the scored pixels, within 10 px of the centre,
//! carried 43% of the error, and the raw Gabor field is as wrong there as the fit.
//!
//! So the stage models the point itself, as fingerprint analysis models its cores (Sherlock
//! & Monro's zero-pole model): near a point of Poincaré index +1 the orientation is a spiral,
//! θ = φ + α (φ the polar angle about the centre; α 0 radial, ±90° circular). The points are
//! found where a circle of orientations turns once (its double angle twice), each centre and
//! α are fitted by weighted least squares to the ring around it (r to 3r, where the fit is
//! reliable), and the model replaces the field within r, blended into it out to 2r. A ring the
//! spiral explains worse than [`MAX_RESIDUAL_DEG`] on average is left alone: it is not a
//! whorl, or not one the model knows.
//!
//! This runs on the CPU on either backend: a sparse scan and one small fit per point, light
//! and branchy (clustering, iterations that may stop early), a few ms at 512².

use crate::analyze::orient::OrientMap;
use crate::eval::metrics::orient_diff;
use crate::stages::orient_resolve::resolve_theta;
use rayon::prelude::*;
use std::f32::consts::PI;

/// The largest mean angle (degrees) between a ring's orientations and the fitted spiral for
/// the model to be used. The synthetic whorls fit within 1-2° (plain strands) and 3-7°
/// (curled); rings around spurious +1 points of photos without a hair mask measured 7.5° and
/// more, mostly 12-40°.
pub const MAX_RESIDUAL_DEG: f32 = 8.0;

/// Grid step (px) of the scan for singular points.
const SCAN_STEP: usize = 3;
/// Samples on a scan circle.
const SCAN_SAMPLES: usize = 32;
/// Least share of the fitting ring's pixels with an orientation.
const MIN_RING_COVER: f32 = 0.8;
/// Rounds of the alternating fit of α and the centre.
const FIT_ROUNDS: usize = 8;

/// A whorl the model is used at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Whorl {
    /// Centre in pixels (pixel centres at +0.5).
    pub centre: [f32; 2],
    /// α in radians, in (−π/2, π/2]: θ = φ + α.
    pub twist: f32,
    /// Mean angle between the ring's orientations and the model, weighted by confidence
    /// (degrees).
    pub residual_deg: f32,
}

/// Angle wrapped to (−π, π].
fn wrap(a: f32) -> f32 {
    let a = a.rem_euclid(2.0 * PI);
    if a > PI {
        a - 2.0 * PI
    } else {
        a
    }
}

fn theta_at(m: &OrientMap, x: i64, y: i64) -> f32 {
    if x < 0 || y < 0 || x >= m.width as i64 || y >= m.height as i64 {
        return f32::NAN;
    }
    m.theta[(y * m.width as i64 + x) as usize]
}

/// Grid points whose circle of radius `r` (every sample with an orientation) turns the
/// double angle by +4π: orientation index +1.
fn scan(m: &OrientMap, r: f32) -> Vec<[f32; 2]> {
    let ring: Vec<(i64, i64)> = (0..SCAN_SAMPLES)
        .map(|k| {
            let a = 2.0 * PI * k as f32 / SCAN_SAMPLES as f32;
            ((r * a.cos()).round() as i64, (r * a.sin()).round() as i64)
        })
        .collect();
    (0..m.height as usize)
        .into_par_iter()
        .step_by(SCAN_STEP)
        .flat_map_iter(|gy| {
            let ring = &ring;
            (0..m.width as usize)
                .step_by(SCAN_STEP)
                .filter_map(move |gx| {
                    let (cx, cy) = (gx as i64, gy as i64);
                    let mut turn = 0.0;
                    let mut prev = theta_at(m, cx + ring[0].0, cy + ring[0].1);
                    if !prev.is_finite() {
                        return None;
                    }
                    for k in 1..=SCAN_SAMPLES {
                        let (dx, dy) = ring[k % SCAN_SAMPLES];
                        let t = theta_at(m, cx + dx, cy + dy);
                        if !t.is_finite() {
                            return None;
                        }
                        turn += wrap(2.0 * (t - prev));
                        prev = t;
                    }
                    ((turn / (2.0 * PI)).round() as i32 == 2).then_some([gx as f32, gy as f32])
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Pixels of the ring r_in..=r_out about `c` with an orientation: (x, y, θ, weight), and the
/// count of the ring's pixels inside the image.
fn ring_pixels(m: &OrientMap, c: [f32; 2], r_in: f32, r_out: f32) -> (Vec<[f32; 4]>, usize) {
    let mut out = Vec::new();
    let mut total = 0;
    for y in (c[1] - r_out).floor() as i64..=(c[1] + r_out).ceil() as i64 {
        for x in (c[0] - r_out).floor() as i64..=(c[0] + r_out).ceil() as i64 {
            let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
            let d = (px - c[0]).hypot(py - c[1]);
            if d < r_in || d > r_out {
                continue;
            }
            total += 1;
            let t = theta_at(m, x, y);
            if t.is_finite() {
                let wgt = m.confidence[(y * m.width as i64 + x) as usize].max(0.0);
                out.push([px, py, t, wgt]);
            }
        }
    }
    (out, total)
}

/// Fits the spiral to the ring about a first guess `c0`: α as the weighted circular mean of
/// 2(θ − φ), then the centre as the least-squares meeting point of the lines each ring
/// pixel's orientation, turned back by α, draws through it (a point of the spiral looks
/// straight at the centre from there); alternated.
fn fit(m: &OrientMap, c0: [f32; 2], r: f32) -> Option<Whorl> {
    let mut c = c0;
    let mut whorl = None;
    for _ in 0..FIT_ROUNDS {
        let (px, total) = ring_pixels(m, c, r, 3.0 * r);
        if total == 0 || (px.len() as f32) < MIN_RING_COVER * total as f32 {
            return None;
        }
        // Each ring pixel's polar angle about this round's centre.
        let phi: Vec<f32> = px
            .iter()
            .map(|&[x, y, ..]| (y - c[1]).atan2(x - c[0]))
            .collect();
        let (mut sx, mut sy, mut sw) = (0.0f64, 0.0f64, 0.0f64);
        for (&[_, _, t, w], &phi) in px.iter().zip(&phi) {
            let a2 = 2.0 * (t - phi);
            sx += (w * a2.cos()) as f64;
            sy += (w * a2.sin()) as f64;
            sw += w as f64;
        }
        if sw <= 0.0 {
            return None;
        }
        let twist = 0.5 * sy.atan2(sx) as f32;
        // Normal n of each radial line: n·c = n·p.
        let (mut a11, mut a12, mut a22, mut b1, mut b2, mut res) =
            (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
        for (&[x, y, t, w], &phi) in px.iter().zip(&phi) {
            let (s, co) = (t - twist).sin_cos();
            let (nx, ny, w) = (s as f64, -co as f64, w as f64);
            let np = nx * x as f64 + ny * y as f64;
            a11 += w * nx * nx;
            a12 += w * nx * ny;
            a22 += w * ny * ny;
            b1 += w * nx * np;
            b2 += w * ny * np;
            res += w * orient_diff(t, phi + twist) as f64;
        }
        whorl = Some(Whorl {
            centre: c,
            twist,
            residual_deg: (res / sw).to_degrees() as f32,
        });
        let det = a11 * a22 - a12 * a12;
        if det.abs() <= 1e-9 * (a11 + a22).powi(2) {
            return None;
        }
        c = [
            ((a22 * b1 - a12 * b2) / det) as f32,
            ((a11 * b2 - a12 * b1) / det) as f32,
        ];
        if !(c[0].is_finite() && c[1].is_finite()) || (c[0] - c0[0]).hypot(c[1] - c0[1]) > r {
            return None;
        }
    }
    whorl
}

/// The whorls of `m` the model is used at, for a model radius `r` (px): scanned on circles
/// of 1.25r, clustered within 1.5r, fitted to the ring r..3r.
pub fn find(m: &OrientMap, r: f32) -> Vec<Whorl> {
    let mut clusters: Vec<(f32, [f32; 2])> = Vec::new();
    for p in scan(m, 1.25 * r) {
        match clusters
            .iter_mut()
            .find(|(_, c)| (c[0] - p[0]).hypot(c[1] - p[1]) < 1.5 * r)
        {
            Some((n, c)) => {
                *n += 1.0;
                c[0] += (p[0] - c[0]) / *n;
                c[1] += (p[1] - c[1]) / *n;
            }
            None => clusters.push((1.0, p)),
        }
    }
    let mut out: Vec<Whorl> = Vec::new();
    for (_, c) in clusters {
        if let Some(w) = fit(m, c, r) {
            let apart = out
                .iter()
                .all(|o| (o.centre[0] - w.centre[0]).hypot(o.centre[1] - w.centre[1]) > r);
            if w.residual_deg <= MAX_RESIDUAL_DEG && apart {
                out.push(w);
            }
        }
    }
    out
}

/// Puts the spiral of each whorl into `m`: the model alone within `r` of the centre, blended
/// (in the double angle, by a smoothstep of the distance) into the field out to 2r; pixels
/// without an orientation keep none.
pub fn apply(m: &mut OrientMap, whorls: &[Whorl], r: f32) {
    let (w, h) = (m.width as i64, m.height as i64);
    for wh in whorls {
        let [cx, cy] = wh.centre;
        let y0 = ((cy - 2.0 * r).floor() as i64).max(0);
        let y1 = ((cy + 2.0 * r).ceil() as i64).min(h - 1);
        let x0 = ((cx - 2.0 * r).floor() as i64).max(0);
        let x1 = ((cx + 2.0 * r).ceil() as i64).min(w - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let i = (y * w + x) as usize;
                let t = m.theta[i];
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                let d = (px - cx).hypot(py - cy);
                if !t.is_finite() || d >= 2.0 * r {
                    continue;
                }
                let u = ((2.0 * r - d) / r).min(1.0);
                let s = u * u * (3.0 - 2.0 * u);
                let model = (py - cy).atan2(px - cx) + wh.twist;
                let vx = s * (2.0 * model).cos() + (1.0 - s) * (2.0 * t).cos();
                let vy = s * (2.0 * model).sin() + (1.0 - s) * (2.0 * t).sin();
                m.theta[i] = resolve_theta(vx, vy);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A field on a `n` x `n` grid from θ(x, y) at pixel centres, confidence 1.
    fn field(n: u32, f: impl Fn(f32, f32) -> f32) -> OrientMap {
        let mut theta = Vec::new();
        for y in 0..n {
            for x in 0..n {
                theta.push(f(x as f32 + 0.5, y as f32 + 0.5).rem_euclid(PI));
            }
        }
        OrientMap {
            width: n,
            height: n,
            theta,
            confidence: vec![1.0; (n * n) as usize],
            whorls: Vec::new(),
        }
    }

    fn spiral(c: [f32; 2], twist: f32) -> impl Fn(f32, f32) -> f32 {
        move |x, y| (y - c[1]).atan2(x - c[0]) + twist
    }

    #[test]
    fn a_spiral_with_a_wrong_centre_is_found_and_mended() {
        let (c, twist) = ([61.3, 58.7], 0.9);
        let truth = field(128, spiral(c, twist));
        // Within 6 px of the centre, the field a smoothing leaves: turned by up to 40°.
        let mut m = field(128, |x, y| {
            let d = (x - c[0]).hypot(y - c[1]);
            spiral(c, twist)(x, y) + 0.7 * (1.0 - d / 6.0).max(0.0)
        });
        let found = find(&m, 8.0);
        assert_eq!(found.len(), 1, "{found:?}");
        let w = found[0];
        assert!(
            (w.centre[0] - c[0]).hypot(w.centre[1] - c[1]) < 0.05,
            "{w:?}"
        );
        assert!((w.twist - twist).abs() < 1e-3, "{w:?}");
        assert!(w.residual_deg < 0.1, "{w:?}");
        apply(&mut m, &found, 8.0);
        let worst = m
            .theta
            .iter()
            .zip(&truth.theta)
            .map(|(a, b)| (0.5 * wrap(2.0 * (a - b))).abs())
            .fold(0.0f32, f32::max);
        assert!(worst.to_degrees() < 0.5, "worst {}°", worst.to_degrees());
    }

    #[test]
    fn fields_without_a_whorl_have_none() {
        // A gentle bend, a field radiating from a point outside the image (a crown above
        // the head), a loop (index +1/2) and a delta (−1/2).
        type Theta = Box<dyn Fn(f32, f32) -> f32>;
        let cases: [(&str, Theta); 4] = [
            ("bend", Box::new(|x, y| 0.3 + 0.004 * x + 0.002 * y)),
            ("crown outside", Box::new(spiral([64.0, -40.0], 0.2))),
            ("loop", Box::new(|x, y| 0.5 * (y - 64.0).atan2(x - 64.0))),
            ("delta", Box::new(|x, y| -0.5 * (y - 64.0).atan2(x - 64.0))),
        ];
        for (name, f) in cases {
            let m = field(128, f);
            assert!(find(&m, 8.0).is_empty(), "{name}: {:?}", find(&m, 8.0));
        }
    }

    #[test]
    fn a_ring_the_spiral_does_not_explain_is_left_alone() {
        // Index +1, but the ring's orientations wander ±30° about the spiral.
        let c = [64.0, 64.0];
        let m = field(128, |x, y| {
            let phi = (y - c[1]).atan2(x - c[0]);
            phi + 0.5 + 0.55 * (3.0 * phi).sin()
        });
        let found = find(&m, 8.0);
        assert!(found.is_empty(), "{found:?}");
    }

    #[test]
    fn pixels_without_orientation_stay_without() {
        let c = [64.0, 64.0];
        let mut m = field(128, spiral(c, 0.4));
        m.theta[64 * 128 + 66] = f32::NAN;
        let found = find(&m, 8.0);
        assert_eq!(found.len(), 1);
        apply(&mut m, &found, 8.0);
        assert!(m.theta[64 * 128 + 66].is_nan());
        assert_eq!(m.theta.iter().filter(|t| t.is_nan()).count(), 1);
    }
}
