//! The tracking core of C13 §3, in memory: given the clip's frames and the model built on
//! the reference frame, the per-frame motion inputs (flow V_i on orientation fields,
//! features tracked from the reference), the warps W*_i of Eq. (6), the head cameras M_i
//! and the strands of Eq. (7). [`crate::video::run`] adds files, resuming and progress.
//!
//! Frames after the reference run forward (V_i from frame i−1 to i); frames before it run
//! backward the same way (V_i from frame i+1 to i, W*_{i+1} in place of W*_{i−1}): the
//! paper writes only i > r, and this is its mirror image.

use crate::analyze::orient::{orient, GrayImage, OrientParams};
use crate::error::{Error, Result};
use crate::gpu::engine::Engine;
use crate::hair::head::{fit_landmarks, Head, WeakPerspective};
use crate::hair::strands::StrandSet;
use crate::io::annot::Landmarks;
use crate::video::diffuse::{spread, DiffuseParams, Guide};
use crate::video::features::{detect, track, KltParams, Tracks, UserPoints};
use crate::video::flow::{orient_features, FlowFeatures, FlowParams};
use crate::video::head::{back_project, fit_features, FramePose, HeadFitParams, PoseSource};
use crate::video::warp::{compose, warp_strands, PAPER_ALPHA};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;

/// Everything `coif video` can tune, with the defaults the issue-15 note measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrackParams {
    /// Weight of the feature warp in Eq. (6); ½ in the paper, 0 flow alone, 1 features alone.
    pub alpha: f32,
    /// Arc length (m) over which β of Eq. (7) rises from 0 at the root to 1.
    pub beta_ramp_m: f32,
    pub orient: OrientParams,
    pub flow: FlowParams,
    pub klt: KltParams,
    pub diffuse: DiffuseParams,
    pub head_fit: HeadFitParams,
    /// Pixels the reference hair mask grows by to take hair features (and to keep face
    /// features off the hair's edge).
    pub mask_margin_px: u32,
    /// Spread the features' departure from the head's rigid motion (and add that motion
    /// back) rather than their raw motion. Measured (`cargo bench --bench video`, 256², 61
    /// frames): Eq. 6's mean drift at r+30 / r+60 went from 1.62 / 1.70 to 1.73 / 1.70 px
    /// (long) and from 0.56 / 0.89 to 0.77 / 0.98 px (side parting), so it is off.
    pub spread_residual: bool,
}

impl Default for TrackParams {
    fn default() -> Self {
        TrackParams {
            alpha: PAPER_ALPHA,
            beta_ramp_m: 0.03,
            orient: crate::video::flow::feature_orient_params(),
            flow: FlowParams::default(),
            klt: KltParams::default(),
            diffuse: DiffuseParams::default(),
            head_fit: HeadFitParams::default(),
            mask_margin_px: 2,
            spread_residual: false,
        }
    }
}

/// What the reference frame's model gives the tracker.
#[derive(Clone, Debug)]
pub struct Reference {
    pub index: usize,
    /// Head model space strands.
    pub strands: StrandSet,
    pub camera: WeakPerspective,
    pub head: Head,
    /// Hair mask of the reference frame (nonzero = hair).
    pub mask: Vec<u8>,
}

/// The order frames are processed in: the reference, then forward to the end, then backward
/// to the start; each with the frame its recursion comes from.
pub fn order(frames: usize, r: usize) -> Vec<(usize, Option<usize>)> {
    let mut o = vec![(r, None)];
    o.extend((r + 1..frames).map(|i| (i, Some(i - 1))));
    o.extend((0..r).rev().map(|i| (i, Some(i + 1))));
    o
}

/// The matched features of every frame: orientation on the whole frame (hair moves out of
/// the reference mask), w·(cos 2θ, sin 2θ) ([`orient_features`]).
pub fn orientation_features(
    engine: &Engine,
    gray: &GrayImage,
    p: &OrientParams,
) -> Result<FlowFeatures> {
    Ok(orient_features(&orient(engine, gray, None, p)?))
}

/// Pixels of the reference frame on the head's face: the head is hit and the pixel is not
/// hair (the hair mask grown by `margin`).
pub fn face_mask(r: &Reference, width: u32, height: u32, margin: u32) -> Vec<u8> {
    let hair = crate::base::mask::dilate(&r.mask, width as usize, height as usize, margin as usize);
    (0..(width * height) as usize)
        .into_par_iter()
        .map(|i| {
            let p = [(i % width as usize) as f32, (i / width as usize) as f32];
            (hair[i] == 0 && back_project(&r.head, &r.camera, p).is_some()) as u8
        })
        .collect()
}

/// Features detected on the reference frame's hair and face, tracked through the clip.
pub struct Features {
    pub tracks: Tracks,
    /// Model points under the face features (index into `tracks`), for the head fit.
    pub face: Vec<(usize, Vec3)>,
    pub hair_count: usize,
}

