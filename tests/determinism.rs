//! What the README's "Determinism" section promises, asserted on a 128² synthetic case run
//! through `coif model` by the real binary:
//! - the cpu backend is bit-identical across runs and thread counts (every file, the JSON
//!   reports compared without their wall-clock keys and the backend's thread count);
//! - lavapipe and the cpu backend agree within the stated tolerances, which come from f32
//!   sums taken in another order, not from a measurement they were fitted to.

mod common;

use coif::io::{npy, strands};
use common::procs::{coif, ok};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn run(c: &mut Command, what: &str) {
    ok(c.output().unwrap(), what);
}

fn case(root: &Path) {
    run(
        coif(root).args(["synth", "--out", "case", "--style", "long", "--size", "128"]),
        "synth",
    );
}

fn model(root: &Path, out: &str, backend: &str, threads: &str) {
    run(
        coif(root)
            .args([
                "model",
                "--image",
                "case/image.png",
                "--strokes",
                "case/strokes.json",
            ])
            .args([
                "--mask",
                "case/mask.png",
                "--landmarks",
                "case/landmarks.json",
            ])
            .args(["--out", out, "--backend", backend])
            .env("RAYON_NUM_THREADS", threads),
        out,
    );
}

/// JSON with what legitimately changes between identical runs removed: wall-clock times
/// (`seconds`, `timings`) and the backend description, which names the thread count.
fn stable_json(v: &mut Value) {
    match v {
        Value::Object(m) => {
            for k in ["seconds", "timings", "backend"] {
                m.remove(k);
            }
            m.values_mut().for_each(stable_json);
        }
        Value::Array(a) => a.iter_mut().for_each(stable_json),
        _ => {}
    }
}

fn files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut m = BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        let mut bytes = std::fs::read(&p).unwrap();
        if p.extension().is_some_and(|x| x == "json") {
            let mut v: Value = serde_json::from_slice(&bytes).unwrap();
            stable_json(&mut v);
            bytes = serde_json::to_vec(&v).unwrap();
        }
        m.insert(p.strip_prefix(dir).unwrap().to_path_buf(), bytes);
    }
    m
}

fn max_abs(a: &[f32], b: &[f32], angle: bool) -> f32 {
    assert_eq!(a.len(), b.len());
    let mut worst = 0f32;
    for (x, y) in a.iter().zip(b) {
        assert_eq!(
            x.is_nan(),
            y.is_nan(),
            "one backend has a value where the other has none"
        );
        if x.is_nan() {
            continue;
        }
        let mut d = (x - y).abs();
        if angle {
            d = d.min(std::f32::consts::PI - d);
        }
        worst = worst.max(d);
    }
    worst
}

#[test]
fn cpu_backend_is_bit_identical_across_runs_and_thread_counts_and_lavapipe_within_tolerance() {
    let root = tempfile::tempdir().unwrap();
    let root = root.path();
    case(root);
    model(root, "cpu1", "cpu", "1");
    model(root, "cpu2", "cpu", "2");
    let (a, b) = (files(&root.join("cpu1")), files(&root.join("cpu2")));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, v) in &a {
        assert!(*v == b[k], "cpu backend, 1 vs 2 threads: {k:?} differs");
    }
    assert!(a.len() >= 10, "the model folder holds {} files", a.len());

    // Without a Vulkan adapter this fails with coif's "no GPU adapter" message.
    model(root, "gpu", "gpu", "2");
    let (cpu, gpu) = (root.join("cpu1"), root.join("gpu"));
    let read = |d: &Path, f: &str| npy::read_f32(&d.join(f)).unwrap().1;
    // Orientation: the Gabor responses summed in another order move the arg max by float
    // rounding only; 0.01° is 1/100 of the smallest angle any consumer resolves.
    let o = max_abs(
        &read(&cpu, "orientation.npy"),
        &read(&gpu, "orientation.npy"),
        true,
    );
    assert!(
        o.to_degrees() <= 0.01,
        "orientation differs by {}°",
        o.to_degrees()
    );
    // Confidence is a variance of responses in [0, 1]-scaled units: 1e-3 absolute.
    let c = max_abs(
        &read(&cpu, "confidence.npy"),
        &read(&gpu, "confidence.npy"),
        false,
    );
    assert!(c <= 1e-3, "confidence differs by {c}");
    // Unit direction vectors from the diffusion: 1e-4 per component.
    let d = max_abs(
        &read(&cpu, "direction.npy"),
        &read(&gpu, "direction.npy"),
        false,
    );
    assert!(d <= 1e-4, "direction differs by {d}");

    // Strands: the same roots (chosen on the CPU); growth can end a strand one step earlier
    // or later where a tolerance test sits on a rounding edge, so the counts are compared
    // in proportion and the geometry strand by strand where the vertex counts agree.
    let sa = strands::read(&cpu.join("strands.hair")).unwrap();
    let sb = strands::read(&gpu.join("strands.hair")).unwrap();
    let (na, nb) = (sa.counts.len(), sb.counts.len());
    assert!(
        na.abs_diff(nb) as f64 <= 1e-3 * na as f64,
        "{na} vs {nb} strands: more than 0.1% apart"
    );
    let (mut off_a, mut off_b, mut same, mut worst) = (0usize, 0usize, 0usize, 0f32);
    for (&ca, &cb) in sa.counts.iter().zip(&sb.counts) {
        let (ca, cb) = (ca as usize, cb as usize);
        if ca == cb {
            same += 1;
            for i in 0..ca {
                let (p, q) = (sa.points[off_a + i], sb.points[off_b + i]);
                let dist =
                    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
                worst = worst.max(dist);
            }
        }
        off_a += ca;
        off_b += cb;
    }
    assert!(
        same as f64 >= 0.99 * na.min(nb) as f64,
        "only {same} of {} strands have the same vertex count",
        na.min(nb)
    );
    // Half a pixel: the head is about 0.25 m across 128 px, so 1 mm.
    assert!(worst <= 1e-3, "strands differ by up to {worst} m");
    eprintln!(
        "cpu vs lavapipe: orientation {:.2e}°, confidence {c:.2e}, direction {d:.2e}, \
         strands {na} vs {nb}, {same} with equal vertex counts, up to {worst:.2e} m apart",
        o.to_degrees()
    );
}
