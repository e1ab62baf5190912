//! Orientation stage at 512² and 1024² on the cpu backend and on lavapipe, next to OpenCV's
//! filter2D bank with the very same kernels, measured in the same run by
//! `benches/peers/gabor_opencv.py` (needs `pip install numpy opencv-python-headless`).
//!
//! Run: `cargo bench --bench orient` (COIF_BENCH_REPS sets repetitions, COIF_BENCH_SIZES
//! e.g. "512,1024", COIF_BENCH_GPU=0 skips lavapipe).

use coif::analyze::orient::{orient, GrayImage, OrientParams, SENTINEL};
use coif::gpu::engine::{BackendChoice, Engine, Recording};
use coif::stages::gabor;
use std::process::Command;
use std::time::Instant;

fn median_ms(reps: usize, mut f: impl FnMut()) -> f64 {
    f(); // warm-up: pipeline compilation, FFT plans, page faults
    let mut v: Vec<f64> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// One Gabor bank (responses, argmax, confidence) as a single dispatch.
fn bank_once(engine: &Engine, img: &GrayImage, p: &OrientParams) {
    let k = &p.kernel;
    let (w, h) = (img.width, img.height);
    let mut rec = Recording::default();
    let cfg = p.gabor_config(w, h);
    let u = rec.uniform("cfg", &cfg);
    let wb = rec.upload("w", &k.pair_weights_padded());
    let s = rec.upload("src", &img.data);
    let m = rec.upload("mask", &vec![1u32; (w * h) as usize]);
    let bytes = w as u64 * h as u64 * 4;
    let o: Vec<_> = (0..3).map(|_| rec.alloc("out", bytes, SENTINEL)).collect();
    rec.dispatch(
        &gabor::STAGE,
        gabor::workgroups(&cfg),
        &[u, wb, s, m, s, s, o[0], o[1], o[2]],
        &k.constants(),
    );
    rec.download(o[2]);
    engine.run(rec).expect("bank runs");
}

fn peer(img: &GrayImage, p: &OrientParams, reps: usize) -> serde_json::Value {
    let dir = tempfile::tempdir().expect("temp dir");
    let (w, h) = (img.width as usize, img.height as usize);
    let ip = dir.path().join("image.npy");
    let kp = dir.path().join("kernels.npy");
    coif::io::npy::write_f32(&ip, &[h, w], &img.data).expect("write image");
    let k = &p.kernel;
    let ks = k.ksize as usize;
    let hf = k.half() as i32;
    let mut kern = Vec::with_capacity(k.n_orient as usize * ks * ks);
    for o in 0..k.n_orient {
        for dy in -hf..=hf {
            for dx in -hf..=hf {
                kern.push(k.weight(o, dx, dy));
            }
        }
    }
    coif::io::npy::write_f32(&kp, &[k.n_orient as usize, ks, ks], &kern).expect("write kernels");
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/peers/gabor_opencv.py");
    let out = Command::new("python3")
        .arg(script)
        .arg(&ip)
        .arg(&kp)
        .args([
            p.refine_iters.to_string(),
            p.dog_sigma_fine.to_string(),
            p.dog_sigma_coarse.to_string(),
            p.smooth_sigma.to_string(),
            reps.to_string(),
        ])
        .output()
        .expect("python3 runs");
    if !out.status.success() {
        eprintln!(
            "the OpenCV peer failed (pip install numpy opencv-python-headless):\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        std::process::exit(1);
    }
    serde_json::from_slice(&out.stdout).expect("peer prints JSON")
}

fn main() {
    // `cargo bench` passes --bench; nothing else to parse.
    let reps: usize = std::env::var("COIF_BENCH_REPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let sizes: Vec<u32> = std::env::var("COIF_BENCH_SIZES")
        .unwrap_or_else(|_| "512,1024".into())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let want_gpu = std::env::var("COIF_BENCH_GPU").map_or(true, |v| v != "0");
    let p = OrientParams::default();
    let cpu = Engine::new(BackendChoice::Cpu).unwrap();
    let gpu = if want_gpu {
        match Engine::new(BackendChoice::Gpu) {
            Ok(e) => Some(e),
            Err(e) => {
                eprintln!("no GPU adapter, lavapipe rows skipped: {e}");
                None
            }
        }
    } else {
        None
    };
    println!(
        "orientation stage: 32 orientations, 17x17 kernels, DoG, {} refinement passes, smoothing; median of {reps}",
        p.refine_iters
    );
    println!("cpu backend: {}", cpu.describe());
    if let Some(g) = &gpu {
        println!("gpu backend: {}", g.describe());
    }
    println!(
        "{:<6} {:<10} {:<22} {:>10} {:>12} {:>8}",
        "size", "what", "coif backend", "coif ms", "OpenCV ms", "ratio"
    );
    for &n in &sizes {
        let case = coif::synth::synth(&coif::synth::SynthParams {
            style: coif::synth::Style::Long,
            seed: 1,
            width: n,
            height: n,
        });
        let img = GrayImage::from_rgb(&case.image);
        let pr = peer(&img, &p, reps);
        let ocv_bank = pr["bank_ms"].as_f64().unwrap();
        let ocv_pipe = pr["pipeline_ms"].as_f64().unwrap();
        let mut engines: Vec<(&str, &Engine)> = vec![("cpu", &cpu)];
        if let Some(g) = &gpu {
            engines.push(("gpu (lavapipe)", g));
        }
        for (name, e) in engines {
            // lavapipe at 1024² takes seconds per run; one repetition says enough.
            let r = if e.is_gpu() && n > 512 { 1 } else { reps };
            let bank = median_ms(r, || bank_once(e, &img, &p));
            let pipe = median_ms(r, || {
                orient(e, &img, None, &p).expect("orientation runs");
            });
            for (what, ms, ocv) in [("bank", bank, ocv_bank), ("pipeline", pipe, ocv_pipe)] {
                println!(
                    "{:<6} {:<10} {:<22} {:>10.1} {:>12.1} {:>7.2}x",
                    format!("{n}²"),
                    what,
                    name,
                    ms,
                    ocv,
                    ms / ocv
                );
            }
        }
    }
    println!("ratio = coif time / OpenCV time in this run (below 1: coif is faster)");
}
