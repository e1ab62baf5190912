//! Synthetic portraits with 3D ground truth (issue 4, item 8).
//!
//! A known strand model is grown on the parametric [`Head`] by a style rule and rendered
//! through a known weak-perspective camera: background, shoulders and a Lambert-shaded head
//! (sphere-traced signed distance) with the cartoon face features of `crate::synth`, then
//! the strands back to front as anti-aliased ~1 px lines with a Kajiya-Kay highlight. The
//! image-space ground truth (mask, growth direction, strokes, landmarks) comes from the same
//! projection, so a reconstruction can be judged in 3D against `gt_strands.hair`.
//!
//! Growth (model space, metres): roots from [`Head::sample_roots`]; each strand leaves the
//! scalp at about 30° and follows a style "combing" vector `c(p)`. Near the body (head ∪
//! shoulders) the inward part of `c` is removed (the surface carries the hair) and the strand
//! is pulled to its own layer, 1.5 mm up to a style's volume (25 mm for long hair) above the
//! surface; away from it `c` turns into gravity.
//! The direction turns towards `c` by at most 12° per 2 mm step near the surface and 5° in
//! free fall, so strands are smooth; a strand stops at its length, at its style's cut line
//! (a fringe above the brows, a bob at the sides), or where staying outside the body would
//! need a sharper bend than 14.5°.
//!
//! Image-space ground truth: a z-buffer over the strands' projected footprints (pixel
//! centres within 0.75 px of a segment; the body hides what lies behind it) gives the
//! front-most visible strand per pixel. `mask` is that footprint closed by a disc of 2 px at
//! 512² (1.5 px at least) with holes under 1% of the image filled; `gt_dir` is the front-most
//! strand's projected growth direction, and in the pixels the closing added that of the
//! nearest covered pixel. Strokes follow visible front strands (root → tip); for short hair,
//! whose strands are too short, they follow `gt_dir`.
//!
//! Camera: `s` = 1000 px/m at 512² (scaled with min(w, h)/512, ±5%), a yaw about the model y
//! axis drawn in ±[`Synth3dOptions::max_yaw_deg`] (8° by default; 0 gives a frontal view),
//! and the face centre (0.3 b below the model origin) placed like `crate::synth` places its
//! face ellipse: about the image centre, a little below it.

use crate::base::mask;
use crate::base::rng::Rng;
use crate::base::sdf::{sd_ellipsoid, smin};
use crate::base::stats::{quantile, Rank};
use crate::error::{Error, Result};
use crate::hair::head::{Head, ScalpPoint, WeakPerspective};
use crate::hair::strands::StrandSet;
use crate::io::annot::{Landmarks, Stroke, StrokeKind, Strokes};
use crate::synth::{mask_interior, Style, SynthCase, SynthParams};
use glam::{DVec3, Mat3, Vec2, Vec3};
use image::{GrayImage, RgbImage};
use rayon::prelude::*;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::f32::consts::PI;
use std::path::Path;

/// Knobs beyond [`SynthParams`].
#[derive(Clone, Debug, PartialEq)]
pub struct Synth3dOptions {
    /// Ground-truth strands (roots drawn uniformly in scalp parameter space, face excluded).
    pub strands: usize,
    /// The camera yaw is drawn uniformly in ± this many degrees; 0 gives a frontal camera.
    pub max_yaw_deg: f32,
}

impl Default for Synth3dOptions {
    fn default() -> Self {
        Synth3dOptions {
            strands: 6000,
            max_yaw_deg: 8.0,
        }
    }
}

/// A synthetic portrait with its 3D ground truth.
#[derive(Clone, Debug)]
pub struct Synth3dCase {
    /// The portrait and its image-space ground truth (same files as `coif synth`).
    pub case: SynthCase,
    /// The head the strands grow on (default parameters, the ones `coif model` fits).
    pub head: Head,
    pub camera: WeakPerspective,
    /// Ground-truth strands, model space metres, root first, per-vertex colours (linear 0..1,
    /// the strand colour the renderer drew before compositing).
    pub gt: StrandSet,
    /// Front depth (px, volume space: larger = nearer) of the head and shoulders per pixel,
    /// `-inf` where the ray misses them. What hides strands behind the head.
    pub body_depth: Vec<f32>,
    /// Depth (px, volume space) of the front-most visible strand at each pixel its 1.5 px
    /// wide footprint covers, `-inf` elsewhere: the visible hair surface, and what `gt_dir`
    /// was taken from.
    pub hair_depth: Vec<f32>,
    /// Yaw of the camera, degrees (rotation about model y; positive turns the face to the
    /// image's right).
    pub yaw_deg: f32,
}

impl Synth3dCase {
    /// Writes everything [`SynthCase::write`] writes, plus `gt_strands.hair` and
    /// `camera.json` (the keys `coif model` uses in `model.json`: `camera` {s, r, t} and
    /// `image_from_model`, plus the head parameters); every file atomically.
    pub fn write(&self, dir: &Path) -> Result<()> {
        self.case.write(dir)?;
        crate::hair::strands::write(&dir.join("gt_strands.hair"), &self.gt)?;
        let meta = serde_json::json!({
            "version": 1,
            "width": self.case.width,
            "height": self.case.height,
            "units": "model space in metres, y up, the face looks toward +z",
            "image_from_model": self.camera.image_from_model(),
            "image_from_model_doc": "rows map homogeneous model points (x, y, z, 1) to image x (px, right), image y (px, down) and depth (px, toward the camera)",
            "camera": self.camera,
            "yaw_deg": self.yaw_deg,
            "head": { "params": self.head.params() },
            "gt_strands": { "file": "gt_strands.hair", "strands": self.gt.len(), "vertices": self.gt.points.len() },
        });
        let text = serde_json::to_string_pretty(&meta)
            .map_err(|e| Error::Invalid(format!("camera.json: {e}")))?;
        crate::io::write_atomic(&dir.join("camera.json"), text.as_bytes())
    }
}

/// [`synth3d_with`] with the default options.
pub fn synth3d(p: &SynthParams) -> Synth3dCase {
    synth3d_with(p, &Synth3dOptions::default())
}

