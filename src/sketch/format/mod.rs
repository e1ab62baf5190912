//! The sketch's three files: `hair.czs` (bit-packed, a few hundred bytes), `sketch.json`
//! (the same content readable, checked against `schemas/sketch.v1.schema.json`) and
//! `sketch.svg` (one polyline per curve, an ellipse per shading base; opens in Inkscape and
//! the SVG stroke importer reads it).
//!
//! All three store the *quantised* sketch ([`quantise`]): every number sits on the lattice
//! `.czs` codes, and each reader snaps what it reads to that lattice and decodes it with the
//! same functions, so reading any of the three files gives the same [`Sketch`], bit for bit.
//!
//! The lattice (see [`quantise`] for the rules):
//! - curves: start rounded to whole pixels; axes on 24 steps of 15°, turning −1, 0 or +1
//!   step per primitive; each centre is the previous centre + [`STEP`] along the new
//!   primitive's axis, so centres are implicit;
//! - side angles: the dictionary {0, 60°, 90°, 120°}, plus, when any side needs it, a
//!   refinement (k − 8)·3.75°, k in 0..16 (−30° to +26.25°);
//! - ρ: 0 or 0.5·2^(4(k−1)/7), k in 1..16 (0.5 to 128);
//! - p_nsk: the first weight in 1/255 (the second is 1 minus it), means and σs on a
//!   log scale of 2^(1/16) steps from 2^−6 to ~940 (and 0);
//! - shading: μ in 100/1023 steps; bases on the lattice of [`super::shading`], amplitudes
//!   in steps of 0.5 from −64 to 63.5;
//! - colour map: u* and v* on a grid of 2 units from −32 to 94, 6-bit codes.
//!
//! Packing, light sequential work over a few hundred bytes: CPU.

use super::shading::{block_centre, theta_of, COARSE, SIGMAS, THETAS};
use super::{
    Base, ColourMap, Curve, Kind, Primitive, RhoPrior, Shading, Sketch, AXIS_QUANTUM, AXIS_STEPS,
    COLOUR_BINS, STEP,
};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::path::Path;

pub use order::paint_order;
pub use rate::{
    rate_rho, rate_shifts, rate_sides, side_sums, RhoStats, SHIFT_CODES, SHIFT_QUANTUM,
    SHIFT_STEPS, SHIFT_ZERO,
};

mod czs;
mod czs_rc;
mod json;
mod order;
mod rate;
mod rc;
mod svg;
pub(crate) mod validate;
pub use czs::*;
pub use json::*;
pub use svg::*;
pub use validate::{require_curves, validate, MARGIN};

/// File magic of `.czs`.
pub const MAGIC: &[u8; 3] = b"CZS";
/// `.czs` and `sketch.json` format version: 2 adds the hair region, 3 the high band's
/// along/across ratio (`Sketch::along_across`), 4 the occluding lines' offsets off their
/// chains (`Primitive::shift`); version 1 to 3 files (no region: the whole image; no ratio: no
/// grain; no offsets: on the chains) are still read.
pub const VERSION: u8 = 4;
/// `.czs` container version: 3 range codes the curves (the sketch is that of [`VERSION`]),
/// 4 with richer contexts (the same fields), 5 the colour map and the region too, and the
/// curves sorted by start with their paint order as a bit per overlapping pair
/// ([`order`]), 6 the along/across ratio (one byte), 7 the occluding lines' offsets off their
/// chains (`Primitive::shift`); versions 1 to 6 are still read.
pub const CZS_VERSION: u8 = 7;
/// The JSON Schema `sketch.json` is checked against.
pub const SCHEMA: &str = include_str!("../../../schemas/sketch.v1.schema.json");
const SCHEMA_URL: &str = "urn:coif:sketch.v1.schema.json";

