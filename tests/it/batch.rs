//! `coif batch` as real processes: shards run at once give the unsharded run's files, a bad
//! job is reported while the others complete, `--resume` skips exactly the matching jobs,
//! manifest errors name the line and key before any job runs, and `--jobs 2` gives the
//! files and summary of jobs run in turn.

use crate::common;

use common::procs::*;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

/// Per case: orientation; directed hair; a sketch and the hair synthesised back from it.
fn manifest_lines(styles: &[&str]) -> Vec<String> {
    let mut v = vec!["# three jobs per case".to_string(), String::new()];
    for s in styles {
        let c = format!("../cases/{s}");
        v.push(format!(
            r#"{{"id": "{s}-orient", "image": "{c}/image.png", "mask": "{c}/mask.png", "out": "out/{s}-orient", "steps": ["orient"]}}"#
        ));
        v.push(format!(
            r#"{{"id": "{s}-analyze", "image": "{c}/image.png", "strokes": "{c}/strokes.json", "mask": "{c}/mask.png", "out": "out/{s}-analyze", "steps": ["analyze"], "analyze": {{"radius": 6}}}}"#
        ));
        v.push(format!(
            r#"{{"id": "{s}-sketch", "image": "{c}/image.png", "mask": "{c}/mask.png", "out": "out/{s}-sketch", "steps": ["sketch", "synth-hair"], "sketch": {{"sweeps": 100, "bases": 4}}, "synth-hair": {{"seed": 3, "rounds": 2}}}}"#
        ));
    }
    v
}

#[test]
fn shards_run_at_once_give_the_unsharded_outputs() {
    let t0 = Instant::now();
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let styles = ["long", "sidepart", "fringe"];
    cases(root, &styles);
    let lines = manifest_lines(&styles);
    let ids: Vec<String> = lines
        .iter()
        .filter(|l| l.starts_with('{'))
        .map(|l| {
            serde_json::from_str::<Value>(l).unwrap()["id"]
                .as_str()
                .unwrap()
                .into()
        })
        .collect();
    assert_eq!(ids.len(), 9);
    let (one, two, three) = (root.join("one"), root.join("two"), root.join("three"));
    for d in [&one, &two, &three] {
        write_manifest(d, &lines);
    }
    // Six processes at once, as GNU parallel would start them: the unsharded run, two
    // shards, three shards (one from --shard, one from Slurm's variables, one from a
    // Kubernetes Indexed Job's).
    let batch = |dir: &Path| {
        let mut c = coif(dir);
        c.args(["batch", "jobs.jsonl", "--backend", "cpu"]);
        c
    };
    let mut procs = vec![("unsharded", batch(&one).spawn().unwrap())];
    for i in 0..2 {
        let s = format!("{i}/2");
        procs.push((
            "2 shards",
            batch(&two).args(["--shard", &s]).spawn().unwrap(),
        ));
    }
    procs.push((
        "3 shards",
        batch(&three).args(["--shard", "0/3"]).spawn().unwrap(),
    ));
    let slurm = batch(&three)
        .env("SLURM_ARRAY_TASK_ID", "2")
        .env("SLURM_ARRAY_TASK_MIN", "1")
        .env("SLURM_ARRAY_TASK_MAX", "3")
        .spawn()
        .unwrap();
    procs.push(("3 shards, Slurm", slurm));
    let k8s = batch(&three)
        .env("JOB_COMPLETION_INDEX", "2")
        .env("COIF_SHARDS", "3")
        .spawn()
        .unwrap();
    procs.push(("3 shards, k8s", k8s));
    for (what, p) in procs {
        wait(p, what);
    }
    let secs = t0.elapsed().as_secs_f64();
    // Each shard ran exactly the jobs k ≡ I (mod N).
    for (dir, n) in [(&one, 1), (&two, 2), (&three, 3)] {
        let mut seen = Vec::new();
        for i in 0..n {
            let name = if n == 1 {
                "jobs.jsonl.summary.json".to_string()
            } else {
                format!("jobs.jsonl.shard-{i}-of-{n}.summary.json")
            };
            let s = read_json(&dir.join(name));
            assert_eq!(s["exit_code"], 0);
            assert_eq!(s["shard"]["index"], i);
            assert_eq!(s["shard"]["count"], n);
            let st = statuses(&s);
            assert!(st.values().all(|v| v == "ok"), "{st:?}");
            let want: Vec<&String> = ids.iter().skip(i).step_by(n).collect();
            let got: Vec<&String> = s["jobs"]
                .as_array()
                .unwrap()
                .iter()
                .map(|j| {
                    ids.iter()
                        .find(|id| *id == j["id"].as_str().unwrap())
                        .unwrap()
                })
                .collect();
            assert_eq!(got, want, "shard {i}/{n}");
            seen.extend(got);
        }
        assert_eq!(seen.len(), 9);
    }
    let n2 = same_outputs(&one.join("out"), &two.join("out"));
    let n3 = same_outputs(&one.join("out"), &three.join("out"));
    assert_eq!(n2, n3);
    // Every job left its record.
    for id in &ids {
        assert!(
            one.join("out").join(id).join(".coif-job.json").is_file(),
            "{id}"
        );
    }
    println!(
        "9 jobs (3 cases × orient, analyze, sketch + synth-hair, 128², cpu) unsharded, as 2 and \
         as 3 shards, 6 processes at once: {secs:.1} s; {n2} files identical (reports less their \
         seconds)"
    );
}

