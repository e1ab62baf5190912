//! Reliable sparse features for W†_i (C13 §3): Shi–Tomasi detection on the reference frame,
//! pyramidal Lucas–Kanade tracking to every other frame, forward–backward checked, plus
//! points a user adds or corrects in any frame.
//!
//! Passes: `klt_score` (corner score per pixel), `klt_pyr_down` (image pyramids) and
//! `klt_track` (one invocation per feature). Choosing corners from the score map (sort and
//! greedy suppression) and the bookkeeping of who is lost stay on the CPU: light and
//! sequential.
//!
//! Tracking moves away from the reference one frame at a time (forward for later frames,
//! backward for earlier ones). With [`Anchor::Reference`] each step's chained estimate is
//! refined against the reference frame's own patch, so errors do not accumulate along the
//! chain, but a patch that has turned since the reference no longer fits it.
//! `tests/it/video_features.rs` measures both over 30 frames of the synthetic portrait with
//! fresh noise per frame: mean drift at frame 30 is 0.35 px chained against 0.09 px anchored
//! on a sliding clip, and 0.56 against 0.46 px on a turning one (0.25°/frame), so
//! [`Anchor::Reference`] is the default.

use crate::analyze::orient::GrayImage;
use crate::base::sentinel::SENTINEL;
use crate::error::{Error, Result};
use crate::gpu::engine::{BufProxy, Engine, Recording};
use crate::stages::klt_pyr_down::{self, Layout};
use crate::stages::{klt_score, klt_track};
use std::collections::BTreeMap;
use std::path::Path;

/// What each tracking step matches the new frame against.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Anchor {
    /// The previous frame's patch only: follows appearance changes, accumulates drift.
    Chain,
    /// The chained estimate, then refined against the reference frame's patch (started
    /// from the chained estimate): no accumulated drift while the patch still looks alike.
    Reference,
}

/// Detection and tracking parameters. Gray values are in [0, 1]; lengths in pixels.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct KltParams {
    /// Most features [`detect`] returns (the strongest first).
    pub max_features: usize,
    /// No two detected features closer than this.
    pub min_distance_px: f32,
    /// Shi–Tomasi relative threshold: keep corners whose score is at least this share of the
    /// image's best score (OpenCV's `qualityLevel`).
    pub quality: f32,
    /// Absolute floor on the min eigenvalue of the window-averaged structure tensor (gray
    /// units² per pixel), for detection and for keeping a tracked feature. 8-bit
    /// quantisation noise alone gives about 1e-6; a 0.1 step blurred over a few pixels,
    /// 1e-4 and more. A flat image therefore has no features, and a patch that became flat
    /// is lost.
    pub min_eigen: f32,
    /// Smallest λmin/λmax of the structure tensor for a detected feature. Along an edge or a strand (ratio near 0) the position is not determined:
    /// translation-only Lucas–Kanade then slides along it as soon as the patch turns a
    /// little (`tests/it/video_features.rs` prints the error by ratio).
    pub min_isotropy: f32,
    /// The same limit for keeping a tracked feature, lower than `min_isotropy` so that a
    /// feature detected near the limit is not lost to the small change of its patch from
    /// one frame to the next (hysteresis).
    pub track_min_isotropy: f32,
    /// Half size of the detection window ((2r+1)², Gaussian weights of sigma r/2).
    pub score_window: u32,
    /// Half size of the tracking window (patch of (2r+1)²); features closer than this plus
    /// one to the border are not detected and are lost when tracked there.
    pub window: u32,
    /// Gaussian blur of every frame before its pyramid (0: none). Bilinear sampling, which
    /// tracking relies on, shifts texture near the Nyquist rate (fine strands) by the wrong
    /// amount; a blur of about a pixel removes that content and the bias with it.
    pub smooth_sigma: f32,
    /// Pyramid levels (1 = no pyramid). Each level doubles the largest motion tracked.
    pub levels: u32,
    /// Newton iterations per level at most.
    pub iterations: u32,
    /// Stop iterating once an update is shorter than this (level pixels).
    pub eps_px: f32,
    /// Forward–backward limit: a step whose back-tracked point misses the start by more is
    /// lost.
    pub fb_max_px: f32,
    /// Largest mean absolute difference between template patch and tracked patch; beyond
    /// it the patch no longer looks like what was tracked (occlusion) and the feature is
    /// lost.
    pub max_residual: f32,
    pub anchor: Anchor,
}

