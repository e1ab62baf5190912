//! `coif` as real processes: the binary with no shard variables from the test's own
//! environment, synthetic cases, manifests, and comparisons of output trees.

use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output};

const SHARD_VARS: [&str; 6] = [
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_COUNT",
    "SLURM_ARRAY_TASK_MIN",
    "SLURM_ARRAY_TASK_MAX",
    "JOB_COMPLETION_INDEX",
    "COIF_SHARDS",
];

/// `coif` in `dir` with no shard variables from the test's own environment.
pub fn coif(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_coif"));
    c.current_dir(dir);
    for v in SHARD_VARS {
        c.env_remove(v);
    }
    c
}

pub fn ok(o: Output, what: &str) -> Output {
    assert!(
        o.status.success(),
        "{what}: {}\n{}{}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// Synthetic 128² cases `cases/<style>` under `root`.
pub fn cases(root: &Path, styles: &[&str]) {
    for (i, s) in styles.iter().enumerate() {
        let out = format!("cases/{s}");
        let seed = (i + 1).to_string();
        let o = coif(root)
            .args([
                "synth", "--out", &out, "--style", s, "--size", "128", "--seed", &seed,
            ])
            .output()
            .unwrap();
        ok(o, "synth");
    }
}

pub fn write_manifest(dir: &Path, lines: &[String]) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let p = dir.join("jobs.jsonl");
    std::fs::write(&p, lines.join("\n") + "\n").unwrap();
    p
}

pub fn read_json(p: &Path) -> Value {
    let t = std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    serde_json::from_str(&t).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Every file under `dir`, by relative path.
pub fn files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(root: &Path, d: &Path, m: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, m);
            } else {
                m.insert(
                    p.strip_prefix(root).unwrap().into(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    let mut m = BTreeMap::new();
    walk(dir, dir, &mut m);
    m
}

/// A job report's JSON without its wall-clock times (every key named "seconds").
pub fn without_seconds(v: &mut Value) {
    match v {
        Value::Object(o) => {
            o.remove("seconds");
            o.values_mut().for_each(without_seconds);
        }
        Value::Array(a) => a.iter_mut().for_each(without_seconds),
        _ => {}
    }
}

/// Two output trees hold the same files; all byte for byte except the reports' JSON,
/// which must agree once their "seconds" are removed. Returns the number of files and of
/// those compared byte for byte.
pub fn same_files(a: &Path, b: &Path) -> (usize, usize) {
    let (fa, fb) = (files(a), files(b));
    let names = |m: &BTreeMap<PathBuf, Vec<u8>>| m.keys().cloned().collect::<Vec<_>>();
    assert_eq!(names(&fa), names(&fb), "{} vs {}", a.display(), b.display());
    let mut raw = 0;
    for (name, bytes) in &fa {
        let other = &fb[name];
        let is_report = name.extension().is_some_and(|e| e == "json")
            && name.file_name().unwrap() != ".coif-job.json";
        if is_report {
            let mut x: Value = serde_json::from_slice(bytes).unwrap();
            let mut y: Value = serde_json::from_slice(other).unwrap();
            without_seconds(&mut x);
            without_seconds(&mut y);
            assert_eq!(x, y, "{} differs beyond its timings", name.display());
        } else {
            raw += 1;
            assert!(
                bytes == other,
                "{} differs between {} and {}",
                name.display(),
                a.display(),
                b.display()
            );
        }
    }
    (fa.len(), raw)
}

/// [`same_files`] of two batch output trees, which hold at least 20 data files.
pub fn same_outputs(a: &Path, b: &Path) -> usize {
    let (n, raw) = same_files(a, b);
    assert!(raw >= 20, "only {raw} data files compared");
    n
}

pub fn statuses(summary: &Value) -> BTreeMap<String, String> {
    summary["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| {
            (
                j["id"].as_str().unwrap().to_string(),
                j["status"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

pub fn wait(c: Child, what: &str) -> Output {
    ok(c.wait_with_output().unwrap(), what)
}
