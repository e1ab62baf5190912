//! The head's signed distance in f32 from [`Head::sdf_packed`](crate::hair::head::Head),
//! line for line as `wgsl/shared/head_sdf.wgsl`: the collision body of the simulation
//! (C13 §4: "the head is represented as a signed distance field"). Ported analytically
//! rather than baked into a grid, so there is no bake error: the only difference from the
//! f64 [`Head::sdf`](crate::hair::head::Head::sdf) is f32 rounding (tested below).

/// Values in a packed head.
pub const PACKED_LEN: usize = 37;

type V3 = [f32; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn len(a: V3) -> f32 {
    dot(a, a).sqrt()
}
fn div(a: V3, b: V3) -> V3 {
    [a[0] / b[0], a[1] / b[1], a[2] / b[2]]
}
fn at(h: &[f32], i: usize) -> V3 {
    [h[i], h[i + 1], h[i + 2]]
}

fn sd_ellipsoid(p: V3, r: V3) -> f32 {
    let k0 = len(div(p, r));
    let k1 = len(div(div(p, r), r));
    let rmin = r[0].min(r[1]).min(r[2]);
    if k1 < 1e-30 {
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

fn sd_capsule(p: V3, a: V3, b: V3, r: f32) -> f32 {
    let (pa, ba) = (sub(p, a), sub(b, a));
    let h = (dot(pa, ba) / dot(ba, ba).max(1e-18)).clamp(0.0, 1.0);
    len(sub(pa, [ba[0] * h, ba[1] * h, ba[2] * h])) - r
}

fn sd_rounded_cylinder(p: V3, c: V3, ra: f32, hh: f32, rb: f32) -> f32 {
    let q = sub(p, c);
    let dx = (q[0] * q[0] + q[2] * q[2]).sqrt() - ra + rb;
    let dy = q[1].abs() - hh + rb;
    let (mx, my) = (dx.max(0.0), dy.max(0.0));
    dx.max(dy).min(0.0) + (mx * mx + my * my).sqrt() - rb
}

fn smin(a: f32, b: f32, k: f32) -> f32 {
    let h = (k - (a - b).abs()).max(0.0) / k;
    a.min(b) - h * h * k * 0.25
}

/// Signed distance (metres, negative inside) at `p` in head space.
pub fn head_sdf(h: &[f32], p: V3) -> f32 {
    let k = h[35];
    let mut d = sd_ellipsoid(sub(p, at(h, 0)), at(h, 3));
    d = smin(d, sd_ellipsoid(sub(p, at(h, 6)), at(h, 9)), k);
    d = smin(d, sd_ellipsoid(sub(p, at(h, 12)), at(h, 15)), 0.5 * k);
    d = smin(d, sd_capsule(p, at(h, 18), at(h, 21), h[24]), 0.5 * k);
    let neck = sd_rounded_cylinder(p, at(h, 30), h[34], h[33], 0.01);
    d = smin(d, neck, 2.0 * k);
    let pe = [p[0].abs(), p[1], p[2]];
    let c = at(h, 25);
    let ear = sd_capsule(
        pe,
        [c[0], c[1] - h[28], c[2]],
        [c[0], c[1] + h[28], c[2]],
        h[29],
    );
    smin(d, ear, h[36])
}

/// Central-difference gradient (step 0.5 mm), not normalised.
pub fn head_sdf_grad(h: &[f32], p: V3) -> V3 {
    let e = 5e-4;
    let f = |dx: f32, dy: f32, dz: f32| head_sdf(h, [p[0] + dx, p[1] + dy, p[2] + dz]);
    [
        f(e, 0.0, 0.0) - f(-e, 0.0, 0.0),
        f(0.0, e, 0.0) - f(0.0, -e, 0.0),
        f(0.0, 0.0, e) - f(0.0, 0.0, -e),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hair::head::Head;
    use glam::Vec3;

    #[test]
    fn f32_port_matches_the_f64_head() {
        let head = Head::default();
        let packed = head.sdf_packed();
        assert_eq!(packed.len(), PACKED_LEN);
        let mut worst = 0.0f32;
        for i in 0..4000 {
            let t = i as f32;
            let p = [
                (t * 0.731).sin() * 0.15,
                (t * 0.377).cos() * 0.2 - 0.02,
                (t * 0.193).sin() * 0.15,
            ];
            let a = head_sdf(&packed, p);
            let b = head.sdf(Vec3::from_array(p));
            worst = worst.max((a - b).abs());
        }
        assert!(worst < 1e-6, "{worst} m");
        let g = head_sdf_grad(&packed, [0.0, 0.3, 0.0]);
        assert!(g[1] > 0.0 && g[1].abs() > g[0].abs() && g[1].abs() > g[2].abs());
    }
}
