//! The cartoon of a sketch (CZ06 §5, Fig. 17): each curve drawn as one brush stroke.
//!
//! A curve's key points are its primitive centres (a single primitive: the two ends of its
//! window, as [`super::vis::centre_line`]). A centripetal Catmull-Rom spline through them is
//! the stroke's skeleton; its ends run toward phantom points one [`STEP`] beyond the first
//! and last centre along those primitives' axes. Each Catmull-Rom segment is converted
//! exactly to a cubic Bézier ([`catmull_rom_bezier`]). The skeleton is sampled every
//! [`NODE_SPACING`] px of arc length; at each sample the stroke is w(t) wide (t the arc
//! length fraction), w = W·k·sin(πt)^0.6 (a brush that swells and narrows to a point at both
//! ends), and the two boundary splines are centripetal Catmull-Roms through the samples
//! offset by ±w/2 along the normal. The closed outline is the left boundary forward and the
//! right one back.
//!
//! Width W is `CartoonParams::width`; k weighs the kinds as outline drawings do: side
//! boundaries and sources (the silhouette) 1.3, occluding lines 1.15, dividing lines 1,
//! stream lines 0.85. The `direction` style moves the widest point to 30 % from the root
//! (t' = t^0.576 in the sine, so the stroke flicks out toward the tip) and adds arrow-heads
//! to strokes longer than four of them.
//!
//! Rendering goes through the anti-aliased rasteriser's mesh path ([`crate::render::raster`],
//! GPU and CPU mirror, 4× MSAA): each brush is triangulated into a strip between its two
//! boundaries (sampled [`RASTER_SUBDIV`] times per boundary segment), every triangle wound
//! front-facing, at its own depth so later brushes lie over earlier ones (stream lines first,
//! the silhouette last). Colours come from a palette texture, one texel per colour, every
//! vertex at its texel's centre (bilinear sampling there returns the texel). Geometry is
//! light sequential work per curve: CPU.

mod svg;

pub use svg::{to_svg, to_svg_with_backdrop};

use super::{Curve, Kind, Sketch, STEP};
use crate::base::colour::{linear_to_srgb, srgb_to_linear};
use crate::error::{Error, Result};
use crate::render::raster::{self, Frame, RasterParams, ScreenMesh, Texture};
use crate::Engine;
use image::RgbImage;
use std::collections::HashMap;
use std::f32::consts::PI;

/// Distance between the skeleton samples the boundary splines pass through, px.
pub const NODE_SPACING: f32 = 0.5 * STEP;
/// Points per boundary spline segment in the rasterised outline.
pub const RASTER_SUBDIV: usize = 4;
/// Exponent of the width profile sin(πt)^p.
pub const PROFILE_EXP: f32 = 0.6;
/// Where the direction style's stroke is widest, as a fraction from the root.
pub const DIRECTED_PEAK: f32 = 0.3;

/// How strokes are coloured.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Style {
    /// Dark ink.
    #[default]
    Ink,
    /// A colour per kind a–e ([`type_colour`]).
    Type,
    /// Hue by growth direction (the hue ring of `coif analyze`), arrow-heads toward the
    /// tips and strokes that flick out where the hair grows to.
    Direction,
}

impl Style {
    pub fn name(self) -> &'static str {
        match self {
            Style::Ink => "ink",
            Style::Type => "type",
            Style::Direction => "direction",
        }
    }
}

impl std::str::FromStr for Style {
    type Err = Error;
    fn from_str(s: &str) -> Result<Style> {
        match s {
            "ink" => Ok(Style::Ink),
            "type" => Ok(Style::Type),
            "direction" => Ok(Style::Direction),
            _ => Err(Error::Invalid(format!(
                "unknown cartoon style {s:?}: expected ink, type or direction"
            ))),
        }
    }
}

/// Cartoon settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartoonParams {
    /// Stroke width W, px (a dividing line's widest point; see the module docs).
    pub width: f32,
    pub style: Style,
    /// MSAA samples per pixel of the rasteriser: 4 or 1.
    pub samples: u32,
}

