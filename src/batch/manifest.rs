//! The batch manifest (`jobs.jsonl`): one JSON object per line, each a job of one or more
//! steps on one portrait. Every line is read and checked before any job runs.

use crate::error::Error;
use crate::jobs::SynthHairJob;
use crate::jobs::{AnalyzeJob, HairRegion, Job, ModelJob, OrientJob, RenderJob, SketchJob};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A step of a job; each writes under the job's `out` folder (see [`Entry::jobs`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Step {
    Orient,
    Analyze,
    Model,
    Render,
    Sketch,
    SynthHair,
}

impl Step {
    fn name(self) -> &'static str {
        match self {
            Step::Orient => "orient",
            Step::Analyze => "analyze",
            Step::Model => "model",
            Step::Render => "render",
            Step::Sketch => "sketch",
            Step::SynthHair => "synth-hair",
        }
    }
}

/// Options of `orient` (also used by `analyze`), as `coif orient` names them.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrientOpts {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientations: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_x: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_y: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lambda: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ksize: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dog_fine: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dog_coarse: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refine: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smooth: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smooth_fit: Option<crate::analyze::orient::SmoothFit>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smooth_weight: Option<crate::analyze::orient::SmoothWeight>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smooth_robust: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smooth_guide_power: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub singular_radius: Option<f32>,
}

/// Options of `analyze`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnalyzeOpts {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radius: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stroke_weight: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segment_smoothness: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segment_luminance: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segment_trust_strokes: Option<bool>,
}

/// Options of `model`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelOpts {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roots: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cells: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refine: Option<u32>,
}

/// Options of `render`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderOpts {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub yaw: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pitch: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roll: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hue: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub saturation: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub highlight: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub width: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
}

/// Options of `sketch`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SketchOpts {
    /// Every pixel is hair (no mask or strokes needed).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub whole: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub curve_penalty: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub primitive_penalty: Option<f32>,
    /// Side angles from the paper's dictionary alone (no refinement).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub dictionary_sides: bool,
    /// μ of the rate choice of side refinements and contrasts.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bit_cost: Option<f32>,
    /// Contrasts chosen by rate too.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub rate_contrast: bool,
    /// A budget for `hair.czs`, bytes: met or refused (replaces `target_bytes`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_bytes: Option<usize>,
    /// The size `hair.czs` is brought under where it can be (default 1024; 0: off).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target_bytes: Option<usize>,
    /// The fill's distance from the dense field the sketch is brought within, degrees
    /// (default 12; 0: off).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target_fill: Option<f32>,
    /// The size the sketch part (the curves) is brought under where the file and the fill
    /// stay within their targets, bytes (default 600; 0: off).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target_sketch_bytes: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub directions: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub crown: Option<String>,
    /// κ, the direction prior's weight against the curves' compatibility (default 0.2).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prior_weight: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sweeps: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bases: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_low: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
}

/// Options of `synth-hair`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SynthHairOpts {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rounds: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub half_length: Option<f32>,
    /// Grain up to the sketch's along/across ratio (default true).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grain: Option<bool>,
    /// Put the hair over the job's image.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub over: bool,
}

/// One manifest line as written (paths relative to the manifest's folder). Serialised
/// again, it is the job's normalised parameters in its record.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Entry {
    pub id: String,
    pub image: PathBuf,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub strokes: Option<PathBuf>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mask: Option<PathBuf>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub landmarks: Option<PathBuf>,
    /// A hair mask drawn by hand that the analyze step scores its mask against.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_mask: Option<PathBuf>,
    pub out: PathBuf,
    pub steps: Vec<Step>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orient: Option<OrientOpts>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub analyze: Option<AnalyzeOpts>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model: Option<ModelOpts>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub render: Option<RenderOpts>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sketch: Option<SketchOpts>,
    #[serde(rename = "synth-hair", skip_serializing_if = "Option::is_none")]
    pub synth_hair: Option<SynthHairOpts>,
}

