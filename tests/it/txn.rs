//! Runs as units, as real processes of `coif`: a failing or interrupted run leaves its output
//! folder byte for byte as it was and no temporaries; a second run into a folder being
//! written is refused; SIGTERM and SIGINT stop a run with 143 and 130; temporaries of dead
//! runs are removed; a batch stopped by SIGTERM and resumed gives the uninterrupted run's
//! files; output paths that are inputs or of the wrong kind are refused before work.

use crate::common;

use common::procs::*;
use common::{fails, stderr};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A synthetic 128² case `<root>/<name>`.
fn case(root: &Path, name: &str, style: &str, seed: u32) {
    let o = coif(root)
        .args(["synth", "--out", name, "--style", style, "--size", "128"])
        .args(["--seed", &seed.to_string()])
        .output()
        .unwrap();
    ok(o, "synth");
}

/// `coif model` of the case `c` into `out`, small and on the cpu backend (about 1-2 s),
/// its output captured.
fn model(root: &Path, c: &str, out: &str) -> Command {
    let mut cmd = coif(root);
    cmd.stdout(Stdio::piped()).stderr(Stdio::piped());
    cmd.args([
        "model",
        "--backend",
        "cpu",
        "--roots",
        "3000",
        "--cells",
        "40",
    ])
    .args(["--image", &format!("{c}/image.png")])
    .args(["--strokes", &format!("{c}/strokes.json")])
    .args(["--mask", &format!("{c}/mask.png")])
    .args(["--landmarks", &format!("{c}/landmarks.json"), "--out", out]);
    cmd
}

/// Every coif temporary under `dir` (hidden entries included): temporary folders, lock
/// files, `write_atomic`'s `.coif-*.tmp` files.
fn temporaries(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            if n.contains(".coif-tmp-")
                || n.ends_with(".coif-lock")
                || (n.starts_with(".coif-") && n.ends_with(".tmp"))
            {
                found.push(e.path());
            }
            if e.file_type().unwrap().is_dir() {
                stack.push(e.path());
            }
        }
    }
    found
}

