//! Synthetic video with exact ground truth (issue 15, item 1): the 3D synthetic portrait of
//! [`synth3d`](crate::synth::synth3d) moved by a known head motion and a known hair motion,
//! independent of coif's simulator (judging the video pipeline with the simulator's own
//! output would be circular).
//!
//! Head: a weak-perspective camera per frame, scale fixed, rotation
//! `R_y(yaw) · R_x(−pitch)` (the order and signs of `sim::track::pose_transform`: positive
//! pitch turns the face up) and the model origin shifted by a few pixels; yaw, pitch and the
//! shift are sinusoids of different periods, zero deviation at frame 0, whose camera is the
//! still case's. The still's yaw is drawn within ±[`REF_MAX_YAW_DEG`] and the swing adds at
//! most [`YAW_SWING_DEG`], so |yaw| ≤ 10°; |pitch| ≤ [`PITCH_SWING_DEG`].
//!
//! Hair (model space, the head does not move in its own space): at every vertex k ≥ 1 of a
//! strand the rest of the strand turns about the reference (frame 0) camera's view axis
//! `a = R₀ᵀ·e_z` through that vertex, so segment k (vertex k to k + 1) ends up turned by the
//! cumulative angle `φ_k = λ · Φ(t, root) · g(s_k)`: `g` a smoothstep of the arc length
//! `s_k` from 0 at [`RAMP_M`]`.0` to 1 at [`RAMP_M`]`.1` (roots and the first millimetres do
//! not move), `Φ` two sinusoids in time whose mix varies slowly with the root position
//! (smooth, non-rigid flow) plus a lock-scale term of three plane waves over the roots a few
//! centimetres long, each with its own period (neighbouring locks swing out of step, as real
//! hair does; [`VideoParams::lock_turn_deg`], 0 turns it off), zero at t = 0. Turning about a fixed axis keeps roots,
//! segment lengths and depth along `a` exactly. `λ ∈ [0, 1]` is per strand and frame: 1
//! unless the turn would push a vertex deeper into the head and shoulders than it was at
//! rest (or closer than [`CLEARANCE_M`] when it was farther), else the largest such scale
//! found by bisection.
//!
//! True 2D motion: the z-buffer of the renderer records, per pixel, the material point of the
//! front-most visible strand (strand, segment, t). The flow from frame i−1 to frame i on
//! frame i−1's pixel is that material point's projection in frame i minus its projection in
//! frame i−1 (exact for the point; the pixel centre lies within 0.75 px of it, across the
//! strand). The same from frame 0 gives the track to frame i. NaN on every pixel no strand
//! covers (background, skin, and mask pixels the closing added). A point hidden in the
//! target frame keeps its flow (it is the motion, not a visibility).

