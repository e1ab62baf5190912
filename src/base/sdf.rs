//! Signed distance helpers shared by the parametric head and the 3D synthetic body.

use glam::DVec3;

/// Ellipsoid distance estimate with semi-axes `r`, centred at the origin. The usual
/// k0 = |p/r| form scaled by 1/|∇k0| = k0/k1 is a unit-gradient bound on the surface, but
/// jumps at the centre (its value there depends on the direction), so inside it is blended
/// towards the smallest radius with weight 1 − k0³: value and gradient are unchanged on the
/// surface (C1 there) and the centre gets the continuous value −r_min.
pub fn sd_ellipsoid(p: DVec3, r: DVec3) -> f64 {
    let k0 = (p / r).length();
    let k1 = (p / (r * r)).length();
    let rmin = r.min_element();
    if k1 < 1e-300 {
        return -rmin;
    }
    let inv_g = k0 / k1;
    if k0 >= 1.0 {
        (k0 - 1.0) * inv_g
    } else {
        let w = k0 * k0 * k0;
        (k0 - 1.0) * (w * inv_g + (1.0 - w) * rmin)
    }
}

/// Quadratic smooth minimum: C1, never above min(a, b), and at most k/4 below it, so a
/// union stays a (slightly conservative) distance bound.
pub fn smin(a: f64, b: f64, k: f64) -> f64 {
    let h = (k - (a - b).abs()).max(0.0) / k;
    a.min(b) - h * h * k * 0.25
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ellipsoid_is_exact_on_axes_and_continuous_at_the_centre() {
        let r = DVec3::new(1.0, 2.0, 3.0);
        assert!(sd_ellipsoid(DVec3::new(1.0, 0.0, 0.0), r).abs() < 1e-12);
        assert!((sd_ellipsoid(DVec3::new(2.0, 0.0, 0.0), r) - 1.0).abs() < 1e-12);
        assert_eq!(sd_ellipsoid(DVec3::ZERO, r), -1.0);
        assert!((sd_ellipsoid(DVec3::new(0.0, 0.0, 1e-6), r) + 1.0).abs() < 1e-5);
    }

    #[test]
    fn smin_stays_within_k_over_4_below_min() {
        for (a, b) in [(0.0, 0.0), (0.1, -0.2), (3.0, 1.0)] {
            let s = smin(a, b, 0.5);
            assert!(s <= a.min(b) && s >= a.min(b) - 0.125);
        }
        assert_eq!(smin(3.0, 1.0, 0.5), 1.0);
    }
}