impl Default for CartoonParams {
    fn default() -> Self {
        CartoonParams {
            width: 3.0,
            style: Style::Ink,
            samples: 4,
        }
    }
}

impl CartoonParams {
    fn check(&self) -> Result<()> {
        if !(self.width.is_finite() && self.width > 0.0 && self.width <= 64.0) {
            return Err(Error::Invalid(format!(
                "cartoon stroke width {} px must lie in (0, 64]",
                self.width
            )));
        }
        Ok(())
    }
}

/// A cubic Bézier segment: start, two controls, end.
pub type Bezier = [[f32; 2]; 4];

/// One curve's brush stroke.
#[derive(Clone, Debug, PartialEq)]
pub struct Brush {
    /// Index of the curve in the sketch.
    pub curve: usize,
    pub kind: Kind,
    /// The skeleton: centripetal Catmull-Rom through the key points, as Béziers.
    pub skeleton: Vec<Bezier>,
    /// Boundary splines, both from the stroke's start to its end; they meet at the two tips.
    pub left: Vec<Bezier>,
    pub right: Vec<Bezier>,
    /// Linear RGB of each boundary segment (`left.len()` entries).
    pub colours: Vec<[f32; 3]>,
    /// Arrow-heads (tip, base corner, base corner) and their linear RGB.
    pub arrows: Vec<([[f32; 2]; 3], [f32; 3])>,
}

impl Brush {
    /// The closed outline as a polygon: the left boundary forward, the right one back, each
    /// segment sampled `subdiv` times (its end points included once).
    pub fn outline(&self, subdiv: usize) -> Vec<[f32; 2]> {
        let l = sample_beziers(&self.left, subdiv);
        let r = sample_beziers(&self.right, subdiv);
        let mut out = l;
        // The tips are shared: skip the right boundary's end and start points.
        out.extend(r.iter().rev().skip(1).take(r.len().saturating_sub(2)));
        out
    }

    /// The colour at the middle of the stroke (the SVG fill).
    pub fn mid_colour(&self) -> [f32; 3] {
        self.colours
            .get(self.colours.len() / 2)
            .copied()
            .unwrap_or([0.0; 3])
    }
}

// ---------------------------------------------------------------------------------------------
// Splines

fn sub(a: [f32; 2], b: [f32; 2]) -> [f32; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn add_scaled(a: [f32; 2], b: [f32; 2], s: f32) -> [f32; 2] {
    [a[0] + s * b[0], a[1] + s * b[1]]
}

fn dist(a: [f32; 2], b: [f32; 2]) -> f32 {
    let d = sub(a, b);
    (d[0] * d[0] + d[1] * d[1]).sqrt()
}

/// Knot spacing of the centripetal parameterisation, |Δp|^½ (guarded against repeats).
fn knot(a: [f32; 2], b: [f32; 2]) -> f32 {
    dist(a, b).sqrt().max(1e-4)
}

/// The centripetal Catmull-Rom segment from p1 to p2 (neighbours p0, p3) at s in [0, 1],
/// by Barry and Goldman's pyramid of linear interpolations.
pub fn catmull_rom_point(p: [[f32; 2]; 4], s: f32) -> [f32; 2] {
    let t0 = 0.0f32;
    let t1 = t0 + knot(p[0], p[1]);
    let t2 = t1 + knot(p[1], p[2]);
    let t3 = t2 + knot(p[2], p[3]);
    let t = t1 + s * (t2 - t1);
    let lerp = |a: [f32; 2], b: [f32; 2], ta: f32, tb: f32| {
        let w = (t - ta) / (tb - ta);
        [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])]
    };
    let a1 = lerp(p[0], p[1], t0, t1);
    let a2 = lerp(p[1], p[2], t1, t2);
    let a3 = lerp(p[2], p[3], t2, t3);
    let b1 = lerp(a1, a2, t0, t2);
    let b2 = lerp(a2, a3, t1, t3);
    lerp(b1, b2, t1, t2)
}

