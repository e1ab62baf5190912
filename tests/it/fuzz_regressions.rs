//! Replays what the fuzzers (`fuzz/`, `scripts/fuzz.sh`) found, once fixed, and the repo's own
//! files of each format, through the same entry point the fuzz targets use, so a parser that
//! regresses fails `cargo test` without cargo-fuzz or a nightly toolchain.

use coif::testing::fuzz::{run, TARGETS};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|r| r.map(|e| e.unwrap().path()).collect())
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn every_target_has_a_fuzz_binary_and_every_binary_a_target() {
    let toml = std::fs::read_to_string(root().join("fuzz/Cargo.toml")).unwrap();
    for t in TARGETS {
        let src = root().join(format!("fuzz/fuzz_targets/{t}.rs"));
        let text = std::fs::read_to_string(&src).unwrap_or_else(|e| panic!("{src:?}: {e}"));
        assert!(
            text.contains(&format!("run(\"{t}\"")),
            "{src:?} runs another target"
        );
        assert!(
            toml.contains(&format!("name = \"{t}\"")),
            "fuzz/Cargo.toml lacks {t}"
        );
    }
    let bins = files(&root().join("fuzz/fuzz_targets"));
    assert_eq!(
        bins.len(),
        TARGETS.len(),
        "fuzz_targets/ has files no target names"
    );
}

#[test]
fn an_unknown_target_is_refused_rather_than_fuzzing_nothing() {
    let r = std::panic::catch_unwind(|| run("no_such_target", b"{}"));
    assert!(r.is_err());
}

#[test]
fn the_fixed_findings_replay_without_a_panic() {
    let mut n = 0;
    for dir in files(&root().join("fuzz/regressions")) {
        let target = dir.file_name().unwrap().to_str().unwrap().to_string();
        assert!(
            TARGETS.contains(&target.as_str()),
            "{dir:?} names no target"
        );
        for f in files(&dir) {
            let data = std::fs::read(&f).unwrap();
            let r = std::panic::catch_unwind(|| run(&target, &data));
            assert!(r.is_ok(), "{target} panics on {f:?}");
            n += 1;
        }
    }
    eprintln!("{n} fixed fuzz findings replayed");
}

/// The repo's own files read, write and read back under every invariant the fuzzers check.
#[test]
fn the_repo_files_of_each_format_pass_the_fuzz_invariants() {
    let cases = [
        ("strands_hair", "tests/data/strands/Bangs_100.hair"),
        ("strands_data", "tests/data/strands/Bangs_100.data"),
        ("strands_ply", "tests/data/strands/Bangs_100_ascii.ply"),
        ("strands_ply", "tests/data/strands/Curly_100.ply"),
        ("strokes_json", "assets/astronaut_strokes.json"),
        ("labelme_json", "tests/data/labelme_strokes.json"),
        ("svg_strokes", "tests/data/svg_strokes.svg"),
        ("sketch_svg", "tests/data/sketch/inkscape/moved.svg"),
    ];
    for (t, f) in cases {
        let data = std::fs::read(root().join(f)).unwrap();
        assert!(run(t, &data), "{t}: {f} is refused");
        // Cut short, each is refused (or still read, for text that stays well-formed), and
        // never panics.
        let _ = run(t, &data[..data.len() / 2]);
    }
    for t in TARGETS {
        assert!(
            !run(t, b"\x00not a file of any format"),
            "{t} accepts garbage"
        );
    }
}