use crate::base::rng::Rng;
use crate::error::{Error, Result};
use crate::hair::head::WeakPerspective;
use crate::hair::strands::StrandSet;
use crate::io::{ensure_dir, write_atomic, write_json, write_png};
use crate::synth::synth3d::{strand_set, Synth3dCase, Synth3dFrame, Synth3dOptions, Synth3dScene};
use crate::synth::{smoothstep, Style, SynthParams};
use glam::{Mat3, Vec2, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::json;
use std::f32::consts::TAU;
use std::path::Path;
use std::time::Instant;

/// The still's (frame 0's) yaw is drawn within ± this many degrees.
pub const REF_MAX_YAW_DEG: f32 = 4.0;
/// Largest yaw swing about frame 0's, degrees.
pub const YAW_SWING_DEG: f32 = 6.0;
/// Largest pitch, degrees.
pub const PITCH_SWING_DEG: f32 = 6.0;
/// Largest shift of the head, as a fraction of min(width, height) (x, y): 4 and 2.5 px at
/// 256².
pub const SHIFT_FRAC: [f32; 2] = [0.016, 0.01];
/// Scale of the hair turn Φ, degrees (|Φ| ≤ 1.4 × this).
pub const HAIR_TURN_DEG: f32 = 4.0;
/// Default scale of the lock-scale part of the turn, degrees (|Φ_lock| ≤ the scale): off,
/// so that the figures of the issue-15 clips stay comparable; 3° is what the README's
/// lock-scale rows use.
pub const LOCK_TURN_DEG: f32 = 0.0;
/// Largest camera noise σ, grey levels.
pub const MAX_NOISE: f32 = 64.0;
/// Wavelength range (metres, over root positions) of the lock-scale turn: locks a few
/// centimetres wide, as real hair moves, not the head-sized waves of the main turn.
pub const LOCK_WAVELENGTH_M: (f32, f32) = (0.035, 0.05);
/// Arc lengths (metres) over which the hair turn grows from 0 to its full value.
pub const RAMP_M: (f32, f32) = (0.004, 0.10);
/// Clearance (metres) a moved vertex keeps from the body, unless it was closer at rest.
pub const CLEARANCE_M: f32 = 0.00025;

/// What to generate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VideoParams {
    /// Style, seed and frame size (as `coif synth`).
    pub synth: SynthParams,
    pub frames: usize,
    /// Ground-truth strands.
    pub strands: usize,
    /// Frames per second (sets the time of each frame, so the speed of the motion).
    pub fps: f32,
    /// Scale of the lock-scale part of the hair turn, degrees (0: the head-sized waves
    /// alone, as clips made before it had).
    pub lock_turn_deg: f32,
    /// Camera noise: σ of a zero-mean Gaussian added to every 8-bit channel of every frame
    /// (fresh per frame, seeded), in grey levels; 0 (the default) keeps clean renders.
    /// Real clips carry it.
    pub noise: f32,
    /// JPEG quality every frame goes through after the noise (1-100, as a compressed clip's
    /// blocks, which move from frame to frame); 0 (the default) keeps lossless frames.
    pub jpeg: u8,
}

impl VideoParams {
    pub const MAX_FRAMES: usize = 10_000;
    pub const MAX_SIZE: u32 = 4096;
    pub const MAX_STRANDS: usize = 200_000;
    pub const DEFAULT_FPS: f32 = 24.0;

    /// `style`, `seed`, a square `size`, `frames`, the still's default strand count, 24 fps.
    pub fn new(style: Style, seed: u64, size: u32, frames: usize) -> VideoParams {
        VideoParams {
            synth: SynthParams {
                style,
                seed,
                width: size,
                height: size,
            },
            frames,
            strands: Synth3dOptions::default().strands,
            fps: Self::DEFAULT_FPS,
            lock_turn_deg: LOCK_TURN_DEG,
            noise: 0.0,
            jpeg: 0,
        }
    }

    /// Clear errors for what cannot be generated.
    pub fn validate(&self) -> Result<()> {
        if !self.synth.style.has_3d() {
            return Err(Error::Invalid(format!(
                "the {} style is 2D only: there is no synthetic video of it",
                self.synth.style
            )));
        }
        if !(2..=Self::MAX_FRAMES).contains(&self.frames) {
            return Err(Error::Invalid(format!(
                "--frames {} is outside 2..={}",
                self.frames,
                Self::MAX_FRAMES
            )));
        }
        for side in [self.synth.width, self.synth.height] {
            if !(SynthParams::MIN_SIZE..=Self::MAX_SIZE).contains(&side) {
                return Err(Error::Invalid(format!(
                    "--size {side} is outside {}..={}",
                    SynthParams::MIN_SIZE,
                    Self::MAX_SIZE
                )));
            }
        }
        if !(1..=Self::MAX_STRANDS).contains(&self.strands) {
            return Err(Error::Invalid(format!(
                "--strands {} is outside 1..={}",
                self.strands,
                Self::MAX_STRANDS
            )));
        }
        if !(self.lock_turn_deg.is_finite() && (0.0..=45.0).contains(&self.lock_turn_deg)) {
            return Err(Error::Invalid(format!(
                "--lock-turn {} must be between 0 and 45 degrees",
                self.lock_turn_deg
            )));
        }
        if !(self.noise.is_finite() && (0.0..=MAX_NOISE).contains(&self.noise)) {
            return Err(Error::Invalid(format!(
                "--noise {} must be between 0 and {MAX_NOISE} grey levels",
                self.noise
            )));
        }
        if self.jpeg > 100 {
            return Err(Error::Invalid(format!(
                "--jpeg {} must be a quality between 1 and 100 (0: lossless frames)",
                self.jpeg
            )));
        }
        if !(self.fps.is_finite() && self.fps > 0.0) {
            return Err(Error::Invalid(format!(
                "fps must be positive, got {}",
                self.fps
            )));
        }
        Ok(())
    }