/// Generates the portrait and its ground truth; deterministic for (params, options).
/// Panics if a side is below [`SynthParams::MIN_SIZE`].
pub fn synth3d_with(p: &SynthParams, o: &Synth3dOptions) -> Synth3dCase {
    assert!(
        p.width >= SynthParams::MIN_SIZE && p.height >= SynthParams::MIN_SIZE,
        "synthetic portraits need at least {0}x{0} pixels, got {1}x{2}",
        SynthParams::MIN_SIZE,
        p.width,
        p.height
    );
    let mut root = Rng::new(p.seed ^ style_salt(p.style));
    // Separate streams, so that changing how one part draws numbers leaves the others alone.
    let mut geo = root.fork(1);
    let mut look_rng = root.fork(2);
    let mut strand_rng = root.fork(3);
    let mut stroke_rng = root.fork(4);

    let head = Head::default();
    let body = Body::new(head.clone());
    let (w, h) = (p.width as usize, p.height as usize);
    let sc = p.width.min(p.height) as f32 / 512.0;

    // Camera: the synth face layout (face centre near the image centre, slightly low).
    let b_m = head.params().landmark_b;
    let s = 1000.0 * sc * (1.0 + 0.05 * geo.range_f32(-1.0, 1.0));
    let yaw_deg = o.max_yaw_deg.abs() * geo.range_f32(-1.0, 1.0);
    let cx = p.width as f32 * 0.5 + geo.range_f32(-0.025, 0.025) * w.min(h) as f32;
    let cy = p.height as f32 * 0.5 + geo.range_f32(0.0, 0.025) * w.min(h) as f32;
    let camera = WeakPerspective::new(
        s,
        Mat3::from_rotation_y(yaw_deg.to_radians()),
        Vec2::new(cx, cy - 0.3 * b_m * s),
    );
    let spec = StyleSpec::new(p.style, &head, &mut geo);
    let look = Look::new(&mut look_rng);

    // Ground-truth strands.
    let roots = head.sample_roots(o.strands, strand_rng.next_u32() as u64);
    let vars: Vec<StrandVar> = roots
        .iter()
        .map(|r| StrandVar::new(r, &spec, &mut strand_rng))
        .collect();
    let strands: Vec<Vec<Vec3>> = roots
        .par_iter()
        .zip(vars.par_iter())
        .map(|(r, v)| grow_strand(&body, &spec, r, v))
        .collect();

    // Body render and depth.
    let bodypix = render_body(&body, &camera, w, h);
    let body_depth: Vec<f32> = bodypix.iter().map(|b| b.depth).collect();
    let mut rgb = render_base(&look, &camera, &head, &bodypix, w, h, s);

    // Per-vertex hair colours (model space shading) and the projection.
    let view = camera.r.row(2);
    let colors: Vec<Vec<[f32; 3]>> = strands
        .iter()
        .zip(&vars)
        .map(|(st, v)| shade_strand(st, v, &look, view))
        .collect();
    let proj: Vec<Vec<Vec3>> = strands
        .iter()
        .map(|st| st.iter().map(|&q| camera.project(q)).collect())
        .collect();
    let tol = 0.002 * s;

    // Image-space ground truth: front-most visible strand at each pixel.
    let fp = Footprint::new(&proj, &body_depth, w, h, 0.75f32.max(0.6 * sc), tol);
    let mask = close_mask(&fp.covered(), w, h, (2.0 * sc).max(1.5));
    let (gt_dir, mask) = fill_dir(&fp, mask, w, h);
    let gt_theta: Vec<f32> = (0..w * h)
        .map(|k| {
            let d = [gt_dir[2 * k], gt_dir[2 * k + 1]];
            if d[0].is_nan() {
                f32::NAN
            } else {
                theta_of(d)
            }
        })
        .collect();

    // Hair: dark base under the mask, then the strands back to front.
    base_fill(&mut rgb, &mask, &look, w, h);
    draw_strands(&mut rgb, &proj, &colors, &vars, &body_depth, tol, sc, w, h);

    let mask_img = GrayImage::from_raw(p.width, p.height, mask).expect("mask size");
    // Where a user starts a stroke on each side of a parting: on the hair just beside it,
    // near the top of the head.
    let anchors = match spec.rule {
        Rule::Part { px, .. } => {
            let top = head.top();
            Some([-1.0f32, 1.0].map(|sd| {
                let q = camera.project(Vec3::new(px + sd * 0.015, top.y, top.z + 0.02));
                [q.x, q.y]
            }))
        }
        _ => None,
    };
    let strokes = make_strokes(
        &proj,
        &vars,
        anchors,
        &mask_img,
        &gt_dir,
        &body_depth,
        tol,
        sc,
        &mut stroke_rng,
    );
    let mut lm = BTreeMap::new();
    for name in head.landmark_names() {
        if let Some(q) = head.landmark(name) {
            let q = camera.project(q);
            lm.insert(name.to_string(), [q.x, q.y]);
        }
    }

    let mut image = RgbImage::new(p.width, p.height);
    for (px, c) in image.pixels_mut().zip(&rgb) {
        *px = image::Rgb(c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8));
    }
    let counts: Vec<u32> = strands.iter().map(|st| st.len() as u32).collect();
    let points: Vec<[f32; 3]> = strands.iter().flatten().map(|q| q.to_array()).collect();
    let mut gt = StrandSet::new(points, counts);
    gt.colors = Some(
        colors
            .into_iter()
            .flatten()
            .map(|c| c.map(|v| v.clamp(0.0, 1.0)))
            .collect(),
    );
    Synth3dCase {
        case: SynthCase {
            image,
            mask: mask_img,
            strokes,
            landmarks: Landmarks::new(lm),
            gt_theta,
            gt_dir,
            width: p.width,
            height: p.height,
        },
        head,
        camera,
        gt,
        body_depth,
        hair_depth: fp.depth,
        yaw_deg,
    }
}

fn style_salt(s: Style) -> u64 {
    // Not the 2D synth's salts: the same seed should not share its look exactly.
    match s {
        Style::Long => 0x3344_4c6f,
        Style::Whorl => 0x3344_5768,
        Style::SidePart => 0x3344_5369,
        Style::Short => 0x3344_5368,
    }
}

// Drawing helpers and colour tables shared with the 2D synth, so the look matches.
use crate::synth::{
    blend, cov, ellipse_sdf, jitter3, mix3, pick, poly_dist, resample, scale3, smoothstep,
    theta_of, Noise, HAIRS, IRISES, SKINS,
};

/// Colours of a portrait (drawn like `crate::synth`'s scene).
struct Look {
    skin: [f32; 3],
    hair: [f32; 3],
    iris: [f32; 3],
    lips: [f32; 3],
    cloth: [f32; 3],
    bg_top: [f32; 3],
    bg_bot: [f32; 3],
    noise: Noise,
}

