//! The generative sketch model of Chen and Zhu 2006 (CZ06): a hair image as three layers,
//! a sketch S (curves of directed primitives), a vector field V = (Θ, ρ, d) filled in from
//! the sketch, and the image bands (a smooth low band of Gaussian shading bases plus a
//! high band of texture, coloured by a map from gray to (u, v)).
//!
//! This file holds the types every part shares and their geometric conventions; the parts:
//! `bands` (Luv, the bands, the colour map), `shading` (the low band's bases by matching
//! pursuit), `prim` (the primitive dictionary, windows, and V_sk painted from a sketch,
//! Eq. 8), `theta` (Θ by Eq. 25), `pursuit` (sketch pursuit, Eq. 24, 26-27), `swc`
//! (directions by Swendsen-Wang cuts, Eq. 28-30), `fill` (V from the sketch, Eq. 14-17),
//! `format` (`.czs`, `sketch.json`, `sketch.svg`).
//!
//! Conventions (`analyze`'s): images row-major W*H, pixel (i, j) at index j*W + i with its
//! centre at (i + 0.5, j + 0.5) in sketch coordinates; x right, y down; angles measured from +x
//! towards +y (clockwise on screen). An orientation Θ is in [0, π); a direction is a unit
//! vector or an angle τ in [0, 2π).
//!
//! A primitive's axis is the direction in which its curve is traversed, in [0, 2π). Its left
//! side is the side of n_l = (sin a, −cos a) (left as seen walking along the axis with y
//! down), its right side n_r = −n_l. The hair orientation on the left is the axis turned by
//! −side[0], on the right by +side[1], so a positive side angle leans the flow away from the
//! axis on both sides (mirror-symmetric): a dividing line with side angles π/2 has its flow
//! leaving it perpendicularly on both sides. A side's direction label ±1 says whether hair
//! grows along that side's flow vector (+1) or against it (−1); labels are relative to the
//! traversal, so reversing a curve changes nothing but flips nothing either: the vectors
//! reverse with the axis and the labels stay.

pub mod bands;
pub mod cartoon;
pub mod edit;
pub mod fill;
pub mod format;
pub mod oracle;
pub mod pairwise;
pub mod prim;
pub mod prune;
pub mod pursuit;
pub mod region;
pub mod rho;
pub mod run;
pub mod samples;
pub mod shading;
pub mod swc;
pub mod synth;
pub mod texture;
pub mod theta;
pub mod vis;

use serde::{Deserialize, Serialize};
use std::f32::consts::PI;

/// The five primitive types of CZ06 §2.1 (Fig. 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// (a) Side boundary: hair runs along the curve on its left, non-hair on its right.
    Boundary,
    /// (b) Source or sink: hair starts or ends at the curve (left side), non-hair on the right.
    Source,
    /// (c) Occluding line: two clusters of different orientation meet; one runs along it.
    Occluding,
    /// (d) Dividing line: same orientation on both sides, directions outward (a parting).
    Dividing,
    /// (e) Stream line: same orientation and direction on both sides, high contrast.
    Stream,
}

impl Kind {
    pub const ALL: [Kind; 5] = [
        Kind::Boundary,
        Kind::Source,
        Kind::Occluding,
        Kind::Dividing,
        Kind::Stream,
    ];

    /// The letter CZ06 Fig. 3 uses.
    pub fn letter(self) -> char {
        match self {
            Kind::Boundary => 'a',
            Kind::Source => 'b',
            Kind::Occluding => 'c',
            Kind::Dividing => 'd',
            Kind::Stream => 'e',
        }
    }

    pub fn from_letter(c: char) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.letter() == c)
    }

    /// Code in the `.czs` file (3 bits).
    pub fn code(self) -> u8 {
        self as u8
    }

    pub fn from_code(c: u8) -> Option<Kind> {
        Kind::ALL.get(c as usize).copied()
    }

    /// Which sides carry hair: a and b only the left one.
    pub fn hair_sides(self) -> [bool; 2] {
        match self {
            Kind::Boundary | Kind::Source => [true, false],
            _ => [true, true],
        }
    }

    /// Free direction variables (CZ06 §2.1: 1, 1, 2, 0, 1). The count of directed
    /// primitives is Σ 2^free = 2 + 2 + 4 + 1 + 2 = 11.
    pub fn free_dirs(self) -> usize {
        match self {
            Kind::Occluding => 2,
            Kind::Dividing => 0,
            _ => 1,
        }
    }
}

