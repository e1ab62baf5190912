//! Issue 4 acceptance on the whole single-view pipeline (cpu backend; every pass it uses has
//! its own lavapipe parity test): roots on the scalp outside the face, coverage of the mask
//! by the projected strands, agreement with the 2D growth direction, smoothness, strand
//! count. Figures are printed for the issue note.

use coif::analyze::analyze;
use coif::io::annot::Strokes;
use coif::model::{figures, model_from_analysis, ModelFigures, ModelParams};
use coif::synth::{synth, Style, SynthParams};
use coif::Engine;

fn print(name: &str, f: &ModelFigures, seconds: f64) {
    println!(
        "{name}: {} strands, roots ≤ {:.2e} cells from the scalp, {} in the face, IoU {:.3}, \
         direction {:.2}%, turning p99 {:.1}° ({seconds:.1} s)",
        f.strands,
        f.root_dist_max_cells,
        f.roots_in_face,
        f.coverage_iou,
        100.0 * f.direction_agreement,
        f.turn_p99_deg
    );
}

fn check_common(name: &str, f: &ModelFigures) {
    assert!(f.root_dist_max_cells <= 0.5, "{name}: root off the scalp");
    assert_eq!(f.roots_in_face, 0, "{name}: roots in the face");
    assert!(
        f.turn_p99_deg <= 30.0,
        "{name}: p99 turning {}",
        f.turn_p99_deg
    );
}

#[test]
fn synthetic_portraits_give_rooted_covering_directed_strands() {
    let engine = Engine::cpu();
    let p = ModelParams::default();
    for style in [Style::Long, Style::SidePart, Style::Whorl] {
        for seed in 1..=2 {
            let c = synth(&SynthParams::new(style, seed));
            let t = std::time::Instant::now();
            let mask: Vec<u8> = c.mask.pixels().map(|m| (m.0[0] > 127) as u8).collect();
            let an = analyze(&engine, &c.image, &c.strokes, Some(mask), &p.analyze).unwrap();
            let m = model_from_analysis(&engine, &c.image, an, Some(&c.landmarks), &p).unwrap();
            let f = figures(&m);
            let name = format!("{style} seed {seed}");
            print(&name, &f, t.elapsed().as_secs_f64());
            check_common(&name, &f);
            // The goals: IoU ≥ 0.90, direction agreement ≥ 95% on every case.
            assert!(f.coverage_iou >= 0.90, "{name}: IoU {}", f.coverage_iou);
            assert!(
                f.direction_agreement >= 0.95,
                "{name}: direction {}",
                f.direction_agreement
            );
            if style == Style::Long {
                assert!(
                    (20_000..=40_000).contains(&f.strands),
                    "{name}: {} strands",
                    f.strands
                );
            }
            // Counts and attributes are consistent, all values finite.
            m.strands.validate().unwrap();
        }
    }
}

#[test]
fn astronaut_photo_gives_rooted_smooth_strands() {
    let engine = Engine::cpu();
    let p = ModelParams::default();
    let img = image::load_from_memory(coif::io::assets::ASTRONAUT_PNG)
        .unwrap()
        .to_rgb8();
    let strokes = Strokes::parse(
        coif::io::assets::ASTRONAUT_STROKES,
        std::path::Path::new("astronaut_strokes.json"),
        Some(img.dimensions()),
    )
    .unwrap();
    let t = std::time::Instant::now();
    let an = analyze(&engine, &img, &strokes, None, &p.analyze).unwrap();
    let m = model_from_analysis(&engine, &img, an, None, &p).unwrap();
    let f = figures(&m);
    print("astronaut", &f, t.elapsed().as_secs_f64());
    // On this hair volume (ragged slivers round the ears) the plain W-cycles stalled at 6e-5
    // and, with these six strokes, diverged: the GCR-accelerated solve must reach the
    // tolerance with a residual that never grows.
    let s = &m.solve;
    println!(
        "  field: {} cycles, CG iterations after GCR {:?}, relative residual {:.1e}",
        s.cycles, s.fallback_cg_iterations, s.rel_residual
    );
    assert!(s.converged, "{s:?}");
    for w in s.history.windows(2) {
        assert!(
            w[1].1 <= w[0].1 * (1.0 + 1e-9),
            "residual grew: {:?}",
            s.history
        );
    }
    check_common("astronaut", &f);
    assert!(f.coverage_iou >= 0.90, "IoU {}", f.coverage_iou);
    // The goal.
    assert!(
        f.direction_agreement >= 0.95,
        "direction agreement {}",
        f.direction_agreement
    );
}
