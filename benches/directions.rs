//! Directed hair (C13 §2.1) over a sweep of synthetic portraits: the four styles × three
//! textures (plain, curly, photo) × seeds 1-3 at 512², the synthesised strokes and the true
//! mask; the share of hair pixels ≥ 5 px inside the mask whose growth direction points the
//! true way, with the parting step off (`--parting=0`), without the weaker cuts in line
//! with a strong one (`--parting-line=0`: partings from the strong cuts alone) and as it is
//! by default. An accuracy sweep, not a timing: too heavy for the test suite (108
//! analyses, a few minutes on 2 cores), and the figures behind the
//! README's "Accuracy and speed" paragraph on side parts.
//!
//! Run: `cargo bench --bench directions` (COIF_BENCH_SEEDS=1,2 narrows the seeds).

use coif::analyze::parting::PartingParams;
use coif::analyze::{analyze, AnalyzeParams};
use coif::eval::metrics::{direction_agreement, erode};
use coif::gpu::engine::Engine;
use coif::synth::{synth_textured, Style, SynthParams, Texture};

const SIZE: u32 = 512;
const TEXTURES: [&str; 3] = ["plain", "curly", "photo"];

fn main() {
    let seeds: Vec<u64> = std::env::var("COIF_BENCH_SEEDS")
        .map(|s| s.split(',').map(|x| x.trim().parse().unwrap()).collect())
        .unwrap_or_else(|_| vec![1, 2, 3]);
    let engine = Engine::cpu();
    let default = AnalyzeParams::default();
    let configs: [(&str, AnalyzeParams); 3] = [
        (
            "no parting step",
            AnalyzeParams {
                parting: PartingParams {
                    threshold: 0.0,
                    ..default.parting.clone()
                },
                ..default.clone()
            },
        ),
        (
            "no line cuts",
            AnalyzeParams {
                parting: PartingParams {
                    line_threshold: 0.0,
                    ..default.parting.clone()
                },
                ..default.clone()
            },
        ),
        ("default", default.clone()),
    ];
    println!(
        "{:<9} {:<6} {:>4} {:>16} {:>16} {:>9} {:>6} {:>8}",
        "style", "texture", "seed", configs[0].0, configs[1].0, configs[2].0, "cuts", "partings"
    );
    let mut sums = [0.0f64; 3];
    let mut worst = [f64::INFINITY; 3];
    let mut n_cases = 0;
    for style in Style::ALL {
        for texture in TEXTURES {
            for &seed in &seeds {
                let t: Texture = texture.parse().unwrap();
                let c = synth_textured(&SynthParams::square(style, seed, SIZE), &t);
                let mask: Vec<u8> = c.mask.pixels().map(|m| (m[0] > 127) as u8).collect();
                let inner = erode(&c.mask, 5);
                let mut row = [0.0f64; 3];
                let (mut cuts, mut lines) = (0, 0);
                for (k, (_, p)) in configs.iter().enumerate() {
                    let an = analyze(&engine, &c.image, &c.strokes, Some(mask.clone()), p)
                        .expect("analysis of a synthetic case");
                    row[k] = 100.0 * direction_agreement(&an.direction, &c.gt_dir, &inner).0;
                    sums[k] += row[k];
                    worst[k] = worst[k].min(row[k]);
                    (cuts, lines) = (an.parting_cuts.len(), an.parting_lines.len());
                }
                n_cases += 1;
                println!(
                    "{:<9} {:<6} {:>4} {:>15.2}% {:>15.2}% {:>8.2}% {:>6} {:>8}",
                    style.name(),
                    texture,
                    seed,
                    row[0],
                    row[1],
                    row[2],
                    cuts,
                    lines
                );
            }
        }
    }
    for (k, (name, _)) in configs.iter().enumerate() {
        println!(
            "{name}: mean {:.2}%, worst {:.2}% over {n_cases} cases",
            sums[k] / n_cases as f64,
            worst[k]
        );
    }
}
