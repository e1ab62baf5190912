//! Every integration test in one binary (`cargo test --release --test it [module::][name]`).
//!
//! Why one binary and not a binary per file: each binary links the whole crate and wgpu, so
//! after a change to the library 48 binaries were rebuilt and linked (4-6 s each on 2 cores);
//! this crate builds in ~36 s. (CI's total did not move: there the library's own unit-test
//! build is the longer path, and the suite's 1,009 s equal the 48 binaries' 1,010 s.)

mod common;

mod accuracy;
mod analyze;
mod batch;
mod cli;
mod determinism;
mod direction;
mod edit;
mod field3d;
mod fuzz_regressions;
mod golden;
mod grow;
mod head;
mod inpaint;
mod memory;
mod model;
mod parity;
mod raster;
mod render;
mod segment_real;
mod shade;
mod shader_validation;
mod sim;
mod sketch_bands;
mod sketch_cartoon;
mod sketch_cli;
mod sketch_edit;
mod sketch_fill;
mod sketch_format;
mod sketch_pursuit;
mod sketch_swc;
mod sketch_synth;
mod sketch_texture;
mod stdin;
mod strands;
mod synth3d;
mod synth_video;
mod timings;
mod txn;
mod validate;
mod variations;
mod video_cli;
mod video_eval;
mod video_features;
mod video_flow;
mod video_frames;
mod video_warp;
mod views;
mod volume;

/// A file in `tests/it/` that this list forgets would never be compiled or run, silently.
#[test]
fn every_file_in_tests_it_is_a_module_here() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/it");
    let main = std::fs::read_to_string(dir.join("main.rs")).unwrap();
    let mut missing = Vec::new();
    for e in std::fs::read_dir(&dir).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        if let Some(m) = name.strip_suffix(".rs") {
            if m != "main" && !main.lines().any(|l| l == format!("mod {m};")) {
                missing.push(name);
            }
        }
    }
    assert!(
        missing.is_empty(),
        "not declared in tests/it/main.rs: {missing:?}"
    );
}
