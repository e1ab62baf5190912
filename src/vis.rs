//! Pictures of intermediate products, for people and for golden tests.

use image::{Rgb, RgbImage};

/// HSV (h in degrees, s and v in [0, 1]) to 8-bit RGB.
pub fn hsv(h: f32, s: f32, v: f32) -> Rgb<u8> {
    let h = h.rem_euclid(360.0) / 60.0;
    let c = v * s;
    let x = c * (1.0 - (h % 2.0 - 1.0).abs());
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    let q = |f: f32| ((f + m) * 255.0).round().clamp(0.0, 255.0) as u8;
    Rgb([q(r), q(g), q(b)])
}

/// Value below which `frac` of the finite samples lie (for robust normalisation).
pub fn percentile(data: &[f32], frac: f32) -> f32 {
    let mut v: Vec<f32> = data.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 0.0;
    }
    let k = ((v.len() - 1) as f32 * frac.clamp(0.0, 1.0)).round() as usize;
    let (_, x, _) = v.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    *x
}

/// Orientation as hue (θ = 0 red, π/3 green, 2π/3 blue, wrapping at π), brightness from
/// the confidence (normalised by its 99th percentile, floor 0.35 so weak hair still shows
/// its hue); black where θ is NaN (off the mask).
pub fn orientation(width: u32, height: u32, theta: &[f32], conf: &[f32]) -> RgbImage {
    let scale = percentile(conf, 0.99).max(1e-12);
    RgbImage::from_fn(width, height, |x, y| {
        let i = (y * width + x) as usize;
        let t = theta[i];
        if !t.is_finite() {
            return Rgb([0, 0, 0]);
        }
        let v = 0.35 + 0.65 * (conf[i] / scale).clamp(0.0, 1.0);
        hsv(t.to_degrees() * 2.0, 1.0, v)
    })
}

/// Confidence as gray, normalised by its 99th percentile.
pub fn confidence(width: u32, height: u32, conf: &[f32]) -> RgbImage {
    let scale = percentile(conf, 0.99).max(1e-12);
    RgbImage::from_fn(width, height, |x, y| {
        let c = conf[(y * width + x) as usize];
        let g = ((c / scale).clamp(0.0, 1.0) * 255.0).round() as u8;
        Rgb([g, g, g])
    })
}