/// Waits until a run has made its temporary folder for `out` (it holds the lock and is
/// working), or panics after a minute.
fn wait_for_tmp(out: &Path, child: &mut Child) {
    let name = format!(".{}.coif-tmp-", out.file_name().unwrap().to_string_lossy());
    let t = Instant::now();
    loop {
        let there = std::fs::read_dir(out.parent().unwrap())
            .unwrap()
            .flatten()
            .any(|e| e.file_name().to_string_lossy().starts_with(&name));
        if there {
            return;
        }
        if let Some(s) = child.try_wait().unwrap() {
            panic!("the run ended ({s}) before its temporary folder was seen");
        }
        assert!(t.elapsed() < Duration::from_secs(60), "no temporary folder");
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn signal(child: &Child, sig: &str) {
    let s = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(s.success());
}

/// A pid that no process has: one of a child that has ended.
fn dead_pid() -> u32 {
    let mut c = Command::new("true").spawn().unwrap();
    let pid = c.id();
    c.wait().unwrap();
    pid
}

// Defect (issue 18): `coif model` wrote the analysis, then failed writing the strands, and
// left the new `curves.json` and `direction.npy` beside the old `strands.hair`. Here the
// write fails by a file size limit (EFBIG: strands.hair is the largest file, written after
// the analysis), and --cells 0 fails before work.
#[test]
fn a_model_run_that_fails_leaves_the_old_folder_byte_identical() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    case(root, "a", "long", 1);
    case(root, "b", "sidepart", 2);
    ok(model(root, "a", "m").output().unwrap(), "model a");
    let before = files(&root.join("m"));
    let hair = before[Path::new("strands.hair")].len();
    let npy = before[Path::new("direction.npy")].len();
    assert!(
        hair > 2 * npy,
        "strands.hair {hair} B, direction.npy {npy} B"
    );
    // A limit between the analysis files and the strands; SIGXFSZ ignored, so the write
    // fails with EFBIG instead of killing the process.
    let limit_kib = (npy + hair) / 2048;
    let cmd = model(root, "b", "m");
    let args: Vec<String> = cmd
        .get_args()
        .map(|a| format!("'{}'", a.to_string_lossy()))
        .collect();
    let o = Command::new("bash")
        .current_dir(root)
        .arg("-c")
        .arg(format!(
            "trap '' XFSZ; ulimit -f {limit_kib}; exec '{}' {}",
            env!("CARGO_BIN_EXE_coif"),
            args.join(" ")
        ))
        .output()
        .unwrap();
    fails(&o, 74, &["File too large"]);
    assert!(files(&root.join("m")) == before, "the old folder changed");
    let o = model(root, "b", "m")
        .args(["--cells", "0"])
        .output()
        .unwrap();
    assert!(!o.status.success(), "--cells 0: {}", stderr(&o));
    assert!(files(&root.join("m")) == before, "the old folder changed");
    assert_eq!(temporaries(root), Vec::<PathBuf>::new());
}

// Defect (issue 18): two runs into one --out mixed their files (1 in 20 trials, both rc 0).
#[test]
fn a_second_run_into_a_folder_being_written_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    case(root, "a", "long", 1);
    case(root, "b", "fringe", 2);
    let mut first = model(root, "a", "m").spawn().unwrap();
    wait_for_tmp(&root.join("m"), &mut first);
    let second = model(root, "b", "m").output().unwrap();
    fails(
        &second,
        75,
        &["m: another coif run", "is writing this folder"],
    );
    let first = first.wait_with_output().unwrap();
    assert!(first.status.success(), "{}", stderr(&first));
    // The first run's files are complete and its own: the same as it alone writes them.
    ok(model(root, "a", "alone").output().unwrap(), "model alone");
    let (n, raw) = same_files(&root.join("alone"), &root.join("m"));
    assert!(raw >= 8, "only {raw} data files compared");
    assert_eq!(temporaries(root), Vec::<PathBuf>::new());
    println!("a second run into the folder refused (exit 75); the first's {n} files complete");
}

// Defect (issue 18): SIGTERM ended a run mid-write (no exit code of its own) and left
// hidden `.coif-*.tmp` files.
#[test]
fn sigterm_and_sigint_stop_a_run_with_143_and_130_and_no_temporaries() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    case(root, "a", "long", 1);
    case(root, "b", "fringe", 2);
    ok(model(root, "a", "m").output().unwrap(), "model a");
    let before = files(&root.join("m"));
    for (sig, code, name) in [("-TERM", 143, "SIGTERM"), ("-INT", 130, "SIGINT")] {
        let mut c = model(root, "b", "m").spawn().unwrap();
        wait_for_tmp(&root.join("m"), &mut c);
        signal(&c, sig);
        let o = c.wait_with_output().unwrap();
        fails(&o, code, &[&format!("interrupted by {name}")]);
        assert!(
            files(&root.join("m")) == before,
            "{name}: the old folder changed"
        );
        assert_eq!(temporaries(root), Vec::<PathBuf>::new(), "{name}");
    }
    // Into a new folder: nothing is left, not even the folder.
    let mut c = model(root, "b", "new").spawn().unwrap();
    wait_for_tmp(&root.join("new"), &mut c);
    signal(&c, "-TERM");
    fails(&c.wait_with_output().unwrap(), 143, &["SIGTERM"]);
    assert!(!root.join("new").exists());
    assert_eq!(temporaries(root), Vec::<PathBuf>::new());
}

