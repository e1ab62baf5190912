//! The files `coif model` writes beside the analysis: the scene (`strands.hair`,
//! `photo.png`, `mask.png`, `model.json` with the modelling figures) and `preview.png`.

use crate::analyze;
use crate::error::Result;
use crate::gpu::engine::Engine;
use crate::io::annot::Landmarks;
use crate::io::{seconds, vis, write_png};
use crate::model::{figures, model_from_analysis, Model, ModelParams};
use serde_json::json;
use std::path::Path;

/// Analysis and model of a photo file with strokes, an optional mask and optional
/// landmarks; the analysis is returned too, written or not.
pub fn run(
    engine: &Engine,
    image: &Path,
    strokes: &Path,
    mask: Option<&Path>,
    landmarks: Option<&Path>,
    p: &ModelParams,
) -> anyhow::Result<(image::RgbImage, Model)> {
    use anyhow::Context;
    let (rgb, an) = analyze::run(engine, image, strokes, mask, &p.analyze)?;
    let lm = match landmarks {
        Some(l) => {
            let _s = crate::timings::stage("read");
            Some(Landmarks::load(l, Some(rgb.dimensions()))?)
        }
        None => None,
    };
    let m = model_from_analysis(engine, &rgb, an, lm.as_ref(), p)
        .with_context(|| format!("3D model of {}", image.display()))?;
    Ok((rgb, m))
}

/// Writes the analysis (see [`analyze::write`]) and the model to `out`.
pub fn write(
    out: &Path,
    image: &Path,
    rgb: &image::RgbImage,
    m: &Model,
    p: &ModelParams,
    backend: &str,
) -> Result<()> {
    analyze::write(out, image, rgb, &m.analysis, &p.analyze, backend)?;
    let figures = figures(m);
    let extra = json!({
        "image": image.display().to_string(),
        "head": { "fit": m.fit },
        "grid": m.grid,
        "h_cells": m.h_cells,
        "constraints": { "curves": m.constraints_curve, "scalp": m.constraints_scalp },
        "field_solve": m.solve,
        "roots": { "drawn": m.roots_drawn, "on_hair": m.roots_kept },
        "strands": { "grown": m.grown_strands },
        "refinement": m.refine,
        "figures": figures,
        "params": p,
        "backend": backend,
        "seconds": seconds(&m.timings),
    });
    m.scene(rgb, out).save(out, extra)?;
    write_png(&out.join("preview.png"), &preview(rgb, m))
}

/// Strands projected over the dimmed photo, coloured by their projected growth direction
/// (the hue ring of the analysis pictures); a subset keeps it legible.
pub fn preview(rgb: &image::RgbImage, m: &Model) -> image::RgbImage {
    let mut pic = vis::dimmed(rgb, 0.35);
    let view = &m.strands_image;
    let off = view.offsets();
    let strand = |i: usize| &view.points[off[i]..off[i + 1]];
    // Far strands first, so nearer ones cover them (painter's order on mean depth).
    let every = (view.len() / 6000).max(1);
    let mut order: Vec<(f32, usize)> = (0..view.len())
        .step_by(every)
        .map(|i| {
            let s = strand(i);
            (s.iter().map(|q| q[2]).sum::<f32>() / s.len() as f32, i)
        })
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    for s in order.iter().map(|&(_, i)| strand(i)) {
        let pts: Vec<[f32; 2]> = s.iter().map(|q| [q[0], q[1]]).collect();
        vis::draw_polyline(&mut pic, &pts, 1.0, |k| {
            vis::direction_colour(pts[k + 1][0] - pts[k][0], pts[k + 1][1] - pts[k][1])
        });
    }
    vis::hue_ring(&mut pic);
    pic
}
