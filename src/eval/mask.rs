//! A hair mask scored against a reference mask drawn by hand (issue 19's figure): the IoU,
//! what was missed and taken, how much of the disagreement lies at the reference's edge
//! (a hand-drawn outline is itself only good to a pixel or two), the boundary F-measure,
//! and a picture of the disagreement.

use crate::synth::distance_to;
use image::{GrayImage, RgbImage};
use serde::Serialize;

/// Width of the band around the reference's edge that the edge-aware figures leave out or
/// forgive (px): about what two careful annotators disagree by.
pub const EDGE_BAND: f32 = 2.0;

/// How a mask agrees with a reference mask (both: > 127 is hair).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MaskAgreement {
    /// |mask ∩ reference| / |mask ∪ reference|.
    pub iou: f64,
    /// Share of the mask's hair that the reference calls hair.
    pub precision: f64,
    /// Share of the reference's hair that the mask has.
    pub recall: f64,
    /// Reference hair pixels.
    pub reference_hair: u64,
    /// Mask hair pixels.
    pub mask_hair: u64,
    /// Reference hair the mask misses.
    pub missed: u64,
    /// Non-hair (to the reference) that the mask takes.
    pub taken: u64,
    /// The band (px) of the next two figures and of the boundary F-measure.
    pub band_px: f32,
    /// The IoU if every error farther than `band_px` from the reference's edge were fixed:
    /// what the errors at the edge alone cost.
    pub iou_edge_errors_only: f64,
    /// The IoU over the pixels farther than `band_px` from the reference's edge: what the
    /// mask gets wrong where the reference is sure.
    pub iou_beyond_band: f64,
    /// Boundary F-measure: the harmonic mean of the shares of each outline's pixels that lie
    /// within `band_px` of the other's.
    pub boundary_f: f64,
    /// The reference grown and shrunk by one pixel all round, scored against itself: what a
    /// one-pixel disagreement along the whole outline costs at this size.
    pub one_pixel_off_iou: [f64; 2],
}

/// Scores `mask` against `reference` (the same size; checked by the caller, which knows the
/// file names). The reference must hold hair: an empty one gives no IoU to read.
pub fn agreement(mask: &GrayImage, reference: &GrayImage) -> MaskAgreement {
    assert_eq!(
        mask.dimensions(),
        reference.dimensions(),
        "masks of one size"
    );
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    let got: Vec<bool> = mask.as_raw().iter().map(|&v| v > 127).collect();
    let truth: Vec<bool> = reference.as_raw().iter().map(|&v| v > 127).collect();
    let (inter, uni, missed, taken) = counts(&got, &truth, |_| true);
    let to_edge = edge_distance(&truth, w, h);
    let near = |i: usize| to_edge[i] <= EDGE_BAND;
    let (_, _, missed_near, taken_near) = counts(&got, &truth, near);
    let reference_hair = truth.iter().filter(|&&t| t).count() as u64;
    let mask_hair = got.iter().filter(|&&t| t).count() as u64;
    let (inter_far, uni_far, _, _) = counts(&got, &truth, |i| !near(i));
    let grown = crate::base::mask::dilate(&as_u8(&truth), w, h, 1);
    let shrunk = crate::base::mask::erode(&as_u8(&truth), w, h, 1);
    let self_iou = |m: &[u8]| {
        let m: Vec<bool> = m.iter().map(|&v| v != 0).collect();
        let (i, u, _, _) = counts(&m, &truth, |_| true);
        ratio(i, u)
    };
    MaskAgreement {
        iou: ratio(inter, uni),
        precision: ratio(inter, mask_hair),
        recall: ratio(inter, reference_hair),
        reference_hair,
        mask_hair,
        missed,
        taken,
        band_px: EDGE_BAND,
        iou_edge_errors_only: ratio(reference_hair - missed_near, reference_hair + taken_near),
        iou_beyond_band: ratio(inter_far, uni_far),
        boundary_f: boundary_f(&got, &truth, w, h, EDGE_BAND),
        one_pixel_off_iou: [self_iou(&grown), self_iou(&shrunk)],
    }
}

/// The photo with agreed hair tinted green, missed hair red and taken non-hair blue; the
/// rest as it is.
pub fn disagreement_picture(photo: &RgbImage, mask: &GrayImage, reference: &GrayImage) -> RgbImage {
    let mut o = photo.clone();
    for (i, p) in o.pixels_mut().enumerate() {
        let (t, c) = (reference.as_raw()[i] > 127, mask.as_raw()[i] > 127);
        let tint = match (t, c) {
            (true, true) => [0, 255, 0],
            (true, false) => [255, 0, 0],
            (false, true) => [0, 80, 255],
            _ => continue,
        };
        for k in 0..3 {
            p[k] = ((p[k] as u32 + tint[k]) / 2) as u8;
        }
    }
    o
}

fn ratio(a: u64, b: u64) -> f64 {
    a as f64 / b.max(1) as f64
}

fn as_u8(m: &[bool]) -> Vec<u8> {
    m.iter().map(|&t| t as u8).collect()
}

