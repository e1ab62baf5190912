//! Strand shading and hair recolouring (issue 5 item 3; C13 §4: "transform the hair color in
//! HSV space, or adjust the amount of synthetic highlights rendered using Marschner et al.'s
//! shading model [2003]").
//!
//! Per vertex, before rasterisation (the rasteriser interpolates the result):
//! ```text
//! base' = HSV-adjusted base colour            (only when hue/saturation/value are not identity)
//! out   = base' · (1 − diffuse + diffuse · Σ_k E_k cos θ_i,k) + amount · Σ_k E_k · spec_k
//! ```
//! clamped to [0, 1]; alpha passes through. `E_k` = light colour × intensity, θ_i the angle
//! between the light and the normal plane of the strand (cos θ_i = sin(t, l), the Kajiya-Kay
//! diffuse factor), `spec_k` = π cos θ_i · S_Marschner (R + TT + TRT) or the Kajiya-Kay
//! highlights; formulas and constants are documented in [`crate::stages::strand_shade`].
//!
//! **Units.** The base colours were sampled from the photo, so they already carry the photo's
//! lighting: a light of intensity 1 is taken as the one that lights a Lambertian fibre of
//! albedo `base` to radiance `base`, i.e. irradiance π, hence the π on the Marschner term.
//!
//! **amount 0** with `diffuse` 0 returns exactly `base'` (NaN channels → 0, others clamped to
//! [0, 1]); with identity HSV settings the HSV step is skipped, so a re-render at amount 0
//! reproduces the sampled photo colours bit for bit. `diffuse` (default 0) lets strands-only
//! renders of uncoloured models get a shape from the lights; under one white light along the
//! view direction it leaves strands in the image plane unchanged.
//!
//! **Spaces.** [`shade`] takes the lights in view space (x right, y up, z toward the camera,
//! as a `--light 0.3,0.6,1` option reads) and rotates them and the view direction into model
//! space with the camera; [`shade_model_space`] takes both already in model space.
//!
//! **HSV** is applied to the displayed colour: linear → sRGB encoding → HSV (hue shifted,
//! saturation and value scaled and clamped to [0, 1]) → RGB → linear, identically on the CPU
//! ([`hsv_adjust`]) and in the shader.

use crate::base::sentinel::SENTINEL;
use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::hair::head::WeakPerspective;
use crate::hair::strands::StrandSet;
use crate::stages::strand_shade::{self, Config, HAS_NEXT, HAS_PREV};
use glam::Vec3;

pub use crate::stages::strand_shade::{kajiya_kay, marschner_lobes, Lobes};
// Kept here for `crate::render`, which calls them as `shade::…`; they live in `base::colour`.

/// The highlight model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ShadingModel {
    /// Marschner et al. 2003 lobes R, TT, TRT with Karis 2016's azimuthal terms.
    #[default]
    Marschner,
    /// Kajiya-Kay 1989 with two shifted highlights (Scheuermann 2004); cheaper.
    KajiyaKay,
}

/// A directional light.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Light {
    /// Direction toward the light (need not be unit). View space for [`shade`]
    /// (x right, y up, z toward the camera), model space for [`shade_model_space`].
    pub dir: [f32; 3],
    /// Linear RGB colour.
    pub color: [f32; 3],
    /// Scales `color`; 1 = the light the photo's colours were taken under (see module doc).
    pub intensity: f32,
}

/// Default key light: upper right, in front (view space).
pub const DEFAULT_LIGHT_DIR: [f32; 3] = [0.3, 0.6, 1.0];

impl Default for Light {
    fn default() -> Self {
        Light {
            dir: DEFAULT_LIGHT_DIR,
            color: [1.0; 3],
            intensity: 1.0,
        }
    }
}

