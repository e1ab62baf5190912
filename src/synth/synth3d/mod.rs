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

use crate::error::{Error, Result};
use crate::hair::head::{Head, WeakPerspective};
use crate::hair::strands::StrandSet;
use crate::io::annot::Landmarks;
use crate::synth::{streams, theta_of, to_image, Look, Style, SynthCase, SynthParams};
use glam::{Mat3, Vec2, Vec3};
use image::{GrayImage, RgbImage};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

mod body;

mod grow;
mod render;
mod strokes;

pub use crate::eval::gt3d::{compare_to_gt, GtFigures, GT_SEARCH_M};
use body::Body;
use grow::{grow_strand, Rule, StrandVar, StyleSpec};
use render::{
    base_fill, close_mask, draw_strands, fill_dir, render_base, render_body, shade_strand,
    Footprint,
};
use strokes::make_strokes;

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
        crate::io::strands::write(&dir.join("gt_strands.hair"), &self.gt)?;
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
    Synth3dScene::new(p, o).still()
}

/// Everything of a synthetic portrait that does not depend on where the camera is: the head
/// and shoulders, the look, the grown strands with their per-strand variation, and the
/// still's camera. [`Synth3dScene::render`] draws it through any camera with any positions
/// of the same strands (a video frame); [`Synth3dScene::still`] is [`synth3d_with`].
pub struct Synth3dScene {
    pub params: SynthParams,
    pub head: Head,
    /// The still's camera.
    pub camera: WeakPerspective,
    /// Yaw of the still's camera, degrees (rotation about model y).
    pub yaw_deg: f32,
    /// Ground-truth strands at rest, model space metres, root first.
    pub strands: Vec<Vec<Vec3>>,
    body: Body,
    look: Look,
    spec: StyleSpec,
    vars: Vec<StrandVar>,
    /// The strokes stream as the scene left it: only the still draws strokes.
    stroke_rng: crate::base::rng::Rng,
}

/// The front-most visible strand at a pixel: the material point at parameter `t` of segment
/// `segment` (vertices `segment` and `segment + 1`) of strand `strand`, `t` being the pixel
/// centre's closest point on the projected segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrandHit {
    pub strand: u32,
    pub segment: u32,
    pub t: f32,
}

/// One rendering of a [`Synth3dScene`] through a camera, with its image-space ground truth.
#[derive(Clone, Debug)]
pub struct Synth3dFrame {
    pub image: RgbImage,
    /// 255 = hair, 0 otherwise.
    pub mask: GrayImage,
    /// H*W*2: unit projected growth direction of the front-most strand; NaN off hair.
    pub gt_dir: Vec<f32>,
    /// H*W: orientation in [0, pi) of `gt_dir`; NaN off hair.
    pub gt_theta: Vec<f32>,
    /// The head's landmarks projected through the camera.
    pub landmarks: Landmarks,
    /// As [`Synth3dCase::body_depth`].
    pub body_depth: Vec<f32>,
    /// As [`Synth3dCase::hair_depth`].
    pub hair_depth: Vec<f32>,
    /// H*W: the front-most visible strand's material point at each pixel its footprint
    /// covers (where `hair_depth` is finite), `None` elsewhere, also on mask pixels the
    /// closing added.
    pub hits: Vec<Option<StrandHit>>,
    /// Per-vertex colours the strands were drawn with (linear, not clamped).
    pub colors: Vec<Vec<[f32; 3]>>,
    /// The strands projected (image x, image y, depth), as drawn.
    pub proj: Vec<Vec<Vec3>>,
}

impl Synth3dScene {
    /// Grows the scene; deterministic for (params, options). Panics if a side is below
    /// [`SynthParams::MIN_SIZE`] or the style has no 3D version ([`Style::has_3d`]).
    pub fn new(p: &SynthParams, o: &Synth3dOptions) -> Synth3dScene {
        assert!(
            p.style.has_3d(),
            "the {} style is 2D only: it has no 3D synth",
            p.style
        );
        let [mut geo, mut look_rng, mut strand_rng, stroke_rng] = streams(p, style_salt(p.style));

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
        Synth3dScene {
            params: *p,
            head,
            camera,
            yaw_deg,
            strands,
            body,
            look,
            spec,
            vars,
            stroke_rng,
        }
    }

    /// Signed distance (metres) from model point `q` to the head united with the shoulders:
    /// what the hair rests on.
    pub fn body_sdf(&self, q: Vec3) -> f32 {
        self.body.sdf(q)
    }