/// Detects features on the hair (grown mask) and on the face separately, so neither crowds
/// the other out of the strongest-first budget, and tracks them all.
pub fn features(
    engine: &Engine,
    gray: &[GrayImage],
    r: &Reference,
    user: &UserPoints,
    p: &TrackParams,
) -> Result<Features> {
    let g = &gray[r.index];
    let (w, h) = (g.width, g.height);
    let hair =
        crate::base::mask::dilate(&r.mask, w as usize, h as usize, p.mask_margin_px as usize);
    let face = face_mask(r, w, h, p.mask_margin_px);
    let mut pts = detect(engine, g, Some(&hair), &p.klt)?;
    let hair_count = pts.len();
    pts.extend(detect(engine, g, Some(&face), &p.klt)?);
    let tracks = track(engine, gray, r.index, &pts, user, &p.klt)?;
    let mut face_pts = Vec::new();
    for (k, f) in tracks.points.iter().enumerate() {
        let Some(q) = f[r.index] else { continue };
        let i = (q[1].round() as usize).min(h as usize - 1) * w as usize
            + (q[0].round() as usize).min(w as usize - 1);
        if face[i] != 0 {
            if let Some(x) = back_project(&r.head, &r.camera, q) {
                face_pts.push((k, x));
            }
        }
    }
    Ok(Features {
        tracks,
        face: face_pts,
        hair_count,
    })
}

/// The model point seen at every reference pixel: the nearest strand vertex projecting into
/// it (holes in the hair filled from the nearest neighbours within the hair mask), else the
/// head's surface, else none (background). What the head's rigid motion moves each pixel by.
pub fn reference_surface(r: &Reference, width: u32, height: u32) -> Vec<Option<Vec3>> {
    let (w, h) = (width as usize, height as usize);
    let mut best: Vec<Option<(f32, Vec3)>> = vec![None; w * h];
    for p in &r.strands.points {
        let v = Vec3::from_array(*p);
        let q = r.camera.project(v);
        let (x, y) = (q.x.round(), q.y.round());
        if x < 0.0 || y < 0.0 || x >= w as f32 || y >= h as f32 {
            continue;
        }
        let i = y as usize * w + x as usize;
        if best[i].is_none_or(|(z, _)| q.z > z) {
            best[i] = Some((q.z, v));
        }
    }
    // Hair pixels between projected vertices take a neighbour's point (a few rounds).
    for _ in 0..4 {
        let prev = best.clone();
        for i in 0..w * h {
            if prev[i].is_some() || r.mask[i] == 0 {
                continue;
            }
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            let mut pick: Option<(f32, Vec3)> = None;
            for (dx, dy) in crate::base::mask::NEIGHBOURS_8 {
                let (nx, ny) = (x + dx as i64, y + dy as i64);
                if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                    continue;
                }
                if let Some(c) = prev[ny as usize * w + nx as usize] {
                    if pick.is_none_or(|(z, _)| c.0 > z) {
                        pick = Some(c);
                    }
                }
            }
            best[i] = pick;
        }
    }
    best.into_par_iter()
        .enumerate()
        .map(|(i, b)| {
            b.map(|(_, v)| v).or_else(|| {
                let p = [(i % w) as f32, (i / w) as f32];
                back_project(&r.head, &r.camera, p)
            })
        })
        .collect()
}

/// The image motion from the reference to frame i were everything to move rigidly with the
/// head: C_i(X(p)) − p for the surface point X(p) of every reference pixel, 0 on the
/// background.
pub fn rigid_motion(
    surface: &[Option<Vec3>],
    cam_i: &crate::hair::head::WeakPerspective,
    width: u32,
) -> Vec<[f32; 2]> {
    surface
        .par_iter()
        .enumerate()
        .map(|(i, x)| match x {
            Some(x) => {
                let q = cam_i.project(*x);
                [
                    q.x - (i % width as usize) as f32,
                    q.y - (i / width as usize) as f32,
                ]
            }
            None => [0.0, 0.0],
        })
        .collect()
}

/// W†_i: every feature known on the reference and on frame i, spread edge-aware over the
/// reference frame. With `rigid` (the head's rigid motion per pixel), the features'
/// departure from it is spread and the motion added back, so a pixel far from every feature
/// stays on the head's motion instead of a blur of distant features' motions; pixels no
/// feature reaches take the rigid motion. Without it, those pixels are marked unknown for
/// Eq. (6) (≥ 1e30), where the flow alone carries the warp.
pub fn feature_warp(
    engine: &Engine,
    guide: &Guide,
    tracks: &Tracks,
    i: usize,
    rigid: Option<&[[f32; 2]]>,
    p: &DiffuseParams,
) -> Result<Vec<[f32; 2]>> {
    let (w, h) = (guide.width, guide.height);
    let Some(rigid) = rigid else {
        let mut f = spread(engine, guide, &tracks.samples(i), p)?;
        for v in &mut f {
            if !(v[0].is_finite() && v[1].is_finite()) {
                *v = [crate::stages::warp_compose::UNKNOWN; 2];
            }
        }
        return Ok(f);
    };
    let flat: Vec<f32> = rigid.iter().flatten().copied().collect();
    let samples: Vec<([f32; 2], [f32; 2])> = tracks
        .samples(i)
        .into_iter()
        .map(|(q, d)| {
            let m = crate::stages::warp_compose::sample2(&flat, w, h, q[0], q[1]);
            (q, [d[0] - m[0], d[1] - m[1]])
        })
        .collect();
    let res = spread(engine, guide, &samples, p)?;
    Ok(res
        .iter()
        .zip(rigid)
        .map(|(d, m)| {
            if d[0].is_finite() && d[1].is_finite() {
                [m[0] + d[0], m[1] + d[1]]
            } else {
                *m
            }
        })
        .collect())
}

