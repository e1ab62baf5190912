//! Accuracy of the dense orientation-field flow (`coif::video::flow::flow`) on a synthetic
//! clip with exact ground truth (`coif synth-video`): for every frame pair (i-1, i) of
//! CLIP_DIR/frames, the flow from the orientation features of the whole frames
//! (`feature_orient_params`, `orient_features`), and its mean
//! end-point error on the pixels where CLIP_DIR/flow/NNNN.npy is finite (frame i-1's hair).
//! The OpenCV peers on the same clip: `benches/peers/flow_opencv.py CLIP_DIR`.
//!
//! Run: `cargo bench --bench flow_epe -- CLIP_DIR [CLIP_DIR ...]`. Environment:
//! COIF_EPE_STEP=k measures every k-th pair only; COIF_EPE_CACHE=DIR keeps each frame's
//! orientation (theta, confidence) there between runs; COIF_EPE_WRITE=DIR saves each flow
//! as DIR/<clip>/NNNN.npy; COIF_FLOW_{LEVELS,MIN_SIZE,WARPS,ITERS,ALPHA,EPS_DATA,EPS_SMOOTH,
//! OMEGA} override the `FlowParams` defaults.

use coif::analyze::orient::{orient, GrayImage, OrientMap, OrientParams};
use coif::gpu::engine::Engine;
use coif::io::npy::{read_f32, write_f32};
use coif::video::flow::{feature_orient_params, flow, orient_features, FlowFeatures, FlowParams};
use std::path::{Path, PathBuf};

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

fn params() -> FlowParams {
    let mut p = FlowParams::default();
    macro_rules! over {
        ($f:ident, $n:literal) => {
            if let Some(v) = env(concat!("COIF_FLOW_", $n)) {
                p.$f = v;
            }
        };
    }
    over!(levels, "LEVELS");
    over!(min_size, "MIN_SIZE");
    over!(warps, "WARPS");
    over!(iters, "ITERS");
    over!(alpha, "ALPHA");
    over!(eps_data, "EPS_DATA");
    over!(eps_smooth, "EPS_SMOOTH");
    over!(omega, "OMEGA");
    over!(fine_warps, "FINE_WARPS");
    p
}

/// Orientation of one frame, from the cache when there is one.
fn orientation(e: &Engine, png: &Path, cache: Option<&Path>, op: &OrientParams) -> OrientMap {
    let cached = cache.map(|d| d.join(png.file_name().unwrap()).with_extension("npy"));
    if let Some(c) = &cached {
        if let Ok((shape, v)) = read_f32(c) {
            let n = shape[0] * shape[1];
            return OrientMap {
                width: shape[1] as u32,
                height: (shape[0] / 2) as u32,
                theta: v[..n / 2].to_vec(),
                confidence: v[n / 2..].to_vec(),
                whorls: Vec::new(),
            };
        }
    }
    let img = image::open(png).expect("frame").to_rgb8();
    let o = orient(e, &GrayImage::from_rgb(&img), None, op).unwrap();
    if let Some(c) = &cached {
        std::fs::create_dir_all(c.parent().unwrap()).unwrap();
        let mut v = o.theta.clone();
        v.extend_from_slice(&o.confidence);
        write_f32(c, &[2 * o.height as usize, o.width as usize], &v).unwrap();
    }
    o
}

/// Experimental: w (cos 2θ, sin 2θ) with w = (c / median c)^k, not clamped.
fn pow_features(o: &OrientMap, k: f32, sat: bool) -> Vec<[f32; 2]> {
    let mut c: Vec<f32> = o
        .confidence
        .iter()
        .zip(&o.theta)
        .filter(|(c, t)| t.is_finite() && **c > 0.0)
        .map(|(c, _)| *c)
        .collect();
    let m = c.len() / 2;
    let (_, &mut med, _) = c.select_nth_unstable_by(m, |a, b| a.total_cmp(b));
    o.theta
        .iter()
        .zip(&o.confidence)
        .map(|(&t, &c)| {
            if t.is_finite() && c > 0.0 {
                let w = if sat {
                    c / (c + k * med)
                } else {
                    (c / med).powf(k)
                };
                [w * (2.0 * t).cos(), w * (2.0 * t).sin()]
            } else {
                [0.0; 2]
            }
        })
        .collect()
}

