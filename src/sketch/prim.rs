//! The primitive dictionary's windows and the sketch's part of the vector field, V_sk
//! (CZ06 Eq. 8): each primitive paints the pixels of its window with the orientation,
//! contrast and (once the curve's labels are known) direction of the side they lie on.
//!
//! A window is a rectangle centred on the primitive, [`ALONG`] pixels along the axis and
//! [`ACROSS`] across it ([`ACROSS_DIVIDING`] for a dividing line, whose middle strip is the
//! scalp and carries no flow). Light sequential work over a few thousand pixels: CPU.

use super::{Curve, Kind, Primitive};

/// Window length along the axis, pixels.
pub const ALONG: f32 = 7.0;
/// Window width across the axis, pixels.
pub const ACROSS: f32 = 5.0;
/// A dividing line's window is wider: its middle strip (|offset| < 1) is the parting.
pub const ACROSS_DIVIDING: f32 = 6.0;
/// Half-width of a dividing line's scalp strip.
pub const STRIP: f32 = 1.0;
/// Tolerance of the window's edges and of the axis, px.
const EDGE_EPS: f32 = 1e-3;

/// Where a window pixel lies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Left,
    Right,
    /// A dividing line's scalp strip.
    Strip,
}

impl Side {
    pub fn index(self) -> Option<usize> {
        match self {
            Side::Left => Some(0),
            Side::Right => Some(1),
            Side::Strip => None,
        }
    }
}

/// Calls `f(pixel index, side)` for every pixel of `p`'s window within a w×h image (see
/// [`classify`]): a window centred on a pixel centre covers 7×5 pixels, one centred on a
/// pixel corner 6×4 (centres on the edges are out). A
/// pixel whose centre lies on the axis counts as left. The right side of a and b (non-hair) is
/// visited too: callers decide what it means.
pub fn window(kind: Kind, p: &Primitive, w: u32, h: u32, mut f: impl FnMut(usize, Side)) {
    let across = if kind == Kind::Dividing {
        ACROSS_DIVIDING
    } else {
        ACROSS
    };
    let (t, n) = (p.tangent(), p.left_normal());
    around(p, 0.5 * across, w, h, |k, d| {
        if let Some(side) = classify(kind == Kind::Dividing, t, n, d) {
            f(k, side);
        }
    });
}

/// Calls `f(pixel index, offset of its centre from p's centre)` for every pixel of the w×h
/// image within the square that holds a rectangle [`ALONG`] long and 2·`half_across` wide
/// around `p`, whatever its axis: the scan [`window`] and [`beside`] pick their pixels from.
fn around(p: &Primitive, half_across: f32, w: u32, h: u32, mut f: impl FnMut(usize, [f32; 2])) {
    let r = ((0.5 * ALONG).hypot(half_across)).ceil() as i64 + 1;
    let (cx, cy) = (p.x.floor() as i64, p.y.floor() as i64);
    for j in (cy - r).max(0)..=(cy + r).min(h as i64 - 1) {
        for i in (cx - r).max(0)..=(cx + r).min(w as i64 - 1) {
            let d = [i as f32 + 0.5 - p.x, j as f32 + 0.5 - p.y];
            f(j as usize * w as usize + i as usize, d);
        }
    }
}

/// Calls `f(pixel index, side index)` for every pixel centre beside `p`'s axis: within the
/// window's length along it ([`ALONG`]) and `near` to `far` px across it, on the left (0) or
/// the right (1). Unlike [`window`], whatever the kind and ownership: it is where a side's
/// flow is read, not what the primitive paints.
pub fn beside(p: &Primitive, w: u32, h: u32, near: f32, far: f32, mut f: impl FnMut(usize, usize)) {
    across(p, w, h, far, |k, c| {
        if c.abs() >= near {
            f(k, (c < 0.0) as usize);
        }
    });
}

