//! Dense orientation-field flow (`coif::video::flow::flow`) at 256² and 512² on the cpu
//! backend and on lavapipe: milliseconds per frame pair, default `FlowParams`. The frames are
//! a synthetic portrait and the same portrait shifted by (2.5, 1) px, both through
//! `orient()` (not timed). The OpenCV peers (DIS, Farneback) are added by
//! `benches/peers/flow_opencv.py`.
//!
//! Run: `cargo bench --bench flow` (COIF_BENCH_REPS sets repetitions, COIF_BENCH_SIZES e.g.
//! "256,512", COIF_BENCH_GPU=0 skips lavapipe).

use coif::analyze::orient::{orient, GrayImage, OrientParams};
use coif::gpu::engine::{BackendChoice, Engine};
use coif::synth::{synth, Style, SynthParams};
use coif::video::flow::{flow, orient_features, FlowParams};
use std::time::Instant;

fn median_ms(reps: usize, mut f: impl FnMut()) -> f64 {
    f(); // warm-up: pipeline compilation, page faults
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

/// Bilinear shift of `img` by (dx, dy): b(q + d) = a(q).
fn shifted(img: &GrayImage, dx: f32, dy: f32) -> GrayImage {
    let (w, h) = (img.width as i32, img.height as i32);
    let at = |x: i32, y: i32| img.data[(y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize];
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 - dx, (i / w) as f32 - dy);
            let (x0, y0) = (x.floor() as i32, y.floor() as i32);
            let (fx, fy) = (x - x0 as f32, y - y0 as f32);
            let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
            let bot = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
            top * (1.0 - fy) + bot * fy
        })
        .collect();
    GrayImage {
        width: img.width,
        height: img.height,
        data,
    }
}

fn main() {
    let reps: usize = std::env::var("COIF_BENCH_REPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    let sizes: Vec<u32> = std::env::var("COIF_BENCH_SIZES")
        .unwrap_or_else(|_| "256,512".into())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let mut engines = vec![("cpu", Engine::cpu())];
    if std::env::var("COIF_BENCH_GPU").as_deref() != Ok("0") {
        match Engine::new(BackendChoice::Gpu) {
            Ok(e) => engines.push(("lavapipe", e)),
            Err(e) => println!("no GPU adapter, lavapipe skipped: {e}"),
        }
    }
    let p = FlowParams::default();
    println!("flow, default FlowParams {p:?}, median of {reps}");
    for &size in &sizes {
        let case = synth(&SynthParams {
            style: Style::Long,
            seed: 1,
            width: size,
            height: size,
        });
        let a = GrayImage::from_rgb(&case.image);
        let b = shifted(&a, 2.5, 1.0);
        let cpu = Engine::cpu();
        let op = OrientParams::default();
        let fa = orient_features(&orient(&cpu, &a, None, &op).expect("orient a"));
        let fb = orient_features(&orient(&cpu, &b, None, &op).expect("orient b"));
        let levels = p.pyramid(size, size).len();
        for (name, e) in &engines {
            let ms = median_ms(reps, || {
                flow(e, &fa, &fb, size, size, &p).expect("flow runs");
            });
            println!("{size}² ({levels} levels) {name}: {ms:.1} ms per frame pair");
        }
    }
}
