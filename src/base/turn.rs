//! The smallest rotation between two directions, the step of every frame transported along
//! a strand (the simulation's skin, the strand hierarchy's residuals).

use glam::{Mat3, Vec3};

/// The smallest rotation taking unit `a` to unit `b` (Rodrigues); the identity when either
/// is zero or they are opposite (no smallest rotation then; a segment does not flip).
pub fn turn(a: Vec3, b: Vec3) -> Mat3 {
    let v = a.cross(b);
    let c = a.dot(b);
    if a == Vec3::ZERO || b == Vec3::ZERO || c <= -0.999_999 {
        return Mat3::IDENTITY;
    }
    let k = Mat3::from_cols(
        Vec3::new(0.0, v.z, -v.y),
        Vec3::new(-v.z, 0.0, v.x),
        Vec3::new(v.y, -v.x, 0.0),
    );
    Mat3::IDENTITY + k + k * k * (1.0 / (1.0 + c))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turn_takes_a_to_b_and_keeps_the_axis() {
        let a = Vec3::new(1.0, 0.0, 0.0);
        let b = Vec3::new(0.6, 0.8, 0.0);
        let r = turn(a, b);
        assert!((r * a - b).length() < 1e-6);
        assert!((r * Vec3::Z - Vec3::Z).length() < 1e-6);
        assert_eq!(turn(a, a), Mat3::IDENTITY);
        assert_eq!(turn(a, -a), Mat3::IDENTITY);
    }
}