/// A checked manifest line.
#[derive(Clone, Debug)]
pub struct BatchJob {
    pub entry: Entry,
    /// Line number in the manifest (from 1).
    pub line: usize,
    /// The manifest's folder, which relative paths are read against.
    pub base: PathBuf,
}

/// Reads and checks a manifest: every error names the file, the line and the key. A
/// manifest that is not a regular file (`/dev/stdin`, `<(...)`) has no folder of its own,
/// so its relative paths are read against the current folder.
pub fn load(path: &Path) -> crate::Result<Vec<BatchJob>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut jobs = parse(path, &text)?;
    if !is_regular(path) {
        for j in &mut jobs {
            j.base = PathBuf::new();
        }
    }
    Ok(jobs)
}

/// Whether `path` is a regular file (symbolic links followed): false for pipes and devices.
pub fn is_regular(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_file())
}

/// Parses manifest text; `path` names the file in errors and gives the base folder.
pub fn parse(path: &Path, text: &str) -> crate::Result<Vec<BatchJob>> {
    let base = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::new(),
    };
    let bad = |line: usize, msg: String| Error::bad_file(path, format!("line {line}: {msg}"));
    let mut jobs = Vec::new();
    let mut ids: HashMap<String, usize> = HashMap::new();
    let mut outs: HashMap<PathBuf, usize> = HashMap::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let t = raw.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let entry: Entry = serde_json::from_str(t).map_err(|e| bad(line, json_msg(&e)))?;
        check(&entry).map_err(|m| bad(line, m))?;
        if let Some(first) = ids.insert(entry.id.clone(), line) {
            return Err(bad(
                line,
                format!("key `id`: {:?} is already the id on line {first}", entry.id),
            ));
        }
        if let Some(first) = outs.insert(base.join(&entry.out), line) {
            return Err(bad(
                line,
                format!(
                    "key `out`: {} is already the out of line {first}",
                    entry.out.display()
                ),
            ));
        }
        jobs.push(BatchJob {
            entry,
            line,
            base: base.clone(),
        });
    }
    if jobs.is_empty() {
        return Err(Error::bad_file(
            path,
            "no jobs (every line blank or a # comment)",
        ));
    }
    Ok(jobs)
}

/// serde_json's message without its position inside the one line (the column is kept).
fn json_msg(e: &serde_json::Error) -> String {
    let m = e.to_string();
    match m.rfind(" at line ") {
        Some(i) => format!("{} (column {})", &m[..i], e.column()),
        None => m,
    }
}