/// The side-angle dictionary of CZ06 §2.1, degrees.
pub const SIDE_DICTIONARY_DEG: [f64; 4] = [0.0, 60.0, 90.0, 120.0];
/// Step of the side refinement, degrees; offsets are (k − 8)·step, k in 0..16.
pub const SIDE_REFINE_STEP_DEG: f64 = 3.75;
/// ρ levels (code 0 is 0): 0.5·2^(4(k−1)/7).
pub const RHO_LEVELS: [f32; 16] = [
    0.0,
    0.5,
    0.742_997_15,
    1.104_089_5,
    1.640_670_7,
    2.438_027_3,
    3.622_894_7,
    5.383_600_7,
    8.0,
    11.887_954,
    17.665_432,
    26.250_73,
    39.008_44,
    57.966_315,
    86.137_61,
    128.0,
];
/// 2^(r/16), r in 0..16: the mantissas of the prior's log scale.
const LOG16: [f64; 16] = [
    1.0,
    1.044_273_782_427_413_8,
    1.090_507_732_665_257_7,
    1.138_788_634_756_691_6,
    1.189_207_115_002_721,
    1.241_857_812_073_484,
    1.296_839_554_651_009_6,
    1.354_255_546_936_892_7,
    std::f64::consts::SQRT_2,
    1.476_826_145_939_499_3,
    1.542_210_825_407_940_7,
    1.610_490_331_949_254_3,
    1.681_792_830_507_429,
    1.756_252_160_373_299_5,
    1.834_008_086_409_342_4,
    1.915_206_561_397_147_4,
];
/// Amplitude step of a shading base, L*.
pub const AMP_STEP: f32 = 0.5;
/// The colour map's chroma grid: u* and v* each CHROMA_LO + k·CHROMA_STEP, k in 0..64
/// (−32 to 94: hair from blue-black to red and blond; a fixed grid, so that snapping a
/// snapped map changes nothing).
pub const CHROMA_LO: f32 = -32.0;
pub const CHROMA_STEP: f32 = 2.0;

/// Bytes per part of a `.czs` file; the header is the rest (magic, version, length, size,
/// seed, flags, p_nsk, padding and checksum), so the parts add up to `total`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CzsSizes {
    pub header: usize,
    pub curves: usize,
    pub shading: usize,
    pub colour: usize,
    pub region: usize,
    pub total: usize,
    /// The range-coded part (colour map, region, curves) by what its bits code, in bytes
    /// to 0.1 (the information of each field under the adaptive model: where a sketch's
    /// bytes go, e.g. starts against side angles).
    pub fields: std::collections::BTreeMap<&'static str, f64>,
}

// ---------------------------------------------------------------------------------------
// The lattice: codes and their decoding.

/// cos(k·15°) from square roots (correctly rounded), so decoding gives the same bits on
/// every platform.
pub(crate) fn cos15(k: i64) -> f64 {
    let s6 = 6f64.sqrt();
    let s2 = 2f64.sqrt();
    let c = [
        1.0,
        (s6 + s2) / 4.0,
        3f64.sqrt() / 2.0,
        s2 / 2.0,
        0.5,
        (s6 - s2) / 4.0,
        0.0,
    ];
    let k = k.rem_euclid(24) as usize;
    match k {
        0..=6 => c[k],
        7..=12 => -c[12 - k],
        13..=18 => -c[k - 12],
        _ => c[24 - k],
    }
}

pub(crate) fn sin15(k: i64) -> f64 {
    cos15(6 - k)
}

fn axis_of(code: u8) -> f32 {
    code as f32 * AXIS_QUANTUM
}

fn side_deg(dict: u8, refine: u8) -> f64 {
    SIDE_DICTIONARY_DEG[dict as usize] + (refine as f64 - 8.0) * SIDE_REFINE_STEP_DEG
}

fn deg_to_rad(d: f64) -> f32 {
    (d * (PI / 180.0)) as f32
}

/// A side angle in radians from its dictionary index and refinement code, as decoded (the
/// pursuit builds its candidates with this, so they sit on the lattice exactly).
pub(crate) fn side_radians(dict: u8, refine: u8) -> f32 {
    deg_to_rad(side_deg(dict, refine))
}

/// (dictionary index, refinement code) nearest to `deg` (the nearest dictionary angle,
/// ties to the smaller; the refinement clamped to its range).
fn snap_side(deg: f64) -> (u8, u8) {
    let deg = if deg.is_finite() { deg } else { 0.0 };
    let mut best = 0;
    for (i, d) in SIDE_DICTIONARY_DEG.iter().enumerate() {
        if (deg - d).abs() < (deg - SIDE_DICTIONARY_DEG[best]).abs() {
            best = i;
        }
    }
    let r = ((deg - SIDE_DICTIONARY_DEG[best]) / SIDE_REFINE_STEP_DEG).round() + 8.0;
    (best as u8, r.clamp(0.0, 15.0) as u8)
}

