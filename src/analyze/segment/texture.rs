//! Strand texture as a second data term of the segmentation (issue 19).
//!
//! Colour alone cannot part hair from skin of nearly the same colour (blond or auburn hair
//! over a face, chest or arms), nor from a backdrop that shares a tone with it. Hair has fine
//! strands, so its luminance varies at a scale of one or two pixels where skin, walls and
//! windows are smooth. The feature is the local RMS of the luminance minus its 3x3 mean,
//! over a 7x7 window, on a log scale; hair and background each get a histogram of it,
//! learned from the same pixels as the colour mixtures, and a pixel pays the negative log of
//! its bin's share. When the feature does not tell the two apart, the histograms agree and
//! the term is near zero for every pixel.

use crate::base::filter::box_mean;

/// Histogram bins over the feature's range.
pub(super) const BINS: usize = 24;
/// Upper end of the feature (ln(1 + RMS in 8-bit levels)); stronger texture shares the
/// last bin.
const F_MAX: f32 = 4.5;

/// Luminance (Rec. 601 weights) and its 3x3 box mean, which both the texture and the
/// flow-agreement terms start from (computed once per segmentation).
pub(super) fn luminance(rgb: &[[f32; 3]], w: usize, h: usize) -> (Vec<f32>, Vec<f32>) {
    let lum: Vec<f32> = rgb
        .iter()
        .map(|c| 0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2])
        .collect();
    let mean = box_mean(&lum, w, h, 1);
    (lum, mean)
}

/// The per-pixel bin of the texture feature, from [`luminance`]'s two planes.
pub(super) fn texture_bins(lum: &[f32], mean: &[f32], w: usize, h: usize) -> Vec<u8> {
    let e: Vec<f32> = lum
        .iter()
        .zip(mean)
        .map(|(l, m)| (l - m) * (l - m))
        .collect();
    let rms = box_mean(&e, w, h, 3);
    rms.iter()
        .map(|&v| {
            let f = (1.0 + v.max(0.0).sqrt()).ln();
            ((f / F_MAX * BINS as f32) as usize).min(BINS - 1) as u8
        })
        .collect()
}

/// Negative log shares of each bin among `idx`'s pixels, smoothed (one count per bin plus
/// a 5% uniform floor) so that an empty bin is unlikely rather than impossible.
/// `B` is the feature's bin count (texture and agreement share this).
pub(super) fn bin_nll<const B: usize>(bins: &[u8], idx: &[usize]) -> [f32; B] {
    let mut count = [1.0f64; B];
    for &i in idx {
        count[bins[i] as usize] += 1.0;
    }
    let total: f64 = count.iter().sum();
    let mut out = [0f32; B];
    for (o, c) in out.iter_mut().zip(count) {
        let p = 0.95 * c / total + 0.05 / B as f64;
        *o = -(p.ln()) as f32;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strands_score_above_smooth_skin() {
        // Left half: 1-px stripes (strands); right half: a smooth ramp (skin, wall).
        let (w, h) = (40, 20);
        let rgb: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let x = i % w;
                let v = if x < w / 2 {
                    if x % 2 == 0 {
                        90.0
                    } else {
                        150.0
                    }
                } else {
                    150.0 + x as f32
                };
                [v, v, v]
            })
            .collect();
        let (lum, mean) = luminance(&rgb, w, h);
        let b = texture_bins(&lum, &mean, w, h);
        let (strand, smooth) = (b[10 * w + 5], b[10 * w + 35]);
        println!("strand bin {strand}, smooth bin {smooth}");
        assert!(strand > smooth + 10, "strand {strand}, smooth {smooth}");
        let hair: Vec<usize> = (0..w * h).filter(|i| i % w < 10).collect();
        let nll: [f32; BINS] = bin_nll(&b, &hair);
        assert!(nll[strand as usize] < nll[smooth as usize]);
    }
}