    /// The still case's options: frame 0 is `synth3d_with(&self.synth, &this)`.
    pub fn still_options(&self) -> Synth3dOptions {
        Synth3dOptions {
            strands: self.strands,
            max_yaw_deg: REF_MAX_YAW_DEG,
        }
    }
}

/// The known motion of the clip: per-seed periods and signs of the sinusoids.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Motion {
    /// Frame 0's yaw, degrees.
    pub yaw0_deg: f32,
    /// yaw(t) = yaw0 + yaw_amp · sin(2π t / yaw_period).
    pub yaw_amp_deg: f32,
    pub yaw_period_s: f32,
    /// pitch(t) = pitch_amp · sin(2π t / pitch_period).
    pub pitch_amp_deg: f32,
    pub pitch_period_s: f32,
    /// shift(t) = shift_amp · sin(2π t / shift_period), per axis, pixels.
    pub shift_amp_px: [f32; 2],
    pub shift_period_s: [f32; 2],
    /// Model-space axis the hair turns about: the reference camera's view axis R₀ᵀ·e_z.
    pub hair_axis: [f32; 3],
    /// Φ(t, root) = amp · [(0.7 + 0.3 cos ψ) sin(2π t / T₀) + 0.4 sin ψ sin(2π t / T₁)],
    /// ψ = 2π (root.x / L₀ + root.z / L₁) + ψ₀.
    pub hair_amp_deg: f32,
    pub hair_period_s: [f32; 2],
    pub hair_wavelength_m: [f32; 2],
    pub hair_phase0: f32,
    /// g(s) = smoothstep(ramp₀, ramp₁, s) of the arc length s (metres) from the root.
    pub hair_ramp_m: [f32; 2],
    pub clearance_m: f32,
    /// Lock-scale turn added to Φ: amp · Σ_j sin(2π k_j·root / L + ψ_j) sin(2π t / T_j) / √3
    /// over three plane waves with unit directions k_j (model space), one wavelength L and
    /// their own periods: neighbouring locks swing out of step, which features a few
    /// centimetres apart spread by a smooth filter do not see and dense flow does.
    pub lock_amp_deg: f32,
    pub lock_wavelength_m: f32,
    pub lock_dirs: [[f32; 3]; 3],
    pub lock_phase: [f32; 3],
    pub lock_period_s: [f32; 3],
}

impl Motion {
    fn new(p: &VideoParams, camera: &WeakPerspective, yaw0_deg: f32) -> Motion {
        // Its own stream: the scene's streams stay those of the still.
        let mut g = Rng::new(p.synth.seed ^ 0x5669_6465_6f00_0000 ^ style_tag(p.synth.style));
        let sign = |g: &mut Rng| if g.next_f32() < 0.5 { -1.0 } else { 1.0 };
        let side = p.synth.width.min(p.synth.height) as f32;
        Motion {
            yaw0_deg,
            yaw_amp_deg: sign(&mut g) * YAW_SWING_DEG * g.range_f32(0.8, 1.0),
            yaw_period_s: g.range_f32(2.2, 2.8),
            pitch_amp_deg: sign(&mut g) * PITCH_SWING_DEG * g.range_f32(0.7, 1.0),
            pitch_period_s: g.range_f32(2.9, 3.6),
            shift_amp_px: SHIFT_FRAC.map(|f| sign(&mut g) * f * side * g.range_f32(0.7, 1.0)),
            shift_period_s: [g.range_f32(2.4, 3.0), g.range_f32(1.7, 2.1)],
            hair_axis: camera.r.row(2).to_array(),
            hair_amp_deg: sign(&mut g) * HAIR_TURN_DEG,
            hair_period_s: [g.range_f32(1.5, 1.9), g.range_f32(0.9, 1.2)],
            hair_wavelength_m: [g.range_f32(0.14, 0.2), g.range_f32(0.2, 0.3)],
            hair_phase0: g.range_f32(0.0, TAU),
            hair_ramp_m: [RAMP_M.0, RAMP_M.1],
            clearance_m: CLEARANCE_M,
            // Drawn after the rest, so the other terms stay those of clips made before.
            lock_amp_deg: sign(&mut g) * p.lock_turn_deg,
            lock_wavelength_m: g.range_f32(LOCK_WAVELENGTH_M.0, LOCK_WAVELENGTH_M.1),
            lock_dirs: [0; 3].map(|_| {
                let z = g.range_f32(-1.0, 1.0);
                let a = g.range_f32(0.0, TAU);
                let r = (1.0 - z * z).max(0.0).sqrt();
                [r * a.cos(), r * a.sin(), z]
            }),
            lock_phase: [0; 3].map(|_| g.range_f32(0.0, TAU)),
            lock_period_s: [0; 3].map(|_| g.range_f32(0.7, 1.3)),
        }
    }

