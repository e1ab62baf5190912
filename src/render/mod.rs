//! Rendering a hair model back into its photo (C13 §4).
//!
//! Layers, back to front:
//! 1. the background ([`layers`]): at the original view the photo itself (so hair pixels no
//!    strand covers come back as the photo's hair); at a novel view the photo with the hair
//!    and the face removed and filled by PatchMatch inpainting ([`crate::render::inpaint`]),
//!    the same for every novel view;
//! 2. the head mesh, depth-tested: at the original view it carries the photo itself
//!    (screen-space uvs, texel centres on pixel centres, so it only hides strands behind the
//!    head); at a novel view it keeps what the photo shows as head and neck skin and carries
//!    the face texture projected from the photo with its unseen parts mirrored or filled
//!    ([`crate::hair::head::texture`]);
//! 3. the strands, one screen-aligned quad per segment with per-vertex colour and alpha
//!    (the colours sampled from the photo by `coif model`, recoloured in HSV and given
//!    highlights by [`crate::render::shade`]), MSAA with alpha-to-coverage, no depth sorting
//!    ([`crate::render::raster`]).
//!
//! Views: the model's weak-perspective camera turned about the head centre (the model
//! origin) by yaw, pitch and roll; optionally a pinhole camera at a distance, whose focal
//! length keeps the head's scale (`distance`), so the view can also be put inside the head,
//! which is refused.

pub mod face_warp;
pub mod inpaint;
pub mod layers;
pub mod raster;
pub mod shade;

use crate::base::colour;
use crate::error::{Error, Result};
use crate::hair::head::texture::HeadTextureParams;
use crate::hair::head::WeakPerspective;
use crate::hair::scene::Scene;
use crate::hair::strands::StrandSet;
use crate::render::inpaint::InpaintParams;
use crate::render::raster::{Frame, RasterParams, ScreenStrands, StrandPhoto, Texture};
use crate::render::shade::ShadeParams;
use crate::Engine;
use glam::{Mat3, Vec2, Vec3};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Colour of strands whose file carries none (a mid brown, linear RGB).
pub const DEFAULT_HAIR_LINEAR: [f32; 3] = [0.12, 0.06, 0.03];

/// Largest output side: the frame and its 4x MSAA targets must fit a GPU buffer.
pub const MAX_SIDE: u32 = 8192;

/// Where a composite render's strand colour comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ColourSource {
    /// The photo at every fragment, at the point where the photo's camera saw that part of
    /// the strand ([`crate::render::raster::StrandPhoto`]); shading and recolouring apply on top. The
    /// limit of C13 §4's per-vertex sampling as the vertex spacing goes to zero: at the
    /// original view the covered hair reproduces the photo (synthetic re-renders 27-29 dB
    /// where the strands cover the hair, against 20-24 dB from vertex colours; issue 5 note).
    #[default]
    Photo,
    /// C13 §4 as written: the colour sampled at each vertex, interpolated along segments.
    Vertex,
}

/// Every setting of a render (written to the sidecar).
#[derive(Clone, Debug, Serialize)]
pub struct RenderParams {
    /// Degrees the head turns about its vertical axis; positive turns the face toward the
    /// image's right.
    pub yaw_deg: f32,
    /// Degrees the head tilts; positive turns the face up.
    pub pitch_deg: f32,
    /// Degrees the head rolls in the image plane; positive is counter-clockwise on screen.
    pub roll_deg: f32,
    /// A pinhole camera this far from the head centre (model units: metres for `coif model`
    /// output) instead of the weak-perspective one; its focal length keeps the head's scale.
    pub distance: Option<f32>,
    /// Output size relative to the model's image (strand width scales with it).
    pub scale: f32,
    /// Output size for models without a photo (imported strands).
    pub size: (u32, u32),
    pub raster: RasterParams,
    pub shade: ShadeParams,
    /// Only the strands, over `background` (transparent when None); no photo, no head.
    pub strands_only: bool,
    /// sRGB 0..1 background colour for `strands_only`.
    pub background: Option<[f32; 3]>,
    /// Spacing (photo px) of extra vertices whose colour is sampled from the photo along each
    /// strand at render time; 0 (default) draws the model's own vertex colours only. At 1 px
    /// the synthetic long-hair re-render gains 0.3 dB for 4x the time (issue 5 note).
    pub colour_spacing_px: f32,
    /// Where strand colour comes from in a composite render of a model with a photo.
    pub colour: ColourSource,
    /// Pixels the hair mask grows by before it is inpainted (the hair's soft edge).
    pub hair_margin_px: u32,
    pub inpaint: InpaintParams,
    pub head_texture: HeadTextureParams,
}

