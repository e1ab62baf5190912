//! Colour conversions in one place: 8- and 16-bit sRGB codes for image files, the f16
//! storage rule of the render target, and the HSV adjustment of strand colours.
//! [`shader`] is the CPU mirror of `wgsl/shared/colour.wgsl` (used by the strand shading and
//! strand raster passes), function for function; [`hsv_adjust`] is its host-side entry.

use glam::Vec3;
use rayon::prelude::*;

/// 8-bit sRGB code to linear light, with the exact sRGB transfer function (a table of
/// [`srgb_to_linear_exact`]: the same values without a `powf` per call, which was most of
/// the per-vertex colour sampling of `coif model`).
pub fn srgb_to_linear(v: u8) -> f32 {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|v| srgb_to_linear_exact(v as u8)))[v as usize]
}

/// 8-bit sRGB code to linear light, computed.
fn srgb_to_linear_exact(v: u8) -> f32 {
    let c = v as f64 / 255.0;
    let l = if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    };
    l as f32
}

fn linear_to_srgb_unit(l: f32) -> f64 {
    // NaN counts as 0.
    let l = if l > 0.0 { (l as f64).min(1.0) } else { 0.0 };
    if l <= 0.0031308 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

/// Linear light to the nearest 8-bit sRGB code (clamped to [0, 1]; NaN gives 0).
pub fn linear_to_srgb(l: f32) -> u8 {
    (linear_to_srgb_unit(l) * 255.0).round() as u8
}

/// Linear light to the nearest 16-bit sRGB code (clamped to [0, 1]; NaN gives 0).
pub fn linear_to_srgb16(l: f32) -> u16 {
    (linear_to_srgb_unit(l) * 65535.0).round() as u16
}

fn unit_alpha(a: f32) -> f64 {
    if a > 0.0 {
        (a as f64).min(1.0)
    } else {
        0.0
    }
}

/// Straight linear RGBA to 8-bit sRGB RGBA (alpha stays linear), e.g. for a PNG.
pub fn to_rgba8(img: &[[f32; 4]]) -> Vec<u8> {
    let mut out = vec![0u8; img.len() * 4];
    out.par_chunks_mut(4 * 4096)
        .zip(img.par_chunks(4096))
        .for_each(|(o, px)| {
            for (o, p) in o.chunks_exact_mut(4).zip(px) {
                for c in 0..3 {
                    o[c] = linear_to_srgb(p[c]);
                }
                o[3] = (unit_alpha(p[3]) * 255.0).round() as u8;
            }
        });
    out
}

/// Straight linear RGBA to 16-bit sRGB RGBA (alpha stays linear), e.g. for a 16-bit PNG.
pub fn to_rgba16(img: &[[f32; 4]]) -> Vec<u16> {
    let mut out = vec![0u16; img.len() * 4];
    out.par_chunks_mut(4 * 4096)
        .zip(img.par_chunks(4096))
        .for_each(|(o, px)| {
            for (o, p) in o.chunks_exact_mut(4).zip(px) {
                for c in 0..3 {
                    o[c] = linear_to_srgb16(p[c]);
                }
                o[3] = (unit_alpha(p[3]) * 65535.0).round() as u16;
            }
        });
    out
}

/// IEEE binary16 bits of `x`, rounded to nearest, ties to even (overflow gives infinity).
pub fn f32_to_f16_bits(x: f32) -> u16 {
    let b = x.to_bits();
    let sign = ((b >> 16) & 0x8000) as u16;
    let exp = ((b >> 23) & 0xff) as i32;
    let man = b & 0x7f_ffff;
    if exp == 0xff {
        let nan = if man != 0 {
            0x200 | (man >> 13) as u16
        } else {
            0
        };
        return sign | 0x7c00 | nan;
    }
    let e = exp - 127 + 15;
    if e >= 0x1f {
        return sign | 0x7c00;
    }
    let (half, rem, halfway) = if e <= 0 {
        // Subnormal half: value = m · 2^-24 with m = mantissa (implicit 1) >> (14 - e).
        if e < -10 {
            return sign;
        }
        let m = man | 0x80_0000;
        let shift = (14 - e) as u32;
        (m >> shift, m & ((1 << shift) - 1), 1u32 << (shift - 1))
    } else {
        (((e as u32) << 10) | (man >> 13), man & 0x1fff, 0x1000)
    };
    let up = rem > halfway || (rem == halfway && half & 1 == 1);
    // A carry out of the mantissa correctly bumps the exponent (up to infinity).
    sign | (half + up as u32) as u16
}

/// The f32 value of IEEE binary16 bits.
pub fn f16_bits_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0f32 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as u32;
    let man = (h & 0x3ff) as u32;
    match exp {
        0 => sign * man as f32 * (1.0 / 16_777_216.0),
        0x1f => f32::from_bits(((h as u32 & 0x8000) << 16) | 0x7f80_0000 | (man << 13)),
        _ => f32::from_bits(((h as u32 & 0x8000) << 16) | ((exp + 112) << 23) | (man << 13)),
    }
}