    /// Head yaw, pitch (degrees) and shift (px) at time `t` seconds.
    pub fn head(&self, t: f32) -> (f32, f32, [f32; 2]) {
        let sin = |period: f32| (TAU * t / period).sin();
        (
            self.yaw0_deg + self.yaw_amp_deg * sin(self.yaw_period_s),
            self.pitch_amp_deg * sin(self.pitch_period_s),
            [0, 1].map(|k| self.shift_amp_px[k] * sin(self.shift_period_s[k])),
        )
    }

    /// The hair turn Φ (radians) at time `t` of a strand rooted at `root`, before the
    /// penetration limit.
    pub fn hair_turn(&self, t: f32, root: Vec3) -> f32 {
        let psi = TAU * (root.x / self.hair_wavelength_m[0] + root.z / self.hair_wavelength_m[1])
            + self.hair_phase0;
        let [t0, t1] = self.hair_period_s;
        let main = self.hair_amp_deg.to_radians()
            * ((0.7 + 0.3 * psi.cos()) * (TAU * t / t0).sin()
                + 0.4 * psi.sin() * (TAU * t / t1).sin());
        if self.lock_amp_deg == 0.0 {
            return main;
        }
        let lock: f32 = (0..3)
            .map(|j| {
                let k = Vec3::from_array(self.lock_dirs[j]);
                (TAU * k.dot(root) / self.lock_wavelength_m + self.lock_phase[j]).sin()
                    * (TAU * t / self.lock_period_s[j]).sin()
            })
            .sum();
        main + self.lock_amp_deg.to_radians() * lock / 3f32.sqrt()
    }
}

fn style_tag(s: Style) -> u64 {
    match s {
        Style::Long => 1,
        Style::Whorl => 2,
        Style::SidePart => 3,
        Style::Short => 4,
        Style::Fringe => 5,
    }
}

/// The head's pose and the hair's state in one frame.
#[derive(Clone, Debug, Serialize)]
pub struct FramePose {
    pub index: usize,
    pub time_s: f32,
    pub camera: WeakPerspective,
    pub yaw_deg: f32,
    pub pitch_deg: f32,
    /// Image shift of the model origin from frame 0's, px.
    pub shift_px: [f32; 2],
    /// Mean of the per-strand scale λ of the hair turn (1 where no limit applied).
    pub hair_scale_mean: f32,
    /// Strands whose turn the penetration limit scaled down.
    pub hair_limited: usize,
    /// Largest |λ Φ| over the strands, degrees: the turn of the farthest segments.
    pub hair_turn_max_deg: f32,
}

/// One frame of the clip.
#[derive(Clone, Debug)]
pub struct VideoFrame {
    pub pose: FramePose,
    /// Ground-truth strands, model space metres (the head at rest; `pose.camera` carries its
    /// motion).
    pub strands: Vec<Vec<Vec3>>,
    /// The rendering and its image-space ground truth.
    pub render: Synth3dFrame,
}

impl VideoFrame {
    /// The strands (with the colours they were drawn with) as a strand set.
    pub fn strand_set(&self) -> StrandSet {
        strand_set(&self.strands, &self.render.colors)
    }
}

/// A synthetic clip: the scene and its known motion; frames are rendered on demand.
pub struct SynthVideo {
    pub params: VideoParams,
    pub scene: Synth3dScene,
    pub motion: Motion,
    /// Per vertex: the rest state's signed distance to the body (the penetration limit).
    rest_sdf: Vec<Vec<f32>>,
    /// Per vertex: g of the arc length from the root.
    ramp: Vec<Vec<f32>>,
}

