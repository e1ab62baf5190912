//! Checks that a sketch is one the model can use, run by every loader ([`super::load`],
//! [`super::from_czs`], [`super::from_json`], [`super::from_svg`]) on what it read, and by
//! [`crate::sketch::edit::apply`] on an edit's result before it is snapped.
//!
//! What is refused, each with the file and the place named:
//! - a number that is not finite (NaN, ±inf) anywhere: centres, axes, contrasts, side
//!   angles, the prior p_nsk, the shading and the colour map. The files cannot hold one
//!   (JSON has no NaN, the SVG reader and `.czs` decoder refuse them), so in practice this
//!   guards sketches built in code and edits;
//! - a colour map of other than [`COLOUR_BINS`] bins;
//! - a primitive whose centre lies more than [`MARGIN`] px outside the image: its window
//!   (7×5 px, half-diagonal 4.6 px) then covers no pixel, so the curve is drawn off the
//!   picture. The pursuit keeps its centres within the image (a pixel at most once the start
//!   is rounded), and a sketch moved in an editor may hang over an edge by a step;
//! - a curve without primitives, a label other than −1, 0, +1, a negative contrast, a
//!   shading base of zero or negative σ, or centred more than [`MARGIN`] px outside;
//! - an image of zero width or height.
//!
//! A sketch with no curves is *not* refused here: `coif sketch` may find none on a
//! featureless picture and its files must still load and convert. What draws from the
//! curves (synthesis, the cartoon, editing) calls [`require_curves`].
//!
//! Light sequential checks over a few hundred numbers: CPU.

use super::super::{Kind, Sketch, COLOUR_BINS, STEP};
use super::{SHIFT_QUANTUM, SHIFT_STEPS};
use crate::error::{Error, Result};
use std::path::Path;

/// How far a primitive's or a base's centre may lie outside the image, px: one step along
/// a curve, more than the half-diagonal of a primitive's window (√(3.5² + 3²) ≈ 4.6).
pub const MARGIN: f32 = STEP;

/// Checks `s` (see the module docs); `path` names the file in the error.
pub fn validate(s: &Sketch, path: &Path) -> Result<()> {
    check(s).map_err(|m| Error::bad_file(path, m))
}

/// Refuses a sketch without curves: synthesis, the cartoon and editing draw from them.
pub fn require_curves(s: &Sketch, path: &Path) -> Result<()> {
    if s.curves.is_empty() {
        return Err(Error::bad_file(
            path,
            "the sketch has no curves: the vector field, the synthesis and the cartoon are \
             drawn from its curves, so it needs at least one",
        ));
    }
    Ok(())
}

fn finite(v: f32, what: impl FnOnce() -> String) -> std::result::Result<(), String> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(format!("{} is {v}, not a finite number", what()))
    }
}

fn outside(x: f32, y: f32, w: u32, h: u32) -> bool {
    x < -MARGIN || y < -MARGIN || x > w as f32 + MARGIN || y > h as f32 + MARGIN
}

