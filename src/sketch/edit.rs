//! Edits of a sketch (CZ06 §5, Fig. 16): delete, move or add a curve, flip its directions,
//! change its contrast, edit, add or delete a shading base. [`apply`] runs a list of edits
//! in order, each on the sketch the previous ones left (so a deletion renumbers the curves
//! after it), checks the result ([`format::validate`]'s rules) and returns it snapped to the
//! lattice the files store ([`format::quantise`]).
//!
//! What each edit means on the lattice:
//! - [`Edit::Move`]: every centre shifts by (dx, dy); the files store a curve as an integer
//!   start and 5 px steps, so the shift is in effect rounded to whole pixels.
//! - [`Edit::Add`]: the curve is snapped as [`format::quantise`] says (start rounded, axes on
//!   15° steps turning at most one step per primitive, centres rebuilt 5 px apart). A drawn
//!   line becomes such a curve with [`curve_from_points`], which walks the lattice along it.
//! - [`Edit::Flip`]: labels are relative to the traversal (see [`crate::sketch`]), so a flip
//!   negates labels. Side boundaries (a) and sources (b) have one label, on the left;
//!   occluding lines (c) one per side, flipped together or one at a time; stream lines (e)
//!   one shared by both sides, flipped whole. A dividing line (d) has no free label (its
//!   flow leaves it on both sides by definition, and reversing its traversal changes
//!   nothing), so flipping it is an error, as is flipping an undecided (0) label or a side
//!   the kind does not have.
//! - [`Edit::Contrast`]: ρ of every primitive scaled or set, then snapped to the 16 levels
//!   (0.5 to 128, log scale).
//! - Bases: set fields are snapped to the shading lattice (centres 4i + 2, θ in 22.5°
//!   steps, σ on 8 levels from 4 to 64, amplitude in 0.5 from −64 to 63.5).
//!
//! Light sequential work over a few hundred numbers: CPU.

use super::format::{self, quantise};
use super::{Base, Curve, Kind, Primitive, Sketch, AXIS_QUANTUM, AXIS_STEPS, STEP};
use crate::error::{Error, Result};
use std::f32::consts::PI;
use std::fmt;
use std::path::Path;

/// Which labels of a curve a flip negates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// Every label the curve has.
    Both,
    Left,
    Right,
}

/// How a contrast edit changes ρ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rho {
    /// Multiplies every primitive's ρ.
    Scale(f32),
    /// Sets every primitive's ρ.
    Set(f32),
}

/// New values for some of a base's fields (θ in radians); `None` keeps the field.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BaseEdit {
    pub amp: Option<f32>,
    pub x: Option<f32>,
    pub y: Option<f32>,
    pub sx: Option<f32>,
    pub sy: Option<f32>,
    pub theta: Option<f32>,
}

/// One edit; indices count from 0 in the sketch as the edits before it left it.
#[derive(Clone, Debug, PartialEq)]
pub enum Edit {
    /// Removes curve i.
    Delete(usize),
    /// Negates curve i's labels on the given side(s).
    Flip(usize, Side),
    /// Shifts curve i by (dx, dy) px.
    Move(usize, [f32; 2]),
    /// Appends a curve.
    Add(Curve),
    /// Changes curve i's contrast.
    Contrast(usize, Rho),
    /// Changes fields of shading base i.
    Base(usize, BaseEdit),
    /// Removes shading base i.
    DeleteBase(usize),
    /// Appends a shading base.
    AddBase(Base),
    /// Sets the high band's along/across ratio (`Sketch::along_across`; None: no grain).
    AlongAcross(Option<f32>),
}