impl SynthVideo {
    /// Grows the scene and fixes the motion; deterministic for the params.
    pub fn new(p: &VideoParams) -> Result<SynthVideo> {
        p.validate()?;
        let scene = Synth3dScene::new(&p.synth, &p.still_options());
        let motion = Motion::new(p, &scene.camera, scene.yaw_deg);
        let rest_sdf = scene
            .strands
            .par_iter()
            .map(|st| st.iter().map(|&q| scene.body_sdf(q)).collect())
            .collect();
        let ramp = scene
            .strands
            .iter()
            .map(|st| {
                let mut s = 0.0;
                let mut out = Vec::with_capacity(st.len());
                for (k, q) in st.iter().enumerate() {
                    if k > 0 {
                        s += q.distance(st[k - 1]);
                    }
                    out.push(smoothstep(motion.hair_ramp_m[0], motion.hair_ramp_m[1], s));
                }
                out
            })
            .collect();
        Ok(SynthVideo {
            params: *p,
            scene,
            motion,
            rest_sdf,
            ramp,
        })
    }

    /// The still case of frame 0 (what `coif model` reads: image, mask, strokes, landmarks,
    /// gt_strands.hair, camera.json), rendered without the camera noise and compression that
    /// frame 0 of the clip carries.
    pub fn reference(&self) -> Synth3dCase {
        self.scene.still()
    }

    /// The camera of frame `i`, with its yaw, pitch and shift.
    pub fn camera(&self, i: usize) -> (WeakPerspective, f32, f32, [f32; 2]) {
        let base = self.scene.camera;
        if i == 0 {
            // Exactly the still's camera (no rounding through the rotation product).
            return (base, self.motion.yaw0_deg, 0.0, [0.0; 2]);
        }
        let (yaw, pitch, shift) = self.motion.head(self.time(i));
        let r =
            Mat3::from_rotation_y(yaw.to_radians()) * Mat3::from_rotation_x(-pitch.to_radians());
        let cam = WeakPerspective::new(base.s, r, base.t + Vec2::from_array(shift));
        (cam, yaw, pitch, shift)
    }

    /// Time of frame `i`, seconds.
    pub fn time(&self, i: usize) -> f32 {
        i as f32 / self.params.fps
    }

    /// The strands of frame `i` (model space) and the per-strand scale λ of their turn.
    pub fn strands(&self, i: usize) -> (Vec<Vec<Vec3>>, Vec<f32>) {
        let t = self.time(i);
        let axis = Vec3::from_array(self.motion.hair_axis);
        self.scene
            .strands
            .par_iter()
            .zip(self.rest_sdf.par_iter())
            .zip(self.ramp.par_iter())
            .map(|((st, rest), g)| {
                let phi = self.motion.hair_turn(t, st[0]);
                let clear = |q: &[Vec3]| {
                    q.iter()
                        .zip(rest)
                        .skip(1)
                        .all(|(&p, &d0)| self.scene.body_sdf(p) >= d0.min(CLEARANCE_M) - 1e-6)
                };
                let full = turn_strand(st, g, axis, phi);
                if phi == 0.0 || clear(&full) {
                    return (full, 1.0);
                }
                // The largest scale that keeps clear (0 always does: the rest state).
                let (mut lo, mut hi) = (0.0f32, 1.0f32);
                let mut best = st.clone();
                for _ in 0..10 {
                    let mid = 0.5 * (lo + hi);
                    let q = turn_strand(st, g, axis, mid * phi);
                    if clear(&q) {
                        lo = mid;
                        best = q;
                    } else {
                        hi = mid;
                    }
                }
                (best, lo)
            })
            .unzip()
    }

    /// Adds frame `i`'s camera noise ([`VideoParams::noise`]) to `image`: its own stream
    /// per frame, so any frame renders alone and the same every time.
    fn add_noise(&self, i: usize, image: &mut image::RgbImage) {
        let sigma = self.params.noise;
        if sigma <= 0.0 {
            return;
        }
        let mut g = Rng::new(self.params.synth.seed ^ 0x6e6f_6973_6500_0000 ^ ((i as u64) << 16));
        for v in image.iter_mut() {
            *v = (*v as f32 + sigma * g.normal_f32())
                .round()
                .clamp(0.0, 255.0) as u8;
        }
    }

