//! Orientation accuracy against the exact ground truth of `coif synth`: every style, seeds
//! 1-3, both backends. Acceptance: mean error <= 1° over hair pixels >= 5 px inside the mask
//! (issue 19's goal; the whorl's seed 3 was 1.11° until its centre got a model of its own).

use crate::common;

use coif::analyze::orient::{orient, GrayImage, OrientParams};
use coif::eval::metrics::orientation_error;
use coif::gpu::engine::Engine;
use coif::synth::{synth, Style, SynthCase, SynthParams};

/// A `coif synth` case at 512², its gray image and its mask as `orient` takes it.
fn case_512(style: Style, seed: u64) -> (SynthCase, GrayImage, Vec<u8>) {
    let case = synth(&SynthParams {
        style,
        seed,
        width: 512,
        height: 512,
    });
    let gray = GrayImage::from_rgb(&case.image);
    let mask = case.mask.pixels().map(|m| (m[0] > 127) as u8).collect();
    (case, gray, mask)
}

#[test]
fn orientation_error_on_synthetic_portraits() {
    const LIMIT: f64 = 1.0;
    let engines = [("cpu", Engine::cpu()), ("gpu", common::gpu())];
    let p = OrientParams::default();
    let mut worst = 0.0f64;
    let mut report = Vec::new();
    for style in Style::ALL {
        for seed in 1..=3 {
            let (case, gray, mask) = case_512(style, seed);
            for (name, e) in &engines {
                let map = orient(e, &gray, Some(&mask), &p).unwrap();
                let err = orientation_error(&map, &case.gt_theta, &case.mask, 5);
                let line = format!(
                    "{style:<9} seed {seed} {name}: mean {:.3} deg, {:.1}% within 5 deg, {} px",
                    err.mean_deg,
                    100.0 * err.within_5deg,
                    err.count
                );
                println!("{line}");
                assert!(err.count > 1000, "{line}: too few scored pixels");
                worst = worst.max(err.mean_deg);
                report.push((line, err.mean_deg));
            }
        }
    }
    println!("worst mean orientation error: {worst:.3} deg (limit {LIMIT})");
    let bad: Vec<_> = report
        .iter()
        .filter(|(_, e)| *e > LIMIT)
        .map(|(l, _)| l.clone())
        .collect();
    assert!(bad.is_empty(), "over {LIMIT} degrees:\n{}", bad.join("\n"));
}

/// The whorl model (`OrientParams::singular_radius`) mends the whorl's centre and leaves a
/// field without a whorl alone, to the bit.
#[test]
fn whorl_model_mends_the_centre_and_nothing_else() {
    let e = Engine::cpu();
    let with = OrientParams::default();
    let without = OrientParams {
        singular_radius: 0.0,
        ..with
    };
    for (style, seed) in [(Style::Whorl, 3), (Style::Long, 1)] {
        let (case, gray, mask) = case_512(style, seed);
        let a = orient(&e, &gray, Some(&mask), &without).unwrap();
        let b = orient(&e, &gray, Some(&mask), &with).unwrap();
        let ea = orientation_error(&a, &case.gt_theta, &case.mask, 5).mean_deg;
        let eb = orientation_error(&b, &case.gt_theta, &case.mask, 5).mean_deg;
        println!("{style:?} seed {seed}: without the model {ea:.3} deg, with it {eb:.3} deg");
        let bits = |m: &coif::analyze::orient::OrientMap| -> Vec<u32> {
            m.theta.iter().map(|t| t.to_bits()).collect()
        };
        if style == Style::Whorl {
            assert!(eb < ea - 0.3, "{style:?}: {ea} -> {eb}");
        } else {
            assert_eq!(bits(&a), bits(&b), "{style:?}: the field changed");
        }
    }
}