impl Default for KltParams {
    fn default() -> Self {
        KltParams {
            max_features: 400,
            min_distance_px: 8.0,
            quality: 0.01,
            min_eigen: 1e-5,
            min_isotropy: 0.1,
            track_min_isotropy: 0.05,
            score_window: 7,
            window: 7,
            smooth_sigma: 1.0,
            levels: 3,
            iterations: 20,
            eps_px: 0.01,
            fb_max_px: 1.0,
            max_residual: 0.1,
            anchor: Anchor::Reference,
        }
    }
}

impl KltParams {
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(m));
        if !(1..=8).contains(&self.levels) {
            return bad(format!("KLT levels {} must be in 1..=8", self.levels));
        }
        if !(1..=20).contains(&self.window) {
            return bad(format!("KLT window {} must be in 1..=20", self.window));
        }
        if !(1..=10).contains(&self.score_window) {
            return bad(format!(
                "KLT score window {} must be in 1..=10",
                self.score_window
            ));
        }
        if !(1..=100).contains(&self.iterations) {
            return bad(format!(
                "KLT iterations {} must be in 1..=100",
                self.iterations
            ));
        }
        for (name, v) in [
            ("min_distance_px", self.min_distance_px),
            ("quality", self.quality),
            ("min_eigen", self.min_eigen),
            ("eps_px", self.eps_px),
            ("fb_max_px", self.fb_max_px),
            ("max_residual", self.max_residual),
            ("smooth_sigma", self.smooth_sigma),
            ("min_isotropy", self.min_isotropy),
            ("track_min_isotropy", self.track_min_isotropy),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("KLT {name} must be a number >= 0, got {v}"));
            }
        }
        if self.smooth_sigma > 16.0 {
            return bad(format!("KLT smooth_sigma {} is over 16", self.smooth_sigma));
        }
        if self.quality > 1.0 {
            return bad(format!("KLT quality {} is over 1", self.quality));
        }
        if self.min_isotropy > 1.0 || self.track_min_isotropy > 1.0 {
            return bad(format!(
                "KLT min_isotropy {} and track_min_isotropy {} must be at most 1",
                self.min_isotropy, self.track_min_isotropy
            ));
        }
        Ok(())
    }

    /// The `klt_track` uniform for `n_points` points on `width` x `height` frames.
    pub fn track_config(&self, width: u32, height: u32, n_points: u32) -> klt_track::Config {
        klt_track::Config {
            n_points,
            levels: self.levels,
            width,
            height,
            win: self.window,
            iters: self.iterations,
            eps: self.eps_px,
            min_eig: self.min_eigen,
            min_iso: self.track_min_isotropy,
            ..Default::default()
        }
    }
}

fn check_image(gray: &GrayImage, what: &str) -> Result<()> {
    if gray.width == 0 || gray.height == 0 {
        return Err(Error::Invalid(format!("{what} is empty (0 pixels)")));
    }
    if gray.data.len() != gray.width as usize * gray.height as usize {
        return Err(Error::Invalid(format!(
            "{what} has {} values for {}x{} pixels",
            gray.data.len(),
            gray.width,
            gray.height
        )));
    }
    if gray.data.iter().any(|v| !v.is_finite()) {
        return Err(Error::Invalid(format!("{what} has NaN or infinite values")));
    }
    Ok(())
}