impl fmt::Display for Edit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Edit::Delete(i) => write!(f, "delete curve {i}"),
            Edit::Flip(i, s) => write!(f, "flip curve {i}{}", side_suffix(*s)),
            Edit::Move(i, d) => write!(f, "move curve {i} by ({}, {})", d[0], d[1]),
            Edit::Add(c) => write!(
                f,
                "add a curve ({}, {} primitives)",
                c.kind.letter(),
                c.prims.len()
            ),
            Edit::Contrast(i, Rho::Scale(k)) => write!(f, "scale curve {i}'s contrast by {k}"),
            Edit::Contrast(i, Rho::Set(v)) => write!(f, "set curve {i}'s contrast to {v}"),
            Edit::Base(i, _) => write!(f, "edit shading base {i}"),
            Edit::DeleteBase(i) => write!(f, "delete shading base {i}"),
            Edit::AddBase(b) => write!(f, "add a shading base at ({}, {})", b.x, b.y),
            Edit::AlongAcross(Some(v)) => write!(f, "set the along/across ratio to {v}"),
            Edit::AlongAcross(None) => write!(f, "remove the along/across ratio"),
        }
    }
}

fn side_suffix(s: Side) -> &'static str {
    match s {
        Side::Both => "",
        Side::Left => " (left)",
        Side::Right => " (right)",
    }
}

/// Applies `edits` in order to `s` (see the module docs) and returns the result quantised.
/// An index out of range, a flip the curve's kind does not allow, a non-finite value or a
/// result that [`format::validate`] refuses is an [`Error::Invalid`] naming the edit.
pub fn apply(s: &Sketch, edits: &[Edit]) -> Result<Sketch> {
    apply_logged(s, edits).map(|(q, _)| q)
}

/// [`apply`], also returning one line per edit saying what it changed (on the quantised
/// result's numbers where the edit snaps them).
pub fn apply_logged(s: &Sketch, edits: &[Edit]) -> Result<(Sketch, Vec<String>)> {
    let mut t = s.clone();
    let mut log = Vec::new();
    for (n, e) in edits.iter().enumerate() {
        let line =
            step(&mut t, e).map_err(|m| Error::Invalid(format!("edit {} ({e}): {m}", n + 1)))?;
        log.push(line);
    }
    let bad = |m: String| Error::Invalid(format!("the edited sketch: {m}"));
    format::validate::check(&t).map_err(bad)?;
    let q = quantise(&t);
    // Snapping can bend a drawn curve (a turn sharper than 15° per step) off the picture.
    format::validate::check(&q).map_err(bad)?;
    Ok((q, log))
}

fn curve_at(t: &Sketch, i: usize) -> std::result::Result<(), String> {
    if i >= t.curves.len() {
        return Err(match t.curves.len() {
            0 => format!("there is no curve {i}: the sketch has no curves"),
            n => format!(
                "there is no curve {i}: the sketch has {n} curves (0 to {})",
                n - 1
            ),
        });
    }
    Ok(())
}

fn base_at(t: &Sketch, i: usize) -> std::result::Result<(), String> {
    let n = t.shading.bases.len();
    if i >= n {
        return Err(match n {
            0 => format!("there is no shading base {i}: the sketch has none"),
            n => format!(
                "there is no shading base {i}: the sketch has {n} (0 to {})",
                n - 1
            ),
        });
    }
    Ok(())
}

fn finite(v: f32, what: &str) -> std::result::Result<(), String> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(format!("{what} is {v}, not a finite number"))
    }
}

fn describe(c: &Curve) -> String {
    format!("{}, {} primitives", c.kind.letter(), c.prims.len())
}

fn mean_rho(c: &Curve) -> f32 {
    c.prims.iter().map(|p| p.rho).sum::<f32>() / c.prims.len().max(1) as f32
}

