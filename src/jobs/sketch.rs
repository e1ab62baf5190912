//! The sketch model's jobs (`coif sketch`): inputs and the run that ties the command line
//! to `crate::sketch`.

use super::Report;
use crate::error::Error;
use crate::gpu::engine::Engine;
use crate::io::images;
use crate::io::outpath::Format;
use crate::sketch::run::{analyse, write, SketchInputs, SketchParams};
use crate::timings::{record_all, stage};
use anyhow::Context;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Where the hair region comes from.
#[derive(Clone, Debug)]
pub enum HairRegion {
    /// A mask image of the photo's size, > 127 on hair.
    Mask(PathBuf),
    /// Segmented from direction strokes (which also clamp the curves they run along).
    Strokes(PathBuf),
    /// Every pixel is hair (a crop of fur or hair).
    Whole,
}

/// A hair image to its sketch (`coif sketch`, CZ06 §4).
#[derive(Clone, Debug)]
pub struct SketchJob {
    pub image: PathBuf,
    pub region: HairRegion,
    /// Direction strokes that clamp directions without segmenting (with `--mask`).
    pub strokes: Option<PathBuf>,
    pub out: PathBuf,
    pub params: SketchParams,
}

pub(super) fn run_sketch(engine: &Engine, j: &SketchJob) -> anyhow::Result<Report> {
    let t0 = Instant::now();
    let read = stage("read");
    let photo = images::load_rgb(&j.image)?;
    let (w, h) = photo.dimensions();
    let n = w as usize * h as usize;
    let stroke_path = match &j.region {
        HairRegion::Strokes(s) => Some(s.clone()),
        _ => j.strokes.clone(),
    };
    let strokes = match &stroke_path {
        Some(s) => Some(crate::io::import::load_strokes(s, (w, h))?),
        None => None,
    };
    drop(read);
    let region = stage("hair_region");
    let hair: Vec<bool> = match &j.region {
        HairRegion::Mask(m) => images::load_mask(m, w, h, &j.image)?
            .into_iter()
            .map(|v| v != 0)
            .collect(),
        HairRegion::Strokes(s) => {
            let seg = crate::analyze::segment::segment(
                &photo,
                strokes.as_ref().expect("loaded above"),
                &Default::default(),
            )
            .with_context(|| {
                format!(
                    "segmenting the hair of {} from {}",
                    j.image.display(),
                    s.display()
                )
            })?;
            seg.as_raw().iter().map(|&v| v > 127).collect()
        }
        HairRegion::Whole => vec![true; n],
    };
    if !hair.iter().any(|&m| m) {
        let what = match &j.region {
            HairRegion::Mask(m) => m.display().to_string(),
            HairRegion::Strokes(s) => format!("the segmentation from {}", s.display()),
            HairRegion::Whole => j.image.display().to_string(),
        };
        return Err(
            Error::Invalid(format!("{what}: the hair mask is empty, nothing to sketch")).into(),
        );
    }
    let gray_span = {
        let mut lo = u8::MAX;
        let mut hi = 0u8;
        for (p, &m) in photo.pixels().zip(&hair) {
            if m {
                let l = p[0].max(p[1]).max(p[2]);
                lo = lo.min(l);
                hi = hi.max(l);
            }
        }
        hi.saturating_sub(lo)
    };
    if gray_span < 4 {
        return Err(Error::bad_file(
            &j.image,
            "the hair region is uniform (no texture to sketch)",
        )
        .into());
    }
    drop(region);
    let inp = SketchInputs {
        image: &photo,
        hair: &hair,
        strokes: strokes.as_ref(),
    };
    let r = analyse(engine, &inp, &j.params)
        .with_context(|| format!("sketching {}", j.image.display()))?;
    let extra = json!({
        "image": j.image,
        "backend": engine.describe(),
        "hair_pixels": hair.iter().filter(|&&m| m).count(),
        "method": j.params.method.name(),
        "crown": j.params.swc.prior.crown.name(),
        "prior_weight": j.params.swc.prior.kappa,
        "seed": j.params.seed,
    });
    record_all(&r.seconds);
    stage("write").run(|| write(&j.out, &photo, &r, extra))?;
    let sizes = crate::sketch::format::czs_sizes(&r.sketch);
    let mut details = stage_lines(&r.seconds);
    let mut warnings = Vec::new();
    if let Some(f) = &r.fill_target {
        if !f.met {
            warnings.push(format!(
                "{}: the fill strays {:.2}° from the dense field, over the {}° target, even \
                 with the curve penalty at {} (kept: the closest)",
                j.image.display(),
                r.fill_error.0,
                f.target_deg,
                f.lambda_nc
            ));
        } else if f.tries.len() > 1 {
            details.push(format!(
                "curve penalty lowered to {} to bring the fill within {}° of the dense field \
                 ({:.2}°; {} analyses)",
                f.lambda_nc,
                f.target_deg,
                r.fill_error.0,
                f.tries.len()
            ));
        }
    }
    if let Some(b) = &r.budget {
        if !b.met {
            warnings.push(format!(
                "{}: hair.czs is {} B, over the {} B target: not even a sketch without curves \
                 fits it (the region, shading and colour map); kept as pursued",
                j.image.display(),
                sizes.total,
                b.max_bytes
            ));
        } else if b.tries.len() > 1 {
            details.push(format!(
                "primitive penalty raised to {} to fit {} B ({} pursuits)",
                b.lambda_b,
                b.max_bytes,
                b.tries.len()
            ));
        }
    }
    if let Some(t) = &r.sketch_target {
        if t.curves_kept < t.curves_pursued {
            details.push(format!(
                "{} of {} curves kept, the ones the fill needs most, to bring the sketch part \
                 within {} B{}",
                t.curves_kept,
                t.curves_pursued,
                t.target_bytes,
                if t.met {
                    ""
                } else {
                    " (not reached: the fill would pass its target)"
                }
            ));
        } else if !t.met {
            details.push(format!(
                "sketch part {} B, over the {} B target: no curve can go without the fill \
                 passing its target (rounds in report.json)",
                sizes.curves, t.target_bytes
            ));
        }
    }
    Ok(Report {
        summary: format!(
            "sketch: {} curves, {} B (.czs; sketch part {} B), fill {} -> {} ({:.1} s on {})",
            r.sketch.curves.len(),
            sizes.total,
            sizes.curves,
            if r.fill_error.1 > 0 {
                format!("{:.2}° from the dense field", r.fill_error.0)
            } else {
                "unscored (no hair 5 px inside the region)".into()
            },
            j.out.display(),
            t0.elapsed().as_secs_f64(),
            engine.describe()
        ),
        details,
        warnings,
    })
}

