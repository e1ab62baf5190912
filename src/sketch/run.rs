//! `coif sketch`: a hair image to its sketch, vector field and bands (CZ06 §4), and the
//! files a user keeps and looks at.
//!
//! Order: bands and colour map → a warm Θ from coif's Gabor filters → shading bases and
//! the region's outline → sketch pursuit (Step 1: Θ and the undirected curves) →
//! directions by Swendsen-Wang cuts (Step 2) → the sketch quantised to what the files store
//! (again with a larger λ_B while over a byte budget) → V filled in from that sketch alone
//! (what synthesis will see; again with a smaller λ_NC while it strays past the fill target,
//! then with a larger λ_B while the curves are over the sketch target) → files.

use super::{bands, fill, format, pursuit, shading, swc, vis};
use super::{Sketch, VectorField};
use crate::analyze::orient::{orient, GrayImage, OrientParams};
use crate::error::{Error, Result};
use crate::gpu::engine::Engine;
use crate::io::annot::Strokes;
use crate::io::{ensure_dir, npy, write_json, write_png};
use image::RgbImage;
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// Every setting of the analysis, with the defaults stated in the README.
#[derive(Clone, Debug)]
pub struct SketchParams {
    /// σ of the low band, px.
    pub sigma_l: f32,
    /// Shading bases K_L.
    pub bases: usize,
    pub pursuit: pursuit::PursuitParams,
    pub swc: swc::SwcParams,
    pub method: swc::Method,
    pub fill: fill::FillParams,
    /// The stored outline of the hair region.
    pub outline: super::region::OutlineParams,
    pub seed: u64,
    /// What `hair.czs`'s size is held to (see [`ByteBudget`]).
    pub budget: ByteBudget,
    /// The fill's mean distance from Step 1's dense Θ (degrees, over hair ≥ 5 px inside the
    /// mask) that the sketch is held to: where it strays further, λ_NC is halved (down to
    /// [`FILL_MIN_LAMBDA_NC`]) and the analysis run again (see [`FillTarget`]); None: off.
    pub fill_target: Option<f32>,
    /// What the sketch part of `hair.czs` (its curves) is held to, bytes, where that keeps
    /// the byte and fill targets met: the curves the fill can best do without are dropped
    /// until it fits (see [`SketchTarget`]); None: off.
    pub sketch_target: Option<usize>,
    /// Tuning of that pruning.
    pub prune: super::prune::PruneParams,
}

/// Issue 16's bound on the sketch part of `hair.czs`, the default sketch target (bytes).
pub const DEFAULT_SKETCH_TARGET_BYTES: usize = 600;

/// How the sketch target was met: by pruning (`super::prune`), after the byte and fill
/// targets, the curves the fill can best do without, with the fill kept within its target.
/// `rounds` holds (curves, sketch part bytes, `.czs` bytes, fill error in degrees), the
/// first row the sketch as pursued; where any curve went, Θ and the directions were then
/// solved again for the curves kept, and the last row is that final sketch.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SketchTarget {
    pub target_bytes: usize,
    pub met: bool,
    pub curves_pursued: usize,
    pub curves_kept: usize,
    pub rounds: Vec<super::prune::Round>,
}

/// Issue 16's bound on the fill against the dense field on real hair photos, the default
/// fill target (degrees).
pub const DEFAULT_FILL_TARGET_DEG: f32 = 12.0;
/// λ_NC is not halved below this for the fill target.
pub const FILL_MIN_LAMBDA_NC: f32 = 5.0;
/// How far inside the mask the fill's error is read (px): the mask's edge is where neither
/// field is sure.
pub const FILL_INSET: usize = 5;

/// How the fill target was met: every (λ_NC, fill error in degrees, `.czs` bytes) tried, in
/// order, and the kept one.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FillTarget {
    pub target_deg: f32,
    pub met: bool,
    pub lambda_nc: f32,
    pub tries: Vec<(f32, f64, usize)>,
}