/// The checks serde cannot make: ids, steps and the keys each step needs.
fn check(e: &Entry) -> Result<(), String> {
    if e.id.trim().is_empty() {
        return Err("key `id` is empty".into());
    }
    if e.steps.is_empty() {
        return Err("key `steps` is empty".into());
    }
    for (k, s) in e.steps.iter().enumerate() {
        let before = &e.steps[..k];
        if before.contains(s) {
            return Err(format!("key `steps`: {} is listed twice", s.name()));
        }
        let needs = |key: &str, has: bool| {
            if has {
                Ok(())
            } else {
                Err(format!("step {} needs key `{key}`", s.name()))
            }
        };
        match s {
            Step::Analyze | Step::Model => needs("strokes", e.strokes.is_some())?,
            Step::Sketch => {
                let whole = e.sketch.as_ref().is_some_and(|o| o.whole);
                if !whole && e.mask.is_none() && e.strokes.is_none() {
                    return Err("step sketch needs key `mask`, `strokes` or `sketch.whole`".into());
                }
            }
            Step::Render if !before.contains(&Step::Model) => {
                return Err("key `steps`: render needs model before it".into())
            }
            Step::SynthHair if !before.contains(&Step::Sketch) => {
                return Err("key `steps`: synth-hair needs sketch before it".into())
            }
            _ => {}
        }
    }
    // Options for a step the job does not run are most likely a typo in `steps`.
    let opts = [
        (
            "orient",
            e.orient.is_some(),
            &[Step::Orient, Step::Analyze][..],
        ),
        ("analyze", e.analyze.is_some(), &[Step::Analyze][..]),
        (
            "reference_mask",
            e.reference_mask.is_some(),
            &[Step::Analyze, Step::Model][..],
        ),
        ("model", e.model.is_some(), &[Step::Model][..]),
        ("render", e.render.is_some(), &[Step::Render][..]),
        ("sketch", e.sketch.is_some(), &[Step::Sketch][..]),
        ("synth-hair", e.synth_hair.is_some(), &[Step::SynthHair][..]),
    ];
    for (key, given, users) in opts {
        if given && !users.iter().any(|u| e.steps.contains(u)) {
            return Err(format!("key `{key}`: for a step not in `steps`"));
        }
    }
    if let Some(d) = e.sketch.as_ref().and_then(|o| o.directions.as_ref()) {
        d.parse::<crate::sketch::swc::Method>()
            .map_err(|err| format!("key `sketch.directions`: {err}"))?;
    }
    if let Some(t) = e.sketch.as_ref().and_then(|o| o.target_fill) {
        if !(t.is_finite() && t >= 0.0) {
            return Err(format!(
                "key `sketch.target_fill`: must be a finite number >= 0, got {t}"
            ));
        }
    }
    if let Some(c) = e.sketch.as_ref().and_then(|o| o.crown.as_ref()) {
        c.parse::<crate::sketch::swc::Crown>()
            .map_err(|err| format!("key `sketch.crown`: {err}"))?;
    }
    if let Some(k) = e.sketch.as_ref().and_then(|o| o.prior_weight) {
        if !(k.is_finite() && k > 0.0) {
            return Err(format!(
                "key `sketch.prior_weight`: must be a finite number > 0, got {k}"
            ));
        }
    }
    Ok(())
}

impl BatchJob {
    pub fn id(&self) -> &str {
        &self.entry.id
    }

    fn path(&self, p: &Path) -> PathBuf {
        self.base.join(p)
    }

    /// The job's output folder.
    pub fn out(&self) -> PathBuf {
        self.path(&self.entry.out)
    }

    /// The input files (key, resolved path) whose hashes go into the record.
    pub fn inputs(&self) -> Vec<(&'static str, PathBuf)> {
        let e = &self.entry;
        let mut v = vec![("image", self.path(&e.image))];
        for (k, p) in [
            ("strokes", &e.strokes),
            ("mask", &e.mask),
            ("landmarks", &e.landmarks),
            ("reference_mask", &e.reference_mask),
        ] {
            if let Some(p) = p {
                v.push((k, self.path(p)));
            }
        }
        v
    }

    /// The steps as library jobs, in order. Under `out`: `orient/`, `analyze/`, `model/`,
    /// `render.png` (of `model/`), `sketch/`, `synth-hair.png` (of `sketch/hair.czs`).
    pub fn jobs(&self) -> Vec<Job> {
        self.jobs_into(&self.out())
    }

