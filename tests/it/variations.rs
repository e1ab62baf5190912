//! Issue 19: orientation, growth direction and the original-view re-render on texture
//! variations of the synthetic portraits (`coif synth --texture`), hair the default look does
//! not draw: wavy strands (curly), and a web-photo mix of wider, fainter, curled strands
//! under blur, noise and JPEG compression (photo). Every style at 512², as tests/it/accuracy.rs
//! (at 384² the default Gabor bank loses 0.3-0.8° on every style, so a smaller size would
//! measure the size, not the texture); orientation on seeds 1-2 and both backends (about a
//! minute, lavapipe included), direction and re-render on seed 1 on the cpu backend.
//!
//! Issue 19's goals, printed per style × variation × seed: orientation mean error ≤ 1.0° over
//! hair pixels ≥ 5 px inside the mask; ≥ 98% of traced curve length and of hair pixels
//! pointing the true growth direction; re-render ≥ 30 dB over the hair region. Asserted are
//! the figures that hold today: the backends agree, and direction ≥ 98% on every style. The
//! side part with curl needs `analyze::parting` (the tracer runs across the part where the
//! curl leaves no apex to cut at): cuts at a line of strand ends, and no votes across that
//! line in the resolution (99.6-99.9% on seed 1; 95.0-97.1% with the cuts alone, 93.6-95.6%
//! with neither). Not met (see the README, "Accuracy and speed"): orientation ≤ 1.0°
//! (0.75-2.24° here with the robust local linear fit; 0.9-2.7° with the weighted mean before
//! it). The re-render holds: every hair pixel shows the photo under it (infinite
//! PSNR over the hair region on every case here).

use crate::common;

use coif::analyze::orient::{orient, GrayImage, OrientParams};
use coif::analyze::{analyze, AnalyzeParams};
use coif::eval::metrics::{direction_agreement, erode, orientation_error};
use coif::gpu::engine::Engine;
use coif::model::{model_from_analysis, ModelParams};
use coif::render::{psnr_region, render, to_rgb8, RenderParams};
use coif::synth::{synth_textured, Style, SynthCase, SynthParams, Texture};
use std::path::Path;

const SIZE: u32 = 512;
const SEEDS: [u64; 2] = [1, 2];
/// Issue 19's orientation goal, degrees.
const GOAL_DEG: f64 = 1.0;
const VARIATIONS: [&str; 2] = ["curly", "photo"];

fn case(style: Style, seed: u64, variation: &str) -> SynthCase {
    let t: Texture = variation.parse().unwrap();
    synth_textured(&SynthParams::square(style, seed, SIZE), &t)
}

fn hair(case: &SynthCase) -> Vec<u8> {
    case.mask.pixels().map(|m| (m[0] > 127) as u8).collect()
}

#[test]
fn texture_variations_keep_the_ground_truth_and_change_the_picture() {
    // Same style and seed: the plain texture is `synth`'s portrait; a pixel-only variation
    // keeps the mask, field and strokes and changes the image; curl changes the field.
    let p = SynthParams {
        style: Style::Short,
        seed: 1,
        width: 128,
        height: 128,
    };
    let plain = coif::synth::synth(&p);
    let same = synth_textured(&p, &Texture::default());
    assert_eq!(plain.image, same.image);
    let jpeg = synth_textured(&p, &"jpeg".parse().unwrap());
    assert_eq!(jpeg.mask, plain.mask);
    assert_eq!(jpeg.strokes, plain.strokes);
    let gt_same = jpeg
        .gt_theta
        .iter()
        .zip(&plain.gt_theta)
        .all(|(a, b)| a.to_bits() == b.to_bits());
    assert!(gt_same, "a pixel-only variation changed the ground truth");
    assert_ne!(jpeg.image, plain.image);
    let curly = synth_textured(&p, &"curly".parse().unwrap());
    assert_eq!(curly.mask, plain.mask);
    let turned = curly
        .gt_theta
        .iter()
        .zip(&plain.gt_theta)
        .filter(|(a, b)| a.is_finite() && coif::synth::orientation_error_deg(**a, **b) > 5.0)
        .count();
    assert!(turned > 100, "curl turned only {turned} px of the field");
}