impl Default for RenderParams {
    fn default() -> Self {
        RenderParams {
            yaw_deg: 0.0,
            pitch_deg: 0.0,
            roll_deg: 0.0,
            distance: None,
            scale: 1.0,
            size: (512, 512),
            raster: RasterParams::default(),
            shade: ShadeParams::default(),
            strands_only: false,
            background: None,
            colour_spacing_px: 0.0,
            colour: ColourSource::default(),
            hair_margin_px: 2,
            inpaint: InpaintParams::default(),
            head_texture: HeadTextureParams::default(),
        }
    }
}

impl RenderParams {
    pub fn is_original_view(&self) -> bool {
        self.yaw_deg == 0.0
            && self.pitch_deg == 0.0
            && self.roll_deg == 0.0
            && self.distance.is_none()
    }

    fn validate(&self) -> Result<()> {
        let angles = [self.yaw_deg, self.pitch_deg, self.roll_deg];
        if !angles.iter().all(|a| a.is_finite()) {
            return Err(Error::Invalid(format!(
                "view angles must be finite, got {angles:?}"
            )));
        }
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(Error::Invalid(format!(
                "scale must be positive, got {}",
                self.scale
            )));
        }
        if !(self.colour_spacing_px.is_finite() && self.colour_spacing_px >= 0.0) {
            return Err(Error::Invalid(format!(
                "colour spacing must be 0 or positive, got {}",
                self.colour_spacing_px
            )));
        }
        if let Some(d) = self.distance {
            if !(d.is_finite() && d > 0.0) {
                return Err(Error::Invalid(format!(
                    "camera distance must be positive, got {d}"
                )));
            }
        }
        if let Some(b) = self.background {
            if !b.iter().all(|v| (0.0..=1.0).contains(v)) {
                return Err(Error::Invalid(format!(
                    "background colour out of 0..1: {b:?}"
                )));
            }
            if !self.strands_only {
                return Err(Error::Invalid(
                    "a background colour replaces the photo only with --strands-only".into(),
                ));
            }
        }
        Ok(())
    }
}

/// The camera of a render: the model's camera turned about the head centre, optionally a
/// pinhole at a distance.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ViewCamera {
    /// Weak-perspective part (rotation includes the view's turn).
    pub camera: WeakPerspective,
    pub distance: Option<f32>,
    pub width: u32,
    pub height: u32,
}

impl ViewCamera {
    /// Screen point `[x px, y px, depth px]` (larger depth = nearer), None behind the camera
    /// or too close to it (nearer than 5% of the distance).
    pub fn project(&self, p: Vec3) -> Option<[f32; 3]> {
        let c = &self.camera;
        let v = c.r * p;
        let (x, y) = match self.distance {
            None => (v.x, v.y),
            Some(d) => {
                let zc = d - v.z;
                if zc < 0.05 * d {
                    return None;
                }
                (v.x * d / zc, v.y * d / zc)
            }
        };
        Some([c.s * x + c.t.x, -c.s * y + c.t.y, c.s * v.z])
    }

    /// The camera's position in model space (pinhole only).
    pub fn position(&self) -> Option<Vec3> {
        self.distance
            .map(|d| self.camera.r.transpose() * Vec3::new(0.0, 0.0, d))
    }
}

fn rotation(p: &RenderParams) -> Mat3 {
    // Model-space turn about the head centre: yaw about +y (face toward +x = image right),
    // pitch about -x (face up), roll about +z.
    Mat3::from_rotation_y(p.yaw_deg.to_radians())
        * Mat3::from_rotation_x(-p.pitch_deg.to_radians())
        * Mat3::from_rotation_z(p.roll_deg.to_radians())
}

/// A frontal camera framing the strands' bounds in `size` with a 5% margin (imported
/// strands carry no camera). Model y is up.
pub fn framing_camera(s: &StrandSet, size: (u32, u32)) -> WeakPerspective {
    let (lo, hi) = s.bounds();
    let (lo, hi) = (Vec3::from_array(lo), Vec3::from_array(hi));
    let ext = (hi - lo).max(Vec3::splat(1e-6));
    let scale = 0.9 * (size.0 as f32 / ext.x).min(size.1 as f32 / ext.y);
    let mid = 0.5 * (lo + hi);
    WeakPerspective::frontal(
        scale,
        Vec2::new(
            0.5 * size.0 as f32 - scale * mid.x,
            0.5 * size.1 as f32 + scale * mid.y,
        ),
    )
}

