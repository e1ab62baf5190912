//! Golden pictures on lavapipe: orientation and confidence of one synthetic case.
//! Metric and blessing: golden/README.md (COIF_BLESS=1 writes missing or changed goldens).

use crate::common;

use coif::analyze::orient::{orient, GrayImage, OrientParams};
use coif::synth::{synth, Style, SynthParams};
use coif::testing::{check_golden_in, check_golden_rgb, golden_dir, rgb_to_rgba};

fn pictures() -> (image::RgbImage, image::RgbImage) {
    let case = synth(&SynthParams {
        style: Style::Long,
        seed: 1,
        width: 256,
        height: 256,
    });
    let gray = GrayImage::from_rgb(&case.image);
    let mask: Vec<u8> = case.mask.pixels().map(|m| (m[0] > 127) as u8).collect();
    let map = orient(&common::gpu(), &gray, Some(&mask), &OrientParams::default()).unwrap();
    (
        coif::io::vis::orientation(256, 256, &map.theta, &map.confidence),
        coif::io::vis::confidence(256, 256, &map.confidence),
    )
}

#[test]
fn orientation_and_confidence_goldens() {
    let (o, c) = pictures();
    let a = check_golden_rgb("orient_synth_long_256", &o);
    let b = check_golden_rgb("confidence_synth_long_256", &c);
    a.unwrap();
    b.unwrap();
}

#[test]
fn a_changed_picture_fails_its_golden() {
    let (mut o, _) = pictures();
    let tmp = tempfile::tempdir().unwrap();
    // The unchanged picture passes (so the failure below is the change, not a missing file).
    check_golden_in(
        &golden_dir(),
        tmp.path(),
        "orient_synth_long_256",
        &rgb_to_rgba(&o),
        false,
    )
    .unwrap();
    for y in 100..140 {
        for x in 100..140 {
            o.put_pixel(x, y, image::Rgb([255, 255, 255]));
        }
    }
    let r = check_golden_in(
        &golden_dir(),
        tmp.path(),
        "orient_synth_long_256",
        &rgb_to_rgba(&o),
        false,
    );
    assert!(r.is_err(), "a 40x40 white block passed the golden check");
}
