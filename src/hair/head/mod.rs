//! Parametric head model, weak-perspective camera and camera fits.
//!
//! Chai et al. 2013 fit a morphable face model to the portrait to get a head surface (hair
//! roots, collision body, depth prior). No morphable model can be shipped, so the head here
//! is a smooth union of a few analytic primitives (cranium, face/jaw, chin, nose, ears,
//! neck) whose frontal landmark layout matches coif's synthetic portraits (`synth.rs`):
//! with face-ellipse semi-axes a (half width) and b (half height), the eyes sit at
//! (±0.4a, −0.1b) from the face centre, the nose tip at +0.3b, the mouth corners at
//! (±0.32a, +0.56b), the chin at +b (image y down), and the skull centre (the model origin)
//! 0.3b above the face centre.
//!
//! Spaces follow `CONVENTIONS.md`: model space in metres, y up, the face looks toward +z;
//! the camera maps it to image pixels (x right, y down) plus a depth in pixels.
//!
//! Everything is computed in f64 internally (finite-difference gradients and root finding
//! need the headroom) and exposed as f32.

mod camera;
mod fit;
pub mod texture;

pub use camera::WeakPerspective;
pub use fit::{
    fit_default, fit_landmarks, fit_points, FitMethod, FitReport, DEFAULT_HAIR_SIDE_M,
    DEFAULT_HAIR_TOP_M,
};

use crate::base::rng::Rng;
use crate::base::sdf::{sd_ellipsoid, smin};
use crate::error::{Error, Result};
use glam::{DVec2, DVec3, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::{HashMap, VecDeque};
use std::f64::consts::TAU;
use std::sync::{Arc, Mutex};

// ---------------------------------------------------------------------------------------------
// Parameters.

/// Shape of the parametric head, metres, model space. Sizes are full extents (diameters);
/// centres are positions. Ears are mirrored in x.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct HeadParams {
    /// Cranium ellipsoid: width (ear to ear), height, depth (front to back) and centre.
    pub skull_width: f32,
    pub skull_height: f32,
    pub skull_depth: f32,
    pub skull_centre: [f32; 3],
    /// Face/jaw ellipsoid: cheeks, mouth region and jaw angle.
    pub face_width: f32,
    pub face_height: f32,
    pub face_depth: f32,
    pub face_centre: [f32; 3],
    /// Chin ellipsoid (full extents) and centre; it pulls the chin forward of the jaw.
    pub chin_size: [f32; 3],
    pub chin_centre: [f32; 3],
    /// Nose: a capsule from the bridge to the centre of the tip's rounding, with a radius.
    pub nose_bridge: [f32; 3],
    pub nose_tip_centre: [f32; 3],
    pub nose_radius: f32,
    /// Right-hand (+x) ear: a vertical capsule (exact distance, unlike a thin ellipsoid)
    /// of this total height and radius around `ear_centre`; the −x ear is its mirror.
    pub ear_height: f32,
    pub ear_radius: f32,
    pub ear_centre: [f32; 3],
    /// Neck: a vertical rounded cylinder at (0, ·, neck_z) from `neck_top` down by
    /// `neck_length`.
    pub neck_radius: f32,
    pub neck_length: f32,
    pub neck_top: f32,
    pub neck_z: f32,
    /// Smooth-union radius between cranium, face, chin, nose and neck; ears use
    /// `ear_blend` so that they stay distinct flaps.
    pub blend: f32,
    pub ear_blend: f32,
    /// Frontal face-ellipse semi-axes the landmark layout is built on (synth convention:
    /// a = half width, b = half height; b ≈ 1.3 a).
    pub landmark_a: f32,
    pub landmark_b: f32,
    /// Scalp map (see [`Head::scalp`]): the centre rays are cast from, the front hairline
    /// and nape angles around the ear axis (degrees, 0 = forward, 90 = up, 180 = back), and
    /// the angular radius of the hairless disc kept around each ear (degrees).
    pub scalp_centre: [f32; 3],
    pub hairline_deg: f32,
    pub nape_deg: f32,
    pub ear_clearance_deg: f32,
}

