//! Video tracking on synthetic clips with exact ground truth (issue 15's acceptance): per
//! style, the flow's mean end-point error on hair beside OpenCV DIS (MEDIUM) and Farneback
//! on the same frames (`benches/peers/flow_opencv.py`, run in the same bench), drift of
//! W*_i at r+30 and r+60 for Eq. (6) against flow alone and features alone, median 3D
//! vertex error, roots, head yaw error, flicker ratio, and seconds per frame on the cpu
//! backend (and lavapipe at one size with COIF_BENCH_GPU=1).
//!
//! Run: `cargo bench --bench video`. COIF_BENCH_SIZE (256), COIF_BENCH_FRAMES (61),
//! COIF_BENCH_STYLES ("long,whorl,sidepart"), COIF_BENCH_STRANDS (6000),
//! COIF_BENCH_LOCK_TURN (degrees of the lock-scale hair turn; 0 for head-sized waves only),
//! COIF_BENCH_NOISE (camera noise σ in grey levels, fresh per frame; 0: clean renders),
//! COIF_BENCH_JPEG (JPEG quality of every frame after the noise; 0: lossless),
//! COIF_BENCH_ORACLE_FLOW=1 composes Eq. 6 with the true flow on hair (what these features
//! get from a flow without error), COIF_BENCH_FLICKER=0 skips the re-render, COIF_BENCH_KEEP=DIR keeps the clips,
//! COIF_BENCH_ANCHOR=chain tracks features frame to frame only (KLT as C13 uses it; the
//! default refines each step against the reference frame's patch),
//! COIF_BENCH_RESIDUAL=1 spreads the features' departure from the head's motion
//! (`TrackParams::spread_residual`).

use coif::eval::video::{evaluate, EvalOptions};
use coif::gpu::engine::{BackendChoice, Engine};
use coif::synth::video::VideoParams;
use coif::synth::Style;
use std::process::Command;

fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(d)
}