/// One edit on `t`; the log line, or what is wrong.
fn step(t: &mut Sketch, e: &Edit) -> std::result::Result<String, String> {
    match e {
        Edit::Delete(i) => {
            curve_at(t, *i)?;
            let c = t.curves.remove(*i);
            Ok(format!("deleted curve {i} ({})", describe(&c)))
        }
        Edit::Flip(i, side) => {
            curve_at(t, *i)?;
            let c = &mut t.curves[*i];
            let which: &[usize] = match (c.kind, side) {
                (Kind::Dividing, _) => {
                    return Err(format!(
                        "curve {i} is a dividing line (d): its flow leaves it on both sides by \
                         definition, so it has no direction to flip (change its kind or delete \
                         it instead)"
                    ))
                }
                (Kind::Boundary | Kind::Source, Side::Both | Side::Left) => &[0],
                (Kind::Boundary | Kind::Source, Side::Right) => {
                    return Err(format!(
                        "curve {i} is a {} ({}): only its left side carries hair, so it has \
                         no right direction (flip it with i or i:l)",
                        kind_name(c.kind),
                        c.kind.letter()
                    ))
                }
                (Kind::Stream, Side::Both) => &[0, 1],
                (Kind::Stream, _) => {
                    return Err(format!(
                        "curve {i} is a stream line (e): its two sides share one direction, \
                         so it flips whole (i, not i:l or i:r)"
                    ))
                }
                (Kind::Occluding, Side::Both) => &[0, 1],
                (Kind::Occluding, Side::Left) => &[0],
                (Kind::Occluding, Side::Right) => &[1],
            };
            let before = c.dirs;
            for &s in which {
                if c.dirs[s] == 0 {
                    return Err(format!(
                        "curve {i}'s {} direction is undecided (label 0): there is nothing to \
                         flip",
                        ["left", "right"][s]
                    ));
                }
            }
            for &s in which {
                c.dirs[s] = -c.dirs[s];
            }
            Ok(format!(
                "flipped curve {i} ({}){}: labels {:?} -> {:?}",
                describe(c),
                side_suffix(*side),
                before,
                c.dirs
            ))
        }
        Edit::Move(i, d) => {
            curve_at(t, *i)?;
            finite(d[0], "dx")?;
            finite(d[1], "dy")?;
            // The files store integer starts: the shift is whole pixels.
            let d = d.map(f32::round);
            for p in &mut t.curves[*i].prims {
                p.x += d[0];
                p.y += d[1];
            }
            Ok(format!(
                "moved curve {i} ({}) by ({}, {}) px",
                describe(&t.curves[*i]),
                d[0],
                d[1]
            ))
        }
        Edit::Add(c) => {
            if c.prims.is_empty() {
                return Err("the curve has no primitives".into());
            }
            t.curves.push(c.clone());
            Ok(format!(
                "added curve {} ({}) starting at ({}, {})",
                t.curves.len() - 1,
                describe(c),
                c.prims[0].x.round(),
                c.prims[0].y.round()
            ))
        }
        Edit::Contrast(i, r) => {
            curve_at(t, *i)?;
            let c = &mut t.curves[*i];
            let before = mean_rho(c);
            match *r {
                Rho::Scale(k) => {
                    finite(k, "the factor")?;
                    if k < 0.0 {
                        return Err(format!("the factor {k} is negative"));
                    }
                    c.prims.iter_mut().for_each(|p| p.rho *= k);
                }
                Rho::Set(v) => {
                    finite(v, "the contrast")?;
                    if v < 0.0 {
                        return Err(format!("the contrast {v} is negative"));
                    }
                    c.prims.iter_mut().for_each(|p| p.rho = v);
                }
            }
            let after = mean_rho(&quantise_curve(t, *i));
            Ok(format!(
                "curve {i} ({}): mean contrast {before:.2} -> {after:.2}",
                describe(&t.curves[*i])
            ))
        }
        Edit::Base(i, b) => {
            base_at(t, *i)?;
            let old = quantised_base(t, *i);
            let base = &mut t.shading.bases[*i];
            for (v, what) in [
                (b.amp, "amp"),
                (b.x, "x"),
                (b.y, "y"),
                (b.sx, "sx"),
                (b.sy, "sy"),
                (b.theta, "theta"),
            ] {
                if let Some(v) = v {
                    finite(v, what)?;
                }
            }
            if b.sx.is_some_and(|v| v <= 0.0) || b.sy.is_some_and(|v| v <= 0.0) {
                return Err("σ must be positive".into());
            }
            base.amp = b.amp.unwrap_or(base.amp);
            base.x = b.x.unwrap_or(base.x);
            base.y = b.y.unwrap_or(base.y);
            base.sx = b.sx.unwrap_or(base.sx);
            base.sy = b.sy.unwrap_or(base.sy);
            base.theta = b.theta.map(|v| v.rem_euclid(PI)).unwrap_or(base.theta);
            Ok(format!(
                "shading base {i}: {} -> {}",
                base_text(&old),
                base_text(&quantised_base(t, *i))
            ))
        }
        Edit::DeleteBase(i) => {
            base_at(t, *i)?;
            let b = quantised_base(t, *i);
            t.shading.bases.remove(*i);
            Ok(format!("deleted shading base {i} ({})", base_text(&b)))
        }
        Edit::AddBase(b) => {
            t.shading.bases.push(*b);
            let i = t.shading.bases.len() - 1;
            Ok(format!(
                "added shading base {i} ({})",
                base_text(&quantised_base(t, i))
            ))
        }
        Edit::AlongAcross(v) => {
            if let Some(x) = v {
                if !(x.is_finite() && *x > 0.0) {
                    return Err(format!(
                        "the along/across ratio must be a positive number, got {x}"
                    ));
                }
            }
            let old = t.along_across;
            t.along_across = *v;
            let text = |v: Option<f32>| match format::quantise_along_across(v) {
                Some(x) => format!("{x:.4}"),
                None => "none".into(),
            };
            Ok(format!(
                "along/across ratio: {} -> {}",
                text(old),
                text(t.along_across)
            ))
        }
    }
}

