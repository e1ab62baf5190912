//! Simulation (issue 14): figures on real strands grown on the parametric head, and the
//! sim_step pass (with `shared/noise.wgsl` and `shared/head_sdf.wgsl`) against its CPU
//! mirror on lavapipe.

use coif::gpu::engine::Engine;
use coif::hair::head::Head;
use coif::hair::strands::StrandSet;
use coif::sim::{max_displacement, HeadTrack, Sim, SimParams};
use coif::synth::synth3d::{synth3d_with, Synth3dOptions};
use coif::synth::{Style, SynthParams};

/// Strands of the 3D ground-truth synth (long style), on the default head.
fn strands(n: usize) -> (StrandSet, Head) {
    let c = synth3d_with(
        &SynthParams {
            style: Style::Long,
            seed: 1,
            width: 128,
            height: 128,
        },
        &Synth3dOptions {
            strands: n,
            max_yaw_deg: 0.0,
        },
    );
    (c.gt, c.head)
}

#[test]
fn strong_wind_keeps_lengths_roots_and_the_head_out() {
    let (s, head) = strands(300);
    let p = SimParams {
        wind: 3.0,
        substeps: 10,
        ..Default::default()
    };
    let e = Engine::cpu();
    let mut sim = Sim::new(&s, &head, &p).unwrap();
    let rest = sim.x.clone();
    let mut worst_p99 = 0.0f64;
    let mut worst_len = 0.0f64;
    let mut worst_root = 0.0f64;
    let mut deepest = f32::INFINITY;
    for _ in 0..10 {
        sim.advance(&e, 100).unwrap();
        let f = sim.figures();
        worst_p99 = worst_p99.max(f.stretch_p99);
        worst_len = worst_len.max(f.length_max);
        worst_root = worst_root.max(f.root_error_max);
        deepest = deepest.min(f.min_head_distance);
        println!("{f:?}");
    }
    let moved = max_displacement(&rest, &sim.x);
    println!(
        "1000 steps, wind 3 m/s: stretch p99 {:.3}%, length {:.3}%, roots {:.1e} m, deepest {:.2} mm, moved {:.1} mm",
        100.0 * worst_p99,
        100.0 * worst_len,
        worst_root,
        deepest * 1e3,
        moved * 1e3
    );
    assert!(moved > 0.01, "the wind should move the hair: {moved} m");
    assert!(worst_p99 <= 0.01, "stretch p99 {worst_p99}");
    assert!(worst_len <= 0.005, "strand length {worst_len}");
    assert!(worst_root <= 1e-6, "roots {worst_root} m");
    assert!(
        deepest >= -5e-4,
        "deepest vertex {deepest} m inside the head"
    );
}

#[test]
fn still_air_and_a_still_head_move_nothing() {
    let (s, head) = strands(200);
    let e = Engine::cpu();
    let mut sim = Sim::new(&s, &head, &SimParams::default()).unwrap();
    let rest = sim.x.clone();
    sim.advance(&e, 1000).unwrap();
    let moved = max_displacement(&rest, &sim.x);
    println!("1000 steps, no wind: largest motion {moved:.2e} m");
    assert!(moved <= 1e-4, "{moved} m");
}

#[test]
fn energy_never_rises_once_the_wind_stops() {
    let (s, head) = strands(200);
    let p = SimParams {
        wind: 2.0,
        wind_until: Some(10),
        ..Default::default()
    };
    let e = Engine::cpu();
    let mut sim = Sim::new(&s, &head, &p).unwrap();
    sim.advance(&e, 10 * p.substeps).unwrap();
    let mut last = sim.energy();
    let mut rises = 0;
    for k in 0..200 {
        sim.advance(&e, 5).unwrap();
        let en = sim.energy();
        if en > last * (1.0 + 1e-6) + 1e-12 {
            rises += 1;
            println!("step {}: energy rose {last:.6e} -> {en:.6e}", k * 5);
        }
        last = en;
    }
    assert_eq!(rises, 0);
}