/// Step between consecutive primitive centres along a curve, in pixels.
pub const STEP: f32 = 5.0;
/// Angular lattice of the axes: 24 steps of 15°.
pub const AXIS_STEPS: u32 = 24;
/// A turn between consecutive primitives is −1, 0 or +1 lattice steps.
pub const AXIS_QUANTUM: f32 = 2.0 * PI / AXIS_STEPS as f32;

/// One primitive B = (ℓ, x, y, θ, ρ, θ_l, θ_r) of Eq. 2; its type is its curve's.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Primitive {
    /// Centre, pixels.
    pub x: f32,
    pub y: f32,
    /// Traversal direction, radians in [0, 2π), on the lattice of [`AXIS_QUANTUM`].
    pub axis: f32,
    /// Contrast ρ across the flow on the primitive (mean |∇⊥Θ I_H|, L* units).
    pub rho: f32,
    /// Side angles (left, right), radians: a dictionary angle (0, π/3, π/2, 2π/3) plus a
    /// refinement within ±π/6, so possibly slightly negative; see the module docs. A side
    /// without hair (the right of a and b) is 0 and ignored.
    pub side: [f32; 2],
    /// How far the centre lies off its curve's chain across the axis, px, to the left: an
    /// occluding line placed to a quarter pixel (`pursuit::place`); 0 for other kinds. The
    /// centre (x, y) is where the primitive is painted, shift included.
    #[serde(default)]
    pub shift: f32,
}

impl Primitive {
    /// Unit vector along the axis.
    pub fn tangent(&self) -> [f32; 2] {
        [self.axis.cos(), self.axis.sin()]
    }

    /// Unit normal towards the left side, (sin a, −cos a).
    pub fn left_normal(&self) -> [f32; 2] {
        [self.axis.sin(), -self.axis.cos()]
    }

    /// The flow vector on side `s` (0 left, 1 right) as an angle in [0, 2π): the axis turned
    /// by −side[0] on the left, +side[1] on the right. Its orientation is this mod π; a
    /// curve's direction label on that side says whether hair grows along it or against it.
    pub fn side_angle(&self, s: usize) -> f32 {
        let a = if s == 0 {
            self.axis - self.side[0]
        } else {
            self.axis + self.side[1]
        };
        a.rem_euclid(2.0 * PI)
    }
}

/// A curve: a chain of primitives of one type with one direction pair.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Curve {
    pub kind: Kind,
    pub prims: Vec<Primitive>,
    /// Direction labels (left, right), each ±1 (along or against that side's flow vector),
    /// 0 where the kind has no variable there: a and b use [d, 0]; c [d_l, d_r]; d is fixed
    /// outward, [1, 1]; e has one variable shared by both sides, [d, d].
    pub dirs: [i8; 2],
}

impl Curve {
    /// A straight stream line of `n` primitives `step` px apart along `axis` from (x, y),
    /// contrast `rho`, both labels `dir`, sides along the axis (the tests' curve).
    #[cfg(test)]
    pub(crate) fn straight(
        x: f32,
        y: f32,
        axis: f32,
        n: usize,
        step: f32,
        rho: f32,
        dir: i8,
    ) -> Curve {
        let (c, s) = (axis.cos(), axis.sin());
        Curve {
            kind: Kind::Stream,
            prims: (0..n)
                .map(|k| Primitive {
                    shift: 0.0,
                    x: x + step * k as f32 * c,
                    y: y + step * k as f32 * s,
                    axis,
                    rho,
                    side: [0.0; 2],
                })
                .collect(),
            dirs: [dir, dir],
        }
    }
}