pub(crate) fn check(s: &Sketch) -> std::result::Result<(), String> {
    let (w, h) = (s.width, s.height);
    if w == 0 || h == 0 {
        return Err(format!("the image size {w}x{h} is empty"));
    }
    for (ci, c) in s.curves.iter().enumerate() {
        if c.prims.is_empty() {
            return Err(format!("curve {ci} has no primitives"));
        }
        if c.dirs.iter().any(|d| !(-1..=1).contains(d)) {
            return Err(format!(
                "curve {ci} has direction labels {:?}; each is -1, 0 or +1",
                c.dirs
            ));
        }
        for (k, p) in c.prims.iter().enumerate() {
            let at = || format!("curve {ci}, primitive {k}");
            finite(p.x, || format!("{}: centre x", at()))?;
            finite(p.y, || format!("{}: centre y", at()))?;
            finite(p.axis, || format!("{}: axis", at()))?;
            finite(p.rho, || format!("{}: contrast ρ", at()))?;
            finite(p.side[0], || format!("{}: left side angle", at()))?;
            finite(p.side[1], || format!("{}: right side angle", at()))?;
            finite(p.shift, || format!("{}: shift", at()))?;
            if p.shift.abs() > SHIFT_STEPS as f32 * SHIFT_QUANTUM
                || (p.shift != 0.0 && c.kind != Kind::Occluding)
            {
                return Err(format!(
                    "{}: a shift of {} px off the chain on a curve of kind {} (only occluding \
                     lines lie off their chains, by at most {} px)",
                    at(),
                    p.shift,
                    c.kind.letter(),
                    SHIFT_STEPS as f32 * SHIFT_QUANTUM
                ));
            }
            if p.rho < 0.0 {
                return Err(format!("{}: contrast ρ = {} is negative", at(), p.rho));
            }
            if outside(p.x, p.y, w, h) {
                return Err(format!(
                    "{}: the centre ({}, {}) lies outside the {w}x{h} image (more than {MARGIN} \
                     px beyond its edge)",
                    at(),
                    p.x,
                    p.y
                ));
            }
        }
    }
    let r = &s.rho_off;
    for (name, v) in [("weight", r.weight), ("mean", r.mean), ("sigma", r.sigma)] {
        for (i, x) in v.iter().enumerate() {
            finite(*x, || format!("rho_off.{name}[{i}]"))?;
            if *x < 0.0 {
                return Err(format!("rho_off.{name}[{i}] = {x} is negative"));
            }
        }
    }
    finite(s.shading.mean, || "the shading mean".into())?;
    for (bi, b) in s.shading.bases.iter().enumerate() {
        let at = || format!("shading base {bi}");
        for (name, v) in [
            ("x", b.x),
            ("y", b.y),
            ("theta", b.theta),
            ("sx", b.sx),
            ("sy", b.sy),
            ("amp", b.amp),
        ] {
            finite(v, || format!("{}: {name}", at()))?;
        }
        if b.sx <= 0.0 || b.sy <= 0.0 {
            return Err(format!("{}: σ ({}, {}) must be positive", at(), b.sx, b.sy));
        }
        if outside(b.x, b.y, w, h) {
            return Err(format!(
                "{}: the centre ({}, {}) lies outside the {w}x{h} image",
                at(),
                b.x,
                b.y
            ));
        }
    }
    if s.colour.uv.len() != COLOUR_BINS {
        return Err(format!(
            "the colour map has {} bins, expected {COLOUR_BINS}",
            s.colour.uv.len()
        ));
    }
    for (i, uv) in s.colour.uv.iter().enumerate() {
        finite(uv[0], || format!("the colour map, bin {i}: u*"))?;
        finite(uv[1], || format!("the colour map, bin {i}: v*"))?;
    }
    for (pi, poly) in s.region.iter().enumerate() {
        if poly.len() < 3 {
            return Err(format!(
                "region polygon {pi} has {} vertices; a polygon needs 3",
                poly.len()
            ));
        }
        if let Some(v) = poly.iter().find(|v| v[0] > w || v[1] > h) {
            return Err(format!(
                "region polygon {pi} has the vertex ({}, {}), outside the {w}x{h} image",
                v[0], v[1]
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sketch::{
        Base, ColourMap, Curve, Kind, Primitive, RhoPrior, Shading, Sketch, COLOUR_BINS,
    };

    fn sketch() -> Sketch {
        Sketch {
            width: 40,
            height: 30,
            seed: 1,
            curves: vec![Curve {
                kind: Kind::Stream,
                prims: (0..3)
                    .map(|i| Primitive {
                        shift: 0.0,
                        x: 10.0 + 5.0 * i as f32,
                        y: 15.0,
                        axis: 0.0,
                        rho: 8.0,
                        side: [0.0; 2],
                    })
                    .collect(),
                dirs: [1, 1],
            }],
            rho_off: RhoPrior {
                weight: [0.5, 0.5],
                mean: [2.0, 8.0],
                sigma: [1.0, 3.0],
            },
            shading: Shading {
                mean: 40.0,
                bases: vec![Base {
                    x: 10.0,
                    y: 10.0,
                    theta: 0.0,
                    sx: 8.0,
                    sy: 8.0,
                    amp: 5.0,
                }],
            },
            colour: ColourMap {
                uv: vec![[10.0, 20.0]; COLOUR_BINS],
            },
            region: Vec::new(),
            along_across: None,
        }
    }

    fn err(s: &Sketch) -> String {
        validate(s, Path::new("f.czs")).unwrap_err().to_string()
    }

    #[test]
    fn each_problem_is_named() {
        let p = Path::new("f.czs");
        validate(&sketch(), p).unwrap();
        let mut s = sketch();
        s.curves[0].prims[1].rho = f32::NAN;
        let m = err(&s);
        assert!(
            m.starts_with("f.czs: curve 0, primitive 1: contrast"),
            "{m}"
        );
        let mut s = sketch();
        s.colour.uv[3][1] = f32::INFINITY;
        assert!(err(&s).contains("colour map, bin 3: v*"));
        let mut s = sketch();
        s.colour.uv.pop();
        assert!(err(&s).contains("15 bins, expected 16"));
        let mut s = sketch();
        // On the margin is kept, beyond it refused.
        s.curves[0].prims[2].x = 40.0 + MARGIN;
        validate(&s, p).unwrap();
        s.curves[0].prims[2].x = 40.0 + MARGIN + 0.5;
        assert!(err(&s).contains("curve 0, primitive 2: the centre"));
        let mut s = sketch();
        s.shading.bases[0].y = -20.0;
        assert!(err(&s).contains("shading base 0"));
        let mut s = sketch();
        s.curves.clear();
        validate(&s, p).unwrap();
        let m = require_curves(&s, p).unwrap_err().to_string();
        assert!(m.starts_with("f.czs: the sketch has no curves"), "{m}");
    }
}
