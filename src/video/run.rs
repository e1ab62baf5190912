//! `coif video`: a clip in, a tracked hair scene out (C13 §3).
//!
//! The output folder is a model folder (`coif render`, `export` and `simulate` read it):
//! the reference frame's model (`strands.hair`, `model.json`, `photo.png`, `mask.png`) with
//! an animation whose frames are `frames/NNNN.hair` (strands with the head at its pose, as a
//! simulation writes them) and whose footage is `photos/NNNN.png`, `masks/NNNN.png` and a
//! camera per frame. `warps/NNNN.npy` keeps W*_i (H×W×2, px) and `video.json` the per-frame
//! figures. Every file is written whole (temporary name, then rename) as its frame is done,
//! and `progress.json` records the frames done for these inputs: a run stopped half-way
//! keeps them, and the same command resumes after the last one. A run of other inputs into
//! the folder starts afresh and first removes the older run's frame files. The environment
//! variable `COIF_VIDEO_STOP_AFTER=N` is a test hook that stops a run after N frames
//! ([`STOP_AFTER_ENV`]).

use crate::analyze::orient::GrayImage;
use crate::error::{Error, Result};
use crate::gpu::engine::Engine;
use crate::hair::scene::{Animation, Footage, Scene};
use crate::hair::strands::StrandSet;
use crate::io::annot::Landmarks;
use crate::io::{ensure_dir, write_json, write_png};
use crate::model::ModelParams;
use crate::video::diffuse::Guide;
use crate::video::features::{load_points, UserPoints};
use crate::video::flow::FlowFeatures;
use crate::video::frames::Clip;
use crate::video::head::{pose_of, pose_rigid, world_camera, FramePose};
use crate::video::track::{
    feature_warp, features, frame_camera, order, orientation_features, reference_surface,
    rigid_motion, step, Reference, TrackParams,
};
use serde_json::json;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The user's files for a clip: the reference frame, its strokes, mask and landmarks, and
/// the per-frame landmarks and feature points. What `coif video` names besides the clip.
#[derive(Clone, Debug)]
pub struct Annotations {
    pub reference: usize,
    /// Strokes on the reference frame.
    pub strokes: PathBuf,
    /// Hair mask of the reference frame (else the analysis segments it).
    pub mask: Option<PathBuf>,
    /// Landmarks of the reference frame.
    pub landmarks: Option<PathBuf>,
    /// A folder of `NNNN.json` landmark files for any frames (numbered like the clip's
    /// frames, from 0).
    pub landmark_dir: Option<PathBuf>,
    /// Feature points the user adds or corrects (see `crate::video::features::load_points`).
    pub points: Option<PathBuf>,
}

/// What a video run reads.
#[derive(Clone, Debug)]
pub struct VideoInputs {
    pub clip: Clip,
    pub ann: Annotations,
}

/// Per-frame figures written to `video.json`.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct FrameFigures {
    pub frame: usize,
    pub pose: FramePose,
    pub yaw_deg: f32,
    /// Features known on this frame, and the median forward–backward error of those (px).
    pub features: usize,
    pub fb_median_px: f32,
    pub seconds: f64,
}

/// The output of a run.
pub struct VideoRun {
    pub frames: usize,
    pub resumed: usize,
    pub per_frame: Vec<FrameFigures>,
    pub seconds: f64,
    pub backend: String,
}

fn frame_name(dir: &str, k: usize, ext: &str) -> String {
    format!("{dir}/{k:04}.{ext}")
}

/// Landmark files for frames: the reference's own file and every `NNNN.json` of the folder.
pub fn load_landmarks(
    inp: &VideoInputs,
    size: (u32, u32),
) -> Result<BTreeMap<usize, (PathBuf, Landmarks)>> {
    let mut out = BTreeMap::new();
    if let Some(dir) = &inp.ann.landmark_dir {
        let rd = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
        for e in rd {
            let path = e.map_err(|e| Error::io(dir, e))?.path();
            if path.extension().and_then(|x| x.to_str()) != Some("json") {
                continue;
            }
            let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
            let k: usize = stem.parse().map_err(|_| {
                Error::bad_file(
                    &path,
                    "a landmark file's name must be its frame number (NNNN.json)",
                )
            })?;
            crate::video::head::check_frame(k, inp.clip.len(), &path)?;
            let lm = Landmarks::load(&path, Some(size))?;
            out.insert(k, (path, lm));
        }
    }
    if let Some(l) = &inp.ann.landmarks {
        out.insert(
            inp.ann.reference,
            (l.clone(), Landmarks::load(l, Some(size))?),
        );
    }
    Ok(out)
}

