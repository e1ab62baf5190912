//! The head's rigid motion M_i through a clip. C13 uses a multilinear face tracker; here a
//! frame's camera comes from the user's landmarks where a file is given for it, and
//! otherwise from features tracked on the face: each is back-projected onto the head fitted
//! on the reference frame, and the frame's weak-perspective camera is fitted to where the
//! features are now ([`crate::hair::head::fit_points`]), dropping outliers (a feature that
//! slid onto moving hair) by their reprojection error. Light, sequential work: CPU.
//!
//! The strands stay in head model space, where the head does not move; a frame's camera
//! carries the motion. For files that expect a moving head in a fixed world (animated USD,
//! the simulator) [`pose_of`] turns the camera pair into the head pose of
//! `crate::sim::track` and [`world_camera`] into the camera that sees the posed strands.

use crate::error::{Error, Result};
use crate::hair::head::{fit_points, Head, WeakPerspective};
use glam::{EulerRot, Mat3, Vec2, Vec3};
use serde::{Deserialize, Serialize};

/// Where a frame's camera came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PoseSource {
    /// The reference frame: the model's own camera.
    Reference,
    /// The user's landmarks for that frame.
    Landmarks,
    /// Features tracked on the face.
    Features,
    /// Too few face features survived: the previous frame's camera is kept.
    Held,
}

/// A frame's camera and how it was found.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FramePose {
    pub camera: WeakPerspective,
    pub source: PoseSource,
    /// Points used (inliers) and their RMS reprojection error, px.
    pub points: usize,
    pub rms_px: f32,
}

/// Knobs of the feature-based fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeadFitParams {
    /// Fewest inlier face features for a fit; fewer and the previous camera is held.
    pub min_points: usize,
    /// A feature is an outlier when its error exceeds this many times the median error,
    /// and at least [`HeadFitParams::min_outlier_px`].
    pub outlier_factor: f32,
    pub min_outlier_px: f32,
}

impl Default for HeadFitParams {
    fn default() -> Self {
        HeadFitParams {
            min_points: 8,
            outlier_factor: 3.0,
            min_outlier_px: 1.0,
        }
    }
}

/// The model point under the reference pixel `p` on the head's front surface, or None when
/// the ray misses the head.
pub fn back_project(head: &Head, cam: &WeakPerspective, p: [f32; 2]) -> Option<Vec3> {
    // Into the scene; the ray starts well in front of the head, on the camera's side.
    let into = cam.view_dir_model();
    let near = cam.unproject(Vec3::new(p[0], p[1], 0.0)) - into * 0.5;
    head.raycast(near, into, 1.0)
}

/// Fits frame i's camera to face anchors (model points) and where the tracked features are
/// in that frame, starting from the previous frame's camera, with rounds of outlier
/// rejection. None when fewer than
/// `p.min_points` pairs are available or survive.
pub fn fit_features(
    anchors: &[Vec3],
    tracked: &[Vec2],
    size: (u32, u32),
    prev: &WeakPerspective,
    p: &HeadFitParams,
) -> Option<(WeakPerspective, usize, f32)> {
    let mut idx: Vec<usize> = (0..anchors.len()).collect();
    let mut best = None;
    for _ in 0..4 {
        if idx.len() < p.min_points.max(4) {
            break;
        }
        let m: Vec<Vec3> = idx.iter().map(|&i| anchors[i]).collect();
        let q: Vec<Vec2> = idx.iter().map(|&i| tracked[i]).collect();
        let Ok((cam, _)) = fit_points(&m, &q, size, Some(prev)) else {
            break;
        };
        // Errors of every pair, so a feature dropped early can come back.
        let err: Vec<f32> = anchors
            .iter()
            .zip(tracked)
            .map(|(a, t)| {
                let r = cam.project(*a);
                (Vec2::new(r.x, r.y) - *t).length()
            })
            .collect();
        let mut cur: Vec<f32> = idx.iter().map(|&i| err[i]).collect();
        cur.sort_by(f32::total_cmp);
        let med = cur[cur.len() / 2];
        let lim = (p.outlier_factor * med).max(p.min_outlier_px);
        let keep: Vec<usize> = (0..anchors.len()).filter(|&i| err[i] <= lim).collect();
        let rms = (idx.iter().map(|&i| err[i] * err[i]).sum::<f32>() / idx.len() as f32).sqrt();
        best = Some((cam, idx.len(), rms));
        if keep == idx {
            break;
        }
        idx = keep;
    }
    best
}

/// The head pose (yaw, pitch, roll in degrees; translation in metres, as
/// `crate::sim::track` keys it) that moves the head so that the reference camera sees it as
/// frame i's camera does; exact but for a change of scale, which a rigid motion cannot show
/// ([`world_camera`] carries it).
pub fn pose_of(cam_r: &WeakPerspective, cam_i: &WeakPerspective) -> [f32; 6] {
    let rot = cam_r.r.transpose() * cam_i.r;
    let (y, x, z) = rot.to_euler(EulerRot::YXZ);
    let t = translation(cam_r, cam_i);
    [
        y.to_degrees(),
        -x.to_degrees(),
        z.to_degrees(),
        t.x,
        t.y,
        t.z,
    ]
}

/// The translation of [`pose_of`]: the model origin's image motion, at the reference scale.
fn translation(cam_r: &WeakPerspective, cam_i: &WeakPerspective) -> Vec3 {
    let d = cam_i.t - cam_r.t;
    cam_r.r.transpose() * Vec3::new(d.x / cam_r.s, -d.y / cam_r.s, 0.0)
}

/// The camera that sees the strands posed by [`pose_of`] exactly as `cam_i` sees them in
/// head space: the reference rotation, frame i's scale, and a translation that undoes the
/// pose's translation at that scale.
pub fn world_camera(cam_r: &WeakPerspective, cam_i: &WeakPerspective) -> WeakPerspective {
    let k = cam_i.s / cam_r.s;
    WeakPerspective::new(cam_i.s, cam_r.r, cam_i.t - k * (cam_i.t - cam_r.t))
}

/// The head pose's rigid transform as a rotation and translation.
pub fn pose_rigid(cam_r: &WeakPerspective, cam_i: &WeakPerspective) -> (Mat3, Vec3) {
    (cam_r.r.transpose() * cam_i.r, translation(cam_r, cam_i))
}

/// Yaw of `cam_i` relative to `cam_r`, degrees (the head pose's yaw).
pub fn relative_yaw_deg(cam_r: &WeakPerspective, cam_i: &WeakPerspective) -> f32 {
    pose_of(cam_r, cam_i)[0]
}

/// Checks that a landmark frame index names a frame of the clip.
pub fn check_frame(k: usize, frames: usize, what: &std::path::Path) -> Result<()> {
    if k >= frames {
        return Err(Error::bad_file(
            what,
            format!(
                "names frame {k}, but the clip has {frames} frames (0..{})",
                frames - 1
            ),
        ));
    }
    Ok(())
}