impl Look {
    fn new(look: &mut Rng) -> Look {
        let bg_top = mix3(
            [look.next_f32(), look.next_f32(), look.next_f32()],
            [0.75, 0.75, 0.75],
            0.55,
        );
        let bg_bot = scale3(bg_top, look.range_f32(0.55, 0.8));
        Look {
            skin: jitter3(pick(look, &SKINS), look, 0.04),
            hair: jitter3(pick(look, &HAIRS), look, 0.08),
            iris: jitter3(pick(look, &IRISES), look, 0.1),
            lips: jitter3([0.72, 0.36, 0.36], look, 0.1),
            cloth: mix3(
                [look.next_f32(), look.next_f32(), look.next_f32()],
                [0.3, 0.3, 0.3],
                0.4,
            ),
            bg_top,
            bg_bot,
            noise: Noise::new(6, look),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The body: head ∪ shoulders.

/// What the hair rests on and what hides it: the head and the shoulders of the synth
/// portraits (its torso ellipse, 3.25 b below the face centre with semi-axes 2.7 a and
/// 1.75 b, made an ellipsoid 0.22 m deep under the neck).
struct Body {
    head: Head,
    torso_c: DVec3,
    torso_r: DVec3,
}

impl Body {
    fn new(head: Head) -> Body {
        let hp = head.params();
        let (a, b) = (hp.landmark_a as f64, hp.landmark_b as f64);
        let face_y = -0.3 * b;
        Body {
            torso_c: DVec3::new(0.0, face_y - 3.25 * b, hp.neck_z as f64),
            torso_r: DVec3::new(2.7 * a, 1.75 * b, 0.11),
            head,
        }
    }

    fn torso_sdf(&self, p: DVec3) -> f64 {
        sd_ellipsoid(p - self.torso_c, self.torso_r)
    }

    fn sdf64(&self, p: DVec3) -> f64 {
        // Smooth join of the neck into the shoulders; never above either distance.
        smin(self.head.sdf64(p), self.torso_sdf(p), 0.03)
    }

    fn sdf(&self, p: Vec3) -> f32 {
        self.sdf64(p.as_dvec3()) as f32
    }

    fn normal(&self, p: Vec3) -> Vec3 {
        const E: f64 = 1e-5;
        let p = p.as_dvec3();
        let f = |d: DVec3| self.sdf64(p + d) - self.sdf64(p - d);
        DVec3::new(f(DVec3::X * E), f(DVec3::Y * E), f(DVec3::Z * E))
            .try_normalize()
            .unwrap_or(DVec3::Y)
            .as_vec3()
    }

    /// Box around head and shoulders (shoulders cut well below any image).
    fn bounds(&self) -> (DVec3, DVec3) {
        let (lo, hi) = self.head.bounds();
        let (tl, th) = (self.torso_c - self.torso_r, self.torso_c + self.torso_r);
        (
            lo.as_dvec3().min(tl) - DVec3::splat(0.01),
            hi.as_dvec3().max(th) + DVec3::splat(0.01),
        )
    }
}

// ---------------------------------------------------------------------------------------------
// Styles and growth.

/// Step between strand vertices, metres.
const STEP: f32 = 0.002;
/// Largest turn per step near the surface and in free fall.
const SURF_TURN: f32 = 12.0 * PI / 180.0;
const FREE_TURN: f32 = 5.0 * PI / 180.0;
/// Hard limit: a strand that would bend more to stay outside the body stops there.
const MAX_TURN: f32 = 14.5 * PI / 180.0;
/// No vertex after the root comes closer than this to the body, metres.
const MIN_CLEAR: f32 = 0.0005;
/// Above its layer by this much a strand no longer feels the surface, metres.
const BAND: f32 = 0.015;

#[derive(Clone, Debug)]
enum Rule {
    /// Hair parted along x = px from the front hairline to the crown: each side combed away
    /// from the parting, sideways and down over the skull, then falling. `back_big/small`:
    /// how strongly hair in front is combed backwards on each side (a side part's big side
    /// sweeps across the forehead instead); `big` = the big side's sign (0 for a centre part).
    Part {
        px: f32,
        big: f32,
        back_big: f32,
        back_small: f32,
        flare: f32,
        wave: bool,
    },
    /// Spiral out of a crown point on the scalp, falling further away.
    Whorl {
        crown: Vec3,
        twist: f32,
        fall: f32,
        r0: f32,
        r1: f32,
    },
    /// Straight out of an apex above the vertex, turned by a small twist.
    Radial { apex: Vec3, twist: f32 },
}

struct StyleSpec {
    rule: Rule,
    /// Strand length range, metres.
    len: (f32, f32),
    /// Largest height of a strand's layer above the surface (the hair's volume), metres.
    layer_max: f32,
    /// Cut line: strands stop below `cut_side` (y, metres) and, in front of the face,
    /// below `cut_front` (a fringe above the brows).
    cut_side: f32,
    cut_front: f32,
}

impl StyleSpec {
    fn new(style: Style, head: &Head, g: &mut Rng) -> StyleSpec {
        let side = if g.next_f32() < 0.5 { -1.0 } else { 1.0 };
        match style {
            Style::Long => StyleSpec {
                rule: Rule::Part {
                    px: g.range_f32(-0.004, 0.004),
                    big: 0.0,
                    back_big: 0.9,
                    back_small: 0.9,
                    flare: g.range_f32(0.15, 0.3),
                    wave: true,
                },
                len: (g.range_f32(0.28, 0.32), g.range_f32(0.40, 0.45)),
                layer_max: 0.025,
                cut_side: -1.0,
                cut_front: 0.03,
            },
            Style::SidePart => StyleSpec {
                rule: Rule::Part {
                    px: side * g.range_f32(0.03, 0.045),
                    big: -side,
                    back_big: g.range_f32(0.15, 0.3),
                    back_small: 1.0,
                    flare: g.range_f32(0.0, 0.08),
                    wave: false,
                },
                len: (0.10, 0.22),
                layer_max: 0.02,
                cut_side: g.range_f32(-0.065, -0.045),
                cut_front: g.range_f32(0.012, 0.025),
            },
            Style::Whorl => {
                let uv = [0.5 + g.range_f32(-0.08, 0.08), g.range_f32(0.14, 0.22)];
                let crown = head
                    .scalp(uv)
                    .map(|sp| sp.pos)
                    .unwrap_or_else(|| head.top());
                StyleSpec {
                    rule: Rule::Whorl {
                        crown,
                        twist: side * g.range_f32(0.8, 1.1),
                        fall: g.range_f32(0.6, 0.9),
                        r0: 0.03,
                        r1: 0.12,
                    },
                    len: (0.05, 0.11),
                    layer_max: 0.015,
                    cut_side: g.range_f32(-0.03, -0.015),
                    cut_front: g.range_f32(0.02, 0.032),
                }
            }
            Style::Short => {
                let top = head.top();
                StyleSpec {
                    rule: Rule::Radial {
                        apex: top
                            + Vec3::new(
                                g.range_f32(-0.02, 0.02),
                                g.range_f32(0.03, 0.05),
                                g.range_f32(-0.03, 0.0),
                            ),
                        twist: side * g.range_f32(0.05, 0.2),
                    },
                    len: (0.015, 0.035),
                    layer_max: 0.008,
                    cut_side: g.range_f32(-0.02, -0.01),
                    cut_front: 0.03,
                }
            }
        }
    }

    /// The y below which a strand at `p` is cut.
    fn cut(&self, p: Vec3) -> f32 {
        let front = smoothstep(0.0, 0.05, p.z) * (1.0 - smoothstep(0.06, 0.09, p.x.abs()));
        self.cut_side + (self.cut_front - self.cut_side) * front
    }
}

/// Per-strand variation.
#[derive(Clone, Debug)]
struct StrandVar {
    /// Side of the parting the root is on (±1; +1 without a parting).
    side: f32,
    len: f32,
    /// Height above the surface the strand settles at, metres.
    layer: f32,
    lean: Vec3,
    cut_jit: f32,
    wave_amp: f32,
    wave_k: f32,
    wave_phase: f32,
    /// Colour factors: brightness, tint, opacity, width (px at 512).
    bright: f32,
    tint: [f32; 3],
    alpha: f32,
    width: f32,
}

impl StrandVar {
    fn new(root: &ScalpPoint, spec: &StyleSpec, r: &mut Rng) -> StrandVar {
        let side = match spec.rule {
            Rule::Part { px, .. } => {
                if root.pos.x >= px {
                    1.0
                } else {
                    -1.0
                }
            }
            _ => 1.0,
        };
        StrandVar {
            side,
            len: r.range_f32(spec.len.0, spec.len.1),
            // Denser near the scalp, as a hair volume is.
            layer: 0.0015 + (spec.layer_max - 0.0015) * r.next_f32().powf(1.3),
            lean: Vec3::new(
                r.range_f32(-1.0, 1.0),
                r.range_f32(-1.0, 1.0),
                r.range_f32(-1.0, 1.0),
            ) * 0.1,
            cut_jit: r.range_f32(-0.004, 0.004),
            wave_amp: r.range_f32(0.1, 0.25),
            wave_k: std::f32::consts::TAU / r.range_f32(0.05, 0.09),
            wave_phase: r.range_f32(0.0, std::f32::consts::TAU),
            bright: (1.0 + 0.35 * r.normal_f32()).clamp(0.55, 1.6),
            tint: [0; 3].map(|_| 1.0 + 0.05 * r.range_f32(-1.0, 1.0)),
            alpha: r.range_f32(0.6, 0.95),
            width: r.range_f32(1.0, 1.5),
        }
    }
}

/// The style's combing vector at `p` (not unit). `n` is the body normal when `surf` > 0
/// (how much the strand still feels the surface, 0..1), `arc` the length grown so far.
fn comb(spec: &StyleSpec, p: Vec3, n: Vec3, surf: f32, v: &StrandVar, arc: f32) -> Vec3 {
    let free = 1.0 - surf;
    let c = match spec.rule {
        Rule::Part {
            big,
            back_big,
            back_small,
            flare,
            wave,
            ..
        } => {
            // How far forward (towards the face) and how far behind the crown p is: behind
            // it the parting ends and hair just falls.
            let front = smoothstep(-0.02, 0.06, p.z);
            let behind = smoothstep(-0.03, -0.09, p.z);
            let back_w = if v.side == big { back_big } else { back_small };
            let lateral = v.side * (1.0 - 0.7 * behind) * (surf + free * flare);
            let mut c = Vec3::new(lateral, -(0.5 + 0.5 * free), -front * back_w);
            if wave {
                c.x += free * v.side * v.wave_amp * (v.wave_k * arc + v.wave_phase).sin();
            }
            c
        }
        Rule::Whorl {
            crown,
            twist,
            fall,
            r0,
            r1,
        } => {
            let rv = p - crown;
            let rt = rv - n * rv.dot(n) * surf;
            let rh = rt.normalize_or_zero();
            let t = rh * twist.cos() + n.cross(rh) * twist.sin() * surf;
            let g = fall * smoothstep(r0, r1, rv.length());
            let front = smoothstep(0.0, 0.06, p.z);
            t * (1.0 - 0.7 * free) - Vec3::Y * (g + free) - Vec3::Z * 0.3 * front * free
        }
        Rule::Radial { apex, twist } => {
            let rh = (p - apex).normalize_or_zero();
            let t = rh + n.cross(rh) * twist * surf;
            t - Vec3::Y * free
        }
    };
    c + v.lean
}

/// Rotates unit `d` towards unit `t` by at most `max` radians.
fn turn_towards(d: Vec3, t: Vec3, max: f32) -> Vec3 {
    let ang = d.dot(t).clamp(-1.0, 1.0).acos();
    if ang <= max {
        return t;
    }
    let axis = d.cross(t);
    let axis = if axis.length_squared() > 1e-12 {
        axis.normalize()
    } else {
        d.any_orthonormal_vector()
    };
    glam::Quat::from_axis_angle(axis, max) * d
}

fn grow_strand(body: &Body, spec: &StyleSpec, root: &ScalpPoint, v: &StrandVar) -> Vec<Vec3> {
    let mut p = root.pos;
    let n0 = root.normal;
    let c0 = comb(spec, p, n0, 1.0, v, 0.0);
    let t0 = (c0 - n0 * c0.dot(n0))
        .try_normalize()
        .unwrap_or_else(|| n0.any_orthonormal_vector());
    // Leave the scalp at about 30°.
    let mut d = (t0 + n0 * 0.6).normalize();
    let mut pts = vec![p];
    let mut arc = 0.0;
    while arc + 0.5 * STEP < v.len {
        let dist = body.sdf(p);
        let surf = 1.0 - smoothstep(v.layer, v.layer + BAND, dist);
        let n = if surf > 0.0 { body.normal(p) } else { Vec3::Y };
        let mut c = comb(spec, p, n, surf, v, arc);
        if surf > 0.0 {
            // The surface carries the hair: no inward part, and a pull up to the layer.
            let cn = c.dot(n);
            if cn < 0.0 {
                c -= n * cn * surf;
            }
            if dist < v.layer {
                c += n * (1.5 * (v.layer - dist) / v.layer) * c.length();
            }
        }
        let Some(target) = c.try_normalize() else {
            break;
        };
        let max = FREE_TURN + (SURF_TURN - FREE_TURN) * surf;
        let nd = turn_towards(d, target, max);
        let mut q = p + nd * STEP;
        let dq = body.sdf(q);
        if dq < MIN_CLEAR {
            q += body.normal(q) * (MIN_CLEAR - dq);
            q = p + (q - p).normalize() * STEP;
            if body.sdf(q) < MIN_CLEAR * 0.5 {
                break;
            }
        }
        let nd = (q - p).normalize();
        if pts.len() >= 2 && nd.dot(d).clamp(-1.0, 1.0).acos() > MAX_TURN {
            break;
        }
        // Hair rooted below the cut line (the nape under a bob) is trimmed to a stub.
        if pts.len() > 4 && q.y < spec.cut(q) + v.cut_jit {
            break;
        }
        d = nd;
        pts.push(q);
        p = q;
        arc += STEP;
    }
    pts
}

// ---------------------------------------------------------------------------------------------
// Rendering.

/// The body seen through one pixel.
#[derive(Clone, Copy, Debug)]
struct BodyPix {
    /// Depth (px) of the first hit, -inf on a miss.
    depth: f32,
    /// Pixel coverage (1 on a hit, an edge ramp from the closest approach on a miss).
    cover: f32,
    normal: Vec3,
    cloth: bool,
}

/// Sphere-traces the body along the view direction at every pixel centre.
fn render_body(body: &Body, cam: &WeakPerspective, w: usize, h: usize) -> Vec<BodyPix> {
    let dir = (-cam.r.row(2)).as_dvec3();
    let (lo, hi) = body.bounds();
    let s = cam.s as f64;
    let miss = BodyPix {
        depth: f32::NEG_INFINITY,
        cover: 0.0,
        normal: Vec3::Z,
        cloth: false,
    };
    let mut out = vec![miss; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            // Origin 1 m in front of the model origin's depth.
            let org = cam
                .unproject(Vec3::new(x as f32 + 0.5, y as f32 + 0.5, cam.s))
                .as_dvec3();
            // Slab test against the bounds.
            let (mut t0, mut t1) = (0.0f64, 3.0f64);
            for k in 0..3 {
                if dir[k].abs() < 1e-12 {
                    if org[k] < lo[k] || org[k] > hi[k] {
                        t1 = -1.0;
                    }
                    continue;
                }
                let (a, b) = ((lo[k] - org[k]) / dir[k], (hi[k] - org[k]) / dir[k]);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
            if t0 > t1 {
                continue;
            }
            let mut t = t0;
            let (mut dmin, mut tmin) = (f64::INFINITY, t0);
            let mut hit = None;
            for _ in 0..300 {
                let q = org + dir * t;
                let d = body.sdf64(q);
                if d < dmin {
                    dmin = d;
                    tmin = t;
                }
                if d < 2e-5 {
                    hit = Some(t);
                    break;
                }
                // The ellipsoid terms are estimates, not bounds: step a little short.
                t += (0.8 * d).max(2e-5);
                if t > t1 {
                    break;
                }
            }
            let (t, cover) = match hit {
                Some(t) => (t, 1.0),
                None => (tmin, cov((dmin * s) as f32)),
            };
            if cover <= 0.0 {
                continue;
            }
            let q = org + dir * t;
            let qf = q.as_vec3();
            *o = BodyPix {
                depth: if hit.is_some() {
                    cam.project(qf).z
                } else {
                    f32::NEG_INFINITY
                },
                cover,
                normal: body.normal(qf),
                cloth: body.torso_sdf(q) < body.head.sdf64(q),
            };
        }
    });
    out
}

/// Background, shoulders, head and face features.
fn render_base(
    look: &Look,
    cam: &WeakPerspective,
    head: &Head,
    body: &[BodyPix],
    w: usize,
    h: usize,
    s: f32,
) -> Vec<[f32; 3]> {
    let light = Vec3::new(-0.35, 0.45, 0.82).normalize();
    let lm = |n: &str| {
        let q = cam.project(head.landmark(n).unwrap_or(Vec3::ZERO));
        [q.x, q.y]
    };
    let feat = Features {
        a: head.params().landmark_a * s,
        b: head.params().landmark_b * s,
        eyes: [lm("left_eye"), lm("right_eye")],
        nose: lm("nose_tip"),
        mouth: [lm("mouth_left"), lm("mouth_right")],
        px: s / 1000.0,
    };
    let mut out = vec![[0.0f32; 3]; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, c) in row.iter_mut().enumerate() {
            let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
            let (u, v) = (fx / w as f32, fy / h as f32);
            let mut col = mix3(look.bg_top, look.bg_bot, v);
            let n = look.noise.sample(u, v) - 0.5;
            let vig = (u - 0.5).powi(2) + (v - 0.45).powi(2);
            col = scale3(col, (1.0 + 0.25 * n) * (1.0 - 0.35 * vig));
            let b = &body[y * w + x];
            if b.cover > 0.0 {
                let lam = b.normal.dot(light).max(0.0);
                let sc = if b.cloth {
                    scale3(look.cloth, 0.55 + 0.45 * lam)
                } else {
                    scale3(look.skin, 0.72 + 0.3 * lam)
                };
                blend(&mut col, sc, b.cover);
                if !b.cloth && b.depth.is_finite() {
                    feat.draw(&mut col, fx, fy, look);
                }
            }
            *c = col;
        }
    });
    out
}