impl std::str::FromStr for Light {
    type Err = Error;
    /// `x,y,z`, `x,y,z,intensity` or `x,y,z,intensity,r,g,b` (a command-line `--light`).
    fn from_str(s: &str) -> Result<Light> {
        let v: Vec<f32> = s
            .split(',')
            .map(|x| x.trim().parse::<f32>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|e| Error::Invalid(format!("light {s:?}: {e}")))?;
        let light = match v.len() {
            3 | 4 | 7 => Light {
                dir: [v[0], v[1], v[2]],
                intensity: v.get(3).copied().unwrap_or(1.0),
                color: if v.len() == 7 {
                    [v[4], v[5], v[6]]
                } else {
                    [1.0; 3]
                },
            },
            n => {
                return Err(Error::Invalid(format!(
                    "light {s:?}: expected x,y,z[,intensity[,r,g,b]], got {n} numbers"
                )))
            }
        };
        light.validate()?;
        Ok(light)
    }
}

impl Light {
    /// A finite non-zero direction, finite non-negative colour and intensity.
    pub fn validate(&self) -> Result<()> {
        let d = Vec3::from(self.dir);
        if !d.is_finite() || d.length_squared() < 1e-12 {
            return Err(Error::Invalid(format!(
                "light direction {:?} must be finite and non-zero",
                self.dir
            )));
        }
        let ok = |x: f32| x.is_finite() && x >= 0.0;
        if !self.color.iter().all(|&c| ok(c)) || !ok(self.intensity) {
            return Err(Error::Invalid(format!(
                "light colour {:?} and intensity {} must be finite and >= 0",
                self.color, self.intensity
            )));
        }
        Ok(())
    }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ShadeParams {
    pub model: ShadingModel,
    /// Scales the highlights only, in [0, ∞). 0 (default) keeps the photo colours, which
    /// already hold the photo's own highlights; 0.6 is a moderate synthetic highlight.
    pub amount: f32,
    /// Weight in [0, 1] of the diffuse factor Σ E cos θ_i on the base colour (0 = none).
    pub diffuse: f32,
    pub lights: Vec<Light>,
    /// Hue shift, degrees (any value, taken mod 360).
    pub hue: f32,
    /// Saturation scale, >= 0 (result clamped to 1).
    pub saturation: f32,
    /// Value scale, >= 0 (result clamped to 1).
    pub value: f32,
    /// Longitudinal shift α_R of the R lobe, degrees; Marschner 2003 Table 1 gives −10..−5.
    /// The TT and TRT lobes sit at −α_R/2 and −3α_R/2 (Kajiya-Kay: the secondary highlight).
    pub alpha_r_deg: f32,
    /// Longitudinal width β_R of the R lobe, degrees; Table 1: 5..10. TT: β_R/2, TRT: 2β_R.
    pub beta_r_deg: f32,
}

impl Default for ShadeParams {
    fn default() -> Self {
        ShadeParams {
            model: ShadingModel::Marschner,
            amount: 0.0,
            diffuse: 0.0,
            lights: vec![Light::default()],
            hue: 0.0,
            saturation: 1.0,
            value: 1.0,
            alpha_r_deg: -7.5,
            beta_r_deg: 7.5,
        }
    }
}

impl ShadeParams {
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str, v: f32| Err(Error::Invalid(format!("shading {what} is {v}")));
        if !(self.amount.is_finite() && self.amount >= 0.0) {
            return bad("amount (must be finite and >= 0)", self.amount);
        }
        if !(0.0..=1.0).contains(&self.diffuse) {
            return bad("diffuse weight (must be in [0, 1])", self.diffuse);
        }
        if !self.hue.is_finite() {
            return bad("hue shift (must be finite)", self.hue);
        }
        if !(self.saturation.is_finite() && self.saturation >= 0.0) {
            return bad(
                "saturation scale (must be finite and >= 0)",
                self.saturation,
            );
        }
        if !(self.value.is_finite() && self.value >= 0.0) {
            return bad("value scale (must be finite and >= 0)", self.value);
        }
        if !(self.alpha_r_deg.is_finite() && self.alpha_r_deg.abs() <= 30.0) {
            return bad("alpha_r (degrees, |α| <= 30)", self.alpha_r_deg);
        }
        if !(self.beta_r_deg.is_finite() && (0.5..=45.0).contains(&self.beta_r_deg)) {
            return bad("beta_r (degrees, in [0.5, 45])", self.beta_r_deg);
        }
        self.lights.iter().try_for_each(Light::validate)
    }