/// The view camera of a render of `m` with `p`.
pub fn view_camera(m: &Scene, p: &RenderParams) -> Result<ViewCamera> {
    p.validate()?;
    let (base, w, h) = match (&m.camera, m.width > 0 && m.height > 0) {
        (Some(c), true) => (*c, m.width, m.height),
        _ => {
            let c = framing_camera(&m.strands, p.size);
            (c, p.size.0, p.size.1)
        }
    };
    let w = (w as f32 * p.scale).round() as u32;
    let h = (h as f32 * p.scale).round() as u32;
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(Error::Invalid(format!(
            "a {w}x{h} render: each side must be 1..={MAX_SIDE} pixels"
        )));
    }
    let camera = WeakPerspective::new(base.s * p.scale, base.r * rotation(p), base.t * p.scale);
    let vc = ViewCamera {
        camera,
        distance: p.distance,
        width: w,
        height: h,
    };
    if let (Some(pos), Some(head)) = (vc.position(), &m.head) {
        if head.sdf(pos) <= 0.0 {
            return Err(Error::Invalid(format!(
                "a camera {:.3} from the head centre is inside the head: move it out (--distance)",
                p.distance.unwrap_or(0.0)
            )));
        }
    }
    Ok(vc)
}

/// Figures of one render (written to the sidecar).
#[derive(Clone, Debug, Default, Serialize)]
pub struct RenderReport {
    pub width: u32,
    pub height: u32,
    pub strands: usize,
    pub segments: usize,
    /// Strand vertices that land inside the frame.
    pub vertices_on_screen: usize,
    /// Vertices behind a pinhole camera (their segments are dropped).
    pub vertices_clipped: usize,
    pub hole_pixels: usize,
    pub original_view: bool,
    pub backend: String,
    pub seconds: Vec<(String, f64)>,
}

/// The rendered frame: linear straight RGBA, row-major.
pub struct Rendered {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 4]>,
    /// Whether the alpha channel carries information (strands over a transparent
    /// background); otherwise every pixel is opaque.
    pub has_alpha: bool,
    pub camera: ViewCamera,
    pub report: RenderReport,
}

fn linear_photo(img: &image::RgbImage) -> Vec<[f32; 3]> {
    img.pixels()
        .map(|p| p.0.map(colour::srgb_to_linear))
        .collect()
}

/// Renders `m` with `p` on `engine`; an edited model's strands as [`render_moved`] draws
/// them from its [`Scene::rest`].
pub fn render(engine: &Engine, m: &Scene, p: &RenderParams) -> Result<Rendered> {
    match &m.rest {
        Some(rest) => render_moved(engine, m, rest, p),
        None => render_impl(engine, m, None, p, None),
    }
}

/// Renders `m`, whose strands have moved from where the photo saw them (a simulated frame
/// taken back to the head's rest pose, an edited model), with `p`: `rest` holds the same
/// strands (same counts) where the photo saw them. Each strand keeps the photo's colour from its rest
/// place, and the background is the photo with its hair inpainted at every view, the
/// photo's own as well: with the photo itself behind them, strands drawn in the photo's
/// colour where they now lie reproduce the photo whatever they do, and a lock that moved
/// leaves its old place showing. `colour_spacing_px` does not apply (the model's vertex
/// colours are drawn).
pub fn render_moved(
    engine: &Engine,
    m: &Scene,
    rest: &StrandSet,
    p: &RenderParams,
) -> Result<Rendered> {
    render_moved_with(engine, m, rest, p, &mut None)
}