/// IEEE binary16 bits of `x`, rounded toward zero (overflow gives the largest finite value),
/// as lavapipe converts when it writes an f32 colour into an Rgba16Float target.
pub fn f32_to_f16_bits_rtz(x: f32) -> u16 {
    let b = x.to_bits();
    let sign = ((b >> 16) & 0x8000) as u16;
    let exp = ((b >> 23) & 0xff) as i32;
    let man = b & 0x7f_ffff;
    if exp == 0xff {
        return f32_to_f16_bits(x);
    }
    let e = exp - 127 + 15;
    if e >= 0x1f {
        return sign | 0x7bff;
    }
    if e <= 0 {
        if e < -10 {
            return sign;
        }
        return sign | ((man | 0x80_0000) >> (14 - e) as u32) as u16;
    }
    sign | (((e as u32) << 10) | (man >> 13)) as u16
}

/// The value a render-target write keeps: f16, truncated (see [`f32_to_f16_bits_rtz`]).
/// Equal to `f16_bits_to_f32(f32_to_f16_bits_rtz(x))`, computed in the f32 domain (the
/// resolve calls it for every sample channel): in the f16 normal range truncation keeps the
/// top 10 mantissa bits, below it the f16 quantum is 2^-24. (Always inlined, so the AVX2
/// resolve rounds natively instead of calling libm's `truncf`.)
#[inline(always)]
pub fn f16_store(x: f32) -> f32 {
    let a = x.abs();
    if a >= 6.103_515_6e-5 {
        if a > 65504.0 {
            return if x.is_nan() {
                f32::NAN
            } else {
                65504.0f32.copysign(x)
            };
        }
        f32::from_bits(x.to_bits() & 0xffff_e000)
    } else {
        // |x| < 2^-14: x·2^24 < 1024 is exact, truncate it (toward zero) and scale back.
        (x * 16_777_216.0).trunc() * (1.0 / 16_777_216.0)
    }
}

/// NaN → 0, then clamped to [0, 1].
pub fn unit_or_zero(x: f32) -> f32 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, 1.0)
    }
}

/// [`hsv_adjust_linear`](shader::hsv_adjust_linear) on a linear colour: NaN channels
/// become 0 and values are clamped to [0, 1] first, the hue shift is taken mod 360.
pub fn hsv_adjust(rgb: [f32; 3], hue_deg_shift: f32, sat_scale: f32, val_scale: f32) -> [f32; 3] {
    let c = Vec3::from(rgb.map(unit_or_zero));
    shader::hsv_adjust_linear(c, hue_deg_shift.rem_euclid(360.0), sat_scale, val_scale).into()
}

/// The mirror of `wgsl/shared/colour.wgsl`: f32 throughout, the operations the shaders do.
pub mod shader {
    use glam::Vec3;

    /// The exact sRGB encoding (IEC 61966-2-1) of a linear value in [0, 1].
    pub fn linear_to_srgb(x: f32) -> f32 {
        if x <= 0.003_130_8 {
            12.92 * x
        } else {
            1.055 * x.powf(0.416_666_66) - 0.055
        }
    }

    /// The exact sRGB decoding of an encoded value in [0, 1].
    pub fn srgb_to_linear(x: f32) -> f32 {
        if x <= 0.040_45 {
            x / 12.92
        } else {
            ((x + 0.055) / 1.055).powf(2.4)
        }
    }

    /// sRGB-encoded RGB in [0, 1] → [sextant base ∈ {0, 2, 4}, offset ∈ [−1, 1], saturation,
    /// value]; the hue is 60° · (base + offset). Base and offset stay apart so that a round trip
    /// keeps the offset's low bits (adding 2 or 4 first would cost up to 2.4e-7 of hue).
    pub fn rgb_to_hsv_split(c: Vec3) -> [f32; 4] {
        let mx = c.x.max(c.y).max(c.z);
        let mn = c.x.min(c.y).min(c.z);
        let ch = mx - mn;
        let s = if mx > 0.0 { ch / mx } else { 0.0 };
        let (base, off) = if ch <= 0.0 {
            (0.0, 0.0)
        } else if mx == c.x {
            (0.0, (c.y - c.z) / ch)
        } else if mx == c.y {
            (2.0, (c.z - c.x) / ch)
        } else {
            (4.0, (c.x - c.y) / ch)
        };
        [base, off, s, mx]
    }

