//! What the synthetic hair rests on and what hides it: the head united with shoulders (an SDF).

use crate::base::sdf::{sd_ellipsoid, smin};
use crate::hair::head::Head;
use glam::{DVec3, Vec3};
/// What the hair rests on and what hides it: the head and the shoulders of the synth
/// portraits (its torso ellipse, 3.25 b below the face centre with semi-axes 2.7 a and
/// 1.75 b, made an ellipsoid 0.22 m deep under the neck).
pub(super) struct Body {
    pub(super) head: Head,
    pub(super) torso_c: DVec3,
    pub(super) torso_r: DVec3,
}

impl Body {
    pub(super) fn new(head: Head) -> Body {
        let hp = head.params();
        let (a, b) = (hp.landmark_a as f64, hp.landmark_b as f64);
        let face_y = -0.3 * b;
        Body {
            torso_c: DVec3::new(0.0, face_y - 3.25 * b, hp.neck_z as f64),
            torso_r: DVec3::new(2.7 * a, 1.75 * b, 0.11),
            head,
        }
    }

    pub(super) fn torso_sdf(&self, p: DVec3) -> f64 {
        sd_ellipsoid(p - self.torso_c, self.torso_r)
    }

    pub(super) fn sdf64(&self, p: DVec3) -> f64 {
        // Smooth join of the neck into the shoulders; never above either distance.
        smin(self.head.sdf64(p), self.torso_sdf(p), 0.03)
    }

    pub(super) fn sdf(&self, p: Vec3) -> f32 {
        self.sdf64(p.as_dvec3()) as f32
    }

    pub(super) fn normal(&self, p: Vec3) -> Vec3 {
        const E: f64 = 1e-5;
        let p = p.as_dvec3();
        let f = |d: DVec3| self.sdf64(p + d) - self.sdf64(p - d);
        DVec3::new(f(DVec3::X * E), f(DVec3::Y * E), f(DVec3::Z * E))
            .try_normalize()
            .unwrap_or(DVec3::Y)
            .as_vec3()
    }

    /// Box around head and shoulders (shoulders cut well below any image).
    pub(super) fn bounds(&self) -> (DVec3, DVec3) {
        let (lo, hi) = self.head.bounds();
        let (tl, th) = (self.torso_c - self.torso_r, self.torso_c + self.torso_r);
        (
            lo.as_dvec3().min(tl) - DVec3::splat(0.01),
            hi.as_dvec3().max(th) + DVec3::splat(0.01),
        )
    }
}