impl Default for HeadParams {
    /// An average adult: skull 0.15 m wide and 0.194 m front to back, vertex 0.12 m above
    /// and chin 0.12 m below the eyes, laid out like coif's synthetic portraits with
    /// a = 0.084 m and b = 1.3 a (so a 512² synth portrait is about 1000 px/m).
    fn default() -> Self {
        let a = 0.084;
        HeadParams {
            skull_width: 0.150,
            skull_height: 0.206,
            skull_depth: 0.194,
            skull_centre: [0.0, 0.0, -0.010],
            face_width: 0.124,
            face_height: 0.150,
            face_depth: 0.150,
            face_centre: [0.0, -0.070, 0.012],
            chin_size: [0.056, 0.050, 0.060],
            chin_centre: [0.0, -0.125, 0.050],
            nose_bridge: [0.0, -0.030, 0.075],
            nose_tip_centre: [0.0, -0.062, 0.100],
            nose_radius: 0.012,
            ear_height: 0.056,
            ear_radius: 0.011,
            ear_centre: [0.072, -0.030, -0.012],
            neck_radius: 0.055,
            neck_length: 0.170,
            neck_top: -0.030,
            neck_z: -0.020,
            blend: 0.012,
            ear_blend: 0.006,
            landmark_a: a,
            landmark_b: 1.3 * a,
            scalp_centre: [0.0, -0.020, -0.010],
            hairline_deg: 36.0,
            nape_deg: 225.0,
            ear_clearance_deg: 40.0,
        }
    }
}

impl HeadParams {
    /// Rejects non-finite or non-positive sizes and an empty scalp angle range.
    pub fn validate(&self) -> Result<()> {
        let sizes = [
            ("skull_width", self.skull_width),
            ("skull_height", self.skull_height),
            ("skull_depth", self.skull_depth),
            ("face_width", self.face_width),
            ("face_height", self.face_height),
            ("face_depth", self.face_depth),
            ("chin_size[0]", self.chin_size[0]),
            ("chin_size[1]", self.chin_size[1]),
            ("chin_size[2]", self.chin_size[2]),
            ("nose_radius", self.nose_radius),
            ("ear_radius", self.ear_radius),
            ("neck_radius", self.neck_radius),
            ("neck_length", self.neck_length),
            ("blend", self.blend),
            ("ear_blend", self.ear_blend),
            ("landmark_a", self.landmark_a),
            ("landmark_b", self.landmark_b),
        ];
        for (name, v) in sizes {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::Invalid(format!(
                    "head parameter {name} must be a positive finite number of metres, got {v}"
                )));
            }
        }
        let points = [
            self.skull_centre,
            self.face_centre,
            self.chin_centre,
            self.nose_bridge,
            self.nose_tip_centre,
            self.ear_centre,
            self.scalp_centre,
        ];
        let scalars = [
            self.neck_top,
            self.neck_z,
            self.hairline_deg,
            self.nape_deg,
            self.ear_clearance_deg,
        ];
        if points
            .iter()
            .flatten()
            .chain(&scalars)
            .any(|v| !v.is_finite())
        {
            return Err(Error::Invalid(
                "head parameters must be finite numbers".into(),
            ));
        }
        if !(self.hairline_deg < self.nape_deg && self.nape_deg - self.hairline_deg < 300.0) {
            return Err(Error::Invalid(format!(
                "scalp angles: need hairline_deg < nape_deg within 300 degrees, got {} and {}",
                self.hairline_deg, self.nape_deg
            )));
        }
        if !(self.ear_clearance_deg > 0.0 && self.ear_clearance_deg < 89.0) {
            return Err(Error::Invalid(format!(
                "ear_clearance_deg must be in (0, 89), got {}",
                self.ear_clearance_deg
            )));
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Distance primitives (f64).

fn sd_capsule(p: DVec3, a: DVec3, b: DVec3, r: f64) -> f64 {
    let (pa, ba) = (p - a, b - a);
    let h = (pa.dot(ba) / ba.length_squared().max(1e-18)).clamp(0.0, 1.0);
    (pa - ba * h).length() - r
}

/// Vertical cylinder (axis through `c`, half height `hh`, radius `ra`) with edges rounded
/// by `rb`: exact distance, so the neck ends in a flat, closed cap.
fn sd_rounded_cylinder(p: DVec3, c: DVec3, ra: f64, hh: f64, rb: f64) -> f64 {
    let q = p - c;
    let d = DVec2::new(DVec2::new(q.x, q.z).length() - ra + rb, q.y.abs() - hh + rb);
    d.x.max(d.y).min(0.0) + d.max(DVec2::ZERO).length() - rb
}

fn v3(a: [f32; 3]) -> DVec3 {
    DVec3::new(a[0] as f64, a[1] as f64, a[2] as f64)
}

// ---------------------------------------------------------------------------------------------
// The head.

/// A point of the scalp with its outward unit normal (model space).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScalpPoint {
    pub pos: Vec3,
    pub normal: Vec3,
}