/// A stamp of the inputs: a resumed run must have been started with the same ones.
fn signature(inp: &VideoInputs, mp: &ModelParams, tp: &TrackParams) -> Result<serde_json::Value> {
    let stamp = |p: &Path| -> Result<serde_json::Value> {
        let m = std::fs::metadata(p).map_err(|e| Error::io(p, e))?;
        let t = m
            .modified()
            .ok()
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_nanos() as u64);
        Ok(json!([p.display().to_string(), m.len(), t]))
    };
    let mut files = Vec::new();
    for f in &inp.clip.frames {
        files.push(stamp(f)?);
    }
    for p in [
        &Some(inp.ann.strokes.clone()),
        &inp.ann.mask,
        &inp.ann.landmarks,
        &inp.ann.points,
    ]
    .into_iter()
    .flatten()
    {
        files.push(stamp(p)?);
    }
    Ok(json!({
        "files": files,
        "reference": inp.ann.reference,
        "landmark_dir": inp.ann.landmark_dir.as_ref().map(|d| d.display().to_string()),
        "model": mp,
        "track": tp,
    }))
}

/// Test hook: with `COIF_VIDEO_STOP_AFTER=N` in the environment a run returns an error
/// right after it has finished (and recorded) N frames, as if it had been stopped there.
/// The resume tests use it to stop a run half-way at a known point; nobody else should.
pub const STOP_AFTER_ENV: &str = "COIF_VIDEO_STOP_AFTER";

fn stop_hook() -> Result<Option<usize>> {
    match std::env::var(STOP_AFTER_ENV) {
        Err(_) => Ok(None),
        Ok(v) => v.trim().parse().map(Some).map_err(|_| {
            Error::Invalid(format!(
                "{STOP_AFTER_ENV}={v}: expected a whole number of frames"
            ))
        }),
    }
}

/// Before a run that resumes nothing writes anything: progress.json first records these
/// inputs with no frame done (a stop from now on cannot resume an older run's frames under
/// this run's model), then an older run's per-frame files go, so that none of them mixes
/// with this run's (a longer clip's extra frames, say). Only in a folder an earlier run
/// wrote (it has a progress.json): files of ours by name, nothing else.
fn start_afresh(out: &Path, sig: &serde_json::Value) -> Result<()> {
    let progress = out.join("progress.json");
    if !progress.exists() {
        return Ok(());
    }
    write_json(&progress, &progress_json(sig, &[]))?;
    for (dir, ext) in [
        ("frames", "hair"),
        ("photos", "png"),
        ("masks", "png"),
        ("warps", "npy"),
    ] {
        let d = out.join(dir);
        let Ok(rd) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in rd.flatten() {
            let p = e.path();
            let ours = p.extension().and_then(|x| x.to_str()) == Some(ext)
                && p.file_stem()
                    .and_then(|x| x.to_str())
                    .is_some_and(|x| !x.is_empty() && x.bytes().all(|b| b.is_ascii_digit()));
            if ours {
                std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
            }
        }
    }
    for f in ["video.json", "preview.gif"] {
        let p = out.join(f);
        if p.exists() {
            std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
        }
    }
    Ok(())
}

/// progress.json: the inputs (for people to read), the same as one compact JSON text (what a
/// resumed run compares) and the frames done.
fn progress_json(sig: &serde_json::Value, done: &[usize]) -> serde_json::Value {
    json!({ "inputs": sig, "key": sig.to_string(), "done": done })
}

fn read_progress(out: &Path, sig: &serde_json::Value) -> Vec<usize> {
    let Ok(text) = std::fs::read_to_string(out.join("progress.json")) else {
        return Vec::new();
    };
    let Ok(v) = serde_json::from_str::<serde_json::Value>(&text) else {
        return Vec::new();
    };
    // By text: JSON numbers read back need not equal the f32 settings they were written from
    // to the last bit, so comparing parsed values would never resume.
    if v.get("key").and_then(|k| k.as_str()) != Some(sig.to_string().as_str()) {
        return Vec::new();
    }
    v.get("done")
        .and_then(|d| serde_json::from_value(d.clone()).ok())
        .unwrap_or_default()
}

