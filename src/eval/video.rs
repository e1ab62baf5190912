//! Figures of video tracking against a synthetic clip's exact ground truth (issue 15): the
//! flow's end-point error on hair, the drift of W*_i (Eq. 6) against flow alone and
//! features alone, 3D vertex error, roots, head yaw, temporal flicker of the re-rendered
//! hair and seconds per frame. Shared by `tests/it/video_eval.rs` (small clips) and
//! `benches/video.rs` (the 256², 61-frame clips beside OpenCV's flows).
//!
//! The tracker starts from the ground-truth strands of frame 0 with the true camera, so the
//! 3D figures measure tracking alone, not single-view modelling (issue 4 measures that).

use crate::analyze::orient::GrayImage;
use crate::error::Result;
use crate::gpu::engine::Engine;
use crate::hair::head::WeakPerspective;
use crate::hair::scene::Scene;
use crate::hair::strands::StrandSet;
use crate::synth::video::{true_flow, visible_in, write_field, SynthVideo, VideoParams};
use crate::video::diffuse::Guide;
use crate::video::features::UserPoints;
use crate::video::head::{pose_of, FramePose, PoseSource};
use crate::video::track::{
    feature_warp, features, frame_camera, orientation_features, reference_surface, rigid_motion,
    step, Reference, TrackParams,
};
use crate::video::warp::compose;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

/// What to measure.
#[derive(Clone, Debug)]
pub struct EvalOptions {
    pub track: TrackParams,
    /// Eq. (6) weights whose drift is measured (the tracked strands use `track.alpha`).
    pub alphas: Vec<f32>,
    /// Frames (after the reference, frame 0) where drift is reported.
    pub drift_frames: Vec<usize>,
    /// Re-render every frame and measure flicker (the slowest part).
    pub flicker: bool,
    /// Moves the strands by the true warp from frame 0 (where a strand covers the pixel; the
    /// head's rigid motion elsewhere) instead of W*: the error Eq. (7) itself leaves.
    pub oracle_warp: bool,
    /// Composes Eq. (6) with the true flow on hair pixels (ours elsewhere) instead of ours:
    /// what Eq. (6) gives these features with a flow that makes no error.
    pub oracle_flow: bool,
    /// Writes `frames/NNNN.png` and `flow/NNNN.npy` (true flow, i ≥ 1) here, for the
    /// OpenCV peer script, and `ours/NNNN.npy` (our flow).
    pub write_dir: Option<PathBuf>,
}

impl Default for EvalOptions {
    fn default() -> Self {
        EvalOptions {
            track: TrackParams::default(),
            alphas: vec![0.5, 0.0, 1.0],
            drift_frames: vec![30, 60],
            flicker: true,
            oracle_warp: false,
            oracle_flow: false,
            write_dir: None,
        }
    }
}

/// Mean drift of a warp against the truth on the reference's hair pixels, px.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Drift {
    pub alpha: f32,
    pub frame: usize,
    pub mean_px: f32,
    pub median_px: f32,
    /// The same over the pixels whose material point is still in front at frame `frame`
    /// (no 2D tracker can see where a hidden point went).
    pub visible_mean_px: f32,
    pub visible_median_px: f32,
    /// Share of the reference's hair pixels that are visible at `frame`.
    pub visible_share: f32,
}

impl std::fmt::Display for Drift {
    /// One line: frame, weight, mean and median over all hair pixels and over the visible.
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "drift at frame {:>2}, alpha {:.1}: mean {:.3} px, median {:.3} px; visible ({:.0}%): mean {:.3} px, median {:.3} px",
            self.frame,
            self.alpha,
            self.mean_px,
            self.median_px,
            100.0 * self.visible_share,
            self.visible_mean_px,
            self.visible_median_px
        )
    }
}