#[test]
fn a_bad_job_is_reported_and_the_others_complete() {
    let t0 = Instant::now();
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    cases(root, &["long", "whorl"]);
    // A mask of another size: the job's own step fails (65), after a missing image (74).
    std::fs::copy(
        root.join("cases/long/mask.png"),
        root.join("cases/small_mask.png"),
    )
    .unwrap();
    let o = coif(root)
        .args(["synth", "--out", "cases/s64", "--size", "64"])
        .output()
        .unwrap();
    ok(o, "synth 64");
    let lines = vec![
        r#"{"id": "good1", "image": "cases/long/image.png", "out": "out/good1", "steps": ["orient"]}"#.to_string(),
        r#"{"id": "missing", "image": "cases/nope.png", "out": "out/missing", "steps": ["orient"]}"#.to_string(),
        r#"{"id": "good2", "image": "cases/whorl/image.png", "mask": "cases/whorl/mask.png", "out": "out/good2", "steps": ["orient"]}"#.to_string(),
        r#"{"id": "mask-size", "image": "cases/long/image.png", "mask": "cases/s64/mask.png", "out": "out/mask-size", "steps": ["orient"]}"#.to_string(),
        r#"{"id": "good3", "image": "cases/whorl/image.png", "out": "out/good3", "steps": ["orient"]}"#.to_string(),
        r#"{"id": "model", "image": "cases/long/image.png", "strokes": "cases/long/strokes.json", "mask": "cases/long/mask.png", "landmarks": "cases/long/landmarks.json", "out": "out/model", "steps": ["model", "render"], "model": {"roots": 2000, "cells": 30}, "render": {"yaw": 25}}"#.to_string(),
    ];
    write_manifest(root, &lines);
    let o = coif(root)
        .args([
            "batch",
            "jobs.jsonl",
            "--backend",
            "cpu",
            "--summary",
            "report/summary.json",
        ])
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(74),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let s = read_json(&root.join("report/summary.json"));
    assert_eq!(s["exit_code"], 74);
    assert_eq!(s["counts"]["ok"], 4);
    assert_eq!(s["counts"]["failed"], 2);
    let jobs = s["jobs"].as_array().unwrap();
    let job = |id: &str| jobs.iter().find(|j| j["id"] == id).unwrap().clone();
    let missing = job("missing");
    assert_eq!(missing["status"], "failed");
    assert_eq!(missing["exit_code"], 74);
    assert_eq!(missing["line"], 2);
    assert!(
        missing["message"]
            .as_str()
            .unwrap()
            .contains("cases/nope.png"),
        "{missing}"
    );
    let size = job("mask-size");
    assert_eq!(size["status"], "failed");
    assert_eq!(size["exit_code"], 65);
    assert!(
        size["message"].as_str().unwrap().contains("mask.png"),
        "{size}"
    );
    for id in ["good1", "good2", "good3"] {
        assert_eq!(job(id)["status"], "ok");
        let out = root.join("out").join(id);
        assert!(out.join("orient/orientation.npy").is_file(), "{id}");
        assert!(out.join(".coif-job.json").is_file(), "{id}");
    }
    assert!(!root.join("out/mask-size/.coif-job.json").exists());
    // The model and render steps with their options from the manifest line.
    assert_eq!(job("model")["status"], "ok");
    let m = read_json(&root.join("out/model/model/model.json"));
    assert_eq!(m["params"]["roots"], 2000, "{}", m["params"]);
    assert_eq!(m["params"]["volume"]["cells"], 30, "{}", m["params"]);
    assert!(root.join("out/model/model/strands.hair").is_file());
    let r = read_json(&root.join("out/model/render.png.json"));
    assert_eq!(r["settings"]["yaw_deg"], 25.0);
    assert!(root.join("out/model/render.png").is_file());
    println!(
        "6 jobs (4 orient, model + render), 2 bad (exit 74 and 65), 4 completed, batch exit 74: {:.1} s",
        t0.elapsed().as_secs_f64()
    );
}