    /// [`BatchJob::jobs`] writing under `out` (the job's temporary folder) instead.
    pub fn jobs_into(&self, out: &Path) -> Vec<Job> {
        let e = &self.entry;
        let image = self.path(&e.image);
        let strokes = e.strokes.as_ref().map(|p| self.path(p));
        let mask = e.mask.as_ref().map(|p| self.path(p));
        let landmarks = e.landmarks.as_ref().map(|p| self.path(p));
        let reference_mask = e.reference_mask.as_ref().map(|p| self.path(p));
        let orient = orient_params(e.orient.as_ref().unwrap_or(&OrientOpts::default()));
        e.steps
            .iter()
            .map(|s| match s {
                Step::Orient => Job::Orient(OrientJob {
                    image: image.clone(),
                    mask: mask.clone(),
                    out: out.join("orient"),
                    params: orient,
                    truth: None,
                }),
                Step::Analyze => {
                    let o = e.analyze.clone().unwrap_or_default();
                    let mut params = crate::analyze::AnalyzeParams {
                        orient,
                        ..Default::default()
                    };
                    set(&mut params.resolve.radius, o.radius);
                    set(&mut params.resolve.stroke_weight, o.stroke_weight);
                    set(&mut params.segment.smoothness, o.segment_smoothness);
                    set(&mut params.segment.luminance, o.segment_luminance);
                    if let Some(trust) = o.segment_trust_strokes {
                        params.segment.release_off_hair = !trust;
                    }
                    Job::Analyze(AnalyzeJob {
                        image: image.clone(),
                        strokes: strokes.clone().expect("checked"),
                        mask: mask.clone(),
                        out: out.join("analyze"),
                        params,
                        reference_mask: reference_mask.clone(),
                    })
                }
                Step::Model => {
                    let o = e.model.clone().unwrap_or_default();
                    let mut params = crate::model::ModelParams::default();
                    set(&mut params.seed, o.seed);
                    set(&mut params.roots, o.roots);
                    set(&mut params.volume.cells, o.cells);
                    set(&mut params.refine.max_iterations, o.refine);
                    Job::Model(ModelJob {
                        image: image.clone(),
                        strokes: strokes.clone().expect("checked"),
                        mask: mask.clone(),
                        landmarks: landmarks.clone(),
                        reference_mask: reference_mask.clone(),
                        out: out.join("model"),
                        params,
                    })
                }
                Step::Render => {
                    let o = e.render.clone().unwrap_or_default();
                    let mut p = crate::render::RenderParams::default();
                    set(&mut p.yaw_deg, o.yaw);
                    set(&mut p.pitch_deg, o.pitch);
                    set(&mut p.roll_deg, o.roll);
                    set(&mut p.scale, o.scale);
                    set(&mut p.shade.hue, o.hue);
                    set(&mut p.shade.saturation, o.saturation);
                    set(&mut p.shade.value, o.value);
                    set(&mut p.shade.amount, o.highlight);
                    set(&mut p.raster.strand_width, o.width);
                    set(&mut p.inpaint.seed, o.seed);
                    set(&mut p.head_texture.inpaint.seed, o.seed);
                    Job::Render(RenderJob {
                        model: out.join("model"),
                        out: out.join("render.png"),
                        params: p,
                        sixteen: false,
                    })
                }
                Step::Sketch => {
                    let o = e.sketch.clone().unwrap_or_default();
                    let region = match (&mask, o.whole, &strokes) {
                        (Some(m), _, _) => HairRegion::Mask(m.clone()),
                        (None, true, _) => HairRegion::Whole,
                        (None, false, Some(s)) => HairRegion::Strokes(s.clone()),
                        (None, false, None) => unreachable!("checked"),
                    };
                    let mut params = crate::sketch::run::SketchParams::default();
                    set(&mut params.pursuit.lambda_nc, o.curve_penalty);
                    set(&mut params.pursuit.lambda_b, o.primitive_penalty);
                    params.pursuit.refine_sides = !o.dictionary_sides;
                    set(&mut params.pursuit.bit_cost, o.bit_cost);
                    params.pursuit.rate_contrast = o.rate_contrast;
                    params.budget =
                        crate::sketch::run::ByteBudget::from_options(o.max_bytes, o.target_bytes);
                    if let Some(t) = o.target_fill {
                        params.fill_target = (t > 0.0).then_some(t);
                    }
                    if let Some(t) = o.target_sketch_bytes {
                        params.sketch_target = (t > 0).then_some(t);
                    }
                    if let Some(d) = &o.directions {
                        params.method = d.parse().expect("checked");
                    }
                    if let Some(c) = &o.crown {
                        params.swc.prior.crown = c.parse().expect("checked");
                    }
                    set(&mut params.swc.prior.kappa, o.prior_weight);
                    set(&mut params.swc.sweeps, o.sweeps);
                    set(&mut params.bases, o.bases);
                    set(&mut params.sigma_l, o.sigma_low);
                    params.seed = o.seed.unwrap_or(1);
                    Job::Sketch(SketchJob {
                        image: image.clone(),
                        region,
                        strokes: strokes.clone(),
                        out: out.join("sketch"),
                        params,
                    })
                }
                Step::SynthHair => {
                    let o = e.synth_hair.clone().unwrap_or_default();
                    let mut params = crate::sketch::synth::SynthParams {
                        seed: o.seed,
                        ..Default::default()
                    };
                    set(&mut params.texture.rounds, o.rounds);
                    set(&mut params.texture.half_len, o.half_length);
                    set(&mut params.grain, o.grain);
                    Job::SynthHair(SynthHairJob {
                        sketch: out.join("sketch").join("hair.czs"),
                        out: out.join("synth-hair.png"),
                        over: o.over.then(|| image.clone()),
                        layers: None,
                        params,
                    })
                }
            })
            .collect()
    }
}

