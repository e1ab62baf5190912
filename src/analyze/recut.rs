//! Cutting resolved curves where their growth direction disagrees with their neighbours'.
//!
//! Resolution (Eq. 1-2) gives each curve one flag, so a curve that runs across a parting
//! carries one direction on both sides of it. The tracer cuts curves at their apex, which on
//! straight hair is the part; curled or swept hair leaves the part at an angle, so the apex
//! lies off it, and the big side's curves spill onto the narrow side with the wrong
//! direction. The orientation map does not show such a part (it is continuous across it, and
//! the thin line of scalp is smoothed away), but the strokes and the curves already resolved
//! on the narrow side do: there, the spilled stretch points against everything near it. So
//! after resolving, each curve is compared vertex by vertex with the other curves and the
//! strokes within a small radius; where the agreement changes sign over a run of vertices,
//! the curve is cut there, and the pieces are resolved again. Each round moves the evidence
//! about one radius further along the part, so a few rounds are run.

use crate::analyze::resolve::intrinsic;
use crate::analyze::trace::{resample, Curve};

/// Parameters of the re-cutting rounds.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RecutParams {
    /// Neighbourhood of a vertex, pixels: small, so that the two sides of a part are not
    /// mixed (the resolution's own radius is 70 px).
    pub radius: f32,
    /// A run of agreeing or disagreeing vertices shorter than this does not count (noise,
    /// crossing curves).
    pub min_run: usize,
    /// Rounds of cutting and resolving again; 0 disables.
    pub rounds: u32,
    /// Neighbourhood radius of the resolution after a cut, pixels. Smaller than the first
    /// resolution's (70 px, the paper's): with its radius, curves just across a part vote
    /// on the pieces beside it, and hair on the two sides of a part points opposite ways,
    /// so Eq. (1) pulls those pieces the wrong way where no stroke is near.
    pub resolve_radius: f32,
}

impl Default for RecutParams {
    fn default() -> Self {
        RecutParams {
            radius: 6.0,
            min_run: 3,
            rounds: 4,
            resolve_radius: 30.0,
        }
    }
}

