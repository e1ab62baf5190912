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

/// Share of the pixels of `keep` where the true growth direction is set whose direction in
/// `dir` points the same way (positive dot product), and how many were scored; both are
/// H×W×2 (x, y per pixel).
pub fn direction_agreement(dir: &[f32], truth: &[f32], keep: &[bool]) -> (f64, usize) {
    let (mut good, mut n) = (0usize, 0usize);
    for (i, &k) in keep.iter().enumerate() {
        if k && truth[2 * i].is_finite() {
            n += 1;
            let d = dir[2 * i] * truth[2 * i] + dir[2 * i + 1] * truth[2 * i + 1];
            good += (d > 0.0) as usize;
        }
    }
    (good as f64 / n.max(1) as f64, n)
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

/// Structural similarity (Wang et al. 2004) of two gray images W*H with values in
/// [0, `peak`], averaged over the pixels of `region`: local statistics under a Gaussian
/// window of σ 1.5 px (radius 5, renormalised at the image border), C1 = (0.01·peak)²,
/// C2 = (0.03·peak)². 1 for identical images.
pub fn ssim_region(a: &[f32], b: &[f32], w: usize, h: usize, region: &[bool], peak: f32) -> f64 {
    assert!(a.len() == w * h && b.len() == w * h && region.len() == w * h);
    const R: i64 = 5;
    let g: Vec<f64> = (-R..=R)
        .map(|k| (-(k * k) as f64 / (2.0 * 1.5 * 1.5)).exp())
        .collect();
    // Separable blur of each product with a border-renormalised window.
    let blur = |f: &dyn Fn(usize) -> f64| -> Vec<f64> {
        let mut tmp = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let (mut s, mut ws) = (0.0, 0.0);
                for (k, gk) in g.iter().enumerate() {
                    let xx = x as i64 + k as i64 - R;
                    if xx >= 0 && (xx as usize) < w {
                        s += gk * f(y * w + xx as usize);
                        ws += gk;
                    }
                }
                tmp[y * w + x] = s / ws;
            }
        }
        let mut out = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let (mut s, mut ws) = (0.0, 0.0);
                for (k, gk) in g.iter().enumerate() {
                    let yy = y as i64 + k as i64 - R;
                    if yy >= 0 && (yy as usize) < h {
                        s += gk * tmp[yy as usize * w + x];
                        ws += gk;
                    }
                }
                out[y * w + x] = s / ws;
            }
        }
        out
    };
    let (fa, fb) = (|i: usize| a[i] as f64, |i: usize| b[i] as f64);
    let ma = blur(&fa);
    let mb = blur(&fb);
    let saa = blur(&|i| fa(i) * fa(i));
    let sbb = blur(&|i| fb(i) * fb(i));
    let sab = blur(&|i| fa(i) * fb(i));
    let c1 = (0.01 * peak as f64).powi(2);
    let c2 = (0.03 * peak as f64).powi(2);
    let (mut s, mut n) = (0.0, 0usize);
    for i in 0..w * h {
        if region[i] {
            let (va, vb) = (saa[i] - ma[i] * ma[i], sbb[i] - mb[i] * mb[i]);
            let cov = sab[i] - ma[i] * mb[i];
            s += (2.0 * ma[i] * mb[i] + c1) * (2.0 * cov + c2)
                / ((ma[i] * ma[i] + mb[i] * mb[i] + c1) * (va + vb + c2));
            n += 1;
        }
    }
    s / n.max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn direction_agreement_counts_pixels_pointing_the_true_way() {
        let truth = [1.0, 0.0, 0.0, 1.0, f32::NAN, f32::NAN, -1.0, 0.0];
        let dir = [0.9, 0.1, 0.0, -1.0, 1.0, 0.0, 1.0, 0.0];
        // Pixel 2 has no truth; of the other three only pixel 0 agrees.
        let (share, n) = direction_agreement(&dir, &truth, &[true; 4]);
        assert_eq!(n, 3);
        assert!((share - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(
            direction_agreement(&dir, &truth, &[true, false, false, false]),
            (1.0, 1)
        );
    }

    #[test]
    fn ssim_is_one_for_equal_images_and_low_for_unrelated_ones() {
        let (w, h) = (48, 40);
        let mut r = crate::base::rng::Rng::new(3);
        let a: Vec<f32> = (0..w * h).map(|_| r.range_f32(0.0, 100.0)).collect();
        let b: Vec<f32> = (0..w * h).map(|_| r.range_f32(0.0, 100.0)).collect();
        let all = vec![true; w * h];
        assert!((ssim_region(&a, &a, w, h, &all, 100.0) - 1.0).abs() < 1e-9);
        let unrelated = ssim_region(&a, &b, w, h, &all, 100.0);
        assert!(unrelated < 0.2, "{unrelated}");
        // A slightly noisier copy sits in between.
        let c: Vec<f32> = a.iter().map(|v| v + r.range_f32(-10.0, 10.0)).collect();
        let near = ssim_region(&a, &c, w, h, &all, 100.0);
        assert!(near > unrelated && near < 1.0, "{near}");
    }
}