/// (intersection, union, missed, taken) over the pixels `keep` accepts.
fn counts(got: &[bool], truth: &[bool], keep: impl Fn(usize) -> bool) -> (u64, u64, u64, u64) {
    let (mut inter, mut uni, mut missed, mut taken) = (0u64, 0u64, 0u64, 0u64);
    for (i, (&c, &t)) in got.iter().zip(truth).enumerate() {
        if !keep(i) {
            continue;
        }
        inter += (t && c) as u64;
        uni += (t || c) as u64;
        missed += (t && !c) as u64;
        taken += (!t && c) as u64;
    }
    (inter, uni, missed, taken)
}

/// Per pixel, the distance to the nearest pixel of the other label.
fn edge_distance(m: &[bool], w: usize, h: usize) -> Vec<f32> {
    let not: Vec<bool> = m.iter().map(|&t| !t).collect();
    let (to_hair, to_not) = (distance_to(m, w, h), distance_to(&not, w, h));
    m.iter()
        .enumerate()
        .map(|(i, &t)| if t { to_not[i] } else { to_hair[i] })
        .collect()
}

/// Hair pixels with a 4-neighbour that is not hair (the image's border is not an edge).
fn outline(m: &[bool], w: usize, h: usize) -> Vec<bool> {
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            m[i] && ((x > 0 && !m[i - 1])
                || (x + 1 < w && !m[i + 1])
                || (y > 0 && !m[i - w])
                || (y + 1 < h && !m[i + w]))
        })
        .collect()
}

fn boundary_f(got: &[bool], truth: &[bool], w: usize, h: usize, band: f32) -> f64 {
    let (a, b) = (outline(got, w, h), outline(truth, w, h));
    let (na, nb) = (
        a.iter().filter(|&&t| t).count(),
        b.iter().filter(|&&t| t).count(),
    );
    if na == 0 || nb == 0 {
        return (na == nb) as u8 as f64;
    }
    let (to_a, to_b) = (distance_to(&a, w, h), distance_to(&b, w, h));
    let hits =
        |on: &[bool], to: &[f32]| on.iter().zip(to).filter(|(&o, &d)| o && d <= band).count();
    let precision = hits(&a, &to_b) as f64 / na as f64;
    let recall = hits(&b, &to_a) as f64 / nb as f64;
    if precision + recall == 0.0 {
        0.0
    } else {
        2.0 * precision * recall / (precision + recall)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc(w: u32, h: u32, cx: f32, cy: f32, r: f32) -> GrayImage {
        GrayImage::from_fn(w, h, |x, y| {
            let d = ((x as f32 - cx).powi(2) + (y as f32 - cy).powi(2)).sqrt();
            image::Luma([if d <= r { 255 } else { 0 }])
        })
    }

    #[test]
    fn a_mask_agrees_with_itself_and_not_with_another() {
        let a = disc(64, 48, 30.0, 24.0, 15.0);
        let s = agreement(&a, &a);
        assert_eq!((s.iou, s.boundary_f, s.missed, s.taken), (1.0, 1.0, 0, 0));
        assert_eq!(s.iou_edge_errors_only, 1.0);
        assert!(s.one_pixel_off_iou[0] < 1.0 && s.one_pixel_off_iou[1] < 1.0);
        // The pair that must fail: a disc moved by 10 px.
        let b = disc(64, 48, 40.0, 24.0, 15.0);
        let s = agreement(&b, &a);
        assert!(s.iou < 0.6, "{s:?}");
        assert!(s.boundary_f < 0.5, "{s:?}");
        assert!(s.missed > 0 && s.taken > 0);
        assert_eq!(s.missed, s.taken, "a moved disc misses what it takes");
    }

    #[test]
    fn errors_at_the_edge_are_told_from_errors_beyond_it() {
        let truth = disc(80, 80, 40.0, 40.0, 20.0);
        // One pixel fatter all round: every error lies at the edge.
        let fat = disc(80, 80, 40.0, 40.0, 21.0);
        let s = agreement(&fat, &truth);
        assert!(s.iou < 1.0 && s.taken > 0 && s.missed == 0);
        assert_eq!(
            s.iou_edge_errors_only, s.iou,
            "all its errors are near the edge"
        );
        assert_eq!(s.iou_beyond_band, 1.0);
        assert_eq!(s.boundary_f, 1.0);
        // A blob far from the hair: an error beyond the band.
        let mut blob = truth.clone();
        for y in 2..8 {
            for x in 2..8 {
                blob.put_pixel(x, y, image::Luma([255]));
            }
        }
        let s = agreement(&blob, &truth);
        assert_eq!(s.taken, 36);
        assert!(s.iou_beyond_band < 1.0);
        assert_eq!(s.iou_edge_errors_only, 1.0);
        assert!(s.boundary_f < 1.0);
    }

    #[test]
    fn the_picture_tints_each_kind_of_pixel() {
        let photo = RgbImage::from_pixel(4, 1, image::Rgb([100, 100, 100]));
        let mask = GrayImage::from_raw(4, 1, vec![255, 0, 255, 0]).unwrap();
        let truth = GrayImage::from_raw(4, 1, vec![255, 255, 0, 0]).unwrap();
        let p = disagreement_picture(&photo, &mask, &truth);
        assert_eq!(p.get_pixel(0, 0).0, [50, 177, 50]);
        assert_eq!(p.get_pixel(1, 0).0, [177, 50, 50]);
        assert_eq!(p.get_pixel(2, 0).0, [50, 90, 177]);
        assert_eq!(p.get_pixel(3, 0).0, [100, 100, 100]);
    }
}