    /// True when the HSV settings change nothing, so the shader skips the conversion.
    pub fn hsv_is_identity(&self) -> bool {
        self.hue.rem_euclid(360.0) == 0.0 && self.saturation == 1.0 && self.value == 1.0
    }
}

/// Direction toward the camera in model space: rᵀ·(0, 0, 1), the third row of r.
pub fn view_dir(cam: &WeakPerspective) -> Vec3 {
    cam.r.transpose() * Vec3::Z
}

/// A view-space direction (x right, y up, z toward the camera) in model space: rᵀ·d.
pub fn view_to_model(cam: &WeakPerspective, d: Vec3) -> Vec3 {
    cam.r.transpose() * d
}

/// Base colours for a strand set: its colours (or `default_rgb`) and alpha = 1 − transparency.
pub fn base_colours(set: &StrandSet, default_rgb: [f32; 3]) -> Vec<[f32; 4]> {
    (0..set.points.len())
        .map(|i| {
            let c = set.colors.as_ref().map_or(default_rgb, |c| c[i]);
            let a = set.transparency.as_ref().map_or(1.0, |t| 1.0 - t[i]);
            [c[0], c[1], c[2], a]
        })
        .collect()
}

/// Shades every vertex for the camera `cam`; `p.lights` are in view space.
pub fn shade(
    engine: &Engine,
    points: &[[f32; 3]],
    counts: &[u32],
    base: &[[f32; 4]],
    cam: &WeakPerspective,
    p: &ShadeParams,
) -> Result<Vec<[f32; 4]>> {
    cam.validate()?;
    p.validate()?;
    let lights = p
        .lights
        .iter()
        .map(|l| Light {
            dir: view_to_model(cam, Vec3::from(l.dir)).into(),
            ..*l
        })
        .collect();
    let pm = ShadeParams {
        lights,
        ..p.clone()
    };
    shade_model_space(engine, points, counts, base, view_dir(cam).into(), &pm)
}

/// Shades every vertex; `view_dir` (toward the camera) and `p.lights` are in model space.
/// `counts` are the vertices per strand (as in `StrandSet`); `base` is linear straight RGBA
/// per vertex. Returns linear straight RGBA per vertex, in [0, 1], never NaN.
pub fn shade_model_space(
    engine: &Engine,
    points: &[[f32; 3]],
    counts: &[u32],
    base: &[[f32; 4]],
    view_dir: [f32; 3],
    p: &ShadeParams,
) -> Result<Vec<[f32; 4]>> {
    p.validate()?;
    let total: u64 = counts.iter().map(|&c| u64::from(c)).sum();
    if total != points.len() as u64 {
        return Err(Error::Invalid(format!(
            "strand vertex counts sum to {total} but there are {} points",
            points.len()
        )));
    }
    if base.len() != points.len() {
        return Err(Error::Invalid(format!(
            "{} base colours for {} points",
            base.len(),
            points.len()
        )));
    }
    let v = Vec3::from(view_dir);
    if !v.is_finite() || v.length_squared() < 1e-12 {
        return Err(Error::Invalid(format!(
            "view direction {view_dir:?} must be finite and non-zero"
        )));
    }
    let v = v.normalize();
    let mut lights: Vec<[f32; 4]> = Vec::with_capacity(2 * p.lights.len().max(1));
    for l in &p.lights {
        let d = Vec3::from(l.dir).normalize();
        let e = Vec3::from(l.color) * l.intensity;
        lights.push([d.x, d.y, d.z, 0.0]);
        lights.push([e.x, e.y, e.z, 0.0]);
    }
    if lights.is_empty() {
        // A binding holds at least one element; n_lights = 0 keeps it unread.
        lights.resize(2, [0.0; 4]);
    }
    let recolour = !p.hsv_is_identity();
    let cfg = Config {
        n_lights: p.lights.len() as u32,
        model: match p.model {
            ShadingModel::Marschner => strand_shade::MODEL_MARSCHNER,
            ShadingModel::KajiyaKay => strand_shade::MODEL_KAJIYA_KAY,
        },
        amount: p.amount,
        diffuse: p.diffuse,
        recolour: recolour as u32,
        hue_deg: p.hue.rem_euclid(360.0),
        sat_scale: p.saturation,
        val_scale: p.value,
        alpha_r: p.alpha_r_deg.to_radians(),
        beta_r: p.beta_r_deg.to_radians(),
        view_x: v.x,
        view_y: v.y,
        view_z: v.z,
        ..Default::default()
    };
    let nbr = neighbour_flags(counts);
    let mut out = Vec::with_capacity(points.len());
    // Whole strands per run, so central differences never need a vertex from another run; the
    // largest per-vertex buffer (RGBA in and out) is 16 bytes.
    let max_vertices = (engine.max_binding_bytes() / 16).min(u32::MAX as u64) as usize;
    for (lo, hi) in strand_chunks(counts, max_vertices)? {
        out.extend(run_chunk(
            engine,
            &cfg,
            &points[lo..hi],
            &nbr[lo..hi],
            &base[lo..hi],
            &lights,
        )?);
    }
    Ok(out)
}

