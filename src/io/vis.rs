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

pub use crate::base::stats::percentile;

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

/// The photo, dimmed and desaturated, as a backdrop for curves.
pub fn dimmed(img: &RgbImage, amount: f32) -> RgbImage {
    RgbImage::from_fn(img.width(), img.height(), |x, y| {
        let p = img.get_pixel(x, y);
        let l = 0.2126 * p[0] as f32 + 0.7152 * p[1] as f32 + 0.0722 * p[2] as f32;
        let v = (l * (1.0 - amount)).round().clamp(0.0, 255.0) as u8;
        Rgb([v, v, v])
    })
}

/// Colour of a growth direction on the hue ring: hue = angle of (dx, dy), x right, y down
/// (0° right = red, 90° down = yellow-green, 180° left = cyan, 270° up = violet).
pub fn direction_colour(dx: f32, dy: f32) -> Rgb<u8> {
    hsv(dy.atan2(dx).to_degrees(), 0.9, 1.0)
}

fn blend_px(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>, a: f32) {
    if x < 0 || y < 0 || x >= img.width() as i64 || y >= img.height() as i64 || a <= 0.0 {
        return;
    }
    let p = img.get_pixel_mut(x as u32, y as u32);
    for k in 0..3 {
        p[k] = (p[k] as f32 * (1.0 - a) + c[k] as f32 * a).round() as u8;
    }
}

/// Anti-aliased polyline: coverage from the distance to each segment, one pass per segment.
pub fn draw_polyline(
    img: &mut RgbImage,
    pts: &[[f32; 2]],
    width: f32,
    colour: impl Fn(usize) -> Rgb<u8>,
) {
    let r = 0.5 * width;
    for (k, s) in pts.windows(2).enumerate() {
        let (a, b) = (s[0], s[1]);
        let c = colour(k);
        let (x0, x1) = (a[0].min(b[0]) - r - 1.0, a[0].max(b[0]) + r + 1.0);
        let (y0, y1) = (a[1].min(b[1]) - r - 1.0, a[1].max(b[1]) + r + 1.0);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let l2 = (dx * dx + dy * dy).max(1e-12);
        for y in y0.floor() as i64..=y1.ceil() as i64 {
            for x in x0.floor() as i64..=x1.ceil() as i64 {
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                let t = (((px - a[0]) * dx + (py - a[1]) * dy) / l2).clamp(0.0, 1.0);
                let d = (px - a[0] - t * dx).hypot(py - a[1] - t * dy);
                // Segments share end points; only the first one draws the shared end.
                if k > 0 && t == 0.0 {
                    continue;
                }
                blend_px(img, x, y, c, (r + 0.5 - d).clamp(0.0, 1.0));
            }
        }
    }
}

/// Directed polylines coloured by the direction of each segment, with a hue-ring legend in
/// the top-left corner (as C13 Fig. 2).
pub fn directed_curves(backdrop: &RgbImage, curves: &[&[[f32; 2]]], width: f32) -> RgbImage {
    let mut img = backdrop.clone();
    for pts in curves {
        draw_polyline(&mut img, pts, width, |k| {
            let (a, b) = (pts[k], pts[k + 1]);
            direction_colour(b[0] - a[0], b[1] - a[1])
        });
    }
    hue_ring(&mut img);
    img
}

/// A hue ring legend: the colour at angle φ is the colour of a curve heading at φ.
pub fn hue_ring(img: &mut RgbImage) {
    let s = (img.width().min(img.height()) as f32 * 0.09).clamp(12.0, 48.0);
    let (cx, cy) = (s + 4.0, s + 4.0);
    for y in 0..(2.0 * s + 8.0) as i64 {
        for x in 0..(2.0 * s + 8.0) as i64 {
            let (dx, dy) = (x as f32 + 0.5 - cx, y as f32 + 0.5 - cy);
            let d = dx.hypot(dy);
            let a = (0.5 - (d - 0.8 * s).abs() + 0.2 * s).clamp(0.0, 1.0);
            blend_px(img, x, y, direction_colour(dx, dy), a);
        }
    }
}

/// A dense direction field (H x W x 2, NaN off hair) as hue over the dimmed photo.
pub fn direction_field(backdrop: &RgbImage, dir: &[f32]) -> RgbImage {
    let mut img = backdrop.clone();
    let w = img.width();
    for (x, y, p) in img.enumerate_pixels_mut() {
        let i = (y * w + x) as usize;
        let (dx, dy) = (dir[2 * i], dir[2 * i + 1]);
        if dx.is_finite() && dy.is_finite() {
            let c = direction_colour(dx, dy);
            for k in 0..3 {
                p[k] = ((p[k] as f32 * 0.35) + c[k] as f32 * 0.65).round() as u8;
            }
        }
    }
    hue_ring(&mut img);
    img
}

