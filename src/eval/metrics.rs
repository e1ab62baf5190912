//! Accuracy figures against ground truth.

use crate::analyze::orient::OrientMap;

/// Mean orientation error in degrees over hair pixels at least `inset` px inside the mask.
#[derive(Clone, Copy, Debug)]
pub struct OrientError {
    pub mean_deg: f64,
    /// Share of scored pixels within 5 degrees.
    pub within_5deg: f64,
    pub count: usize,
}

/// Pixels whose Chebyshev distance to the nearest non-hair pixel (or the image border) is at
/// least `inset`: a square erosion of the mask, separable so it costs O(n) per radius.
pub fn erode(mask: &image::GrayImage, inset: u32) -> Vec<bool> {
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    let on: Vec<u8> = mask.pixels().map(|p| (p[0] > 127) as u8).collect();
    crate::base::mask::erode(&on, w, h, inset as usize)
        .into_iter()
        .map(|v| v != 0)
        .collect()
}

/// Angular distance of two orientations modulo π, in radians.
pub fn orient_diff(a: f32, b: f32) -> f32 {
    let d = (a - b).abs() % std::f32::consts::PI;
    d.min(std::f32::consts::PI - d)
}

/// Mean orientation error in degrees of `theta` against `truth` over the pixels of `keep`
/// where the truth is set (an unset `theta` counts 90°), and how many were scored.
pub fn mean_orient_error_deg(theta: &[f32], truth: &[f32], keep: &[bool]) -> (f64, usize) {
    let (mut s, mut n) = (0.0f64, 0usize);
    for i in 0..keep.len() {
        if keep[i] && truth[i].is_finite() {
            s += if theta[i].is_finite() {
                orient_diff(theta[i], truth[i]).to_degrees() as f64
            } else {
                90.0
            };
            n += 1;
        }
    }
    (s / n.max(1) as f64, n)
}

pub fn orientation_error(
    map: &OrientMap,
    gt_theta: &[f32],
    mask: &image::GrayImage,
    inset: u32,
) -> OrientError {
    let inner = erode(mask, inset);
    let (mut sum, mut n, mut good) = (0.0f64, 0usize, 0usize);
    for (i, &keep) in inner.iter().enumerate() {
        if !keep || !gt_theta[i].is_finite() {
            continue;
        }
        let d = if map.theta[i].is_finite() {
            orient_diff(map.theta[i], gt_theta[i]).to_degrees() as f64
        } else {
            90.0
        };
        sum += d;
        n += 1;
        good += (d <= 5.0) as usize;
    }
    OrientError {
        mean_deg: if n > 0 { sum / n as f64 } else { f64::NAN },
        within_5deg: if n > 0 { good as f64 / n as f64 } else { 0.0 },
        count: n,
    }
}