/// Per vertex: [`HAS_PREV`] unless first in its strand, [`HAS_NEXT`] unless last.
pub fn neighbour_flags(counts: &[u32]) -> Vec<u32> {
    let mut f = Vec::new();
    for &c in counts {
        for j in 0..c {
            f.push(if j > 0 { HAS_PREV } else { 0 } | if j + 1 < c { HAS_NEXT } else { 0 });
        }
    }
    f
}

/// Vertex ranges of consecutive whole strands, each at most `max_vertices` long.
fn strand_chunks(counts: &[u32], max_vertices: usize) -> Result<Vec<(usize, usize)>> {
    let mut chunks = Vec::new();
    let (mut lo, mut hi) = (0usize, 0usize);
    for (i, &c) in counts.iter().enumerate() {
        let c = c as usize;
        if c > max_vertices {
            return Err(Error::TooLarge {
                what: format!("strand {i} ({c} vertices) for shading"),
                needed: 16 * c as u64,
                limit: 16 * max_vertices as u64,
                limit_name: "largest buffer binding".into(),
                unit: "bytes",
            });
        }
        if hi - lo + c > max_vertices {
            chunks.push((lo, hi));
            lo = hi;
        }
        hi += c;
    }
    if hi > lo {
        chunks.push((lo, hi));
    }
    Ok(chunks)
}

fn run_chunk(
    engine: &Engine,
    cfg: &Config,
    points: &[[f32; 3]],
    nbr: &[u32],
    base: &[[f32; 4]],
    lights: &[[f32; 4]],
) -> Result<Vec<[f32; 4]>> {
    let n = points.len() as u32;
    let (wg, row_stride) = strand_shade::workgroups(n, 65535);
    let cfg = Config {
        n_vertices: n,
        row_stride,
        ..*cfg
    };
    let mut rec = Recording::default();
    let u = rec.uniform("coif.shade.cfg", &cfg);
    let pb = rec.upload("coif.shade.points", points);
    let nb = rec.upload("coif.shade.nbr", nbr);
    let bb = rec.upload("coif.shade.base", base);
    let lb = rec.upload("coif.shade.lights", lights);
    let ob = rec.alloc("coif.shade.out", 16 * n as u64, SENTINEL);
    rec.dispatch(&strand_shade::STAGE, wg, &[u, pb, nb, bb, lb, ob], &[]);
    rec.download(ob);
    Ok(engine.run(rec)?.get::<[f32; 4]>(ob))
}
