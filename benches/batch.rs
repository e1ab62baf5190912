//! Batch throughput (issue 18): jobs per hour for `coif batch` on a manifest of the embedded
//! cases (the synthetic styles of `coif synth` and the embedded astronaut photo), against the
//! peer: the same jobs as separate `coif` processes (one per step) under GNU parallel,
//! measured in the same run. Prints jobs per hour for each, the ratio batch / peer, and
//! whether the two wrote identical data files.
//!
//! Run: `cargo bench --bench batch`. The peer needs GNU parallel (`apt-get install parallel`;
//! without it the peer is skipped with a message). Knobs: COIF_BENCH_SIZE (256, synthetic
//! image side), COIF_BENCH_STYLES ("long,sidepart,whorl,short,fringe"), COIF_BENCH_ASTRONAUT
//! (1; 0 leaves the 512² photo out), COIF_BENCH_REPEAT (1: copies of every job, for bigger
//! runs), COIF_BENCH_STEPS ("model,render"; any of orient, analyze, model, render, sketch,
//! synth-hair), COIF_BENCH_BACKEND (cpu), COIF_BENCH_JOBS (2: the batch's --jobs),
//! COIF_BENCH_PARALLEL (2: parallel's -j), COIF_BENCH_ROUNDS (1: rounds of batch then peer;
//! each side's fastest is kept).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

const COIF: &str = env!("CARGO_BIN_EXE_coif");

fn env(k: &str, d: &str) -> String {
    std::env::var(k).unwrap_or_else(|_| d.to_string())
}

fn num(k: &str, d: usize) -> usize {
    let v = env(k, &d.to_string());
    v.parse()
        .unwrap_or_else(|_| panic!("{k}={v}: expected a whole number"))
}

/// One case's input files, relative to the bench folder.
struct Case {
    name: String,
    image: String,
    strokes: String,
    mask: Option<String>,
    landmarks: Option<String>,
}