fn main() {
    let clips: Vec<PathBuf> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .map(PathBuf::from)
        .collect();
    if clips.is_empty() {
        eprintln!("usage: cargo bench --bench flow_epe -- CLIP_DIR [CLIP_DIR ...]");
        std::process::exit(2);
    }
    let step: usize = env("COIF_EPE_STEP").unwrap_or(1);
    let cache: Option<PathBuf> = env("COIF_EPE_CACHE");
    let write: Option<PathBuf> = env("COIF_EPE_WRITE");
    let p = params();
    let mut op = feature_orient_params();
    if let Some(v) = env("COIF_ORIENT_SMOOTH") {
        op.smooth_sigma = v;
    }
    if let Some(v) = env("COIF_ORIENT_REFINE") {
        op.refine_iters = v;
    }
    let pow: Option<f32> = env("COIF_EPE_POW");
    let sat: Option<f32> = env("COIF_EPE_SAT");
    let feats = |o: &OrientMap| match (pow, sat) {
        (Some(k), _) => FlowFeatures::same(pow_features(o, k, false)),
        (_, Some(k)) => FlowFeatures::same(pow_features(o, k, true)),
        _ => orient_features(o),
    };
    println!("{p:?}");
    let e = Engine::cpu();
    for clip in &clips {
        let name = clip.file_name().unwrap().to_string_lossy().to_string();
        let mut frames: Vec<PathBuf> = std::fs::read_dir(clip.join("frames"))
            .expect("CLIP_DIR/frames")
            .map(|d| d.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "png"))
            .collect();
        frames.sort();
        let cdir = cache
            .as_ref()
            .map(|c| c.join(format!("{name}-s{}-r{}", op.smooth_sigma, op.refine_iters)));
        let (mut sum, mut sum0, mut pairs) = (0.0, 0.0, 0);
        let t = std::time::Instant::now();
        for i in (1..frames.len()).step_by(step) {
            let oa = orientation(&e, &frames[i - 1], cdir.as_deref(), &op);
            let ob = orientation(&e, &frames[i], cdir.as_deref(), &op);
            let (w, h) = (oa.width, oa.height);
            let got = flow(&e, &feats(&oa), &feats(&ob), w, h, &p).unwrap();
            let stem = frames[i].file_stem().unwrap().to_string_lossy().to_string();
            let (_, truth) = read_f32(&clip.join("flow").join(format!("{stem}.npy"))).unwrap();
            let (mut s, mut s0, mut n) = (0.0f64, 0.0f64, 0usize);
            for (k, g) in got.iter().enumerate() {
                let tr = [truth[2 * k], truth[2 * k + 1]];
                if tr[0].is_finite() && tr[1].is_finite() {
                    s += ((g[0] - tr[0]).hypot(g[1] - tr[1])) as f64;
                    s0 += tr[0].hypot(tr[1]) as f64;
                    n += 1;
                }
            }
            if let Some(wd) = &write {
                let flat: Vec<f32> = got.iter().flatten().copied().collect();
                let d = wd.join(&name);
                std::fs::create_dir_all(&d).unwrap();
                write_f32(
                    &d.join(format!("{stem}.npy")),
                    &[h as usize, w as usize, 2],
                    &flat,
                )
                .unwrap();
            }
            let n = n.max(1) as f64;
            sum += s / n;
            sum0 += s0 / n;
            pairs += 1;
        }
        let k = pairs.max(1) as f64;
        println!(
            "{name}: {pairs} pairs, EPE on hair {:.3} px (zero flow, i.e. mean |V|: {:.3}), {:.1} s",
            sum / k,
            sum0 / k,
            t.elapsed().as_secs_f64()
        );
    }
}
