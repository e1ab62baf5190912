//! `coif sketch` (CZ06 §4, issue 16) and `coif synth-hair` (§3, issue 17) at 512²: seconds
//! per stage on the cpu backend (and on lavapipe with COIF_BENCH_GPU=1), the sketch's bytes, and the orientation error against
//! the ground truth of synthetic portraits of three fields: the one filled in from the
//! sketch alone (a few hundred bytes), Step 1's dense Θ, and the peer, a dense
//! structure-tensor field in OpenCV (`benches/peers/tensor_opencv.py`, run in the same
//! bench; needs `pip install numpy opencv-python-headless`), with the time ratio to it.
//!
//! Run: `cargo bench --bench sketch`. COIF_BENCH_SIZE (512), COIF_BENCH_SEED (1), COIF_BENCH_STYLES
//! ("long,sidepart,whorl,short,fringe"), COIF_BENCH_GPU=1 adds lavapipe, COIF_BENCH_SAMPLES=0
//! skips the real photographs.

use coif::eval::metrics::erode;
use coif::gpu::engine::{BackendChoice, Engine};
use coif::sketch::format;
use coif::sketch::run::{analyse, SketchInputs, SketchParams};
use coif::sketch::samples::{self, Sample};
use coif::sketch::synth::synthesise;
use coif::synth::{synth, Style, SynthParams};
use std::process::Command;
use std::time::Instant;

fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(d)
}

fn mean_err(theta: &[f32], truth: &[f32], keep: &[bool]) -> f64 {
    coif::eval::metrics::mean_orient_error_deg(theta, truth, keep).0
}

/// The peer's field and its median milliseconds, or None when OpenCV is missing.
fn peer(gray: &[f32], w: u32, h: u32) -> Option<(Vec<f32>, f64)> {
    let dir = tempfile::tempdir().ok()?;
    let inp = dir.path().join("gray.npy");
    let out = dir.path().join("theta.npy");
    coif::io::npy::write_f32(&inp, &[h as usize, w as usize], gray).ok()?;
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/benches/peers/tensor_opencv.py"
    );
    let o = Command::new("python3")
        .arg(script)
        .arg(&inp)
        .arg(&out)
        .arg("2.0")
        .arg("5")
        .output()
        .ok()?;
    if !o.status.success() {
        eprintln!("OpenCV peer failed: {}", String::from_utf8_lossy(&o.stderr));
        return None;
    }
    let v: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&o.stdout).lines().last()?).ok()?;
    let (_, theta) = coif::io::npy::read_f32(&out).ok()?;
    Some((theta, v["median_ms"].as_f64()?))
}

fn main() {
    let size: u32 = env("COIF_BENCH_SIZE", 512);
    let seed: u64 = env("COIF_BENCH_SEED", 1);
    let gpu = env("COIF_BENCH_GPU", 0) != 0;
    let styles: String = env(
        "COIF_BENCH_STYLES",
        "long,sidepart,whorl,short,fringe".to_string(),
    );
    let mut engines = vec![("cpu", Engine::cpu())];
    if gpu {
        match Engine::new(BackendChoice::Gpu) {
            Ok(e) => engines.push(("lavapipe", e)),
            Err(e) => eprintln!("no GPU engine: {e}"),
        }
    }
    println!(
        "coif sketch at {size}², fields against the ground truth (mean °, ≥ 5 px inside the mask)"
    );
    println!(
        "{:<9} {:<8} {:>7} {:>6} {:>6} {:>9} {:>9} {:>9} {:>9} {:>8}",
        "case",
        "backend",
        "seconds",
        "curves",
        "czs B",
        "fill err",
        "Θ err",
        "peer err",
        "peer ms",
        "ratio"
    );
    for name in styles.split(',').filter(|s| !s.is_empty()) {
        let style: Style = name.parse().expect("style");
        let c = synth(&SynthParams {
            style,
            seed,
            width: size,
            height: size,
        });
        let hair: Vec<bool> = c.mask.pixels().map(|p| p[0] > 127).collect();
        let inner = erode(&c.mask, 5);
        let gray = coif::analyze::orient::GrayImage::from_rgb(&c.image);
        let pe = peer(&gray.data, size, size);
        for (bname, engine) in &engines {
            let t = Instant::now();
            let inp = SketchInputs {
                image: &c.image,
                hair: &hair,
                strokes: None,
            };
            let r = analyse(engine, &inp, &SketchParams::default()).expect("sketch");
            let secs = t.elapsed().as_secs_f64();
            let sizes = format::czs_sizes(&r.sketch);
            let (perr, pms) = match &pe {
                Some((th, ms)) => (mean_err(th, &c.gt_theta, &inner), *ms),
                None => (f64::NAN, f64::NAN),
            };
            println!(
                "{:<9} {:<8} {:>7.2} {:>6} {:>6} {:>8.2}° {:>8.2}° {:>8.2}° {:>9.1} {:>8.0}",
                name,
                bname,
                secs,
                r.sketch.curves.len(),
                sizes.total,
                mean_err(&r.field.theta, &c.gt_theta, &inner),
                mean_err(&r.theta, &c.gt_theta, &inner),
                perr,
                pms,
                secs * 1e3 / pms
            );
            let stages: Vec<String> = r
                .seconds
                .iter()
                .map(|(k, s)| format!("{k} {s:.2}"))
                .collect();
            println!("          stages (s): {}", stages.join(", "));
            // And back: the image synthesised from the stored sketch alone (issue 17).
            let stored = format::from_czs(&format::to_czs(&r.sketch), "mem.czs".as_ref())
                .expect("czs round trip");
            let t = Instant::now();
            let syn = synthesise(engine, &stored, None, &Default::default()).expect("synth-hair");
            let stages: Vec<String> = syn
                .seconds
                .iter()
                .map(|(k, s)| format!("{k} {s:.2}"))
                .collect();
            println!(
                "          synth-hair {:.2} s ({})",
                t.elapsed().as_secs_f64(),
                stages.join(", ")
            );
        }
    }
    if env("COIF_BENCH_SAMPLES", 1) == 0 {
        return;
    }
    println!("real photographs (no ground truth): seconds, curves, bytes");
    for s in Sample::ALL {
        let img = samples::load(s).expect("sample");
        for (bname, engine) in &engines {
            let t = Instant::now();
            let inp = SketchInputs {
                image: &img.image,
                hair: &img.hair,
                strokes: None,
            };
            let r = analyse(engine, &inp, &SketchParams::default()).expect("sketch");
            println!(
                "{:<10} {}x{} {:<8} {:>7.2} s {:>4} curves {:>5} B",
                img.name,
                img.image.width(),
                img.image.height(),
                bname,
                t.elapsed().as_secs_f64(),
                r.sketch.curves.len(),
                format::czs_sizes(&r.sketch).total
            );
        }
    }
}