fn run(cmd: &mut Command, what: &str) {
    let o = cmd.output().unwrap_or_else(|e| panic!("{what}: {e}"));
    assert!(
        o.status.success(),
        "{what} failed ({:?}):\n{}{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

fn cases(root: &Path, size: usize, styles: &str, astronaut: bool) -> Vec<Case> {
    let mut out = Vec::new();
    for style in styles.split(',').filter(|s| !s.is_empty()) {
        let dir = format!("cases/{style}");
        run(
            Command::new(COIF).current_dir(root).args([
                "synth",
                "--style",
                style,
                "--size",
                &size.to_string(),
                "--seed",
                "1",
                "--out",
                &dir,
            ]),
            &format!("coif synth --style {style}"),
        );
        out.push(Case {
            name: style.to_string(),
            image: format!("{dir}/image.png"),
            strokes: format!("{dir}/strokes.json"),
            mask: Some(format!("{dir}/mask.png")),
            landmarks: Some(format!("{dir}/landmarks.json")),
        });
    }
    if astronaut {
        let dir = root.join("cases/astronaut");
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("image.png"), coif::io::assets::ASTRONAUT_PNG).unwrap();
        std::fs::write(
            dir.join("strokes.json"),
            coif::io::assets::ASTRONAUT_STROKES,
        )
        .unwrap();
        // No mask or landmarks: segmented from the strokes, head placed from the image.
        out.push(Case {
            name: "astronaut".into(),
            image: "cases/astronaut/image.png".into(),
            strokes: "cases/astronaut/strokes.json".into(),
            mask: None,
            landmarks: None,
        });
    }
    out
}

/// The manifest line of a job.
fn manifest_line(id: &str, c: &Case, out: &str, steps: &[&str]) -> String {
    let mut v = serde_json::json!({
        "id": id, "image": c.image, "strokes": c.strokes, "out": out, "steps": steps,
    });
    if let Some(m) = &c.mask {
        v["mask"] = m.as_str().into();
    }
    if let Some(l) = &c.landmarks {
        v["landmarks"] = l.as_str().into();
    }
    v.to_string()
}

/// The same job as one shell line of `coif` commands, a step each, as `coif batch` lays out
/// its outputs (see `coif batch --help`).
fn shell_line(c: &Case, out: &str, steps: &[&str], backend: &str) -> String {
    let mut cmds = Vec::new();
    for s in steps {
        let mut a: Vec<String> = vec![COIF.into(), s.to_string()];
        let mut arg = |k: &str, v: &str| {
            a.push(k.into());
            a.push(v.into());
        };
        match *s {
            "orient" => {
                arg("--image", &c.image);
                if let Some(m) = &c.mask {
                    arg("--mask", m);
                }
                arg("--out", &format!("{out}/orient"));
            }
            "analyze" | "model" => {
                arg("--image", &c.image);
                arg("--strokes", &c.strokes);
                if let Some(m) = &c.mask {
                    arg("--mask", m);
                }
                if *s == "model" {
                    if let Some(l) = &c.landmarks {
                        arg("--landmarks", l);
                    }
                }
                arg("--out", &format!("{out}/{s}"));
            }
            "render" => {
                arg("--model", &format!("{out}/model"));
                arg("--out", &format!("{out}/render.png"));
            }
            "sketch" => {
                arg("--image", &c.image);
                match &c.mask {
                    Some(m) => arg("--mask", m),
                    None => arg("--strokes", &c.strokes),
                }
                arg("--out", &format!("{out}/sketch"));
            }
            "synth-hair" => {
                arg("--sketch", &format!("{out}/sketch/hair.czs"));
                arg("--out", &format!("{out}/synth-hair.png"));
            }
            other => panic!("COIF_BENCH_STEPS: unknown step {other:?}"),
        }
        arg("--backend", backend);
        cmds.push(a.join(" "));
    }
    format!("mkdir -p {out} && {}", cmds.join(" && "))
}

/// Every data file under `dir` (relative path, bytes): JSON files left out.
fn files(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut v = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_none_or(|e| e != "json") {
                // JSON reports hold timings and their own paths, which differ by nature.
                v.push((
                    p.strip_prefix(dir).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    v.sort();
    v
}

fn has_parallel() -> bool {
    Command::new("parallel")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

fn main() {
    let size = num("COIF_BENCH_SIZE", 256);
    let styles = env("COIF_BENCH_STYLES", "long,sidepart,whorl,short,fringe");
    let astronaut = num("COIF_BENCH_ASTRONAUT", 1) != 0;
    let repeat = num("COIF_BENCH_REPEAT", 1).max(1);
    let steps_s = env("COIF_BENCH_STEPS", "model,render");
    let steps: Vec<&str> = steps_s.split(',').filter(|s| !s.is_empty()).collect();
    let backend = env("COIF_BENCH_BACKEND", "cpu");
    // 0 is passed on, for coif to refuse: the bench measures what the user would type.
    let jobs = num("COIF_BENCH_JOBS", 2);
    let pj = num("COIF_BENCH_PARALLEL", 2).max(1);
    let rounds = num("COIF_BENCH_ROUNDS", 1).max(1);

    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let cases = cases(root, size, &styles, astronaut);
    let mut manifest = String::new();
    let mut shell = String::new();
    let mut ids = Vec::new();
    for r in 0..repeat {
        for c in &cases {
            let id = format!("{}-{r}", c.name);
            manifest.push_str(&manifest_line(&id, c, &format!("batch/{id}"), &steps));
            manifest.push('\n');
            shell.push_str(&shell_line(c, &format!("peer/{id}"), &steps, &backend));
            shell.push('\n');
            ids.push(id);
        }
    }
    std::fs::write(root.join("jobs.jsonl"), &manifest).unwrap();
    std::fs::write(root.join("jobs.sh"), &shell).unwrap();
    let n = ids.len();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!(
        "batch throughput: {n} jobs ({} synthetic at {size}²{}, x{repeat}), steps {}, \
         backend {backend}, batch --jobs {jobs}, {cores} cores, best of {rounds} round(s)",
        cases.len() - astronaut as usize,
        if astronaut { " + astronaut 512²" } else { "" },
        steps.join("+"),
    );

    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "  load average before: {}",
        load.split(' ').take(3).collect::<Vec<_>>().join(" ")
    );
    let parallel = has_parallel();
    if !parallel {
        println!(
            "  peer skipped: GNU parallel is not installed (apt-get install parallel); no ratio"
        );
    }
    // Rounds alternate batch and peer, and each side keeps its fastest round: on a shared
    // machine the least disturbed run is the one that says most.
    let (mut batch_s, mut peer_s) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..rounds {
        for d in ["batch", "peer"] {
            let _ = std::fs::remove_dir_all(root.join(d));
        }
        let t = Instant::now();
        run(
            Command::new(COIF).current_dir(root).args([
                "batch",
                "jobs.jsonl",
                "--backend",
                &backend,
                "--jobs",
                &jobs.to_string(),
            ]),
            "coif batch",
        );
        batch_s = batch_s.min(t.elapsed().as_secs_f64());
        if parallel {
            let t = Instant::now();
            run(
                Command::new("parallel")
                    .current_dir(root)
                    .args(["--will-cite", "--halt", "now,fail=1", "-j", &pj.to_string()])
                    .stdin(std::fs::File::open(root.join("jobs.sh")).unwrap()),
                "GNU parallel",
            );
            peer_s = peer_s.min(t.elapsed().as_secs_f64());
        }
    }
    let per_hour = |s: f64| n as f64 * 3600.0 / s;
    println!(
        "  coif batch --jobs {jobs:<3} (one process)       {batch_s:8.1} s  {:8.0} jobs/hour",
        per_hour(batch_s)
    );
    if !parallel {
        return;
    }
    println!(
        "  peer: coif per step under parallel -j{pj}    {peer_s:8.1} s  {:8.0} jobs/hour",
        per_hour(peer_s)
    );
    println!(
        "  ratio batch / peer (jobs per hour)         {:8.2}",
        peer_s / batch_s
    );
    // Files that differ between the two runs, job by job (a missing one counts).
    let mut differ = Vec::new();
    for id in &ids {
        let (a, b) = (
            files(&root.join("batch").join(id)),
            files(&root.join("peer").join(id)),
        );
        let names: std::collections::BTreeSet<&PathBuf> =
            a.iter().chain(&b).map(|f| &f.0).collect();
        for name in names {
            let find =
                |v: &[(PathBuf, Vec<u8>)]| v.iter().find(|f| &f.0 == name).map(|f| f.1.clone());
            if find(&a) != find(&b) {
                differ.push(format!("{id}/{}", name.display()));
            }
        }
    }
    match differ.is_empty() {
        true => {
            println!("  outputs: identical data files (JSON reports not compared) for all {n} jobs")
        }
        false => println!(
            "  outputs: {} files differ: {}",
            differ.len(),
            differ.join(", ")
        ),
    }
}