/// Landmark names the head knows besides [`REQUIRED_LANDMARKS`]; a `landmarks.json` may
/// carry them and the fit then uses them too. Left/right as seen in the image (model −x is
/// "left"). The ear points are the outermost points of the ears in a frontal view.
pub const EXTRA_LANDMARKS: [&str; 3] = ["nose_bridge", "left_ear", "right_ear"];

/// Frontal layout of the required landmarks relative to the face centre, in units of the
/// face semi-axes (a, b), image y down: copied from `synth.rs` (`eye`, `nose_tip`, `mouth`,
/// `chin`) so that a fit to synthetic landmarks places the head where the image draws it.
const LAYOUT: [(&str, f64, f64); 6] = [
    ("left_eye", -0.4, -0.1),
    ("right_eye", 0.4, -0.1),
    ("nose_tip", 0.0, 0.3),
    ("mouth_left", -0.32, 0.56),
    ("mouth_right", 0.32, 0.56),
    ("chin", 0.0, 1.0),
];
/// The skull centre (model origin) is this many b above the face centre (synth: hy).
const SKULL_ABOVE_FACE: f64 = 0.3;
/// Ray casts against the head end when the bracket is this narrow (metres): far below f32
/// resolution at head scale (~1e-8 m), so the f32 points they give are exact.
const CAST_TOL: f64 = 1e-12;

/// Parametric head: signed distance, mesh, scalp map and landmarks.
#[derive(Clone, Debug)]
pub struct Head {
    params: HeadParams,
    skull_c: DVec3,
    skull_r: DVec3,
    face_c: DVec3,
    face_r: DVec3,
    chin_c: DVec3,
    chin_r: DVec3,
    nose_a: DVec3,
    nose_b: DVec3,
    nose_r: f64,
    ear_c: DVec3,
    /// Half length of the ear capsule's segment.
    ear_hh: f64,
    ear_r: f64,
    neck_c: DVec3,
    neck_hh: f64,
    neck_r: f64,
    blend: f64,
    ear_blend: f64,
    scalp_c: DVec3,
    beta_front: f64,
    beta_back: f64,
    cos_clear: f64,
    /// Face-exclusion rule constants (see [`Head::in_face`]).
    eye_y: f64,
    ear_z: f64,
    front_z: f64,
    landmarks: Vec<(&'static str, Vec3)>,
    top: Vec3,
}

impl Default for Head {
    fn default() -> Self {
        Head::new(&HeadParams::default())
    }
}

impl Head {
    /// Builds the head. Parameters are assumed sane (see [`HeadParams::validate`]; use
    /// [`Head::try_new`] for untrusted input): landmarks are placed by casting rays onto the
    /// surface, which needs a closed head.
    pub fn new(p: &HeadParams) -> Head {
        let neck_top = p.neck_top as f64;
        let neck_len = p.neck_length as f64;
        let mut h = Head {
            params: p.clone(),
            skull_c: v3(p.skull_centre),
            skull_r: DVec3::new(
                p.skull_width as f64,
                p.skull_height as f64,
                p.skull_depth as f64,
            ) * 0.5,
            face_c: v3(p.face_centre),
            face_r: DVec3::new(
                p.face_width as f64,
                p.face_height as f64,
                p.face_depth as f64,
            ) * 0.5,
            chin_c: v3(p.chin_centre),
            chin_r: v3(p.chin_size) * 0.5,
            nose_a: v3(p.nose_bridge),
            nose_b: v3(p.nose_tip_centre),
            nose_r: p.nose_radius as f64,
            ear_c: v3(p.ear_centre),
            ear_hh: (0.5 * p.ear_height as f64 - p.ear_radius as f64).max(0.0),
            ear_r: p.ear_radius as f64,
            neck_c: DVec3::new(0.0, neck_top - 0.5 * neck_len, p.neck_z as f64),
            neck_hh: 0.5 * neck_len,
            neck_r: p.neck_radius as f64,
            blend: p.blend as f64,
            ear_blend: p.ear_blend as f64,
            scalp_c: v3(p.scalp_centre),
            beta_front: (p.hairline_deg as f64).to_radians(),
            beta_back: (p.nape_deg as f64).to_radians(),
            cos_clear: (p.ear_clearance_deg as f64).to_radians().cos(),
            eye_y: 0.0,
            ear_z: p.ear_centre[2] as f64,
            front_z: 0.0,
            landmarks: Vec::new(),
            top: Vec3::ZERO,
        };
        let (a, b) = (p.landmark_a as f64, p.landmark_b as f64);
        let face_y = -SKULL_ABOVE_FACE * b;
        let front = |h: &Head, x: f64, y: f64| {
            h.cast(DVec3::new(x, y, 1.0), DVec3::NEG_Z, 2.0)
                .unwrap_or(DVec3::new(x, y, 0.0))
        };
        let mut lms = Vec::new();
        for (name, fx, fy) in LAYOUT {
            // Image y is down, model y is up.
            lms.push((name, front(&h, fx * a, face_y - fy * b)));
        }
        h.eye_y = face_y + 0.1 * b;
        lms.push(("nose_bridge", front(&h, 0.0, h.eye_y)));
        for (name, side) in [("left_ear", -1.0), ("right_ear", 1.0)] {
            let o = DVec3::new(side, h.ear_c.y, h.ear_c.z);
            let hit = h
                .cast(o, DVec3::new(-side, 0.0, 0.0), 2.0)
                .unwrap_or(DVec3::new(side * h.ear_c.x, h.ear_c.y, h.ear_c.z));
            lms.push((name, hit));
        }
        h.landmarks = lms.into_iter().map(|(n, q)| (n, q.as_vec3())).collect();
        h.front_z = front(&h, 0.0, h.eye_y + 0.03).z;
        h.top = h
            .cast(DVec3::new(0.0, 1.0, h.skull_c.z), DVec3::NEG_Y, 2.0)
            .unwrap_or(h.skull_c + DVec3::Y * h.skull_r.y)
            .as_vec3();
        h
    }