    /// Renders frame `i`.
    pub fn frame(&self, i: usize) -> VideoFrame {
        let (camera, yaw_deg, pitch_deg, shift_px) = self.camera(i);
        let (strands, scale) = self.strands(i);
        let t = self.time(i);
        let turn_max = self
            .scene
            .strands
            .iter()
            .zip(&scale)
            .map(|(st, l)| (l * self.motion.hair_turn(t, st[0])).abs())
            .fold(0.0f32, f32::max);
        let mut render = self.scene.render(&camera, &strands);
        self.add_noise(i, &mut render.image);
        if self.params.jpeg > 0 {
            render.image = crate::synth::texture::jpeg_round_trip(&render.image, self.params.jpeg);
        }
        VideoFrame {
            pose: FramePose {
                index: i,
                time_s: t,
                camera,
                yaw_deg,
                pitch_deg,
                shift_px,
                hair_scale_mean: scale.iter().sum::<f32>() / scale.len().max(1) as f32,
                hair_limited: scale.iter().filter(|&&l| l < 1.0).count(),
                hair_turn_max_deg: turn_max.to_degrees(),
            },
            strands,
            render,
        }
    }

    /// Generates the clip into `out` (created), every file atomically: `frames/NNNN.png`,
    /// `masks/NNNN.png`, `landmarks/NNNN.json`, `gt/NNNN.hair` (positions only; the colours
    /// are in `reference/gt_strands.hair`), `flow/NNNN.npy` (i ≥ 1),
    /// `track/NNNN.npy`, `cameras.json`, `preview.gif` and the still case of frame 0 in
    /// `reference/`. `progress` shows a bar over the frames on a terminal.
    pub fn write(&self, out: &Path, progress: bool) -> Result<VideoSummary> {
        let t0 = Instant::now();
        let p = &self.params;
        let (w, h) = (p.synth.width as usize, p.synth.height as usize);
        for d in ["frames", "masks", "landmarks", "gt", "flow", "track"] {
            ensure_dir(&out.join(d))?;
        }
        self.reference().write(&out.join("reference"))?;

        let bar = if progress {
            indicatif::ProgressBar::new(p.frames as u64)
        } else {
            indicatif::ProgressBar::hidden()
        };
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "synth-video {bar:30} {pos}/{len} frames {eta}",
            )
            .expect("static template"),
        );
        // The preview holds at most ~120 frames of at most 256 px.
        let gif_step = p.frames.div_ceil(120);
        let gif_scale = (w.max(h) as f32 / 256.0).max(1.0);
        let mut gif_frames = Vec::new();
        let mut poses = Vec::with_capacity(p.frames);
        let mut first: Option<VideoFrame> = None;
        let mut prev: Option<VideoFrame> = None;
        let mut flow_stats = FlowStats::default();
        for i in 0..p.frames {
            let f = self.frame(i);
            let name = format!("{i:04}");
            write_png(&out.join(format!("frames/{name}.png")), &f.render.image)?;
            write_png(&out.join(format!("masks/{name}.png")), &f.render.mask)?;
            f.render
                .landmarks
                .save(&out.join(format!("landmarks/{name}.json")))?;
            // Positions only (as `coif simulate`'s frames): the colours are the reference's,
            // and a long clip of long hair would otherwise double its size.
            let gt = f.strand_set();
            let gt = StrandSet::new(gt.points, gt.counts);
            crate::io::strands::write(&out.join(format!("gt/{name}.hair")), &gt)?;
            if let Some(a) = &prev {
                let v = true_flow(a, &f);
                flow_stats.add(&v);
                write_field(&out.join(format!("flow/{name}.npy")), w, h, &v)?;
            }
            let track = true_flow(first.as_ref().unwrap_or(&f), &f);
            write_field(&out.join(format!("track/{name}.npy")), w, h, &track)?;
            if i % gif_step == 0 {
                gif_frames.push(downscale(&f.render.image, gif_scale));
            }
            poses.push(f.pose.clone());
            if first.is_none() {
                first = Some(f.clone());
            }
            prev = Some(f);
            bar.inc(1);
        }
        bar.finish_and_clear();

        let doc = json!({
            "version": 1,
            "coif": env!("CARGO_PKG_VERSION"),
            "style": p.synth.style.name(),
            "seed": p.synth.seed,
            "width": p.synth.width,
            "height": p.synth.height,
            "frames": p.frames,
            "fps": p.fps,
            "noise_sigma": p.noise,
            "jpeg_quality": p.jpeg,
            "noise_doc": "zero-mean Gaussian noise of this sigma (grey levels) on every channel of frames/, fresh per frame; reference/ holds the clean still",
            "strands": self.scene.strands.len(),
            "units": "model space in metres, y up, the face looks toward +z; image pixels, x right, y down, centres at integer + 0.5",
            "camera_doc": "image x = s (r p).x + t.x, image y = -s (r p).y + t.y, depth = s (r p).z; r = R_y(yaw) R_x(-pitch), s fixed, t = t0 + shift",
            "flow_doc": "flow/NNNN.npy (H, W, 2): motion from frame NNNN-1 to NNNN of the front-most strand's material point at each pixel of frame NNNN-1; track/NNNN.npy: from frame 0 to NNNN on frame 0's pixels; NaN where no strand covers the pixel",
            "motion": self.motion,
            "per_frame": poses.iter().map(|q| json!({
                "index": q.index,
                "time_s": q.time_s,
                "camera": q.camera,
                "image_from_model": q.camera.image_from_model(),
                "yaw_deg": q.yaw_deg,
                "pitch_deg": q.pitch_deg,
                "shift_px": q.shift_px,
                "hair": {
                    "scale_mean": q.hair_scale_mean,
                    "limited_strands": q.hair_limited,
                    "turn_max_deg": q.hair_turn_max_deg,
                },
            })).collect::<Vec<_>>(),
        });
        write_json(&out.join("cameras.json"), &doc)?;
        let delay_ms = 1000.0 * gif_step as f32 / p.fps;
        write_atomic(&out.join("preview.gif"), &gif(&gif_frames, delay_ms)?)?;
        Ok(VideoSummary {
            frames: p.frames,
            seconds: t0.elapsed().as_secs_f64(),
            flow_mean_px: flow_stats.sum / flow_stats.n.max(1) as f64,
            flow_max_px: flow_stats.max,
            hair_limited_max: poses.iter().map(|q| q.hair_limited).max().unwrap_or(0),
            hair_turn_max_deg: poses
                .iter()
                .map(|q| q.hair_turn_max_deg)
                .fold(0.0, f32::max),
            yaw_range_deg: range(poses.iter().map(|q| q.yaw_deg)),
            pitch_range_deg: range(poses.iter().map(|q| q.pitch_deg)),
        })
    }
}