/// [`render_moved`] for one of many views of the same scene (a simulation's frames):
/// `cache` keeps what every view shares (the inpainted background, the head layer), filled
/// by the first call. Views differ only in the head's turn; the scene and the rest of `p`
/// must be the same on every call.
pub fn render_moved_with(
    engine: &Engine,
    m: &Scene,
    rest: &StrandSet,
    p: &RenderParams,
    cache: &mut Option<layers::Base>,
) -> Result<Rendered> {
    if rest.counts != m.strands.counts || rest.points.len() != m.strands.points.len() {
        return Err(Error::Invalid(format!(
            "{}: the moved strands ({} strands, {} vertices) are not the rest strands ({} \
             strands, {} vertices) with their vertices moved",
            m.dir.display(),
            m.strands.counts.len(),
            m.strands.points.len(),
            rest.counts.len(),
            rest.points.len()
        )));
    }
    render_impl(engine, m, Some(rest), p, Some(cache))
}

fn render_impl(
    engine: &Engine,
    m: &Scene,
    rest: Option<&StrandSet>,
    p: &RenderParams,
    cache: Option<&mut Option<layers::Base>>,
) -> Result<Rendered> {
    let vc = view_camera(m, p)?;
    let (w, h) = (vc.width, vc.height);
    let mut report = RenderReport {
        width: w,
        height: h,
        strands: m.strands.len(),
        original_view: p.is_original_view(),
        backend: engine.describe(),
        ..Default::default()
    };
    let mut clock = Instant::now();
    let mut lap = |name: &str, report: &mut RenderReport| {
        report
            .seconds
            .push((name.to_string(), clock.elapsed().as_secs_f64()));
        clock = Instant::now();
    };

    check_memory(engine, m, p, w, h)?;
    // Strands: colours resampled along them from the photo, shaded in model space, then
    // projected.
    let dense = match rest {
        None => resample_colours(m, p.colour_spacing_px),
        Some(_) => None,
    };
    let strands_m = dense.as_ref().unwrap_or(&m.strands);
    let base = shade::base_colours(strands_m, DEFAULT_HAIR_LINEAR);
    let mut sp = p.shade.clone();
    if strands_m.colors.is_none() && sp.diffuse == 0.0 {
        // One flat colour would show no shape: let the lights model it.
        sp.diffuse = 0.7;
    }
    let colors = shade::shade(
        engine,
        &strands_m.points,
        &strands_m.counts,
        &base,
        &vc.camera,
        &sp,
    )?;
    lap("shading", &mut report);
    let mut points = Vec::with_capacity(strands_m.points.len());
    for q in &strands_m.points {
        match vc.project(Vec3::from_array(*q)) {
            Some(s) => {
                if s[0] >= 0.0 && s[1] >= 0.0 && s[0] < w as f32 && s[1] < h as f32 {
                    report.vertices_on_screen += 1;
                }
                points.push(s);
            }
            None => {
                report.vertices_clipped += 1;
                // The rasteriser drops segments with a non-finite end.
                points.push([f32::NAN; 3]);
            }
        }
    }
    report.segments = strands_m
        .counts
        .iter()
        .map(|&c| c.saturating_sub(1) as usize)
        .sum();
    if report.vertices_on_screen == 0 {
        return Err(Error::Invalid(format!(
            "none of the {} strand vertices of {} lands in the {w}x{h} view",
            strands_m.points.len(),
            m.dir.join("strands.hair").display()
        )));
    }
    let composite = !p.strands_only;
    // The photo in linear light, once for the strands' photo colour and the layers.
    let lin = m.photo.as_ref().filter(|_| composite).map(linear_photo);
    let photo = match (&m.photo, &m.camera, &strands_m.colors) {
        (Some(img), Some(cam0), Some(_)) if composite && p.colour == ColourSource::Photo => {
            Some(strand_photo(
                img,
                lin.as_deref().expect("composite"),
                cam0,
                m.mask
                    .as_deref()
                    .filter(|_| rest.is_some() || !p.is_original_view()),
                rest.unwrap_or(strands_m),
                p,
            ))
        }
        _ => None,
    };
    let colors = match &photo {
        // The vertex colours become what shading added to the (HSV-adjusted) base colour;
        // the rasteriser adds it to the photo under each fragment.
        Some(ph) => colors
            .iter()
            .zip(&base)
            .map(|(c, b)| {
                let b = [b[0], b[1], b[2]];
                let b = match ph.hsv {
                    Some([hue, sat, val]) => colour::hsv_adjust(b, hue, sat, val),
                    None => b.map(colour::unit_or_zero),
                };
                [c[0] - b[0], c[1] - b[1], c[2] - b[2], c[3]]
            })
            .collect(),
        None => colors,
    };
    let strands = ScreenStrands {
        points,
        counts: strands_m.counts.clone(),
        colors,
        photo,
    };

    if composite && (m.photo.is_none() || m.camera.is_none()) {
        return Err(Error::Invalid(format!(
            "{} has no photo and camera to render into (imported strands?): use --strands-only",
            m.dir.display()
        )));
    }
    let (background, mesh) = if composite {
        let lin = lin
            .as_deref()
            .expect("checked above: composite renders have a photo");
        let l = layers::layers(engine, m, lin, &vc, p, rest.is_some(), &mut report, cache)?;
        lap("layers", &mut report);
        let (pw, ph) = m.photo.as_ref().expect("composite").dimensions();
        (Some(resample_to(&l.background, pw, ph, &vc)), l.mesh)
    } else {
        let bg = p
            .background
            .map(|c| vec![c.map(|v| colour::srgb_to_linear((v * 255.0).round() as u8)); 1]);
        let bg = bg.map(|c| {
            let c = c[0];
            vec![[c[0], c[1], c[2], 1.0]; (w * h) as usize]
        });
        (bg, None)
    };

    // Depth range over everything drawn, with a margin.
    let (mut far, mut near) = (f32::INFINITY, f32::NEG_INFINITY);
    for q in strands
        .points
        .iter()
        .chain(mesh.iter().flat_map(|m| m.positions.iter()))
    {
        if q[2].is_finite() {
            far = far.min(q[2]);
            near = near.max(q[2]);
        }
    }
    let frame = Frame {
        width: w,
        height: h,
        depth_range: (far - 1.0, near + 1.0),
        background,
    };
    let mut rp = p.raster;
    rp.strand_width *= p.scale;
    let pixels = raster::render(engine, &frame, mesh.as_ref(), Some(&strands), &rp)?;
    lap("rasterisation", &mut report);
    Ok(Rendered {
        width: w,
        height: h,
        pixels,
        has_alpha: p.strands_only && p.background.is_none(),
        camera: vc,
        report,
    })
}

