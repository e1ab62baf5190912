//! The files `coif orient` and `coif analyze` write, and the inputs they read. Every output
//! is computed before the first file is written, and each file is written to a temporary
//! name and renamed (see [`crate::io::write_atomic`]).

use crate::analyze::orient::{orient, GrayImage, OrientMap, OrientParams};
use crate::analyze::{analyze, Analysis, AnalyzeParams};
use crate::error::{Error, Result};
use crate::gpu::engine::Engine;
use crate::io::{
    ensure_dir, images, import, npy, seconds, vis, write_atomic, write_json, write_png,
};
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// The photo and its optional mask (1 on hair), checked against each other and against the
/// Gabor kernel size.
pub fn load_photo(
    image: &Path,
    mask: Option<&Path>,
    ksize: u32,
) -> Result<(image::RgbImage, Option<Vec<u8>>)> {
    let rgb = images::load_rgb(image)?;
    if rgb.width() < ksize || rgb.height() < ksize {
        return Err(Error::bad_file(
            image,
            format!(
                "image is {}x{} px, smaller than the {ksize}x{ksize} Gabor kernel",
                rgb.width(),
                rgb.height()
            ),
        ));
    }
    let m = match mask {
        Some(m) => Some(images::load_mask(m, rgb.width(), rgb.height(), image)?),
        None => None,
    };
    Ok((rgb, m))
}

/// Everything `coif orient` writes, computed before anything is written.
pub struct OrientRun {
    pub map: OrientMap,
    pub params: OrientParams,
    pub backend: String,
    pub seconds: f64,
}

/// The orientation stage on an image file (and its optional mask).
pub fn run_orient(
    engine: &Engine,
    image: &Path,
    mask: Option<&Path>,
    params: &OrientParams,
) -> anyhow::Result<OrientRun> {
    use anyhow::Context;
    let stage = crate::timings::stage("read");
    let (rgb, mask_px) = load_photo(image, mask, params.kernel.ksize)?;
    let gray = GrayImage::from_rgb(&rgb);
    drop(stage);
    // Only the gray image is needed from here: the colour copy would stay for the whole run.
    drop(rgb);
    let t = Instant::now();
    let _s = crate::timings::stage("orientation");
    let map = orient(engine, &gray, mask_px.as_deref(), params)
        .with_context(|| format!("orientation of {}", image.display()))?;
    Ok(OrientRun {
        map,
        params: *params,
        backend: engine.describe(),
        seconds: t.elapsed().as_secs_f64(),
    })
}

/// `orientation.npy`, `confidence.npy`, their pictures and `orient.json`.
pub fn write_orient(out: &Path, image: &Path, r: &OrientRun) -> Result<()> {
    ensure_dir(out)?;
    let (w, h) = (r.map.width, r.map.height);
    let shape = [h as usize, w as usize];
    npy::write_f32(&out.join("orientation.npy"), &shape, &r.map.theta)?;
    npy::write_f32(&out.join("confidence.npy"), &shape, &r.map.confidence)?;
    write_png(
        &out.join("orientation.png"),
        &vis::orientation(w, h, &r.map.theta, &r.map.confidence),
    )?;
    write_png(
        &out.join("confidence.png"),
        &vis::confidence(w, h, &r.map.confidence),
    )?;
    let meta = json!({
        "version": 1,
        "coif": env!("CARGO_PKG_VERSION"),
        "image": image.display().to_string(),
        "backend": r.backend,
        "params": r.params,
        "seconds": r.seconds,
        "orientation": "radians in [0, pi), x right, y down; NaN off the mask",
        // Where the field carries a whorl's spiral (`singular`): θ = φ + twist about the
        // centre (px, pixel centres at +0.5).
        "whorls": r.map.whorls.iter().map(|w| json!({
            "centre": w.centre,
            "twist_deg": w.twist.to_degrees(),
            "ring_residual_deg": w.residual_deg,
        })).collect::<Vec<_>>(),
    });
    write_json(&out.join("orient.json"), &meta)
}

/// The analysis of a photo file with a strokes file (`strokes.json`, labelme or SVG) and an
/// optional mask file.
pub fn run(
    engine: &Engine,
    image: &Path,
    strokes: &Path,
    mask: Option<&Path>,
    params: &AnalyzeParams,
) -> anyhow::Result<(image::RgbImage, Analysis)> {
    use anyhow::Context;
    let stage = crate::timings::stage("read");
    let (rgb, m) = load_photo(image, mask, params.orient.kernel.ksize)?;
    let s = import::load_strokes(strokes, rgb.dimensions())?;
    drop(stage);
    let an = analyze(engine, &rgb, &s, m, params)
        .with_context(|| format!("analysis of {} with {}", image.display(), strokes.display()))?;
    for w in &an.warnings {
        log::warn!("{w}");
    }
    Ok((rgb, an))
}

