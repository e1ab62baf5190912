//! Ken Perlin's improved noise (Perlin 2002, "Improving Noise"), the wind of C13 §4.
//!
//! [`perlin64`] is the reference implementation transcribed in f64 (it reproduces Perlin's
//! published values exactly); [`perlin32`] does the same f32 arithmetic in the same order as
//! `wgsl/shared/noise.wgsl`, so the CPU mirror and the shader agree to rounding.

/// Perlin's permutation of 0..=255.
pub const PERM: [u8; 256] = [
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69,
    142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219,
    203, 117, 35, 11, 32, 57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175,
    74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230,
    220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76,
    132, 187, 208, 89, 18, 169, 200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173,
    186, 3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212, 207, 206,
    59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213, 119, 248, 152, 2, 44, 154, 163,
    70, 221, 153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232,
    178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162,
    241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157, 184, 84, 204,
    176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141,
    128, 195, 78, 66, 215, 61, 156, 180,
];

/// The doubled table the shaders read (`p[i] = PERM[i & 255]` for i < 512), as u32.
pub fn perm_table() -> Vec<u32> {
    (0..512).map(|i| PERM[i & 255] as u32).collect()
}

fn p(i: usize) -> usize {
    PERM[i & 255] as usize
}

pub fn fade64(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lerp64(t: f64, a: f64, b: f64) -> f64 {
    a + t * (b - a)
}

fn grad64(hash: usize, x: f64, y: f64, z: f64) -> f64 {
    let h = hash & 15;
    let u = if h < 8 { x } else { y };
    let v = if h < 4 {
        y
    } else if h == 12 || h == 14 {
        x
    } else {
        z
    };
    (if h & 1 == 0 { u } else { -u }) + (if h & 2 == 0 { v } else { -v })
}

/// Improved noise at (x, y, z), in about [-1, 1]; the reference implementation.
pub fn perlin64(x: f64, y: f64, z: f64) -> f64 {
    let (fx, fy, fz) = (x.floor(), y.floor(), z.floor());
    let (xi, yi, zi) = (
        (fx as i64 & 255) as usize,
        (fy as i64 & 255) as usize,
        (fz as i64 & 255) as usize,
    );
    let (x, y, z) = (x - fx, y - fy, z - fz);
    let (u, v, w) = (fade64(x), fade64(y), fade64(z));
    let a = p(xi) + yi;
    let (aa, ab) = (p(a) + zi, p(a + 1) + zi);
    let b = p(xi + 1) + yi;
    let (ba, bb) = (p(b) + zi, p(b + 1) + zi);
    lerp64(
        w,
        lerp64(
            v,
            lerp64(u, grad64(p(aa), x, y, z), grad64(p(ba), x - 1.0, y, z)),
            lerp64(
                u,
                grad64(p(ab), x, y - 1.0, z),
                grad64(p(bb), x - 1.0, y - 1.0, z),
            ),
        ),
        lerp64(
            v,
            lerp64(
                u,
                grad64(p(aa + 1), x, y, z - 1.0),
                grad64(p(ba + 1), x - 1.0, y, z - 1.0),
            ),
            lerp64(
                u,
                grad64(p(ab + 1), x, y - 1.0, z - 1.0),
                grad64(p(bb + 1), x - 1.0, y - 1.0, z - 1.0),
            ),
        ),
    )
}

fn fade32(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lerp32(t: f32, a: f32, b: f32) -> f32 {
    a + t * (b - a)
}

/// Branch-free: the hash is random, so branches on it would mispredict about half the time
/// (the noise was a fifth of a simulation step with them). Selects and sign flips of the
/// bits give the values of the branches, to the bit.
fn grad32(hash: u32, x: f32, y: f32, z: f32) -> f32 {
    let h = hash & 15;
    let pick = |c: bool, a: f32, b: f32| {
        let m = (c as u32).wrapping_neg();
        f32::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
    };
    let u = pick(h < 8, x, y);
    let v = pick(h < 4, y, pick(h == 12 || h == 14, x, z));
    // Negation flips the sign bit and nothing else.
    let u = f32::from_bits(u.to_bits() ^ ((h & 1) << 31));
    let v = f32::from_bits(v.to_bits() ^ ((h & 2) << 30));
    u + v
}

/// `f32::floor` without the libm call (the baseline x86-64 has no rounding instruction):
/// truncation, one down for negative non-integers; values of 2^23 and more are integers
/// already, and NaN stays NaN. Equal to `floor` to the bit, the sign of zero included.
fn floor32(x: f32) -> f32 {
    if x.is_nan() || x.abs() >= 8_388_608.0 {
        return x;
    }
    let t = x as i32 as f32;
    let f = if t > x { t - 1.0 } else { t };
    if f == 0.0 {
        f.copysign(x)
    } else {
        f
    }
}

/// [`perlin64`] in f32, as the shaders compute it. `perm` is [`perm_table`].
pub fn perlin32(perm: &[u32], x: f32, y: f32, z: f32) -> f32 {
    let (fx, fy, fz) = (floor32(x), floor32(y), floor32(z));
    // Two's complement & 255 wraps negative cells as the reference does.
    let xi = (fx as i32 & 255) as u32;
    let yi = (fy as i32 & 255) as u32;
    let zi = (fz as i32 & 255) as u32;
    let (x, y, z) = (x - fx, y - fy, z - fz);
    let (u, v, w) = (fade32(x), fade32(y), fade32(z));
    let q = |i: u32| perm[i as usize];
    let a = q(xi) + yi;
    let (aa, ab) = (q(a) + zi, q(a + 1) + zi);
    let b = q(xi + 1) + yi;
    let (ba, bb) = (q(b) + zi, q(b + 1) + zi);
    let x1 = x - 1.0;
    let y1 = y - 1.0;
    let z1 = z - 1.0;
    lerp32(
        w,
        lerp32(
            v,
            lerp32(u, grad32(q(aa), x, y, z), grad32(q(ba), x1, y, z)),
            lerp32(u, grad32(q(ab), x, y1, z), grad32(q(bb), x1, y1, z)),
        ),
        lerp32(
            v,
            lerp32(u, grad32(q(aa + 1), x, y, z1), grad32(q(ba + 1), x1, y, z1)),
            lerp32(
                u,
                grad32(q(ab + 1), x, y1, z1),
                grad32(q(bb + 1), x1, y1, z1),
            ),
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor32_is_floor_to_the_bit() {
        let mut xs = vec![
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            8_388_607.5,
            -8_388_607.5,
        ];
        xs.extend([
            8_388_608.0,
            -8_388_609.0,
            3e9,
            -3e9,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ]);
        xs.extend([
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            0.99999994,
        ]);
        let mut r = crate::base::rng::Rng::new(7);
        for _ in 0..100_000 {
            let e = r.below(60) as i32 - 30;
            xs.push(r.range_f32(-1.0, 1.0) * 2f32.powi(e));
        }
        for x in xs {
            assert_eq!(floor32(x).to_bits(), x.floor().to_bits(), "{x:e}");
        }
        assert!(floor32(f32::NAN).is_nan());
    }

    #[test]
    fn grad32_takes_the_branches_values() {
        let (x, y, z) = (0.3f32, -0.7f32, 0.0f32);
        for h in 0..64u32 {
            let g = h & 15;
            let u = if g < 8 { x } else { y };
            let v = if g < 4 {
                y
            } else if g == 12 || g == 14 {
                x
            } else {
                z
            };
            let want = (if g & 1 == 0 { u } else { -u }) + (if g & 2 == 0 { v } else { -v });
            assert_eq!(grad32(h, x, y, z).to_bits(), want.to_bits(), "hash {h}");
        }
    }

    #[test]
    // 3.14 is Perlin's test point, not an approximation of π.
    #[allow(clippy::approx_constant)]
    fn reference_values() {
        assert_eq!(perlin64(3.14, 42.0, 7.0), 0.13691995878400012);
        assert_eq!(perlin64(-4.2, 10.0, 6.0), 0.14208000000000043);
        assert_eq!(fade64(0.75), 0.896484375);
        // Integer lattice points are zero.
        assert_eq!(perlin64(1.0, 2.0, 3.0), 0.0);
    }

    #[test]
    fn f32_follows_f64() {
        let perm = perm_table();
        let mut worst = 0.0f64;
        for i in 0..20_000 {
            let t = i as f32 * 0.01;
            let (x, y, z) = (t * 1.3 - 50.0, (t * 0.7).sin() * 9.0, t * 0.37 + 3.0);
            let a = perlin32(&perm, x, y, z) as f64;
            let b = perlin64(x as f64, y as f64, z as f64);
            worst = worst.max((a - b).abs());
        }
        assert!(worst < 2e-5, "{worst}");
    }
}