/// The photo colour of a composite render: every vertex's point in the photo as the model's
/// camera sees it, the photo in linear light, the strand width in photo px (the view's
/// `scale` widens strands on screen only) and the HSV adjustment.
///
/// With `hair` (a novel view), the strands see only the photo's hair: every other pixel
/// takes the hair colour around it (a push-pull fill). A strand the photo shows over the
/// face, the ear or the backdrop (the far side of the head, a tip just past the mask) was
/// hidden or missed there; a turned view uncovers it, and with the full photo it came out
/// as a ribbon of skin or backdrop colour. At the original view the full photo stays, so
/// that a strand over a pixel that is not hair shows what the photo shows there.
fn strand_photo(
    img: &image::RgbImage,
    lin: &[[f32; 3]],
    cam0: &WeakPerspective,
    hair: Option<&[u8]>,
    s: &StrandSet,
    p: &RenderParams,
) -> StrandPhoto {
    let points = s
        .points
        .iter()
        .map(|&q| {
            let o = cam0.project(Vec3::from_array(q));
            [o.x, o.y]
        })
        .collect();
    let hair_only = hair
        .filter(|h| h.len() == lin.len() && h.iter().any(|&v| v != 0))
        .map(|h| {
            let known: Vec<bool> = h.iter().map(|&v| v != 0).collect();
            let fill = inpaint::push_pull(img.width(), img.height(), lin, &known, false);
            lin.iter()
                .zip(&known)
                .zip(fill)
                .map(|((&c, &k), f)| if k { c } else { f })
                .collect::<Vec<_>>()
        });
    let texels = hair_only
        .as_deref()
        .unwrap_or(lin)
        .iter()
        .map(|c| [c[0], c[1], c[2], 1.0])
        .collect();
    let sp = &p.shade;
    StrandPhoto {
        points,
        texture: Texture {
            width: img.width(),
            height: img.height(),
            texels,
        },
        half_width: 0.5 * p.raster.strand_width,
        hsv: (!sp.hsv_is_identity()).then_some([sp.hue, sp.saturation, sp.value]),
    }
}