fn snap_rho(rho: f32) -> u8 {
    if !(rho.is_finite() && rho >= 0.25) {
        return 0;
    }
    let l = rho.ln();
    (1..16u8)
        .min_by(|&a, &b| {
            let da = (l - RHO_LEVELS[a as usize].ln()).abs();
            let db = (l - RHO_LEVELS[b as usize].ln()).abs();
            da.total_cmp(&db)
        })
        .unwrap_or(0)
}

/// The prior's 8-bit log scale: 0 is 0, k ≥ 1 is 2^((k − 97)/16).
fn prior_value(code: u8) -> f32 {
    if code == 0 {
        return 0.0;
    }
    let e = code as i32 - 97;
    let (q, r) = (e.div_euclid(16), e.rem_euclid(16));
    (LOG16[r as usize] * 2f64.powi(q)) as f32
}

fn snap_prior(v: f32) -> u8 {
    if !(v.is_finite() && v > 0.0) {
        return 0;
    }
    let k = (16.0 * (v as f64).log2()).round() + 97.0;
    if k < 1.0 {
        // Below 2^−6.03: nearer 0 than the first level?
        return if (v as f64) < 0.5 * prior_value(1) as f64 {
            0
        } else {
            1
        };
    }
    k.min(255.0) as u8
}

fn sigma_code(s: f32) -> u8 {
    if !(s.is_finite() && s > 0.0) {
        return 0;
    }
    let l = s.ln();
    (0..SIGMAS.len() as u8)
        .min_by(|&a, &b| {
            let da = (l - SIGMAS[a as usize].ln()).abs();
            let db = (l - SIGMAS[b as usize].ln()).abs();
            da.total_cmp(&db)
        })
        .unwrap_or(0)
}

fn mean_code(m: f32) -> u16 {
    (finite_or(m, 0.0) / 100.0 * 1023.0)
        .round()
        .clamp(0.0, 1023.0) as u16
}

fn mean_of(code: u16) -> f32 {
    (code as f64 * 100.0 / 1023.0) as f32
}

fn finite_or(v: f32, d: f32) -> f32 {
    if v.is_finite() {
        v
    } else {
        d
    }
}

#[derive(Clone, Debug, PartialEq)]
struct PrimCodes {
    /// −1, 0, +1 (unused on the first primitive).
    turn: i8,
    /// Per side (dictionary index, refinement code); the right side of a and b unused.
    side: [(u8, u8); 2],
    rho: u8,
    /// The occluding line's offset off the chain ([`SHIFT_ZERO`]: on it).
    shift: u8,
}

#[derive(Clone, Debug, PartialEq)]
struct CurveCodes {
    kind: Kind,
    dirs: [i8; 2],
    start: [u32; 2],
    axis: u8,
    prims: Vec<PrimCodes>,
}

#[derive(Clone, Debug, PartialEq)]
struct BaseCodes {
    x: u32,
    y: u32,
    theta: u8,
    sx: u8,
    sy: u8,
    amp: i8,
}

#[derive(Clone, Debug, PartialEq)]
struct ColourCodes {
    /// Per bin (u, v) codes, 6 bits each.
    k: Vec<[u8; 2]>,
}

#[derive(Clone, Debug, PartialEq)]
struct Codes {
    width: u32,
    height: u32,
    seed: u64,
    curves: Vec<CurveCodes>,
    /// weight[0], mean[0..2], sigma[0..2].
    rho_off: [u8; 5],
    mean: u16,
    bases: Vec<BaseCodes>,
    colour: ColourCodes,
    region: super::Region,
    /// [`along_across_code`].
    along_across: u8,
}

fn sign(d: i8) -> i8 {
    d.signum()
}

/// The labels a kind stores (see [`Curve::dirs`]).
fn canonical_dirs(kind: Kind, d: [i8; 2]) -> [i8; 2] {
    match kind {
        Kind::Boundary | Kind::Source => [sign(d[0]), 0],
        Kind::Occluding => [sign(d[0]), sign(d[1])],
        Kind::Dividing => [1, 1],
        Kind::Stream => {
            let v = if d[0] != 0 { sign(d[0]) } else { sign(d[1]) };
            [v, v]
        }
    }
}

/// The free label variables of a kind, as indices into `dirs`.
fn free_labels(kind: Kind) -> &'static [usize] {
    match kind {
        Kind::Occluding => &[0, 1],
        Kind::Dividing => &[],
        _ => &[0],
    }
}