/// The same segment as a cubic Bézier, exactly: the pyramid is a cubic whose derivatives at
/// p1 and p2 are m1, m2 below (in the knot parameter); scaled to [0, 1] they give the
/// Hermite form, and Bézier controls p1 + m1·Δt/3, p2 − m2·Δt/3.
pub fn catmull_rom_bezier(p: [[f32; 2]; 4]) -> Bezier {
    let d01 = knot(p[0], p[1]);
    let d12 = knot(p[1], p[2]);
    let d23 = knot(p[2], p[3]);
    let m1: [f32; 2] = std::array::from_fn(|k| {
        (p[1][k] - p[0][k]) / d01 - (p[2][k] - p[0][k]) / (d01 + d12) + (p[2][k] - p[1][k]) / d12
    });
    let m2: [f32; 2] = std::array::from_fn(|k| {
        (p[2][k] - p[1][k]) / d12 - (p[3][k] - p[1][k]) / (d12 + d23) + (p[3][k] - p[2][k]) / d23
    });
    [
        p[1],
        add_scaled(p[1], m1, d12 / 3.0),
        add_scaled(p[2], m2, -d12 / 3.0),
        p[2],
    ]
}

/// A centripetal Catmull-Rom spline through `pts` (consecutive repeats dropped), with
/// phantom neighbours `lead` before the first and `tail` after the last; as Béziers.
pub fn catmull_rom_spline(pts: &[[f32; 2]], lead: [f32; 2], tail: [f32; 2]) -> Vec<Bezier> {
    let mut q: Vec<[f32; 2]> = Vec::with_capacity(pts.len() + 2);
    q.push(lead);
    for &p in pts {
        if q.len() == 1 || dist(p, q[q.len() - 1]) > 1e-3 {
            q.push(p);
        }
    }
    q.push(tail);
    q.windows(4)
        .map(|w| catmull_rom_bezier([w[0], w[1], w[2], w[3]]))
        .collect()
}

/// Point of a Bézier at s in [0, 1] (de Casteljau).
pub fn bezier_point(b: &Bezier, s: f32) -> [f32; 2] {
    let u = 1.0 - s;
    std::array::from_fn(|k| {
        u * u * u * b[0][k]
            + 3.0 * u * u * s * b[1][k]
            + 3.0 * u * s * s * b[2][k]
            + s * s * s * b[3][k]
    })
}

/// Derivative of a Bézier at s.
pub fn bezier_tangent(b: &Bezier, s: f32) -> [f32; 2] {
    let u = 1.0 - s;
    std::array::from_fn(|k| {
        3.0 * u * u * (b[1][k] - b[0][k])
            + 6.0 * u * s * (b[2][k] - b[1][k])
            + 3.0 * s * s * (b[3][k] - b[2][k])
    })
}

/// Every segment sampled `subdiv` times, shared end points once.
pub fn sample_beziers(bs: &[Bezier], subdiv: usize) -> Vec<[f32; 2]> {
    let n = subdiv.max(1);
    let mut out = Vec::with_capacity(bs.len() * n + 1);
    for (i, b) in bs.iter().enumerate() {
        let start = if i == 0 { 0 } else { 1 };
        for k in start..=n {
            out.push(bezier_point(b, k as f32 / n as f32));
        }
    }
    out
}

/// The key points of a curve: its primitive centres; a single primitive gives the two ends
/// of its window.
pub fn key_points(c: &Curve) -> Vec<[f32; 2]> {
    super::vis::centre_line(c)
}

/// The skeleton of a curve: a centripetal Catmull-Rom through its key points, the phantom
/// end points one [`STEP`] out along the first and last axes. Empty for a curve without
/// primitives.
pub fn skeleton(c: &Curve) -> Vec<Bezier> {
    let pts = key_points(c);
    if pts.len() < 2 {
        return Vec::new();
    }
    let (f, l) = (&c.prims[0], &c.prims[c.prims.len() - 1]);
    let lead = add_scaled(pts[0], f.tangent(), -STEP);
    let tail = add_scaled(pts[pts.len() - 1], l.tangent(), STEP);
    catmull_rom_spline(&pts, lead, tail)
}

