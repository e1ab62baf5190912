//! A sketch drawn as a cartoon (`coif cartoon`, CZ06 Fig. 17): one brush stroke per curve,
//! as a PNG through the rasteriser or as an SVG of Bézier outlines.

use super::Report;
use crate::gpu::engine::Engine;
use crate::io::outpath::{self, Format};
use crate::sketch::cartoon::{render, to_svg_with_backdrop, CartoonParams};
use crate::sketch::format;
use crate::timings::stage;
use anyhow::Context;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// `coif cartoon`: a sketch file to a PNG or an SVG (by the output's extension).
#[derive(Clone, Debug)]
pub struct CartoonJob {
    /// hair.czs, sketch.json or sketch.svg.
    pub sketch: PathBuf,
    /// .png or .svg.
    pub out: PathBuf,
    /// A photo of the sketch's size to draw over instead of white paper.
    pub over: Option<PathBuf>,
    pub params: CartoonParams,
}

/// How the SVG refers to the backdrop: by file name when both sit in one folder (the pair
/// can move together), else by absolute path.
fn href(over: &Path, out: &Path) -> String {
    let dir = |p: &Path| {
        p.parent()
            .map(|d| d.canonicalize().unwrap_or_else(|_| d.to_path_buf()))
    };
    match (dir(over), dir(out), over.file_name()) {
        (Some(a), Some(b), Some(name)) if a == b => name.to_string_lossy().into_owned(),
        _ => over
            .canonicalize()
            .unwrap_or_else(|_| over.to_path_buf())
            .display()
            .to_string(),
    }
}

pub(super) fn run_cartoon(engine: &Engine, j: &CartoonJob) -> anyhow::Result<Report> {
    let t0 = Instant::now();
    // Everything is checked before anything is drawn or written: the output's type, its
    // folder, and that it is not an input.
    let mut inputs = vec![j.sketch.as_path()];
    inputs.extend(j.over.as_deref());
    let kind = outpath::check(&j.out, &[Format::Png, Format::Jpeg, Format::Svg], &inputs)?;
    let read = stage("read");
    let s = format::load(&j.sketch)?;
    format::require_curves(&s, &j.sketch)?;
    let photo = super::sketch::load_backdrop(j.over.as_deref(), &s, &j.sketch)?;
    drop(read);
    let backend = match kind {
        Format::Png | Format::Jpeg => {
            let img = stage("draw")
                .run(|| render(engine, &s, &j.params, photo.as_ref()))
                .with_context(|| format!("drawing the cartoon of {}", j.sketch.display()))?;
            stage("write").run(|| super::sketch::write_image(&j.out, &img))?;
            engine.describe()
        }
        Format::Svg => {
            let h = j.over.as_deref().map(|o| href(o, &j.out));
            let text = stage("draw").run(|| to_svg_with_backdrop(&s, &j.params, h.as_deref()));
            stage("write").run(|| crate::io::write_atomic(&j.out, text.as_bytes()))?;
            "svg".to_string()
        }
    };
    Ok(Report {
        summary: format!(
            "cartoon: {} curves, {} style, width {} px, {}x{} -> {} ({:.2} s, {backend})",
            s.curves.len(),
            j.params.style.name(),
            j.params.width,
            s.width,
            s.height,
            j.out.display(),
            t0.elapsed().as_secs_f64()
        ),
        ..Default::default()
    })
}
