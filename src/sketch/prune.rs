//! The sketch target by pruning: curves the fill can do without are dropped until the
//! sketch part of `hair.czs` fits (issue 16's 600 B), most bytes saved for least fill lost
//! first.
//!
//! The pursuit (Eq. 24) lays a curve wherever it lowers Step 1's energy, which is about how
//! well Θ explains the image; whether the fill (Eq. 14-17) could have rebuilt that stretch of
//! Θ from the neighbouring curves is not its question. On flowing hair it is often so:
//! neighbouring stream lines run parallel and the fill between two of them gives the third.
//! So each curve is scored by what leaving it out costs the fill, read off the fill's
//! per-pixel error against Step 1's Θ around it, per byte it takes in the file; the cheapest
//! go first, a third of the sketch part (or the excess) a round, and the scores are taken
//! again on what is left. A minimum-description-length reading, as the bit cost's: bytes
//! are spent where the fill needs them.
//!
//! Leaving out every curve one at a time would cost a fill per curve. Curves whose boxes
//! (their primitives' centres grown by [`PruneParams::margin`]) lie at least a margin
//! apart barely reach each other's pixels through the fill, so they are left out together:
//! one fill per group of such curves, a dozen or two a round, each cut short at
//! [`PruneParams::score_sweeps`]. A round whose fill passes the fill target is tried again
//! with half its removals, down to one curve.
//!
//! Sequential: a handful of fills (each the `cz_fill` pass) and encodes a round; the
//! choices are a sort.

use super::{fill, format, prim, Curve, Sketch};
use crate::error::Result;
use crate::eval::metrics::orient_diff;
use crate::gpu::engine::Engine;

/// Tuning of [`prune`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PruneParams {
    /// How far beyond a curve's primitive centres its leave-out effect is read (px), and how
    /// far apart curves left out in the same fill stay. 12 px: a window reaches ~4 px from
    /// its centre, and the fill's weights carry a curve's angle some pixels further.
    pub margin: f32,
    /// The most of the sketch part one round removes (its bytes' share), so that scores are
    /// taken again before neighbours of a removed curve go too.
    pub share: f64,
    /// Sweeps of the fills that score the curves (the round's own fill, which decides
    /// whether it stays within the fill target, has the fill's full cap). A curve's effect
    /// is local, and the fill's angles settle near it long before its weights spread (see
    /// `fill`): on the raccoon crop 150 / 300 / 600 sweeps kept 72 / 73 / 71 curves, 588 /
    /// 597 / 598 B, fill 11.60 / 11.44 / 11.55°, pruning in 27 / 51 / 100 s.
    pub score_sweeps: u32,
}

impl Default for PruneParams {
    fn default() -> Self {
        PruneParams {
            margin: 12.0,
            share: 1.0 / 3.0,
            score_sweeps: 150,
        }
    }
}

/// One round's outcome: curves left, the sketch part's bytes, the file's bytes and the
/// fill's mean error (degrees). The first row is the sketch as given.
pub type Round = (usize, usize, usize, f64);

/// What [`prune`] kept.
pub struct Pruned {
    /// Per input curve, whether it stays.
    pub keep: Vec<bool>,
    /// Whether the sketch part fits the target.
    pub met: bool,
    pub rounds: Vec<Round>,
}

/// Where and against what the fill is scored, and how it is made.
pub struct FillCheck<'a> {
    pub engine: &'a Engine,
    pub hair: &'a [bool],
    /// Pixels where the error is read (the hair [`super::run::FILL_INSET`] px inside).
    pub inner: &'a [bool],
    /// The dense field the fill is read against (Step 1's Θ).
    pub theta: &'a [f32],
    pub fill: &'a fill::FillParams,
    pub seed: u64,
}

impl FillCheck<'_> {
    /// The fill of the stored sketch `s`: its per-pixel error (0 off `inner`) and mean.
    fn error(&self, s: &Sketch) -> Result<(Vec<f32>, f64)> {
        self.error_with(s, self.fill)
    }

    /// As [`Self::error`], the fill made with `fp`.
    fn error_with(&self, s: &Sketch, fp: &fill::FillParams) -> Result<(Vec<f32>, f64)> {
        let painted = prim::paint(&s.curves, s.width, s.height, Some(self.hair));
        let f = fill::fill(self.engine, &painted, self.hair, &s.rho_off, self.seed, fp)?;
        let mut err = vec![0f32; self.inner.len()];
        let (mut sum, mut n) = (0f64, 0usize);
        for (i, e) in err.iter_mut().enumerate() {
            if self.inner[i] && self.theta[i].is_finite() {
                // As `mean_orient_error_deg`: an unfilled pixel is 90° off.
                *e = if f.theta[i].is_finite() {
                    orient_diff(f.theta[i], self.theta[i]).to_degrees()
                } else {
                    90.0
                };
                sum += *e as f64;
                n += 1;
            }
        }
        Ok((err, if n > 0 { sum / n as f64 } else { 0.0 }))
    }
}

