//! `coif sketch`: a hair image to its sketch, vector field and bands (CZ06 §4), and the
//! files a user keeps and looks at.
//!
//! Order: bands and colour map → a warm Θ from coif's Gabor filters → sketch pursuit
//! (Step 1: Θ and the undirected curves) → directions by Swendsen-Wang cuts (Step 2) →
//! shading bases → the sketch quantised to what the files store → V filled in from that
//! sketch alone (what synthesis will see) → files.

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
}

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
    let hair_px = inp.hair.iter().filter(|&&m| m).count();
    if hair_px == 0 {
        return Err(Error::Invalid(
            "the hair mask is empty: no hair to sketch".into(),
        ));
    }
    let mut seconds = Vec::new();
    let mut t = Instant::now();
    let mut lap = |name: &'static str, t: &mut Instant| {
        seconds.push((name, t.elapsed().as_secs_f64()));
        *t = Instant::now();
    };

    let b = bands::bands(engine, inp.image, inp.hair, p.sigma_l)?;
    let colour = super::ColourMap::fit(&b, inp.hair);
    lap("bands", &mut t);

    let gray = GrayImage::from_rgb(inp.image);
    let mask8: Vec<u8> = inp.hair.iter().map(|&m| m as u8).collect();
    let warm = orient(engine, &gray, Some(&mask8), &OrientParams::default())?;
    lap("gabor", &mut t);

    let high = GrayImage {
        width: w,
        height: h,
        data: b.high.clone(),
    };
    let pu = pursuit::pursue(engine, &high, inp.hair, &warm.theta, &p.pursuit)?;
    lap("pursuit", &mut t);

    let clamps = match inp.strokes {
        Some(s) => swc::stroke_clamps(&pu.curves, s, inp.hair, w, h),
        None => Vec::new(),
    };
    let directed = swc::directions(
        &pu.curves, &pu.theta, inp.hair, w, h, &clamps, &p.swc, p.method,
    )?;
    lap("directions", &mut t);

    let shading = shading::fit(&b.low, inp.hair, w, h, p.bases);
    lap("shading", &mut t);

    let sketch = format::quantise(&Sketch {
        width: w,
        height: h,
        seed: p.seed,
        curves: directed.curves.clone(),
        rho_off: pu.rho_off,
        shading,
        colour,
        region: super::region::outline(inp.hair, w, h, &p.outline),
    });
    let painted = super::prim::paint(&sketch.curves, w, h, Some(inp.hair));
    let field = fill::fill(engine, &painted, inp.hair, &sketch.rho_off, p.seed, &p.fill)?;
    lap("fill", &mut t);

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
    })
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
    });
    if let (Some(o), Some(e)) = (report.as_object_mut(), extra.as_object()) {
        for (k, v) in e {
            o.insert(k.clone(), v.clone());
        }
    }
    write_json(&out.join("report.json"), &report)?;
    Ok(())
}