fn opencv(dir: &std::path::Path) -> Option<(f64, f64, f64, f64)> {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/peers/flow_opencv.py");
    let out = Command::new("python3").arg(script).arg(dir).output().ok()?;
    if !out.status.success() {
        eprintln!(
            "OpenCV peer failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        return None;
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let last = text.lines().last()?;
    let v: serde_json::Value = serde_json::from_str(last).ok()?;
    let s = v.get("summary")?;
    let g = |m: &str, k: &str| s.get(m)?.get(k)?.as_f64();
    Some((
        g("dis_medium", "mean_epe")?,
        g("dis_medium", "mean_ms")?,
        g("farneback", "mean_epe")?,
        g("farneback", "mean_ms")?,
    ))
}

fn main() {
    let size: u32 = env("COIF_BENCH_SIZE", 256);
    let frames: usize = env("COIF_BENCH_FRAMES", 61);
    let strands: usize = env("COIF_BENCH_STRANDS", 6000);
    let lock_turn: f32 = env("COIF_BENCH_LOCK_TURN", coif::synth::video::LOCK_TURN_DEG);
    let noise: f32 = env("COIF_BENCH_NOISE", 0.0);
    let jpeg: u8 = env("COIF_BENCH_JPEG", 0);
    let flicker = env("COIF_BENCH_FLICKER", 1) != 0;
    let gpu = env("COIF_BENCH_GPU", 0) != 0;
    let styles: String = env("COIF_BENCH_STYLES", "long,whorl,sidepart".to_string());
    let keep: Option<std::path::PathBuf> = std::env::var("COIF_BENCH_KEEP").ok().map(Into::into);
    let chain = env("COIF_BENCH_ANCHOR", "reference".to_string()) == "chain";
    let mut engines = vec![("cpu", Engine::cpu())];
    if gpu {
        match Engine::new(BackendChoice::Gpu) {
            Ok(e) => engines.push(("lavapipe", e)),
            Err(e) => eprintln!("no GPU engine: {e}"),
        }
    }
    println!(
        "video bench: {size}², {frames} frames, {strands} strands, lock turn {lock_turn}°, camera noise σ {noise}, JPEG quality {jpeg} (0: lossless), reference frame 0"
    );
    for style in styles.split(',') {
        let style: Style = match style.trim().parse() {
            Ok(s) => s,
            Err(e) => {
                eprintln!("{style}: {e}");
                continue;
            }
        };
        for (name, engine) in &engines {
            let tmp = tempfile::tempdir().expect("temp dir");
            let dir = match &keep {
                Some(k) => k.join(format!("{style:?}").to_lowercase()),
                None => tmp.path().to_path_buf(),
            };
            let mut vp = VideoParams::new(style, 1, size, frames);
            vp.strands = strands;
            vp.lock_turn_deg = lock_turn;
            vp.noise = noise;
            vp.jpeg = jpeg;
            let mut track = coif::video::track::TrackParams {
                spread_residual: env("COIF_BENCH_RESIDUAL", 0) != 0,
                ..Default::default()
            };
            if chain {
                track.klt.anchor = coif::video::features::Anchor::Chain;
            }
            let o = EvalOptions {
                track,
                drift_frames: vec![30, 60].into_iter().filter(|&f| f < frames).collect(),
                flicker: flicker && *name == "cpu",
                oracle_flow: env("COIF_BENCH_ORACLE_FLOW", 0) != 0,
                write_dir: Some(dir.clone()),
                ..Default::default()
            };
            let f = match evaluate(engine, &vp, &o) {
                Ok(f) => f,
                Err(e) => {
                    eprintln!("{style:?} on {name}: {e}");
                    continue;
                }
            };
            let ours = f.flow_epe.iter().sum::<f32>() / f.flow_epe.len() as f32;
            let motion = f.flow_mean_motion.iter().sum::<f32>() / f.flow_mean_motion.len() as f32;
            println!(
                "\n{style:?} on {name}: {:.3} s per frame (tracking)",
                f.seconds_per_frame
            );
            println!(
                "  flow EPE on hair: ours {ours:.3} px (true motion {motion:.3} px per frame)"
            );
            if *name == "cpu" {
                match opencv(&dir) {
                    Some((dis, dis_ms, fb, fb_ms)) => println!(
                        "  OpenCV DIS MEDIUM {dis:.3} px ({dis_ms:.1} ms/pair), Farneback {fb:.3} px ({fb_ms:.1} ms/pair); ratio ours / DIS = {:.2}",
                        ours as f64 / dis
                    ),
                    None => println!("  OpenCV peer unavailable (pip install opencv-python-headless)"),
                }
            }
            for d in &f.drift {
                println!("  {d}");
            }
            let mut v = f.vertex_median_mm.clone();
            v.sort_by(f32::total_cmp);
            let mut vv = f.vertex_visible_median_mm.clone();
            vv.sort_by(f32::total_cmp);
            println!(
                "  3D: median vertex error {:.2} mm (median over frames; last frame {:.2} mm; visible vertices {:.2} mm), roots {:.1e} m, stretch p99 {:.2} % (largest {:.1} %)",
                v[v.len() / 2],
                f.vertex_median_mm[f.vertex_median_mm.len() - 1],
                vv[vv.len() / 2],
                f.root_max_m,
                100.0 * f.stretch_p99,
                100.0 * f.stretch_max
            );
            println!(
                "  head: yaw error {:.2}° at most, rotation error {:.2}°, poses {:?}; features {} of {} on the last frame",
                f.yaw_err_max_deg, f.rot_err_max_deg, f.pose_sources, f.features_last, f.features_reference
            );
            if let Some(r) = f.flicker_ratio {
                println!(
                    "  flicker on hair: input {:.2}, re-rendered {:.2}, ratio {r:.2}; with the reference's vertex colours {:.2}, ratio {:.2}",
                    f.flicker_in.unwrap_or(0.0),
                    f.flicker_out.unwrap_or(0.0),
                    f.flicker_vertex_out.unwrap_or(0.0),
                    f.flicker_vertex_ratio.unwrap_or(0.0)
                );
            }
        }
    }
}