#[test]
fn a_head_turn_carries_the_roots() {
    let (s, head) = strands(200);
    let p = SimParams {
        track: HeadTrack {
            yaw: coif::sim::track::parse_keys("0:0,15:20,30:0").unwrap(),
            ..Default::default()
        },
        ..Default::default()
    };
    let e = Engine::cpu();
    let mut sim = Sim::new(&s, &head, &p).unwrap();
    let mut worst_root = 0.0f64;
    let mut deepest = f32::INFINITY;
    for _ in 0..30 {
        sim.advance(&e, p.substeps).unwrap();
        let f = sim.figures();
        worst_root = worst_root.max(f.root_error_max);
        deepest = deepest.min(f.min_head_distance);
    }
    println!(
        "20° head turn: roots {worst_root:.1e} m, deepest {:.2} mm",
        deepest * 1e3
    );
    assert!(worst_root <= 1e-6, "{worst_root}");
    assert!(deepest >= -5e-4, "{deepest}");
}

fn lavapipe() -> Engine {
    Engine::new(coif::gpu::engine::BackendChoice::Gpu).expect("a Vulkan adapter (lavapipe)")
}

/// sim_step on lavapipe against its CPU mirror: after one step and after 100 steps of wind
/// with a head turn.
#[test]
fn sim_step_parity() {
    let (s, head) = strands(256);
    let p = SimParams {
        wind: 1.5,
        track: HeadTrack {
            yaw: coif::sim::track::parse_keys("0:0,10:10").unwrap(),
            ..Default::default()
        },
        ..Default::default()
    };
    let (cpu, gpu) = (Engine::cpu(), lavapipe());
    let mut a = Sim::new(&s, &head, &p).unwrap();
    let mut b = Sim::new(&s, &head, &p).unwrap();
    a.advance(&cpu, 1).unwrap();
    b.advance(&gpu, 1).unwrap();
    let one = max_displacement(&a.x, &b.x);
    println!("sim_step parity after 1 step: largest difference {one:.2e} m");
    assert!(one <= 1e-5, "{one} m");
    a.advance(&cpu, 99).unwrap();
    b.advance(&gpu, 99).unwrap();
    let mut d: Vec<f64> =
        a.x.chunks(3)
            .zip(b.x.chunks(3))
            .map(|(p, q)| max_displacement(p, q))
            .collect();
    d.sort_by(f64::total_cmp);
    let q999 = d[((d.len() - 1) as f64 * 0.999) as usize];
    let moved = max_displacement(&s_first(&a), &a.x);
    println!(
        "after 100 steps: 99.9th percentile difference {q999:.2e} m, largest {:.2e} m (hair moved up to {moved:.3} m)",
        d[d.len() - 1]
    );
    assert!(q999 <= 1e-3, "{q999} m");
}

fn s_first(sim: &Sim) -> Vec<f32> {
    sim.rest.points.iter().flatten().copied().collect()
}

fn coif(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_coif"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("coif runs")
}

/// A model folder (strands, head, camera, photo) from the 3D ground-truth synth.
fn model_folder(dir: &std::path::Path, n: usize) {
    let c = synth3d_with(
        &SynthParams {
            style: Style::Long,
            seed: 2,
            width: 128,
            height: 128,
        },
        &Synth3dOptions {
            strands: n,
            max_yaw_deg: 0.0,
        },
    );
    let scene = coif::hair::scene::Scene {
        dir: dir.to_path_buf(),
        strands: c.gt,
        camera: Some(c.camera),
        head: Some(c.head),
        photo: Some(c.case.image.clone()),
        mask: None,
        width: 128,
        height: 128,
        animation: None,
        rest: None,
    };
    scene.save(dir, serde_json::json!({})).unwrap();
}

