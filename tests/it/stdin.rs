//! Inputs read once (issue 18, "Inputs are read twice, so `/dev/stdin` and process
//! substitution fail with a misleading message"): real `coif` processes given a pipe as
//! `/dev/stdin` or `/proc/self/fd/0` (what `<(...)` hands over as `/dev/fd/63`), checked
//! against the same run on the file. Each test's comment says how it failed before the fix.

use crate::common;

use common::{fails, stderr};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// Runs coif in `cwd` with `input` written to its stdin through a pipe.
fn coif_piped(cwd: &Path, args: &[&str], input: &[u8]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_coif"))
        .args(args)
        .current_dir(cwd)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("coif runs");
    let mut pipe = child.stdin.take().unwrap();
    let bytes = input.to_vec();
    // A writer thread: coif may not read everything (an error), and a full pipe must not
    // block the test.
    let writer = std::thread::spawn(move || {
        let _ = pipe.write_all(&bytes);
    });
    let out = child.wait_with_output().expect("coif finishes");
    writer.join().unwrap();
    out
}

fn coif(cwd: &Path, args: &[&str]) -> Output {
    coif_piped(cwd, args, b"")
}

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "rc {:?}: {}",
        o.status.code(),
        stderr(o)
    );
}

/// A 128² synthetic portrait (`coif synth`) in a temporary folder, under `case/`.
struct Case {
    dir: tempfile::TempDir,
}

impl Case {
    fn new() -> Self {
        let c = Case {
            dir: tempfile::tempdir().unwrap(),
        };
        ok(&coif(
            c.dir.path(),
            &["synth", "--size", "128", "--style", "long", "--out", "case"],
        ));
        c
    }
    fn root(&self) -> &Path {
        self.dir.path()
    }
    fn p(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }
    fn bytes(&self, name: &str) -> Vec<u8> {
        std::fs::read(self.p(name)).unwrap()
    }
}

fn orient_args<'a>(image: &'a str, out: &'a str) -> Vec<&'a str> {
    vec![
        "orient",
        "--image",
        image,
        "--mask",
        "case/mask.png",
        "--out",
        out,
        "--backend",
        "cpu",
    ]
}

/// Before: the image was read once for its size and again to decode, so the second read of
/// the pipe found nothing: rc 65, "cannot decode the image: The image format could not be
/// determined".
#[test]
fn orient_reads_the_image_from_a_pipe() {
    let c = Case::new();
    ok(&coif(c.root(), &orient_args("case/image.png", "file")));
    let png = c.bytes("case/image.png");
    for (path, out) in [("/dev/stdin", "stdin"), ("/proc/self/fd/0", "fd0")] {
        let o = coif_piped(c.root(), &orient_args(path, out), &png);
        ok(&o);
        for f in ["orientation.npy", "confidence.npy"] {
            assert_eq!(
                c.bytes(&format!("{out}/{f}")),
                c.bytes(&format!("file/{f}")),
                "{f} from {path} differs from the run on the file"
            );
        }
    }
}

/// Before: the mask went through the same two reads as the image: rc 65.
#[test]
fn orient_reads_the_mask_from_a_pipe() {
    let c = Case::new();
    ok(&coif(c.root(), &orient_args("case/image.png", "file")));
    let args = [
        "orient",
        "--image",
        "case/image.png",
        "--mask",
        "/proc/self/fd/0",
        "--out",
        "fd0",
        "--backend",
        "cpu",
    ];
    ok(&coif_piped(c.root(), &args, &c.bytes("case/mask.png")));
    assert_eq!(
        c.bytes("fd0/orientation.npy"),
        c.bytes("file/orientation.npy")
    );
}

fn analyze_args(strokes: &str, out: &str) -> Vec<String> {
    [
        "analyze",
        "--image",
        "case/image.png",
        "--mask",
        "case/mask.png",
        "--strokes",
        strokes,
        "--out",
        out,
        "--backend",
        "cpu",
    ]
    .map(String::from)
    .to_vec()
}