/// The figures of one clip.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ClipFigures {
    /// Per frame pair (i−1, i): mean end-point error of our flow on hair pixels, px.
    pub flow_epe: Vec<f32>,
    /// Per frame pair: mean true motion on hair pixels, px (the scale of the EPE).
    pub flow_mean_motion: Vec<f32>,
    pub drift: Vec<Drift>,
    /// Per frame: median distance of the tracked vertices from their true positions, mm.
    pub vertex_median_mm: Vec<f32>,
    /// The same over the vertices visible on the reference frame (within 3 mm of the
    /// nearest vertex at their pixel): those whose motion the image shows. A hidden vertex
    /// takes the warp of what covers it (Eq. 7 knows no occlusion).
    pub vertex_visible_median_mm: Vec<f32>,
    /// Largest distance of a root from its true position (the head's motion), m.
    pub root_max_m: f32,
    /// 99th percentile (the largest over frames) and largest relative change of a segment's
    /// length
    /// (Eq. 7 does not keep lengths: neighbouring vertices a pixel apart sample the warp
    /// where it changes fast).
    pub stretch_p99: f32,
    pub stretch_max: f32,
    /// Largest error of the head's yaw relative to the reference, degrees, and of the
    /// whole relative rotation.
    pub yaw_err_max_deg: f32,
    pub rot_err_max_deg: f32,
    /// Frames whose camera came from face features / was held.
    pub pose_sources: BTreeMap<String, usize>,
    /// Features known on the last frame, of those on the reference.
    pub features_last: usize,
    pub features_reference: usize,
    /// Flicker of the re-rendered clip over that of the input, on the hair.
    pub flicker_ratio: Option<f32>,
    pub flicker_in: Option<f32>,
    pub flicker_out: Option<f32>,
    /// The same with the reference frame's vertex colours carried by the tracked strands
    /// (C13 §4's per-vertex colours, [`ColourSource::Vertex`](crate::render::ColourSource)):
    /// the photo mode samples each frame under the strands and so shows that frame's own
    /// flicker, while these colours move only with the tracking, so a strand that jitters
    /// shows here.
    pub flicker_vertex_ratio: Option<f32>,
    pub flicker_vertex_out: Option<f32>,
    /// Seconds per frame of tracking (orientation, flow, spread, Eq. 6, head fit, Eq. 7).
    pub seconds_per_frame: f64,
}

fn mean_epe(a: &[[f32; 2]], truth: &[[f32; 2]]) -> (f32, f32, usize) {
    let (mut e, mut m, mut n) = (0.0f64, 0.0f64, 0usize);
    for (p, t) in a.iter().zip(truth) {
        if t[0].is_finite() && t[1].is_finite() {
            e += (((p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2)) as f64).sqrt();
            m += ((t[0] * t[0] + t[1] * t[1]) as f64).sqrt();
            n += 1;
        }
    }
    let d = n.max(1) as f64;
    ((e / d) as f32, (m / d) as f32, n)
}

fn rot_err(
    cr: &WeakPerspective,
    ci: &WeakPerspective,
    gr: &WeakPerspective,
    gi: &WeakPerspective,
) -> (f32, f32) {
    let ours = cr.r.transpose() * ci.r;
    let truth = gr.r.transpose() * gi.r;
    let d = ours * truth.transpose();
    let c = ((d.x_axis.x + d.y_axis.y + d.z_axis.z - 1.0) * 0.5).clamp(-1.0, 1.0);
    let yaw = (pose_of(cr, ci)[0] - pose_of(gr, gi)[0]).abs();
    (yaw, c.acos().to_degrees())
}

/// Mean absolute temporal difference (0..255 per channel) over pixels of `region` pairs.
fn flicker(frames: &[image::RgbImage], region: &[Vec<bool>]) -> f32 {
    let mut acc = 0.0f64;
    let mut n = 0usize;
    for k in 1..frames.len() {
        let (a, b) = (frames[k - 1].as_raw(), frames[k].as_raw());
        for (i, &on) in region[k].iter().enumerate() {
            if on {
                for c in 0..3 {
                    acc += (a[3 * i + c] as f64 - b[3 * i + c] as f64).abs();
                }
                n += 3;
            }
        }
    }
    (acc / n.max(1) as f64) as f32
}