/// Figures of a written clip.
#[derive(Clone, Debug)]
pub struct VideoSummary {
    pub frames: usize,
    pub seconds: f64,
    /// Mean and largest length of the true flow on hair pixels, px per frame.
    pub flow_mean_px: f64,
    pub flow_max_px: f32,
    /// Most strands the penetration limit scaled down in one frame.
    pub hair_limited_max: usize,
    pub hair_turn_max_deg: f32,
    pub yaw_range_deg: [f32; 2],
    pub pitch_range_deg: [f32; 2],
}

#[derive(Default)]
struct FlowStats {
    sum: f64,
    n: usize,
    max: f32,
}

impl FlowStats {
    fn add(&mut self, v: &[[f32; 2]]) {
        for d in v.iter().filter(|d| !d[0].is_nan()) {
            let l = d[0].hypot(d[1]);
            self.sum += l as f64;
            self.n += 1;
            self.max = self.max.max(l);
        }
    }
}

fn range(it: impl Iterator<Item = f32>) -> [f32; 2] {
    it.fold([f32::INFINITY, f32::NEG_INFINITY], |[lo, hi], v| {
        [lo.min(v), hi.max(v)]
    })
}

/// `st` with segment k (vertex k to k + 1) turned by `phi · g[k]` about `axis` through its
/// (moved) first vertex: every vertex turns the rest of the strand by the increment. Roots
/// and lengths stay; vertices before the first turn are copied bit for bit.
pub fn turn_strand(st: &[Vec3], g: &[f32], axis: Vec3, phi: f32) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(st.len());
    let mut moved = false;
    for (k, &q) in st.iter().enumerate() {
        if k == 0 {
            out.push(q);
            continue;
        }
        let a = phi * g[k - 1];
        moved |= a != 0.0;
        if !moved {
            out.push(q);
            continue;
        }
        let prev = out[k - 1];
        out.push(prev + Mat3::from_axis_angle(axis, a) * (q - st[k - 1]));
    }
    out
}