#[test]
fn resume_skips_exactly_the_jobs_whose_record_matches() {
    let t0 = Instant::now();
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let styles = ["long", "whorl", "short", "sidepart"];
    cases(root, &styles);
    let line = |s: &str, extra: &str| {
        format!(
            r#"{{"id": "{s}", "image": "cases/{s}/image.png", "mask": "cases/{s}/mask.png", "out": "out/{s}", "steps": ["orient"]{extra}}}"#
        )
    };
    let lines: Vec<String> = styles.iter().map(|s| line(s, "")).collect();
    write_manifest(root, &lines);
    let run = |resume: bool| {
        let mut c = coif(root);
        c.args(["batch", "jobs.jsonl", "--backend", "cpu"]);
        if resume {
            c.arg("--resume");
        }
        ok(c.output().unwrap(), "batch");
        statuses(&read_json(&root.join("jobs.jsonl.summary.json")))
    };
    let first = run(false);
    assert!(first.values().all(|s| s == "ok"), "{first:?}");
    let orientation = root.join("out/long/orient/orientation.npy");
    let before = std::fs::metadata(&orientation).unwrap().modified().unwrap();
    let again = run(true);
    assert!(again.values().all(|s| s == "skipped"), "{again:?}");
    assert_eq!(
        std::fs::metadata(&orientation).unwrap().modified().unwrap(),
        before
    );
    // Without --resume every job runs again.
    assert!(run(false).values().all(|s| s == "ok"));
    // One input changed, one job's parameters changed, one record from another version.
    std::fs::copy(
        root.join("cases/short/image.png"),
        root.join("cases/long/image.png"),
    )
    .unwrap();
    let mut lines = lines.clone();
    lines[1] = line("whorl", r#", "orient": {"smooth": 2}"#);
    write_manifest(root, &lines);
    let rec = root.join("out/short/.coif-job.json");
    let mut r = read_json(&rec);
    r["coif_version"] = "0.0.0".into();
    std::fs::write(&rec, serde_json::to_string(&r).unwrap()).unwrap();
    let third = run(true);
    let want: BTreeMap<String, String> = [
        ("long", "ok"),
        ("whorl", "ok"),
        ("short", "ok"),
        ("sidepart", "skipped"),
    ]
    .iter()
    .map(|(a, b)| (a.to_string(), b.to_string()))
    .collect();
    assert_eq!(third, want);
    // The re-run wrote the record of the new input.
    let r = read_json(&root.join("out/long/.coif-job.json"));
    let short = read_json(&root.join("out/short/.coif-job.json"));
    assert_eq!(r["inputs"]["image"], short["inputs"]["image"]);
    assert_eq!(short["coif_version"], env!("CARGO_PKG_VERSION"));
    assert!(run(true).values().all(|s| s == "skipped"));
    println!(
        "resume: 4 jobs run, 4 skipped, 3 re-run after changes (input, params, version), 4 \
         skipped: {:.1} s",
        t0.elapsed().as_secs_f64()
    );
}

#[test]
fn manifest_errors_name_the_line_and_key_before_any_job_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    cases(root, &["long"]);
    let good =
        r#"{"id": "a", "image": "cases/long/image.png", "out": "out/a", "steps": ["orient"]}"#;
    let cases: [(&str, &str, &[&str]); 9] = [
        (r#"{"id": "b", "image": "x.png""#, "line 3", &["EOF"]),
        (
            r#"{"id": "b", "image": "x.png", "out": "o", "steps": ["orient", "paint"]}"#,
            "line 3",
            &["unknown variant `paint`"],
        ),
        (good, "line 3", &["key `id`", "line 1"]),
        (
            r#"{"id": "b", "image": "x.png", "out": "o", "steps": ["orient"], "colour": 1}"#,
            "line 3",
            &["unknown field `colour`"],
        ),
        (
            r#"{"id": "b", "image": "x.png", "out": "o"}"#,
            "line 3",
            &["missing field `steps`"],
        ),
        (
            r#"{"id": "b", "image": "x.png", "out": "o", "steps": ["model"]}"#,
            "line 3",
            &["needs key `strokes`"],
        ),
        (
            r#"{"id": "b", "image": "x.png", "out": "o", "steps": ["orient"], "render": {"yaw": 2}}"#,
            "line 3",
            &["key `render`"],
        ),
        (
            r#"{"id": "b", "image": "x.png", "out": "o", "steps": ["orient"], "orient": {"sigma": 2}}"#,
            "line 3",
            &["unknown field `sigma`"],
        ),
        (
            r#"{"id": "b", "image": "x.png", "out": "out/a", "steps": ["orient"]}"#,
            "line 3",
            &["key `out`", "line 1"],
        ),
    ];
    for (bad, line, words) in cases {
        std::fs::write(
            root.join("jobs.jsonl"),
            format!("{good}\n# a comment\n{bad}\n"),
        )
        .unwrap();
        let o = coif(root)
            .args(["batch", "jobs.jsonl", "--backend", "cpu"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(65), "{bad}: {err}");
        assert!(
            err.contains(&format!("jobs.jsonl: {line}:")),
            "{bad}: {err}"
        );
        for w in words {
            assert!(err.contains(w), "{bad}: {w:?} not in {err}");
        }
        assert!(!root.join("out").exists(), "{bad}: a job ran");
        assert!(!root.join("jobs.jsonl.summary.json").exists(), "{bad}");
    }
    // Inconsistent shard variables are refused before any job runs (exit 64).
    std::fs::write(root.join("jobs.jsonl"), format!("{good}\n")).unwrap();
    let o = coif(root)
        .args(["batch", "jobs.jsonl", "--backend", "cpu"])
        .env("SLURM_ARRAY_TASK_ID", "4")
        .env("SLURM_ARRAY_TASK_COUNT", "4")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(64), "{err}");
    assert!(
        err.contains("shard index 4 is not below the count 4"),
        "{err}"
    );
    let o = coif(root)
        .args(["batch", "jobs.jsonl", "--backend", "cpu"])
        .env("JOB_COMPLETION_INDEX", "1")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(64));
    assert!(String::from_utf8_lossy(&o.stderr).contains("COIF_SHARDS"));
    assert!(!root.join("out").exists());
}

