//! The image bands of CZ06 §2 (Eq. 1): CIE L*u*v* (D65) from sRGB, gray I_Y = L*, the low
//! band I_L (a Gaussian low-pass of I_Y inside the hair), the high band I_H = I_Y − I_L,
//! and the colour map from gray to (u*, v*).
//!
//! The low band is a normalised convolution, G∗(I_Y·m) / G∗m with m the hair mask, so that
//! the background does not bleed into the hair near its edge; both blurs are the `sep_blur`
//! pass through the engine. The colour conversions and the map are per-pixel arithmetic and
//! a 16-bin histogram: CPU.

use super::{ColourMap, COLOUR_BINS};
use crate::base::sentinel::SENTINEL;
use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::stages::sep_blur;
use image::RgbImage;

/// Default σ of the low band, pixels (the reading notes' proposal).
pub const SIGMA_L: f32 = 8.0;

/// D65 white point, Y = 1.
const WHITE: [f64; 3] = [0.95047, 1.0, 1.08883];

fn white_uv() -> (f64, f64) {
    let [x, y, z] = WHITE;
    let d = x + 15.0 * y + 3.0 * z;
    (4.0 * x / d, 9.0 * y / d)
}

fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn linear_to_srgb(c: f64) -> f64 {
    if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// CIE L*u*v* (D65) of an 8-bit sRGB colour: L* in [0, 100], u*, v* roughly in [−100, 180].
pub fn rgb_to_luv(rgb: [u8; 3]) -> [f32; 3] {
    let [r, g, b] = rgb.map(|c| srgb_to_linear(c as f64 / 255.0));
    let x = 0.4124564 * r + 0.3575761 * g + 0.1804375 * b;
    let y = 0.2126729 * r + 0.7151522 * g + 0.0721750 * b;
    let z = 0.0193339 * r + 0.1191920 * g + 0.9503041 * b;
    let yr = y / WHITE[1];
    let l = if yr > (6.0f64 / 29.0).powi(3) {
        116.0 * yr.cbrt() - 16.0
    } else {
        (29.0f64 / 3.0).powi(3) * yr
    };
    let d = x + 15.0 * y + 3.0 * z;
    if d <= 0.0 {
        return [l as f32, 0.0, 0.0];
    }
    let (un, vn) = white_uv();
    let (up, vp) = (4.0 * x / d, 9.0 * y / d);
    [
        l as f32,
        (13.0 * l * (up - un)) as f32,
        (13.0 * l * (vp - vn)) as f32,
    ]
}

/// Linear sRGB (unclamped) of an L*u*v* colour.
fn luv_to_linear(l: f32, u: f32, v: f32) -> [f64; 3] {
    let (l, u, v) = (l as f64, u as f64, v as f64);
    if l <= 0.0 {
        return [0.0; 3];
    }
    let (un, vn) = white_uv();
    let up = u / (13.0 * l) + un;
    let vp = v / (13.0 * l) + vn;
    let y = if l > 8.0 {
        ((l + 16.0) / 116.0).powi(3)
    } else {
        l * (3.0f64 / 29.0).powi(3)
    } * WHITE[1];
    if vp <= 0.0 {
        return [y; 3];
    }
    let x = y * 9.0 * up / (4.0 * vp);
    let z = y * (12.0 - 3.0 * up - 20.0 * vp) / (4.0 * vp);
    [
        3.2404542 * x - 1.5371385 * y - 0.4985314 * z,
        -0.9692660 * x + 1.8760108 * y + 0.0415560 * z,
        0.0556434 * x - 0.2040259 * y + 1.0572252 * z,
    ]
}

/// 8-bit sRGB of an L*u*v* colour, its chroma reduced into the gamut at constant L*.
pub fn luv_to_rgb(l: f32, u: f32, v: f32) -> [u8; 3] {
    // Out of gamut, the chroma shrinks at constant L* (bisection on its scale; gray is in
    // gamut): clipping each channel instead would change the lightness, and with it the
    // texture's streaks in dark or light hair.
    let inside = |c: [f64; 3]| c.iter().all(|v| (-1e-4..=1.0 + 1e-4).contains(v));
    let mut rgb = luv_to_linear(l, u, v);
    if !inside(rgb) {
        let (mut lo, mut hi) = (0.0f32, 1.0f32);
        for _ in 0..16 {
            let m = 0.5 * (lo + hi);
            if inside(luv_to_linear(l, m * u, m * v)) {
                lo = m;
            } else {
                hi = m;
            }
        }
        rgb = luv_to_linear(l, lo * u, lo * v);
    }
    rgb.map(|c| {
        (linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0)
            .round()
            .clamp(0.0, 255.0) as u8
    })
}

/// The bands of an image, each row-major width*height.
#[derive(Clone, Debug)]
pub struct Bands {
    pub width: u32,
    pub height: u32,
    /// Gray I_Y = L*, 0..100.
    pub l: Vec<f32>,
    /// Low band I_L: inside the hair the normalised Gaussian convolution of I_Y over the
    /// hair; outside it, I_Y itself (so the high band is 0 there).
    pub low: Vec<f32>,
    /// High band I_H = I_Y − I_L.
    pub high: Vec<f32>,
    /// Chroma u*, v*.
    pub u: Vec<f32>,
    pub v: Vec<f32>,
}

fn check_inputs(img: &RgbImage, hair: &[bool], sigma: f32, what: &str) -> Result<()> {
    let (w, h) = img.dimensions();
    if w == 0 || h == 0 {
        return Err(Error::Invalid(format!(
            "{what}: the image is empty ({w}x{h})"
        )));
    }
    if hair.len() != w as usize * h as usize {
        return Err(Error::Invalid(format!(
            "{what}: the hair mask has {} pixels, the {w}x{h} image {}",
            hair.len(),
            w as usize * h as usize
        )));
    }
    if !hair.iter().any(|&m| m) {
        return Err(Error::Invalid(format!("{what}: the hair mask is empty")));
    }
    if !(sigma.is_finite() && (0.5..=128.0).contains(&sigma)) {
        return Err(Error::Invalid(format!(
            "{what}: the low band's sigma must be in 0.5..=128 pixels, got {sigma}"
        )));
    }
    Ok(())
}

/// Normalised Gaussian convolutions of `planes` (each w*h) inside `hair`, one engine run:
/// G∗(p·m) / G∗m on hair pixels, NaN elsewhere.
pub fn blur_in_mask(
    engine: &Engine,
    planes: &[&[f32]],
    hair: &[bool],
    w: u32,
    h: u32,
    sigma: f32,
) -> Result<Vec<Vec<f32>>> {
    let n = w as usize * h as usize;
    let mut rec = Recording::default();
    let m: Vec<f32> = hair.iter().map(|&b| b as u8 as f32).collect();
    let mut outs = Vec::new();
    for p in std::iter::once(&m[..]).chain(planes.iter().copied()) {
        let data: Vec<f32> = p.iter().zip(&m).map(|(a, b)| a * b).collect();
        let src = rec.upload("coif.sketch.bands.plane", &data);
        let out = rec.alloc("coif.sketch.bands.blurred", n as u64 * 4, SENTINEL);
        sep_blur::record_gaussian(&mut rec, src, out, w, h, sigma);
        rec.download(out);
        outs.push(out);
    }
    let dl = engine.run(rec)?;
    let blurred: Vec<Vec<f32>> = outs
        .iter()
        .map(|&o| dl.get::<f32>(o)[..n].to_vec())
        .collect();
    if blurred
        .iter()
        .any(|b| b.iter().any(|v| v.to_bits() == SENTINEL))
    {
        return Err(Error::Gpu("sep_blur left band pixels unwritten".into()));
    }
    let den = &blurred[0];
    Ok(blurred[1..]
        .iter()
        .map(|num| {
            (0..n)
                .map(|k| {
                    // A hair pixel weighs exp(0) in its own sum, so den > 0 up to rounding.
                    if hair[k] && den[k] > 1e-6 {
                        num[k] / den[k]
                    } else {
                        f32::NAN
                    }
                })
                .collect()
        })
        .collect())
}

/// Splits `img` into its bands with the low band blurred by `sigma_l` pixels inside `hair`.
pub fn bands(engine: &Engine, img: &RgbImage, hair: &[bool], sigma_l: f32) -> Result<Bands> {
    check_inputs(img, hair, sigma_l, "bands")?;
    let (w, h) = img.dimensions();
    let n = w as usize * h as usize;
    let (mut l, mut u, mut v) = (vec![0f32; n], vec![0f32; n], vec![0f32; n]);
    for (k, p) in img.pixels().enumerate() {
        let [a, b, c] = rgb_to_luv(p.0);
        (l[k], u[k], v[k]) = (a, b, c);
    }
    let blurred = blur_in_mask(engine, &[&l], hair, w, h, sigma_l)?;
    let low: Vec<f32> = blurred[0]
        .iter()
        .zip(&l)
        .map(|(&b, &y)| if b.is_nan() { y } else { b })
        .collect();
    let high = l.iter().zip(&low).map(|(y, lo)| y - lo).collect();
    Ok(Bands {
        width: w,
        height: h,
        l,
        low,
        high,
        u,
        v,
    })
}

/// `img` blurred by `sigma` inside `hair`, per sRGB channel (normalised convolution), as
/// 8-bit-scale floats; pixels off the hair keep their colour. The reference the low band
/// plus colour map is measured against.
pub fn blur_rgb_in_mask(
    engine: &Engine,
    img: &RgbImage,
    hair: &[bool],
    sigma: f32,
) -> Result<Vec<[f32; 3]>> {
    check_inputs(img, hair, sigma, "blur")?;
    let (w, h) = img.dimensions();
    let ch: Vec<Vec<f32>> = (0..3)
        .map(|c| img.pixels().map(|p| p[c] as f32).collect())
        .collect();
    let b = blur_in_mask(engine, &[&ch[0], &ch[1], &ch[2]], hair, w, h, sigma)?;
    Ok((0..w as usize * h as usize)
        .map(|k| {
            let pick = |c: usize| if b[c][k].is_nan() { ch[c][k] } else { b[c][k] };
            [pick(0), pick(1), pick(2)]
        })
        .collect())
}

/// Width of an L* bin of the colour map.
const BIN: f32 = 100.0 / COLOUR_BINS as f32;

impl ColourMap {
    /// The mean (u*, v*) of the hair pixels in each of the 16 L* bins; empty bins take the
    /// linear interpolation of their nearest non-empty neighbours (the end ones the nearest
    /// value). No hair at all gives a gray map.
    pub fn fit(b: &Bands, hair: &[bool]) -> ColourMap {
        let mut sum = vec![[0f64; 3]; COLOUR_BINS];
        for (k, _) in hair.iter().enumerate().take(b.l.len()).filter(|(_, &m)| m) {
            let i = ((b.l[k] / BIN) as usize).min(COLOUR_BINS - 1);
            sum[i][0] += b.u[k] as f64;
            sum[i][1] += b.v[k] as f64;
            sum[i][2] += 1.0;
        }
        let full: Vec<usize> = (0..COLOUR_BINS).filter(|&i| sum[i][2] > 0.0).collect();
        let mean = |i: usize| {
            [
                (sum[i][0] / sum[i][2]) as f32,
                (sum[i][1] / sum[i][2]) as f32,
            ]
        };
        let uv = (0..COLOUR_BINS)
            .map(|i| {
                if full.is_empty() {
                    return [0.0, 0.0];
                }
                if sum[i][2] > 0.0 {
                    return mean(i);
                }
                let below = full.iter().rev().find(|&&j| j < i);
                let above = full.iter().find(|&&j| j > i);
                match (below, above) {
                    (Some(&a), Some(&c)) => {
                        let t = (i - a) as f32 / (c - a) as f32;
                        let (p, q) = (mean(a), mean(c));
                        [p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]
                    }
                    (Some(&a), None) => mean(a),
                    (None, Some(&c)) => mean(c),
                    (None, None) => unreachable!("full is not empty"),
                }
            })
            .collect();
        ColourMap { uv }
    }

    /// (u*, v*) at gray `l`: linear between the bin centres, constant beyond the end ones.
    pub fn chroma(&self, l: f32) -> [f32; 2] {
        let n = self.uv.len();
        if n == 0 {
            return [0.0, 0.0];
        }
        let t = (l / BIN - 0.5).clamp(0.0, (n - 1) as f32);
        let t = if t.is_nan() { 0.0 } else { t };
        let i = (t as usize).min(n - 1);
        let j = (i + 1).min(n - 1);
        let f = t - i as f32;
        let (a, b) = (self.uv[i], self.uv[j]);
        [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])]
    }

    /// The 8-bit sRGB colour of gray `l` (L*) through the map.
    pub fn to_rgb(&self, l: f32) -> [u8; 3] {
        let [u, v] = self.chroma(l);
        luv_to_rgb(l, u, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn luv_round_trips_and_matches_references() {
        // Reference values (D65): white, a mid gray, pure red.
        let w = rgb_to_luv([255, 255, 255]);
        assert!((w[0] - 100.0).abs() < 1e-3 && w[1].abs() < 1e-2 && w[2].abs() < 1e-2);
        let r = rgb_to_luv([255, 0, 0]);
        assert!((r[0] - 53.24).abs() < 0.02, "{r:?}");
        assert!(
            (r[1] - 175.01).abs() < 0.05 && (r[2] - 37.76).abs() < 0.05,
            "{r:?}"
        );
        let mut worst = 0;
        for k in 0..4096u32 {
            let c = [
                (k * 37 % 256) as u8,
                (k * 101 % 256) as u8,
                (k * 7 % 256) as u8,
            ];
            let [l, u, v] = rgb_to_luv(c);
            let back = luv_to_rgb(l, u, v);
            for i in 0..3 {
                worst = worst.max((back[i] as i32 - c[i] as i32).abs());
            }
        }
        assert!(worst <= 1, "round trip off by {worst}");
    }

    #[test]
    fn bands_split_and_respect_the_mask() {
        let (w, h) = (40u32, 30u32);
        let img = RgbImage::from_fn(w, h, |x, y| {
            if x < 20 {
                image::Rgb([200, 180, 150])
            } else {
                image::Rgb([(x * 3 + y) as u8, 40, 30])
            }
        });
        // The hair is the right half; the bright left half must not leak into its low band.
        let hair: Vec<bool> = (0..w * h).map(|i| i % w >= 20).collect();
        let b = bands(&Engine::cpu(), &img, &hair, 4.0).unwrap();
        let brightest_hair = (0..(w * h) as usize)
            .filter(|&k| hair[k])
            .map(|k| b.l[k])
            .fold(f32::MIN, f32::max);
        for (k, &m) in hair.iter().enumerate() {
            assert!((b.l[k] - b.low[k] - b.high[k]).abs() < 1e-4);
            if m {
                assert!(b.low[k] <= brightest_hair + 1e-3, "leak at {k}");
            } else {
                assert_eq!(b.high[k], 0.0);
            }
        }
        let e = bands(&Engine::cpu(), &img, &vec![false; (w * h) as usize], 4.0);
        assert!(e.unwrap_err().to_string().contains("empty"));
    }

    #[test]
    fn colour_map_interpolates_empty_bins() {
        let b = Bands {
            width: 3,
            height: 1,
            l: vec![10.0, 60.0, 99.0],
            low: vec![0.0; 3],
            high: vec![0.0; 3],
            u: vec![2.0, 12.0, 40.0],
            v: vec![-4.0, 6.0, 0.0],
        };
        let m = ColourMap::fit(&b, &[true, true, false]);
        assert_eq!(m.uv.len(), COLOUR_BINS);
        // L 10 is bin 1, L 60 bin 9; bins between interpolate, bins after repeat bin 9.
        assert_eq!(m.uv[0], [2.0, -4.0]);
        assert_eq!(m.uv[1], [2.0, -4.0]);
        assert!((m.uv[5][0] - 7.0).abs() < 1e-5 && (m.uv[5][1] - 1.0).abs() < 1e-5);
        assert_eq!(m.uv[15], [12.0, 6.0]);
        // A gray map gives gray colours.
        let g = ColourMap {
            uv: vec![[0.0, 0.0]; COLOUR_BINS],
        };
        let c = g.to_rgb(50.0);
        assert!(
            c[0].abs_diff(c[1]) <= 1 && c[1].abs_diff(c[2]) <= 1,
            "{c:?}"
        );
    }
}