/// The strands with extra vertices every `spacing` px (as the photo sees them) whose colour
/// and transparency are sampled from the photo like `coif model` samples the model's own
/// vertices (C13 §4). The model's vertices sit half a grid cell apart (~3 px at 512²), while
/// the photo's hair varies at the scale of a pixel across strands: sampling only at the
/// vertices smears it along the strand. None without a photo, or when `spacing` is 0.
/// Bytes per strand vertex drawn: the resampled set (point, colour, transparency: 28), its
/// base and shaded colours (24), the shading pass's buffers and their read-back (80) and the
/// projected points (16); the rasteriser's quads come on top ([`BYTES_PER_SEGMENT`]).
pub const BYTES_PER_VERTEX: u64 = 148;
/// Bytes per segment rasterised (a quad's four corners with colour and coverage).
pub const BYTES_PER_SEGMENT: u64 = 128;
/// Bytes per output pixel: 4x MSAA samples of colour and depth, the layers (photo,
/// inpainted background, head) in linear f32 RGBA and the 8/16-bit output.
pub const BYTES_PER_PIXEL: u64 = 4 * 20 + 3 * 16 + 8;

/// Refuses a render whose vertices (`--colour-spacing` adds up to 63 per segment) or pixels
/// (`--scale`, `--size`) would take more than the engine's memory budget, before any of
/// them is allocated.
fn check_memory(engine: &Engine, m: &Scene, p: &RenderParams, w: u32, h: u32) -> Result<()> {
    use crate::base::budget::{Bytes, Cause};
    let verts = dense_vertices(m, p.colour_spacing_px);
    let segs = verts.saturating_sub(m.strands.len() as u64);
    let strands = verts * BYTES_PER_VERTEX + segs * BYTES_PER_SEGMENT;
    let pixels = w as u64 * h as u64 * BYTES_PER_PIXEL;
    let detail = format!(
        "{verts} strand vertices: {}; a {w}x{h} picture: {}",
        Bytes(strands),
        Bytes(pixels)
    );
    let what = if strands >= pixels && p.colour_spacing_px > 0.0 {
        format!("--colour-spacing {}", p.colour_spacing_px)
    } else if strands >= pixels {
        format!("the model's {} strands", m.strands.len())
    } else {
        format!("a {w}x{h} render (--scale {}, --size)", p.scale)
    };
    engine
        .budget()
        .check(Cause::Option, &what, strands + pixels, &detail)
}

/// The vertex count [`resample_colours`] gives, counted without building the set.
fn dense_vertices(m: &Scene, spacing: f32) -> u64 {
    let n = m.strands.points.len() as u64;
    let (Some(_), Some(cam)) = (m.photo.as_ref(), m.camera) else {
        return n;
    };
    if spacing.is_nan() || spacing <= 0.0 || m.strands.colors.is_none() {
        return n;
    }
    let mut total = 0u64;
    let mut start = 0usize;
    for &c in &m.strands.counts {
        let pts = &m.strands.points[start..start + c as usize];
        start += c as usize;
        total += pts.len() as u64;
        for s in pts.windows(2) {
            let (a, b) = (Vec3::from_array(s[0]), Vec3::from_array(s[1]));
            let len = (cam.project(b) - cam.project(a)).truncate().length();
            total += ((len / spacing).ceil() as u64).clamp(1, 64) - 1;
        }
    }
    total
}

fn resample_colours(m: &Scene, spacing: f32) -> Option<StrandSet> {
    let (photo, cam) = (m.photo.as_ref()?, m.camera?);
    if spacing.is_nan() || spacing <= 0.0 || m.strands.colors.is_none() {
        return None;
    }
    let (w, h) = photo.dimensions();
    let sample = |q: Vec3| -> ([f32; 3], f32) {
        let s = cam.project(q);
        let rgb = colour::sample_rgb(photo, s.x, s.y);
        let on = s.x >= 0.0
            && s.y >= 0.0
            && s.x < w as f32
            && s.y < h as f32
            && m.mask
                .as_ref()
                .is_none_or(|mk| mk[s.y as usize * w as usize + s.x as usize] != 0);
        (rgb, if on { 0.0 } else { 1.0 })
    };
    let mut out = StrandSet::default();
    let (mut colors, mut transp) = (Vec::new(), Vec::new());
    let mut start = 0usize;
    for &c in &m.strands.counts {
        let pts = &m.strands.points[start..start + c as usize];
        start += c as usize;
        let mut n = 0u32;
        for (k, &q) in pts.iter().enumerate() {
            let q = Vec3::from_array(q);
            if k > 0 {
                let prev = Vec3::from_array(pts[k - 1]);
                let len = (cam.project(q) - cam.project(prev)).truncate().length();
                let pieces = ((len / spacing).ceil() as u32).clamp(1, 64);
                for i in 1..pieces {
                    let r = prev.lerp(q, i as f32 / pieces as f32);
                    let (rgb, t) = sample(r);
                    out.points.push(r.to_array());
                    colors.push(rgb);
                    transp.push(t);
                    n += 1;
                }
            }
            let (rgb, t) = sample(q);
            out.points.push(q.to_array());
            colors.push(rgb);
            transp.push(t);
            n += 1;
        }
        out.counts.push(n);
    }
    out.colors = Some(colors);
    out.transparency = Some(transp);
    Some(out)
}