    /// The textbook sector formula for hue 60° · (base + off), base integer-valued, off any real.
    pub fn hsv_split_to_rgb(base: f32, off: f32, s: f32, v: f32) -> Vec3 {
        let fl = off.floor();
        let f = off - fl;
        let k = base + fl;
        let sector = k - 6.0 * (k / 6.0).floor();
        let p = v - v * s;
        let q = v - v * s * f;
        let t = v - v * s * (1.0 - f);
        if sector < 0.5 {
            Vec3::new(v, t, p)
        } else if sector < 1.5 {
            Vec3::new(q, v, p)
        } else if sector < 2.5 {
            Vec3::new(p, v, t)
        } else if sector < 3.5 {
            Vec3::new(p, q, v)
        } else if sector < 4.5 {
            Vec3::new(t, p, v)
        } else {
            Vec3::new(v, p, q)
        }
    }

    /// HSV adjustment of a linear colour in [0, 1], done on the displayed (sRGB-encoded) colour:
    /// hue + `hue_deg`, saturation and value scaled and clamped to [0, 1].
    pub fn hsv_adjust_linear(rgb: Vec3, hue_deg: f32, sat: f32, val: f32) -> Vec3 {
        let c = Vec3::new(
            linear_to_srgb(rgb.x),
            linear_to_srgb(rgb.y),
            linear_to_srgb(rgb.z),
        );
        let hsv = rgb_to_hsv_split(c);
        // The shift in sextants, split so that whole sextants move the base exactly.
        let x = hue_deg / 60.0;
        let xi = x.floor();
        let o = hsv_split_to_rgb(
            hsv[0] + xi,
            hsv[1] + (x - xi),
            (hsv[2] * sat).clamp(0.0, 1.0),
            (hsv[3] * val).clamp(0.0, 1.0),
        );
        Vec3::new(
            srgb_to_linear(o.x),
            srgb_to_linear(o.y),
            srgb_to_linear(o.z),
        )
    }
}

/// Bilinear sample of the photo at pixel coordinates (pixel centres at +0.5), linear 0..1.
pub fn sample_rgb(img: &image::RgbImage, x: f32, y: f32) -> [f32; 3] {
    let (w, h) = img.dimensions();
    let fx = (x - 0.5).clamp(0.0, (w - 1) as f32);
    let fy = (y - 0.5).clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (fx.floor() as u32, fy.floor() as u32);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (ax, ay) = (fx - x0 as f32, fy - y0 as f32);
    // Linear light, as `StrandSet::colors` holds (and bilinear mixing is meant in).
    let px = |x, y| img.get_pixel(x, y).0.map(srgb_to_linear);
    let (a, b, c, d) = (px(x0, y0), px(x1, y0), px(x0, y1), px(x1, y1));
    std::array::from_fn(|k| {
        let top = a[k] + ax * (b[k] - a[k]);
        let bot = c[k] + ax * (d[k] - c[k]);
        top + ay * (bot - top)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_and_matches_the_curve() {
        for v in 0..=255u8 {
            assert_eq!(linear_to_srgb(srgb_to_linear(v)), v);
        }
        assert_eq!(srgb_to_linear(0), 0.0);
        assert_eq!(srgb_to_linear(255), 1.0);
        // Mid-grey 0.5 linear is sRGB 187.5 -> 188 (the curve, not a 2.2 gamma: 186).
        assert_eq!(linear_to_srgb(0.5), 188);
        assert_eq!(linear_to_srgb(f32::NAN), 0);
        assert_eq!(linear_to_srgb(2.0), 255);
        assert_eq!(linear_to_srgb16(1.0), 65535);
        assert!((srgb_to_linear(10) - 10.0 / 255.0 / 12.92).abs() < 1e-9);
        let img = [[1.0f32, 0.5, 0.0, 0.5]];
        assert_eq!(to_rgba8(&img), vec![255, 188, 0, 128]);
        assert_eq!(to_rgba16(&img)[3], 32768);
    }

    #[test]
    fn f16_conversion_is_exact_and_rounds_to_even() {
        for h in 0..=u16::MAX {
            let f = f16_bits_to_f32(h);
            if f.is_nan() {
                assert!(f32_to_f16_bits(f) & 0x7c00 == 0x7c00 && f32_to_f16_bits(f) & 0x3ff != 0);
                continue;
            }
            assert_eq!(f32_to_f16_bits(f), h, "round trip of {h:#06x} ({f})");
            // Midpoint to the next value up rounds to the even one of the two.
            let next = h.wrapping_add(1);
            if h & 0x7fff < 0x7bff {
                let g = f16_bits_to_f32(next);
                let mid = ((f as f64 + g as f64) / 2.0) as f32;
                if mid as f64 == (f as f64 + g as f64) / 2.0 {
                    let even = if h & 1 == 0 { h } else { next };
                    assert_eq!(
                        f32_to_f16_bits(mid),
                        even,
                        "tie between {h:#06x} and {next:#06x}"
                    );
                }
            }
        }
        assert_eq!(f16_bits_to_f32(0x3c00), 1.0);
        assert_eq!(f32_to_f16_bits(65520.0), 0x7c00, "rounds up to infinity");
        assert_eq!(f32_to_f16_bits(1e-8), 0);
    }
}
