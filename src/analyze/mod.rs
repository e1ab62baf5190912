//! From a photo and strokes to directed hair (issue 3, C13 §2.1): segmentation (when no mask
//! is given), orientation, 2D tracing, growth-direction resolution (Eq. 1-2) and the dense
//! direction field.

pub mod direction;
pub mod orient;
pub mod parting;
pub mod recut;
pub mod resolve;
pub mod segment;
pub mod singular;
pub mod trace;
mod write;

pub use write::{load_photo, run, run_orient, write, write_agreement, write_orient, OrientRun};

use crate::analyze::direction::{dense_direction, DirectionParams, Domain};
use crate::analyze::orient::{orient, GrayImage, OrientMap, OrientParams};
use crate::analyze::parting::{cut_at_partings, Parted, PartingImage, PartingLine, PartingParams};
use crate::analyze::recut::{cut_disagreeing, RecutParams};
use crate::analyze::resolve::{resolve_directions_apart, ResolveParams, Resolved};
use crate::analyze::segment::{segment_with_warnings, SegmentParams};
use crate::analyze::trace::{split_curves, trace_curves, Curve, TraceParams};
use crate::error::{Error, Result};
use crate::gpu::engine::Engine;
use crate::io::annot::{StrokeKind, Strokes};
use std::time::Instant;

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct AnalyzeParams {
    pub segment: SegmentParams,
    pub orient: OrientParams,
    pub trace: TraceParams,
    /// Traced curves are resolved in pieces of at most this many vertices; 0 (default)
    /// resolves them whole, since the tracer already cuts curves at a parting's apex. See
    /// [`split_curves`].
    pub piece_vertices: usize,
    /// Traced curves cut where they cross a line of strand ends (a parting the orientation
    /// runs through); see [`crate::analyze::parting`].
    pub parting: PartingParams,
    pub resolve: ResolveParams,
    /// Curves cut where they point against their neighbours, then resolved again (parts that
    /// curled or swept hair leaves at an angle); see [`crate::analyze::recut`].
    pub recut: RecutParams,
    pub direction: DirectionParams,
}