/// Colour of a mask's outline in [`mask_overlay`]: a yellow purer than hair, even blond, shows.
pub const MASK_EDGE: Rgb<u8> = Rgb([255, 230, 0]);
/// Colour of background strokes in [`mask_overlay`].
pub const BACKGROUND_STROKE: Rgb<u8> = Rgb([255, 0, 255]);
/// Colour of a direction stroke that lies mostly off the mask in [`mask_overlay`] (the
/// stroke `analyze` warns about).
pub const OFF_HAIR_STROKE: Rgb<u8> = Rgb([255, 128, 0]);

/// A hair mask over its photo, for a person to check the segmentation at a glance: hair
/// pixels keep the photo's colours, the rest is dimmed grey, the mask's edge (hair pixels
/// with a 4-neighbour off the hair) is [`MASK_EDGE`], and the strokes are drawn on top:
/// direction strokes white edged in black ([`OFF_HAIR_STROKE`] where under half of a
/// stroke's points lie on the mask), background strokes [`BACKGROUND_STROKE`].
/// `mask` is W·H bytes, non-zero on hair.
pub fn mask_overlay(
    photo: &RgbImage,
    mask: &[u8],
    direction: &[Vec<[f32; 2]>],
    background: &[Vec<[f32; 2]>],
) -> RgbImage {
    let (w, h) = photo.dimensions();
    assert_eq!(mask.len(), (w * h) as usize, "mask size");
    let back = dimmed(photo, 0.55);
    let hair = |x: i64, y: i64| {
        // Outside the image counts as hair, so hair cut by the frame has no edge there.
        x < 0 || y < 0 || x >= w as i64 || y >= h as i64 || mask[(y * w as i64 + x) as usize] != 0
    };
    let mut img = RgbImage::from_fn(w, h, |x, y| {
        let (xi, yi) = (x as i64, y as i64);
        if !hair(xi, yi) {
            *back.get_pixel(x, y)
        } else if [(-1, 0), (1, 0), (0, -1), (0, 1)]
            .iter()
            .any(|(dx, dy)| !hair(xi + dx, yi + dy))
        {
            MASK_EDGE
        } else {
            *photo.get_pixel(x, y)
        }
    });
    for s in direction {
        let core = if crate::base::mask::share_on(s, mask, w, h) < 0.5 {
            OFF_HAIR_STROKE
        } else {
            Rgb([255, 255, 255])
        };
        draw_polyline(&mut img, s, 4.0, |_| Rgb([0, 0, 0]));
        draw_polyline(&mut img, s, 2.0, |_| core);
    }
    for s in background {
        draw_polyline(&mut img, s, 2.0, |_| BACKGROUND_STROKE);
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mask_overlay_keeps_hair_dims_the_rest_and_outlines_the_edge() {
        let (w, h) = (20u32, 16u32);
        let photo = RgbImage::from_fn(w, h, |x, y| Rgb([200, 120 + x as u8, 60 + y as u8]));
        // Hair: the square x, y in 4..12.
        let mask: Vec<u8> = (0..w * h)
            .map(|i| (((4..12).contains(&(i % w)) && (4..12).contains(&(i / w))) as u8) * 255)
            .collect();
        let bg = vec![vec![[16.5, 2.0], [16.5, 14.0]]];
        let img = mask_overlay(&photo, &mask, &[], &bg);
        // Inside, away from the edge: the photo's own colour.
        assert_eq!(img.get_pixel(7, 8), photo.get_pixel(7, 8));
        // The edge: the square's outer ring of hair pixels.
        for (x, y) in [(4, 4), (11, 7), (8, 11), (4, 9)] {
            assert_eq!(*img.get_pixel(x, y), MASK_EDGE, "({x}, {y})");
        }
        // Off the hair: grey and darker than the photo.
        let (p, q) = (img.get_pixel(1, 1), photo.get_pixel(1, 1));
        assert!(p[0] == p[1] && p[1] == p[2] && p[0] < q[0], "{p:?}");
        // The background stroke down column 16.
        assert_eq!(*img.get_pixel(16, 8), BACKGROUND_STROKE);
        // Direction strokes: white on the hair, the warning's colour mostly off it.
        let on = vec![[6.5, 5.0], [6.5, 10.0]];
        let off = vec![[1.5, 1.0], [1.5, 14.0], [6.0, 14.5]];
        let img = mask_overlay(&photo, &mask, &[on, off], &[]);
        assert_eq!(*img.get_pixel(6, 7), Rgb([255, 255, 255]));
        assert_eq!(*img.get_pixel(1, 4), OFF_HAIR_STROKE);
        // A mask of another size is a caller's bug.
        let r = std::panic::catch_unwind(|| mask_overlay(&photo, &mask[1..], &[], &[]));
        assert!(r.is_err());
    }
}