/// Issue 16's bound on `hair.czs` ("≤ 1 KiB on every test image"), the default target.
pub const DEFAULT_TARGET_BYTES: usize = 1024;

/// What `hair.czs`'s size is held to. Where the sketch comes out larger, λ_B is raised until
/// it fits (see [`Budget`]): fewer primitives where they gain least, a coarser fill.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ByteBudget {
    /// The pursuit's λ_B as given, whatever the size.
    Off,
    /// Brought under this many bytes where a sketch with curves can be; where not even the
    /// region, shading and colour map fit, the λ_B-as-given sketch is kept and the report says
    /// the target was missed. The default, at [`DEFAULT_TARGET_BYTES`]: CZ06's sketch is the
    /// small part a user keeps, so a file over it is what a user would not expect. With a
    /// sketch target it is met by that target's pruning first (the curves the fill needs
    /// least dropped, after the fill target), and λ_B raised only where pruning stops short.
    Target(usize),
    /// Met, or the analysis is refused (a user's explicit budget).
    Max(usize),
}

impl ByteBudget {
    /// From the command's or the manifest's options: a budget (`--max-bytes`) wins over a
    /// target (`--target-bytes`, 0 off); neither gives the default target.
    pub fn from_options(max_bytes: Option<usize>, target_bytes: Option<usize>) -> Self {
        match (max_bytes, target_bytes) {
            (Some(b), _) => ByteBudget::Max(b),
            (None, Some(0)) => ByteBudget::Off,
            (None, Some(b)) => ByteBudget::Target(b),
            (None, None) => ByteBudget::Target(DEFAULT_TARGET_BYTES),
        }
    }

    fn bytes(self) -> Option<usize> {
        match self {
            ByteBudget::Off => None,
            ByteBudget::Target(b) | ByteBudget::Max(b) => Some(b),
        }
    }
}

impl Default for SketchParams {
    fn default() -> Self {
        SketchParams {
            sigma_l: 8.0,
            bases: 10,
            pursuit: Default::default(),
            swc: Default::default(),
            method: swc::Method::Swc,
            fill: Default::default(),
            outline: Default::default(),
            seed: 1,
            budget: ByteBudget::Target(DEFAULT_TARGET_BYTES),
            fill_target: Some(DEFAULT_FILL_TARGET_DEG),
            sketch_target: Some(DEFAULT_SKETCH_TARGET_BYTES),
            prune: Default::default(),
        }
    }
}

/// What the analysis reads.
pub struct SketchInputs<'a> {
    pub image: &'a RgbImage,
    /// Hair pixels, W*H.
    pub hair: &'a [bool],
    /// Direction strokes that clamp the curves they run along.
    pub strokes: Option<&'a Strokes>,
}

/// Everything the analysis made.
pub struct SketchResult {
    /// The sketch as the files store it.
    pub sketch: Sketch,
    /// Step 1's dense Θ (Eq. 25 with the sketch as constraint).
    pub theta: Vec<f32>,
    /// Step 1's curves, before their directions (for ablations of Step 2).
    pub undirected: Vec<super::Curve>,
    /// V filled in from the stored sketch alone.
    pub field: VectorField,
    /// Energy of the empty sketch, then after each accepted curve (CZ06 Fig. 13).
    pub energy: Vec<f64>,
    pub pursuit: pursuit::PursuitStats,
    pub swc: swc::Directed,
    pub bands: bands::Bands,
    /// The hair mask analysed.
    pub hair: Vec<bool>,
    pub seconds: Vec<(&'static str, f64)>,
    /// How a byte budget was met, when one was given.
    pub budget: Option<Budget>,
    /// The fill's mean error against Step 1's Θ (degrees) over the hair pixels at least
    /// [`FILL_INSET`] px inside the mask, and how many (0: none that far inside).
    pub fill_error: (f64, usize),
    /// How the fill target was met, when one was given.
    pub fill_target: Option<FillTarget>,
    /// How the sketch target was met, when one was given and the curves were over it.
    pub sketch_target: Option<SketchTarget>,
}

/// How a byte budget was met: λ_B doubled from 1 (or from the given λ_B) until the file fits,
/// then the interval halved twice; the smallest λ_B tried that fits is kept. The file's size
/// is not strictly monotonic in λ_B, so this finds a λ_B that fits, not the least one.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Budget {
    /// "target" (the default, kept unmet where it cannot be met) or "max" (a user's).
    pub kind: &'static str,
    pub max_bytes: usize,
    /// Whether the kept sketch fits.
    pub met: bool,
    /// The λ_B the kept sketch was pursued with.
    pub lambda_b: f32,
    /// Every (λ_B, `.czs` bytes) tried, in order.
    pub tries: Vec<(f32, usize)>,
    /// Met by the sketch target's pruning (its rounds under [`SketchTarget`]) rather than by
    /// raising λ_B: with a sketch target, the default byte target is met that way first.
    pub pruned: bool,
}