/// The cartoon face features of `crate::synth` (`Scene::features`), placed relative to the
/// projected landmarks instead of a face ellipse.
struct Features {
    a: f32,
    b: f32,
    eyes: [[f32; 2]; 2],
    nose: [f32; 2],
    mouth: [[f32; 2]; 2],
    /// Length unit: 1 at 1000 px/m.
    px: f32,
}

impl Features {
    fn draw(&self, c: &mut [f32; 3], x: f32, y: f32, look: &Look) {
        let (a, b, s) = (self.a, self.b, self.px);
        let p = [x, y];
        // Quick reject: far from every feature.
        let near = |q: [f32; 2], r: f32| (x - q[0]).abs() < r && (y - q[1]).abs() < r;
        let r = 0.5 * b;
        let nearby = [
            self.eyes[0],
            self.eyes[1],
            self.nose,
            self.mouth[0],
            self.mouth[1],
        ];
        if !nearby.iter().any(|&q| near(q, r)) {
            return;
        }
        let brow = scale3(look.hair, 0.6);
        for (i, side) in [-1.0f32, 1.0].into_iter().enumerate() {
            let [ex, ey] = self.eyes[i];
            let pts = [
                [ex - side * 0.23 * a, ey - 0.19 * b],
                [ex, ey - 0.25 * b],
                [ex + side * 0.23 * a, ey - 0.19 * b],
            ];
            blend(c, brow, 0.9 * cov(poly_dist(p, &pts) - 0.035 * b));
            let scl = ellipse_sdf(x - ex, y - ey, 0.18 * a, 0.075 * b);
            blend(c, [0.95, 0.94, 0.92], cov(scl));
            let iris = ((x - ex).hypot(y - ey) - 0.065 * b).max(scl);
            blend(c, look.iris, cov(iris));
            let pupil = (x - ex).hypot(y - ey) - 0.03 * b;
            blend(c, [0.03, 0.03, 0.03], cov(pupil));
            let glint = (x - ex - 0.02 * b).hypot(y - ey + 0.02 * b) - 0.012 * b;
            blend(c, [1.0, 1.0, 1.0], 0.9 * cov(glint));
            let lid = (scl.abs() - 0.9 * s).max(y - ey);
            blend(c, [0.12, 0.08, 0.07], cov(lid));
        }
        let [nx, ny] = self.nose;
        for side in [-1.0f32, 1.0] {
            let nos = ellipse_sdf(
                x - (nx + side * 0.09 * a),
                y - (ny + 0.015 * b),
                0.05 * a,
                0.022 * b,
            );
            blend(c, scale3(look.skin, 0.5), cov(nos));
        }
        let (ml, mr) = (self.mouth[0], self.mouth[1]);
        let (mcx, my) = (0.5 * (ml[0] + mr[0]), 0.5 * (ml[1] + mr[1]));
        let mw = 0.5 * (mr[0] - ml[0]).abs().max(1e-3);
        let lips = ellipse_sdf(x - mcx, y - (my + 0.01 * b), mw * 1.02, 0.065 * b);
        blend(c, look.lips, cov(lips));
        let line = [
            [mcx - mw, my],
            [mcx - 0.5 * mw, my + 0.02 * b],
            [mcx, my + 0.025 * b],
            [mcx + 0.5 * mw, my + 0.02 * b],
            [mcx + mw, my],
        ];
        blend(c, [0.3, 0.1, 0.1], cov(poly_dist(p, &line) - 0.7 * s));
    }
}

