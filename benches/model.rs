//! `coif model` end to end at 512² (the synthetic long-hair case with its mask and landmarks,
//! and the embedded astronaut photo): a per-stage table on the CPU backend and on lavapipe
//! measured in the same run, with the lavapipe / cpu ratio per stage, and the peak memory of
//! each. Then the growth rows: the synthetic long case at 1024² and with twice the roots
//! (twice the strands) on the CPU backend, against its 512² row of the same run.
//!
//! Peak memory is the process's resident-set high-water mark (`VmHWM` of
//! `/proc/self/status`), reset to the current RSS before each measured run by writing `5` to
//! `/proc/self/clear_refs`: the figure is the RSS the process held at its peak during that
//! run, including what it held before the run (printed as "RSS before"; the inputs, the
//! GPU context). Where the reset is refused, the figure is the process's peak so far (said).
//!
//! Run: `cargo bench --bench model`
//! (COIF_BENCH_REPS sets CPU repetitions, default 2; lavapipe runs once: it is slow
//! software. COIF_BENCH_GROWTH=0 skips the growth rows, COIF_BENCH_GPU=0 lavapipe.)

use coif::analyze::analyze;
use coif::io::annot::{Landmarks, Strokes};
use coif::model::{model_from_analysis, ModelParams};
use coif::synth::{synth, Style, SynthParams};
use coif::timings::{peak_rss_bytes, reset_peak_rss};
use coif::{BackendChoice, Engine};
use std::time::Instant;

struct Case {
    name: String,
    image: image::RgbImage,
    strokes: Strokes,
    mask: Option<Vec<u8>>,
    landmarks: Option<Landmarks>,
}