fn run_analyze(c: &Case, strokes: &str, out: &str, input: &[u8]) -> Output {
    let args = analyze_args(strokes, out);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    coif_piped(c.root(), &args, input)
}

/// Before: the strokes were read once to tell labelme from strokes.json and again to parse,
/// so the pipe read empty: rc 65, "malformed JSON: EOF while parsing a value".
#[test]
fn analyze_reads_strokes_json_from_a_pipe() {
    let c = Case::new();
    ok(&run_analyze(&c, "case/strokes.json", "file", b""));
    let json = c.bytes("case/strokes.json");
    for (path, out) in [("/dev/stdin", "stdin"), ("/proc/self/fd/0", "fd0")] {
        ok(&run_analyze(&c, path, out, &json));
        assert_eq!(
            c.bytes(&format!("{out}/direction.npy")),
            c.bytes("file/direction.npy"),
            "direction from {path} differs from the run on the file"
        );
    }
}

/// The synthetic strokes as an SVG drawing (polylines), for the stroke importer.
fn strokes_svg(c: &Case) -> String {
    let v: serde_json::Value = serde_json::from_slice(&c.bytes("case/strokes.json")).unwrap();
    let mut svg =
        String::from("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"128\" height=\"128\">\n");
    for s in v["strokes"].as_array().unwrap() {
        let pts: Vec<String> = s["points"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| format!("{},{}", p[0], p[1]))
            .collect();
        let class = if s["kind"] == "background" {
            " class=\"background\""
        } else {
            ""
        };
        svg.push_str(&format!(
            "<polyline{class} points=\"{}\"/>\n",
            pts.join(" ")
        ));
    }
    svg.push_str("</svg>\n");
    svg
}

/// A pipe has no extension, so an SVG drawing is told by its content. Before: it was read
/// as strokes.json after a first read had emptied the pipe: rc 65, "malformed JSON".
#[test]
fn analyze_reads_svg_strokes_from_a_pipe() {
    let c = Case::new();
    let svg = strokes_svg(&c);
    std::fs::write(c.p("strokes.svg"), &svg).unwrap();
    ok(&run_analyze(&c, "strokes.svg", "file", b""));
    ok(&run_analyze(&c, "/dev/stdin", "stdin", svg.as_bytes()));
    assert_eq!(
        c.bytes("stdin/direction.npy"),
        c.bytes("file/direction.npy")
    );
}

/// Before: a sketch's format came from its extension only, and a pipe has none: rc 65,
/// "unknown sketch file type". Now each of the three files is told by its content.
#[test]
fn sketch_convert_reads_each_sketch_format_from_a_pipe() {
    let c = Case::new();
    ok(&coif(
        c.root(),
        &[
            "sketch",
            "--image",
            "case/image.png",
            "--mask",
            "case/mask.png",
            "--out",
            "sk",
            "--backend",
            "cpu",
        ],
    ));
    for f in ["hair.czs", "sketch.json", "sketch.svg"] {
        let out = format!("{f}.czs");
        let o = coif_piped(
            c.root(),
            &["sketch-convert", "--sketch", "/dev/stdin", "--out", &out],
            &c.bytes(&format!("sk/{f}")),
        );
        ok(&o);
        assert_eq!(c.bytes(&out), c.bytes("sk/hair.czs"), "{f} through a pipe");
    }
}

fn strand_data(name: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/strands")
            .join(name),
    )
    .unwrap()
}