/// The Shi–Tomasi score of every pixel (the `klt_score` pass) of `gray` blurred by
/// `p.smooth_sigma` (what tracking sees), 0 where λmin < min_isotropy·λmax.
pub fn score(engine: &Engine, gray: &GrayImage, p: &KltParams) -> Result<Vec<f32>> {
    check_image(gray, "the image")?;
    let cfg = klt_score::Config {
        width: gray.width,
        height: gray.height,
        radius: p.score_window,
        min_iso: p.min_isotropy,
    };
    let mut rec = Recording::default();
    let u = rec.uniform("coif.klt_score.cfg", &cfg);
    let mut src = rec.upload("coif.klt_score.gray", &gray.data);
    if p.smooth_sigma > 0.0 {
        let blurred = rec.alloc(
            "coif.klt_score.blurred",
            gray.data.len() as u64 * 4,
            SENTINEL,
        );
        crate::stages::sep_blur::record_gaussian(
            &mut rec,
            src,
            blurred,
            gray.width,
            gray.height,
            p.smooth_sigma,
        );
        src = blurred;
    }
    let out = rec.alloc("coif.klt_score.out", gray.data.len() as u64 * 4, SENTINEL);
    rec.dispatch(
        &klt_score::STAGE,
        klt_score::workgroups(&cfg),
        &[u, src, out],
        &[],
    );
    rec.download(out);
    Ok(engine.run(rec)?.get(out))
}

/// Shi–Tomasi corners: pixels whose score is a 3x3 local maximum, at least `quality` times
/// the best score and at least `min_eigen`, at least `window + 1` pixels from the border and
/// on the mask (nonzero; every pixel without one), strongest first, none closer than
/// `min_distance_px` to a stronger one, at most `max_features`.
pub fn detect(
    engine: &Engine,
    gray: &GrayImage,
    mask: Option<&[u8]>,
    p: &KltParams,
) -> Result<Vec<[f32; 2]>> {
    p.validate()?;
    let (w, h) = (gray.width as usize, gray.height as usize);
    if let Some(m) = mask {
        if m.len() != w * h {
            return Err(Error::Invalid(format!(
                "mask has {} pixels, image has {}",
                m.len(),
                w * h
            )));
        }
    }
    let s = score(engine, gray, p)?;
    // Selection is a sort and a greedy sweep over a few thousand candidates: CPU work.
    let border = (p.window.max(p.score_window) + 1) as usize;
    let allowed = |x: usize, y: usize| {
        x >= border
            && y >= border
            && x + border < w
            && y + border < h
            && mask.is_none_or(|m| m[y * w + x] != 0)
    };
    let mut best = 0.0f32;
    for y in 0..h {
        for x in 0..w {
            if allowed(x, y) {
                best = best.max(s[y * w + x]);
            }
        }
    }
    let threshold = (p.quality * best).max(p.min_eigen);
    let mut cand: Vec<(f32, usize)> = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let v = s[y * w + x];
            if !allowed(x, y) || v.is_nan() || v < threshold {
                continue;
            }
            // `allowed` keeps a margin of at least 2, so the 3x3 neighbours exist.
            let local_max = (y - 1..=y + 1).all(|yy| (x - 1..=x + 1).all(|xx| s[yy * w + xx] <= v));
            if local_max {
                cand.push((v, y * w + x));
            }
        }
    }
    cand.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    // Greedy suppression with a grid of cells min_distance wide: only the 3x3 cells around
    // a candidate can hold a feature closer than min_distance.
    let cell = p.min_distance_px.max(1.0);
    let (gw, gh) = (
        (w as f32 / cell).ceil() as usize,
        (h as f32 / cell).ceil() as usize,
    );
    let mut grid: Vec<Vec<[f32; 2]>> = vec![Vec::new(); gw * gh];
    let mut out = Vec::new();
    let d2 = p.min_distance_px * p.min_distance_px;
    for (_, i) in cand {
        if out.len() >= p.max_features {
            break;
        }
        let pt = [(i % w) as f32, (i / w) as f32];
        let (cx, cy) = ((pt[0] / cell) as usize, (pt[1] / cell) as usize);
        let near = (cy.saturating_sub(1)..=(cy + 1).min(gh - 1)).any(|yy| {
            (cx.saturating_sub(1)..=(cx + 1).min(gw - 1)).any(|xx| {
                grid[yy * gw + xx]
                    .iter()
                    .any(|q| (q[0] - pt[0]).powi(2) + (q[1] - pt[1]).powi(2) < d2)
            })
        });
        if !near {
            grid[cy * gw + cx].push(pt);
            out.push(pt);
        }
    }
    Ok(out)
}