/// Frame i's camera: the user's landmarks for that frame when given, else the face features.
#[allow(clippy::too_many_arguments)]
pub fn frame_camera(
    r: &Reference,
    i: usize,
    size: (u32, u32),
    landmarks: &BTreeMap<usize, Landmarks>,
    feats: &Features,
    prev: &FramePose,
    p: &HeadFitParams,
) -> Result<FramePose> {
    if i == r.index && !landmarks.contains_key(&i) {
        return Ok(FramePose {
            camera: r.camera,
            source: PoseSource::Reference,
            points: 0,
            rms_px: 0.0,
        });
    }
    if let Some(lm) = landmarks.get(&i) {
        let (camera, rep) = fit_landmarks(&r.head, lm, size)
            .map_err(|e| Error::Invalid(format!("landmarks of frame {i}: {e}")))?;
        return Ok(FramePose {
            camera,
            source: PoseSource::Landmarks,
            points: rep.points.len(),
            rms_px: rep.rms_px.unwrap_or(0.0),
        });
    }
    let (mut anchors, mut seen) = (Vec::new(), Vec::new());
    for &(k, x) in &feats.face {
        if let Some(q) = feats.tracks.points[k][i] {
            anchors.push(x);
            seen.push(Vec2::from_array(q));
        }
    }
    Ok(match fit_features(&anchors, &seen, size, &prev.camera, p) {
        Some((camera, points, rms_px)) => FramePose {
            camera,
            source: PoseSource::Features,
            points,
            rms_px,
        },
        None => FramePose {
            source: PoseSource::Held,
            points: anchors.len(),
            ..*prev
        },
    })
}

/// The hair mask of frame i: the reference mask carried by W*_i (forward splat) and closed
/// by one pixel, which fills the holes a stretching splat leaves without growing it (the
/// renderer adds its own margin before inpainting).
pub fn warp_mask(mask: &[u8], wstar: &[[f32; 2]], width: u32, height: u32) -> Vec<u8> {
    let (w, h) = (width as usize, height as usize);
    let mut out = vec![0u8; w * h];
    for (i, &m) in mask.iter().enumerate() {
        if m == 0 {
            continue;
        }
        let d = wstar[i];
        if !(d[0].is_finite() && d[1].is_finite()) || d[0].abs() >= 1e29 {
            continue;
        }
        let x = (i % w) as f32 + d[0];
        let y = (i / w) as f32 + d[1];
        let (xi, yi) = (x.round(), y.round());
        if xi >= 0.0 && yi >= 0.0 && (xi as usize) < w && (yi as usize) < h {
            out[yi as usize * w + xi as usize] = 255;
        }
    }
    // Erosion clears the image's border; the splat's own pixels stay.
    let closed = crate::base::mask::erode(&crate::base::mask::dilate(&out, w, h, 1), w, h, 1);
    closed
        .into_iter()
        .zip(&out)
        .map(|(c, o)| if c != 0 || *o != 0 { 255 } else { 0 })
        .collect()
}

/// One frame's result.
pub struct FrameResult {
    pub wstar: Vec<[f32; 2]>,
    pub pose: FramePose,
    /// Head model space.
    pub strands: StrandSet,
    pub mask: Vec<u8>,
}

/// A 2D vector field borrowed (W*, V), px.
pub type FieldRef<'a> = &'a [[f32; 2]];

/// Frame i from its recursion source: Eq. (6) then Eq. (7). `prev` is W*_j of the frame the
/// recursion comes from (j = i ∓ 1), `flow_ji` the flow from frame j to frame i.
#[allow(clippy::too_many_arguments)]
pub fn step(
    engine: &Engine,
    r: &Reference,
    wdag: &[[f32; 2]],
    prev: Option<(FieldRef, FieldRef)>,
    pose: FramePose,
    beta_v: &[f32],
    size: (u32, u32),
    p: &TrackParams,
) -> Result<FrameResult> {
    let (w, h) = size;
    let wstar = match prev {
        // W*_r = 0 (the paper's boundary condition).
        None => vec![[0.0f32; 2]; (w * h) as usize],
        Some((wprev, v)) => compose(engine, wdag, wprev, v, w, h, p.alpha)?,
    };
    let strands = warp_strands(
        engine,
        &r.strands,
        beta_v,
        &wstar,
        w,
        h,
        &r.camera,
        &pose.camera,
    )?;
    let mask = warp_mask(&r.mask, &wstar, w, h);
    Ok(FrameResult {
        wstar,
        pose,
        strands,
        mask,
    })
}