    /// [`Head::new`] after [`HeadParams::validate`].
    pub fn try_new(p: &HeadParams) -> Result<Head> {
        p.validate()?;
        Ok(Head::new(p))
    }

    pub fn params(&self) -> &HeadParams {
        &self.params
    }

    /// Signed distance in f64 (metres, negative inside).
    pub fn sdf64(&self, p: DVec3) -> f64 {
        let k = self.blend;
        let mut d = sd_ellipsoid(p - self.skull_c, self.skull_r);
        d = smin(d, sd_ellipsoid(p - self.face_c, self.face_r), k);
        d = smin(d, sd_ellipsoid(p - self.chin_c, self.chin_r), 0.5 * k);
        d = smin(
            d,
            sd_capsule(p, self.nose_a, self.nose_b, self.nose_r),
            0.5 * k,
        );
        let neck = sd_rounded_cylinder(p, self.neck_c, self.neck_r, self.neck_hh, 0.01);
        d = smin(d, neck, 2.0 * k);
        // Both ears through one mirrored evaluation.
        let pe = DVec3::new(p.x.abs(), p.y, p.z);
        let seg = DVec3::Y * self.ear_hh;
        let ear = sd_capsule(pe, self.ear_c - seg, self.ear_c + seg, self.ear_r);
        smin(d, ear, self.ear_blend)
    }

    /// Signed distance (metres, negative inside): a smooth union of ellipsoids, a capsule
    /// and a rounded cylinder; unit gradient on the surface, Lipschitz about 1 near it.
    pub fn sdf(&self, p: Vec3) -> f32 {
        self.sdf64(p.as_dvec3()) as f32
    }

    /// Unnormalised central-difference gradient (f64).
    fn grad64_raw(&self, p: DVec3) -> DVec3 {
        const E: f64 = 1e-6;
        let f = |d: DVec3| self.sdf64(p + d) - self.sdf64(p - d);
        DVec3::new(f(DVec3::X * E), f(DVec3::Y * E), f(DVec3::Z * E)) / (2.0 * E)
    }

    fn grad64(&self, p: DVec3) -> DVec3 {
        self.grad64_raw(p).try_normalize().unwrap_or(DVec3::Y)
    }

    /// Normalised gradient of the SDF: the outward surface normal on the surface.
    pub fn sdf_grad(&self, p: Vec3) -> Vec3 {
        self.grad64(p.as_dvec3()).as_vec3()
    }

