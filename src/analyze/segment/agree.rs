//! Agreement with the strokes' flow, a third data term of the segmentation (issue 19).
//!
//! The user's direction strokes say not only where hair is but which way it runs. Hair near
//! a stroke runs roughly along it; a face, a lace collar or a shop window next to the hair
//! shows edges that run any way (eyelids and brows across a curtain of straight hair) or
//! none (smooth skin, walls). The feature is the image's local orientation, from the
//! structure tensor, compared with the orientation the strokes predict there:
//! `coherence · cos 2(θ_image − θ_strokes)`, in [−1, 1]. The prediction at a pixel is the
//! doubled-angle mean of the stroke segments' directions weighted by a Gaussian of the
//! distance to each segment, measured from the nearest one (so that it is defined far from
//! every stroke too). As with the texture term, hair and background each get a histogram
//! of the feature learned from the current labelling, so a portrait where it does not tell
//! the two apart (short hair that curls every way) gets a term near zero.
//!
//! The term is one-sided: structure across the strokes counts against hair, structure
//! along them does not count for it. A face's contour, a cheek's folds and a collar's edge
//! beside the hair run along the strokes too; counted as hair evidence, they pulled whole
//! cheeks into the mask on the Grace Hopper portrait once the weight passed 3, while the
//! one-sided term holds from weight 1 to 9 (issue 19 note).

use crate::base::filter::box_mean;
use crate::io::annot::{StrokeKind, Strokes};
use rayon::prelude::*;

/// Histogram bins over [−1, 1].
pub(super) const BINS: usize = 16;
/// Gaussian (px) of the distance to a stroke segment in the predicted orientation.
const SIGMA: f32 = 12.0;
/// Box radius of the structure tensor's window, applied twice (a Gaussian-like window of
/// about 7 px across).
const WINDOW: usize = 2;

/// The per-pixel bin of the agreement feature. `lum` is the luminance's 3x3 mean
/// (`texture::luminance`): the light blur keeps JPEG noise from passing for structure.
pub(super) fn agreement_bins(lum: &[f32], strokes: &Strokes, w: usize, h: usize) -> Vec<u8> {
    let predicted = stroke_orientation(strokes, w, h);
    let (mut xx, mut yy, mut xy) = (vec![0f32; w * h], vec![0f32; w * h], vec![0f32; w * h]);
    for y in 0..h {
        for x in 0..w {
            let at = |xi: usize, yi: usize| lum[yi * w + xi];
            let gx = 0.5 * (at((x + 1).min(w - 1), y) - at(x.saturating_sub(1), y));
            let gy = 0.5 * (at(x, (y + 1).min(h - 1)) - at(x, y.saturating_sub(1)));
            let i = y * w + x;
            (xx[i], yy[i], xy[i]) = (gx * gx, gy * gy, gx * gy);
        }
    }
    let smooth = |v: &[f32]| box_mean(&box_mean(v, w, h, WINDOW), w, h, WINDOW);
    let (xx, yy, xy) = (smooth(&xx), smooth(&yy), smooth(&xy));
    (0..w * h)
        .map(|i| {
            // The gradient's doubled angle is (xx − yy, 2xy); the strands run across it.
            let (c, s) = (yy[i] - xx[i], -2.0 * xy[i]);
            let trace = xx[i] + yy[i];
            let f = if trace > 1e-6 {
                let [pc, ps] = predicted[i];
                (c * pc + s * ps) / trace
            } else {
                0.0
            };
            (((f.clamp(-1.0, 1.0) + 1.0) * 0.5 * BINS as f32) as usize).min(BINS - 1) as u8
        })
        .collect()
}

/// A direction stroke's segment: start, direction (end − start), squared length and the
/// doubled-angle unit vector of its orientation.
struct Segment {
    a: [f32; 2],
    d: [f32; 2],
    l2: f32,
    doubled: [f32; 2],
}

/// The strokes' predicted orientation at every pixel as a doubled-angle vector
/// (cos 2θ, sin 2θ) scaled by how much the nearby segments agree (1 when they are parallel).
fn stroke_orientation(strokes: &Strokes, w: usize, h: usize) -> Vec<[f32; 2]> {
    let segs: Vec<Segment> = strokes
        .strokes
        .iter()
        .filter(|s| s.kind == StrokeKind::Direction)
        .flat_map(|s| s.points.windows(2))
        .filter_map(|p| {
            let (a, b) = (p[0], p[1]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let l2 = d[0] * d[0] + d[1] * d[1];
            (l2 > 0.0).then(|| {
                let (c, s) = (d[0] / l2.sqrt(), d[1] / l2.sqrt());
                Segment {
                    a,
                    d,
                    l2,
                    doubled: [c * c - s * s, 2.0 * c * s],
                }
            })
        })
        .collect();
    // Per pixel and independent, so parallel and still deterministic.
    (0..w * h)
        .into_par_iter()
        .map_init(
            || vec![0f32; segs.len()],
            |d2, i| {
                let (px, py) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
                for (k, g) in segs.iter().enumerate() {
                    let (a, d) = (g.a, g.d);
                    let t = (((px - a[0]) * d[0] + (py - a[1]) * d[1]) / g.l2).clamp(0.0, 1.0);
                    let (ex, ey) = (px - a[0] - t * d[0], py - a[1] - t * d[1]);
                    d2[k] = ex * ex + ey * ey;
                }
                let nearest = d2.iter().copied().fold(f32::INFINITY, f32::min);
                let (mut c, mut s, mut sum) = (0f32, 0f32, 0f32);
                for (k, g) in segs.iter().enumerate() {
                    // Longer segments carry more of the stroke; distances from the nearest one.
                    let wt = g.l2.sqrt() * (-(d2[k] - nearest) / (2.0 * SIGMA * SIGMA)).exp();
                    c += wt * g.doubled[0];
                    s += wt * g.doubled[1];
                    sum += wt;
                }
                if sum > 0.0 {
                    [c / sum, s / sum]
                } else {
                    [0.0, 0.0]
                }
            },
        )
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::annot::Stroke;

    #[test]
    fn stripes_along_the_stroke_agree_and_across_disagree() {
        // Left half: vertical 3-px stripes (hair along a vertical stroke); right half:
        // horizontal stripes (an edge pattern across it); a vertical stroke on the left.
        let (w, h) = (40, 40);
        let rgb: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let on = if x < w / 2 { x % 6 < 3 } else { y % 6 < 3 };
                let v = if on { 60.0 } else { 160.0 };
                [v, v, v]
            })
            .collect();
        let s = Strokes::new(vec![Stroke::new(
            StrokeKind::Direction,
            vec![[10.0, 5.0], [10.0, 35.0]],
        )]);
        let (_, blur) = super::super::texture::luminance(&rgb, w, h);
        let b = agreement_bins(&blur, &s, w, h);
        let (along, across) = (b[20 * w + 8], b[20 * w + 30]);
        println!("along {along}, across {across}");
        assert!(along as usize >= BINS - 2, "along {along}");
        assert!(across <= 1, "across {across}");
    }
}