/// Per-vertex strand colour: the strand's base colour, Kajiya-Kay diffuse and specular
/// terms from its 3D tangent (a highlight band across the crown), darker deep in the hair.
fn shade_strand(st: &[Vec3], v: &StrandVar, look: &Look, view: Vec3) -> Vec<[f32; 3]> {
    let light = Vec3::new(-0.3, 0.6, 0.75).normalize();
    let half = (light + view).normalize();
    let lum = 0.3 * look.hair[0] + 0.59 * look.hair[1] + 0.11 * look.hair[2];
    // A grey sheen keeps dark hair's strands visible, as on real black hair.
    let sheen = 0.16 * (1.0 - lum);
    let base: [f32; 3] = std::array::from_fn(|k| (look.hair[k] + sheen) * v.bright * v.tint[k]);
    let depth = 0.75 + 0.25 * smoothstep(0.0015, 0.012, v.layer);
    let hl = mix3(look.hair, [1.0, 0.97, 0.9], 0.6);
    (0..st.len())
        .map(|i| {
            let (a, b) = (st[i.saturating_sub(1)], st[(i + 1).min(st.len() - 1)]);
            let t = (b - a).normalize_or_zero();
            let tl = t.dot(light);
            let diffuse = (1.0 - tl * tl).max(0.0).sqrt();
            let th = t.dot(half);
            let spec = (1.0 - th * th).max(0.0).powf(30.0);
            let f = depth * (0.55 + 0.45 * diffuse);
            std::array::from_fn(|k| base[k] * f + 0.3 * spec * hl[k])
        })
        .collect()
}

/// Front-most visible strand per pixel: a z-buffer over pixel centres within `radius` px of
/// a projected segment, with the body hiding what lies behind it.
struct Footprint {
    depth: Vec<f32>,
    dir: Vec<[f32; 2]>,
}

impl Footprint {
    fn new(proj: &[Vec<Vec3>], body_depth: &[f32], w: usize, h: usize, r: f32, tol: f32) -> Self {
        let mut depth = vec![f32::NEG_INFINITY; w * h];
        let mut dir = vec![[f32::NAN; 2]; w * h];
        for st in proj {
            for seg in st.windows(2) {
                let (a, b) = (seg[0], seg[1]);
                let (dx, dy) = (b.x - a.x, b.y - a.y);
                let l2 = dx * dx + dy * dy;
                // Segments seen end-on have no image direction.
                if l2 < 1e-6 {
                    continue;
                }
                let l = l2.sqrt();
                let u = [dx / l, dy / l];
                let x0 = (a.x.min(b.x) - r).floor().max(0.0) as usize;
                let x1 = ((a.x.max(b.x) + r).ceil().max(0.0) as usize).min(w);
                let y0 = (a.y.min(b.y) - r).floor().max(0.0) as usize;
                let y1 = ((a.y.max(b.y) + r).ceil().max(0.0) as usize).min(h);
                for y in y0..y1 {
                    for x in x0..x1 {
                        let (px, py) = (x as f32 + 0.5 - a.x, y as f32 + 0.5 - a.y);
                        let t = ((px * dx + py * dy) / l2).clamp(0.0, 1.0);
                        if (px - t * dx).hypot(py - t * dy) > r {
                            continue;
                        }
                        let k = y * w + x;
                        let z = a.z + t * (b.z - a.z);
                        if z < body_depth[k] - tol || z <= depth[k] {
                            continue;
                        }
                        depth[k] = z;
                        dir[k] = u;
                    }
                }
            }
        }
        Footprint { depth, dir }
    }

    fn covered(&self) -> Vec<bool> {
        self.depth.iter().map(|d| d.is_finite()).collect()
    }
}

/// Morphological closing (disc of radius r; outside the image counts as hair for the
/// erosion, so hair reaching the border stays), then small holes (< 1% of the image) filled.
/// Returns 255 / 0 bytes.
fn close_mask(raw: &[bool], w: usize, h: usize, r: f32) -> Vec<u8> {
    let offs = mask::disc(r, false);
    let mut m = mask::erode_by(&mask::dilate_by(raw, w, h, &offs, false), w, h, &offs, true);
    // Holes: 4-connected non-hair components not touching the border.
    let mut fill = Vec::new();
    mask::for_each_component(&m, w, h, false, false, |comp, border| {
        if !border && comp.len() * 100 < w * h {
            fill.extend_from_slice(comp);
        }
    });
    for k in fill {
        m[k] = true;
    }
    m.iter().map(|&b| if b { 255 } else { 0 }).collect()
}

/// gt_dir over the mask: the footprint's direction where a strand passes, elsewhere (gaps
/// the closing filled) that of the nearest covered pixel (breadth-first inside the mask).
/// Mask pixels no covered pixel reaches are dropped from the mask.
fn fill_dir(fp: &Footprint, mut mask: Vec<u8>, w: usize, h: usize) -> (Vec<f32>, Vec<u8>) {
    let mut dir = vec![f32::NAN; 2 * w * h];
    let mut queue = VecDeque::new();
    for k in 0..w * h {
        if mask[k] != 0 && fp.depth[k].is_finite() {
            dir[2 * k] = fp.dir[k][0];
            dir[2 * k + 1] = fp.dir[k][1];
            queue.push_back(k);
        }
    }
    while let Some(k) = queue.pop_front() {
        let (x, y) = ((k % w) as i64, (k / w) as i64);
        for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                continue;
            }
            let j = ny as usize * w + nx as usize;
            if mask[j] != 0 && dir[2 * j].is_nan() {
                dir[2 * j] = dir[2 * k];
                dir[2 * j + 1] = dir[2 * k + 1];
                queue.push_back(j);
            }
        }
    }
    for k in 0..w * h {
        if dir[2 * k].is_nan() {
            mask[k] = 0;
        }
    }
    (dir, mask)
}