#[test]
fn orientation_on_texture_variations() {
    let engines = [("cpu", Engine::cpu()), ("gpu", common::gpu())];
    let p = OrientParams::default();
    let (mut met, mut total) = (0usize, 0usize);
    let mut disagree = Vec::new();
    for style in Style::ALL {
        for variation in VARIATIONS {
            for seed in SEEDS {
                let c = case(style, seed, variation);
                let gray = GrayImage::from_rgb(&c.image);
                let mut means = Vec::new();
                for (name, e) in &engines {
                    let map = orient(e, &gray, Some(&hair(&c)), &p).unwrap();
                    let err = orientation_error(&map, &c.gt_theta, &c.mask, 5);
                    let line = format!(
                        "{style:<9} {variation:<6} seed {seed} {name}: mean {:.3} deg, {:.1}% \
                         within 5 deg, {} px{}",
                        err.mean_deg,
                        100.0 * err.within_5deg,
                        err.count,
                        if err.mean_deg <= GOAL_DEG {
                            ""
                        } else {
                            "  (over the 1.0 deg goal)"
                        }
                    );
                    println!("{line}");
                    assert!(err.count > 1000, "{line}: too few scored pixels");
                    met += (err.mean_deg <= GOAL_DEG) as usize;
                    total += 1;
                    means.push(err.mean_deg);
                }
                if (means[0] - means[1]).abs() > 0.01 {
                    disagree.push(format!(
                        "{style} {variation} seed {seed}: cpu {:.3} deg, gpu {:.3} deg",
                        means[0], means[1]
                    ));
                }
            }
        }
    }
    println!("orientation goal (mean <= {GOAL_DEG} deg) met on {met} of {total} runs");
    assert!(
        disagree.is_empty(),
        "backends disagree by over 0.01 deg:\n{}",
        disagree.join("\n")
    );
}

/// Share of curve length whose segments point along the true growth direction.
fn curve_share(curves: &[coif::analyze::trace::Curve], gt_dir: &[f32], w: u32) -> f64 {
    let (mut good, mut total) = (0.0f64, 0.0f64);
    for c in curves {
        for s in c.points.windows(2) {
            let (a, b) = (s[0], s[1]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let (mx, my) = (0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]));
            let i = (my as u32 * w + mx as u32) as usize;
            let (gx, gy) = (gt_dir[2 * i], gt_dir[2 * i + 1]);
            if !gx.is_finite() {
                continue;
            }
            let len = dx.hypot(dy) as f64;
            total += len;
            if dx * gx + dy * gy > 0.0 {
                good += len;
            }
        }
    }
    good / total.max(1e-9)
}

#[test]
fn direction_and_rerender_on_texture_variations() {
    let engine = Engine::cpu();
    let mp = ModelParams::default();
    let ap: &AnalyzeParams = &mp.analyze;
    let mut bad = Vec::new();
    let mut worst_psnr = f64::INFINITY;
    for style in Style::ALL {
        for variation in VARIATIONS {
            // One seed: an analysis and a model per case cost about 10 s on 2 cores.
            let seed = 1;
            let c = case(style, seed, variation);
            let mask = hair(&c);
            let region: Vec<bool> = mask.iter().map(|&m| m != 0).collect();
            let an = analyze(&engine, &c.image, &c.strokes, Some(mask), ap).unwrap();
            let curve_ok = curve_share(&an.resolved.curves, &c.gt_dir, SIZE);
            let inner = erode(&c.mask, 5);
            let (px_ok, n) = direction_agreement(&an.direction, &c.gt_dir, &inner);
            let m = model_from_analysis(&engine, &c.image, an, Some(&c.landmarks), &mp).unwrap();
            let scene = m.scene(&c.image, Path::new("synth"));
            let img = to_rgb8(&render(&engine, &scene, &RenderParams::default()).unwrap());
            let psnr = psnr_region(&img, &c.image, &region);
            worst_psnr = worst_psnr.min(psnr);
            let line = format!(
                "{style:<9} {variation:<6} seed {seed}: direction {:.2}% of curve length, \
                 {:.2}% of {n} hair px; re-render {psnr:.2} dB over the hair region",
                100.0 * curve_ok,
                100.0 * px_ok,
            );
            println!("{line}");
            if curve_ok < 0.98 || px_ok < 0.98 {
                bad.push(line);
            }
        }
    }
    println!("worst re-render PSNR over the hair region: {worst_psnr:.2} dB (goal 30)");
    assert!(bad.is_empty(), "direction under 98%:\n{}", bad.join("\n"));
}