    /// The distance primitives as f32, packed as `crate::sim::head_sdf` and
    /// `wgsl/shared/head_sdf.wgsl` read them ([`crate::sim::head_sdf::PACKED_LEN`] values):
    /// passes that collide with the head evaluate the same smooth union in f32.
    pub fn sdf_packed(&self) -> Vec<f32> {
        let mut v = Vec::with_capacity(40);
        for a in [
            self.skull_c,
            self.skull_r,
            self.face_c,
            self.face_r,
            self.chin_c,
            self.chin_r,
            self.nose_a,
            self.nose_b,
        ] {
            v.extend(a.to_array().map(|x| x as f32));
        }
        v.push(self.nose_r as f32);
        v.extend(self.ear_c.to_array().map(|x| x as f32));
        v.extend([self.ear_hh as f32, self.ear_r as f32]);
        v.extend(self.neck_c.to_array().map(|x| x as f32));
        v.extend([
            self.neck_hh as f32,
            self.neck_r as f32,
            self.blend as f32,
            self.ear_blend as f32,
        ]);
        v
    }

    /// Moves a point onto the zero level by Newton steps along the gradient.
    fn project64(&self, mut p: DVec3) -> DVec3 {
        for _ in 0..12 {
            let d = self.sdf64(p);
            if d.abs() < 1e-9 {
                break;
            }
            let g = self.grad64_raw(p);
            let g2 = g.length_squared();
            if g2 < 1e-12 {
                break;
            }
            p -= g * (d / g2);
        }
        p
    }

    /// Nearest-ish surface point (Newton projection along the gradient).
    pub fn project_to_surface(&self, p: Vec3) -> Vec3 {
        self.project64(p.as_dvec3()).as_vec3()
    }

    /// First surface crossing along a ray (f64), within [`CAST_TOL`] along the ray.
    /// Conservative marching, then a bracketed search once the sign flips, so an
    /// overestimating step cannot tunnel silently.
    fn cast(&self, o: DVec3, dir: DVec3, max_t: f64) -> Option<DVec3> {
        let dir = dir.try_normalize()?;
        let d0 = self.sdf64(o);
        let outside = d0 > 0.0;
        let mut t0 = 0.0;
        let mut d_prev = d0;
        while t0 < max_t {
            let step = (0.8 * d_prev.abs()).clamp(2e-4, 0.01);
            let t1 = (t0 + step).min(max_t);
            let d1 = self.sdf64(o + dir * t1);
            if (d1 > 0.0) != outside {
                // Illinois false position on the bracket, with a bisection step whenever a
                // step fails to halve it: superlinear near the smooth crossing (~6
                // evaluations to CAST_TOL where bisection to adjacent doubles took ~45) and
                // never slower than bisection.
                let (mut lo, mut hi) = (t0, t1);
                let (mut f_lo, mut f_hi) = (d_prev, d1);
                let mut last_side = 0i8;
                let mut bisect = false;
                for _ in 0..200 {
                    let width = hi - lo;
                    if width <= CAST_TOL {
                        break;
                    }
                    let secant = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
                    let m = if !bisect && secant > lo && secant < hi {
                        secant
                    } else {
                        0.5 * (lo + hi)
                    };
                    if m <= lo || m >= hi {
                        // lo and hi are adjacent doubles.
                        break;
                    }
                    let f_m = self.sdf64(o + dir * m);
                    if (f_m > 0.0) == outside {
                        lo = m;
                        f_lo = f_m;
                        if last_side == -1 {
                            f_hi *= 0.5;
                        }
                        last_side = -1;
                    } else {
                        hi = m;
                        f_hi = f_m;
                        if last_side == 1 {
                            f_lo *= 0.5;
                        }
                        last_side = 1;
                    }
                    bisect = hi - lo > 0.5 * width;
                }
                return Some(o + dir * (0.5 * (lo + hi)));
            }
            if t1 >= max_t {
                break;
            }
            t0 = t1;
            d_prev = d1;
        }
        None
    }

    /// First point where the ray `origin + t·dir`, 0 ≤ t ≤ max_t (metres), crosses the
    /// surface (entering from outside, or leaving when the origin is inside).
    pub fn raycast(&self, origin: Vec3, dir: Vec3, max_t: f32) -> Option<Vec3> {
        self.cast(origin.as_dvec3(), dir.as_dvec3(), max_t as f64)
            .map(|p| p.as_vec3())
    }

    /// The vertex: the highest surface point above the cranium centre.
    pub fn top(&self) -> Vec3 {
        self.top
    }