/// Calls `f(pixel index, signed offset of its centre across the axis, + left)` for every
/// pixel centre within the window's length along `p`'s axis ([`ALONG`]) and less than `far`
/// px across it.
pub fn across(p: &Primitive, w: u32, h: u32, far: f32, mut f: impl FnMut(usize, f32)) {
    let (t, n) = (p.tangent(), p.left_normal());
    around(p, far, w, h, |k, d| {
        let a = d[0] * t[0] + d[1] * t[1];
        let c = d[0] * n[0] + d[1] * n[1];
        if a.abs() < 0.5 * ALONG - EDGE_EPS && c.abs() < far {
            f(k, c);
        }
    });
}

/// Where a pixel centre at offset `d` from a primitive's centre falls in its window, given
/// the axis's unit tangent `t` and left normal `n` (None: outside). The one rule for the
/// windows, shared with the pursuit's window sums: pixel centres strictly inside the
/// rectangle, a centre within a tolerance of an edge counting as outside, so f32 rounding
/// (sin π ≠ 0) does not decide and a reversed curve covers the same pixels.
pub fn classify(dividing: bool, t: [f32; 2], n: [f32; 2], d: [f32; 2]) -> Option<Side> {
    let across = if dividing { ACROSS_DIVIDING } else { ACROSS };
    let (ba, bc) = (0.5 * ALONG - EDGE_EPS, 0.5 * across - EDGE_EPS);
    let a = d[0] * t[0] + d[1] * t[1];
    let c = d[0] * n[0] + d[1] * n[1];
    if a.abs() >= ba || c.abs() >= bc {
        return None;
    }
    Some(if dividing && c.abs() < STRIP - EDGE_EPS {
        Side::Strip
    } else if c >= -EDGE_EPS {
        Side::Left
    } else {
        Side::Right
    })
}

/// V_sk: the sketch's pixels and what they carry.
#[derive(Clone, Debug)]
pub struct Painted {
    pub width: u32,
    pub height: u32,
    /// Orientation in [0, π) on the sketch's hair pixels, NaN elsewhere.
    pub theta: Vec<f32>,
    /// Direction angle τ in [0, 2π) where the curve's label on that side is known, NaN
    /// elsewhere (undirected curves, a dividing line's strip, off the sketch).
    pub tau: Vec<f32>,
    /// Contrast on the sketch, NaN elsewhere.
    pub rho: Vec<f32>,
    /// Pixels any window covers (including non-hair sides and strips): Λ_sk.
    pub on: Vec<bool>,
    /// Index of the curve that painted the pixel, u32::MAX off the sketch.
    pub curve: Vec<u32>,
}

