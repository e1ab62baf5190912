//! The head's signed distance in f32 from [`Head::sdf_packed`](crate::hair::head::Head),
//! the arithmetic of `wgsl/shared/head_sdf.wgsl` (its branches as selects here, so that
//! several points can run through it as SIMD lanes): the collision body of the simulation
//! (C13 §4: "the head is represented as a signed distance field"). Ported analytically
//! rather than baked into a grid, so there is no bake error: the only difference from the
//! f64 [`Head::sdf`](crate::hair::head::Head::sdf) is f32 rounding (tested below).

/// Values in a packed head.
pub const PACKED_LEN: usize = 37;

type V3 = [f32; 3];

/// What the distance is computed in: one f32, or [`Lanes`] of several points at once. Both
/// run the same operations in the same order, so a lane's value equals the scalar one to
/// the bit; branches are selects (both sides computed), as a SIMD lane needs them.
pub trait Num:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
{
    fn splat(v: f32) -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
    /// `f32::clamp(self, 0, 1)`.
    fn clamp01(self) -> Self;
    /// `a` where `self < o`, else `b`.
    fn if_lt(self, o: Self, a: Self, b: Self) -> Self;
}

impl Num for f32 {
    fn splat(v: f32) -> Self {
        v
    }
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    fn abs(self) -> Self {
        f32::abs(self)
    }
    fn min(self, o: Self) -> Self {
        f32::min(self, o)
    }
    fn max(self, o: Self) -> Self {
        f32::max(self, o)
    }
    fn clamp01(self) -> Self {
        self.clamp(0.0, 1.0)
    }
    fn if_lt(self, o: Self, a: Self, b: Self) -> Self {
        if self < o {
            a
        } else {
            b
        }
    }
}

/// `L` values computed side by side, lane by lane: loops the compiler turns into SIMD.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lanes<const L: usize>(pub [f32; L]);

impl<const L: usize> Lanes<L> {
    fn map(self, f: impl Fn(f32) -> f32) -> Self {
        Lanes(self.0.map(f))
    }
    fn zip(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        Lanes(std::array::from_fn(|k| f(self.0[k], o.0[k])))
    }
}

macro_rules! lanes_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl<const L: usize> std::ops::$tr for Lanes<L> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                self.zip(o, |a, b| a $op b)
            }
        }
    };
}
lanes_op!(Add, add, +);
lanes_op!(Sub, sub, -);
lanes_op!(Mul, mul, *);
lanes_op!(Div, div, /);

impl<const L: usize> Num for Lanes<L> {
    fn splat(v: f32) -> Self {
        Lanes([v; L])
    }
    fn sqrt(self) -> Self {
        self.map(f32::sqrt)
    }
    fn abs(self) -> Self {
        self.map(f32::abs)
    }
    fn min(self, o: Self) -> Self {
        self.zip(o, f32::min)
    }
    fn max(self, o: Self) -> Self {
        self.zip(o, f32::max)
    }
    fn clamp01(self) -> Self {
        self.map(|v| v.clamp(0.0, 1.0))
    }
    fn if_lt(self, o: Self, a: Self, b: Self) -> Self {
        Lanes(std::array::from_fn(|k| {
            if self.0[k] < o.0[k] {
                a.0[k]
            } else {
                b.0[k]
            }
        }))
    }
}

type P<T> = [T; 3];

fn sub<T: Num>(a: P<T>, b: P<T>) -> P<T> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot<T: Num>(a: P<T>, b: P<T>) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn len<T: Num>(a: P<T>) -> T {
    dot(a, a).sqrt()
}
fn div<T: Num>(a: P<T>, b: P<T>) -> P<T> {
    [a[0] / b[0], a[1] / b[1], a[2] / b[2]]
}
fn at<T: Num>(h: &[f32], i: usize) -> P<T> {
    [T::splat(h[i]), T::splat(h[i + 1]), T::splat(h[i + 2])]
}

fn sd_ellipsoid<T: Num>(p: P<T>, r: P<T>, rmin: f32) -> T {
    let k0 = len(div(p, r));
    let k1 = len(div(div(p, r), r));
    let inv_g = k0 / k1;
    let one = T::splat(1.0);
    let outside = (k0 - one) * inv_g;
    let w = k0 * k0 * k0;
    let inside = (k0 - one) * (w * inv_g + (one - w) * T::splat(rmin));
    let d = k0.if_lt(one, inside, outside);
    k1.if_lt(T::splat(1e-30), T::splat(-rmin), d)
}

fn sd_capsule<T: Num>(p: P<T>, a: P<T>, b: P<T>, r: f32) -> T {
    let (pa, ba) = (sub(p, a), sub(b, a));
    let h = (dot(pa, ba) / dot(ba, ba).max(T::splat(1e-18))).clamp01();
    len(sub(pa, [ba[0] * h, ba[1] * h, ba[2] * h])) - T::splat(r)
}

