//! The manifest's JSON Schema (`schemas/batch-job.v1.schema.json`) and its serde types
//! accept and refuse the same lines.

use super::manifest::parse;
use std::path::Path;

const SCHEMA: &str = include_str!("../../schemas/batch-job.v1.schema.json");

fn schema_accepts(line: &str) -> bool {
    let url = "https://coif.invalid/batch-job.v1.schema.json";
    let mut schemas = boon::Schemas::new();
    let mut compiler = boon::Compiler::new();
    compiler
        .add_resource(url, serde_json::from_str(SCHEMA).unwrap())
        .unwrap();
    let idx = compiler.compile(url, &mut schemas).unwrap();
    let v: serde_json::Value = serde_json::from_str(line).unwrap();
    schemas.validate(&v, idx).is_ok()
}

#[test]
fn schema_and_parser_agree() {
    let full = r#"{"id": "p", "image": "a.png", "strokes": "s.json", "mask": "m.png", "landmarks": "l.json", "reference_mask": "r.png", "out": "o", "steps": ["orient", "analyze", "model", "render", "sketch", "synth-hair"], "orient": {"orientations": 16, "sigma_x": 1, "sigma_y": 2, "lambda": 4, "ksize": 17, "dog_fine": 0.5, "dog_coarse": 3, "refine": 1, "smooth": 0}, "analyze": {"radius": 5, "stroke_weight": 2, "segment_smoothness": 25, "segment_luminance": 1, "segment_trust_strokes": true}, "model": {"seed": 7, "roots": 99, "cells": 20, "refine": 2}, "render": {"yaw": 25, "pitch": -5, "roll": 1, "scale": 0.5, "hue": 30, "saturation": 1.2, "value": 0.9, "highlight": 0.6, "width": 1.5, "seed": 4}, "sketch": {"whole": true, "curve_penalty": 2, "primitive_penalty": 1, "dictionary_sides": true, "bit_cost": 0.5, "rate_contrast": true, "max_bytes": 900, "target_bytes": 0, "target_fill": 10, "target_sketch_bytes": 500, "directions": "icm", "crown": "parting", "prior_weight": 0.5, "sweeps": 5, "bases": 3, "sigma_low": 6, "seed": 9}, "synth-hair": {"seed": 1, "rounds": 1, "half_length": 8, "grain": false, "over": true}}"#;
    let good = [
        full,
        r#"{"id": "p001", "image": "a.png", "strokes": "a.json", "landmarks": "a_lm.json", "mask": "m.png", "out": "out/p001", "steps": ["model", "render"], "render": {"yaw": 25}}"#,
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["orient"]}"#,
    ];
    for l in good {
        assert!(schema_accepts(l), "schema refuses {l}");
        parse(Path::new("m.jsonl"), l).unwrap_or_else(|e| panic!("{l}: {e}"));
    }
    // Every key of the full line reaches the parser: written again (numbers as f32 or
    // integers), it has the same keys.
    let jobs = parse(Path::new("m.jsonl"), full).unwrap();
    let again = serde_json::to_value(&jobs[0].entry).unwrap();
    let orig: serde_json::Value = serde_json::from_str(full).unwrap();
    assert_eq!(keys(&again, ""), keys(&orig, ""));
    // 14 keys of the line; options: orient 9, analyze 5, model 4, render 10, sketch 17,
    // synth-hair 5.
    assert_eq!(keys(&orig, "").len(), 14 + 9 + 5 + 4 + 10 + 17 + 5);
    let bad = [
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["paint"]}"#,
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["orient"], "colour": 1}"#,
        r#"{"id": "a", "image": "a.png", "steps": ["orient"]}"#,
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["orient"], "orient": {"sigma": 1}}"#,
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": []}"#,
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["orient", "orient"]}"#,
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["model"], "strokes": "s", "model": {"roots": -1}}"#,
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["sketch"], "sketch": {"whole": true, "directions": "best"}}"#,
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["sketch"], "sketch": {"whole": true, "crown": "top"}}"#,
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["sketch"], "sketch": {"whole": true, "target_fill": -1}}"#,
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["sketch"], "sketch": {"whole": true, "prior_weight": 0}}"#,
        r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["analyze"], "strokes": "s", "analyze": {"segment_trust_strokes": 1}}"#,
        r#"{"id": "", "image": "a.png", "out": "o", "steps": ["orient"]}"#,
        r#"{"id": "a", "image": 3, "out": "o", "steps": ["orient"]}"#,
    ];
    for l in bad {
        assert!(!schema_accepts(l), "schema accepts {l}");
        assert!(
            parse(Path::new("m.jsonl"), l).is_err(),
            "parser accepts {l}"
        );
    }
}

/// Every object key path of `v`.
fn keys(v: &serde_json::Value, at: &str) -> Vec<String> {
    match v {
        serde_json::Value::Object(o) => o
            .iter()
            .flat_map(|(k, x)| {
                let p = format!("{at}/{k}");
                std::iter::once(p.clone()).chain(keys(x, &p))
            })
            .collect(),
        _ => Vec::new(),
    }
}