fn blocks(n: u32) -> u32 {
    n.div_ceil(COARSE)
}

/// The start `.czs` stores for curve `c` on a w×h image (its first centre rounded to whole
/// pixels, clamped to [0, W]×[0, H]); None without primitives.
pub fn curve_start(c: &Curve, w: u32, h: u32) -> Option<[u32; 2]> {
    let first = c.prims.first()?;
    let r = |v: f32, n: u32| finite_or(v, 0.0).round().clamp(0.0, n as f32) as u32;
    let [x, y] = on_chain(first);
    Some([r(x, w), r(y, h)])
}

fn curve_codes(c: &Curve, w: u32, h: u32) -> Option<CurveCodes> {
    let first = c.prims.first()?;
    let start = curve_start(c, w, h)?;
    let q = AXIS_QUANTUM as f64;
    let mut idx = (finite_or(first.axis, 0.0) as f64 / q).round() as i64;
    let axis = idx.rem_euclid(AXIS_STEPS as i64) as u8;
    let hair = c.kind.hair_sides();
    let prims = c
        .prims
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let mut turn = 0i8;
            if k > 0 {
                let want = (finite_or(p.axis, 0.0) as f64 / q).round() as i64;
                let d = (want - idx).rem_euclid(AXIS_STEPS as i64);
                let d = if d >= AXIS_STEPS as i64 / 2 {
                    d - AXIS_STEPS as i64
                } else {
                    d
                };
                turn = d.clamp(-1, 1) as i8;
                idx += turn as i64;
            }
            let side = [0, 1].map(|s| {
                if hair[s] {
                    snap_side((finite_or(p.side[s], 0.0) as f64).to_degrees())
                } else {
                    (0, 8)
                }
            });
            PrimCodes {
                turn,
                side,
                rho: snap_rho(p.rho),
                shift: if c.kind == Kind::Occluding {
                    shift_code(p.shift)
                } else {
                    SHIFT_ZERO
                },
            }
        })
        .collect();
    Some(CurveCodes {
        kind: c.kind,
        dirs: canonical_dirs(c.kind, c.dirs),
        start,
        axis,
        prims,
    })
}

fn base_codes(b: &Base, w: u32, h: u32) -> BaseCodes {
    let cell = |v: f32, n: u32| {
        let k = ((finite_or(v, 0.0) - 0.5 * COARSE as f32) / COARSE as f32).round();
        k.clamp(0.0, blocks(n).saturating_sub(1) as f32) as u32
    };
    let t = (finite_or(b.theta, 0.0) as f64 / (std::f64::consts::PI / THETAS as f64)).round();
    BaseCodes {
        x: cell(b.x, w),
        y: cell(b.y, h),
        theta: (t as i64).rem_euclid(THETAS as i64) as u8,
        sx: sigma_code(b.sx),
        sy: sigma_code(b.sy),
        amp: (finite_or(b.amp, 0.0) / AMP_STEP)
            .round()
            .clamp(-128.0, 127.0) as i8,
    }
}

fn colour_codes(c: &ColourMap) -> ColourCodes {
    let k = (0..COLOUR_BINS)
        .map(|i| {
            let p = c.uv.get(i).copied().unwrap_or([0.0, 0.0]);
            p.map(|v| {
                ((finite_or(v, 0.0) - CHROMA_LO) / CHROMA_STEP)
                    .round()
                    .clamp(0.0, 63.0) as u8
            })
        })
        .collect();
    ColourCodes { k }
}

fn rho_off_codes(r: &RhoPrior) -> [u8; 5] {
    let (a, b) = (finite_or(r.weight[0], 0.0), finite_or(r.weight[1], 0.0));
    let w0 = if a >= 0.0 && b >= 0.0 && a + b > 0.0 {
        a / (a + b)
    } else {
        0.5
    };
    [
        (w0 * 255.0).round().clamp(0.0, 255.0) as u8,
        snap_prior(r.mean[0]),
        snap_prior(r.mean[1]),
        snap_prior(r.sigma[0]),
        snap_prior(r.sigma[1]),
    ]
}