fn sd_rounded_cylinder<T: Num>(p: P<T>, c: P<T>, ra: f32, hh: f32, rb: f32) -> T {
    let q = sub(p, c);
    let (ra, hh, rb) = (T::splat(ra), T::splat(hh), T::splat(rb));
    let dx = (q[0] * q[0] + q[2] * q[2]).sqrt() - ra + rb;
    let dy = q[1].abs() - hh + rb;
    let zero = T::splat(0.0);
    let (mx, my) = (dx.max(zero), dy.max(zero));
    dx.max(dy).min(zero) + (mx * mx + my * my).sqrt() - rb
}

fn smin<T: Num>(a: T, b: T, k: f32) -> T {
    let kk = T::splat(k);
    let h = (kk - (a - b).abs()).max(T::splat(0.0)) / kk;
    a.min(b) - h * h * kk * T::splat(0.25)
}

/// Signed distance (metres, negative inside) at `p` in head space.
pub fn head_sdf(h: &[f32], p: V3) -> f32 {
    head_sdf_of(h, p)
}

/// [`head_sdf`] of every lane's point.
pub fn head_sdf_of<T: Num>(h: &[f32], p: P<T>) -> T {
    let k = h[35];
    let rmin = |i: usize| h[i].min(h[i + 1]).min(h[i + 2]);
    let mut d = sd_ellipsoid(sub(p, at(h, 0)), at(h, 3), rmin(3));
    d = smin(d, sd_ellipsoid(sub(p, at(h, 6)), at(h, 9), rmin(9)), k);
    d = smin(
        d,
        sd_ellipsoid(sub(p, at(h, 12)), at(h, 15), rmin(15)),
        0.5 * k,
    );
    d = smin(d, sd_capsule(p, at(h, 18), at(h, 21), h[24]), 0.5 * k);
    let neck = sd_rounded_cylinder(p, at(h, 30), h[34], h[33], 0.01);
    d = smin(d, neck, 2.0 * k);
    let pe = [p[0].abs(), p[1], p[2]];
    let c = [h[25], h[26], h[27]];
    let s = T::splat;
    let ear = sd_capsule(
        pe,
        [s(c[0]), s(c[1] - h[28]), s(c[2])],
        [s(c[0]), s(c[1] + h[28]), s(c[2])],
        h[29],
    );
    smin(d, ear, h[36])
}

/// Central-difference gradient (step 0.5 mm), not normalised. The six points are one
/// batch of lanes.
pub fn head_sdf_grad(h: &[f32], p: V3) -> V3 {
    let e = 5e-4;
    let mut q = [Lanes([p[0]; 8]), Lanes([p[1]; 8]), Lanes([p[2]; 8])];
    for (lane, (axis, step)) in [(0, e), (0, -e), (1, e), (1, -e), (2, e), (2, -e)]
        .into_iter()
        .enumerate()
    {
        q[axis].0[lane] = p[axis] + step;
    }
    let f = head_sdf_of(h, q).0;
    [f[0] - f[1], f[2] - f[3], f[4] - f[5]]
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

    /// Lanes give each point's scalar distance to the bit, inside, outside and on the axes
    /// where the branches switch; the gradient's six lanes give the scalar differences.
    #[test]
    fn lanes_give_the_scalar_values_to_the_bit() {
        let packed = Head::default().sdf_packed();
        let mut pts: Vec<V3> = vec![[0.0; 3], [0.0, 0.3, 0.0], [-0.0, 0.0, -0.0]];
        pts.extend((0..4000).map(|i| {
            let t = i as f32;
            [
                (t * 0.731).sin() * 0.2,
                (t * 0.377).cos() * 0.25 - 0.05,
                (t * 0.193).sin() * 0.2,
            ]
        }));
        pts.extend([
            at::<f32>(&packed, 0),
            at(&packed, 6),
            at(&packed, 12),
            at(&packed, 25),
        ]);
        for chunk in pts.chunks(8) {
            let mut q = [Lanes([0.0f32; 8]); 3];
            for (k, p) in chunk.iter().enumerate() {
                for c in 0..3 {
                    q[c].0[k] = p[c];
                }
            }
            let lanes = head_sdf_of(&packed, q).0;
            for (k, p) in chunk.iter().enumerate() {
                assert_eq!(lanes[k].to_bits(), head_sdf(&packed, *p).to_bits(), "{p:?}");
            }
        }
        let e = 5e-4f32;
        for p in &pts[..500] {
            let f = |a: usize, s: f32| {
                let mut q = *p;
                q[a] += s;
                head_sdf(&packed, q)
            };
            let want = [f(0, e) - f(0, -e), f(1, e) - f(1, -e), f(2, e) - f(2, -e)];
            assert_eq!(
                head_sdf_grad(&packed, *p).map(f32::to_bits),
                want.map(f32::to_bits)
            );
        }
    }
}
