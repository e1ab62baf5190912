//! `coif synth-hair`: a sketch back to a hair image (CZ06 §3), from the sketch file alone.
//!
//! Order: the hair region from the sketch's outline → V = (Θ, ρ, d) filled in from the
//! curves (Eq. 14-17, `fill`) → the high band synthesised along V (§3.2, `texture`), with
//! grain up to the sketch's along/across ratio when it stores one (`texture::add_grain`) → the
//! low band from the shading bases (Eq. 1) → I_Y = I_L + I_H → the colour map from gray to
//! (u, v) → sRGB, composited over a photo when one is given.
//!
//! The noise draws come from the sketch's seed (or the one given), so a sketch and a seed
//! give the same image bit for bit on one backend; another seed gives a "different but
//! similar" image (CZ06 §3.2).

use super::{fill, prim, region, texture, Sketch, VectorField};
use crate::error::{Error, Result};
use crate::gpu::engine::Engine;
use image::RgbImage;
use std::time::Instant;

/// Every setting of the synthesis.
#[derive(Clone, Debug)]
pub struct SynthParams {
    pub fill: fill::FillParams,
    pub texture: texture::TextureParams,
    /// Seed of the draws (ρ off the sketch, texture noise); None = the sketch's own.
    pub seed: Option<u64>,
    /// Add grain up to the sketch's along/across ratio (`texture::add_grain`); false: the
    /// band as line-integral convolution leaves it.
    pub grain: bool,
}

impl Default for SynthParams {
    fn default() -> Self {
        SynthParams {
            fill: Default::default(),
            texture: Default::default(),
            seed: None,
            grain: true,
        }
    }
}

/// What the synthesis made.
pub struct Synthesis {
    /// Hair pixels (the sketch's region).
    pub hair: Vec<bool>,
    pub field: VectorField,
    /// The low band I_L (L*), W*H.
    pub low: Vec<f32>,
    /// The high band I_H (L*, zero mean over the hair), W*H.
    pub high: Vec<f32>,
    /// I_Y = I_L + I_H clamped to [0, 100] on the hair; the low band's mean elsewhere.
    pub gray: Vec<f32>,
    /// The coloured image: hair through the colour map, the rest from `over` or, without
    /// one, the hair's mean colour.
    pub image: RgbImage,
    /// The grain added to the high band, if any.
    pub grain: Option<texture::Grain>,
    pub seconds: Vec<(&'static str, f64)>,
}

/// Synthesises the hair image of `s`, over `over` (the sketch's size) when given.
pub fn synthesise(
    engine: &Engine,
    s: &Sketch,
    over: Option<&RgbImage>,
    p: &SynthParams,
) -> Result<Synthesis> {
    let (w, h) = (s.width, s.height);
    if s.curves.is_empty() {
        return Err(Error::Invalid(
            "the sketch has no curves: there is no field to synthesise hair along".into(),
        ));
    }
    if let Some(o) = over {
        if o.dimensions() != (w, h) {
            return Err(Error::Invalid(format!(
                "the photo is {}x{}, the sketch {w}x{h}",
                o.width(),
                o.height()
            )));
        }
    }
    let seed = p.seed.unwrap_or(s.seed);
    let mut seconds = Vec::new();
    let mut t = Instant::now();
    let mut lap = |name: &'static str, t: &mut Instant| {
        seconds.push((name, t.elapsed().as_secs_f64()));
        *t = Instant::now();
    };
    let hair = region::fill(&s.region, w, h);
    if !hair.iter().any(|&m| m) {
        return Err(Error::Invalid(
            "the sketch's hair region covers no pixel centre".into(),
        ));
    }
    let painted = prim::paint(&s.curves, w, h, Some(&hair));
    if painted.theta.iter().all(|t| t.is_nan()) {
        return Err(Error::Invalid(
            "no curve of the sketch lies inside its hair region".into(),
        ));
    }
    let field = fill::fill(engine, &painted, &hair, &s.rho_off, seed, &p.fill)?;
    lap("fill", &mut t);
    let mut high = texture::synthesise(engine, &field, &hair, seed, &p.texture)?;
    let grain = match (p.grain, s.along_across) {
        (true, Some(t)) => texture::add_grain(&mut high, &field, &hair, seed, t),
        _ => None,
    };
    lap("texture", &mut t);
    let low = s.shading.render(w, h);
    let gray: Vec<f32> = (0..hair.len())
        .map(|i| {
            if hair[i] {
                (low[i] + high[i]).clamp(0.0, 100.0)
            } else {
                s.shading.mean
            }
        })
        .collect();
    // Without a photo, the hair's mean colour fills the rest: a neutral card that adds no
    // edge of its own along the region's outline (`coif synth-hair` marks it transparent).
    let card = image::Rgb(s.colour.to_rgb(s.shading.mean));
    let image = RgbImage::from_fn(w, h, |x, y| {
        let i = y as usize * w as usize + x as usize;
        if hair[i] {
            image::Rgb(s.colour.to_rgb(gray[i]))
        } else {
            match over {
                Some(o) => *o.get_pixel(x, y),
                None => card,
            }
        }
    });
    lap("colour", &mut t);
    Ok(Synthesis {
        hair,
        field,
        low,
        high,
        gray,
        image,
        grain,
        seconds,
    })
}