/// Cuts the directed `curves` (root -> tip) where they point against their neighbours (other
/// curves, and the `strokes` counted `stroke_weight` times per vertex) over a run of at least
/// `min_run` vertices while agreeing with them elsewhere. Returns `None` when nothing is cut.
pub fn cut_disagreeing(
    curves: &[Curve],
    strokes: &[Vec<[f32; 2]>],
    stroke_weight: f32,
    p: &RecutParams,
) -> Option<Vec<Curve>> {
    let r = p.radius;
    if r.is_nan() || r <= 0.0 || curves.is_empty() {
        return None;
    }
    // Every vertex with its tangent, weight and owner (curve index; strokes own none).
    let spacing = {
        let (l, s) = curves.iter().fold((0.0f32, 0usize), |(l, s), c| {
            (l + c.length(), s + c.points.len().saturating_sub(1))
        });
        if s > 0 && l > 0.0 {
            l / s as f32
        } else {
            2.0
        }
    };
    let mut pts: Vec<([f32; 2], [f32; 2], f32, usize)> = Vec::new();
    for (i, c) in curves.iter().enumerate() {
        for (q, t) in c.points.iter().zip(intrinsic(&c.points)) {
            pts.push((*q, t, 1.0, i));
        }
    }
    for s in strokes {
        let s = resample(s, spacing);
        for (q, t) in s.iter().zip(intrinsic(&s)) {
            pts.push((*q, t, stroke_weight, usize::MAX));
        }
    }
    let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
    for (q, ..) in &pts {
        x0 = x0.min(q[0]);
        y0 = y0.min(q[1]);
        x1 = x1.max(q[0]);
        y1 = y1.max(q[1]);
    }
    let gw = ((x1 - x0) / r) as usize + 1;
    let gh = ((y1 - y0) / r) as usize + 1;
    let cell = |q: [f32; 2]| -> (usize, usize) {
        (
            (((q[0] - x0) / r) as usize).min(gw - 1),
            (((q[1] - y0) / r) as usize).min(gh - 1),
        )
    };
    let mut grid: Vec<Vec<u32>> = vec![Vec::new(); gw * gh];
    for (k, (q, ..)) in pts.iter().enumerate() {
        let (cx, cy) = cell(*q);
        grid[cy * gw + cx].push(k as u32);
    }
    let r2 = r * r;
    let min_run = p.min_run.max(1);

    let mut out = Vec::with_capacity(curves.len());
    let mut cut_any = false;
    for (i, c) in curves.iter().enumerate() {
        let t = intrinsic(&c.points);
        // Sign of the agreement per vertex; 0 where nothing is near.
        let mut sign: Vec<i8> = c
            .points
            .iter()
            .zip(&t)
            .map(|(q, tq)| {
                let (cx, cy) = cell(*q);
                let mut a = 0.0f32;
                for gy in cy.saturating_sub(1)..=(cy + 1).min(gh - 1) {
                    for gx in cx.saturating_sub(1)..=(cx + 1).min(gw - 1) {
                        for &k in &grid[gy * gw + gx] {
                            let (v, tv, wv, o) = pts[k as usize];
                            if o == i {
                                continue;
                            }
                            let (dx, dy) = (v[0] - q[0], v[1] - q[1]);
                            if dx * dx + dy * dy <= r2 {
                                a += wv * (tq[0] * tv[0] + tq[1] * tv[1]);
                            }
                        }
                    }
                }
                if a > 0.0 {
                    1
                } else if a < 0.0 {
                    -1
                } else {
                    0
                }
            })
            .collect();
        // Vertices without evidence take the sign before them (the first nonzero one at the
        // start).
        let first = sign.iter().copied().find(|&s| s != 0).unwrap_or(0);
        let mut prev = first;
        for s in sign.iter_mut() {
            if *s == 0 {
                *s = prev;
            } else {
                prev = *s;
            }
        }
        // Runs, with short ones merged into what precedes them (or follows, at the start).
        let mut runs: Vec<(i8, usize)> = Vec::new();
        for &s in &sign {
            match runs.last_mut() {
                Some((rs, n)) if *rs == s => *n += 1,
                _ => runs.push((s, 1)),
            }
        }
        let mut merged: Vec<(i8, usize)> = Vec::new();
        for (s, n) in runs {
            match merged.last_mut() {
                Some((ms, mn)) if *ms == s || n < min_run => *mn += n,
                Some((ms, mn)) if *mn < min_run => {
                    *ms = s;
                    *mn += n;
                }
                _ => merged.push((s, n)),
            }
        }
        if merged.len() < 2 {
            out.push(c.clone());
            continue;
        }
        cut_any = true;
        let mut start = 0;
        for (_, n) in merged {
            out.push(Curve {
                points: c.points[start..start + n].to_vec(),
            });
            start += n;
        }
    }
    cut_any.then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(x0: f32, y: f32, dx: f32, n: usize) -> Curve {
        Curve {
            points: (0..n).map(|k| [x0 + dx * k as f32, y]).collect(),
        }
    }

    #[test]
    fn a_curve_spilling_across_a_part_is_cut_where_its_neighbours_turn() {
        // A part at x = 50: hair runs left of it towards -x, right of it towards +x. The curve
        // under test runs +x from x = 20 to 90, so its left stretch points against the left
        // neighbours and the stroke.
        let mut curves = vec![line(20.0, 50.0, 2.0, 36)];
        curves.push(Curve {
            points: line(10.0, 54.0, 2.0, 20).points.into_iter().rev().collect(),
        });
        curves.push(line(52.0, 54.0, 2.0, 20));
        let strokes = vec![vec![[48.0, 46.0], [20.0, 46.0]]];
        let cut = cut_disagreeing(&curves, &strokes, 10.0, &RecutParams::default()).expect("a cut");
        assert_eq!(cut.len(), 4, "{cut:?}");
        let (a, b) = (&cut[0].points, &cut[1].points);
        let at = a.last().unwrap()[0];
        println!("cut between x = {at} and {}", b[0][0]);
        assert!(
            (at - 50.0).abs() <= 6.0,
            "cut at x = {at}, not near the part"
        );
        // The neighbours agree with everything near them: left whole.
        assert_eq!(cut[2], curves[1]);
        assert_eq!(cut[3], curves[2]);
    }

    #[test]
    fn parallel_agreeing_curves_are_not_cut() {
        let curves: Vec<Curve> = (0..5).map(|k| line(0.0, 4.0 * k as f32, 2.0, 40)).collect();
        let strokes = vec![vec![[0.0, 8.0], [60.0, 8.0]]];
        assert!(cut_disagreeing(&curves, &strokes, 10.0, &RecutParams::default()).is_none());
    }
}