fn codes(s: &Sketch) -> Codes {
    let (w, h) = (s.width, s.height);
    Codes {
        width: w,
        height: h,
        seed: s.seed,
        curves: s
            .curves
            .iter()
            .filter_map(|c| curve_codes(c, w, h))
            .collect(),
        rho_off: rho_off_codes(&s.rho_off),
        mean: mean_code(s.shading.mean),
        bases: s
            .shading
            .bases
            .iter()
            .map(|b| base_codes(b, w, h))
            .collect(),
        colour: colour_codes(&s.colour),
        region: region_codes(&s.region, w, h),
        along_across: along_across_code(s.along_across),
    }
}

/// `Sketch::along_across` as the files store it: 0 for none; q in 1..=255 stands for
/// 2^(−(q − 1)/16), from 1 down to 1.7e-5 in steps of 4.4% (a ratio over 1 is stored as
/// 1; a value that is not a positive finite number as none).
fn along_across_code(v: Option<f32>) -> u8 {
    match v {
        Some(t) if t.is_finite() && t > 0.0 => {
            (1.0 - 16.0 * t.log2()).round().clamp(1.0, 255.0) as u8
        }
        _ => 0,
    }
}

fn along_across_value(q: u8) -> Option<f32> {
    (q > 0).then(|| (-(q as f32 - 1.0) / 16.0).exp2())
}

/// An along/across ratio as the files store it.
pub fn quantise_along_across(v: Option<f32>) -> Option<f32> {
    along_across_value(along_across_code(v))
}

/// The region as the files store it: vertices clamped to the image's corners, repeats
/// dropped, polygons of fewer than 3 vertices dropped.
fn region_codes(r: &super::Region, w: u32, h: u32) -> super::Region {
    r.iter()
        .map(|poly| {
            let mut out: Vec<[u32; 2]> = Vec::with_capacity(poly.len());
            for p in poly {
                let q = [p[0].min(w), p[1].min(h)];
                if out.last() != Some(&q) {
                    out.push(q);
                }
            }
            while out.len() > 1 && out.first() == out.last() {
                out.pop();
            }
            out
        })
        .filter(|p| p.len() >= 3)
        .collect()
}

/// The offset of shift code `code` off the chain, px (to the left).
pub fn shift_of(code: u8) -> f32 {
    (code as i32 - SHIFT_STEPS) as f32 * SHIFT_QUANTUM
}

/// The nearest shift code of an offset `shift` px (clamped to ±[`SHIFT_STEPS`] steps).
pub fn shift_code(shift: f32) -> u8 {
    let k = (finite_or(shift, 0.0) / SHIFT_QUANTUM).round();
    (k.clamp(-(SHIFT_STEPS as f32), SHIFT_STEPS as f32) as i32 + SHIFT_STEPS) as u8
}

/// The shift code of a stored offset `shift` px, which must lie on the code lattice (the
/// readers' check; the error says what the lattice is).
pub(super) fn exact_shift_code(shift: f64) -> std::result::Result<u8, String> {
    let code = shift_code(shift as f32);
    if shift_of(code) as f64 == shift {
        Ok(code)
    } else {
        Err(format!(
            "shifts are multiples of {SHIFT_QUANTUM} px within ±{} px",
            SHIFT_STEPS as f32 * SHIFT_QUANTUM
        ))
    }
}

/// The centre of a primitive with axis `axis` whose chain point is (x, y), shift code
/// `code` off it along the left normal (sin a, −cos a): f64, then f32, so that the
/// pursuit's placement and the decoder's agree to the bit.
pub fn off_chain(x: f32, y: f32, axis: f32, code: u8) -> [f32; 2] {
    if code == SHIFT_ZERO {
        return [x, y];
    }
    let (o, a) = (shift_of(code) as f64, axis as f64);
    [
        (x as f64 + o * a.sin()) as f32,
        (y as f64 - o * a.cos()) as f32,
    ]
}

/// The point of `p`'s chain under its centre: (x, y) less its shift along the left normal
/// (the inverse of [`off_chain`] to within f32 rounding).
pub fn on_chain(p: &Primitive) -> [f32; 2] {
    let o = finite_or(p.shift, 0.0) as f64;
    let a = finite_or(p.axis, 0.0) as f64;
    [
        (p.x as f64 - o * a.sin()) as f32,
        (p.y as f64 + o * a.cos()) as f32,
    ]
}