/// Before: the strand format came from the extension only: rc 64, "unknown strand format".
/// Now .hair and .ply are told by their magic, .obj as text, .data by its strict layout.
#[test]
fn convert_reads_strand_files_from_a_pipe() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::write(root.join("in.hair"), strand_data("Bangs_100.hair")).unwrap();
    std::fs::write(root.join("in.data"), strand_data("Bangs_100.data")).unwrap();
    std::fs::write(root.join("in.ply"), strand_data("Bangs_100_ascii.ply")).unwrap();
    ok(&coif(root, &["convert", "in.hair", "in.obj"]));
    for kind in ["hair", "data", "ply", "obj"] {
        let named = format!("in.{kind}");
        let (by_name, by_pipe) = (format!("{kind}_named.hair"), format!("{kind}_piped.hair"));
        ok(&coif(root, &["convert", &named, &by_name]));
        let bytes = std::fs::read(root.join(&named)).unwrap();
        ok(&coif_piped(
            root,
            &["convert", "/dev/stdin", &by_pipe],
            &bytes,
        ));
        assert_eq!(
            std::fs::read(root.join(&by_pipe)).unwrap(),
            std::fs::read(root.join(&by_name)).unwrap(),
            "{kind} through a pipe"
        );
    }
    // Not a strand file at all: the message says why the format could not be told.
    let o = coif_piped(
        root,
        &["convert", "/dev/stdin", "x.hair"],
        b"\x89PNG\r\n\x1a\n....",
    );
    fails(
        &o,
        65,
        &["/dev/stdin", "cannot tell the strand format", "extension"],
    );
}

const JOB: &str = r#"{"id": "a", "image": "case/image.png", "mask": "case/mask.png", "out": "jobs/a", "steps": ["orient"]}"#;

/// Before: a manifest on a pipe had /dev as its folder, so "case/image.png" was looked for
/// as /dev/case/image.png (the job failed), and the default summary went to
/// /dev/stdin.summary.json. Now its paths are read against the current folder and the
/// summary must be named.
#[test]
fn batch_reads_the_manifest_from_a_pipe() {
    let c = Case::new();
    let o = coif_piped(
        c.root(),
        &["batch", "/dev/stdin", "--backend", "cpu"],
        JOB.as_bytes(),
    );
    fails(&o, 64, &["/dev/stdin", "not a regular file", "--summary"]);
    let o = coif_piped(
        c.root(),
        &[
            "batch",
            "/dev/stdin",
            "--summary",
            "sum.json",
            "--backend",
            "cpu",
        ],
        JOB.as_bytes(),
    );
    ok(&o);
    ok(&coif(c.root(), &orient_args("case/image.png", "file")));
    assert_eq!(
        c.bytes("jobs/a/orient/orientation.npy"),
        c.bytes("file/orientation.npy")
    );
    let sum: serde_json::Value = serde_json::from_slice(&c.bytes("sum.json")).unwrap();
    assert_eq!(sum["jobs"][0]["status"], "ok", "{sum}");
}

/// A batch job's inputs are hashed for its record and read by each step, so a pipe cannot
/// serve. Before: the hash emptied the pipe and the step said "cannot decode the image".
#[test]
fn batch_refuses_a_pipe_as_a_job_input_and_says_why() {
    let c = Case::new();
    let job = JOB.replace("case/image.png", "/dev/stdin");
    std::fs::write(c.p("jobs.jsonl"), job).unwrap();
    let o = coif_piped(
        c.root(),
        &["batch", "jobs.jsonl", "--backend", "cpu"],
        &c.bytes("case/image.png"),
    );
    assert_eq!(o.status.code(), Some(65), "{}", stderr(&o));
    let sum: serde_json::Value =
        serde_json::from_slice(&c.bytes("jobs.jsonl.summary.json")).unwrap();
    let msg = sum["jobs"][0]["message"].as_str().unwrap_or_default();
    for needle in ["/dev/stdin", "key `image`", "not a regular file"] {
        assert!(msg.contains(needle), "message lacks {needle:?}: {sum}");
    }
}

/// A video is probed and then decoded (two reads) and stamped by size and time: a pipe
/// cannot serve. Before: "not a video file (it is a folder)".
#[test]
fn video_refuses_a_pipe_and_says_why() {
    let c = Case::new();
    let o = coif_piped(
        c.root(),
        &[
            "video",
            "--video",
            "/dev/stdin",
            "--strokes",
            "case/strokes.json",
            "--out",
            "v",
            "--backend",
            "cpu",
        ],
        b"not a video",
    );
    fails(&o, 65, &["/dev/stdin", "pipe", "save the stream to a file"]);
}