/// One shading base of Eq. 1: α·G(x − x_i, y − y_i; θ_i, σx_i, σy_i), G unnormalised
/// (peak 1), α > 0 a highlight, < 0 a shadow.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Base {
    pub x: f32,
    pub y: f32,
    /// Orientation of the σx axis, radians in [0, π).
    pub theta: f32,
    pub sx: f32,
    pub sy: f32,
    /// Amplitude in gray units (L*, 0..100).
    pub amp: f32,
}

/// The low band: I_L = μ + Σ α_i G_i inside the hair.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Shading {
    /// Mean L* over the hair.
    pub mean: f32,
    pub bases: Vec<Base>,
}

/// Bins of the colour map over L* in [0, 100].
pub const COLOUR_BINS: usize = 16;

/// The colour map from gray (L*) to (u*, v*): the mean chroma of the hair's pixels in each
/// of [`COLOUR_BINS`] equal L* bins (empty bins interpolated from their neighbours).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ColourMap {
    pub uv: Vec<[f32; 2]>,
}

/// A whole sketch: what `hair.czs`, `sketch.json` and `sketch.svg` each hold.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sketch {
    pub width: u32,
    pub height: u32,
    /// Seed of the draws that synthesis makes from it (ρ off the sketch, texture noise).
    pub seed: u64,
    pub curves: Vec<Curve>,
    /// p_nsk: the contrast off the sketch.
    pub rho_off: RhoPrior,
    pub shading: Shading,
    pub colour: ColourMap,
    /// The hair region (see [`region`]): closed polygons on the pixel-corner lattice, even-odd;
    /// empty = the whole image.
    #[serde(default)]
    pub region: Region,
    /// Σ(∇_θ I_H)²/Σ(∇⊥ I_H)² of the analysed image under its Θ (Eq. 12's along-Θ variance
    /// relative to the contrast across, [`texture::along_across`]): synthesis adds grain
    /// up to it ([`texture::add_grain`]). None: not measured (a hand-drawn sketch, or a
    /// file written before it was stored), and synthesis adds none.
    #[serde(default)]
    pub along_across: Option<f32>,
}

/// Closed polygons of pixel-corner points (x in 0..=W, y in 0..=H), filled by the even-odd
/// rule.
pub type Region = Vec<Vec<[u32; 2]>>;

/// p_nsk of Eq. 5-6: a mixture of two Gaussians over the contrast ρ off the sketch (the
/// fill draws ρ there from it).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RhoPrior {
    pub weight: [f32; 2],
    pub mean: [f32; 2],
    pub sigma: [f32; 2],
}

/// The vector field V = (Θ, ρ, d) on the image's pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct VectorField {
    pub width: u32,
    pub height: u32,
    /// Orientation in [0, π); NaN where the field is not defined (off the hair).
    pub theta: Vec<f32>,
    /// Contrast across Θ; NaN off the hair.
    pub rho: Vec<f32>,
    /// Unit growth direction (dx, dy), ±(cos Θ, sin Θ); NaN where undecided or off the hair.
    pub dir: Vec<[f32; 2]>,
}

/// Wraps an angle into [0, π).
pub fn wrap_pi(a: f32) -> f32 {
    let r = a.rem_euclid(PI);
    if r >= PI {
        0.0
    } else {
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eleven_directed_primitives() {
        let n: usize = Kind::ALL.iter().map(|k| 1usize << k.free_dirs()).sum();
        assert_eq!(n, 11);
    }

    #[test]
    fn side_angles_lean_away_on_both_sides() {
        // A dividing line along +x with sides π/2: left flow points to the left normal
        // (up on screen, −y), right flow down (+y).
        let p = Primitive {
            shift: 0.0,
            x: 0.0,
            y: 0.0,
            axis: 0.0,
            rho: 1.0,
            side: [PI / 2.0, PI / 2.0],
        };
        let l = p.side_angle(0);
        let r = p.side_angle(1);
        let nl = p.left_normal();
        assert!((l.cos() - nl[0]).abs() < 1e-6 && (l.sin() - nl[1]).abs() < 1e-6);
        assert!((r.cos() + nl[0]).abs() < 1e-6 && (r.sin() + nl[1]).abs() < 1e-6);
    }
}