/// PSNR (dB) of `a` against `b` (sRGB 8-bit RGB) over the pixels where `region` is set.
pub fn psnr_region(a: &image::RgbImage, b: &image::RgbImage, region: &[bool]) -> f64 {
    let mut se = 0.0f64;
    let mut n = 0usize;
    for ((pa, pb), &r) in a.pixels().zip(b.pixels()).zip(region) {
        if !r {
            continue;
        }
        for k in 0..3 {
            let d = pa.0[k] as f64 - pb.0[k] as f64;
            se += d * d;
        }
        n += 3;
    }
    if n == 0 {
        return f64::NAN;
    }
    let mse = se / n as f64;
    if mse == 0.0 {
        return f64::INFINITY;
    }
    10.0 * (255.0 * 255.0 / mse).log10()
}

/// The frame as 8-bit sRGB RGB (alpha dropped: the frame is opaque).
pub fn to_rgb8(r: &Rendered) -> image::RgbImage {
    let bytes = colour::to_rgba8(&r.pixels);
    let rgb: Vec<u8> = bytes.chunks(4).flat_map(|c| [c[0], c[1], c[2]]).collect();
    image::RgbImage::from_raw(r.width, r.height, rgb).expect("frame size")
}

/// Writes the frame as PNG (8-bit sRGB, or 16-bit with `sixteen`; RGBA when it has alpha)
/// atomically, and a sidecar `<path>.json` with the camera, the settings and the report.
pub fn write(path: &Path, r: &Rendered, p: &RenderParams, sixteen: bool) -> Result<PathBuf> {
    use image::ImageEncoder;
    let jpeg = crate::io::outpath::Format::of(path) == Some(crate::io::outpath::Format::Jpeg);
    if jpeg {
        jpeg_fits(path, p, sixteen)?;
    }
    let mut bytes = Vec::new();
    let enc = image::codecs::png::PngEncoder::new(&mut bytes);
    let res =
        if jpeg {
            let rgb: Vec<u8> = colour::to_rgba8(&r.pixels)
                .chunks(4)
                .flat_map(|c| [c[0], c[1], c[2]])
                .collect();
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, JPEG_QUALITY)
                .write_image(&rgb, r.width, r.height, image::ExtendedColorType::Rgb8)
        } else if sixteen {
            let px = colour::to_rgba16(&r.pixels);
            let (data, ct): (Vec<u16>, _) = if r.has_alpha {
                (px, image::ExtendedColorType::Rgba16)
            } else {
                (
                    px.chunks(4).flat_map(|c| [c[0], c[1], c[2]]).collect(),
                    image::ExtendedColorType::Rgb16,
                )
            };
            // PNG stores 16-bit samples big-endian.
            let be: Vec<u8> = data.iter().flat_map(|v| v.to_be_bytes()).collect();
            enc.write_image(&be, r.width, r.height, ct)
        } else {
            let px = colour::to_rgba8(&r.pixels);
            if r.has_alpha {
                enc.write_image(&px, r.width, r.height, image::ExtendedColorType::Rgba8)
            } else {
                let rgb: Vec<u8> = px.chunks(4).flat_map(|c| [c[0], c[1], c[2]]).collect();
                enc.write_image(&rgb, r.width, r.height, image::ExtendedColorType::Rgb8)
            }
        };
    res.map_err(|e| Error::bad_file(path, format!("image encoding failed: {e}")))?;
    crate::io::write_atomic(path, &bytes)?;
    let side = sidecar_path(path);
    let meta = serde_json::json!({
        "version": 1,
        "coif": env!("CARGO_PKG_VERSION"),
        // Its name only: the side file lies beside it, and the folder may be a run's
        // temporary one, renamed when the run ends.
        "image": path.file_name().map(|n| n.to_string_lossy().into_owned()),
        "encoding": match (jpeg, sixteen) {
            (true, _) => "8-bit sRGB JPEG",
            (false, true) => "16-bit sRGB PNG",
            (false, false) => "8-bit sRGB PNG",
        },
        "camera": r.camera,
        "image_from_model": r.camera.camera.image_from_model(),
        "settings": p,
        "report": r.report,
    });
    crate::io::write_atomic(
        &side,
        serde_json::to_string_pretty(&meta)
            .map_err(|e| Error::Invalid(e.to_string()))?
            .as_bytes(),
    )?;
    Ok(side)
}

