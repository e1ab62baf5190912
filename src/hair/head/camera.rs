//! The weak-perspective camera mapping model space (metres) to image pixels and depth.

use crate::error::{Error, Result};
use glam::{Mat3, Vec2, Vec3};
use serde::{Deserialize, Serialize};

/// Weak-perspective camera of `CONVENTIONS.md`: view = r·p; image x = s·view.x + t.x;
/// image y = −s·view.y + t.y; depth = s·view.z (pixels, larger = nearer the camera).
/// Serialised as `{ "s": .., "r": [[row0], [row1], [row2]], "t": [x, y] }`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "CameraRepr", into = "CameraRepr")]
pub struct WeakPerspective {
    /// Pixels per metre.
    pub s: f32,
    /// Rotation model → view.
    pub r: Mat3,
    /// Image position of the model origin, pixels.
    pub t: Vec2,
}

#[derive(Serialize, Deserialize)]
struct CameraRepr {
    s: f32,
    r: [[f32; 3]; 3],
    t: [f32; 2],
}

impl From<WeakPerspective> for CameraRepr {
    fn from(c: WeakPerspective) -> Self {
        CameraRepr {
            s: c.s,
            r: [0, 1, 2].map(|i| c.r.row(i).to_array()),
            t: c.t.to_array(),
        }
    }
}

impl TryFrom<CameraRepr> for WeakPerspective {
    type Error = String;
    fn try_from(c: CameraRepr) -> std::result::Result<Self, String> {
        let r = Mat3::from_cols_array_2d(&c.r).transpose();
        let cam = WeakPerspective {
            s: c.s,
            r,
            t: Vec2::from_array(c.t),
        };
        cam.validate().map_err(|e| e.to_string())?;
        Ok(cam)
    }
}

impl WeakPerspective {
    pub fn new(s: f32, r: Mat3, t: Vec2) -> Self {
        WeakPerspective { s, r, t }
    }

    /// Frontal camera (no rotation).
    pub fn frontal(s: f32, t: Vec2) -> Self {
        WeakPerspective {
            s,
            r: Mat3::IDENTITY,
            t,
        }
    }

    /// Checks a positive finite scale and a proper rotation (orthonormal to 1e-3, det +1).
    pub fn validate(&self) -> Result<()> {
        if !(self.s.is_finite() && self.s > 0.0) {
            return Err(Error::Invalid(format!(
                "camera scale must be positive and finite, got {}",
                self.s
            )));
        }
        if !self.r.is_finite() || !self.t.is_finite() {
            return Err(Error::Invalid("camera has non-finite values".into()));
        }
        let e = (self.r * self.r.transpose() - Mat3::IDENTITY)
            .to_cols_array()
            .iter()
            .fold(0.0f32, |m, v| m.max(v.abs()));
        if e > 1e-3 || self.r.determinant() < 0.0 {
            return Err(Error::Invalid(format!(
                "camera rotation is not a proper rotation (orthonormality error {e:.2e}, \
                 det {:.4})",
                self.r.determinant()
            )));
        }
        Ok(())
    }

    /// Model point → (image x, image y, depth), pixels.
    pub fn project(&self, p: Vec3) -> Vec3 {
        let v = self.r * p;
        Vec3::new(
            self.s * v.x + self.t.x,
            -self.s * v.y + self.t.y,
            self.s * v.z,
        )
    }

    /// (image x, image y, depth) → model point; inverse of [`WeakPerspective::project`].
    pub fn unproject(&self, q: Vec3) -> Vec3 {
        let v = Vec3::new(
            (q.x - self.t.x) / self.s,
            -(q.y - self.t.y) / self.s,
            q.z / self.s,
        );
        self.r.transpose() * v
    }

    /// The 3x4 matrix of `project` (rows: image x, image y, depth).
    pub fn image_from_model(&self) -> [[f32; 4]; 3] {
        let (r0, r1, r2) = (self.r.row(0), self.r.row(1), self.r.row(2));
        let s = self.s;
        [
            [s * r0.x, s * r0.y, s * r0.z, self.t.x],
            [-s * r1.x, -s * r1.y, -s * r1.z, self.t.y],
            [s * r2.x, s * r2.y, s * r2.z, 0.0],
        ]
    }

    /// Model-space direction → volume-space direction (rotation and y flip, no scaling,
    /// so unit vectors stay unit).
    pub fn to_volume_dir(&self, v: Vec3) -> Vec3 {
        let w = self.r * v;
        Vec3::new(w.x, -w.y, w.z)
    }

    /// Volume-space direction → model-space direction; inverse of `to_volume_dir`.
    pub fn from_volume_dir(&self, v: Vec3) -> Vec3 {
        self.r.transpose() * Vec3::new(v.x, -v.y, v.z)
    }

    /// Unit viewing direction in model space (from the camera into the scene: decreasing
    /// depth).
    pub fn view_dir_model(&self) -> Vec3 {
        -self.r.row(2)
    }
}
