//! The memory budget (issue 18): options and inputs that size large allocations are refused
//! before work with a message naming them, and the cpu backend's tiled orientation equals
//! the one-piece run. Real `coif` processes: a refusal must come before anything is written.

use crate::common;

use common::fails;
use std::path::Path;
use std::process::{Command, Output};

fn coif(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_coif"))
        .args(args)
        .output()
        .expect("coif runs")
}

fn ok(o: &Output) {
    assert!(o.status.success(), "{}", common::stderr(o));
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A `size`² synthetic case in `dir`.
fn synth(dir: &Path, size: u32) -> std::path::PathBuf {
    let case = dir.join("case");
    ok(&coif(&[
        "synth",
        "--out",
        s(&case),
        "--size",
        &size.to_string(),
    ]));
    case
}

#[test]
fn cells_and_roots_over_the_budget_are_refused_before_work() {
    let t = tempfile::tempdir().unwrap();
    let case = synth(t.path(), 128);
    let out = t.path().join("model");
    let (img, strokes) = (case.join("image.png"), case.join("strokes.json"));
    let model = |extra: &[&str]| {
        let mut a = vec![
            "model",
            "--image",
            s(&img),
            "--strokes",
            s(&strokes),
            "--out",
            s(&out),
            "--backend",
            "cpu",
        ];
        a.extend_from_slice(extra);
        coif(&a)
    };
    // The cases: 150 GB and 96 GB asked for, the process aborted with no message.
    let o = model(&["--cells", "100000"]);
    fails(&o, 64, &["--cells 100000", "over the memory budget"]);
    let o = model(&["--roots", "4000000000"]);
    fails(&o, 64, &["--roots 4000000000", "over the memory budget"]);
    // Under a set budget, an ordinary count is refused too, and the budget is named.
    let o = model(&["--max-memory", "400M", "--roots", "1000000"]);
    fails(&o, 64, &["--roots 1000000", "400.0 MiB (--max-memory)"]);
    assert!(!out.exists(), "a refused run wrote {}", out.display());
}

#[test]
fn a_tiny_budget_refuses_orient_naming_the_image() {
    let t = tempfile::tempdir().unwrap();
    let case = synth(t.path(), 128);
    let img = case.join("image.png");
    let out = t.path().join("orient");
    let o = coif(&[
        "--max-memory",
        "1M",
        "orient",
        "--image",
        s(&img),
        "--out",
        s(&out),
        "--backend",
        "cpu",
    ]);
    fails(
        &o,
        65,
        &[
            &format!("--image {} (128x128 px)", img.display()),
            "1.0 MiB (--max-memory)",
        ],
    );
    assert!(!out.exists());
    // The same run under the machine's budget goes through: the refusal was the budget's.
    ok(&coif(&[
        "orient",
        "--image",
        s(&img),
        "--out",
        s(&out),
        "--backend",
        "cpu",
    ]));
    // A malformed size is a usage error naming the value.
    let o = coif(&[
        "--max-memory",
        "4X",
        "orient",
        "--image",
        s(&img),
        "--out",
        s(&out),
    ]);
    fails(&o, 64, &["\"4X\""]);
}

#[test]
fn colour_spacing_over_the_budget_is_refused_before_rendering() {
    let t = tempfile::tempdir().unwrap();
    let case = synth(t.path(), 128);
    let model = t.path().join("model");
    ok(&coif(&[
        "model",
        "--image",
        s(&case.join("image.png")),
        "--strokes",
        s(&case.join("strokes.json")),
        "--mask",
        s(&case.join("mask.png")),
        "--out",
        s(&model),
        "--roots",
        "2000",
        "--cells",
        "40",
        "--backend",
        "cpu",
    ]));
    let png = t.path().join("render.png");
    let render = |spacing: &str| {
        coif(&[
            "--max-memory",
            "256M",
            "render",
            "--model",
            s(&model),
            "--out",
            s(&png),
            "--colour-spacing",
            spacing,
            "--backend",
            "cpu",
        ])
    };
    // 1e-9 px puts 63 extra vertices on every segment (17 GB on the model).
    fails(
        &render("1e-9"),
        64,
        &[
            "--colour-spacing 0.000000001",
            "strand vertices",
            "256.0 MiB (--max-memory)",
        ],
    );
    assert!(!png.exists() && !t.path().join("render.png.json").exists());
    // The same budget renders the model at an ordinary spacing.
    ok(&render("2"));
    assert!(png.exists());
}

#[test]
fn tiled_orient_on_the_cpu_equals_one_piece() {
    let t = tempfile::tempdir().unwrap();
    let case = synth(t.path(), 256);
    let img = case.join("image.png");
    let run = |dir: &str, extra: &[&str]| {
        let out = t.path().join(dir);
        let mut a = vec![
            "-v",
            "orient",
            "--image",
            s(&img),
            "--out",
            s(&out),
            "--backend",
            "cpu",
        ];
        a.extend_from_slice(extra);
        let o = coif(&a);
        ok(&o);
        let read = |f: &str| coif::io::npy::read_f32(&out.join(f)).unwrap().1;
        (
            read("orientation.npy"),
            read("confidence.npy"),
            common::stderr(&o),
        )
    };
    let (theta, conf, _) = run("whole", &[]);
    // 96 kept px + the halo on each side: a 256² image in 3x3 tiles (the largest binding
    // is the linear fit's moment planes).
    let halo = coif::analyze::orient::OrientParams::default().halo() as u64;
    let side = 96 + 2 * halo;
    let planes = coif::stages::orient_moments::PLANES as u64;
    let limit = (side * side * 4 * planes).to_string();
    let (tt, tc, log) = run("tiled", &["--max-binding-bytes", &limit]);
    assert!(log.contains("in 9 tiles"), "not tiled:\n{log}");
    // The FFT sizes differ between a tile and the whole image, so values agree to rounding
    // (the parity test's tolerances): 0.5° on 99.9% of hair pixels, 1e-4 of the range.
    let cmax = conf.iter().fold(0.0f32, |a, &b| a.max(b));
    let mut far = 0;
    for i in 0..theta.len() {
        assert!(
            (tc[i] - conf[i]).abs() <= 1e-4 * cmax,
            "confidence at {i}: {} vs {}",
            tc[i],
            conf[i]
        );
        let d = (tt[i] - theta[i]).abs() % std::f32::consts::PI;
        if d.min(std::f32::consts::PI - d) > 0.5f32.to_radians() {
            far += 1;
        }
    }
    assert!(
        far as f64 <= 1e-3 * theta.len() as f64,
        "{far} angles differ by > 0.5°"
    );
}

/// A modelled 128² synthetic case (cpu backend) in `dir`.
fn modelled(dir: &Path) -> std::path::PathBuf {
    let case = synth(dir, 128);
    let model = dir.join("model");
    ok(&coif(&[
        "model",
        "--image",
        s(&case.join("image.png")),
        "--strokes",
        s(&case.join("strokes.json")),
        "--out",
        s(&model),
        "--backend",
        "cpu",
    ]));
    model
}

#[test]
fn simulate_frames_over_the_budget_are_refused_before_work() {
    let t = tempfile::tempdir().unwrap();
    let model = modelled(t.path());
    let out = t.path().join("sim");
    let sim = |extra: &[&str]| {
        let mut a = vec![
            "simulate",
            "--model",
            s(&model),
            "--out",
            s(&out),
            "--backend",
            "cpu",
        ];
        a.extend_from_slice(extra);
        coif(&a)
    };
    // Every frame is held until written: a million frames of this model are terabytes.
    let o = sim(&["--max-memory", "2G", "--frames", "1000000"]);
    fails(&o, 64, &["--frames 1000000", "2.0 GiB (--max-memory)"]);
    // A budget the model alone does not fit names the model.
    let o = sim(&["--max-memory", "1M", "--frames", "1"]);
    fails(
        &o,
        65,
        &[&format!("--model {}", model.display()), "vertices"],
    );
    assert!(!out.exists(), "a refused run wrote {}", out.display());
    // The same run under the machine's budget goes through.
    ok(&sim(&["--frames", "1", "--substeps", "1"]));
    assert!(out.join("frames/0001.hair").exists());
}

#[test]
fn sketch_and_synth_hair_over_the_budget_are_refused_before_work() {
    let t = tempfile::tempdir().unwrap();
    let case = synth(t.path(), 128);
    let (img, strokes) = (case.join("image.png"), case.join("strokes.json"));
    let out = t.path().join("sketch");
    let sketch = |extra: &[&str]| {
        let mut a = vec![
            "sketch",
            "--image",
            s(&img),
            "--strokes",
            s(&strokes),
            "--out",
            s(&out),
            "--backend",
            "cpu",
        ];
        a.extend_from_slice(extra);
        coif(&a)
    };
    let o = sketch(&["--max-memory", "2M"]);
    fails(
        &o,
        65,
        &[
            &format!("--image {} (128x128 px)", img.display()),
            "2.0 MiB (--max-memory)",
        ],
    );
    assert!(!out.exists(), "a refused run wrote {}", out.display());
    ok(&sketch(&[]));
    let czs = out.join("hair.czs");
    let png = t.path().join("hair.png");
    let synth_hair = |extra: &[&str]| {
        let mut a = vec![
            "synth-hair",
            "--sketch",
            s(&czs),
            "--out",
            s(&png),
            "--backend",
            "cpu",
        ];
        a.extend_from_slice(extra);
        coif(&a)
    };
    let o = synth_hair(&["--max-memory", "2M"]);
    fails(
        &o,
        65,
        &[
            &format!("--sketch {} (128x128 px)", czs.display()),
            "2.0 MiB (--max-memory)",
        ],
    );
    assert!(!png.exists(), "a refused run wrote {}", png.display());
    ok(&synth_hair(&[]));
    assert!(png.exists());
}