/// Paints V_sk from `curves` on a w×h image (Eq. 8). A pixel keeps the first primitive that
/// reaches it, in curve order then primitive order. `hair`, when given, limits the painted
/// flow to hair pixels (the non-hair side of a and b is never painted with flow).
pub fn paint(curves: &[Curve], w: u32, h: u32, hair: Option<&[bool]>) -> Painted {
    let n = w as usize * h as usize;
    let mut out = Painted {
        width: w,
        height: h,
        theta: vec![f32::NAN; n],
        tau: vec![f32::NAN; n],
        rho: vec![f32::NAN; n],
        on: vec![false; n],
        curve: vec![u32::MAX; n],
    };
    for (ci, c) in curves.iter().enumerate() {
        let hair_sides = c.kind.hair_sides();
        for p in &c.prims {
            window(c.kind, p, w, h, |k, side| {
                if out.on[k] {
                    return;
                }
                out.on[k] = true;
                out.curve[k] = ci as u32;
                let Some(s) = side.index() else { return };
                if !hair_sides[s] || hair.is_some_and(|m| !m[k]) {
                    return;
                }
                let a = p.side_angle(s);
                out.theta[k] = super::wrap_pi(a);
                out.rho[k] = p.rho;
                let label = c.dirs[s];
                if label != 0 {
                    let tau = if label > 0 {
                        a
                    } else {
                        a + std::f32::consts::PI
                    };
                    out.tau[k] = tau.rem_euclid(2.0 * std::f32::consts::PI);
                }
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    fn prim(x: f32, y: f32, axis: f32, side: [f32; 2]) -> Primitive {
        Primitive {
            shift: 0.0,
            x,
            y,
            axis,
            rho: 10.0,
            side,
        }
    }

    /// The band beside a primitive: pixel centres `near` to `far` px from the axis within
    /// the window's length, left (the normal's side) 0 and right 1.
    #[test]
    fn beside_visits_the_band_on_both_sides() {
        // Along +x at y = 10: the left normal (sin a, −cos a) points to −y.
        let p = prim(10.5, 10.5, 0.0, [0.0; 2]);
        let mut seen = Vec::new();
        beside(&p, 21, 21, 1.0, 2.5, |k, s| seen.push((k % 21, k / 21, s)));
        // Columns 7..=13 (|a| < 3.5), rows 8 and 9 on the left, 11 and 12 on the right.
        assert_eq!(seen.len(), 7 * 4);
        for &(x, y, s) in &seen {
            assert!((7..=13).contains(&x), "{x}");
            assert_eq!(s, if y < 10 { 0 } else { 1 }, "({x}, {y})");
            assert!([8, 9, 11, 12].contains(&y), "{y}");
        }
    }

    #[test]
    fn window_has_the_dictionary_size() {
        let mut count = [0usize; 3];
        window(
            Kind::Stream,
            &prim(20.5, 20.5, 0.0, [0.0; 2]),
            40,
            40,
            |_, s| {
                count[match s {
                    Side::Left => 0,
                    Side::Right => 1,
                    Side::Strip => 2,
                }] += 1
            },
        );
        // 7 along × 5 across, centre row on the axis counts as left.
        assert_eq!(count, [21, 14, 0]);
        let mut strip = 0;
        window(
            Kind::Dividing,
            &prim(20.0, 20.0, 0.0, [PI / 2.0; 2]),
            40,
            40,
            |_, s| strip += (s == Side::Strip) as usize,
        );
        // Centred on a pixel corner: 6 columns, and the two rows beside the axis are strip.
        assert_eq!(strip, 12);
    }

    #[test]
    fn a_reversed_primitive_covers_the_same_pixels() {
        for (x, y) in [(20.0, 20.0), (20.5, 20.5), (20.3, 19.7)] {
            for k in 0..24 {
                let a = k as f32 * crate::sketch::AXIS_QUANTUM;
                let mut fwd = Vec::new();
                let mut back = Vec::new();
                window(Kind::Stream, &prim(x, y, a, [0.0; 2]), 40, 40, |i, _| {
                    fwd.push(i)
                });
                let rev = prim(x, y, (a + PI).rem_euclid(2.0 * PI), [0.0; 2]);
                window(Kind::Stream, &rev, 40, 40, |i, _| back.push(i));
                fwd.sort_unstable();
                back.sort_unstable();
                assert_eq!(fwd, back, "centre ({x}, {y}), axis step {k}");
            }
        }
    }

    #[test]
    fn dividing_line_paints_outward_directions() {
        let c = Curve {
            kind: Kind::Dividing,
            prims: vec![prim(20.0, 20.0, 0.0, [PI / 2.0; 2])],
            dirs: [1, 1],
        };
        let v = paint(&[c], 40, 40, None);
        // Above the axis (left, y smaller) hair grows up (τ = 3π/2), below it grows down.
        let above = 18 * 40 + 20;
        let below = 22 * 40 + 20;
        assert!((v.tau[above] - 1.5 * PI).abs() < 1e-5, "{}", v.tau[above]);
        assert!((v.tau[below] - 0.5 * PI).abs() < 1e-5, "{}", v.tau[below]);
        assert!(v.theta[20 * 40 + 20].is_nan() && v.on[20 * 40 + 20]);
    }
}