/// A Gaussian pyramid in one buffer (the layout of `klt_pyr_down`).
#[derive(Clone, Debug)]
pub struct Pyramid {
    pub layout: Layout,
    pub data: Vec<f32>,
}

/// Pyramids of `levels` levels for every frame, each frame blurred by `smooth_sigma` first
/// (`sep_blur`, then the `klt_pyr_down` pass), a few frames per engine run.
pub fn pyramids(
    engine: &Engine,
    frames: &[GrayImage],
    levels: u32,
    smooth_sigma: f32,
) -> Result<Vec<Pyramid>> {
    let mut out = Vec::with_capacity(frames.len());
    for chunk in frames.chunks(8) {
        let mut rec = Recording::default();
        let mut bufs = Vec::new();
        for f in chunk {
            let layout = Layout::new(f.width, f.height, levels);
            let buf = if smooth_sigma > 0.0 {
                let src = rec.upload("coif.klt.frame", &f.data);
                let buf = rec.alloc("coif.klt.pyramid", layout.len as u64 * 4, SENTINEL);
                // sep_blur writes the first w*h values: level 0 of the pyramid.
                crate::stages::sep_blur::record_gaussian(
                    &mut rec,
                    src,
                    buf,
                    f.width,
                    f.height,
                    smooth_sigma,
                );
                buf
            } else {
                let mut init = vec![f32::from_bits(SENTINEL); layout.len as usize];
                init[..f.data.len()].copy_from_slice(&f.data);
                rec.upload("coif.klt.pyramid", &init)
            };
            for l in 1..levels as usize {
                let cfg = layout.config(l);
                let u = rec.uniform("coif.klt_pyr_down.cfg", &cfg);
                rec.dispatch(
                    &klt_pyr_down::STAGE,
                    klt_pyr_down::workgroups(&cfg),
                    &[u, buf],
                    &[],
                );
            }
            rec.download(buf);
            bufs.push((layout, buf));
        }
        let dl = engine.run(rec)?;
        for (layout, buf) in bufs {
            let data: Vec<f32> = dl.get(buf);
            if data.iter().any(|v| v.to_bits() == SENTINEL) {
                return Err(Error::Gpu("a pyramid level was left unwritten".into()));
            }
            out.push(Pyramid {
                data: data[..layout.len as usize].to_vec(),
                layout,
            });
        }
    }
    Ok(out)
}

/// One tracking step's outcome for one point: its new position and forward–backward error,
/// or lost.
pub type StepResult = Option<([f32; 2], f32)>;