// Defect (issue 18): temporaries of killed runs stayed forever. A run killed with SIGKILL
// (no handler runs) leaves its temporary folder; the next run into that folder removes it
// and `write_atomic` files of dead runs, and keeps a live run's.
#[test]
fn temporaries_of_dead_runs_are_removed_by_the_next_run() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    case(root, "a", "long", 1);
    ok(model(root, "a", "m").output().unwrap(), "model a");
    let mut c = model(root, "a", "m").spawn().unwrap();
    wait_for_tmp(&root.join("m"), &mut c);
    signal(&c, "-KILL");
    c.wait().unwrap();
    let dead = dead_pid();
    std::fs::write(root.join(format!("m/.coif-{dead}-Ab12Cd.tmp")), b"half").unwrap();
    std::fs::write(root.join(format!(".coif-{dead}-Ef34Gh.tmp")), b"half").unwrap();
    let mut live = Command::new("sleep").arg("60").spawn().unwrap();
    let live_tmp = root.join(format!(".m.coif-tmp-{}", live.id()));
    std::fs::create_dir(&live_tmp).unwrap();
    // The killed run's folder and lock file, two files of a dead run, a live run's folder.
    let left = temporaries(root);
    assert_eq!(left.len(), 5, "{left:?}");
    // A run into m: its lock file and temporary are its own and gone when it ends.
    ok(model(root, "a", "m").output().unwrap(), "model a again");
    live.kill().unwrap();
    live.wait().unwrap();
    assert_eq!(temporaries(root), vec![live_tmp]);
}

/// Eight jobs over four cases: an orientation and a model with its render per case.
fn acceptance_manifest(cases: &[&str]) -> Vec<String> {
    let mut v = Vec::new();
    for s in cases {
        let c = format!("../{s}");
        v.push(format!(
            r#"{{"id": "{s}-orient", "image": "{c}/image.png", "mask": "{c}/mask.png", "out": "out/{s}-orient", "steps": ["orient"]}}"#
        ));
        v.push(format!(
            r#"{{"id": "{s}-model", "image": "{c}/image.png", "strokes": "{c}/strokes.json", "mask": "{c}/mask.png", "landmarks": "{c}/landmarks.json", "out": "out/{s}-model", "steps": ["model", "render"], "model": {{"roots": 2000, "cells": 30}}, "render": {{"yaw": 20}}}}"#
        ));
    }
    v
}

fn records(out: &Path) -> usize {
    std::fs::read_dir(out).map_or(0, |rd| {
        rd.flatten()
            .filter(|e| e.path().join(".coif-job.json").is_file())
            .count()
    })
}

// Acceptance (issue 18): a batch killed with SIGTERM half-way and resumed gives the
// uninterrupted run's outputs with no temporary files left. Before: SIGTERM ended the batch
// at once, with no summary and a job's folder half-written.
#[test]
fn a_batch_stopped_by_sigterm_and_resumed_gives_the_uninterrupted_outputs() {
    let t0 = Instant::now();
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    // Styles whose synthetic strokes include direction strokes at 128².
    let styles = [("long", 1), ("sidepart", 2), ("fringe", 3), ("long", 4)];
    let names: Vec<String> = styles.iter().map(|(s, k)| format!("{s}{k}")).collect();
    for ((s, k), name) in styles.iter().zip(&names) {
        case(root, name, s, *k);
    }
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let lines = acceptance_manifest(&names);
    assert_eq!(lines.len(), 8);
    let (whole, stopped) = (root.join("whole"), root.join("stopped"));
    write_manifest(&whole, &lines);
    write_manifest(&stopped, &lines);
    let batch = |dir: &Path| {
        let mut c = coif(dir);
        c.args(["batch", "jobs.jsonl", "--backend", "cpu"]);
        c
    };
    let reference = batch(&whole).spawn().unwrap();
    let mut c = batch(&stopped)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Half-way: three jobs done.
    while records(&stopped.join("out")) < 3 {
        assert!(c.try_wait().unwrap().is_none(), "the batch ended early");
        std::thread::sleep(Duration::from_millis(20));
    }
    signal(&c, "-TERM");
    let o = c.wait_with_output().unwrap();
    fails(&o, 143, &["interrupted by SIGTERM", "--resume"]);
    let s = read_json(&stopped.join("jobs.jsonl.summary.json"));
    assert_eq!(s["exit_code"], 143);
    assert_eq!(s["interrupted"], "SIGTERM");
    let st = statuses(&s);
    assert_eq!(st.len(), 8, "{st:?}");
    let count = |v: &str| st.values().filter(|s| *s == v).count();
    let (done, not_run) = (count("ok"), count("not-run"));
    assert!(done >= 3 && not_run >= 1, "{st:?}");
    assert_eq!(done + not_run + count("interrupted"), 8, "{st:?}");
    assert_eq!(temporaries(&stopped), Vec::<PathBuf>::new());
    // Resumed: the finished jobs skipped, the rest run.
    let o = ok(batch(&stopped).arg("--resume").output().unwrap(), "resume");
    let resumed = statuses(&read_json(&stopped.join("jobs.jsonl.summary.json")));
    let want: BTreeMap<String, String> = st
        .iter()
        .map(|(k, v)| (k.clone(), if v == "ok" { "skipped" } else { "ok" }.into()))
        .collect();
    assert_eq!(resumed, want, "{}", String::from_utf8_lossy(&o.stdout));
    wait(reference, "uninterrupted batch");
    let n = same_outputs(&whole.join("out"), &stopped.join("out"));
    assert_eq!(temporaries(root), Vec::<PathBuf>::new());
    println!(
        "8 jobs (4 cases × orient, model + render; 128², cpu): SIGTERM after {done} done, \
         {not_run} not run, exit 143; --resume ran the rest; {n} files identical to the \
         uninterrupted run, no temporaries: {:.1} s",
        t0.elapsed().as_secs_f64()
    );
}