fn kind_name(k: Kind) -> &'static str {
    match k {
        Kind::Boundary => "side boundary",
        Kind::Source => "source or sink",
        Kind::Occluding => "occluding line",
        Kind::Dividing => "dividing line",
        Kind::Stream => "stream line",
    }
}

fn quantise_curve(t: &Sketch, i: usize) -> Curve {
    let one = Sketch {
        curves: vec![t.curves[i].clone()],
        shading: Default::default(),
        ..t.clone()
    };
    quantise(&one)
        .curves
        .pop()
        .unwrap_or_else(|| t.curves[i].clone())
}

fn quantised_base(t: &Sketch, i: usize) -> Base {
    let sh = super::Shading {
        mean: t.shading.mean,
        bases: vec![t.shading.bases[i]],
    };
    format::quantise_shading(&sh, t.width, t.height).bases[0]
}

fn base_text(b: &Base) -> String {
    format!(
        "amp {}, centre ({}, {}), θ {}°, σ ({:.2}, {:.2})",
        b.amp,
        b.x,
        b.y,
        (b.theta.to_degrees() * 10.0).round() / 10.0,
        b.sx,
        b.sy
    )
}

/// Default side angles of a drawn curve of `kind`: a boundary's and a stream line's flow
/// runs along them, a source's and a dividing line's leaves them perpendicularly, and an
/// occluding line has one cluster along it (left) and one meeting it at 60° (right).
pub fn default_sides(kind: Kind) -> [f32; 2] {
    match kind {
        Kind::Boundary | Kind::Stream => [0.0, 0.0],
        Kind::Source => [PI / 2.0, 0.0],
        Kind::Occluding => [0.0, PI / 3.0],
        Kind::Dividing => [PI / 2.0, PI / 2.0],
    }
}

