//! Strokes to directed hair on the synthetic portraits: with the true mask and each case's
//! strokes, the share of traced curve length and of hair pixels (>= 5 px inside the mask)
//! whose growth direction is within 90° of the truth.
//!
//! Issue 3 asks for 98% on every case. The side parting is the hard one: the orientation is
//! continuous across the part, so the tracer runs across it and overshoots onto the narrow
//! side; cutting curves at every apex (`TraceParams::apex_drop`, 1 px) separates the two
//! sides, and the parts then reach 98.1-98.6%.

use coif::analyze::{analyze, AnalyzeParams};
use coif::eval::metrics::{direction_agreement, erode};
use coif::gpu::engine::Engine;
use coif::synth::{synth, Style, SynthParams};

/// Share of curve length whose segments point along the true growth direction.
fn curve_share(curves: &[coif::analyze::trace::Curve], gt_dir: &[f32], w: u32) -> (f64, f64) {
    let (mut good, mut total) = (0.0f64, 0.0f64);
    for c in curves {
        for s in c.points.windows(2) {
            let (a, b) = (s[0], s[1]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let len = dx.hypot(dy) as f64;
            let (mx, my) = (0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]));
            let i = (my as u32 * w + mx as u32) as usize;
            let (gx, gy) = (gt_dir[2 * i], gt_dir[2 * i + 1]);
            if !gx.is_finite() {
                continue;
            }
            total += len;
            if dx * gx + dy * gy > 0.0 {
                good += len;
            }
        }
    }
    (good / total.max(1e-9), total)
}

#[test]
fn directions_on_synthetic_portraits() {
    let engine = Engine::cpu();
    let p = AnalyzeParams::default();
    let mut failures = Vec::new();
    for style in Style::ALL {
        for seed in 1..=3 {
            let case = synth(&SynthParams {
                style,
                seed,
                width: 512,
                height: 512,
            });
            let mask: Vec<u8> = case.mask.pixels().map(|m| (m[0] > 127) as u8).collect();
            let an = analyze(&engine, &case.image, &case.strokes, Some(mask), &p).unwrap();
            let (curve_ok, len) = curve_share(&an.resolved.curves, &case.gt_dir, 512);
            let inner = erode(&case.mask, 5);
            let (px_ok, n) = direction_agreement(&an.direction, &case.gt_dir, &inner);
            let line = format!(
                "{style:<9} seed {seed}: {} curves ({:.0} px), {:.2}% of curve length and {:.2}% of {n} hair px point the true way, {} unreachable",
                an.traced.len(),
                len,
                100.0 * curve_ok,
                100.0 * px_ok,
                an.resolved.unreachable.len()
            );
            println!("{line}");
            if curve_ok < 0.98 || px_ok < 0.98 {
                failures.push(line.clone());
            }
        }
    }
    assert!(failures.is_empty(), "under 98%:\n{}", failures.join("\n"));
}

#[test]
fn segmentation_from_strokes_matches_the_true_mask() {
    let engine = Engine::cpu();
    let p = AnalyzeParams::default();
    let mut failures = Vec::new();
    for style in Style::ALL {
        for seed in 1..=3 {
            let case = synth(&SynthParams {
                style,
                seed,
                width: 512,
                height: 512,
            });
            let an = analyze(&engine, &case.image, &case.strokes, None, &p).unwrap();
            let (mut inter, mut uni) = (0usize, 0usize);
            for (i, m) in case.mask.pixels().enumerate() {
                let t = m[0] > 127;
                let c = an.mask[i] != 0;
                inter += (t && c) as usize;
                uni += (t || c) as usize;
            }
            let iou = inter as f64 / uni as f64;
            let line = format!("{style:<9} seed {seed}: mask IoU {iou:.4}");
            println!("{line}");
            if iou < 0.95 {
                failures.push(line);
            }
        }
    }
    assert!(
        failures.is_empty(),
        "IoU under 0.95:\n{}",
        failures.join("\n")
    );
}