/// Dark base colour of the hair under the mask (soft-edged), so no skin or background
/// shows through gaps between strands.
fn base_fill(rgb: &mut [[f32; 3]], mask: &[u8], look: &Look, w: usize, h: usize) {
    let base = scale3(look.hair, 0.4);
    for y in 0..h {
        for x in 0..w {
            let mut sum = 0.0;
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let (nx, ny) = (
                        (x as i64 + dx).clamp(0, w as i64 - 1) as usize,
                        (y as i64 + dy).clamp(0, h as i64 - 1) as usize,
                    );
                    sum += mask[ny * w + nx] as f32 / 255.0;
                }
            }
            let a = if mask[y * w + x] != 0 { 1.0 } else { sum / 9.0 };
            blend(&mut rgb[y * w + x], base, a);
        }
    }
}

/// Draws the strands in painter's order over pieces of 12 segments (sorted by mean depth,
/// far first). Within a piece each pixel keeps its largest coverage, so a strand does not
/// darken its own pixels twice; the body hides what lies behind it.
#[allow(clippy::too_many_arguments)]
fn draw_strands(
    rgb: &mut [[f32; 3]],
    proj: &[Vec<Vec3>],
    colors: &[Vec<[f32; 3]>],
    vars: &[StrandVar],
    body_depth: &[f32],
    tol: f32,
    sc: f32,
    w: usize,
    h: usize,
) {
    const PIECE: usize = 12;
    // Arc length (projected px) at every vertex, for the tapers.
    let arcs: Vec<Vec<f32>> = proj
        .iter()
        .map(|st| {
            let mut acc = 0.0;
            let mut a = vec![0.0];
            for q in st.windows(2) {
                acc += (q[1].x - q[0].x).hypot(q[1].y - q[0].y);
                a.push(acc);
            }
            a
        })
        .collect();
    let mut pieces: Vec<(f32, u32, u32)> = Vec::new();
    for (si, st) in proj.iter().enumerate() {
        let nseg = st.len().saturating_sub(1);
        let mut i = 0;
        while i < nseg {
            let j = (i + PIECE).min(nseg);
            let z = st[i..=j].iter().map(|q| q.z).sum::<f32>() / (j - i + 1) as f32;
            pieces.push((z, si as u32, i as u32));
            i = j;
        }
    }
    pieces.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));

    let mut stamp = vec![0u32; w * h];
    let mut cover = vec![0.0f32; w * h];
    let mut col = vec![[0.0f32; 3]; w * h];
    let mut zs = vec![0.0f32; w * h];
    let mut touched = Vec::new();
    let wscale = sc.clamp(0.75, 1.5);
    for (id, &(_, si, i0)) in pieces.iter().enumerate() {
        let id = id as u32 + 1;
        let (si, i0) = (si as usize, i0 as usize);
        let st = &proj[si];
        let arc = &arcs[si];
        let total = *arc.last().unwrap_or(&0.0);
        let v = &vars[si];
        let width = v.width * wscale;
        let half = 0.5 * width;
        let tip_taper = (4.0 * sc).min(0.4 * total).max(1e-3);
        let root_taper = (2.0 * sc).min(0.35 * total).max(1e-3);
        touched.clear();
        let i1 = (i0 + PIECE).min(st.len() - 1);
        for i in i0..i1 {
            let (a, b) = (st[i], st[i + 1]);
            let mid = 0.5 * (arc[i] + arc[i + 1]);
            let taper = smoothstep(0.0, root_taper, mid) * smoothstep(0.0, tip_taper, total - mid);
            let (dx, dy) = (b.x - a.x, b.y - a.y);
            let l2 = dx * dx + dy * dy;
            let pad = half + 1.0;
            let x0 = (a.x.min(b.x) - pad).floor().max(0.0) as usize;
            let x1 = ((a.x.max(b.x) + pad).ceil().max(0.0) as usize).min(w);
            let y0 = (a.y.min(b.y) - pad).floor().max(0.0) as usize;
            let y1 = ((a.y.max(b.y) + pad).ceil().max(0.0) as usize).min(h);
            for y in y0..y1 {
                for x in x0..x1 {
                    let (px, py) = (x as f32 + 0.5 - a.x, y as f32 + 0.5 - a.y);
                    let t = if l2 > 0.0 {
                        ((px * dx + py * dy) / l2).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    let d = (px - t * dx).hypot(py - t * dy);
                    let c = (half + 0.5 - d).clamp(0.0, 1.0).min(width) * taper;
                    if c <= 0.0 {
                        continue;
                    }
                    let k = y * w + x;
                    if stamp[k] != id {
                        stamp[k] = id;
                        cover[k] = 0.0;
                        touched.push(k);
                    }
                    if c > cover[k] {
                        cover[k] = c;
                        zs[k] = a.z + t * (b.z - a.z);
                        col[k] = mix3(colors[si][i], colors[si][i + 1], t);
                    }
                }
            }
        }
        for &k in &touched {
            if zs[k] >= body_depth[k] - tol {
                blend(&mut rgb[k], col[k], v.alpha * cover[k]);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Strokes.

/// What the stroke maker needs to know about the image.
struct StrokeCtx<'a> {
    proj: &'a [Vec<Vec3>],
    mask: &'a GrayImage,
    inner: Vec<bool>,
    /// A narrower margin for the strokes beside a parting: the narrow side of a side part
    /// leaves little room, and a user follows the hair closer to its edge there.
    inner_near: Vec<bool>,
    gt_dir: &'a [f32],
    body_depth: &'a [f32],
    tol: f32,
    /// Length unit: 1 at 512 px (at least 0.25).
    su: f32,
}

impl StrokeCtx<'_> {
    fn pix(&self, q: [f32; 2]) -> Option<usize> {
        let (w, h) = (self.mask.width() as usize, self.mask.height() as usize);
        let (x, y) = (q[0].floor(), q[1].floor());
        (x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h)
            .then(|| y as usize * w + x as usize)
    }

    /// A stroke along strand `si`: its longest run of vertices that are visible, well inside
    /// the hair, not foreshortened and within 20° of gt_dir (so on the front layer), cut to
    /// 70-150 px (from the run's start with `from_start`, for the strokes beside a parting,
    /// else at a random offset),
    /// resampled every 10 px and checked against gt_dir. None if under 40 px.
    fn along(&self, si: usize, from_start: bool, rng: &mut Rng) -> Option<Vec<[f32; 2]>> {
        let st = &self.proj[si];
        let inner = if from_start {
            &self.inner_near
        } else {
            &self.inner
        };
        let cos20 = 20f32.to_radians().cos();
        let good: Vec<bool> = (0..st.len())
            .map(|i| {
                let q = st[i];
                let Some(k) = self.pix([q.x, q.y]) else {
                    return false;
                };
                let (a, b) = (st[i.saturating_sub(1)], st[(i + 1).min(st.len() - 1)]);
                let (dx, dy) = (b.x - a.x, b.y - a.y);
                let l = dx.hypot(dy);
                inner[k]
                    && q.z >= self.body_depth[k] - self.tol
                    && l > 0.5 * (b - a).length()
                    && l > 1e-3
                    && (dx * self.gt_dir[2 * k] + dy * self.gt_dir[2 * k + 1]) / l > cos20
            })
            .collect();
        let (mut best, mut start) = ((0, 0), 0);
        for i in 0..=good.len() {
            if i == good.len() || !good[i] {
                if i - start > best.1 - best.0 {
                    best = (start, i);
                }
                start = i + 1;
            }
        }
        if best.1 - best.0 < 2 {
            return None;
        }
        let run: Vec<[f32; 2]> = st[best.0..best.1].iter().map(|q| [q.x, q.y]).collect();
        let want = rng.range_f32(70.0, 150.0) * self.su;
        let run = sub_run(&run, want, from_start, rng);
        self.finish(&run)
    }

    fn finish(&self, path: &[[f32; 2]]) -> Option<Vec<[f32; 2]>> {
        let (w, h) = (self.mask.width() as usize, self.mask.height() as usize);
        let pts = checked_prefix(resample(path, 10.0 * self.su), self.mask, self.gt_dir, w, h);
        let total: f32 = pts
            .windows(2)
            .map(|q| (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]))
            .sum();
        (pts.len() >= 2 && total >= 40.0 * self.su).then_some(pts)
    }
}

/// 4-6 direction strokes along visible front strands (root → tip), well inside the hair,
/// agreeing with gt_dir, spread out. With a parting, first one on each side starting just
/// beside it at the top (`anchors`), drawn away from it, as a user would: that is what
/// decides the growth direction of the curves meeting at the parting.
#[allow(clippy::too_many_arguments)]
fn make_strokes(
    proj: &[Vec<Vec3>],
    vars: &[StrandVar],
    anchors: Option<[[f32; 2]; 2]>,
    mask: &GrayImage,
    gt_dir: &[f32],
    body_depth: &[f32],
    tol: f32,
    sc: f32,
    rng: &mut Rng,
) -> Strokes {
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    let ctx = StrokeCtx {
        proj,
        mask,
        // As `crate::synth` from 256² up; smaller images (whose hair is only a few dozen
        // pixels across) get proportionally smaller margins and strokes.
        inner: mask_interior(mask, 7.0 * (1.2 * sc).clamp(0.36, 0.6).max(sc)),
        inner_near: mask_interior(mask, 0.35 * 7.0 * (1.2 * sc).clamp(0.36, 0.6).max(sc)),
        gt_dir,
        body_depth,
        tol,
        su: sc.max(0.25),
    };
    let su = ctx.su;
    let mut chosen: Vec<Vec<[f32; 2]>> = Vec::new();
    if let Some(anchors) = anchors {
        for (side, a) in [(-1.0f32, anchors[0]), (1.0, anchors[1])] {
            // Strands of that side rooted nearest the anchor, followed from their start.
            let mut near: Vec<(f32, usize)> = (0..proj.len())
                .filter(|&si| vars[si].side == side)
                .map(|si| ((proj[si][0].x - a[0]).hypot(proj[si][0].y - a[1]), si))
                .collect();
            near.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            let best = near
                .iter()
                .take(150)
                .filter_map(|&(_, si)| ctx.along(si, true, rng))
                .filter(|pts| pts.iter().all(|q| (q[0] - a[0]) * side >= -2.0))
                .min_by(|x, y| {
                    let d = |p: &[[f32; 2]]| (p[0][0] - a[0]).hypot(p[0][1] - a[1]);
                    d(x).total_cmp(&d(y))
                });
            chosen.extend(best);
        }
    }

    // Candidates for the rest, from strands in random order.
    let mut order: Vec<usize> = (0..proj.len()).collect();
    for i in (1..order.len()).rev() {
        order.swap(i, rng.below(i as u32 + 1) as usize);
    }
    let mut cands: Vec<Vec<[f32; 2]>> = Vec::new();
    for &si in &order {
        if cands.len() >= 300 {
            break;
        }
        cands.extend(ctx.along(si, false, rng));
    }
    // Short hair has no strand long enough for a stroke: follow the front-most strands'
    // image direction instead (what a user tracing the visible hair would draw).
    let mut tries = 0;
    while cands.len() < 12 && tries < 3000 {
        tries += 1;
        let q = [rng.range_f32(0.0, w as f32), rng.range_f32(0.0, h as f32)];
        if ctx.pix(q).is_none_or(|k| !ctx.inner[k]) {
            continue;
        }
        let len = rng.range_f32(70.0, 150.0) * su;
        let back = len * rng.range_f32(0.3, 0.6);
        let mut path = trace_dir(q, -1.0, back, gt_dir, &ctx.inner, w, h);
        path.reverse();
        path.push(q);
        path.extend(trace_dir(q, 1.0, len - back, gt_dir, &ctx.inner, w, h));
        cands.extend(ctx.finish(&path));
    }
    // Prefer the longer half when there is a choice: short strokes say little.
    let arc = |p: &[[f32; 2]]| -> f32 {
        p.windows(2)
            .map(|q| (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]))
            .sum()
    };
    let long: Vec<Vec<[f32; 2]>> = cands
        .iter()
        .filter(|p| arc(p) >= 55.0 * su)
        .cloned()
        .collect();
    if long.len() >= 12 {
        cands = long;
    }
    let want = 4 + rng.below(3) as usize;
    let mut used: Vec<[f32; 2]> = chosen.iter().flatten().copied().collect();
    while chosen.len() < want && !cands.is_empty() {
        // Farthest from what is already drawn, with a little randomness.
        let best = cands
            .iter()
            .enumerate()
            .map(|(i, pts)| {
                let d = pts
                    .iter()
                    .flat_map(|p| used.iter().map(move |q| (p[0] - q[0]).hypot(p[1] - q[1])))
                    .fold(f32::INFINITY, f32::min);
                let d = if d.is_finite() { d } else { 1e9 };
                (i, d * rng.range_f32(0.8, 1.0))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((i, _)) = best else { break };
        let pts = cands.swap_remove(i);
        used.extend(pts.iter().copied());
        chosen.push(pts);
    }
    Strokes::new(
        chosen
            .into_iter()
            .map(|points| Stroke {
                kind: StrokeKind::Direction,
                points,
            })
            .collect(),
    )
}

/// Follows gt_dir (nearest pixel, half-pixel steps) from `start` for up to `len` px, with
/// `sign` -1 against the growth direction; stops leaving `inner` or where the direction
/// jumps (a parting). Returns the points after `start`.
fn trace_dir(
    start: [f32; 2],
    sign: f32,
    len: f32,
    gt_dir: &[f32],
    inner: &[bool],
    w: usize,
    h: usize,
) -> Vec<[f32; 2]> {
    let at = |q: [f32; 2]| -> Option<[f32; 2]> {
        let (x, y) = (q[0].floor(), q[1].floor());
        if x < 0.0 || y < 0.0 || x as usize >= w || y as usize >= h {
            return None;
        }
        let k = y as usize * w + x as usize;
        (inner[k] && gt_dir[2 * k].is_finite())
            .then(|| [sign * gt_dir[2 * k], sign * gt_dir[2 * k + 1]])
    };
    let mut out = Vec::new();
    let mut p = start;
    let Some(mut prev) = at(p) else {
        return out;
    };
    let mut travelled = 0.0;
    while travelled < len {
        let Some(d) = at(p) else { break };
        if d[0] * prev[0] + d[1] * prev[1] < 0.9 {
            break;
        }
        // Midpoint step, so curved hair is followed without drifting outwards.
        let Some(d2) = at([p[0] + 0.25 * d[0], p[1] + 0.25 * d[1]]) else {
            break;
        };
        let q = [p[0] + 0.5 * d2[0], p[1] + 0.5 * d2[1]];
        if at(q).is_none() {
            break;
        }
        out.push(q);
        travelled += 0.5;
        p = q;
        prev = d;
    }
    out
}

/// A piece of about `len` px of arc length from a polyline, from its start or at a random
/// offset.
fn sub_run(path: &[[f32; 2]], len: f32, from_start: bool, rng: &mut Rng) -> Vec<[f32; 2]> {
    let mut arc = vec![0.0f32];
    for q in path.windows(2) {
        arc.push(arc.last().unwrap() + (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]));
    }
    let total = *arc.last().unwrap();
    if total <= len {
        return path.to_vec();
    }
    let off = if from_start {
        0.0
    } else {
        rng.range_f32(0.0, total - len)
    };
    path.iter()
        .zip(&arc)
        .filter(|(_, &a)| a >= off && a <= off + len)
        .map(|(p, _)| *p)
        .collect()
}

/// The longest prefix of a stroke whose points are hair and whose segments agree with the
/// ground truth at their midpoints (from `crate::synth`).
fn checked_prefix(
    pts: Vec<[f32; 2]>,
    mask: &GrayImage,
    gt_dir: &[f32],
    w: usize,
    h: usize,
) -> Vec<[f32; 2]> {
    let m = mask.as_raw();
    let at = |p: [f32; 2]| -> Option<usize> {
        let (ix, iy) = (p[0].floor() as i64, p[1].floor() as i64);
        (ix >= 0 && iy >= 0 && (ix as usize) < w && (iy as usize) < h)
            .then(|| iy as usize * w + ix as usize)
            .filter(|&i| m[i] > 0)
    };
    let mut out: Vec<[f32; 2]> = Vec::new();
    for p in pts {
        if at(p).is_none() {
            break;
        }
        if let Some(&q) = out.last() {
            let mid = [(p[0] + q[0]) * 0.5, (p[1] + q[1]) * 0.5];
            let Some(i) = at(mid) else { break };
            let l = (p[0] - q[0]).hypot(p[1] - q[1]).max(1e-6);
            let seg = [(p[0] - q[0]) / l, (p[1] - q[1]) / l];
            if seg[0] * gt_dir[2 * i] + seg[1] * gt_dir[2 * i + 1] < 12f32.to_radians().cos() {
                break;
            }
        }
        out.push(p);
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Comparison with the ground truth.

/// How close a reconstructed strand model is to the ground truth, in 3D (model space).
#[derive(Clone, Debug, serde::Serialize)]
pub struct GtFigures {
    pub model_vertices: usize,
    pub gt_vertices: usize,
    /// Angle between each model vertex's tangent and the tangent of the nearest GT vertex,
    /// sign-aware (root → tip both), degrees: median, and the share within 30°. Model
    /// vertices with no GT vertex within [`GT_SEARCH_M`] count as 180°; vertices of
    /// one-vertex strands (no tangent) are left out.
    pub tangent_median_deg: f32,
    pub tangent_within_30: f32,
    /// Distance of each model vertex to the nearest GT vertex, mm (capped at
    /// [`GT_SEARCH_M`]): median and 90th percentile.
    pub dist_median_mm: f32,
    pub dist_p90_mm: f32,
    /// Share of GT vertices with a model vertex within 1 cm.
    pub gt_covered_1cm: f32,
    /// Share of model vertices more than 1 mm inside the head.
    pub model_inside_head: f32,
}

/// Nearest-neighbour searches give up beyond this distance, metres.
pub const GT_SEARCH_M: f32 = 0.05;

/// Uniform-grid spatial hash over points.
struct PointHash {
    cell: f32,
    map: HashMap<[i32; 3], (u32, u32)>,
    order: Vec<u32>,
    pts: Vec<Vec3>,
}

impl PointHash {
    fn new(pts: Vec<Vec3>, cell: f32) -> Self {
        let key = |p: Vec3| (p / cell).floor().as_ivec3().to_array();
        let mut order: Vec<u32> = (0..pts.len() as u32).collect();
        order.sort_by_key(|&i| key(pts[i as usize]));
        let mut map = HashMap::new();
        let mut i = 0;
        while i < order.len() {
            let k = key(pts[order[i] as usize]);
            let mut j = i + 1;
            while j < order.len() && key(pts[order[j] as usize]) == k {
                j += 1;
            }
            map.insert(k, (i as u32, j as u32));
            i = j;
        }
        PointHash {
            cell,
            map,
            order,
            pts,
        }
    }

    /// Whether any point lies within `r`.
    fn any_within(&self, p: Vec3, r: f32) -> bool {
        let lo = ((p - r) / self.cell).floor().as_ivec3();
        let hi = ((p + r) / self.cell).floor().as_ivec3();
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    if let Some(&(a, b)) = self.map.get(&[x, y, z]) {
                        if self.order[a as usize..b as usize]
                            .iter()
                            .any(|&i| self.pts[i as usize].distance(p) <= r)
                        {
                            return true;
                        }
                    }
                }
            }
        }
        false
    }

    /// Nearest point within `max` (index, distance).
    fn nearest(&self, p: Vec3, max: f32) -> Option<(usize, f32)> {
        let c = (p / self.cell).floor().as_ivec3();
        let rings = (max / self.cell).ceil() as i32 + 1;
        let mut best: Option<(usize, f32)> = None;
        for r in 0..=rings {
            // Every point in ring r+1 or beyond is at least r cells away.
            if let Some((_, d)) = best {
                if d <= (r - 1).max(0) as f32 * self.cell {
                    break;
                }
            }
            for dz in -r..=r {
                for dy in -r..=r {
                    for dx in -r..=r {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != r {
                            continue;
                        }
                        let k = [c.x + dx, c.y + dy, c.z + dz];
                        let Some(&(a, b)) = self.map.get(&k) else {
                            continue;
                        };
                        for &i in &self.order[a as usize..b as usize] {
                            let d = self.pts[i as usize].distance(p);
                            if d <= max && best.is_none_or(|(_, bd)| d < bd) {
                                best = Some((i as usize, d));
                            }
                        }
                    }
                }
            }
        }
        best
    }
}