/// Tracks `from` (points on frame `prev`) into frame `cur`: forward with the zero-motion
/// prior, optionally refined against `anchor` (a template pyramid and the points' positions
/// on it), then back from the result into `prev` with the zero-motion prior again (an
/// unbiased check), all in one engine run. A point is lost when a pass loses it, when the
/// back-tracked point misses its start by more than `fb_max_px`, or when its patch
/// residual exceeds `max_residual`.
pub fn track_step(
    engine: &Engine,
    prev: &Pyramid,
    cur: &Pyramid,
    from: &[[f32; 2]],
    anchor: Option<(&Pyramid, &[[f32; 2]])>,
    p: &KltParams,
) -> Result<Vec<StepResult>> {
    if from.is_empty() {
        return Ok(Vec::new());
    }
    let (w, h, _) = prev.layout.levels[0];
    let cfg = p.track_config(w, h, from.len() as u32);
    let pts4: Vec<[f32; 4]> = from.iter().map(|q| [q[0], q[1], 1.0, 0.0]).collect();
    let bytes = pts4.len() as u64 * 16;
    let mut rec = Recording::default();
    let u = rec.uniform("coif.klt_track.cfg", &cfg);
    let prev_b = rec.upload("coif.klt.prev", &prev.data);
    let cur_b = rec.upload("coif.klt.cur", &cur.data);
    let from_b = rec.upload("coif.klt.from", &pts4);
    let dispatch = |rec: &mut Recording, tmpl, tmpl_pts, tgt, guess| -> BufProxy {
        let out = rec.alloc("coif.klt.out", bytes, SENTINEL);
        rec.dispatch(
            &klt_track::STAGE,
            klt_track::workgroups(&cfg),
            &[u, tmpl, tmpl_pts, tgt, guess, out],
            &[],
        );
        out
    };
    let mut fwd = dispatch(&mut rec, prev_b, from_b, cur_b, from_b);
    if let Some((apyr, apts)) = anchor {
        let a4: Vec<[f32; 4]> = apts.iter().map(|q| [q[0], q[1], 1.0, 0.0]).collect();
        let ab = rec.upload("coif.klt.anchor", &apyr.data);
        let ap = rec.upload("coif.klt.anchor_pts", &a4);
        fwd = dispatch(&mut rec, ab, ap, cur_b, fwd);
    }
    let back = dispatch(&mut rec, cur_b, fwd, prev_b, fwd);
    rec.download(fwd);
    rec.download(back);
    let dl = engine.run(rec)?;
    let (f, b): (Vec<[f32; 4]>, Vec<[f32; 4]>) = (dl.get(fwd), dl.get(back));
    if f.iter().chain(&b).any(|q| q[2].to_bits() == SENTINEL) {
        return Err(Error::Gpu("klt_track left points unwritten".into()));
    }
    Ok(from
        .iter()
        .zip(f.iter().zip(&b))
        .map(|(s, (f, b))| {
            if f[2] == 0.0 || b[2] == 0.0 || f[3].is_nan() || f[3] > p.max_residual {
                return None;
            }
            let fb = ((b[0] - s[0]).powi(2) + (b[1] - s[1]).powi(2)).sqrt();
            (fb <= p.fb_max_px).then_some(([f[0], f[1]], fb))
        })
        .collect())
}

/// One point a user placed: feature `id` is at `pos` in frame `frame`.
#[derive(Clone, Debug, PartialEq)]
pub struct UserPoint {
    pub id: String,
    pub frame: usize,
    pub pos: [f32; 2],
}

/// Points users add or correct (see [`load_points`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UserPoints {
    pub points: Vec<UserPoint>,
}

/// The id prefix that names a detected feature: "klt:17" is the 18th point given to
/// [`track`], so a user can correct it.
pub const DETECTED_PREFIX: &str = "klt:";

/// Reads user points from a JSON file:
/// `{"points": [{"id": "a", "frame": 12, "x": 40.5, "y": 80}, ...]}`, pixel coordinates
/// on frame `frame` (0-based, pixel centres at integers).
///
/// An id names one feature across frames. An id "klt:N" corrects detected feature N;
/// any other id adds a feature. At every frame a feature has a user point, that position
/// replaces the tracked one (and revives the feature if it was lost); tracking goes on from
/// it. A new feature without a point on the reference frame is tracked from its given
/// frame nearest the reference (the earlier one on a tie) to the reference, frame by frame;
/// if it is lost on the way it keeps only the positions the user gave (it has no position on
/// the reference, so it adds nothing to W†).
///
/// A malformed file (bad JSON, missing or mistyped fields, a frame outside `0..frames`, a
/// non-finite coordinate, a point outside the `width` x `height` image, one id twice on one
/// frame) is refused with [`Error::BadFile`] naming the file and the entry.
pub fn load_points(path: &Path, width: u32, height: u32, frames: usize) -> Result<UserPoints> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_points(&text, path, width, height, frames)
}

