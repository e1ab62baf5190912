//! `--timings FILE` as real processes on 128² synthetic cases: each pipeline command writes
//! a file the schema accepts, naming that command's stages, with times that add up; lavapipe
//! reports GPU time per pass; `coif batch`'s summary aggregates its jobs' timings. No test
//! asserts on a duration.

use crate::common;

use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

const SCHEMA: &str = include_str!("../../schemas/timings.v1.schema.json");

fn coif(dir: &Path, args: &[&str]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_coif"));
    c.current_dir(dir).args(args);
    // Batch shards come from these when set; the test's own environment must not choose.
    for v in [
        "SLURM_ARRAY_TASK_ID",
        "SLURM_ARRAY_TASK_COUNT",
        "JOB_COMPLETION_INDEX",
        "COIF_SHARDS",
    ] {
        c.env_remove(v);
    }
    let o = c.output().unwrap();
    assert!(
        o.status.success(),
        "coif {args:?}: {}\n{}{}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        common::stderr(&o)
    );
    o
}

fn read(p: &Path) -> Value {
    let text = std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The schema's verdict on `v`, with boon's message.
fn validate(v: &Value) -> Result<(), String> {
    let url = "https://coif.invalid/timings.v1.schema.json";
    let mut schemas = boon::Schemas::new();
    let mut compiler = boon::Compiler::new();
    compiler
        .add_resource(url, serde_json::from_str(SCHEMA).unwrap())
        .unwrap();
    let idx = compiler.compile(url, &mut schemas).unwrap();
    schemas.validate(v, idx).map_err(|e| format!("{e:#}"))
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// Checks a command's timings file and returns its stage names.
fn check(p: &Path, command: &str) -> Vec<String> {
    check_at_once(p, command, 1)
}

/// [`check`] of a run that ran `at_once` jobs at the same time (`coif batch --jobs`), whose
/// stages may sum to that many times the wall.
fn check_at_once(p: &Path, command: &str, at_once: u64) -> Vec<String> {
    let v = read(p);
    validate(&v).unwrap_or_else(|e| panic!("{}: {e}\n{v:#}", p.display()));
    assert_eq!(v["command"], command);
    assert_eq!(v["coif_version"], env!("CARGO_PKG_VERSION"));
    let wall = f(&v["wall_seconds"]);
    let stages = v["stages"].as_array().unwrap();
    let sum: f64 = stages.iter().map(|s| f(&s["seconds"])).sum();
    assert!(
        stages.iter().all(|s| f(&s["seconds"]) >= 0.0),
        "{command}: {v:#}"
    );
    assert!(
        sum <= wall * at_once as f64,
        "{command}: stages sum to {sum} s, wall {wall} s, {at_once} at once"
    );
    assert!(v["peak_rss_bytes"].as_u64().unwrap() > 0);
    stages
        .iter()
        .map(|s| s["name"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn every_pipeline_command_names_its_stages_on_the_cpu_backend() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    coif(d, &["synth", "--out", "case", "--size", "128"]);
    let cpu = ["--backend", "cpu"];
    let runs: Vec<(&str, Vec<&str>, Vec<&str>)> = vec![
        (
            "orient",
            vec!["--image", "case/image.png", "--out", "o", "--truth", "case"],
            vec!["engine", "read", "orientation", "score", "write"],
        ),
        (
            "analyze",
            vec![
                "--image",
                "case/image.png",
                "--strokes",
                "case/strokes.json",
                "--out",
                "a",
            ],
            vec![
                "engine",
                "read",
                "segment",
                "orientation",
                "trace",
                "resolve",
                "direction",
                "write",
            ],
        ),
        (
            "model",
            vec![
                "--image",
                "case/image.png",
                "--strokes",
                "case/strokes.json",
                "--landmarks",
                "case/landmarks.json",
                "--out",
                "m",
                "--cells",
                "12",
                "--roots",
                "500",
            ],
            vec![
                "engine",
                "read",
                "segment",
                "orientation",
                "trace",
                "resolve",
                "direction",
                "head_fit",
                "hair_volume",
                "constraints",
                "direction_field",
                "growth",
                "refinement",
                "colour",
                "write",
            ],
        ),
        (
            "render",
            vec!["--model", "m", "--out", "r.png", "--yaw", "20"],
            vec![
                "engine",
                "load",
                "shading",
                "layers",
                "rasterisation",
                "write",
            ],
        ),
        (
            "simulate",
            vec!["--model", "m", "--out", "s", "--frames", "2"],
            vec!["engine", "load", "simulate", "write"],
        ),
        (
            "sketch",
            vec![
                "--image",
                "case/image.png",
                "--mask",
                "case/mask.png",
                "--out",
                "sk",
                "--sweeps",
                "100",
                "--bases",
                "4",
            ],
            vec![
                "engine",
                "read",
                "hair_region",
                "bands",
                "gabor",
                "shading",
                "pursuit",
                "directions",
                "fill",
                "write",
            ],
        ),
        (
            "synth-hair",
            vec!["--sketch", "sk/hair.czs", "--out", "sh.png"],
            vec!["engine", "read", "fill", "texture", "colour", "write"],
        ),
        (
            "cartoon",
            vec!["--sketch", "sk/hair.czs", "--out", "c.png"],
            vec!["engine", "read", "draw", "write"],
        ),
    ];
    for (cmd, args, expected) in runs {
        let file = format!("t-{cmd}.json");
        let mut all = vec![cmd];
        all.extend(args);
        all.extend(cpu);
        // A global option: accepted after the command's own.
        all.extend(["--timings", &file]);
        coif(d, &all);
        assert_eq!(check(&d.join(&file), cmd), expected, "{cmd}");
        let v = read(&d.join(&file));
        assert_eq!(v["backend"]["kind"], "cpu");
        assert_eq!(v["gpu_time"]["status"], "unavailable", "{cmd}");
        assert!(v["gpu_time"]["reason"].as_str().unwrap().contains("cpu"));
    }
    // A stage run once per frame is one entry with its count: two frames of the simulated
    // model rendered into a folder.
    coif(
        d,
        &[
            "--timings",
            "t-frames.json",
            "render",
            "--model",
            "s",
            "--out",
            "frames",
            "--backend",
            "cpu",
        ],
    );
    let names = check(&d.join("t-frames.json"), "render");
    assert_eq!(
        names,
        [
            "engine",
            "load",
            "shading",
            "layers",
            "rasterisation",
            "write"
        ]
    );
    let v = read(&d.join("t-frames.json"));
    let frames = std::fs::read_dir(d.join("frames"))
        .unwrap()
        .filter(|e| e.as_ref().unwrap().path().extension() == Some("png".as_ref()))
        .count() as u64;
    assert!(frames >= 2);
    for s in v["stages"].as_array().unwrap() {
        let expected = if ["engine", "load"].contains(&s["name"].as_str().unwrap()) {
            1
        } else {
            frames
        };
        assert_eq!(s["count"], expected, "{s}");
    }
}

#[test]
fn lavapipe_reports_gpu_time_per_pass() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    coif(d, &["synth", "--out", "case", "--size", "128"]);
    coif(
        d,
        &[
            "orient",
            "--image",
            "case/image.png",
            "--out",
            "o",
            "--backend",
            "gpu",
            "--timings",
            "t.json",
        ],
    );
    check(&d.join("t.json"), "orient");
    let v = read(&d.join("t.json"));
    assert_eq!(v["backend"]["kind"], "gpu");
    // lavapipe has timestamp queries; a test on an adapter without them would see
    // "unavailable" and fail here, which is what it should report then.
    assert_eq!(v["backend"]["timestamp_queries"], true, "{v:#}");
    assert_eq!(v["gpu_time"]["status"], "measured", "{v:#}");
    let passes = v["gpu_time"]["passes"].as_array().unwrap();
    let names: Vec<&str> = passes.iter().map(|p| p["name"].as_str().unwrap()).collect();
    for n in ["gabor", "orient_moments", "orient_fit", "sep_blur"] {
        assert!(names.contains(&n), "no pass {n}: {names:?}");
    }
    let sum: f64 = passes.iter().map(|p| f(&p["seconds"])).sum();
    assert!((sum - f(&v["gpu_time"]["seconds"])).abs() <= 1e-9 * sum.max(1.0));
    assert!(passes
        .iter()
        .all(|p| p["dispatches"].as_u64().unwrap() >= 1));
    // GPU time is inside the run's wall time.
    assert!(sum <= f(&v["wall_seconds"]), "{v:#}");
}

#[test]
fn a_bad_timings_path_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    coif(d, &["synth", "--out", "case", "--size", "128"]);
    let run = |t: &str| {
        Command::new(env!("CARGO_BIN_EXE_coif"))
            .current_dir(d)
            .args([
                "orient",
                "--image",
                "case/image.png",
                "--out",
                "o",
                "--backend",
                "cpu",
                "--timings",
                t,
            ])
            .output()
            .unwrap()
    };
    common::fails(&run("t.txt"), 64, &["--timings t.txt", ".json"]);
    common::fails(&run("case"), 64, &["--timings case"]);
    common::fails(&run("no/such/t.json"), 74, &["no/such"]);
    assert!(!d.join("o").exists(), "the orientation ran");
    let info = Command::new(env!("CARGO_BIN_EXE_coif"))
        .args(["info", "--timings", "t.json"])
        .current_dir(d)
        .output()
        .unwrap();
    common::fails(&info, 64, &["--timings", "info"]);
}

#[test]
fn the_batch_summary_aggregates_its_jobs_timings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for s in ["1", "2"] {
        let out = format!("cases/{s}");
        coif(
            d,
            &[
                "synth", "--out", &out, "--style", "long", "--size", "128", "--seed", s,
            ],
        );
    }
    let mut lines = Vec::new();
    for s in ["1", "2"] {
        let c = format!("cases/{s}");
        lines.push(format!(
            r#"{{"id": "{s}-orient", "image": "{c}/image.png", "mask": "{c}/mask.png", "out": "out/{s}-orient", "steps": ["orient"]}}"#
        ));
        lines.push(format!(
            r#"{{"id": "{s}-analyze", "image": "{c}/image.png", "strokes": "{c}/strokes.json", "out": "out/{s}-analyze", "steps": ["orient", "analyze"]}}"#
        ));
    }
    std::fs::write(d.join("jobs.jsonl"), lines.join("\n") + "\n").unwrap();
    coif(
        d,
        &[
            "batch",
            "jobs.jsonl",
            "--backend",
            "cpu",
            "--timings",
            "batch-timings.json",
        ],
    );
    let summary = read(&d.join("jobs.jsonl.summary.json"));
    let jobs = summary["jobs"].as_array().unwrap();
    assert_eq!(jobs.len(), 4);
    // Each job's timings: its steps' stages under the step's name.
    let mut per_stage: std::collections::BTreeMap<String, Vec<f64>> = Default::default();
    let mut peaks = Vec::new();
    for j in jobs {
        let t = &j["timings"];
        let names: Vec<&str> = t["stages"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s["name"].as_str().unwrap())
            .collect();
        let mut expected = vec!["orient/read", "orient/orientation", "orient/write"];
        if j["id"].as_str().unwrap().ends_with("analyze") {
            expected.extend([
                "analyze/read",
                "analyze/segment",
                "analyze/orientation",
                "analyze/trace",
                "analyze/resolve",
                "analyze/direction",
                "analyze/write",
            ]);
        }
        assert_eq!(names, expected, "{}", j["id"]);
        let sum: f64 = t["stages"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| f(&s["seconds"]))
            .sum();
        assert!(sum <= f(&t["wall_seconds"]));
        for s in t["stages"].as_array().unwrap() {
            per_stage
                .entry(s["name"].as_str().unwrap().to_string())
                .or_default()
                .push(f(&s["seconds"]));
        }
        peaks.push(t["peak_rss_bytes"].as_u64().unwrap());
    }
    let agg = &summary["timings"];
    assert_eq!(agg["jobs"], 4);
    let stages = agg["stages"].as_array().unwrap();
    assert_eq!(stages.len(), per_stage.len());
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 + 1e-9 * b.abs();
    for s in stages {
        let v = &per_stage[s["name"].as_str().unwrap()];
        let total: f64 = v.iter().sum();
        let max = v.iter().cloned().fold(0.0, f64::max);
        assert_eq!(s["jobs"].as_u64().unwrap(), v.len() as u64, "{s}");
        assert!(close(f(&s["total_seconds"]), total), "{s} vs {v:?}");
        assert!(close(f(&s["max_seconds"]), max), "{s} vs {v:?}");
        assert!(close(f(&s["mean_seconds"]), total / v.len() as f64), "{s}");
    }
    assert_eq!(
        agg["peak_rss_bytes_max"].as_u64(),
        peaks.iter().max().copied()
    );
    // The batch's own file: the same totals, in the timings format.
    // Two jobs at once (the default --jobs): their stages overlap in time.
    assert_eq!(summary["jobs_at_once"], 2);
    let names = check_at_once(&d.join("batch-timings.json"), "batch", 2);
    let bt = read(&d.join("batch-timings.json"));
    assert_eq!(names.len(), stages.len());
    for (s, a) in bt["stages"].as_array().unwrap().iter().zip(stages) {
        assert_eq!(s["name"], a["name"]);
        assert!(close(f(&s["seconds"]), f(&a["total_seconds"])));
        assert_eq!(s["count"], a["jobs"]);
    }
    assert!(bt["peak_rss_bytes"].as_u64().unwrap() >= *peaks.iter().max().unwrap());
}
