//! The parsers under coverage-guided fuzzing (`fuzz/`, `scripts/fuzz.sh`), by target name.
//! One function runs a target on one input, so the fuzz targets, the seed-corpus replay and
//! the regression test (`tests/it/fuzz_regressions.rs`) exercise exactly the same code.
//!
//! A parser may refuse any input with an error; it must not panic, hang or allocate without
//! bound. Where a writer exists, whatever a reader accepts must write and read back (the
//! writer sees everything a user could feed it through the reader).

use crate::io::strands::{self, Format};
use crate::sketch::format as sk;
use std::path::Path;

/// Every fuzz target: one per file format coif reads.
pub const TARGETS: [&str; 14] = [
    "strands_hair",
    "strands_data",
    "strands_ply",
    "strands_obj",
    "strokes_json",
    "landmarks_json",
    "labelme_json",
    "svg_strokes",
    "sketch_czs",
    "sketch_json",
    "sketch_svg",
    "npy",
    "model_json",
    "manifest",
];

/// Runs target `name` on `data`; true when the parser accepted it. Panics on a broken
/// invariant (that is the finding); an unknown name panics too, so a typo in a target cannot
/// fuzz nothing.
pub fn run(name: &str, data: &[u8]) -> bool {
    let path = Path::new("fuzz-input");
    let text = std::str::from_utf8(data);
    match name {
        "strands_hair" => strands_round_trip(data, Format::Hair),
        "strands_data" => strands_round_trip(data, Format::Data),
        "strands_ply" => strands_round_trip(data, Format::Ply),
        "strands_obj" => strands_round_trip(data, Format::Obj),
        "npy" => {
            let r = crate::io::npy::from_bytes(data);
            if let Ok((shape, values)) = &r {
                let n: usize = shape.iter().product();
                assert_eq!(n, values.len(), "npy: shape {shape:?} vs {}", values.len());
                let back = crate::io::npy::from_bytes(&crate::io::npy::to_bytes(shape, values))
                    .expect("npy: written bytes read back");
                assert_eq!(&back.0, shape);
                assert_eq!(bits(&back.1), bits(values), "npy: values changed");
            }
            r.is_ok()
        }
        "sketch_czs" => sk::from_czs(data, path)
            .map(|s| sketch_round_trip(&s))
            .is_ok(),
        _ => {
            // The rest are text formats: bytes that are not UTF-8 are refused by the readers
            // before parsing, as `read_text` does.
            let Ok(text) = text else {
                assert!(TARGETS.contains(&name), "unknown fuzz target {name:?}");
                return false;
            };
            run_text(name, text, path)
        }
    }
}

fn run_text(name: &str, text: &str, path: &Path) -> bool {
    let valid = |s: crate::io::annot::Strokes, what: &str| {
        assert!(s.validate(None).is_ok(), "{what}: accepted but invalid");
    };
    match name {
        "strokes_json" => crate::io::annot::Strokes::parse(text, path, None)
            .map(|s| valid(s, "strokes"))
            .is_ok(),
        "landmarks_json" => crate::io::annot::Landmarks::parse(text, path, None).is_ok(),
        "labelme_json" => crate::io::import::labelme_from_str(text, path)
            .map(|s| valid(s, "labelme"))
            .is_ok(),
        "svg_strokes" => crate::io::import::svg_strokes_from_str(text, path)
            .map(|s| valid(s, "svg strokes"))
            .is_ok(),
        "sketch_json" => sk::from_json(text, path)
            .map(|s| sketch_round_trip(&s))
            .is_ok(),
        "sketch_svg" => sk::from_svg(text, path)
            .map(|s| sketch_round_trip(&s))
            .is_ok(),
        "model_json" => crate::hair::scene::SceneMeta::parse(text, path).is_ok(),
        // Building the jobs is what `coif batch` does next with a parsed manifest.
        "manifest" => crate::batch::manifest::parse(path, text)
            .map(|jobs| jobs.iter().for_each(|j| drop(j.jobs())))
            .is_ok(),
        other => panic!("unknown fuzz target {other:?}; the targets are {TARGETS:?}"),
    }
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// A strand file a reader accepts writes back in its format and reads back to the same shape.
fn strands_round_trip(data: &[u8], format: Format) -> bool {
    let path = Path::new("fuzz-input");
    let Ok(set) = strands::decode(data, format, path) else {
        return false;
    };
    let bytes = strands::encode(&set, format, path)
        .unwrap_or_else(|e| panic!("{format:?}: read but cannot write back: {e}"));
    let back = strands::decode(&bytes, format, path)
        .unwrap_or_else(|e| panic!("{format:?}: its own output does not read back: {e}"));
    assert_eq!(back.counts, set.counts, "{format:?}: strand counts changed");
    true
}

/// A sketch a reader accepts is written by all three writers, and each reads back equal to
/// the others (the readers snap to the `.czs` lattice, so the three agree exactly).
fn sketch_round_trip(s: &crate::sketch::Sketch) {
    let path = Path::new("fuzz-input");
    let czs = sk::from_czs(&sk::to_czs(s), path)
        .unwrap_or_else(|e| panic!("a sketch read in does not read back from .czs: {e}"));
    let json = sk::from_json(&sk::to_json(s), path)
        .unwrap_or_else(|e| panic!("a sketch read in does not read back from .json: {e}"));
    let svg = sk::from_svg(&sk::to_svg(s), path)
        .unwrap_or_else(|e| panic!("a sketch read in does not read back from .svg: {e}"));
    assert_eq!(czs, json, "the .czs and .json round trips differ");
    assert_eq!(czs, svg, "the .czs and .svg round trips differ");
}