/// Unit tangents (root → tip) of every vertex, central differences.
fn tangents(s: &StrandSet) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(s.points.len());
    for st in s.strands() {
        for i in 0..st.len() {
            let a = Vec3::from_array(st[i.saturating_sub(1)]);
            let b = Vec3::from_array(st[(i + 1).min(st.len() - 1)]);
            out.push((b - a).normalize_or_zero());
        }
    }
    out
}

/// Compares a reconstructed model (model space, metres) with the ground truth.
pub fn compare_to_gt(model: &StrandSet, gt: &StrandSet, head: &Head) -> GtFigures {
    let gt_pts: Vec<Vec3> = gt.points.iter().map(|&p| Vec3::from_array(p)).collect();
    let m_pts: Vec<Vec3> = model.points.iter().map(|&p| Vec3::from_array(p)).collect();
    let gt_tan = tangents(gt);
    let m_tan = tangents(model);
    let gh = PointHash::new(gt_pts.clone(), 0.01);
    // (angle, or NaN for a vertex without a tangent; distance mm).
    let per: Vec<(f32, f32)> = m_pts
        .par_iter()
        .zip(m_tan.par_iter())
        .map(|(&p, &t)| {
            let tangent = t != Vec3::ZERO;
            match gh.nearest(p, GT_SEARCH_M) {
                Some((i, d)) => {
                    let g = gt_tan[i];
                    let ang = if !tangent {
                        f32::NAN
                    } else if g == Vec3::ZERO {
                        // A GT strand of one vertex has no direction to agree with.
                        180.0
                    } else {
                        t.dot(g).clamp(-1.0, 1.0).acos().to_degrees()
                    };
                    (ang, d * 1000.0)
                }
                None => (if tangent { 180.0 } else { f32::NAN }, GT_SEARCH_M * 1000.0),
            }
        })
        .collect();
    let mut angs: Vec<f32> = per.iter().map(|x| x.0).filter(|a| !a.is_nan()).collect();
    let mut dists: Vec<f32> = per.iter().map(|x| x.1).collect();
    let within = angs.iter().filter(|&&a| a <= 30.0).count();
    let n_ang = angs.len().max(1) as f32;
    let mh = PointHash::new(m_pts.clone(), 0.01);
    let covered = gt_pts
        .par_iter()
        .filter(|&&p| mh.any_within(p, 0.01))
        .count();
    let inside = m_pts.par_iter().filter(|&&p| head.sdf(p) < -0.001).count();
    let n = m_pts.len().max(1) as f32;
    GtFigures {
        model_vertices: m_pts.len(),
        gt_vertices: gt_pts.len(),
        tangent_median_deg: quantile(&mut angs, 0.5, Rank::Floor).unwrap_or(f32::NAN),
        tangent_within_30: within as f32 / n_ang,
        dist_median_mm: quantile(&mut dists, 0.5, Rank::Floor).unwrap_or(f32::NAN),
        dist_p90_mm: quantile(&mut dists, 0.9, Rank::Floor).unwrap_or(f32::NAN),
        gt_covered_1cm: covered as f32 / gt_pts.len().max(1) as f32,
        model_inside_head: inside as f32 / n,
    }
}