/// A sketch file converted to another of the three formats (`coif sketch-convert`): an
/// Inkscape-edited `sketch.svg` back to `.czs`, a `.czs` to readable JSON.
#[derive(Clone, Debug)]
pub struct SketchConvertJob {
    pub input: PathBuf,
    pub out: PathBuf,
}

pub(super) fn run_sketch_convert(j: &SketchConvertJob) -> anyhow::Result<Report> {
    let s = crate::sketch::format::load(&j.input)?;
    crate::sketch::format::save(&s, &j.out)?;
    let sizes = crate::sketch::format::czs_sizes(&s);
    Ok(Report {
        summary: format!(
            "sketch-convert: {} -> {} ({}x{}, {} curves, {} primitives, {} bases; {} B as .czs)",
            j.input.display(),
            j.out.display(),
            s.width,
            s.height,
            s.curves.len(),
            s.curves.iter().map(|c| c.prims.len()).sum::<usize>(),
            s.shading.bases.len(),
            sizes.total
        ),
        ..Default::default()
    })
}

/// A sketch back to a hair image (`coif synth-hair`, CZ06 §3).
#[derive(Clone, Debug)]
pub struct SynthHairJob {
    pub sketch: PathBuf,
    /// The image to write, `.png` or `.jpg`.
    pub out: PathBuf,
    /// A photo to composite the hair over.
    pub over: Option<PathBuf>,
    /// A folder for the layers (field and bands).
    pub layers: Option<PathBuf>,
    pub params: crate::sketch::synth::SynthParams,
}

/// Encodes `img` in the format `path`'s extension names (PNG or JPEG) and writes it
/// atomically.
pub(crate) fn write_image(path: &std::path::Path, img: &image::RgbImage) -> anyhow::Result<()> {
    let format = crate::io::outpath::check(path, &[Format::Png, Format::Jpeg], &[])?
        .image_format()
        .expect("a raster format");
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, format)
        .with_context(|| format!("encoding {}", path.display()))?;
    crate::io::write_atomic(path, bytes.get_ref())?;
    Ok(())
}

/// The photo a sketch's picture is drawn over: it must have the sketch's size.
pub(super) fn load_backdrop(
    over: Option<&std::path::Path>,
    s: &crate::sketch::Sketch,
    sketch: &std::path::Path,
) -> anyhow::Result<Option<image::RgbImage>> {
    let Some(p) = over else {
        return Ok(None);
    };
    let img = images::load_rgb(p)?;
    if img.dimensions() != (s.width, s.height) {
        return Err(Error::bad_file(
            p,
            format!(
                "the photo is {}x{} px but the sketch {} is {}x{}",
                img.width(),
                img.height(),
                sketch.display(),
                s.width,
                s.height
            ),
        )
        .into());
    }
    Ok(Some(img))
}