/// Quality of a render written as `.jpg` (the `image` crate's scale, 1-100).
pub const JPEG_QUALITY: u8 = 95;

/// JPEG keeps 8 bits and no alpha: refuses `--16bit` and transparent renders (strands only,
/// no background) for a `.jpg` output, before any work.
pub fn jpeg_fits(out: &Path, p: &RenderParams, sixteen: bool) -> Result<()> {
    let why = if sixteen {
        "16-bit output needs a .png file (JPEG has 8-bit samples)"
    } else if p.strands_only && p.background.is_none() {
        "strands without a background are transparent and JPEG has no alpha: write .png or \
         give a background colour"
    } else {
        return Ok(());
    };
    Err(Error::Invalid(format!("{}: {why}", out.display())))
}

/// `render.png` -> `render.png.json`.
pub fn sidecar_path(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(".json");
    PathBuf::from(s)
}

/// The background layer at the view's size (a scaled view resamples it bilinearly).
fn resample_to(bg: &[[f32; 4]], w: u32, h: u32, vc: &ViewCamera) -> Vec<[f32; 4]> {
    if (vc.width, vc.height) == (w, h) {
        return bg.to_vec();
    }
    let (sx, sy) = (w as f32 / vc.width as f32, h as f32 / vc.height as f32);
    let at = |x: i64, y: i64| {
        bg[(y.clamp(0, h as i64 - 1) * w as i64 + x.clamp(0, w as i64 - 1)) as usize]
    };
    let mut out = Vec::with_capacity((vc.width * vc.height) as usize);
    for j in 0..vc.height {
        for i in 0..vc.width {
            let x = (i as f32 + 0.5) * sx - 0.5;
            let y = (j as f32 + 0.5) * sy - 0.5;
            let (x0, y0) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0, y - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let mut c = [0.0f32; 4];
            for (dx, dy, wgt) in [
                (0, 0, (1.0 - fx) * (1.0 - fy)),
                (1, 0, fx * (1.0 - fy)),
                (0, 1, (1.0 - fx) * fy),
                (1, 1, fx * fy),
            ] {
                let v = at(x0 + dx, y0 + dy);
                for k in 0..4 {
                    c[k] += wgt * v[k];
                }
            }
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At a novel view the strands see only the photo's hair: a pixel beside the hair takes
    /// the hair's colour, not the backdrop's; at the original view the photo stays whole.
    #[test]
    fn novel_views_colour_strands_from_the_hair_only() {
        let (w, h) = (16u32, 8u32);
        // Left half brown hair, right half a blue backdrop.
        let img = image::RgbImage::from_fn(w, h, |x, _| {
            if x < w / 2 {
                image::Rgb([120, 70, 30])
            } else {
                image::Rgb([40, 90, 220])
            }
        });
        let hair: Vec<u8> = (0..w * h).map(|i| (i % w < w / 2) as u8).collect();
        let lin = linear_photo(&img);
        let cam = WeakPerspective::frontal(1.0, Vec2::ZERO);
        let s = StrandSet::default();
        let p = RenderParams::default();
        let backdrop_px = (3 * w + 12) as usize;
        let novel = strand_photo(&img, &lin, &cam, Some(&hair), &s, &p);
        let c = novel.texture.texels[backdrop_px];
        assert!(
            c[2] < c[0],
            "the backdrop's blue reaches the strands: {c:?}"
        );
        assert_eq!(novel.texture.texels[3 * w as usize], {
            let l = lin[3 * w as usize];
            [l[0], l[1], l[2], 1.0]
        });
        let original = strand_photo(&img, &lin, &cam, None, &s, &p);
        let c = original.texture.texels[backdrop_px];
        assert!(c[2] > c[0], "the original view keeps the photo: {c:?}");
    }
}