/// Generates the clip, tracks it from frame 0 and measures everything.
pub fn evaluate(engine: &Engine, vp: &VideoParams, o: &EvalOptions) -> Result<ClipFigures> {
    let sv = SynthVideo::new(vp)?;
    let n = vp.frames;
    let (w, h) = (vp.synth.width, vp.synth.height);
    let size = (w, h);
    if let Some(d) = &o.write_dir {
        for sub in ["frames", "flow", "ours"] {
            crate::io::ensure_dir(&d.join(sub))?;
        }
    }

    // Pass 1: images, masks, the true flow between neighbours and from frame 0.
    let f0 = sv.frame(0);
    let mut rgb = vec![f0.render.image.clone()];
    let mut masks = vec![f0.render.mask.as_raw().clone()];
    let mut true_flows: Vec<Vec<[f32; 2]>> = vec![Vec::new()];
    let mut tracks_gt: BTreeMap<usize, Vec<[f32; 2]>> = BTreeMap::new();
    let mut visible_gt: BTreeMap<usize, Vec<bool>> = BTreeMap::new();
    let mut prev = f0.clone();
    for i in 1..n {
        let f = sv.frame(i);
        true_flows.push(true_flow(&prev, &f));
        if o.drift_frames.contains(&i) || o.oracle_warp {
            tracks_gt.insert(i, true_flow(&f0, &f));
            visible_gt.insert(i, visible_in(&f0, &f));
        }
        rgb.push(f.render.image.clone());
        masks.push(f.render.mask.as_raw().clone());
        prev = f;
    }
    if let Some(d) = &o.write_dir {
        for (i, im) in rgb.iter().enumerate() {
            crate::io::write_png(&d.join(format!("frames/{i:04}.png")), im)?;
            if i > 0 {
                write_field(
                    &d.join(format!("flow/{i:04}.npy")),
                    w as usize,
                    h as usize,
                    &true_flows[i],
                )?;
            }
        }
    }

    let reference = Reference {
        index: 0,
        strands: f0.strand_set(),
        camera: f0.pose.camera,
        head: sv.scene.head.clone(),
        mask: masks[0].clone(),
    };
    let tp = &o.track;
    let t0 = Instant::now();
    let gray: Vec<GrayImage> = rgb.iter().map(GrayImage::from_rgb).collect();
    let feats = features(engine, &gray, &reference, &UserPoints::default(), tp)?;
    let guide = Guide::from_rgb(&rgb[0]);
    let beta_v = crate::video::warp::beta(&reference.strands, tp.beta_ramp_m);
    let surface = reference_surface(&reference, w, h);

    let mut flow_epe = Vec::new();
    let mut flow_mean_motion = Vec::new();
    let mut drift = Vec::new();
    let mut warps: Vec<Vec<[f32; 2]>> = vec![vec![[0.0; 2]; (w * h) as usize]; o.alphas.len()];
    let mut poses: Vec<FramePose> = Vec::with_capacity(n);
    let mut tracked: Vec<StrandSet> = Vec::with_capacity(n);
    let mut out_masks: Vec<Vec<u8>> = Vec::with_capacity(n);
    // No landmarks beyond frame 0's true camera: the head's motion comes from the face.
    let lm: BTreeMap<usize, crate::io::annot::Landmarks> = BTreeMap::new();
    let pose0 = frame_camera(
        &reference,
        0,
        size,
        &lm,
        &feats,
        &FramePose {
            camera: reference.camera,
            source: PoseSource::Reference,
            points: 0,
            rms_px: 0.0,
        },
        &tp.head_fit,
    )?;
    let r0 = step(engine, &reference, &[], None, pose0, &beta_v, size, tp)?;
    poses.push(pose0);
    tracked.push(r0.strands);
    out_masks.push(r0.mask);
    let mut feat_prev = orientation_features(engine, &gray[0], &tp.orient)?;
    let mut main_warp = vec![[0.0f32; 2]; (w * h) as usize];
    for i in 1..n {
        let feat_i = orientation_features(engine, &gray[i], &tp.orient)?;
        let v = crate::video::flow::flow(engine, &feat_prev, &feat_i, size.0, size.1, &tp.flow)?;
        let (e, m, _) = mean_epe(&v, &true_flows[i]);
        flow_epe.push(e);
        flow_mean_motion.push(m);
        if let Some(d) = &o.write_dir {
            write_field(
                &d.join(format!("ours/{i:04}.npy")),
                w as usize,
                h as usize,
                &v,
            )?;
        }
        let prev_pose = *poses.last().expect("frame 0");
        let pose = frame_camera(&reference, i, size, &lm, &feats, &prev_pose, &tp.head_fit)?;
        let rigid = rigid_motion(&surface, &pose.camera, w);
        let wdag = feature_warp(
            engine,
            &guide,
            &feats.tracks,
            i,
            tp.spread_residual.then_some(rigid.as_slice()),
            &tp.diffuse,
        )?;
        let v = if o.oracle_flow {
            v.iter()
                .zip(&true_flows[i])
                .map(|(ours, t)| {
                    if t[0].is_finite() && t[1].is_finite() {
                        *t
                    } else {
                        *ours
                    }
                })
                .collect()
        } else {
            v
        };
        for (k, &a) in o.alphas.iter().enumerate() {
            let next = compose(engine, &wdag, &warps[k], &v, w, h, a)?;
            warps[k] = next;
            if let Some(gt) = tracks_gt.get(&i) {
                let vis = &visible_gt[&i];
                let mut all = Vec::new();
                let mut seen = Vec::new();
                for ((p, t), &v) in warps[k].iter().zip(gt).zip(vis) {
                    if t[0].is_finite() && t[1].is_finite() {
                        let e = ((p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2)).sqrt();
                        all.push(e);
                        if v {
                            seen.push(e);
                        }
                    }
                }
                let mean = |e: &[f32]| e.iter().sum::<f32>() / e.len().max(1) as f32;
                let median = |e: &[f32]| crate::base::stats::percentile(e, 0.5);
                drift.push(Drift {
                    alpha: a,
                    frame: i,
                    mean_px: mean(&all),
                    median_px: median(&all),
                    visible_mean_px: mean(&seen),
                    visible_median_px: median(&seen),
                    visible_share: seen.len() as f32 / all.len().max(1) as f32,
                });
            }
        }
        // The tracked strands follow the paper's weight (or the one asked for).
        let k = o.alphas.iter().position(|&a| a == tp.alpha).unwrap_or(0);
        if o.alphas.get(k) == Some(&tp.alpha) {
            main_warp = warps[k].clone();
        } else {
            main_warp = compose(engine, &wdag, &main_warp, &v, w, h, tp.alpha)?;
        }
        if o.oracle_warp {
            let gt = &tracks_gt[&i];
            main_warp = gt
                .iter()
                .zip(&rigid)
                .map(|(t, m)| if t[0].is_finite() { *t } else { *m })
                .collect();
        }
        let res = crate::video::warp::warp_strands(
            engine,
            &reference.strands,
            &beta_v,
            &main_warp,
            w,
            h,
            &reference.camera,
            &pose.camera,
        )?;
        out_masks.push(crate::video::track::warp_mask(
            &reference.mask,
            &main_warp,
            w,
            h,
        ));
        poses.push(pose);
        tracked.push(res);
        feat_prev = feat_i;
    }
    let seconds_per_frame = t0.elapsed().as_secs_f64() / n as f64;

    // Pass 2: 3D against the true strands, frame by frame.
    let mut vertex_median_mm = Vec::with_capacity(n);
    let mut root_max_m = 0.0f32;
    let (mut stretch_p99, mut stretch_max) = (0.0f32, 0.0f32);
    let (mut yaw_err_max_deg, mut rot_err_max_deg) = (0.0f32, 0.0f32);
    let rest_len: Vec<f32> = reference
        .strands
        .strands()
        .flat_map(|s| {
            s.windows(2)
                .map(|p| glam::Vec3::from(p[0]).distance(glam::Vec3::from(p[1])))
                .collect::<Vec<_>>()
        })
        .collect();
    let off = reference.strands.offsets();
    // Visibility on the reference: a z-buffer of the vertices' depths.
    let cam0 = reference.camera;
    let mut zbuf = vec![f32::NEG_INFINITY; (w * h) as usize];
    let pix = |q: glam::Vec3| -> Option<usize> {
        let (x, y) = (q.x.round(), q.y.round());
        (x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32)
            .then(|| y as usize * w as usize + x as usize)
    };
    for p in &reference.strands.points {
        let q = cam0.project(glam::Vec3::from(*p));
        if let Some(i) = pix(q) {
            zbuf[i] = zbuf[i].max(q.z);
        }
    }
    let visible: Vec<bool> = reference
        .strands
        .points
        .iter()
        .map(|p| {
            let q = cam0.project(glam::Vec3::from(*p));
            pix(q).is_some_and(|i| q.z >= zbuf[i] - 0.003 * cam0.s)
        })
        .collect();
    let mut vertex_visible_median_mm = Vec::with_capacity(n);
    for (i, ours) in tracked.iter().enumerate() {
        let (truth, _) = sv.strands(i);
        let mut d: Vec<f32> = ours
            .strands()
            .zip(&truth)
            .flat_map(|(a, b)| {
                a.iter()
                    .zip(b)
                    .map(|(p, q)| glam::Vec3::from(*p).distance(*q))
                    .collect::<Vec<_>>()
            })
            .collect();
        for (s, b) in truth.iter().enumerate() {
            let a = ours.points[off[s]];
            root_max_m = root_max_m.max(glam::Vec3::from(a).distance(b[0]));
        }
        let mut seg = 0usize;
        let mut stretch = Vec::with_capacity(rest_len.len());
        for s in ours.strands() {
            for p in s.windows(2) {
                let l = glam::Vec3::from(p[0]).distance(glam::Vec3::from(p[1]));
                let l0 = rest_len[seg];
                if l0 > 0.0 {
                    stretch.push((l / l0 - 1.0).abs());
                }
                seg += 1;
            }
        }
        let mut dv: Vec<f32> = d
            .iter()
            .zip(&visible)
            .filter(|(_, v)| **v)
            .map(|(e, _)| *e)
            .collect();
        dv.sort_by(f32::total_cmp);
        vertex_visible_median_mm.push(1e3 * dv.get(dv.len() / 2).copied().unwrap_or(0.0));
        stretch_p99 = stretch_p99.max(crate::base::stats::percentile(&stretch, 0.99));
        stretch_max = stretch.iter().fold(stretch_max, |a, &b| a.max(b));
        d.sort_by(f32::total_cmp);
        vertex_median_mm.push(1e3 * d[d.len() / 2]);
        let (gi, ..) = sv.camera(i);
        let (ye, re) = rot_err(&reference.camera, &poses[i].camera, &reference.camera, &gi);
        yaw_err_max_deg = yaw_err_max_deg.max(ye);
        rot_err_max_deg = rot_err_max_deg.max(re);
    }
    let mut pose_sources = BTreeMap::new();
    for p in &poses {
        *pose_sources
            .entry(format!("{:?}", p.source).to_lowercase())
            .or_insert(0) += 1;
    }

    // Flicker: every frame re-rendered into its own photo with its tracked strands.
    let (mut flicker_ratio, mut flicker_in, mut flicker_out) = (None, None, None);
    let (mut flicker_vertex_ratio, mut flicker_vertex_out) = (None, None);
    if o.flicker {
        let colours = reference.strands.colors.clone();
        let vertex_params = crate::render::RenderParams {
            colour: crate::render::ColourSource::Vertex,
            ..Default::default()
        };
        let mut rendered = Vec::with_capacity(n);
        let mut rendered_vertex = Vec::with_capacity(n);
        for i in 0..n {
            let mut strands = tracked[i].clone();
            strands.colors = colours.clone();
            let scene = Scene {
                dir: PathBuf::from("synthetic clip"),
                strands,
                camera: Some(poses[i].camera),
                head: Some(reference.head.clone()),
                photo: Some(rgb[i].clone()),
                mask: Some(out_masks[i].clone()),
                width: w,
                height: h,
                animation: None,
                rest: None,
            };
            let r = crate::render::render(engine, &scene, &crate::render::RenderParams::default())?;
            rendered.push(crate::render::to_rgb8(&r));
            let r = crate::render::render(engine, &scene, &vertex_params)?;
            rendered_vertex.push(crate::render::to_rgb8(&r));
        }
        let region: Vec<Vec<bool>> = (0..n)
            .map(|k| {
                let prev = if k > 0 { &masks[k - 1] } else { &masks[k] };
                masks[k]
                    .iter()
                    .zip(prev)
                    .map(|(a, b)| *a != 0 || *b != 0)
                    .collect()
            })
            .collect();
        let (fi, fo) = (flicker(&rgb, &region), flicker(&rendered, &region));
        flicker_in = Some(fi);
        flicker_out = Some(fo);
        flicker_ratio = Some(fo / fi.max(1e-6));
        let fv = flicker(&rendered_vertex, &region);
        flicker_vertex_out = Some(fv);
        flicker_vertex_ratio = Some(fv / fi.max(1e-6));
        if let Some(d) = &o.write_dir {
            crate::io::ensure_dir(&d.join("rendered"))?;
            crate::io::ensure_dir(&d.join("rendered_vertex"))?;
            for (i, (im, iv)) in rendered.iter().zip(&rendered_vertex).enumerate() {
                crate::io::write_png(&d.join(format!("rendered/{i:04}.png")), im)?;
                crate::io::write_png(&d.join(format!("rendered_vertex/{i:04}.png")), iv)?;
            }
        }
    }
    Ok(ClipFigures {
        flow_epe,
        flow_mean_motion,
        drift,
        vertex_median_mm,
        vertex_visible_median_mm,
        root_max_m,
        stretch_p99,
        stretch_max,
        yaw_err_max_deg,
        rot_err_max_deg,
        pose_sources,
        features_last: feats.tracks.alive(n - 1),
        features_reference: feats.tracks.alive(0),
        flicker_ratio,
        flicker_in,
        flicker_out,
        flicker_vertex_ratio,
        flicker_vertex_out,
        seconds_per_frame,
    })
}