/// Largest λ_B the budget search tries before giving up.
const BUDGET_MAX_LAMBDA_B: f32 = 1024.0;

/// Runs the analysis.
pub fn analyse(engine: &Engine, inp: &SketchInputs, p: &SketchParams) -> Result<SketchResult> {
    let (w, h) = inp.image.dimensions();
    let n = w as usize * h as usize;
    if inp.hair.len() != n {
        return Err(Error::Invalid(format!(
            "the hair mask has {} pixels, the image {w}x{h}",
            inp.hair.len()
        )));
    }
    if let Some(t) = p.fill_target {
        if !(t.is_finite() && t > 0.0) {
            return Err(Error::Invalid(format!(
                "the fill target must be a finite number of degrees > 0, got {t}"
            )));
        }
    }
    let hair_px = inp.hair.iter().filter(|&&m| m).count();
    if hair_px == 0 {
        return Err(Error::Invalid(
            "the hair mask is empty: no hair to sketch".into(),
        ));
    }
    let mut seconds = Vec::new();
    let mut t = Instant::now();
    let lap = |seconds: &mut Vec<(&'static str, f64)>, name: &'static str, t: &mut Instant| {
        seconds.push((name, t.elapsed().as_secs_f64()));
        *t = Instant::now();
    };

    let b = bands::bands(engine, inp.image, inp.hair, p.sigma_l)?;
    let colour = super::ColourMap::fit(&b, inp.hair);
    lap(&mut seconds, "bands", &mut t);

    let gray = GrayImage::from_rgb(inp.image);
    let mask8: Vec<u8> = inp.hair.iter().map(|&m| m as u8).collect();
    let warm = orient(engine, &gray, Some(&mask8), &OrientParams::default())?;
    lap(&mut seconds, "gabor", &mut t);

    let high = GrayImage {
        width: w,
        height: h,
        data: b.high.clone(),
    };
    let shading = shading::fit(&b.low, inp.hair, w, h, p.bases);
    let region = super::region::outline(inp.hair, w, h, &p.outline);
    lap(&mut seconds, "shading", &mut t);

    // Steps 1 and 2 and the stored sketch, for one λ_NC and λ_B; their times summed over
    // attempts.
    let times = std::cell::Cell::new([0.0f64; 3]);
    // Step 2 on a pursuit's curves, the strokes clamping the curves they run along.
    let direct = |pu: &pursuit::Pursuit| -> Result<swc::Directed> {
        let clamps = match inp.strokes {
            Some(s) => swc::stroke_clamps(&pu.curves, s, inp.hair, w, h),
            None => Vec::new(),
        };
        swc::directions(
            &pu.curves, &pu.theta, inp.hair, w, h, &clamps, &p.swc, p.method,
        )
    };
    // The sketch as the files store it.
    let stored = |pu: &pursuit::Pursuit, directed: &swc::Directed| {
        // Eq. 12's along/across ratio of the high band under Step 1's Θ.
        let along_across = super::texture::along_across(&high.data, &pu.theta, inp.hair, w, h);
        format::quantise(&Sketch {
            width: w,
            height: h,
            seed: p.seed,
            curves: directed.curves.clone(),
            rho_off: pu.rho_off,
            shading: shading.clone(),
            colour: colour.clone(),
            region: region.clone(),
            along_across,
        })
    };
    let attempt =
        |lambda_nc: f32, lambda_b: f32| -> Result<(pursuit::Pursuit, swc::Directed, Sketch)> {
            // A budget's pursuits are the run's longest stretch: a signal stops it between them.
            crate::interrupt::check()?;
            let pp = pursuit::PursuitParams {
                lambda_nc,
                lambda_b,
                ..p.pursuit
            };
            let t0 = Instant::now();
            let pu = pursuit::pursue(engine, &high, inp.hair, &warm.theta, &pp)?;
            let t1 = Instant::now();
            let directed = direct(&pu)?;
            let [a, b, c] = times.get();
            times.set([
                a + (t1 - t0).as_secs_f64(),
                b + t1.elapsed().as_secs_f64(),
                c,
            ]);
            let sketch = stored(&pu, &directed);
            Ok((pu, directed, sketch))
        };
    // Where the fill's error is read.
    let inner: Vec<bool> = {
        let m: Vec<u8> = inp.hair.iter().map(|&v| v as u8).collect();
        crate::base::mask::erode(&m, w as usize, h as usize, FILL_INSET)
            .into_iter()
            .map(|v| v != 0)
            .collect()
    };
    // One λ_NC: the pursuit at the given λ_B, the byte budget, and the fill from the stored
    // sketch with its error against Step 1's Θ.
    let finish = |(pu, directed, sketch): (pursuit::Pursuit, swc::Directed, Sketch),
                  budget: Option<Budget>|
     -> Result<Run> {
        let t0 = Instant::now();
        let painted = super::prim::paint(&sketch.curves, w, h, Some(inp.hair));
        let field = fill::fill(engine, &painted, inp.hair, &sketch.rho_off, p.seed, &p.fill)?;
        let [a, b, c] = times.get();
        times.set([a, b, c + t0.elapsed().as_secs_f64()]);
        let fill_error =
            crate::eval::metrics::mean_orient_error_deg(&field.theta, &pu.theta, &inner);
        Ok(Run {
            pu,
            directed,
            sketch,
            budget,
            field,
            fill_error,
        })
    };
    // With a sketch target, the byte target (not a user's budget) is met by the same
    // pruning, after the fill target, rather than by pursuing again with a larger λ_B; λ_B
    // is raised only where pruning stops short of it.
    let defer = matches!(p.budget, ByteBudget::Target(_)) && p.sketch_target.is_some();
    let run_at = |lambda_nc: f32, budgeted: bool| -> Result<Run> {
        let first = attempt(lambda_nc, p.pursuit.lambda_b)?;
        let (kept, budget) = match p.budget.bytes().filter(|_| budgeted) {
            Some(max) => {
                let strict = matches!(p.budget, ByteBudget::Max(_));
                let (kept, b) = fit_budget(max, strict, p.pursuit.lambda_b, first, |lb| {
                    attempt(lambda_nc, lb)
                })?;
                (kept, Some(b))
            }
            None => (first, None),
        };
        finish(kept, budget)
    };
    let mut kept = run_at(p.pursuit.lambda_nc, !defer)?;
    let fill_target = match p.fill_target {
        Some(target) => {
            let mut tries = vec![(
                p.pursuit.lambda_nc,
                kept.fill_error.0,
                format::to_czs(&kept.sketch).len(),
            )];
            let mut lambda_kept = p.pursuit.lambda_nc;
            let missed = |r: &Run| r.fill_error.1 > 0 && r.fill_error.0 > target as f64;
            let mut lambda = p.pursuit.lambda_nc;
            while missed(&kept) && 0.5 * lambda >= FILL_MIN_LAMBDA_NC {
                lambda *= 0.5;
                log::info!(
                    "sketch: the fill strays {:.2}° from the dense field, over the {target}° \
                     target: pursuing again at λ_NC {lambda}",
                    kept.fill_error.0
                );
                let r = run_at(lambda, !defer)?;
                tries.push((lambda, r.fill_error.0, format::to_czs(&r.sketch).len()));
                // Unmet to the end, the closest fill is kept.
                if r.fill_error.0 < kept.fill_error.0 {
                    (kept, lambda_kept) = (r, lambda);
                }
            }
            Some(FillTarget {
                target_deg: target,
                met: !missed(&kept),
                lambda_nc: lambda_kept,
                tries,
            })
        }
        None => None,
    };
    let t_prune = Instant::now();
    // The curves kept, with Θ solved again under them (the dropped curves no longer clamp
    // it) and their directions taken again on that Θ.
    let rebuild = |run: &Run, keep: &[bool]| -> Result<Run> {
        let (mut pu, budget) = (run.pu.clone(), run.budget.clone());
        let undirected: Vec<_> = pu
            .curves
            .iter()
            .zip(keep)
            .filter(|(_, &k)| k)
            .map(|(c, _)| c.clone())
            .collect();
        let painted = super::prim::paint(&undirected, w, h, Some(inp.hair));
        let tp = super::theta::ThetaParams {
            sigma2: Some(pu.sigma2),
            ..p.pursuit.theta
        };
        let theta = super::theta::diffuse(engine, &high, inp.hair, Some(&painted), &pu.theta, &tp)?;
        let (gx, gy) = super::theta::gradients(&high.data, w, h, inp.hair);
        pu.rho = super::rho::rho_field(&gx, &gy, &theta);
        (pu.theta, pu.curves) = (theta, undirected);
        let t1 = Instant::now();
        let directed = direct(&pu)?;
        let [a, b, c] = times.get();
        times.set([a, b + t1.elapsed().as_secs_f64(), c]);
        let sketch = stored(&pu, &directed);
        finish((pu, directed, sketch), budget)
    };
    let check = (engine, inp.hair, inner.as_slice());
    let sketch_target = match p.sketch_target {
        Some(target) => {
            let mut met_both = None;
            if let (true, Some(max)) = (defer, p.budget.bytes()) {
                // The curves' share of the byte target, where the rest leaves them one.
                let z = format::czs_sizes(&kept.sketch);
                let rest = z.total - z.curves;
                let pruned = if rest < max {
                    Some(meet_sketch_target(
                        target.min(max - rest),
                        &kept,
                        p,
                        check,
                        rebuild,
                    )?)
                } else {
                    None
                };
                // The last round is the sketch kept (the first, where none went).
                let last = |st: &SketchTarget| st.rounds[st.rounds.len() - 1];
                match pruned {
                    Some((r, mut st)) if last(&st).2 <= max => {
                        let mut r = r.unwrap_or(kept);
                        st.target_bytes = target;
                        st.met = last(&st).1 <= target;
                        r.budget = Some(Budget {
                            kind: "target",
                            max_bytes: max,
                            met: true,
                            lambda_b: p.pursuit.lambda_b,
                            tries: vec![(p.pursuit.lambda_b, z.total)],
                            pruned: st.curves_kept < st.curves_pursued,
                        });
                        kept = r;
                        met_both = Some(st);
                    }
                    _ => {
                        let lambda_nc = fill_target
                            .as_ref()
                            .map_or(p.pursuit.lambda_nc, |f| f.lambda_nc);
                        log::info!(
                            "sketch: pruning leaves the file over the {max} B target: pursuing \
                             again with a larger primitive penalty"
                        );
                        kept = run_at(lambda_nc, true)?;
                    }
                }
            }
            Some(match met_both {
                Some(st) => st,
                None => {
                    let (r, st) = meet_sketch_target(target, &kept, p, check, rebuild)?;
                    if let Some(r) = r {
                        kept = r;
                    }
                    st
                }
            })
        }
        None => None,
    };
    let Run {
        pu,
        directed,
        sketch,
        budget,
        field,
        fill_error,
    } = kept;
    let [t_pursuit, t_directions, t_fill] = times.get();
    seconds.push(("pursuit", t_pursuit));
    seconds.push(("directions", t_directions));
    seconds.push(("fill", t_fill));
    // The pruning's own fills and the rebuild (Θ, directions, fill) of what it kept.
    if sketch_target.as_ref().is_some_and(|t| t.rounds.len() > 1) {
        seconds.push(("prune", t_prune.elapsed().as_secs_f64()));
    }

    Ok(SketchResult {
        sketch,
        theta: pu.theta,
        undirected: pu.curves,
        field,
        energy: std::iter::once(pu.energy_empty)
            .chain(pu.energy.iter().copied())
            .collect(),
        pursuit: pu.stats.clone(),
        swc: directed,
        bands: b,
        hair: inp.hair.to_vec(),
        seconds,
        budget,
        fill_error,
        fill_target,
        sketch_target,
    })
}

/// Rebuilds that may follow a pruning whose rebuilt sketch came out over the target (Step 2
/// taken again can cost a few bytes more than the pruning counted).
const PRUNE_AGAIN: usize = 2;

/// Brings the curves of `kept` (already within the byte and fill targets) under `target`
/// bytes by pruning them (`super::prune`), the fill held within its target; `rebuild`
/// makes the run of the curves kept. A sketch whose fill already misses its target is kept
/// as it is, and so is one from which no curve could go. Where the rebuilt sketch is still
/// over the target, it is pruned again from there, at most [`PRUNE_AGAIN`] times.
fn meet_sketch_target(
    target: usize,
    kept: &Run,
    p: &SketchParams,
    check: (&Engine, &[bool], &[bool]),
    rebuild: impl Fn(&Run, &[bool]) -> Result<Run>,
) -> Result<(Option<Run>, SketchTarget)> {
    let sizes = format::czs_sizes(&kept.sketch);
    let first = (
        kept.sketch.curves.len(),
        sizes.curves,
        sizes.total,
        kept.fill_error.0,
    );
    let fill_max = p.fill_target.map(|f| f as f64);
    let done = |met: bool, rounds: Vec<super::prune::Round>| SketchTarget {
        target_bytes: target,
        met,
        curves_pursued: first.0,
        curves_kept: rounds.last().map_or(first.0, |r| r.0),
        rounds,
    };
    let over_fill = kept.fill_error.1 > 0 && fill_max.is_some_and(|f| first.3 > f);
    if sizes.curves <= target || over_fill {
        return Ok((None, done(sizes.curves <= target, vec![first])));
    }
    let (engine, hair, inner) = check;
    let prune = |from: &Run| {
        super::prune::prune(
            &from.sketch,
            &from.directed.curves,
            target,
            fill_max,
            &super::prune::FillCheck {
                engine,
                hair,
                inner,
                theta: &from.pu.theta,
                fill: &p.fill,
                seed: p.seed,
            },
            &p.prune,
        )
    };
    let pruned = prune(kept)?;
    if pruned.keep.iter().all(|&k| k) {
        return Ok((None, done(false, pruned.rounds)));
    }
    let mut rounds = pruned.rounds;
    let mut r = rebuild(kept, &pruned.keep)?;
    for again in 0..=PRUNE_AGAIN {
        let sizes = format::czs_sizes(&r.sketch);
        rounds.push((
            r.sketch.curves.len(),
            sizes.curves,
            sizes.total,
            r.fill_error.0,
        ));
        let over_fill = fill_max.is_some_and(|f| r.fill_error.0 > f);
        if sizes.curves <= target || over_fill || again == PRUNE_AGAIN {
            break;
        }
        log::info!(
            "sketch: the rebuilt sketch part is {} B, over the {target} B target: pruning again",
            sizes.curves
        );
        let more = prune(&r)?;
        if more.keep.iter().all(|&k| k) {
            break;
        }
        // The new pruning's first round is the rebuilt sketch, already counted.
        rounds.extend(more.rounds.into_iter().skip(1));
        r = rebuild(&r, &more.keep)?;
    }
    let met = rounds.last().is_some_and(|x| x.1 <= target);
    Ok((Some(r), done(met, rounds)))
}

/// One run of Steps 1 and 2 and the fill at one λ_NC.
struct Run {
    pu: pursuit::Pursuit,
    directed: swc::Directed,
    sketch: Sketch,
    budget: Option<Budget>,
    field: VectorField,
    fill_error: (f64, usize),
}

/// Meets a byte budget (see [`Budget`]) from the first attempt's result, calling `attempt`
/// with larger λ_B as needed; returns the kept attempt. Unless `strict`, a budget that not
/// even a sketch without curves meets keeps the first attempt, reported as missed.
fn fit_budget<T>(
    max: usize,
    strict: bool,
    lambda0: f32,
    first: (T, swc::Directed, Sketch),
    attempt: impl Fn(f32) -> Result<(T, swc::Directed, Sketch)>,
) -> Result<((T, swc::Directed, Sketch), Budget)> {
    // The file's length only: `czs_sizes` would also encode it three more times to split it.
    let bytes = |s: &Sketch| format::to_czs(s).len();
    let kind = if strict { "max" } else { "target" };
    let mut tries = vec![(lambda0, bytes(&first.2))];
    let met = tries[0].1 <= max;
    // The region, shading and colour map alone; only needed when the first is over.
    let bare = if met {
        0
    } else {
        bytes(&Sketch {
            curves: Vec::new(),
            ..first.2.clone()
        })
    };
    if met || (!strict && bare > max) {
        let b = Budget {
            kind,
            pruned: false,
            max_bytes: max,
            met,
            lambda_b: lambda0,
            tries,
        };
        return Ok((first, b));
    }
    if bare > max {
        return Err(Error::Invalid(format!(
            "a byte budget of {max} B cannot be met: without any curve the sketch takes \
             {bare} B (its region, shading and colour map)"
        )));
    }
    // Double λ_B until the sketch fits, then halve the interval twice.
    let (mut lo, mut hi) = (lambda0, None);
    let mut next = (2.0 * lo).max(1.0);
    while hi.is_none() && next <= BUDGET_MAX_LAMBDA_B {
        log::info!(
            "sketch: {} B at λ_B {lo}, over the {max} B {kind}: pursuing again at λ_B {next}",
            tries.last().map_or(0, |t| t.1)
        );
        let r = attempt(next)?;
        let n = bytes(&r.2);
        tries.push((next, n));
        if n <= max {
            hi = Some((next, r));
        } else {
            lo = next;
            next *= 2.0;
        }
    }
    let Some((mut best, mut kept)) = hi else {
        if !strict {
            let b = Budget {
                kind,
                pruned: false,
                max_bytes: max,
                met: false,
                lambda_b: lambda0,
                tries,
            };
            return Ok((first, b));
        }
        return Err(Error::Invalid(format!(
            "a byte budget of {max} B was not met with a primitive penalty up to \
             {BUDGET_MAX_LAMBDA_B} (tried: {tries:?})"
        )));
    };
    for _ in 0..2 {
        let mid = 0.5 * (lo + best);
        log::info!("sketch: fits at λ_B {best}; trying λ_B {mid}");
        let r = attempt(mid)?;
        let n = bytes(&r.2);
        tries.push((mid, n));
        if n <= max {
            (best, kept) = (mid, r);
        } else {
            lo = mid;
        }
    }
    let b = Budget {
        kind,
        pruned: false,
        max_bytes: max,
        met: true,
        lambda_b: best,
        tries,
    };
    Ok((kept, b))
}

/// The pursuit's counts, with its wall-clock times under "seconds" as everywhere in the
/// reports (so runs compare equal without them).
fn pursuit_report(st: &pursuit::PursuitStats) -> serde_json::Value {
    let mut v = json!(st);
    if let Some(o) = v.as_object_mut() {
        let times: serde_json::Map<_, _> = o
            .iter()
            .filter_map(|(k, x)| Some((k.strip_prefix("seconds_")?.to_string(), x.clone())))
            .collect();
        o.retain(|k, _| !k.starts_with("seconds_"));
        o.insert("seconds".into(), times.into());
    }
    v
}

/// Writes the sketch's files into `out` (each atomically): `hair.czs`, `sketch.json`,
/// `sketch.svg`, `theta.npy`, `vector.npy`, `rho.npy`, `sketch.png`, `field.png`,
/// `energy.png`, `shading.png` and `report.json`.
pub fn write(
    out: &Path,
    photo: &RgbImage,
    r: &SketchResult,
    extra: serde_json::Value,
) -> Result<()> {
    ensure_dir(out)?;
    let s = &r.sketch;
    let (w, h) = (s.width as usize, s.height as usize);
    let czs = format::to_czs(s);
    crate::io::write_atomic(&out.join("hair.czs"), &czs)?;
    crate::io::write_atomic(&out.join("sketch.json"), format::to_json(s).as_bytes())?;
    crate::io::write_atomic(&out.join("sketch.svg"), format::to_svg(s).as_bytes())?;
    npy::write_f32(&out.join("theta.npy"), &[h, w], &r.field.theta)?;
    let vector: Vec<f32> = r.field.dir.iter().flat_map(|d| [d[0], d[1]]).collect();
    npy::write_f32(&out.join("vector.npy"), &[h, w, 2], &vector)?;
    npy::write_f32(&out.join("rho.npy"), &[h, w], &r.field.rho)?;
    let backdrop = crate::io::vis::dimmed(photo, 0.45);
    write_png(&out.join("sketch.png"), &vis::sketch_picture(&backdrop, s))?;
    write_png(
        &out.join("field.png"),
        &vis::field_picture(&backdrop, &r.field),
    )?;
    write_png(
        &out.join("energy.png"),
        &vis::energy_picture(&r.energy, 480, 240),
    )?;
    let low = s.shading.render(s.width, s.height);
    let shading_img = RgbImage::from_fn(s.width, s.height, |x, y| {
        let l = low[(y as usize) * w + x as usize];
        image::Rgb(s.colour.to_rgb(l))
    });
    write_png(&out.join("shading.png"), &shading_img)?;
    let sizes = format::czs_sizes(s);
    let mut report = json!({
        "width": s.width,
        "height": s.height,
        "bytes": sizes,
        "curves": s.curves.len(),
        "primitives": s.curves.iter().map(|c| c.prims.len()).sum::<usize>(),
        "curves_by_kind": super::Kind::ALL.map(|k| (k.letter().to_string(), s.curves.iter().filter(|c| c.kind == k).count())).into_iter().collect::<std::collections::BTreeMap<_,_>>(),
        "bases": s.shading.bases.len(),
        "region": {
            "polygons": s.region.len(),
            "vertices": s.region.iter().map(|p| p.len()).sum::<usize>(),
            "iou_with_mask": super::region::iou(&super::region::fill(&s.region, s.width, s.height), &r.hair),
        },
        "energy": { "per_curve": r.energy, "directions": r.swc.energy },
        "seconds": crate::io::seconds(&r.seconds),
        "pursuit": pursuit_report(&r.pursuit),
        "budget": r.budget,
        "fill": {
            "error_deg": r.fill_error.0,
            "pixels": r.fill_error.1,
            "inset_px": FILL_INSET,
            "against": "Step 1's dense Θ",
            "target": r.fill_target,
        },
        "sketch_target": r.sketch_target,
    });
    if let (Some(o), Some(e)) = (report.as_object_mut(), extra.as_object()) {
        for (k, v) in e {
            o.insert(k.clone(), v.clone());
        }
    }
    write_json(&out.join("report.json"), &report)?;
    Ok(())
}