/// The stored sketch of `base` with the curves of `curves` that `keep` marks.
fn with_curves(base: &Sketch, curves: &[Curve], keep: &[bool]) -> Sketch {
    format::quantise(&Sketch {
        curves: curves
            .iter()
            .zip(keep)
            .filter(|(_, &k)| k)
            .map(|(c, _)| c.clone())
            .collect(),
        ..base.clone()
    })
}

/// Drops curves of `curves` (directed, in paint order; `base` holds the rest of the sketch)
/// until the sketch part of the file takes at most `target` bytes, keeping the fill's error
/// within `fill_max` degrees where given (see the module docs).
pub fn prune(
    base: &Sketch,
    curves: &[Curve],
    target: usize,
    fill_max: Option<f64>,
    check: &FillCheck,
    p: &PruneParams,
) -> Result<Pruned> {
    let n = curves.len();
    let mut keep = vec![true; n];
    let mut sketch = with_curves(base, curves, &keep);
    let (mut err, mut mean) = check.error(&sketch)?;
    let sizes = |s: &Sketch| {
        let z = format::czs_sizes(s);
        (z.curves, z.total)
    };
    let (mut cb, total) = sizes(&sketch);
    let mut rounds = vec![(n, cb, total, mean)];
    // Each curve's box: its primitives' centres grown by the margin.
    let boxes: Vec<[f32; 4]> = curves
        .iter()
        .map(|c| {
            c.prims
                .iter()
                .fold([f32::MAX, f32::MAX, f32::MIN, f32::MIN], |b, q| {
                    [
                        b[0].min(q.x - p.margin),
                        b[1].min(q.y - p.margin),
                        b[2].max(q.x + p.margin),
                        b[3].max(q.y + p.margin),
                    ]
                })
        })
        .collect();
    // Boxes closer than a margin share pixels the fill carries between them.
    let near = |a: &[f32; 4], b: &[f32; 4]| {
        a[0] <= b[2] + p.margin
            && b[0] <= a[2] + p.margin
            && a[1] <= b[3] + p.margin
            && b[1] <= a[3] + p.margin
    };
    let (w, h) = (base.width as usize, base.height as usize);
    let box_sum = |v: &[f32], b: &[f32; 4]| {
        let (x0, y0) = (b[0].max(0.0) as usize, b[1].max(0.0) as usize);
        let (x1, y1) = (
            (b[2].max(0.0) as usize).min(w - 1),
            (b[3].max(0.0) as usize).min(h - 1),
        );
        if x0 > x1 || y0 > y1 {
            // A box wholly off the image (no primitive of the curve on it).
            return 0.0;
        }
        let mut s = 0f64;
        for y in y0..=y1 {
            s += v[y * w + x0..=y * w + x1]
                .iter()
                .map(|&e| e as f64)
                .sum::<f64>();
        }
        s
    };
    while cb > target {
        let live: Vec<usize> = (0..n).filter(|&i| keep[i]).collect();
        if live.is_empty() {
            break;
        }
        // Greedy groups of curves far apart, in paint order.
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for &i in &live {
            match groups
                .iter_mut()
                .find(|g| g.iter().all(|&j| !near(&boxes[i], &boxes[j])))
            {
                Some(g) => g.push(i),
                None => groups.push(vec![i]),
            }
        }
        // What each curve costs the fill when left out, summed over its box.
        // Scored on shorter fills, the sketch as it stands included, so that the difference
        // is the curves' and not the sweeps'.
        let scoring = fill::FillParams {
            max_sweeps: p.score_sweeps.min(check.fill.max_sweeps),
            ..*check.fill
        };
        let base_err = if scoring.max_sweeps == check.fill.max_sweeps {
            err.clone()
        } else {
            check.error_with(&sketch, &scoring)?.0
        };
        let mut cost = vec![0f64; n];
        for g in &groups {
            let mut k = keep.clone();
            for &i in g {
                k[i] = false;
            }
            let (e, _) = check.error_with(&with_curves(base, curves, &k), &scoring)?;
            let diff: Vec<f32> = e.iter().zip(&base_err).map(|(a, b)| a - b).collect();
            for &i in g {
                cost[i] = box_sum(&diff, &boxes[i]);
            }
        }
        // What it saves: the sketch part's bytes without it (the coder is adaptive, so
        // this is read, not added up).
        let saves: Vec<f64> = live
            .iter()
            .map(|&i| {
                let mut k = keep.clone();
                k[i] = false;
                (cb as f64 - format::czs_sizes(&with_curves(base, curves, &k)).curves as f64)
                    .max(1.0)
            })
            .collect();
        let mut order: Vec<usize> = (0..live.len()).collect();
        order.sort_by(|&a, &b| {
            (cost[live[a]] / saves[a])
                .total_cmp(&(cost[live[b]] / saves[b]))
                .then(a.cmp(&b))
        });
        let want = ((cb - target) as f64).min(p.share * cb as f64);
        let mut take = 0;
        let mut saved = 0.0;
        while take < order.len() && saved < want {
            saved += saves[order[take]];
            take += 1;
        }
        // Halved until the fill stays within its target.
        let mut accepted = None;
        while take > 0 {
            let mut k = keep.clone();
            for &o in &order[..take] {
                k[live[o]] = false;
            }
            let s = with_curves(base, curves, &k);
            let (e, m) = check.error(&s)?;
            if fill_max.is_none_or(|f| m <= f) {
                accepted = Some((k, s, e, m));
                break;
            }
            take /= 2;
        }
        let Some((k, s, e, m)) = accepted else {
            break;
        };
        (keep, sketch, err, mean) = (k, s, e, m);
        let (c, t) = sizes(&sketch);
        cb = c;
        rounds.push((sketch.curves.len(), c, t, mean));
        log::info!(
            "sketch: pruned to {} curves, sketch part {c} B, file {t} B, fill {mean:.2}°",
            sketch.curves.len()
        );
    }
    Ok(Pruned {
        keep,
        met: cb <= target,
        rounds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sketch::{ColourMap, RhoPrior};

    /// Hair flowing level above row 40 and at 30° below it. Five level streams (one every
    /// 8 px) and one at 30°: the level ones stand in for each other, the tilted one for
    /// nothing, so a target one level stream's bytes under the sketch drops level streams
    /// and keeps the fill close.
    #[test]
    fn the_curves_the_fill_can_rebuild_go_first() {
        let (w, h) = (64u32, 64u32);
        let n = (w * h) as usize;
        let hair = vec![true; n];
        let tilt = 30f32.to_radians();
        let theta: Vec<f32> = (0..n)
            .map(|i| if i / w as usize >= 40 { tilt } else { 0.0 })
            .collect();
        let mut curves: Vec<Curve> = (0..5)
            .map(|k| Curve::straight(6.0, 4.0 + 8.0 * k as f32, 0.0, 10, 5.0, 8.0, 1))
            .collect();
        curves.push(Curve::straight(6.0, 44.0, tilt, 10, 5.0, 8.0, 1));
        let base = Sketch {
            width: w,
            height: h,
            seed: 1,
            curves: Vec::new(),
            rho_off: RhoPrior {
                weight: [0.5, 0.5],
                mean: [1.0, 4.0],
                sigma: [0.5, 2.0],
            },
            shading: Default::default(),
            colour: ColourMap {
                uv: vec![[0.0, 0.0]; crate::sketch::COLOUR_BINS],
            },
            region: Vec::new(),
            along_across: None,
        };
        let engine = Engine::cpu();
        let check = FillCheck {
            engine: &engine,
            hair: &hair,
            inner: &hair,
            theta: &theta,
            fill: &fill::FillParams::default(),
            seed: 1,
        };
        let all = with_curves(&base, &curves, &[true; 6]);
        let (_, e_all) = check.error(&all).unwrap();
        let bytes = format::czs_sizes(&all).curves;
        let target = bytes - 4;
        let p = PruneParams::default();
        let r = prune(&base, &curves, target, Some(e_all + 2.0), &check, &p).unwrap();
        println!("{:?} {:?}", r.keep, r.rounds);
        assert!(r.met, "{:?}", r.rounds);
        assert!(r.keep[5], "the tilted stream went: {:?}", r.keep);
        assert!(r.keep[..5].iter().any(|&k| !k), "{:?}", r.keep);
        assert_eq!(r.rounds[0], (6, bytes, r.rounds[0].2, e_all));
        let last = *r.rounds.last().unwrap();
        assert!(last.1 <= target && last.3 <= e_all + 2.0, "{last:?}");
        // Left out instead, the tilted stream costs the fill far more than a level one.
        let mut k = [true; 6];
        k[5] = false;
        let (_, e_tilt) = check.error(&with_curves(&base, &curves, &k)).unwrap();
        assert!(e_tilt > last.3 + 2.0, "{e_tilt} vs {}", last.3);
        // A target no curve can meet within the fill's bound keeps what it can.
        let r = prune(&base, &curves, 1, Some(e_all + 0.01), &check, &p).unwrap();
        assert!(!r.met);
        assert!(
            r.rounds.iter().all(|x| x.3 <= e_all + 0.01),
            "{:?}",
            r.rounds
        );
    }
}