/// What one case measured on one backend.
struct Measured {
    /// Seconds per stage (analysis stages included), minimum over the repetitions.
    stages: Vec<(&'static str, f64)>,
    /// Wall time, minimum over the repetitions.
    wall: f64,
    strands: usize,
    vertices: usize,
    /// RSS high-water mark over the repetitions (bytes), and the RSS before them.
    peak: Option<u64>,
    before: Option<u64>,
}

/// Seconds per stage (analysis stages included) and the wall time, minimum over `reps`
/// runs per stage (the least disturbed run on a shared machine), and the peak memory.
fn run(engine: &Engine, c: &Case, reps: usize, p: &ModelParams) -> Measured {
    let mut best: Vec<(&'static str, f64)> = Vec::new();
    let mut wall = f64::INFINITY;
    let (mut strands, mut vertices) = (0, 0);
    let before = rss_bytes();
    reset_peak_rss();
    for _ in 0..reps {
        let t = Instant::now();
        let an = analyze(engine, &c.image, &c.strokes, c.mask.clone(), &p.analyze).unwrap();
        let m = model_from_analysis(engine, &c.image, an, c.landmarks.as_ref(), p).unwrap();
        wall = wall.min(t.elapsed().as_secs_f64());
        strands = m.strands.len();
        vertices = m.strands.points.len();
        if best.is_empty() {
            best = m.timings.clone();
        } else {
            for (b, t) in best.iter_mut().zip(&m.timings) {
                b.1 = b.1.min(t.1);
            }
        }
    }
    Measured {
        stages: best,
        wall,
        strands,
        vertices,
        peak: peak_rss_bytes(),
        before,
    }
}

/// The current resident set (bytes), from `VmRSS`.
fn rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let kb = s.lines().find_map(|l| l.strip_prefix("VmRSS:"))?;
    kb.trim()
        .trim_end_matches("kB")
        .trim()
        .parse::<u64>()
        .ok()
        .map(|k| k * 1024)
}

fn mib(b: Option<u64>) -> String {
    b.map_or("n/a".into(), |b| {
        format!("{:.0}", b as f64 / (1 << 20) as f64)
    })
}

fn synth_case(size: u32) -> Case {
    let s = synth(&SynthParams {
        width: size,
        height: size,
        ..SynthParams::new(Style::Long, 1)
    });
    Case {
        name: format!("synth long {size}²"),
        mask: Some(s.mask.pixels().map(|m| (m.0[0] > 127) as u8).collect()),
        landmarks: Some(s.landmarks.clone()),
        strokes: s.strokes.clone(),
        image: s.image.clone(),
    }
}

fn main() {
    let reps: usize = std::env::var("COIF_BENCH_REPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2);
    let growth = std::env::var("COIF_BENCH_GROWTH").map_or(true, |v| v != "0");
    if !reset_peak_rss() {
        println!("(/proc/self/clear_refs refused: peak memory is the process's peak so far)");
    }
    let astro = image::load_from_memory(coif::io::assets::ASTRONAUT_PNG)
        .unwrap()
        .to_rgb8();
    let cases = [
        synth_case(512),
        Case {
            name: "astronaut 512²".into(),
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
    let p = ModelParams::default();
    // CPU runs first (both cases, then the growth rows), lavapipe last: what the driver
    // keeps resident after a run would otherwise sit under every later CPU figure.
    let cpu: Vec<Measured> = cases
        .iter()
        .map(|c| run(&Engine::cpu(), c, reps, &p))
        .collect();
    let growth_rows = growth.then(|| {
        // The synthetic case at twice the side (4x the pixels) and with twice the roots,
        // on the CPU backend only (lavapipe skipped: one such run takes about a minute).
        let big = synth_case(1024);
        let p2 = ModelParams {
            roots: 2 * p.roots,
            ..ModelParams::default()
        };
        [
            ("1024² (4x pixels)", run(&Engine::cpu(), &big, reps, &p)),
            ("512², 2x roots", run(&Engine::cpu(), &cases[0], reps, &p2)),
        ]
    });
    // COIF_BENCH_GPU=0: the cpu backend alone (profiling).
    let gpu = if std::env::var("COIF_BENCH_GPU").is_ok_and(|v| v == "0") {
        Err(coif::Error::Invalid("COIF_BENCH_GPU=0".into()))
    } else {
        Engine::new(BackendChoice::Gpu)
    };
    if let Err(e) = &gpu {
        println!("no GPU backend ({e}); CPU only");
    }
    for (c, cpu) in cases.iter().zip(&cpu) {
        let g = gpu.as_ref().ok().map(|g| (g.describe(), run(g, c, 1, &p)));
        println!(
            "\ncoif model, {} ({} strands, {} vertices), default parameters:",
            c.name, cpu.strands, cpu.vertices
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
        for (i, (stage, t)) in cpu.stages.iter().enumerate() {
            match &g {
                Some((_, gm)) => {
                    let tg = gm.stages[i].1;
                    println!(
                        "  {stage:<18} {t:>10.3} {tg:>12.3} {:>7.1}x",
                        tg / t.max(1e-9)
                    );
                }
                None => println!("  {stage:<18} {t:>10.3}"),
            }
        }
        match &g {
            Some((_, gm)) => {
                println!(
                    "  {:<18} {:>10.3} {:>12.3} {:>7.1}x   (lavapipe / cpu)",
                    "total (wall)",
                    cpu.wall,
                    gm.wall,
                    gm.wall / cpu.wall
                );
                println!(
                    "  {:<18} {:>10} {:>12}            (MiB, process RSS high-water mark)",
                    "peak RSS",
                    mib(cpu.peak),
                    mib(gm.peak)
                );
                println!(
                    "  {:<18} {:>10} {:>12}",
                    "RSS before",
                    mib(cpu.before),
                    mib(gm.before)
                );
            }
            None => {
                println!("  {:<18} {:>10.3}", "total (wall)", cpu.wall);
                println!(
                    "  {:<18} {:>10}   (MiB, process RSS high-water mark; before: {})",
                    "peak RSS",
                    mib(cpu.peak),
                    mib(cpu.before)
                );
            }
        }
    }
    let Some(rows) = growth_rows else {
        return;
    };
    let base = &cpu[0];
    println!(
        "\ngrowth, synth long on the cpu backend (lavapipe skipped: too slow for a default run);\n\
         ratios against the 512² row above (1x roots: {} strands, {} vertices):",
        base.strands, base.vertices
    );
    println!(
        "  {:<18} {:>8} {:>9} {:>9} {:>7} {:>9} {:>7}",
        "case", "strands", "vertices", "wall s", "ratio", "peak MiB", "ratio"
    );
    let peak_ratio = |m: &Measured| match (m.peak, base.peak) {
        (Some(a), Some(b)) => format!("{:.2}x", a as f64 / b as f64),
        _ => "n/a".into(),
    };
    println!(
        "  {:<18} {:>8} {:>9} {:>9.3} {:>7} {:>9} {:>7}",
        "512², 1x roots",
        base.strands,
        base.vertices,
        base.wall,
        "1.00x",
        mib(base.peak),
        "1.00x"
    );
    for (name, m) in &rows {
        println!(
            "  {:<18} {:>8} {:>9} {:>9.3} {:>6.2}x {:>9} {:>7}",
            name,
            m.strands,
            m.vertices,
            m.wall,
            m.wall / base.wall,
            mib(m.peak),
            peak_ratio(m)
        );
    }
    println!("  per stage, s (512² 1x | 1024² | 512² 2x roots):");
    for (i, (stage, t)) in base.stages.iter().enumerate() {
        let a = rows[0].1.stages[i].1;
        let b = rows[1].1.stages[i].1;
        println!(
            "  {stage:<18} {t:>8.3} {a:>8.3} ({:>4.2}x) {b:>8.3} ({:>4.2}x)",
            a / t.max(1e-9),
            b / t.max(1e-9)
        );
    }
}

fn name_short(desc: &str) -> String {
    desc.split_whitespace()
        .take(2)
        .collect::<Vec<_>>()
        .join(" ")
}