fn decode_curve(c: &CurveCodes) -> Curve {
    let mut idx = c.axis as i64;
    let (mut x, mut y) = (c.start[0] as f64, c.start[1] as f64);
    let hair = c.kind.hair_sides();
    let prims = c
        .prims
        .iter()
        .enumerate()
        .map(|(k, p)| {
            if k > 0 {
                idx += p.turn as i64;
                x += STEP as f64 * cos15(idx);
                y += STEP as f64 * sin15(idx);
            }
            let side = [0, 1].map(|s| {
                if hair[s] {
                    deg_to_rad(side_deg(p.side[s].0, p.side[s].1))
                } else {
                    0.0
                }
            });
            let axis = axis_of(idx.rem_euclid(AXIS_STEPS as i64) as u8);
            let [x, y] = off_chain(x as f32, y as f32, axis, p.shift);
            Primitive {
                shift: shift_of(p.shift),
                x,
                y,
                axis,
                rho: RHO_LEVELS[p.rho as usize],
                side,
            }
        })
        .collect();
    Curve {
        kind: c.kind,
        prims,
        dirs: c.dirs,
    }
}

fn decode_base(b: &BaseCodes) -> Base {
    Base {
        x: block_centre(b.x),
        y: block_centre(b.y),
        theta: theta_of(b.theta as u32),
        sx: SIGMAS[b.sx as usize],
        sy: SIGMAS[b.sy as usize],
        amp: b.amp as f32 * AMP_STEP,
    }
}

fn decode_colour(c: &ColourCodes) -> ColourMap {
    ColourMap {
        uv: c
            .k
            .iter()
            .map(|k| k.map(|k| CHROMA_LO + CHROMA_STEP * k as f32))
            .collect(),
    }
}

fn decode(c: &Codes) -> Sketch {
    let r = &c.rho_off;
    Sketch {
        width: c.width,
        height: c.height,
        seed: c.seed,
        curves: c.curves.iter().map(decode_curve).collect(),
        rho_off: RhoPrior {
            weight: [
                (r[0] as f64 / 255.0) as f32,
                ((255 - r[0]) as f64 / 255.0) as f32,
            ],
            mean: [prior_value(r[1]), prior_value(r[2])],
            sigma: [prior_value(r[3]), prior_value(r[4])],
        },
        shading: Shading {
            mean: mean_of(c.mean),
            bases: c.bases.iter().map(decode_base).collect(),
        },
        colour: decode_colour(&c.colour),
        region: c.region.clone(),
        along_across: along_across_value(c.along_across),
    }
}

/// Snaps a sketch to what the files store:
/// - curves without primitives are dropped; a curve's start is its first centre rounded
///   to whole pixels and clamped to [0, W]×[0, H]; each axis is snapped to its 15° step
///   and each turn clamped to ±1 step (a sharper bend is cut to 15°); the centres are then
///   rebuilt as the chain of [`STEP`]s along the axes, so a curve of the pursuit's lattice
///   keeps its geometry and any other one is redrawn on it;
/// - side angles go to the nearest dictionary angle plus the nearest refinement (a
///   negative angle, down to −30°, leans the flow the other way; beyond 146.25° is
///   clamped); the right side of a and b is 0; ρ to the nearest level in log scale;
/// - labels: a and b keep [sign d, 0], c [sign d_l, sign d_r], d is [1, 1], e takes its
///   first nonzero label on both sides; 0 (undecided) stays 0;
/// - p_nsk: weights normalised to sum 1; shading and colour map as the module docs say
///   (amplitudes beyond ±64 are clamped); a map of other than 16 bins is cut or padded
///   with gray; non-finite numbers become 0;
/// - region: vertices clamped to [0, W]×[0, H], repeated vertices dropped, polygons of
///   fewer than 3 vertices dropped;
/// - the along/across ratio to the nearest 2^(−k/16), at most 1 (see `along_across_code`).
pub fn quantise(s: &Sketch) -> Sketch {
    decode(&codes(s))
}

/// The shading as the files store it on a w×h image.
pub fn quantise_shading(s: &Shading, w: u32, h: u32) -> Shading {
    Shading {
        mean: mean_of(mean_code(s.mean)),
        bases: s
            .bases
            .iter()
            .map(|b| decode_base(&base_codes(b, w, h)))
            .collect(),
    }
}

/// A contrast as `.czs` stores it (the nearest of [`RHO_LEVELS`] in log scale).
pub fn quantise_rho(rho: f32) -> f32 {
    RHO_LEVELS[snap_rho(rho) as usize]
}

/// The colour map as the files store it.
pub fn quantise_colour(c: &ColourMap) -> ColourMap {
    decode_colour(&colour_codes(c))
}