    /// Axis-aligned box (min, max) containing the surface.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        let mut add = |c: DVec3, r: DVec3| {
            lo = lo.min(c - r);
            hi = hi.max(c + r);
        };
        add(self.skull_c, self.skull_r);
        add(self.face_c, self.face_r);
        add(self.chin_c, self.chin_r);
        add(self.nose_a, DVec3::splat(self.nose_r));
        add(self.nose_b, DVec3::splat(self.nose_r));
        for s in [-1.0, 1.0] {
            let r = DVec3::new(self.ear_r, self.ear_hh + self.ear_r, self.ear_r);
            add(self.ear_c * DVec3::new(s, 1.0, 1.0), r);
        }
        add(
            self.neck_c,
            DVec3::new(self.neck_r, self.neck_hh, self.neck_r),
        );
        // Smooth unions grow the surface by at most a quarter of the largest blend radius.
        let m = DVec3::splat(0.5 * self.blend + 1e-3);
        ((lo - m).as_vec3(), (hi + m).as_vec3())
    }

    // -----------------------------------------------------------------------------------------
    // Mesh.

    /// Closed, consistently wound (counter-clockwise seen from outside) triangle mesh of the
    /// zero level: marching tetrahedra over a grid with `resolution` cells along the longest
    /// side of [`Head::bounds`] (Kuhn split of every cube, so neighbouring cubes share faces
    /// and the mesh is watertight), vertices shared per grid edge and then moved onto the
    /// surface by Newton steps. Resolution is clamped to [8, 512].
    ///
    /// The last few meshes are kept, by parameters and resolution (a head is a function of
    /// its [`HeadParams`]): every frame of a rendered clip asks for the same head's mesh, and
    /// meshing it again was a sixth of the render's time.
    pub fn mesh(&self, resolution: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        type Kept = (HeadParams, u32, Arc<(Vec<Vec3>, Vec<[u32; 3]>)>);
        const KEEP: usize = 4;
        static KEPT: Mutex<VecDeque<Kept>> = Mutex::new(VecDeque::new());
        let find = |kept: &VecDeque<Kept>| {
            kept.iter()
                .find(|(p, r, _)| *r == resolution && *p == self.params)
                .map(|(_, _, m)| m.clone())
        };
        // A poisoned lock only means another thread panicked while holding it; the list
        // itself is always whole.
        let lock = || KEPT.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(m) = find(&lock()) {
            return (m.0.clone(), m.1.clone());
        }
        let m = Arc::new(self.mesh_uncached(resolution));
        let mut kept = lock();
        if find(&kept).is_none() {
            if kept.len() == KEEP {
                kept.pop_front();
            }
            kept.push_back((self.params.clone(), resolution, m.clone()));
        }
        (m.0.clone(), m.1.clone())
    }

    fn mesh_uncached(&self, resolution: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let res = resolution.clamp(8, 512) as f64;
        let (lo, hi) = self.bounds();
        let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
        let ext = hi - lo;
        let cell = ext.max_element() / res;
        // One spare cell on every side so the surface never touches the grid boundary.
        let origin = lo - DVec3::splat(cell);
        let n = [
            (ext.x / cell).ceil() as usize + 2,
            (ext.y / cell).ceil() as usize + 2,
            (ext.z / cell).ceil() as usize + 2,
        ];
        let (sx, sy) = (n[0] + 1, n[1] + 1);
        let corner = |i: usize, j: usize, k: usize| i + sx * (j + sy * k);
        let pos =
            |i: usize, j: usize, k: usize| origin + DVec3::new(i as f64, j as f64, k as f64) * cell;
        let mut val = vec![0.0f64; sx * sy * (n[2] + 1)];
        for k in 0..=n[2] {
            for j in 0..=n[1] {
                for i in 0..=n[0] {
                    val[corner(i, j, k)] = self.sdf64(pos(i, j, k));
                }
            }
        }
        let corner_pos = |c: usize| pos(c % sx, (c / sx) % sy, c / (sx * sy));

        let mut verts: Vec<DVec3> = Vec::new();
        let mut edge_vert: HashMap<(usize, usize), u32> = HashMap::new();
        let mut tris: Vec<[u32; 3]> = Vec::new();
        let mut vert_on = |a: usize, b: usize, verts: &mut Vec<DVec3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *edge_vert.entry(key).or_insert_with(|| {
                // `a` inside (< 0), `b` outside (>= 0).
                let (va, vb) = (val[a], val[b]);
                let t = (va / (va - vb)).clamp(0.0, 1.0);
                verts.push(corner_pos(a).lerp(corner_pos(b), t));
                (verts.len() - 1) as u32
            })
        };
        // Kuhn triangulation: 6 tetrahedra along the main diagonal 0 -> 7.
        const TETS: [[usize; 4]; 6] = [
            [0, 1, 3, 7],
            [0, 1, 5, 7],
            [0, 2, 3, 7],
            [0, 2, 6, 7],
            [0, 4, 5, 7],
            [0, 4, 6, 7],
        ];
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let cube: [usize; 8] = std::array::from_fn(|b| {
                        corner(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1))
                    });
                    for tet in TETS {
                        let c = tet.map(|b| cube[b]);
                        let ins: Vec<usize> = c.iter().copied().filter(|&q| val[q] < 0.0).collect();
                        let out: Vec<usize> =
                            c.iter().copied().filter(|&q| val[q] >= 0.0).collect();
                        // Outward direction: from the inside corners to the outside ones.
                        let centroid = |s: &[usize]| {
                            s.iter().map(|&q| corner_pos(q)).sum::<DVec3>() / s.len() as f64
                        };
                        let mut emit = |tri: [u32; 3], verts: &Vec<DVec3>, dir: DVec3| {
                            let [a, b, cc] = tri.map(|v| verts[v as usize]);
                            if (b - a).cross(cc - a).dot(dir) < 0.0 {
                                tris.push([tri[0], tri[2], tri[1]]);
                            } else {
                                tris.push(tri);
                            }
                        };
                        match ins.len() {
                            1 => {
                                let dir = centroid(&out) - centroid(&ins);
                                let t = [
                                    vert_on(ins[0], out[0], &mut verts),
                                    vert_on(ins[0], out[1], &mut verts),
                                    vert_on(ins[0], out[2], &mut verts),
                                ];
                                emit(t, &verts, dir);
                            }
                            3 => {
                                let dir = centroid(&out) - centroid(&ins);
                                let t = [
                                    vert_on(ins[0], out[0], &mut verts),
                                    vert_on(ins[1], out[0], &mut verts),
                                    vert_on(ins[2], out[0], &mut verts),
                                ];
                                emit(t, &verts, dir);
                            }
                            2 => {
                                let dir = centroid(&out) - centroid(&ins);
                                // The four crossing edges form the cycle
                                // (i0o0, i0o1, i1o1, i1o0).
                                let q = [
                                    vert_on(ins[0], out[0], &mut verts),
                                    vert_on(ins[0], out[1], &mut verts),
                                    vert_on(ins[1], out[1], &mut verts),
                                    vert_on(ins[1], out[0], &mut verts),
                                ];
                                emit([q[0], q[1], q[2]], &verts, dir);
                                emit([q[0], q[2], q[3]], &verts, dir);
                            }
                            _ => {}
                        }
                    }
                }
            }
        }
        let verts = verts
            .into_iter()
            .map(|p| self.project64(p).as_vec3())
            .collect();
        (verts, tris)
    }

    // -----------------------------------------------------------------------------------------
    // Scalp.

    /// Unit direction from the scalp centre for a scalp coordinate.
    fn scalp_dir(&self, uv: [f32; 2]) -> DVec3 {
        let (u, v) = (uv[0] as f64, uv[1] as f64);
        let ca = (2.0 * u - 1.0) * self.cos_clear;
        let sa = (1.0 - ca * ca).max(0.0).sqrt();
        let beta = self.beta_front + v * (self.beta_back - self.beta_front);
        DVec3::new(ca, sa * beta.sin(), sa * beta.cos())
    }

    /// Scalp map. A direction d from the scalp centre c (between the ears) is written in
    /// spherical coordinates about the ear-to-ear axis x: polar angle α from +x and angle β
    /// around x (0 = forward +z, 90° = up, 180° = back). `u` sets cos α linearly from
    /// −cos(clearance) (u = 0, model −x, the image's left side) to +cos(clearance)
    /// (u = 1), `v` sets β linearly from the front hairline (v = 0) over the crown to the
    /// nape (v = 1); the surface point is where the ray c + t·d leaves the head.
    ///
    /// On a sphere this map is exactly equal-area (Archimedes: uniform cos α and uniform β
    /// give uniform area), and it is smooth with no pole inside the domain: the poles of
    /// the parameterisation are the ears, which the clearance disc keeps outside the scalp.
    /// On the head the area element varies by the ray-length² / obliquity factor only.
    /// Returns None outside [0, 1]² (or for non-finite input).
    pub fn scalp(&self, uv: [f32; 2]) -> Option<ScalpPoint> {
        if !uv.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)) {
            return None;
        }
        let d = self.scalp_dir(uv);
        let p = self.cast(self.scalp_c, d, 1.0)?;
        Some(ScalpPoint {
            pos: p.as_vec3(),
            normal: self.grad64(p).as_vec3(),
        })
    }

    /// Inverse of [`Head::scalp`] for a point on the surface: its scalp coordinate, or None
    /// when the point is not on the scalp (outside the hairline, nape or ear clearance).
    pub fn scalp_uv(&self, p: Vec3) -> Option<[f32; 2]> {
        let d = (p.as_dvec3() - self.scalp_c).try_normalize()?;
        let u = 0.5 * (d.x / self.cos_clear + 1.0);
        // β in (−π, π]; angles more than half the gap below the hairline belong past the
        // nape, so the cut sits in the middle of the non-scalp range.
        let span = self.beta_back - self.beta_front;
        let mut beta = d.y.atan2(d.z);
        if beta < self.beta_front - 0.5 * (TAU - span) {
            beta += TAU;
        }
        let v = (beta - self.beta_front) / span;
        let tol = 1e-6;
        if (-tol..=1.0 + tol).contains(&u) && (-tol..=1.0 + tol).contains(&v) {
            Some([u.clamp(0.0, 1.0) as f32, v.clamp(0.0, 1.0) as f32])
        } else {
            None
        }
    }

    /// Whether `uv` is a scalp coordinate: inside [0, 1]², maps onto the surface, and the
    /// point is not on the face (the face-exclusion rule [`Head::in_face`] is applied as a
    /// guard, so a future map change cannot silently grow hair on the face).
    pub fn scalp_contains(&self, uv: [f32; 2]) -> bool {
        self.scalp(uv).is_some_and(|sp| !self.in_face(sp.pos))
    }

    /// Face-exclusion rule, independent of the scalp map: a surface point belongs to the
    /// face when it is in front of the ears (more than 2.5 cm ahead of the ear centre) and
    /// below brow level (2 cm above the eyes), or on the forehead band (within 3 cm of the
    /// front of the head) up to 5 cm above the eyes. Hair is never rooted there.
    pub fn in_face(&self, p: Vec3) -> bool {
        let p = p.as_dvec3();
        let cheeks = p.z > self.ear_z + 0.025 && p.y < self.eye_y + 0.02;
        let forehead = p.z > self.front_z - 0.03 && p.y < self.eye_y + 0.05;
        cheeks || forehead
    }

    /// `n` hair roots uniform in scalp (u, v), deterministic for a seed.
    pub fn sample_roots(&self, n: usize, seed: u64) -> Vec<ScalpPoint> {
        use rayon::prelude::*;
        let mut rng = Rng::new(seed);
        let mut out = Vec::with_capacity(n);
        // Every uv in [0,1]² maps to the scalp; the attempt cap only guards against a
        // broken custom parameter set looping forever.
        let cap = 4 * n + 64;
        let mut attempts = 0usize;
        // The uvs are drawn in sequence and the first n that land on the scalp off the face
        // kept, as one draw at a time would; each batch (as many draws as roots are missing)
        // casts its rays in parallel (the casts were most of the growth stage).
        while out.len() < n && attempts < cap {
            let batch = (n - out.len()).min(cap - attempts);
            attempts += batch;
            let uvs: Vec<[f32; 2]> = (0..batch)
                .map(|_| [rng.next_f32(), rng.next_f32()])
                .collect();
            let hits: Vec<Option<ScalpPoint>> = uvs
                .par_iter()
                .map(|&uv| self.scalp(uv).filter(|sp| !self.in_face(sp.pos)))
                .collect();
            out.extend(hits.into_iter().flatten());
        }
        out
    }

    // -----------------------------------------------------------------------------------------
    // Landmarks.

    /// A named landmark on the surface ([`REQUIRED_LANDMARKS`] or [`EXTRA_LANDMARKS`]).
    pub fn landmark(&self, name: &str) -> Option<Vec3> {
        self.landmarks
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, p)| *p)
    }

    /// All landmark names the head knows, required ones first.
    pub fn landmark_names(&self) -> Vec<&'static str> {
        self.landmarks.iter().map(|(n, _)| *n).collect()
    }
}