#[test]
fn simulate_writes_frames_that_render_and_export_as_usd() {
    let t = tempfile::tempdir().unwrap();
    let p = |s: &str| t.path().join(s).display().to_string();
    model_folder(&t.path().join("model"), 150);
    let o = coif(&[
        "simulate",
        "--backend",
        "cpu",
        "--model",
        &p("model"),
        "--frames",
        "4",
        "--wind",
        "1",
        "--head-yaw",
        "0:0,4:5",
        "--out",
        &p("wind"),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let out = String::from_utf8_lossy(&o.stdout);
    println!("{out}");
    assert!(out.contains("stretch p99"), "{out}");
    for k in 0..5 {
        assert!(t.path().join(format!("wind/frames/{k:04}.hair")).is_file());
    }
    for f in [
        "sim.json",
        "preview.gif",
        "model.json",
        "strands.hair",
        "photo.png",
    ] {
        assert!(t.path().join("wind").join(f).is_file(), "{f}");
    }
    // Every frame rendered into a folder.
    let o = coif(&[
        "render",
        "--backend",
        "cpu",
        "--model",
        &p("wind"),
        "--out",
        &p("frames"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for k in 0..5 {
        let f = t.path().join(format!("frames/{k:04}.png"));
        let img = image::open(&f).unwrap();
        assert_eq!(img.width(), 128);
    }
    // Animated USD: points as time samples, the head as an animated transform.
    let usda = p("wind.usda");
    let o = coif(&["export", "--model", &p("wind"), "--to", &usda]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&usda).unwrap();
    assert!(text.contains("points.timeSamples") && text.contains("xformOp:transform.timeSamples"));
    let check = std::process::Command::new("python3")
        .args([
            "-c",
            "import sys\nfrom pxr import Usd, UsdGeom\ns = Usd.Stage.Open(sys.argv[1])\nc = UsdGeom.BasisCurves(s.GetPrimAtPath('/hair'))\nts = c.GetPointsAttr().GetTimeSamples()\nassert len(ts) == 5, ts\nassert len(c.GetPointsAttr().Get(4)) == sum(c.GetCurveVertexCountsAttr().Get())\nx = UsdGeom.Xformable(s.GetPrimAtPath('/head'))\nassert len(x.GetTimeSamples()) == 5\nprint('usd ok', s.GetEndTimeCode())",
            &usda,
        ])
        .output()
        .expect("python3 runs");
    assert!(
        check.status.success(),
        "usd-core rejects the animated stage: {}",
        String::from_utf8_lossy(&check.stderr)
    );
}

#[test]
fn simulate_refuses_bad_input_and_writes_nothing() {
    let t = tempfile::tempdir().unwrap();
    let p = |s: &str| t.path().join(s).display().to_string();
    model_folder(&t.path().join("model"), 60);
    let cases: &[(&[&str], i32, &str)] = &[
        (&["--wind", "nan"], 64, "--wind must be finite"),
        (&["--fps", "inf"], 64, "--fps must be finite"),
        (
            &["--substeps", "1", "--head-yaw", "0:0,1:90"],
            64,
            "too large to stay stable",
        ),
        (
            &["--substeps", "2", "--strain-limit", "0", "--wind", "4"],
            64,
            "too large to stay stable",
        ),
        (&["--verts", "200"], 64, "--verts must be in"),
    ];
    for (extra, code, needle) in cases {
        let mut args = vec!["simulate", "--backend", "cpu", "--model"];
        let model = p("model");
        let out = p("out");
        args.extend([model.as_str(), "--frames", "6", "--out", out.as_str()]);
        args.extend(extra.iter());
        let o = coif(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(*code), "{extra:?}: {err}");
        assert!(err.contains(needle), "{extra:?}: {err}");
        assert!(!t.path().join("out").exists(), "{extra:?} wrote output");
    }
    // Strands without a head (an imported file): nothing to collide with or carry roots.
    let o = coif(&["import", &p("model/strands.hair"), "--out", &p("bare")]);
    assert!(o.status.success());
    let o = coif(&[
        "simulate",
        "--backend",
        "cpu",
        "--model",
        &p("bare"),
        "--out",
        &p("out"),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(65), "{err}");
    assert!(
        err.contains("model.json") && err.contains("no head"),
        "{err}"
    );
    assert!(!t.path().join("out").exists());
}

/// The wind's noise in WGSL (`noise_eval`, the `shared/noise.wgsl` that sim_step includes)
/// against the mirror and against Perlin's f64 reference, on 10⁵ points.
#[test]
fn noise_eval_parity_on_lavapipe() {
    use coif::stages::noise_eval;
    let mut rng = coif::base::rng::Rng::new(7);
    let pts: Vec<[f32; 3]> = (0..100_000)
        .map(|_| {
            [
                rng.range_f32(-60.0, 60.0),
                rng.range_f32(-60.0, 60.0),
                rng.range_f32(-60.0, 60.0),
            ]
        })
        .collect();
    let gpu = noise_eval::eval(&lavapipe(), &pts).unwrap();
    let cpu = noise_eval::eval(&Engine::cpu(), &pts).unwrap();
    let (mut mirror, mut reference) = (0.0f64, 0.0f64);
    for ((g, c), p) in gpu.iter().zip(&cpu).zip(&pts) {
        assert!(g.is_finite(), "the pass left a value unwritten");
        mirror = mirror.max((g - c).abs() as f64);
        let r = coif::sim::noise::perlin64(p[0] as f64, p[1] as f64, p[2] as f64);
        reference = reference.max((*g as f64 - r).abs());
    }
    println!(
        "noise on 1e5 points: WGSL vs mirror {mirror:.2e}, WGSL vs f64 reference {reference:.2e}"
    );
    assert!(mirror <= 1e-5, "{mirror}");
    assert!(reference <= 1e-4, "{reference}");
}

/// A simulated frame's strands keep the photo's colour from where the photo saw them, over
/// the photo with its hair inpainted (`render::render_moved`, what `coif render` draws a
/// simulation's frames with). Shifted 24 px sideways in the image, the moved hair must look
/// like the rest hair shifted; `render` of the same moved strands at the photo's view gives
/// the photo back whatever the strands do (a wind clip rendered so showed no motion).
#[test]
fn moved_strands_carry_their_photo_colour() {
    use coif::render::{render, render_moved, to_rgb8, RenderParams};
    let (w, h) = (256u32, 256u32);
    let c = synth3d_with(
        &SynthParams {
            style: Style::Long,
            seed: 2,
            width: w,
            height: h,
        },
        &Synth3dOptions {
            strands: 3000,
            max_yaw_deg: 0.0,
        },
    );
    let mut rest = c.gt.clone();
    rest.colors = Some(vec![[0.3, 0.2, 0.1]; rest.points.len()]);
    let mask: Vec<u8> = c.case.mask.pixels().map(|m| (m.0[0] > 127) as u8).collect();
    let scene = coif::hair::scene::Scene {
        dir: "moved".into(),
        strands: rest.clone(),
        camera: Some(c.camera),
        head: Some(c.head),
        photo: Some(c.case.image.clone()),
        mask: Some(mask.clone()),
        width: w,
        height: h,
        animation: None,
        rest: None,
    };
    const SHIFT: f32 = 24.0;
    let delta = c.camera.r.transpose() * glam::Vec3::new(SHIFT / c.camera.s, 0.0, 0.0);
    let q0 = glam::Vec3::from_array(rest.points[0]);
    let moved_px = c.camera.project(q0 + delta) - c.camera.project(q0);
    assert!((moved_px.x - SHIFT).abs() < 1e-3 && moved_px.y.abs() < 1e-3);
    let mut moved = scene.clone();
    for q in &mut moved.strands.points {
        *q = (glam::Vec3::from_array(*q) + delta).to_array();
    }
    let e = Engine::cpu();
    let mut p = RenderParams::default();
    p.head_texture.tex_size = 256;
    let at_rest = to_rgb8(&render(&e, &scene, &p).unwrap());
    let shown = to_rgb8(&render_moved(&e, &moved, &rest, &p).unwrap());
    let photo_back = to_rgb8(&render(&e, &moved, &p).unwrap());
    // Hair pixels 3 px inside the mask whose shifted place is in the frame.
    let inner = coif::base::mask::erode(&mask, w as usize, h as usize, 3);
    let median_diff = |img: &image::RgbImage| {
        let mut d: Vec<i32> = (0..w * h)
            .filter(|&i| inner[i as usize] != 0 && (i % w) as f32 + SHIFT < w as f32)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let a = at_rest.get_pixel(x, y).0;
                let b = img.get_pixel(x + SHIFT as u32, y).0;
                (0..3)
                    .map(|k| (a[k] as i32 - b[k] as i32).abs())
                    .max()
                    .unwrap()
            })
            .collect();
        d.sort_unstable();
        (d[d.len() / 2], d[d.len() * 9 / 10], d.len())
    };
    let (m_new, p90_new, n) = median_diff(&shown);
    let (m_old, p90_old, _) = median_diff(&photo_back);
    println!(
        "hair shifted {SHIFT} px, {n} px compared with the rest render shifted: median / 90th \
         percentile difference {m_new} / {p90_new} levels with render_moved, {m_old} / \
         {p90_old} with render (the photo back)"
    );
    assert!(
        m_new <= 4,
        "moved hair does not look like the rest hair: {m_new}"
    );
    assert!(
        m_old > 2 * m_new.max(1),
        "render of moved strands no longer gives the photo back"
    );
}