/// The true motion, per pixel of `from`, of the material point of `from`'s front-most strand
/// there: its image position in `to` minus that in `from` (px; NaN where no strand covers
/// the pixel). Both frames must come from the same clip.
pub fn true_flow(from: &VideoFrame, to: &VideoFrame) -> Vec<[f32; 2]> {
    let at = |f: &VideoFrame, hit: &crate::synth::synth3d::StrandHit| {
        let st = &f.strands[hit.strand as usize];
        let (a, b) = (st[hit.segment as usize], st[hit.segment as usize + 1]);
        let q = f.pose.camera.project(a + (b - a) * hit.t);
        [q.x, q.y]
    };
    from.render
        .hits
        .par_iter()
        .map(|h| match h {
            Some(hit) => {
                let (p, q) = (at(from, hit), at(to, hit));
                [q[0] - p[0], q[1] - p[1]]
            }
            None => [f32::NAN; 2],
        })
        .collect()
}

/// Per pixel of `from`: whether the material point [`true_flow`] follows is still the
/// front-most strand (the same strand, within one segment) at its pixel in `to`, so that an
/// image-based tracker can see where it went. False where no strand covers the pixel.
pub fn visible_in(from: &VideoFrame, to: &VideoFrame) -> Vec<bool> {
    let (w, h) = to.render.image.dimensions();
    from.render
        .hits
        .par_iter()
        .map(|h0| {
            let Some(hit) = h0 else { return false };
            let st = &to.strands[hit.strand as usize];
            let (a, b) = (st[hit.segment as usize], st[hit.segment as usize + 1]);
            let q = to.pose.camera.project(a + (b - a) * hit.t);
            let (x, y) = (q.x.floor(), q.y.floor());
            if !(x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32) {
                return false;
            }
            match &to.render.hits[y as usize * w as usize + x as usize] {
                Some(t) => t.strand == hit.strand && t.segment.abs_diff(hit.segment) <= 1,
                None => false,
            }
        })
        .collect()
}

/// A 2D field as (H, W, 2) float32 `.npy`.
pub fn write_field(path: &Path, w: usize, h: usize, v: &[[f32; 2]]) -> Result<()> {
    let flat: Vec<f32> = v.iter().flatten().copied().collect();
    crate::io::npy::write_f32(path, &[h, w, 2], &flat)
}

fn downscale(img: &image::RgbImage, f: f32) -> image::RgbImage {
    if f <= 1.0 {
        return img.clone();
    }
    let (w, h) = img.dimensions();
    let nw = ((w as f32 / f).round() as u32).max(1);
    let nh = ((h as f32 / f).round() as u32).max(1);
    image::imageops::resize(img, nw, nh, image::imageops::FilterType::Triangle)
}

/// The frames as a looping animated GIF, `delay_ms` per frame.
fn gif(frames: &[image::RgbImage], delay_ms: f32) -> Result<Vec<u8>> {
    use image::codecs::gif::{GifEncoder, Repeat};
    let mut bytes = Vec::new();
    {
        let mut enc = GifEncoder::new_with_speed(&mut bytes, 20);
        enc.set_repeat(Repeat::Infinite)
            .map_err(|e| Error::Invalid(format!("GIF: {e}")))?;
        let delay = image::Delay::from_numer_denom_ms(delay_ms.round().max(10.0) as u32, 1);
        for f in frames {
            let rgba = image::DynamicImage::ImageRgb8(f.clone()).to_rgba8();
            enc.encode_frame(image::Frame::from_parts(rgba, 0, 0, delay))
                .map_err(|e| Error::Invalid(format!("GIF: {e}")))?;
        }
    }
    Ok(bytes)
}