fn set<T>(field: &mut T, v: Option<T>) {
    if let Some(v) = v {
        *field = v;
    }
}

fn orient_params(o: &OrientOpts) -> crate::analyze::orient::OrientParams {
    let mut p = crate::analyze::orient::OrientParams::default();
    set(&mut p.kernel.n_orient, o.orientations);
    set(&mut p.kernel.sigma_x, o.sigma_x);
    set(&mut p.kernel.sigma_y, o.sigma_y);
    set(&mut p.kernel.lambda, o.lambda);
    set(&mut p.kernel.ksize, o.ksize);
    set(&mut p.dog_sigma_fine, o.dog_fine);
    set(&mut p.dog_sigma_coarse, o.dog_coarse);
    set(&mut p.refine_iters, o.refine);
    set(&mut p.smooth_sigma, o.smooth);
    set(&mut p.smooth_fit, o.smooth_fit);
    set(&mut p.smooth_weight, o.smooth_weight);
    set(&mut p.smooth_robust_deg, o.smooth_robust);
    set(&mut p.smooth_guide_power, o.smooth_guide_power);
    set(&mut p.singular_radius, o.singular_radius);
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_reach_the_jobs_and_paths_the_manifest_folder() {
        let line = r#"{"id": "p", "image": "a.png", "strokes": "s.json", "mask": "/abs/m.png", "reference_mask": "refs/r.png", "out": "o", "steps": ["orient", "analyze", "model", "render", "sketch", "synth-hair"], "orient": {"orientations": 16, "smooth": 0}, "analyze": {"radius": 5, "segment_smoothness": 25, "segment_luminance": 1, "segment_trust_strokes": true}, "model": {"seed": 7, "roots": 99, "cells": 20, "refine": 2}, "render": {"yaw": 25, "hue": 30, "seed": 4}, "sketch": {"directions": "icm", "sweeps": 5, "seed": 9}, "synth-hair": {"rounds": 1, "over": true}}"#;
        let jobs = parse(Path::new("runs/jobs.jsonl"), line).unwrap();
        let j = jobs[0].jobs();
        assert_eq!(j.len(), 6);
        let base = Path::new("runs");
        match &j[0] {
            Job::Orient(o) => {
                assert_eq!(o.image, base.join("a.png"));
                assert_eq!(o.mask.as_deref(), Some(Path::new("/abs/m.png")));
                assert_eq!(o.out, base.join("o/orient"));
                assert_eq!(o.params.kernel.n_orient, 16);
                assert_eq!(o.params.smooth_sigma, 0.0);
            }
            other => panic!("{other:?}"),
        }
        match &j[1] {
            Job::Analyze(a) => {
                assert_eq!(a.params.orient.kernel.n_orient, 16);
                assert_eq!(a.params.resolve.radius, 5.0);
                assert_eq!(a.params.segment.smoothness, 25.0);
                assert_eq!(a.params.segment.luminance, 1.0);
                assert!(!a.params.segment.release_off_hair);
                assert_eq!(a.strokes, base.join("s.json"));
                assert_eq!(a.reference_mask, Some(base.join("refs/r.png")));
            }
            other => panic!("{other:?}"),
        }
        match &j[2] {
            Job::Model(m) => {
                assert_eq!((m.params.seed, m.params.roots), (7, 99));
                assert_eq!(m.params.volume.cells, 20);
                assert_eq!(m.params.refine.max_iterations, 2);
                assert_eq!(m.out, base.join("o/model"));
                assert_eq!(m.reference_mask, Some(base.join("refs/r.png")));
            }
            other => panic!("{other:?}"),
        }
        match &j[3] {
            Job::Render(r) => {
                assert_eq!(r.params.yaw_deg, 25.0);
                assert_eq!(r.params.shade.hue, 30.0);
                assert_eq!(r.params.inpaint.seed, 4);
                assert_eq!(r.model, base.join("o/model"));
                assert_eq!(r.out, base.join("o/render.png"));
            }
            other => panic!("{other:?}"),
        }
        match &j[4] {
            Job::Sketch(s) => {
                assert!(matches!(&s.region, HairRegion::Mask(m) if m == Path::new("/abs/m.png")));
                assert_eq!(s.params.method, crate::sketch::swc::Method::Icm);
                assert_eq!((s.params.swc.sweeps, s.params.seed), (5, 9));
            }
            other => panic!("{other:?}"),
        }
        match &j[5] {
            Job::SynthHair(h) => {
                assert_eq!(h.sketch, base.join("o/sketch/hair.czs"));
                assert_eq!(h.params.texture.rounds, 1);
                assert_eq!(h.over.as_deref(), Some(base.join("a.png").as_path()));
            }
            other => panic!("{other:?}"),
        }
        // The record's parameters: the line with keys in a fixed order, paths as written.
        let v = serde_json::to_value(&jobs[0].entry).unwrap();
        assert_eq!(v["model"]["roots"], 99);
        assert_eq!(v["mask"], "/abs/m.png");
        assert!(v["landmarks"].is_null());
    }

    #[test]
    fn errors_name_the_line() {
        let ok = r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["orient"]}"#;
        for (text, want) in [
            (format!("{ok}\n\n{ok}"), "line 3: key `id`"),
            ("# only\n\n".to_string(), "no jobs"),
            (
                r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["sketch"]}"#.into(),
                "line 1: step sketch needs key `mask`",
            ),
            (
                r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["render", "model"], "strokes": "s"}"#.into(),
                "line 1: key `steps`: render needs model before it",
            ),
            (
                r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["orient"], "reference_mask": "r.png"}"#.into(),
                "line 1: key `reference_mask`: for a step not in `steps`",
            ),
            (
                r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["orient", "orient"]}"#.into(),
                "line 1: key `steps`: orient is listed twice",
            ),
            (
                r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["sketch"], "sketch": {"whole": true, "directions": "best"}}"#.into(),
                "line 1: key `sketch.directions`",
            ),
            (
                r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["sketch"], "sketch": {"whole": true, "crown": "top"}}"#.into(),
                "line 1: key `sketch.crown`",
            ),
            (
                r#"{"id": "a", "image": "a.png", "out": "o", "steps": ["sketch"], "sketch": {"whole": true, "prior_weight": -1}}"#.into(),
                "line 1: key `sketch.prior_weight`: must be a finite number > 0, got -1",
            ),
            (
                r#"{"id": "", "image": "a.png", "out": "o", "steps": ["orient"]}"#.into(),
                "line 1: key `id` is empty",
            ),
        ] {
            let e = parse(Path::new("m.jsonl"), &text).unwrap_err();
            assert_eq!(e.exit_code(), 65);
            let m = e.to_string();
            assert!(m.starts_with("m.jsonl: ") && m.contains(want), "{m}");
        }
    }
}
