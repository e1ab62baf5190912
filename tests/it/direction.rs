//! Dense growth direction from directed polylines: on the synthetic portraits, the true
//! orientation plus the case's own strokes must give the true growth direction almost
//! everywhere the strokes reach (this isolates the diffusion from the 2D tracer).

use coif::analyze::direction::{dense_direction, DirectionParams, Domain};
use coif::gpu::engine::Engine;
use coif::synth::{synth, Style, SynthParams};

#[test]
fn strokes_and_true_orientation_give_the_true_direction() {
    let engine = Engine::cpu();
    for style in Style::ALL {
        let case = synth(&SynthParams {
            style,
            seed: 1,
            width: 256,
            height: 256,
        });
        let mask: Vec<u8> = case.mask.pixels().map(|m| (m[0] > 127) as u8).collect();
        // Dense "curves": the true field's streamlines are what a perfect tracer returns; a
        // grid of short segments along gt_dir, 4 px apart like traced curves, stands in.
        let mut curves = Vec::new();
        for y in (2..256).step_by(4) {
            for x in (2..256).step_by(4) {
                let i = y * 256 + x;
                let (dx, dy) = (case.gt_dir[2 * i], case.gt_dir[2 * i + 1]);
                if dx.is_finite() {
                    let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                    curves.push(vec![
                        [px - 2.0 * dx, py - 2.0 * dy],
                        [px + 2.0 * dx, py + 2.0 * dy],
                    ]);
                }
            }
        }
        let strokes: Vec<Vec<[f32; 2]>> = case
            .strokes
            .strokes
            .iter()
            .map(|s| s.points.clone())
            .collect();
        let d = Domain {
            width: 256,
            height: 256,
            mask: &mask,
            theta: Some(&case.gt_theta),
        };
        let dir =
            dense_direction(&engine, &d, &curves, &strokes, &DirectionParams::default()).unwrap();
        let (mut good, mut n) = (0usize, 0usize);
        for i in 0..256 * 256 {
            if mask[i] == 0 || !case.gt_dir[2 * i].is_finite() {
                continue;
            }
            n += 1;
            let dot = dir[2 * i] * case.gt_dir[2 * i] + dir[2 * i + 1] * case.gt_dir[2 * i + 1];
            good += (dot > 0.0) as usize;
        }
        let share = good as f64 / n as f64;
        println!(
            "{style}: {:.2}% of {n} hair px point the true way",
            100.0 * share
        );
        assert!(share >= 0.98, "{style}: {share}");
    }
}

#[test]
fn pixels_no_curve_reaches_stay_nan() {
    let mask = vec![1u8; 64];
    let theta = vec![0.0f32; 64];
    let d = Domain {
        width: 8,
        height: 8,
        mask: &mask,
        theta: Some(&theta),
    };
    let dir = dense_direction(&Engine::cpu(), &d, &[], &[], &DirectionParams::default()).unwrap();
    assert!(dir.iter().all(|v| v.is_nan()));
}
