//! The video commands' jobs (`coif synth-video`, `coif video`, `coif transfer`): their
//! inputs and their runs, which tie the command line to `crate::synth::video` and
//! `crate::video`.

use super::{render_frames, RenderJob, Report};
use crate::gpu::engine::Engine;
use crate::hair::scene::Scene;
use crate::model::ModelParams;
use crate::render::RenderParams;
use crate::synth;
use anyhow::Context;
use std::path::PathBuf;
use std::time::Instant;

/// Where a clip comes from (`coif video --frames DIR` or `--video FILE`).
#[derive(Clone, Debug)]
pub enum ClipSource {
    Frames(PathBuf),
    /// Decoded with ffmpeg into `<out>/decoded/` first.
    Video(PathBuf),
}

/// A hair model tracked through a clip (`coif video`, C13 §3).
#[derive(Clone, Debug)]
pub struct VideoJob {
    pub source: ClipSource,
    pub ann: crate::video::run::Annotations,
    pub out: PathBuf,
    pub model: ModelParams,
    pub track: crate::video::track::TrackParams,
}

/// Another model's hair carried through a tracked clip (`coif transfer`, C13 §4).
#[derive(Clone, Debug)]
pub struct TransferJob {
    pub video_model: PathBuf,
    pub model: PathBuf,
    pub out: PathBuf,
    pub render: RenderParams,
}

/// A synthetic clip with exact ground truth: known head and hair motion, per-frame strands,
/// cameras and true flow (`coif synth-video`).
#[derive(Clone, Debug)]
pub struct SynthVideoJob {
    pub out: PathBuf,
    pub params: synth::video::VideoParams,
}

pub(super) fn run_synth_video(j: &SynthVideoJob) -> anyhow::Result<Report> {
    let p = &j.params;
    let v = synth::video::SynthVideo::new(p)?;
    let r = v.write(&j.out, true)?;
    Ok(Report {
        summary: format!(
            "synth-video: {} seed {} ({}x{}, {} frames, {} strands) -> {} ({:.1} s)",
            p.synth.style,
            p.synth.seed,
            p.synth.width,
            p.synth.height,
            r.frames,
            v.scene.strands.len(),
            j.out.display(),
            r.seconds
        ),
        details: vec![
            format!(
                "head: yaw {:.1}..{:.1}°, pitch {:.1}..{:.1}°",
                r.yaw_range_deg[0], r.yaw_range_deg[1], r.pitch_range_deg[0], r.pitch_range_deg[1]
            ),
            format!(
                "hair: turn up to {:.1}°, at most {} strands limited by the body in a frame",
                r.hair_turn_max_deg, r.hair_limited_max
            ),
            format!(
                "true flow on hair: mean {:.2} px, max {:.2} px per frame",
                r.flow_mean_px, r.flow_max_px
            ),
        ],
        warnings: Vec::new(),
    })
}

pub(super) fn run_video(engine: &Engine, j: &VideoJob) -> anyhow::Result<Report> {
    let fresh = !j.out.exists();
    let r = run_video_in(engine, j);
    if r.is_err() && fresh {
        // A run that failed before writing a frame leaves no empty folders behind (a video
        // that could not be decoded, say); remove_dir keeps any folder that holds a file.
        for d in ["decoded", "frames", "photos", "masks", "warps", ""] {
            let _ = std::fs::remove_dir(j.out.join(d));
        }
    }
    r
}

fn run_video_in(engine: &Engine, j: &VideoJob) -> anyhow::Result<Report> {
    use crate::video::frames;
    let clip = crate::timings::stage("read").run(|| match &j.source {
        ClipSource::Frames(d) => frames::open_frames_dir(d),
        ClipSource::Video(v) => frames::decode_video(v, &j.out.join("decoded")),
    })?;
    let inp = crate::video::run::VideoInputs {
        clip,
        ann: j.ann.clone(),
    };
    let r = crate::video::run::run(engine, &inp, &j.model, &j.track, &j.out, true)?;
    let fb: Vec<f32> = r
        .per_frame
        .iter()
        .map(|f| f.fb_median_px)
        .filter(|v| v.is_finite())
        .collect();
    let held = r
        .per_frame
        .iter()
        .filter(|f| f.pose.source == crate::video::head::PoseSource::Held)
        .count();
    let mut warnings = Vec::new();
    if held > 0 {
        warnings.push(format!(
            "{held} frames kept the previous head pose: too few face features survived (add landmark files for them with --landmark-dir)"
        ));
    }
    let yaw =
        |f: fn(f32, f32) -> f32, init: f32| r.per_frame.iter().map(|p| p.yaw_deg).fold(init, f);
    Ok(Report {
        summary: format!(
            "video: {} frames (reference {}{}) -> {} ({:.1} s, {:.2} s/frame on {})",
            r.frames,
            j.ann.reference,
            if r.resumed > 0 {
                format!(", {} resumed", r.resumed)
            } else {
                String::new()
            },
            j.out.display(),
            r.seconds,
            r.seconds / (r.frames - r.resumed).max(1) as f64,
            r.backend
        ),
        details: vec![
            format!(
                "features         {} to {} per frame, median forward-backward error {:.2} px",
                r.per_frame.iter().map(|f| f.features).min().unwrap_or(0),
                r.per_frame.iter().map(|f| f.features).max().unwrap_or(0),
                crate::base::stats::percentile(&fb, 0.5)
            ),
            format!(
                "head yaw         {:.1}° to {:.1}° from the reference",
                yaw(f32::min, f32::INFINITY),
                yaw(f32::max, f32::NEG_INFINITY)
            ),
        ],
        warnings,
    })
}

pub(super) fn run_transfer(engine: &Engine, j: &TransferJob) -> anyhow::Result<Report> {
    let t = Instant::now();
    let stage = crate::timings::stage;
    let (video, new) =
        stage("load").run(|| anyhow::Ok((Scene::load(&j.video_model)?, Scene::load(&j.model)?)))?;
    let transfer = stage("transfer");
    let s = crate::video::transfer::transfer(&video, &new, &j.out).with_context(|| {
        format!(
            "carrying {} through {}",
            j.model.display(),
            j.video_model.display()
        )
    })?;
    s.save(&j.out, serde_json::json!({ "transfer": { "video": j.video_model.display().to_string(), "model": j.model.display().to_string() } }))?;
    let gif = crate::video::run::preview(&s)?;
    crate::io::write_atomic(&j.out.join("preview.gif"), &gif)?;
    drop(transfer);
    let rj = RenderJob {
        model: j.out.clone(),
        out: j.out.join("render"),
        params: j.render.clone(),
        sixteen: false,
    };
    // The frames' own stages (load, shading, ..., write) fall inside this one.
    stage("render").run(|| render_frames(engine, &s, &rj))?;
    Ok(Report {
        summary: format!(
            "transfer: {} strands through {} frames -> {} (renders in {}, {:.1} s on {})",
            s.strands.len(),
            s.animation.as_ref().map_or(0, |a| a.frames.len()),
            j.out.display(),
            rj.out.display(),
            t.elapsed().as_secs_f64(),
            engine.describe()
        ),
        ..Default::default()
    })
}