/// The width profile: w(t)/(W·k) at arc-length fraction t; `peak` is where it is widest
/// (0.5 symmetric).
pub fn profile(t: f32, peak: f32) -> f32 {
    let t = t.clamp(0.0, 1.0);
    // t^γ = ½ at t = peak, so sin(π t^γ) is 1 there.
    let g = if (peak - 0.5).abs() < 1e-6 {
        1.0
    } else {
        0.5f32.ln() / peak.ln()
    };
    (PI * t.powf(g)).sin().max(0.0).powf(PROFILE_EXP)
}

/// Weight of a kind's stroke width (module docs).
pub fn kind_weight(k: Kind) -> f32 {
    match k {
        Kind::Boundary | Kind::Source => 1.3,
        Kind::Occluding => 1.15,
        Kind::Dividing => 1.0,
        Kind::Stream => 0.85,
    }
}

// ---------------------------------------------------------------------------------------------
// Colours

fn srgb8(c: [u8; 3]) -> [f32; 3] {
    c.map(srgb_to_linear)
}

/// The ink of the ink style (sRGB #1c1c22).
pub const INK: [u8; 3] = [28, 28, 34];
/// Strokes with no known growth direction in the direction style (sRGB gray).
pub const UNDIRECTED: [u8; 3] = [120, 120, 120];

/// A kind's colour in the type style, sRGB: `sketch::vis::kind_colour`'s (a blue,
/// b violet, c orange, d red), except the stream line, white there over a dimmed photo and
/// here a dark slate so it shows on paper as over a photo.
pub fn type_colour(k: Kind) -> [u8; 3] {
    match k {
        Kind::Stream => [70, 80, 96],
        _ => super::vis::kind_colour(k).0,
    }
}

/// The direction style's colour of a growth direction, sRGB: the hue of `coif analyze`'s
/// hue ring (`io::vis::direction_colour`) at value 0.8, so that yellows show on paper;
/// hues are rounded to whole degrees (the palette texture holds at most 360 of them).
pub fn direction_colour(g: [f32; 2]) -> [u8; 3] {
    let deg = g[1].atan2(g[0]).to_degrees().round();
    crate::io::vis::hsv(deg, 0.9, 0.8).0
}

/// Growth vector of a curve at each key point: the mean over the primitive's labelled hair
/// sides of label × that side's flow vector (zero where no side is labelled, and near zero
/// on a dividing line whose two sides leave it in opposite directions).
fn growth(c: &Curve) -> Vec<[f32; 2]> {
    let hair = c.kind.hair_sides();
    let per_prim: Vec<[f32; 2]> = c
        .prims
        .iter()
        .map(|p| {
            let (mut g, mut n) = ([0.0f32; 2], 0);
            for (s, &has_hair) in hair.iter().enumerate() {
                if has_hair && c.dirs[s] != 0 {
                    let a = p.side_angle(s);
                    let l = c.dirs[s] as f32;
                    g = [g[0] + l * a.cos(), g[1] + l * a.sin()];
                    n += 1;
                }
            }
            if n > 0 {
                g.map(|v| v / n as f32)
            } else {
                g
            }
        })
        .collect();
    if per_prim.len() == 1 {
        vec![per_prim[0]; 2]
    } else {
        per_prim
    }
}

// ---------------------------------------------------------------------------------------------
// Brushes

/// Arc length positions of a dense sampling of the skeleton: (segment, s, point, cumulative
/// length).
struct ArcTable {
    rows: Vec<(usize, f32, f32)>,
    length: f32,
}

const ARC_SUBDIV: usize = 32;

impl ArcTable {
    fn new(sk: &[Bezier]) -> ArcTable {
        let mut rows = vec![(0usize, 0.0f32, 0.0f32)];
        let mut len = 0.0;
        for (i, b) in sk.iter().enumerate() {
            let mut prev = b[0];
            for k in 1..=ARC_SUBDIV {
                let s = k as f32 / ARC_SUBDIV as f32;
                let q = bezier_point(b, s);
                len += dist(prev, q);
                prev = q;
                rows.push((i, s, len));
            }
        }
        ArcTable { rows, length: len }
    }