fn is_jpeg(p: &std::path::Path) -> bool {
    Format::of(p) == Some(Format::Jpeg)
}

pub(super) fn run_synth_hair(engine: &Engine, j: &SynthHairJob) -> anyhow::Result<Report> {
    let t0 = Instant::now();
    // The output is checked before any work: its type, its folder, not an input.
    let mut inputs = vec![j.sketch.as_path()];
    inputs.extend(j.over.as_deref());
    crate::io::outpath::check(&j.out, &[Format::Png, Format::Jpeg], &inputs)?;
    let read = stage("read");
    let s = crate::sketch::format::load(&j.sketch)?;
    crate::sketch::format::require_curves(&s, &j.sketch)?;
    super::memory::check_synth_hair(engine, &j.sketch, s.width, s.height)?;
    let over = load_backdrop(j.over.as_deref(), &s, &j.sketch)?;
    drop(read);
    let r = crate::sketch::synth::synthesise(engine, &s, over.as_ref(), &j.params)
        .with_context(|| format!("synthesising hair from {}", j.sketch.display()))?;
    record_all(&r.seconds);
    let _write = stage("write");
    if let Some(dir) = &j.layers {
        use crate::io::npy;
        crate::io::ensure_dir(dir)?;
        let (w, h) = (s.width as usize, s.height as usize);
        npy::write_f32(&dir.join("theta.npy"), &[h, w], &r.field.theta)?;
        let vector: Vec<f32> = r.field.dir.iter().flat_map(|d| [d[0], d[1]]).collect();
        npy::write_f32(&dir.join("vector.npy"), &[h, w, 2], &vector)?;
        npy::write_f32(&dir.join("rho.npy"), &[h, w], &r.field.rho)?;
        npy::write_f32(&dir.join("low.npy"), &[h, w], &r.low)?;
        npy::write_f32(&dir.join("high.npy"), &[h, w], &r.high)?;
        let backdrop = crate::io::vis::dimmed(&r.image, 0.45);
        crate::io::write_png(
            &dir.join("field.png"),
            &crate::sketch::vis::field_picture(&backdrop, &r.field),
        )?;
    }
    if j.over.is_none() && !is_jpeg(&j.out) {
        // Hair on a transparent card (its colour under alpha 0), ready to composite.
        let w = s.width;
        let rgba = image::RgbaImage::from_fn(w, s.height, |x, y| {
            let p = r.image.get_pixel(x, y);
            let a = if r.hair[(y * w + x) as usize] { 255 } else { 0 };
            image::Rgba([p[0], p[1], p[2], a])
        });
        crate::io::write_png(&j.out, &rgba)?;
    } else if j.over.is_none() {
        // JPEG has no alpha: the hair on white paper.
        let w = s.width;
        let paper = image::RgbImage::from_fn(w, s.height, |x, y| {
            if r.hair[(y * w + x) as usize] {
                *r.image.get_pixel(x, y)
            } else {
                image::Rgb([255, 255, 255])
            }
        });
        write_image(&j.out, &paper)?;
    } else {
        write_image(&j.out, &r.image)?;
    }
    Ok(Report {
        summary: format!(
            "synth-hair: {} ({}x{}, {} curves, seed {}) -> {} ({:.1} s on {})",
            j.sketch.display(),
            s.width,
            s.height,
            s.curves.len(),
            j.params.seed.unwrap_or(s.seed),
            j.out.display(),
            t0.elapsed().as_secs_f64(),
            engine.describe()
        ),
        details: stage_lines(&r.seconds)
            .into_iter()
            .chain(grain_line(&s, j.params.grain, r.grain.as_ref()))
            .collect(),
        warnings: Vec::new(),
    })
}

/// What the grain did, for the report.
fn grain_line(
    s: &crate::sketch::Sketch,
    on: bool,
    g: Option<&crate::sketch::texture::Grain>,
) -> Option<String> {
    Some(match (s.along_across, g) {
        (_, Some(g)) => format!(
            "grain: along/across {:.4} -> {:.4} (the sketch's {:.4})",
            g.before, g.after, g.target
        ),
        (Some(t), None) if on => format!(
            "grain: none needed (the band's along/across already reaches the sketch's {t:.4})"
        ),
        (Some(_), None) => "grain: off (--no-grain)".into(),
        (None, _) => "grain: none (the sketch stores no along/across ratio)".into(),
    })
}

/// One report line per stage: its name and seconds.
fn stage_lines(seconds: &[(&'static str, f64)]) -> Vec<String> {
    seconds
        .iter()
        .map(|(k, s)| format!("{k:<16} {s:.2} s"))
        .collect()
}