// `--jobs N` runs up to N jobs at once in one process: the same files, statuses, order and
// exit code as jobs run in turn, a failing job among them reported while the others
// complete, the memory budget divided between the jobs at once, and 0 or junk refused.
#[test]
fn jobs_at_once_give_the_files_and_summary_of_jobs_in_turn() {
    let t0 = Instant::now();
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let styles = ["long", "sidepart", "fringe"];
    cases(root, &styles);
    let mut lines = manifest_lines(&styles);
    // A missing image (74) early and a mask of another size (65) later: the batch exits
    // with the first in manifest order whichever ends first.
    lines.insert(
        3,
        r#"{"id": "missing", "image": "../cases/nope.png", "out": "out/missing", "steps": ["orient"]}"#.into(),
    );
    let o = coif(root)
        .args(["synth", "--out", "cases/s64", "--size", "64"])
        .output()
        .unwrap();
    ok(o, "synth 64");
    lines.push(
        r#"{"id": "mask-size", "image": "../cases/long/image.png", "mask": "../cases/s64/mask.png", "out": "out/mask-size", "steps": ["orient"]}"#.into(),
    );
    let (one, two) = (root.join("one"), root.join("two"));
    let run = |dir: &Path, jobs: &str| {
        write_manifest(dir, &lines);
        let o = coif(dir)
            .args(["batch", "jobs.jsonl", "--backend", "cpu", "--jobs", jobs])
            .output()
            .unwrap();
        assert_eq!(
            o.status.code(),
            Some(74),
            "--jobs {jobs}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        (read_json(&dir.join("jobs.jsonl.summary.json")), out)
    };
    let (s1, _) = run(&one, "1");
    let (s2, out2) = run(&two, "2");
    assert_eq!(s1["jobs_at_once"], 1);
    assert_eq!(s2["jobs_at_once"], 2);
    assert_eq!(s2["exit_code"], 74);
    assert_eq!(s2["counts"]["ok"], 9);
    assert_eq!(s2["counts"]["failed"], 2);
    // The same jobs in manifest order with the same outcomes.
    let outcome = |s: &Value| -> Vec<(Value, Value, Value, Value, Value)> {
        s["jobs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|j| {
                let f = |k: &str| j.get(k).cloned().unwrap_or(Value::Null);
                (
                    f("id"),
                    f("line"),
                    f("status"),
                    f("exit_code"),
                    f("message"),
                )
            })
            .collect()
    };
    assert_eq!(outcome(&s1), outcome(&s2));
    let code = |id: &str| outcome(&s2).into_iter().find(|o| o.0 == id).unwrap().3;
    assert_eq!(code("missing"), 74);
    assert_eq!(code("mask-size"), 65);
    // Every job's line printed, in whatever order they ended.
    for j in s2["jobs"].as_array().unwrap() {
        let id = j["id"].as_str().unwrap();
        assert!(
            out2.lines()
                .any(|l| l.split_whitespace().nth(1) == Some(id)),
            "{id} not in {out2}"
        );
        // Two jobs shared the process: its peak is not one job's.
        if j["status"] == "ok" {
            assert_eq!(j["timings"]["peak_rss_scope"], "process", "{j}");
            assert!(!j["timings"]["stages"].as_array().unwrap().is_empty());
        }
    }
    let n = same_outputs(&one.join("out"), &two.join("out"));
    // The failed job left no folder (it had none before).
    assert!(!two.join("out/mask-size").exists());

    // Each of 2 jobs at once gets half of --max-memory: 40 MiB holds one 128² orient
    // (about 24 MiB estimated) but not two.
    let budget = root.join("budget");
    write_manifest(
        &budget,
        &[
            r#"{"id": "a", "image": "../cases/long/image.png", "out": "out/a", "steps": ["orient"]}"#.into(),
            r#"{"id": "b", "image": "../cases/sidepart/image.png", "out": "out/b", "steps": ["orient"]}"#.into(),
        ],
    );
    let with = |jobs: &str| {
        coif(&budget)
            .args(["--max-memory", "40M", "batch", "jobs.jsonl"])
            .args(["--backend", "cpu", "--jobs", jobs])
            .output()
            .unwrap()
    };
    ok(with("1"), "batch --jobs 1 --max-memory 40M");
    let o = with("2");
    assert_eq!(o.status.code(), Some(65));
    let s = read_json(&budget.join("jobs.jsonl.summary.json"));
    for j in s["jobs"].as_array().unwrap() {
        let m = j["message"].as_str().unwrap_or_default();
        assert!(m.contains("20.0 MiB") && m.contains("--jobs 2"), "{j}");
    }

    // 0 and junk are usage errors, before any job runs.
    for bad in ["0", "two", "-1", ""] {
        let dir = root.join("refused");
        write_manifest(&dir, &lines);
        let o = coif(&dir)
            .args(["batch", "jobs.jsonl", "--backend", "cpu"])
            .arg(format!("--jobs={bad}"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(64), "--jobs {bad:?}: {err}");
        assert!(err.contains("--jobs"), "{err}");
        assert!(!dir.join("out").exists() && !dir.join("jobs.jsonl.summary.json").exists());
    }
    println!(
        "11 jobs (9 good, 2 bad) with --jobs 1 and --jobs 2: same statuses, order and exit \
         (74); {n} files identical; --max-memory 40M divided by --jobs 2; --jobs 0 refused: \
         {:.1} s",
        t0.elapsed().as_secs_f64()
    );
}

// A later step that fails on an earlier step's file names it in the job's folder, not in the
// job's temporary folder (whose name carries the process id and is gone after the run).
#[test]
fn a_failing_step_names_the_jobs_folder_not_its_temporary() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    cases(root, &["whorl"]);
    // The 128² whorl's sketch at λ_NC 40 has no curves (the fill target off, which would
    // lower λ_NC until it has), so synth-hair refuses the sketch step's file.
    let line = r#"{"id": "w", "image": "../cases/whorl/image.png", "mask": "../cases/whorl/mask.png", "out": "out/w", "steps": ["sketch", "synth-hair"], "sketch": {"sweeps": 100, "bases": 4, "target_fill": 0}}"#;
    let m = write_manifest(&root.join("m"), &[line.to_string()]);
    let o = coif(root)
        .args(["batch", "--backend", "cpu"])
        .arg(&m)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert_eq!(o.status.code(), Some(65), "{stdout}");
    let s = read_json(&root.join("m/jobs.jsonl.summary.json"));
    let msg = s["jobs"][0]["message"].as_str().unwrap();
    assert!(
        msg.contains("out/w/sketch/hair.czs") && !msg.contains("coif-tmp"),
        "{msg}"
    );
    assert!(
        stdout.contains("out/w/sketch/hair.czs") && !stdout.contains("coif-tmp"),
        "{stdout}"
    );
}