// ---------------------------------------------------------------------------------------
// Files

/// The three sketch files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    Czs,
    Json,
    Svg,
}

impl FileKind {
    /// By extension (case-insensitive) when it is `.czs`, `.json` or `.svg`; otherwise (a
    /// pipe such as `/dev/stdin` has none) by content: the `.czs` magic, JSON's `{` or `[`, SVG's `<`.
    pub fn of(path: &Path, bytes: &[u8]) -> Option<FileKind> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("czs") => return Some(FileKind::Czs),
            Some("json") => return Some(FileKind::Json),
            Some("svg") => return Some(FileKind::Svg),
            _ => {}
        }
        if bytes.starts_with(MAGIC) {
            return Some(FileKind::Czs);
        }
        let text = bytes.strip_prefix("\u{feff}".as_bytes()).unwrap_or(bytes);
        match text.iter().find(|b| !b.is_ascii_whitespace()) {
            Some(b'{' | b'[') => Some(FileKind::Json),
            Some(b'<') => Some(FileKind::Svg),
            _ => None,
        }
    }
}

/// Reads a sketch from `hair.czs`, `sketch.json` or `sketch.svg` (format by extension, else
/// by content, see [`FileKind::of`]), checked by [`validate`] (each reader runs it). The
/// file is read once, so a pipe works.
pub fn load(path: &Path) -> Result<Sketch> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    from_bytes(&bytes, path)
}

/// Parses the bytes of a sketch file; `path` names it in errors and its extension, if one
/// of the three, chooses the format.
pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Sketch> {
    let text = || {
        std::str::from_utf8(bytes).map_err(|e| {
            Error::bad_file(path, format!("not UTF-8 text (byte {})", e.valid_up_to()))
        })
    };
    match FileKind::of(path, bytes) {
        Some(FileKind::Czs) => from_czs(bytes, path),
        Some(FileKind::Json) => from_json(text()?, path),
        Some(FileKind::Svg) => from_svg(text()?, path),
        None => Err(Error::bad_file(
            path,
            "unknown sketch file type: expected a .czs, .json or .svg extension, or content \
             that starts like one (the CZS magic, a JSON object, an SVG element)",
        )),
    }
}

/// Writes `s` (quantised) to `path` atomically, in the format its extension names.
pub fn save(s: &Sketch, path: &Path) -> Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let bytes = match ext.as_deref() {
        Some("czs") => to_czs(s),
        Some("json") => to_json(s).into_bytes(),
        Some("svg") => to_svg(s).into_bytes(),
        _ => {
            return Err(Error::Invalid(format!(
                "{}: unknown sketch file type: expected a .czs, .json or .svg extension",
                path.display()
            )))
        }
    };
    crate::io::write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_code_snaps_back_to_its_value() {
        for d in 0..4u8 {
            for r in 0..16u8 {
                let deg = side_deg(d, r);
                let (d2, r2) = snap_side((deg_to_rad(deg) as f64).to_degrees());
                assert_eq!(side_deg(d2, r2), deg, "side ({d}, {r})");
            }
        }
        for k in 0..16u8 {
            assert_eq!(snap_rho(RHO_LEVELS[k as usize]), k);
        }
        for k in 0..=255u8 {
            assert_eq!(snap_prior(prior_value(k)), k, "prior {k}");
        }
        for k in 0..SIGMAS.len() as u8 {
            assert_eq!(sigma_code(SIGMAS[k as usize]), k);
        }
        for k in 0..=1023u16 {
            assert_eq!(mean_code(mean_of(k)), k);
        }
        for a in 0..AXIS_STEPS as u8 {
            let c = curve_codes(
                &Curve {
                    kind: Kind::Stream,
                    prims: vec![Primitive {
                        shift: 0.0,
                        x: 1.0,
                        y: 1.0,
                        axis: axis_of(a),
                        rho: 0.0,
                        side: [0.0; 2],
                    }],
                    dirs: [1, 1],
                },
                4,
                4,
            )
            .unwrap();
            assert_eq!(c.axis, a);
            // The cosine table agrees with the library's cosine.
            let t = a as f64 * PI / 12.0;
            assert!((cos15(a as i64) - t.cos()).abs() < 1e-15);
            assert!((sin15(a as i64) - t.sin()).abs() < 1e-15);
        }
    }
}