    /// (segment, s) at arc length `l`, linear between table rows.
    fn at(&self, l: f32) -> (usize, f32) {
        let k = self
            .rows
            .partition_point(|r| r.2 < l)
            .clamp(1, self.rows.len() - 1);
        let (a, b) = (self.rows[k - 1], self.rows[k]);
        let w = if b.2 > a.2 {
            ((l - a.2) / (b.2 - a.2)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        // Rows of one segment: interpolate s; the first row of a segment starts at s = 0.
        let sa = if a.0 == b.0 { a.1 } else { 0.0 };
        (b.0, sa + w * (b.1 - sa))
    }
}

fn unit(v: [f32; 2]) -> [f32; 2] {
    let n = (v[0] * v[0] + v[1] * v[1]).sqrt();
    if n > 1e-12 {
        [v[0] / n, v[1] / n]
    } else {
        [1.0, 0.0]
    }
}

/// One curve's brush, or None for a curve without primitives.
pub fn brush(index: usize, c: &Curve, p: &CartoonParams) -> Option<Brush> {
    let sk = skeleton(c);
    if sk.is_empty() {
        return None;
    }
    let arc = ArcTable::new(&sk);
    let g = growth(c);
    // Whether the hair grows along the curve (+1), against it (−1), or across it (0).
    let along: f32 = {
        let mut dot = 0.0;
        for (k, b) in sk.iter().enumerate() {
            let t = unit(bezier_tangent(b, 0.5));
            let gm = [0.5 * (g[k][0] + g[k + 1][0]), 0.5 * (g[k][1] + g[k + 1][1])];
            dot += gm[0] * t[0] + gm[1] * t[1];
        }
        let mean = dot / sk.len() as f32;
        if mean > 0.3 {
            1.0
        } else if mean < -0.3 {
            -1.0
        } else {
            0.0
        }
    };
    let directed = p.style == Style::Direction && along != 0.0;
    let peak = if directed { DIRECTED_PEAK } else { 0.5 };
    let w_max = p.width * kind_weight(c.kind);
    let n = ((arc.length / NODE_SPACING).ceil() as usize).max(4);
    let mut centres = Vec::with_capacity(n + 1);
    let mut left = Vec::with_capacity(n + 1);
    let mut right = Vec::with_capacity(n + 1);
    let mut node_g = Vec::with_capacity(n + 1);
    for i in 0..=n {
        let t = i as f32 / n as f32;
        let (seg, s) = arc.at(t * arc.length);
        let b = &sk[seg];
        let c0 = bezier_point(b, s);
        let tan = unit(bezier_tangent(b, s));
        let nl = [tan[1], -tan[0]];
        // Root at t = 0 when the hair grows along the curve, at t = 1 when against it.
        let from_root = if along < 0.0 { 1.0 - t } else { t };
        let half = 0.5 * w_max * profile(from_root, peak);
        centres.push((c0, tan));
        left.push(add_scaled(c0, nl, half));
        right.push(add_scaled(c0, nl, -half));
        node_g.push([
            g[seg][0] + s * (g[seg + 1][0] - g[seg][0]),
            g[seg][1] + s * (g[seg + 1][1] - g[seg][1]),
        ]);
    }
    // The tips are exact points (w = 0 there): both boundaries meet at them.
    let reflect = |a: [f32; 2], b: [f32; 2]| add_scaled(a, sub(a, b), 1.0);
    let boundary = |pts: &[[f32; 2]]| {
        catmull_rom_spline(
            pts,
            reflect(pts[0], pts[1]),
            reflect(pts[pts.len() - 1], pts[pts.len() - 2]),
        )
    };
    let (lb, rb) = (boundary(&left), boundary(&right));
    let colour = |gv: [f32; 2]| match p.style {
        Style::Ink => srgb8(INK),
        Style::Type => srgb8(type_colour(c.kind)),
        Style::Direction => {
            if (gv[0] * gv[0] + gv[1] * gv[1]).sqrt() < 0.25 {
                srgb8(UNDIRECTED)
            } else {
                srgb8(direction_colour(gv))
            }
        }
    };
    let colours: Vec<[f32; 3]> = (0..lb.len())
        .map(|i| {
            let (a, b) = (node_g[i], node_g[(i + 1).min(n)]);
            colour([0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])])
        })
        .collect();
    let mut arrows = Vec::new();
    let size = 1.2 * p.width + 1.5;
    // One arrow-head per 60 px of stroke, pointing where the hair grows; strokes shorter
    // than four arrow-heads show the way by their taper alone (arrows would clutter them).
    if directed && arc.length >= 4.0 * size {
        let count = ((arc.length / 60.0).round() as usize).max(1);
        for k in 0..count {
            let t = (k as f32 + 0.5) / count as f32;
            let i = ((t * n as f32).round() as usize).min(n);
            let (c0, tan) = centres[i];
            let u = [along * tan[0], along * tan[1]];
            let nl = [u[1], -u[0]];
            let tip = add_scaled(c0, u, size);
            let base = add_scaled(c0, u, -0.5 * size);
            arrows.push((
                [
                    tip,
                    add_scaled(base, nl, 0.75 * size),
                    add_scaled(base, nl, -0.75 * size),
                ],
                colour(node_g[i]),
            ));
        }
    }
    Some(Brush {
        curve: index,
        kind: c.kind,
        skeleton: sk,
        left: lb,
        right: rb,
        colours,
        arrows,
    })
}

