//! `coif model` end to end at 512² (the synthetic long-hair case with its mask and landmarks,
//! and the embedded astronaut photo): a per-stage table on the CPU backend and on lavapipe
//! measured in the same run, with the lavapipe / cpu ratio per stage.
//!
//! Run: `CARGO_TARGET_DIR=/work/target cargo bench --bench model`
//! (COIF_BENCH_REPS sets CPU repetitions, default 2; lavapipe runs once: it is slow software.)

use coif::analyze::analyze;
use coif::io::annot::{Landmarks, Strokes};
use coif::model::{model_from_analysis, ModelParams};
use coif::synth::{synth, Style, SynthParams};
use coif::{BackendChoice, Engine};
use std::time::Instant;

struct Case {
    name: &'static str,
    image: image::RgbImage,
    strokes: Strokes,
    mask: Option<Vec<u8>>,
    landmarks: Option<Landmarks>,
}

/// Seconds per stage (analysis stages included) and the wall time, minimum over `reps`
/// runs per stage (the least disturbed run on a shared machine).
fn run(engine: &Engine, c: &Case, reps: usize) -> (Vec<(&'static str, f64)>, f64, usize) {
    let p = ModelParams::default();
    let mut best: Vec<(&'static str, f64)> = Vec::new();
    let mut wall = f64::INFINITY;
    let mut strands = 0;
    for _ in 0..reps {
        let t = Instant::now();
        let an = analyze(engine, &c.image, &c.strokes, c.mask.clone(), &p.analyze).unwrap();
        let m = model_from_analysis(engine, &c.image, an, c.landmarks.as_ref(), &p).unwrap();
        wall = wall.min(t.elapsed().as_secs_f64());
        strands = m.strands.len();
        if best.is_empty() {
            best = m.timings.clone();
        } else {
            for (b, t) in best.iter_mut().zip(&m.timings) {
                b.1 = b.1.min(t.1);
            }
        }
    }
    (best, wall, strands)
}

fn main() {
    let reps: usize = std::env::var("COIF_BENCH_REPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2);
    let s = synth(&SynthParams::new(Style::Long, 1));
    let astro = image::load_from_memory(coif::io::assets::ASTRONAUT_PNG)
        .unwrap()
        .to_rgb8();
    let cases = [
        Case {
            name: "synth long 512²",
            mask: Some(s.mask.pixels().map(|m| (m.0[0] > 127) as u8).collect()),
            landmarks: Some(s.landmarks.clone()),
            strokes: s.strokes.clone(),
            image: s.image.clone(),
        },
        Case {
            name: "astronaut 512²",
            image: astro,
            strokes: Strokes::parse(
                coif::io::assets::ASTRONAUT_STROKES,
                std::path::Path::new("assets/astronaut_strokes.json"),
                Some((512, 512)),
            )
            .unwrap(),
            mask: None,
            landmarks: None,
        },
    ];
    let gpu = Engine::new(BackendChoice::Gpu);
    if let Err(e) = &gpu {
        println!("no GPU backend ({e}); CPU only");
    }
    for c in &cases {
        let (cpu, cpu_wall, n) = run(&Engine::cpu(), c, reps);
        let g = gpu.as_ref().ok().map(|g| (g.describe(), run(g, c, 1)));
        println!(
            "\ncoif model, {} ({n} strands), default parameters:",
            c.name
        );
        match &g {
            Some((name, _)) => println!(
                "  {:<18} {:>10} {:>12} {:>8}",
                "stage",
                "cpu s",
                name_short(name),
                "ratio"
            ),
            None => println!("  {:<18} {:>10}", "stage", "cpu s"),
        }
        for (i, (stage, t)) in cpu.iter().enumerate() {
            match &g {
                Some((_, (gt, _, _))) => {
                    let tg = gt[i].1;
                    println!(
                        "  {stage:<18} {t:>10.3} {tg:>12.3} {:>7.1}x",
                        tg / t.max(1e-9)
                    );
                }
                None => println!("  {stage:<18} {t:>10.3}"),
            }
        }
        match &g {
            Some((_, (_, gw, _))) => println!(
                "  {:<18} {cpu_wall:>10.3} {gw:>12.3} {:>7.1}x   (lavapipe / cpu)",
                "total (wall)",
                gw / cpu_wall
            ),
            None => println!("  {:<18} {cpu_wall:>10.3}", "total (wall)"),
        }
    }
}

fn name_short(desc: &str) -> String {
    desc.split_whitespace()
        .take(2)
        .collect::<Vec<_>>()
        .join(" ")
}