/// Runs `coif video`: the reference model, then every frame, writing as it goes.
pub fn run(
    engine: &Engine,
    inp: &VideoInputs,
    mp: &ModelParams,
    tp: &TrackParams,
    out: &Path,
    progress: bool,
) -> anyhow::Result<VideoRun> {
    use anyhow::Context;
    let t0 = Instant::now();
    let n = inp.clip.len();
    if inp.ann.reference >= n {
        return Err(Error::Invalid(format!(
            "reference frame {} is out of range: the clip has {n} frames (0..{})",
            inp.ann.reference,
            n - 1
        ))
        .into());
    }
    let size = (inp.clip.width, inp.clip.height);
    let lm_files = load_landmarks(inp, size)?;
    let landmarks: BTreeMap<usize, Landmarks> =
        lm_files.iter().map(|(k, (_, l))| (*k, l.clone())).collect();
    let user = match &inp.ann.points {
        Some(p) => load_points(p, size.0, size.1, n)?,
        None => UserPoints::default(),
    };
    for d in ["frames", "photos", "masks", "warps"] {
        ensure_dir(&out.join(d))?;
    }
    let sig = signature(inp, mp, tp)?;
    let mut done = read_progress(out, &sig);
    let resumed = done.len();
    if done.is_empty() {
        start_afresh(out, &sig)?;
    }
    let stop_after = stop_hook()?;
    let mut computed = 0usize;

    // The reference model, or the one a stopped run of the same inputs already wrote.
    let ref_png = inp.clip.frames[inp.ann.reference].clone();
    let stage = crate::timings::stage;
    let reference_model = stage("reference_model");
    let scene = if done.contains(&inp.ann.reference) {
        Scene::load(out).context("resuming: the reference model")?
    } else {
        // The reference's landmarks: its own file, else its file in the landmark folder.
        let ref_lm = lm_files.get(&inp.ann.reference).map(|(p, _)| p.clone());
        let (rgb, m) = crate::model::run(
            engine,
            &ref_png,
            &inp.ann.strokes,
            inp.ann.mask.as_deref(),
            ref_lm.as_deref(),
            mp,
        )?;
        crate::model::write(out, &ref_png, &rgb, &m, mp, &engine.describe())?;
        Scene::load(out)?
    };
    let r = Reference {
        index: inp.ann.reference,
        strands: scene.strands.clone(),
        camera: scene.camera.context("the reference model has no camera")?,
        head: scene
            .head
            .clone()
            .context("the reference model has no head")?,
        mask: scene
            .mask
            .clone()
            .context("the reference model has no hair mask")?,
    };
    let beta_v = crate::video::warp::beta(&r.strands, tp.beta_ramp_m);
    drop(reference_model);
    let features_stage = stage("features");

    // Gray frames for the features; every frame is loaded once here to check it.
    let rgb_ref = inp.clip.load_rgb(inp.ann.reference)?;
    let mut gray = Vec::with_capacity(n);
    for k in 0..n {
        gray.push(GrayImage::from_rgb(&inp.clip.load_rgb(k)?));
    }
    let feats = features(engine, &gray, &r, &user, tp).context("tracking features")?;
    // The tracks, for a user who corrects points (`--points`) and for inspection.
    let face: std::collections::BTreeSet<usize> = feats.face.iter().map(|f| f.0).collect();
    let list: Vec<serde_json::Value> = (0..feats.tracks.ids.len())
        .map(|k| {
            json!({
                "id": feats.tracks.ids[k],
                "user": feats.tracks.user[k],
                "face": face.contains(&k),
                "points": feats.tracks.points[k],
                "fb_error_px": feats.tracks.fb_error[k].iter().map(|e| if e.is_finite() { Some(*e) } else { None }).collect::<Vec<_>>(),
            })
        })
        .collect();
    write_json(
        &out.join("features.json"),
        &json!({ "version": 1, "reference": inp.ann.reference, "features": list }),
    )?;
    drop(features_stage);
    let frames_stage = stage("frames");
    let guide = Guide::from_rgb(&rgb_ref);
    let surface = reference_surface(&r, size.0, size.1);

    let bar = if progress {
        indicatif::ProgressBar::new(n as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("video {bar:30} {pos}/{len} frames {eta}")
            .expect("static template"),
    );
    let mut per_frame: BTreeMap<usize, FrameFigures> = BTreeMap::new();
    if let Ok(text) = std::fs::read_to_string(out.join("video.json")) {
        if let Ok(v) = serde_json::from_str::<serde_json::Value>(&text) {
            if let Some(pf) = v.get("per_frame") {
                if let Ok(list) = serde_json::from_value::<Vec<FrameFigures>>(pf.clone()) {
                    for f in list.into_iter().filter(|f| done.contains(&f.frame)) {
                        per_frame.insert(f.frame, f);
                    }
                }
            }
        }
    }
    // State carried along the recursion: W*, the orientation features and the pose of the
    // frame it comes from.
    let mut carry: BTreeMap<usize, (Vec<[f32; 2]>, FramePose)> = BTreeMap::new();
    let mut feat_cache: BTreeMap<usize, FlowFeatures> = BTreeMap::new();
    for (i, from) in order(n, inp.ann.reference) {
        let t = Instant::now();
        if done.contains(&i) {
            // Resume: the frame's warp and pose from its files.
            let (shape, data) = crate::io::npy::read_f32(&out.join(frame_name("warps", i, "npy")))?;
            if shape != [size.1 as usize, size.0 as usize, 2] {
                return Err(Error::bad_file(
                    out.join(frame_name("warps", i, "npy")),
                    format!("shape {shape:?}, expected [{}, {}, 2]", size.1, size.0),
                )
                .into());
            }
            let w: Vec<[f32; 2]> = data.chunks(2).map(|c| [c[0], c[1]]).collect();
            let pose = per_frame
                .get(&i)
                .map(|f| f.pose)
                .context("resuming: video.json lacks a finished frame")?;
            carry.insert(i, (w, pose));
            bar.inc(1);
            continue;
        }
        let mut feat = |k: usize| -> Result<FlowFeatures> {
            if let Some(f) = feat_cache.get(&k) {
                return Ok(f.clone());
            }
            let f = orientation_features(engine, &gray[k], &tp.orient)?;
            feat_cache.insert(k, f.clone());
            Ok(f)
        };
        let (res, pose) = match from {
            None => {
                let pose = frame_camera(
                    &r,
                    i,
                    size,
                    &landmarks,
                    &feats,
                    &dummy_pose(&r),
                    &tp.head_fit,
                )?;
                (step(engine, &r, &[], None, pose, &beta_v, size, tp)?, pose)
            }
            Some(j) => {
                let v = crate::video::flow::flow(
                    engine,
                    &feat(j)?,
                    &feat(i)?,
                    size.0,
                    size.1,
                    &tp.flow,
                )
                .with_context(|| format!("flow from frame {j} to {i}"))?;
                let (wprev, prev_pose) = carry.get(&j).context("recursion order")?;
                let pose = frame_camera(&r, i, size, &landmarks, &feats, prev_pose, &tp.head_fit)?;
                let rigid = rigid_motion(&surface, &pose.camera, size.0);
                let wdag = feature_warp(
                    engine,
                    &guide,
                    &feats.tracks,
                    i,
                    tp.spread_residual.then_some(rigid.as_slice()),
                    &tp.diffuse,
                )?;
                let res = step(
                    engine,
                    &r,
                    &wdag,
                    Some((wprev, &v)),
                    pose,
                    &beta_v,
                    size,
                    tp,
                )?;
                (res, pose)
            }
        };
        // Drop features of frames the recursion has passed.
        feat_cache.retain(|&k, _| k == i);
        write_frame(out, i, inp, &r, &res.strands, &res.mask, &res.wstar, &pose)?;
        let fb: Vec<f32> = feats
            .tracks
            .fb_error
            .iter()
            .map(|e| e[i])
            .filter(|v| v.is_finite())
            .collect();
        per_frame.insert(
            i,
            FrameFigures {
                frame: i,
                pose,
                yaw_deg: pose_of(&r.camera, &pose.camera)[0],
                features: feats.tracks.alive(i),
                fb_median_px: crate::base::stats::percentile(&fb, 0.5),
                seconds: t.elapsed().as_secs_f64(),
            },
        );
        carry.insert(i, (res.wstar, pose));
        done.push(i);
        write_progress(out, &sig, &done, &per_frame)?;
        bar.inc(1);
        computed += 1;
        // A frame boundary: the frames done so far are recorded, a rerun resumes after them.
        crate::interrupt::check()?;
        if stop_after == Some(computed) {
            return Err(Error::Invalid(format!(
                "stopped after {computed} frames ({STOP_AFTER_ENV} test hook)"
            ))
            .into());
        }
    }
    bar.finish_and_clear();
    drop(frames_stage);
    let _s = stage("write");

    // The scene with its animation, and the preview, once every frame is there.
    let mut cams = Vec::with_capacity(n);
    let mut poses = Vec::with_capacity(n);
    for k in 0..n {
        let f = per_frame
            .get(&k)
            .context("a frame is missing from the run")?;
        cams.push(world_camera(&r.camera, &f.pose.camera));
        poses.push(pose_of(&r.camera, &f.pose.camera));
    }
    let mut s = scene.clone();
    s.dir = out.to_path_buf();
    s.animation = Some(Animation {
        fps: inp.clip.fps.unwrap_or(24.0),
        frames: (0..n).map(|k| frame_name("frames", k, "hair")).collect(),
        head: poses,
        footage: Some(Footage {
            photos: (0..n).map(|k| frame_name("photos", k, "png")).collect(),
            masks: (0..n).map(|k| frame_name("masks", k, "png")).collect(),
            cameras: cams,
        }),
    });
    s.save(out, json!({ "video": "video.json" }))?;
    let gif = preview(&s)?;
    crate::io::write_atomic(&out.join("preview.gif"), &gif)?;
    Ok(VideoRun {
        frames: n,
        resumed,
        per_frame: per_frame.into_values().collect(),
        seconds: t0.elapsed().as_secs_f64(),
        backend: engine.describe(),
    })
}

fn dummy_pose(r: &Reference) -> FramePose {
    FramePose {
        camera: r.camera,
        source: crate::video::head::PoseSource::Reference,
        points: 0,
        rms_px: 0.0,
    }
}

#[allow(clippy::too_many_arguments)]
fn write_frame(
    out: &Path,
    i: usize,
    inp: &VideoInputs,
    r: &Reference,
    head_space: &StrandSet,
    mask: &[u8],
    wstar: &[[f32; 2]],
    pose: &FramePose,
) -> Result<()> {
    let (w, h) = (inp.clip.width, inp.clip.height);
    let (rot, tr) = pose_rigid(&r.camera, &pose.camera);
    let world: Vec<[f32; 3]> = head_space
        .points
        .iter()
        .map(|p| (rot * glam::Vec3::from_array(*p) + tr).to_array())
        .collect();
    crate::io::strands::write(
        &out.join(frame_name("frames", i, "hair")),
        &StrandSet::new(world, head_space.counts.clone()),
    )?;
    write_png(
        &out.join(frame_name("photos", i, "png")),
        &inp.clip.load_rgb(i)?,
    )?;
    write_png(
        &out.join(frame_name("masks", i, "png")),
        &image::GrayImage::from_raw(w, h, mask.to_vec()).expect("mask size"),
    )?;
    let flat: Vec<f32> = wstar.iter().flatten().copied().collect();
    crate::io::npy::write_f32(
        &out.join(frame_name("warps", i, "npy")),
        &[h as usize, w as usize, 2],
        &flat,
    )
}

fn write_progress(
    out: &Path,
    sig: &serde_json::Value,
    done: &[usize],
    per_frame: &BTreeMap<usize, FrameFigures>,
) -> Result<()> {
    let list: Vec<&FrameFigures> = per_frame.values().collect();
    write_json(
        &out.join("video.json"),
        &json!({ "version": 1, "per_frame": list }),
    )?;
    // Written last: a frame counts as done only once all its files are.
    write_json(&out.join("progress.json"), &progress_json(sig, done))
}

/// Every frame's strands over its photo, dimmed, as an animated GIF.
pub fn preview(s: &Scene) -> Result<Vec<u8>> {
    let a = s.animation.as_ref().expect("a tracked scene");
    crate::sim::run::preview_gif_with(a.frames.len(), a.fps, |k| {
        let f = s.footage_frame(k)?.expect("a scene with footage");
        let photo = f.photo.as_ref().expect("footage has a photo");
        Ok((
            crate::io::vis::dimmed(photo, 0.35),
            f.camera.expect("footage has a camera"),
            f.strands,
        ))
    })
}