    /// Renders the scene through `camera` with `strands` (the scene's strands, same counts,
    /// moved anywhere): body, face features at the projected landmarks, the hair mask and
    /// directions, then the strands back to front. The still is this with the scene's own
    /// camera and strands. Panics if `strands` does not match the scene's counts.
    pub fn render(&self, camera: &WeakPerspective, strands: &[Vec<Vec3>]) -> Synth3dFrame {
        assert_eq!(strands.len(), self.strands.len(), "strand count");
        let p = &self.params;
        let (w, h) = (p.width as usize, p.height as usize);
        let sc = p.width.min(p.height) as f32 / 512.0;
        let s = camera.s;

        // Body render and depth.
        let bodypix = render_body(&self.body, camera, w, h);
        let body_depth: Vec<f32> = bodypix.iter().map(|b| b.depth).collect();
        let mut rgb = render_base(&self.look, camera, &self.head, &bodypix, w, h, s);

        // Per-vertex hair colours (model space shading) and the projection.
        let view = camera.r.row(2);
        let colors: Vec<Vec<[f32; 3]>> = strands
            .iter()
            .zip(&self.vars)
            .map(|(st, v)| shade_strand(st, v, &self.look, view))
            .collect();
        let proj: Vec<Vec<Vec3>> = strands
            .iter()
            .map(|st| st.iter().map(|&q| camera.project(q)).collect())
            .collect();
        let tol = tolerance(s);

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
        base_fill(&mut rgb, &mask, &self.look, w, h);
        draw_strands(
            &mut rgb,
            &proj,
            &colors,
            &self.vars,
            &body_depth,
            tol,
            sc,
            w,
            h,
        );

        let mut lm = BTreeMap::new();
        for name in self.head.landmark_names() {
            if let Some(q) = self.head.landmark(name) {
                let q = camera.project(q);
                lm.insert(name.to_string(), [q.x, q.y]);
            }
        }
        Synth3dFrame {
            image: to_image(&rgb, p.width, p.height),
            mask: GrayImage::from_raw(p.width, p.height, mask).expect("mask size"),
            gt_dir,
            gt_theta,
            landmarks: Landmarks::new(lm),
            body_depth,
            hair_depth: fp.depth,
            hits: fp.hit,
            colors,
            proj,
        }
    }

    /// The still portrait: the scene through its own camera, with strokes.
    pub fn still(&self) -> Synth3dCase {
        let p = &self.params;
        let mut stroke_rng = self.stroke_rng.clone();
        let camera = self.camera;
        let f = self.render(&camera, &self.strands);
        let sc = p.width.min(p.height) as f32 / 512.0;
        // Where a user starts a stroke on each side of a parting: on the hair just beside it,
        // near the top of the head.
        let anchors = match self.spec.rule {
            Rule::Part { px, .. } => {
                let top = self.head.top();
                Some([-1.0f32, 1.0].map(|sd| {
                    let q = camera.project(Vec3::new(px + sd * 0.015, top.y, top.z + 0.02));
                    [q.x, q.y]
                }))
            }
            _ => None,
        };
        let strokes = make_strokes(
            &f.proj,
            &self.vars,
            anchors,
            &f.mask,
            &f.gt_dir,
            &f.body_depth,
            tolerance(camera.s),
            sc,
            &mut stroke_rng,
        );
        Synth3dCase {
            gt: strand_set(&self.strands, &f.colors),
            case: SynthCase {
                image: f.image,
                mask: f.mask,
                strokes,
                landmarks: f.landmarks,
                gt_theta: f.gt_theta,
                gt_dir: f.gt_dir,
                width: p.width,
                height: p.height,
            },
            head: self.head.clone(),
            camera,
            body_depth: f.body_depth,
            hair_depth: f.hair_depth,
            yaw_deg: self.yaw_deg,
        }
    }
}

/// Depth slack (px) within which a strand on the body's surface counts as in front of it.
fn tolerance(s: f32) -> f32 {
    0.002 * s
}

/// Strands and their per-vertex colours (clamped to 0..1) as a strand set.
pub fn strand_set(strands: &[Vec<Vec3>], colors: &[Vec<[f32; 3]>]) -> StrandSet {
    let counts: Vec<u32> = strands.iter().map(|st| st.len() as u32).collect();
    let points: Vec<[f32; 3]> = strands.iter().flatten().map(|q| q.to_array()).collect();
    let mut gt = StrandSet::new(points, counts);
    gt.colors = Some(
        colors
            .iter()
            .flatten()
            .map(|c| c.map(|v| v.clamp(0.0, 1.0)))
            .collect(),
    );
    gt
}

fn style_salt(s: Style) -> u64 {
    // Not the 2D synth's salts: the same seed should not share its look exactly.
    match s {
        Style::Long => 0x3344_4c6f,
        Style::Whorl => 0x3344_5768,
        Style::SidePart => 0x3344_5369,
        Style::Short => 0x3344_5368,
        Style::Fringe => unreachable!("2D only, refused by Synth3dScene::new"),
    }
}