/// [`load_points`] on text already read; `path` names the source in errors.
pub fn parse_points(
    text: &str,
    path: &Path,
    width: u32,
    height: u32,
    frames: usize,
) -> Result<UserPoints> {
    let bad = |m: String| Error::bad_file(path, m);
    let v: serde_json::Value =
        serde_json::from_str(text).map_err(|e| bad(format!("not valid JSON: {e}")))?;
    let list = v
        .get("points")
        .and_then(|p| p.as_array())
        .ok_or_else(|| bad("expected an object with a \"points\" array".into()))?;
    let mut points = Vec::with_capacity(list.len());
    let mut seen = std::collections::HashSet::new();
    for (k, e) in list.iter().enumerate() {
        let id = e
            .get("id")
            .and_then(|v| v.as_str())
            .ok_or_else(|| bad(format!("points[{k}]: \"id\" must be a string")))?;
        if id.is_empty() {
            return Err(bad(format!("points[{k}]: \"id\" is empty")));
        }
        let frame = e
            .get("frame")
            .and_then(|v| v.as_u64())
            .ok_or_else(|| bad(format!("points[{k}]: \"frame\" must be an integer >= 0")))?;
        if frame >= frames as u64 {
            return Err(bad(format!(
                "points[{k}] (id \"{id}\"): frame {frame} is out of range (the clip has \
                 {frames} frames, 0..{})",
                frames.saturating_sub(1)
            )));
        }
        let coord = |name: &str| -> Result<f32> {
            let c = e.get(name).and_then(|v| v.as_f64()).ok_or_else(|| {
                bad(format!(
                    "points[{k}] (id \"{id}\"): \"{name}\" must be a number"
                ))
            })?;
            if !c.is_finite() || !(c as f32).is_finite() {
                return Err(bad(format!(
                    "points[{k}] (id \"{id}\"): \"{name}\" is not finite"
                )));
            }
            Ok(c as f32)
        };
        let pos = [coord("x")?, coord("y")?];
        if !point_inside(pos, width, height) {
            return Err(bad(format!(
                "points[{k}] (id \"{id}\"): ({}, {}) is outside the {width}x{height} image",
                pos[0], pos[1]
            )));
        }
        if !seen.insert((id.to_string(), frame)) {
            return Err(bad(format!(
                "points[{k}]: id \"{id}\" is given twice on frame {frame}"
            )));
        }
        points.push(UserPoint {
            id: id.to_string(),
            frame: frame as usize,
            pos,
        });
    }
    Ok(UserPoints { points })
}

fn point_inside(p: [f32; 2], width: u32, height: u32) -> bool {
    p[0].is_finite()
        && p[1].is_finite()
        && p[0] >= 0.0
        && p[1] >= 0.0
        && p[0] <= (width - 1) as f32
        && p[1] <= (height - 1) as f32
}

/// Features tracked through a clip.
#[derive(Clone, Debug)]
pub struct Tracks {
    pub width: u32,
    pub height: u32,
    pub reference: usize,
    /// Per feature: "klt:N" for detected feature N, else the user's id.
    pub ids: Vec<String>,
    /// Per feature, per frame: position, or None (lost, or never found).
    pub points: Vec<Vec<Option<[f32; 2]>>>,
    /// Per feature, per frame: forward–backward error of the step that reached the frame;
    /// 0 on the reference frame and where the user gave the position, NaN where lost.
    pub fb_error: Vec<Vec<f32>>,
    /// Per feature: added by a user (rather than detected).
    pub user: Vec<bool>,
}

