//! The sketch's growth directions (CZ06 §4.2, Step 2) against the direction prior's weight
//! κ: the five synthetic styles (the four of issue 16 and the fringe) × seeds 1-6 at 512²,
//! each sketched once with the defaults; then Step 2 again on its undirected curves for each
//! prior, by Swendsen-Wang cuts and by the prior alone, the labels filled in from the sketch
//! and scored as the share of hair pixels whose direction points the true way. Also checks,
//! per case and prior, that the sampler's energy is at most ICM's and the prior-only
//! labels'. An accuracy sweep, not a timing: too heavy for the test suite (30 pursuits and
//! 420 direction runs, about ten minutes on 2 cores), and the figures behind the README's
//! Step 2 paragraph under `coif sketch`, where the default κ was chosen.
//!
//! Run: `cargo bench --bench sketch_directions` (COIF_BENCH_SEEDS=1,2 narrows the seeds).

use coif::eval::metrics::direction_agreement;
use coif::gpu::engine::Engine;
use coif::sketch::run::{analyse, SketchInputs, SketchParams, SketchResult};
use coif::sketch::swc::{self, Crown, DirPrior, Method, SwcParams};
use coif::sketch::{fill, format, prim, Curve, Sketch};
use coif::synth::{synth, Style, SynthParams};

const SIZE: u32 = 512;

/// (label, crown, κ): the default until 2026-12-06 first, then the scan.
const PRIORS: [(&str, Crown, f32); 7] = [
    ("parting κ1", Crown::Parting, 1.0),
    ("κ1", Crown::Centroid, 1.0),
    ("κ0.4", Crown::Centroid, 0.4),
    ("κ0.3", Crown::Centroid, 0.3),
    ("κ0.2", Crown::Centroid, 0.2),
    ("κ0.1", Crown::Centroid, 0.1),
    ("κ0.03", Crown::Centroid, 0.03),
];

/// Hair pixels whose filled-in growth direction agrees with the truth, %.
fn agreement(
    e: &Engine,
    r: &SketchResult,
    curves: Vec<Curve>,
    hair: &[bool],
    truth: &[f32],
) -> f64 {
    let s = format::quantise(&Sketch {
        curves,
        ..r.sketch.clone()
    });
    let painted = prim::paint(&s.curves, s.width, s.height, Some(hair));
    let f = fill::fill(
        e,
        &painted,
        hair,
        &s.rho_off,
        s.seed,
        &SketchParams::default().fill,
    )
    .expect("fill");
    let dir: Vec<f32> = f.dir.iter().flatten().copied().collect();
    100.0 * direction_agreement(&dir, truth, hair).0
}

fn main() {
    let seeds: Vec<u64> = std::env::var("COIF_BENCH_SEEDS")
        .map(|s| s.split(',').map(|x| x.trim().parse().unwrap()).collect())
        .unwrap_or_else(|_| (1..=6).collect());
    let engine = Engine::cpu();
    let styles: Vec<Style> = Style::ALL.iter().chain(&Style::EXTRA).copied().collect();
    print!("{:<9} {:>4}", "style", "seed");
    for (name, _, _) in PRIORS {
        print!(" {:>15}", format!("{name} SW/pri"));
    }
    println!();
    let mut sums = [0.0f64; PRIORS.len()];
    let mut worst = [f64::INFINITY; PRIORS.len()];
    let mut energy_breaches = 0;
    let mut n_cases = 0;
    for &style in &styles {
        for &seed in &seeds {
            let c = synth(&SynthParams::square(style, seed, SIZE));
            let hair: Vec<bool> = c.mask.pixels().map(|p| p[0] > 127).collect();
            let inp = SketchInputs {
                image: &c.image,
                hair: &hair,
                strokes: None,
            };
            let r = analyse(&engine, &inp, &SketchParams::default()).expect("sketch");
            print!("{:<9} {:>4}", style.name(), seed);
            for (k, &(_, crown, kappa)) in PRIORS.iter().enumerate() {
                let p = SwcParams {
                    prior: DirPrior {
                        crown,
                        kappa,
                        ..DirPrior::default()
                    },
                    ..SwcParams::default()
                };
                let run = |m| {
                    swc::directions(&r.undirected, &r.theta, &hair, SIZE, SIZE, &[], &p, m)
                        .expect("directions")
                };
                let (sw, icm, pri) = (run(Method::Swc), run(Method::Icm), run(Method::Prior));
                let flag = if sw.energy <= icm.energy + 1e-6 && sw.energy <= pri.energy + 1e-6 {
                    " "
                } else {
                    energy_breaches += 1;
                    "!"
                };
                let a_sw = agreement(&engine, &r, sw.curves, &hair, &c.gt_dir);
                let a_pri = agreement(&engine, &r, pri.curves, &hair, &c.gt_dir);
                sums[k] += a_sw;
                worst[k] = worst[k].min(a_sw);
                print!(" {:>14}{flag}", format!("{a_sw:.1}/{a_pri:.1}"));
            }
            println!();
            n_cases += 1;
        }
    }
    for (k, (name, _, _)) in PRIORS.iter().enumerate() {
        println!(
            "{name}: SW mean {:.2}%, worst {:.2}% over {n_cases} cases",
            sums[k] / n_cases as f64,
            worst[k]
        );
    }
    println!(
        "SW's energy above ICM's or the prior-only labels' (marked !): {energy_breaches} of {}",
        n_cases * PRIORS.len()
    );
}