/// A curve of `kind` along a drawn line `points` (pixels, in drawing order, the traversal
/// direction), on the lattice the pursuit produces: an integer start at the first point,
/// axes on 15° steps turning at most one step per primitive, centres [`STEP`] px apart.
/// Each step takes the turn (−1, 0, +1) whose centre lands nearest the point of the line
/// at the same arc length, so a line that bends more gently than the lattice's tightest
/// radius (about 19 px) is followed within a pixel or two; a tighter bend is cut.
/// Primitives: round(length / 5) + 1, each with `rho`, `sides` and labels `dirs`
/// (canonicalised for the kind when the sketch is quantised). Also returns the largest
/// distance from a centre to its point of the line, px.
pub fn curve_from_points(
    kind: Kind,
    points: &[[f32; 2]],
    rho: f32,
    sides: [f32; 2],
    dirs: [i8; 2],
) -> std::result::Result<(Curve, f32), String> {
    if let Some(p) = points
        .iter()
        .find(|p| !(p[0].is_finite() && p[1].is_finite()))
    {
        return Err(format!("the point ({}, {}) is not finite", p[0], p[1]));
    }
    // Arc lengths of the vertices, repeated points dropped.
    let mut pts: Vec<[f32; 2]> = Vec::new();
    for p in points {
        if pts
            .last()
            .is_none_or(|q| (p[0] - q[0]).hypot(p[1] - q[1]) > 1e-4)
        {
            pts.push(*p);
        }
    }
    if pts.len() < 2 {
        return Err("a curve needs at least two distinct points".into());
    }
    let mut arc = vec![0.0f32];
    for w in pts.windows(2) {
        let l = arc[arc.len() - 1] + (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
        arc.push(l);
    }
    let len = arc[arc.len() - 1];
    let at = |s: f32| -> [f32; 2] {
        let s = s.clamp(0.0, len);
        let k = arc.partition_point(|&a| a < s).clamp(1, pts.len() - 1);
        let (a0, a1) = (arc[k - 1], arc[k]);
        let f = if a1 > a0 { (s - a0) / (a1 - a0) } else { 0.0 };
        [
            pts[k - 1][0] + f * (pts[k][0] - pts[k - 1][0]),
            pts[k - 1][1] + f * (pts[k][1] - pts[k - 1][1]),
        ]
    };
    let n = (len / STEP).round() as usize + 1;
    let unit = |k: i64| {
        let a = k as f32 * AXIS_QUANTUM;
        [a.cos(), a.sin()]
    };
    let steps = AXIS_STEPS as i64;
    let start = [pts[0][0].round(), pts[0][1].round()];
    let towards = at(STEP.min(len));
    let mut k =
        ((towards[1] - start[1]).atan2(towards[0] - start[0]) / AXIS_QUANTUM).round() as i64;
    let mut c = start;
    let mut worst = (start[0] - pts[0][0]).hypot(start[1] - pts[0][1]);
    let mut prims = Vec::with_capacity(n);
    let prim = |c: [f32; 2], k: i64| Primitive {
        shift: 0.0,
        x: c[0],
        y: c[1],
        axis: k.rem_euclid(steps) as f32 * AXIS_QUANTUM,
        rho,
        side: sides,
    };
    prims.push(prim(c, k));
    for i in 1..n {
        let target = at(i as f32 * STEP);
        let (best, next) = (-1..=1)
            .map(|t| {
                let u = unit(k + t);
                let q = [c[0] + STEP * u[0], c[1] + STEP * u[1]];
                (k + t, q)
            })
            .min_by(|a, b| {
                let da = (a.1[0] - target[0]).hypot(a.1[1] - target[1]);
                let db = (b.1[0] - target[0]).hypot(b.1[1] - target[1]);
                da.total_cmp(&db)
            })
            .expect("three turns");
        k = best;
        c = next;
        worst = worst.max((c[0] - target[0]).hypot(c[1] - target[1]));
        prims.push(prim(c, k));
    }
    Ok((Curve { kind, prims, dirs }, worst))
}

/// The median ρ of `s`'s primitives (8 when it has none): the contrast given to a drawn
/// curve, so it stands out as much as the sketch's own.
pub fn median_rho(s: &Sketch) -> f32 {
    let mut r: Vec<f32> = s
        .curves
        .iter()
        .flat_map(|c| c.prims.iter().map(|p| p.rho))
        .filter(|v| v.is_finite())
        .collect();
    if r.is_empty() {
        return 8.0;
    }
    r.sort_by(f32::total_cmp);
    r[r.len() / 2]
}

/// The curves an `--add` file holds, for adding to `like` (whose median ρ a drawn line
/// takes):
/// - a sketch file (`.czs`, `sketch.json`, or an SVG with `data-cz-format="coif-sketch"`):
///   its curves as they are (already on the lattice);
/// - any other SVG (a drawing, e.g. Inkscape's): each `<polyline>` and straight-segment
///   `<path>` through the stroke importer, walked onto the lattice by [`curve_from_points`];
/// - a JSON curve: an object (or an array of them) either in `sketch.json`'s curve form
///   (`kind`, `dirs`, `start`, `prims` of `axis`, `sides`, `rho`) or as a drawn line
///   `{"kind": "e", "points": [[x, y], ...]}` with optional `dirs`, `rho` and `sides`
///   (degrees).
///
/// `kind`, when given, overrides the kind of every curve; a drawn line without one is a
/// stream line (e). Returns each curve with the largest distance (px) from its centres to
/// the drawn line (0 for curves read from a sketch).
pub fn curves_from_file(
    path: &Path,
    kind: Option<Kind>,
    like: &Sketch,
) -> Result<Vec<(Curve, f32)>> {
    let bad = |m: String| Error::bad_file(path, m);
    // Read once, so a pipe works; the format by extension, else by content.
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = || {
        std::str::from_utf8(&bytes)
            .map_err(|e| bad(format!("not UTF-8 text (byte {})", e.valid_up_to())))
    };
    let drawn = |kind_here: Option<Kind>, pts: &[[f32; 2]], extra: Extra| {
        let k = kind.or(kind_here).unwrap_or(Kind::Stream);
        curve_from_points(
            k,
            pts,
            extra.rho.unwrap_or_else(|| median_rho(like)),
            extra
                .sides
                .map(|s| s.map(|d| d.to_radians()))
                .unwrap_or_else(|| default_sides(k)),
            extra.dirs.unwrap_or([1, 1]),
        )
    };
    let from_sketch = |s: Sketch| -> Vec<(Curve, f32)> {
        s.curves
            .into_iter()
            .map(|mut c| {
                if let Some(k) = kind {
                    c.kind = k;
                }
                (c, 0.0)
            })
            .collect()
    };
    let out = match format::FileKind::of(path, &bytes) {
        Some(format::FileKind::Czs) => from_sketch(format::from_czs(&bytes, path)?),
        Some(format::FileKind::Svg) => {
            let t = text()?;
            if t.contains("data-cz-format") {
                from_sketch(format::from_svg(t, path)?)
            } else {
                let strokes = crate::io::import::svg_strokes_from_str(t, path)?;
                let mut out = Vec::new();
                for (n, st) in strokes.strokes.iter().enumerate() {
                    let c = drawn(None, &st.points, Extra::default())
                        .map_err(|m| bad(format!("line {n}: {m}")))?;
                    out.push(c);
                }
                out
            }
        }
        Some(format::FileKind::Json) => {
            let t = text()?;
            let v: serde_json::Value =
                serde_json::from_str(t).map_err(|e| bad(format!("malformed JSON: {e}")))?;
            if v.get("format").is_some() {
                from_sketch(format::from_json(t, path)?)
            } else {
                let items = match v {
                    serde_json::Value::Array(a) => a,
                    o => vec![o],
                };
                let mut out = Vec::new();
                for (n, item) in items.into_iter().enumerate() {
                    let c: JsonCurve = serde_json::from_value(item).map_err(|e| {
                        bad(format!(
                            "curve {n}: neither a sketch.json curve (kind, dirs, start, prims) \
                             nor a drawn line (kind, points): {e}"
                        ))
                    })?;
                    out.push(json_curve(c, &drawn).map_err(|m| bad(format!("curve {n}: {m}")))?);
                }
                out
            }
        }
        None => {
            return Err(bad(
                "cannot tell what to add: expected a .svg (a drawing or a sketch), a .json \
                 curve or sketch, or a .czs sketch"
                    .into(),
            ))
        }
    };
    if out.is_empty() {
        return Err(bad("holds no curve to add".into()));
    }
    Ok(out)
}

#[derive(Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Extra {
    dirs: Option<[i8; 2]>,
    rho: Option<f32>,
    /// Degrees.
    sides: Option<[f32; 2]>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonPrim {
    axis: u32,
    sides: [f32; 2],
    rho: f32,
}

#[derive(serde::Deserialize)]
#[serde(untagged)]
enum JsonCurve {
    Lattice {
        kind: String,
        dirs: [i8; 2],
        start: [u32; 2],
        prims: Vec<JsonPrim>,
    },
    Drawn {
        kind: Option<String>,
        points: Vec<[f32; 2]>,
        #[serde(flatten)]
        extra: Extra,
    },
}

fn kind_of(s: &str) -> std::result::Result<Kind, String> {
    let mut c = s.chars();
    match (c.next(), c.next()) {
        (Some(l), None) => Kind::from_letter(l),
        _ => None,
    }
    .ok_or_else(|| format!("unknown kind \"{s}\": expected one of a, b, c, d, e"))
}

/// Makes a curve of a drawn line: (its kind if the file names one, the points, the rest).
type Drawn<'a> =
    dyn Fn(Option<Kind>, &[[f32; 2]], Extra) -> std::result::Result<(Curve, f32), String> + 'a;

fn json_curve(c: JsonCurve, drawn: &Drawn<'_>) -> std::result::Result<(Curve, f32), String> {
    match c {
        JsonCurve::Lattice {
            kind,
            dirs,
            start,
            prims,
        } => {
            let kind = kind_of(&kind)?;
            if prims.is_empty() {
                return Err("the curve has no primitives".into());
            }
            let (mut x, mut y) = (start[0] as f32, start[1] as f32);
            let mut out = Vec::new();
            for (k, p) in prims.iter().enumerate() {
                if p.axis % 15 != 0 || p.axis >= 360 {
                    return Err(format!(
                        "primitive {k}: axis {}° is not a multiple of 15 in 0..360",
                        p.axis
                    ));
                }
                let a = (p.axis / 15) as f32 * AXIS_QUANTUM;
                if k > 0 {
                    x += STEP * a.cos();
                    y += STEP * a.sin();
                }
                out.push(Primitive {
                    shift: 0.0,
                    x,
                    y,
                    axis: a,
                    rho: p.rho,
                    side: p.sides.map(f32::to_radians),
                });
            }
            Ok((
                Curve {
                    kind,
                    prims: out,
                    dirs,
                },
                0.0,
            ))
        }
        JsonCurve::Drawn {
            kind,
            points,
            extra,
        } => {
            let kind = kind.as_deref().map(kind_of).transpose()?;
            drawn(kind, &points, extra)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_straight_line_lands_on_the_lattice() {
        let (c, worst) = curve_from_points(
            Kind::Stream,
            &[[10.2, 20.0], [40.2, 20.0]],
            8.0,
            [0.0; 2],
            [1, 1],
        )
        .unwrap();
        assert_eq!(c.prims.len(), 7);
        assert!(worst < 0.3, "{worst}");
        assert!(c.prims.iter().all(|p| p.axis == 0.0));
        assert_eq!((c.prims[0].x, c.prims[6].x), (10.0, 40.0));
        // A gentle arc (radius 40 px) is followed within a couple of pixels.
        let arc: Vec<[f32; 2]> = (0..=60)
            .map(|i| {
                let a = i as f32 / 60.0 * 1.5;
                [50.0 + 40.0 * a.sin(), 50.0 + 40.0 - 40.0 * a.cos()]
            })
            .collect();
        let (c, worst) = curve_from_points(Kind::Stream, &arc, 8.0, [0.0; 2], [1, 1]).unwrap();
        assert!(worst < 2.5, "arc: {worst} px");
        assert_eq!(c.prims.len(), (60.0f32 / STEP).round() as usize + 1);
        assert!(curve_from_points(Kind::Stream, &[[1.0, 1.0]], 8.0, [0.0; 2], [1, 1]).is_err());
    }
}