impl Tracks {
    pub fn frames(&self) -> usize {
        self.points.first().map_or(0, |p| p.len())
    }

    /// (position on the reference frame, displacement to frame `frame`) of every feature
    /// known on both: the samples [`crate::video::diffuse::spread`] turns into W†_frame.
    pub fn samples(&self, frame: usize) -> Vec<([f32; 2], [f32; 2])> {
        self.points
            .iter()
            .filter_map(|f| {
                let (r, i) = (f[self.reference]?, f[frame]?);
                Some((r, [i[0] - r[0], i[1] - r[1]]))
            })
            .collect()
    }

    /// Features with a position on `frame`.
    pub fn alive(&self, frame: usize) -> usize {
        self.points.iter().filter(|f| f[frame].is_some()).count()
    }
}

/// Tracks features from frame `reference` through `frames`: forward for the later frames,
/// backward for the earlier ones, one frame at a time, each step forward–backward checked
/// ([`track_step`]); a lost feature stays lost unless a user point revives it. `pts` are the
/// detected features on the reference frame (ids "klt:0", "klt:1", ...); `user` adds and
/// corrects features as [`load_points`] describes.
pub fn track(
    engine: &Engine,
    frames: &[GrayImage],
    reference: usize,
    pts: &[[f32; 2]],
    user: &UserPoints,
    p: &KltParams,
) -> Result<Tracks> {
    p.validate()?;
    let nf = frames.len();
    if nf == 0 {
        return Err(Error::Invalid("no frames to track through".into()));
    }
    if reference >= nf {
        return Err(Error::Invalid(format!(
            "reference frame {reference} is out of range (the clip has {nf} frames)"
        )));
    }
    let (w, h) = (frames[0].width, frames[0].height);
    for (i, f) in frames.iter().enumerate() {
        check_image(f, &format!("frame {i}"))?;
        if (f.width, f.height) != (w, h) {
            return Err(Error::Invalid(format!(
                "frame {i} is {}x{}, frame 0 is {w}x{h}",
                f.width, f.height
            )));
        }
    }
    for (k, &q) in pts.iter().enumerate() {
        if !point_inside(q, w, h) {
            return Err(Error::Invalid(format!(
                "feature {k} at {q:?} is not inside the {w}x{h} reference frame"
            )));
        }
    }

    // Features: the detected ones, then one per new user id, in order of first mention.
    let mut ids: Vec<String> = (0..pts.len())
        .map(|k| format!("{DETECTED_PREFIX}{k}"))
        .collect();
    let mut is_user = vec![false; pts.len()];
    let mut given: Vec<BTreeMap<usize, [f32; 2]>> = vec![BTreeMap::new(); pts.len()];
    let mut by_id: BTreeMap<String, usize> = BTreeMap::new();
    for up in &user.points {
        if up.frame >= nf || !point_inside(up.pos, w, h) {
            return Err(Error::Invalid(format!(
                "user point \"{}\" at {:?} on frame {} is outside the {w}x{h}x{nf} clip",
                up.id, up.pos, up.frame
            )));
        }
        let f = if let Some(n) = up.id.strip_prefix(DETECTED_PREFIX) {
            match n.parse::<usize>() {
                Ok(n) if n < pts.len() => n,
                _ => {
                    return Err(Error::Invalid(format!(
                        "user point \"{}\" names no detected feature (there are {})",
                        up.id,
                        pts.len()
                    )))
                }
            }
        } else {
            *by_id.entry(up.id.clone()).or_insert_with(|| {
                ids.push(up.id.clone());
                is_user.push(true);
                given.push(BTreeMap::new());
                ids.len() - 1
            })
        };
        given[f].insert(up.frame, up.pos);
    }
    let n = ids.len();
    let pyr = pyramids(engine, frames, p.levels, p.smooth_sigma)?;
    let mut points = vec![vec![None; nf]; n];
    let mut fb_error = vec![vec![f32::NAN; nf]; n];

    // Positions on the reference frame.
    for f in 0..n {
        if let Some(&q) = given[f].get(&reference) {
            points[f][reference] = Some(q);
        } else if f < pts.len() {
            points[f][reference] = Some(pts[f]);
        } else {
            points[f][reference] = back_to_reference(engine, &pyr, reference, &given[f], p)?;
        }
        if points[f][reference].is_some() {
            fb_error[f][reference] = 0.0;
        }
    }
    let ref_pts: Vec<Option<[f32; 2]>> = points.iter().map(|f| f[reference]).collect();

    let order = (reference + 1..nf)
        .map(|i| (i - 1, i))
        .chain((0..reference).rev().map(|i| (i + 1, i)));
    for (prev, cur) in order {
        let mut idx = Vec::new();
        let mut from = Vec::new();
        let mut anchor_pts = Vec::new();
        for f in 0..n {
            if let Some(&q) = given[f].get(&cur) {
                points[f][cur] = Some(q);
                fb_error[f][cur] = 0.0;
            } else if let Some(q) = points[f][prev] {
                idx.push(f);
                from.push(q);
                // Features that reached the clip only through user points on other frames
                // have no reference patch; they fall back to the previous frame's.
                anchor_pts.push(ref_pts[f].unwrap_or(q));
            }
        }
        let anchor = (p.anchor == Anchor::Reference).then_some((&pyr[reference], &anchor_pts[..]));
        // Features without a reference patch must not be refined against it.
        let res = if anchor.is_some() && idx.iter().any(|&f| ref_pts[f].is_none()) {
            let (with, without): (Vec<usize>, Vec<usize>) =
                (0..idx.len()).partition(|&k| ref_pts[idx[k]].is_some());
            let pick = |ks: &[usize], v: &[[f32; 2]]| ks.iter().map(|&k| v[k]).collect::<Vec<_>>();
            let a = pick(&with, &anchor_pts);
            let r_with = track_step(
                engine,
                &pyr[prev],
                &pyr[cur],
                &pick(&with, &from),
                Some((&pyr[reference], &a)),
                p,
            )?;
            let r_without = track_step(
                engine,
                &pyr[prev],
                &pyr[cur],
                &pick(&without, &from),
                None,
                p,
            )?;
            let mut res = vec![None; idx.len()];
            for (k, r) in with.iter().zip(r_with).chain(without.iter().zip(r_without)) {
                res[*k] = r;
            }
            res
        } else {
            track_step(engine, &pyr[prev], &pyr[cur], &from, anchor, p)?
        };
        for (&f, r) in idx.iter().zip(res) {
            if let Some((q, fb)) = r {
                points[f][cur] = Some(q);
                fb_error[f][cur] = fb;
            }
        }
    }
    Ok(Tracks {
        width: w,
        height: h,
        reference,
        ids,
        points,
        fb_error,
        user: is_user,
    })
}

/// The reference-frame position of a user feature given only on other frames: chained
/// tracking from its given frame nearest the reference (no other given frame lies between);
/// None when it is lost before it arrives.
fn back_to_reference(
    engine: &Engine,
    pyr: &[Pyramid],
    reference: usize,
    given: &BTreeMap<usize, [f32; 2]>,
    p: &KltParams,
) -> Result<Option<[f32; 2]>> {
    let Some((&start, &q0)) = given
        .iter()
        .min_by_key(|(&k, _)| (k.abs_diff(reference), k))
    else {
        return Ok(None);
    };
    let mut q = q0;
    let mut k = start;
    while k != reference {
        let next = if k > reference { k - 1 } else { k + 1 };
        match track_step(engine, &pyr[k], &pyr[next], &[q], None, p)?[0] {
            Some((r, _)) => q = r,
            None => return Ok(None),
        }
        k = next;
    }
    Ok(Some(q))
}