/// `mask.png` and `mask_overlay.png`, the orientation, `direction.npy`, `curves.json`, the
/// curve and direction pictures and `analyze.json`.
pub fn write(
    out: &Path,
    image: &Path,
    rgb: &image::RgbImage,
    an: &Analysis,
    params: &AnalyzeParams,
    backend: &str,
) -> Result<()> {
    ensure_dir(out)?;
    let (w, h) = (an.width, an.height);
    let shape = [h as usize, w as usize];
    write_png(&out.join("mask.png"), &an.mask_image())?;
    write_png(
        &out.join("mask_overlay.png"),
        &vis::mask_overlay(rgb, &an.mask, &an.strokes, &an.background_strokes),
    )?;
    npy::write_f32(&out.join("orientation.npy"), &shape, &an.orient.theta)?;
    npy::write_f32(&out.join("confidence.npy"), &shape, &an.orient.confidence)?;
    npy::write_f32(
        &out.join("direction.npy"),
        &[h as usize, w as usize, 2],
        &an.direction,
    )?;
    let mut curves: Vec<serde_json::Value> = an
        .resolved
        .curves
        .iter()
        .map(|c| json!({"points": c.points, "source": "traced"}))
        .collect();
    curves.extend(
        an.strokes
            .iter()
            .map(|s| json!({"points": s, "source": "stroke"})),
    );
    let doc = json!({"version": 1, "curves": curves});
    let text = serde_json::to_string(&doc).map_err(|e| Error::Invalid(e.to_string()))?;
    write_atomic(&out.join("curves.json"), text.as_bytes())?;
    let back = vis::dimmed(rgb, 0.55);
    let before: Vec<&[[f32; 2]]> = an.traced.iter().map(|c| c.points.as_slice()).collect();
    let after: Vec<&[[f32; 2]]> = an
        .resolved
        .curves
        .iter()
        .map(|c| c.points.as_slice())
        .collect();
    write_png(
        &out.join("curves_before.png"),
        &vis::directed_curves(&back, &before, 1.5),
    )?;
    let mut after_img = vis::directed_curves(&back, &after, 1.5);
    for s in &an.strokes {
        vis::draw_polyline(&mut after_img, s, 4.0, |_| image::Rgb([255, 255, 255]));
    }
    let sdraw: Vec<&[[f32; 2]]> = an.strokes.iter().map(|s| s.as_slice()).collect();
    let mut after_img = vis::directed_curves(&after_img, &sdraw, 2.0);
    // Partings as white lines edged in black, which no direction hue is.
    for l in &an.parting_lines {
        let ends = l.ends();
        vis::draw_polyline(&mut after_img, &ends, 3.0, |_| image::Rgb([0, 0, 0]));
        vis::draw_polyline(&mut after_img, &ends, 1.0, |_| image::Rgb([255, 255, 255]));
    }
    write_png(&out.join("curves_after.png"), &after_img)?;
    write_png(
        &out.join("direction.png"),
        &vis::direction_field(&back, &an.direction),
    )?;
    write_png(
        &out.join("orientation.png"),
        &vis::orientation(w, h, &an.orient.theta, &an.orient.confidence),
    )?;
    let meta = json!({
        "version": 1,
        "coif": env!("CARGO_PKG_VERSION"),
        "image": image.display().to_string(),
        "backend": backend,
        // What a rerun needs (the segmentation's, the orientation's, the vote's, ...).
        "params": params,
        "mask": if an.mask_computed { "segmented from the strokes" } else { "given" },
        "curves": an.traced.len(),
        "parting_cuts": an.parting_cuts.len(),
        "partings": an.parting_lines.iter().map(|l| json!({
            "ends": l.ends(),
            "cuts": l.cuts,
        })).collect::<Vec<_>>(),
        "unreachable_curves": an.resolved.unreachable.len(),
        "warnings": an.warnings,
        "seconds": seconds(&an.timings),
        "direction": "unit growth direction, H x W x 2, x right, y down, NaN off hair",
    });
    write_json(&out.join("analyze.json"), &meta)
}

/// `mask_agreement.json` and `mask_vs_reference.png`: the analysis's mask scored against a
/// reference mask (`coif analyze --reference-mask`); returns the figures.
pub fn write_agreement(
    out: &Path,
    rgb: &image::RgbImage,
    an: &Analysis,
    reference: &image::GrayImage,
    reference_path: &Path,
) -> Result<crate::eval::mask::MaskAgreement> {
    use crate::eval::mask::{agreement, disagreement_picture};
    let mask = an.mask_image();
    let a = agreement(&mask, reference);
    write_png(
        &out.join("mask_vs_reference.png"),
        &disagreement_picture(rgb, &mask, reference),
    )?;
    let doc = json!({
        "version": 1,
        "reference": reference_path.display().to_string(),
        "mask": if an.mask_computed { "segmented from the strokes" } else { "given" },
        "agreement": a,
        "picture": "mask_vs_reference.png: agreed hair green, missed hair red, taken non-hair blue",
    });
    write_json(&out.join("mask_agreement.json"), &doc)?;
    Ok(a)
}