/// Draw rank of a kind: stream lines first, the silhouette last (on top).
fn rank(k: Kind) -> usize {
    match k {
        Kind::Stream => 0,
        Kind::Dividing => 1,
        Kind::Occluding => 2,
        Kind::Source => 3,
        Kind::Boundary => 4,
    }
}

/// Every curve's brush, in drawing order (stream lines first, side boundaries last; in
/// sketch order within a kind). Curves without primitives have none.
pub fn brushes(s: &Sketch, p: &CartoonParams) -> Vec<Brush> {
    let mut order: Vec<usize> = (0..s.curves.len()).collect();
    order.sort_by_key(|&i| (rank(s.curves[i].kind), i));
    order
        .into_iter()
        .filter_map(|i| brush(i, &s.curves[i], p))
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Rendering

/// Triangles of one brush, wound front-facing: (corners, colour). The strip between the two
/// boundaries, each quad split in two, then the arrow-heads.
pub fn triangles(b: &Brush) -> Vec<([[f32; 2]; 3], [f32; 3])> {
    let l = sample_beziers(&b.left, RASTER_SUBDIV);
    let r = sample_beziers(&b.right, RASTER_SUBDIV);
    let mut out = Vec::with_capacity(2 * l.len() + b.arrows.len());
    for i in 0..l.len().min(r.len()).saturating_sub(1) {
        let col = b.colours[(i / RASTER_SUBDIV).min(b.colours.len() - 1)];
        out.push(([l[i], r[i], l[i + 1]], col));
        out.push(([r[i], r[i + 1], l[i + 1]], col));
    }
    out.extend(b.arrows.iter().copied());
    out
}

/// The corners ordered counter-clockwise as the image is viewed (y down), which is what the
/// rasteriser takes as front-facing: a fold in a boundary must not cull part of a stroke.
fn front_facing(t: [[f32; 2]; 3]) -> [[f32; 2]; 3] {
    let e1 = sub(t[1], t[0]);
    let e2 = sub(t[2], t[0]);
    if e1[0] * e2[1] - e1[1] * e2[0] > 0.0 {
        [t[0], t[2], t[1]]
    } else {
        t
    }
}

/// The brushes as one textured mesh: each brush at its own depth (1, 2, ... in drawing
/// order; the frame's depth range is (0, brushes + 1)), colours from a palette texture.
pub fn mesh(brushes: &[Brush]) -> ScreenMesh {
    let mut palette: Vec<[f32; 3]> = Vec::new();
    let mut index: HashMap<[u32; 3], usize> = HashMap::new();
    let mut tris: Vec<([[f32; 2]; 3], usize, f32)> = Vec::new();
    for (k, b) in brushes.iter().enumerate() {
        for (t, c) in triangles(b) {
            let key = c.map(f32::to_bits);
            let id = *index.entry(key).or_insert_with(|| {
                palette.push(c);
                palette.len() - 1
            });
            tris.push((front_facing(t), id, (k + 1) as f32));
        }
    }
    // A square-ish texture keeps both sides far below any device limit.
    let n = palette.len().max(1);
    let tw = (n as f32).sqrt().ceil() as usize;
    let th = n.div_ceil(tw);
    let mut texels = vec![[1.0f32; 4]; tw * th];
    for (i, c) in palette.iter().enumerate() {
        texels[i] = [c[0], c[1], c[2], 1.0];
    }
    let uv = |i: usize| {
        [
            ((i % tw) as f32 + 0.5) / tw as f32,
            ((i / tw) as f32 + 0.5) / th as f32,
        ]
    };
    let mut positions = Vec::with_capacity(3 * tris.len());
    let mut uvs = Vec::with_capacity(3 * tris.len());
    let mut triangles = Vec::with_capacity(tris.len());
    for (t, id, depth) in tris {
        let base = positions.len() as u32;
        for q in t {
            positions.push([q[0], q[1], depth]);
            uvs.push(uv(id));
        }
        triangles.push([base, base + 1, base + 2]);
    }
    ScreenMesh {
        positions,
        uvs,
        triangles,
        texture: Texture {
            width: tw as u32,
            height: th as u32,
            texels,
        },
    }
}

/// The cartoon of `s` on white paper, or over `over` (which must be the sketch's size),
/// through the rasteriser on the engine's backend.
pub fn render(
    engine: &Engine,
    s: &Sketch,
    p: &CartoonParams,
    over: Option<&RgbImage>,
) -> Result<RgbImage> {
    p.check()?;
    let (w, h) = (s.width, s.height);
    let background: Vec<[f32; 4]> = match over {
        Some(img) => {
            if img.dimensions() != (w, h) {
                return Err(Error::Invalid(format!(
                    "the backdrop is {}x{} px but the sketch is {w}x{h}",
                    img.width(),
                    img.height()
                )));
            }
            img.pixels()
                .map(|q| {
                    let c = q.0.map(srgb_to_linear);
                    [c[0], c[1], c[2], 1.0]
                })
                .collect()
        }
        None => vec![[1.0; 4]; w as usize * h as usize],
    };
    let bs = brushes(s, p);
    let m = mesh(&bs);
    let frame = Frame {
        width: w,
        height: h,
        depth_range: (0.0, bs.len() as f32 + 1.0),
        background: Some(background),
    };
    let rp = RasterParams {
        samples: p.samples,
        ..Default::default()
    };
    let px = raster::render(engine, &frame, Some(&m), None, &rp)?;
    let mut img = RgbImage::new(w, h);
    for (q, c) in img.pixels_mut().zip(&px) {
        q.0 = [
            linear_to_srgb(c[0]),
            linear_to_srgb(c[1]),
            linear_to_srgb(c[2]),
        ];
    }
    Ok(img)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_peaks_where_asked() {
        assert!((profile(0.5, 0.5) - 1.0).abs() < 1e-6);
        assert!((profile(DIRECTED_PEAK, DIRECTED_PEAK) - 1.0).abs() < 1e-5);
        assert_eq!(profile(0.0, 0.5), 0.0);
        assert!(profile(1.0, 0.5) < 1e-3);
    }

    #[test]
    fn styles_parse_and_name() {
        for s in [Style::Ink, Style::Type, Style::Direction] {
            assert_eq!(s.name().parse::<Style>().unwrap(), s);
        }
        assert!("pencil".parse::<Style>().is_err());
    }
}
