//! Pictures of a sketch for people and for golden tests: the curves over the photo (CZ06
//! Fig. 8b), the vector field (Fig. 8d) and the energy per accepted curve (Fig. 13c).

use super::{Curve, Kind, Sketch, VectorField};
use crate::io::vis::{direction_colour, draw_polyline, hsv, hue_ring};
use image::{Rgb, RgbImage};

/// The colour of a curve's type: a boundary blue, a source violet, an occluding line
/// orange, a dividing line red, a stream line white.
pub fn kind_colour(k: Kind) -> Rgb<u8> {
    match k {
        Kind::Boundary => Rgb([60, 140, 255]),
        Kind::Source => Rgb([190, 90, 255]),
        Kind::Occluding => Rgb([255, 150, 30]),
        Kind::Dividing => Rgb([255, 40, 40]),
        Kind::Stream => Rgb([245, 245, 245]),
    }
}

/// The curve's centre line, one point per primitive (a single primitive spans its window).
pub fn centre_line(c: &Curve) -> Vec<[f32; 2]> {
    if c.prims.len() == 1 {
        let p = &c.prims[0];
        let t = p.tangent();
        let h = 0.5 * super::prim::ALONG;
        return vec![
            [p.x - h * t[0], p.y - h * t[1]],
            [p.x + h * t[0], p.y + h * t[1]],
        ];
    }
    c.prims.iter().map(|p| [p.x, p.y]).collect()
}

/// The sketch over `backdrop` (the dimmed photo): each curve in its type's colour, and on
/// each hair side of each primitive a short tick along the growth direction, coloured by
/// that direction on the hue ring of `coif analyze` (the legend in the corner); an
/// undirected side gets a gray tick along its orientation.
pub fn sketch_picture(backdrop: &RgbImage, s: &Sketch) -> RgbImage {
    let mut img = backdrop.clone();
    let tick = 4.0;
    for c in &s.curves {
        let hair = c.kind.hair_sides();
        for p in &c.prims {
            for (side, &has_hair) in hair.iter().enumerate() {
                if !has_hair {
                    continue;
                }
                let n = p.left_normal();
                let sign = if side == 0 { 1.0 } else { -1.0 };
                let o = [p.x + sign * 2.0 * n[0], p.y + sign * 2.0 * n[1]];
                let a = p.side_angle(side);
                let label = c.dirs[side];
                let (v, col) = if label == 0 {
                    ([a.cos(), a.sin()], Rgb([150, 150, 150]))
                } else {
                    let l = label as f32;
                    let v = [l * a.cos(), l * a.sin()];
                    (v, direction_colour(v[0], v[1]))
                };
                let q = [o[0] + tick * v[0], o[1] + tick * v[1]];
                draw_polyline(&mut img, &[o, q], 1.2, |_| col);
            }
        }
        let line = centre_line(c);
        draw_polyline(&mut img, &line, 2.0, |_| kind_colour(c.kind));
    }
    hue_ring(&mut img);
    img
}

/// The vector field over `backdrop`: the growth direction's hue where it is known, the
/// orientation's (doubled-angle hue, paler) where only Θ is.
pub fn field_picture(backdrop: &RgbImage, v: &VectorField) -> RgbImage {
    let mut img = backdrop.clone();
    let w = v.width;
    for (x, y, p) in img.enumerate_pixels_mut() {
        let i = (y * w + x) as usize;
        let d = v.dir[i];
        let c = if d[0].is_finite() && d[1].is_finite() {
            direction_colour(d[0], d[1])
        } else if v.theta[i].is_finite() {
            hsv(2.0 * v.theta[i].to_degrees(), 0.4, 0.9)
        } else {
            continue;
        };
        for k in 0..3 {
            p[k] = (p[k] as f32 * 0.35 + c[k] as f32 * 0.65).round() as u8;
        }
    }
    hue_ring(&mut img);
    img
}

/// The energy after each accepted curve as a line plot (x: curves, y: energy, scaled to
/// the range), on a dark ground with a light frame; `energies[0]` is the empty sketch's.
pub fn energy_picture(energies: &[f64], width: u32, height: u32) -> RgbImage {
    let mut img = RgbImage::from_pixel(width, height, Rgb([24, 24, 28]));
    let m = 12.0;
    let (x0, y0, x1, y1) = (m, m, width as f32 - m, height as f32 - m);
    draw_polyline(&mut img, &[[x0, y0], [x0, y1], [x1, y1]], 1.0, |_| {
        Rgb([160, 160, 160])
    });
    let finite: Vec<f64> = energies.iter().copied().filter(|e| e.is_finite()).collect();
    if finite.len() < 2 {
        return img;
    }
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let span = (hi - lo).max(1e-12);
    let n = finite.len() - 1;
    let pts: Vec<[f32; 2]> = finite
        .iter()
        .enumerate()
        .map(|(k, &e)| {
            [
                x0 + (x1 - x0) * k as f32 / n as f32,
                y1 - (y1 - y0) * ((e - lo) / span) as f32,
            ]
        })
        .collect();
    draw_polyline(&mut img, &pts, 2.0, |_| Rgb([255, 190, 60]));
    img
}