// Defect (issue 18, Deliver 2): output paths that are inputs or of the wrong kind were
// accepted: `convert a.hair a.hair` rewrote its input, `export --to` a folder and
// `orient --out image.png` failed only after the work, `sketch-convert` could overwrite
// the sketch it read.
#[test]
fn output_paths_that_are_inputs_or_of_the_wrong_kind_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    std::fs::copy(data.join("strands/Bangs_100.hair"), root.join("a.hair")).unwrap();
    std::fs::copy(data.join("sketch/inkscape/written.svg"), root.join("s.svg")).unwrap();
    case(root, "c", "long", 1);
    ok(
        coif(root)
            .args(["import", "a.hair", "--out", "m"])
            .output()
            .unwrap(),
        "import",
    );
    let snapshot = || {
        let mut m = files(root);
        m.retain(|p, _| !p.starts_with("out"));
        m
    };
    let before = snapshot();
    let run = |args: &[&str]| coif(root).args(args).output().unwrap();
    fails(
        &run(&["convert", "a.hair", "a.hair"]),
        64,
        &["overwrite the input"],
    );
    fails(
        &run(&["convert", "a.hair", "./m/../a.hair"]),
        64,
        &["overwrite"],
    );
    fails(&run(&["convert", "a.hair", "m"]), 64, &["is a folder"]);
    fails(
        &run(&["export", "--model", "m", "--to", "m/strands.hair"]),
        64,
        &["overwrite"],
    );
    fails(
        &run(&["export", "--model", "m", "--to", "m"]),
        64,
        &["is a folder"],
    );
    fails(
        &run(&["export", "--model", "m", "--to", "no/x.obj"]),
        74,
        &["does not exist"],
    );
    fails(
        &run(&["sketch-convert", "--sketch", "s.svg", "--out", "s.svg"]),
        64,
        &["overwrite the input"],
    );
    let orient = [
        "orient",
        "--backend",
        "cpu",
        "--image",
        "c/image.png",
        "--out",
        "c/image.png",
    ];
    fails(&run(&orient), 64, &["exists and is not a folder"]);
    fails(
        &run(&["import", "a.hair", "--out", "a.hair"]),
        64,
        &["not a folder"],
    );
    fails(&run(&["synth", "--out", "s.svg"]), 64, &["not a folder"]);
    assert!(snapshot() == before, "a refused run changed a file");
    // Beside the inputs, and a model folder rewritten in place, are fine.
    ok(run(&["convert", "a.hair", "m/a.obj"]), "convert");
    ok(run(&["import", "m/a.obj", "--out", "m"]), "import in place");
    assert_eq!(temporaries(root), Vec::<PathBuf>::new());
}