pub struct Analysis {
    pub width: u32,
    pub height: u32,
    /// One byte per pixel, 1 on hair.
    pub mask: Vec<u8>,
    /// Whether the mask was segmented from the strokes (no mask given).
    pub mask_computed: bool,
    pub orient: OrientMap,
    /// Curves as traced (split into pieces), before their direction is known.
    pub traced: Vec<Curve>,
    /// Where traced curves were cut at a line of strand ends ([`parting`]).
    pub parting_cuts: Vec<[f32; 2]>,
    /// Straight runs of those cuts: partings, across which curves do not vote on each
    /// other's direction ([`resolve::resolve_directions_apart`]).
    pub parting_lines: Vec<PartingLine>,
    pub resolved: Resolved,
    /// The direction strokes, root→tip.
    pub strokes: Vec<Vec<[f32; 2]>>,
    /// The background strokes (drawn over `mask_overlay.png`).
    pub background_strokes: Vec<Vec<[f32; 2]>>,
    /// Unit growth direction, H x W x 2 (x right, y down), NaN off hair.
    pub direction: Vec<f32>,
    /// Things the user should know that did not stop the run.
    pub warnings: Vec<String>,
    /// Seconds per stage.
    pub timings: Vec<(&'static str, f64)>,
}

impl Analysis {
    /// The hair mask as `mask.png` stores it: 255 on hair, 0 elsewhere.
    pub fn mask_image(&self) -> image::GrayImage {
        let px = self.mask.iter().map(|&v| 255 * (v != 0) as u8).collect();
        image::GrayImage::from_raw(self.width, self.height, px).expect("the mask has w*h pixels")
    }
}

pub fn analyze(
    engine: &Engine,
    image: &image::RgbImage,
    strokes: &Strokes,
    mask: Option<Vec<u8>>,
    p: &AnalyzeParams,
) -> Result<Analysis> {
    let (w, h) = image.dimensions();
    let mut timings = Vec::new();
    let mut warnings = Vec::new();
    let dir_strokes: Vec<Vec<[f32; 2]>> = strokes
        .strokes
        .iter()
        .filter(|s| s.kind == StrokeKind::Direction)
        .map(|s| s.points.clone())
        .collect();
    if dir_strokes.is_empty() {
        return Err(Error::Invalid(
            "the strokes have no \"direction\" stroke; draw at least one along the hair, root to tip"
                .into(),
        ));
    }
    let t = Instant::now();
    let (mask, mask_computed) = match mask {
        Some(m) => (m, false),
        None => {
            let (m, said) = segment_with_warnings(image, strokes, &p.segment)?;
            warnings.extend(said);
            timings.push(("segment", t.elapsed().as_secs_f64()));
            (m.pixels().map(|v| (v[0] > 127) as u8).collect(), true)
        }
    };
    if mask.len() != (w * h) as usize {
        return Err(Error::Invalid(format!(
            "mask has {} pixels, the image {}",
            mask.len(),
            w * h
        )));
    }
    if !mask.iter().any(|&m| m != 0) {
        return Err(Error::Invalid("the hair mask is empty".into()));
    }
    let shares: Vec<f32> = dir_strokes
        .iter()
        .map(|s| crate::base::mask::share_on(s, &mask, w, h))
        .collect();
    if shares.iter().all(|&s| s < 0.5) {
        return Err(Error::Invalid(
            "none of the direction strokes lies on the hair mask (each has under half of its \
             points on hair); draw them over the hair"
                .into(),
        ));
    }
    for (i, s) in shares.iter().enumerate() {
        if *s < 0.5 {
            warnings.push(format!(
                "direction stroke {i} lies mostly off the hair ({:.0}% of its points on hair); \
                 it still votes within the {} px radius",
                100.0 * s,
                p.resolve.radius
            ));
        }
    }
    let t = Instant::now();
    let gray = GrayImage::from_rgb(image);
    let om = orient(engine, &gray, Some(&mask), &p.orient)?;
    timings.push(("orientation", t.elapsed().as_secs_f64()));
    crate::interrupt::check()?;
    let t = Instant::now();
    let traced = split_curves(
        &trace_curves(&om.theta, &om.confidence, &mask, w, h, &p.trace),
        p.piece_vertices,
    );
    // Off (threshold 0) means no cut, so the smoothed image is not made at all.
    let Parted {
        pieces: mut traced,
        cuts,
        lines,
    } = if p.parting.threshold > 0.0 {
        let parting = PartingImage::new(&gray.data, &mask, w, h, &p.parting);
        cut_at_partings(&traced, &parting, &p.parting)
    } else {
        Parted {
            pieces: traced,
            cuts: Vec::new(),
            lines: Vec::new(),
        }
    };
    log::debug!("{} traced curves cut at a line of strand ends", cuts.len());
    timings.push(("trace", t.elapsed().as_secs_f64()));
    let t = Instant::now();
    log::debug!("{} partings among the cuts", lines.len());
    let mut resolved = resolve_directions_apart(&traced, &dir_strokes, &lines, &p.resolve);
    let recut_resolve = ResolveParams {
        radius: p.recut.resolve_radius.min(p.resolve.radius),
        ..p.resolve.clone()
    };
    for _ in 0..p.recut.rounds {
        let Some(cut) = cut_disagreeing(
            &resolved.curves,
            &dir_strokes,
            p.resolve.stroke_weight,
            &p.recut,
        ) else {
            break;
        };
        traced = cut;
        resolved = resolve_directions_apart(&traced, &dir_strokes, &lines, &recut_resolve);
    }
    timings.push(("resolve", t.elapsed().as_secs_f64()));
    crate::interrupt::check()?;
    if !resolved.unreachable.is_empty() {
        warnings.push(format!(
            "{} of {} curves had no resolved neighbour within {} px of any stroke and were \
             resolved through other curves or left to the rule of the paper; a stroke near \
             them would make them certain",
            resolved.unreachable.len(),
            traced.len(),
            p.resolve.radius
        ));
    }
    let t = Instant::now();
    let curves: Vec<Vec<[f32; 2]>> = resolved.curves.iter().map(|c| c.points.clone()).collect();
    let direction = dense_direction(
        engine,
        &Domain {
            width: w,
            height: h,
            mask: &mask,
            theta: Some(&om.theta),
        },
        &curves,
        &dir_strokes,
        &p.direction,
    )?;
    timings.push(("direction", t.elapsed().as_secs_f64()));
    Ok(Analysis {
        width: w,
        height: h,
        mask,
        mask_computed,
        orient: om,
        traced,
        parting_cuts: cuts,
        parting_lines: lines,
        resolved,
        strokes: dir_strokes,
        background_strokes: strokes
            .strokes
            .iter()
            .filter(|s| s.kind == StrokeKind::Background)
            .map(|s| s.points.clone())
            .collect(),
        direction,
        warnings,
        timings,
    })
}
