//! Strand rasteriser (C13 §4): one frame = an optional background image, then an optional
//! textured triangle mesh (the head), then the strands as screen-aligned quads, all
//! depth-tested in one multisampled target with alpha-to-coverage and no depth sorting.
//! Two implementations give the same image: wgpu ([`render_gpu`], host in `gpu.rs`: render
//! pipelines, shaders `wgsl/render/strand_raster.wgsl` and `wgsl/render/mesh_raster.wgsl`,
//! and at 4x MSAA the strands as compute passes, `wgsl/render/strand_vis64.wgsl` where the
//! device has 64-bit atomics, else `strand_vis.wgsl`, host `gpu/vis.rs`; registered in
//! [`crate::stages::RENDER`]) and a CPU mirror ([`render_cpu`], tiled,
//! rayon-parallel, driver in `cpu.rs`) that evaluates coverage exactly as a Vulkan rasteriser
//! does; its per-primitive parts read like the shaders and sit next to the compute mirrors:
//! [`crate::stages::strand_raster`], [`crate::stages::mesh_raster`] and
//! [`crate::stages::raster_common`].
//! Host preparation (validation, skipping, clipping, depth mapping) is shared, so both paths
//! see the same segments and triangles; the GPU path splits them into draws whose storage
//! bindings respect `GpuContext::max_binding_bytes`.
//!
//! # Rules shared by both paths (the CPU mirror reproduces each one)
//! - **Screen space** (`CONVENTIONS-render.md`): pixel (i, j) covers [i, i+1) x [j, j+1),
//!   y down; depth in px, larger = nearer; `Frame::depth_range = (far, near)` maps depth d to
//!   the depth buffer as z = (near - d) / (near - far) (0 = near, 1 = far); geometry outside
//!   the range is clipped, and geometry exactly at `far` is not drawn.
//! - **Samples**: 4 (Vulkan standard positions [`SAMPLE_POSITIONS_4`]) or 1 (pixel centre).
//!   Vertices are snapped to 1/256 px (8 sub-pixel bits, lavapipe's and most GPUs'
//!   precision); a sample is covered when it is inside all three edges of a triangle or on a
//!   top or left edge (top-left fill rule, y down), so shared edges are never drawn twice.
//! - **Depth**: per sample, compare `Less` against a buffer cleared to 1, and every drawn
//!   sample writes its depth (mesh and strands), so the nearest surface wins whatever the
//!   draw order; on an exact tie the earlier draw (mesh first, then strands in input order)
//!   keeps the sample.
//! - **Colour** is evaluated once per pixel at the pixel centre (no per-sample shading),
//!   screen-linearly interpolated (exact for a weak-perspective camera), and written to
//!   every sample the fragment covers; the output is the MSAA resolve (mean of samples).
//! - **Strands**: segment (p_k, p_k+1) becomes a quad `strand_width` px across, extended by
//!   half a width past both ends so consecutive quads overlap at bends (no gaps). Its colour
//!   at a pixel is the vertex colours mixed at the pixel centre's position along the segment,
//!   clamped to [0, 1]; its depth is one plane (constant across the width, z0 at the start
//!   cap's edge to z1 at the end cap's edge). Segments are skipped when an end point or
//!   colour is not finite, when they are shorter than 1e-4 px, when both alphas are <= 0,
//!   and when they cannot touch the frame; segments leaving the frame are clipped to a guard
//!   band (frame grown by 16 + 2 x width px) with depth and colour interpolated.
//! - **Photo colour** ([`StrandPhoto`], optional): the quad's corners get photo points built
//!   like the screen corners, o = o0 + t (o1 - o0) ± n_o with t = -h/len or 1 + h/len and
//!   n_o the unit normal of o1 - o0 times the photo half width (0 when o1 = o0); the
//!   fragment's photo point is their screen-linear interpolation at the pixel centre, its
//!   colour clamp(HSV(bilinear photo at that point) + vertex colour rgb, 0, 1) (bilinear as
//!   the mesh texture, in photo px). Segments with a non-finite photo point are skipped.
//! - **Alpha-to-coverage**, explicit (see the WGSL for why): a strand fragment keeps
//!   k = floor(alpha·N + 0.5) of its samples, taken in the order r, r+1, ... (mod N) with
//!   r = (x + 2·y + strand index) mod N. Adding the strand index lets overlapping
//!   semi-transparent strands cover different samples, as transparency should.
//! - **Mesh**: opaque where it is drawn; back faces culled (front faces are
//!   counter-clockwise as the image is viewed, which is what a mesh counter-clockwise from
//!   outside gives after the camera's y flip); bilinear texture with clamp-to-edge, texel
//!   (i, j) centred at uv ((i + 0.5) / W, (j + 0.5) / H), row 0 at v = 0. The texture's
//!   alpha is coverage, by the strands' rule without the strand term (r = (x + 2·y) mod N),
//!   so a texture can cut the mesh's outline along its own texels, anti-aliased (the head
//!   layer's neck and face outline). Triangles with a non-finite vertex or uv are skipped.
//! - **Compositing**: samples start as the background (premultiplied; None = transparent
//!   black); a drawn sample becomes opaque. The result is returned as straight
//!   (un-premultiplied) linear RGBA, so an opaque background gives alpha 1 everywhere.
//!   Non-finite background or texel values count as 0.
//! - **Precision**: the target is Rgba16Float (the WebGPU-core format that is both
//!   multisampled and resolvable; Rgba32Float needs an adapter-specific feature that
//!   `GpuContext` does not request, although lavapipe would offer it), so the CPU mirror
//!   stores every sample and the resolved mean as f16 as well: 11 significant bits, ample
//!   for 8-bit and 16-bit sRGB output. It truncates toward zero as lavapipe does (Vulkan
//!   allows either rounding; a GPU that rounds to nearest differs by one f16 ulp).

mod cpu;
mod gpu;

use crate::error::{Error, Result};
use crate::gpu::GpuContext;
use crate::stages::raster_common::TileBuf;
use crate::Engine;
use rayon::prelude::*;

// The records and the uniform both paths share are defined next to the shaders' mirrors.
pub use crate::stages::mesh_raster::TriRec;
pub use crate::stages::raster_common::{Config, SAMPLE_POSITIONS_4};
pub use crate::stages::strand_raster::SegRec;
// Kept here for `crate::render`, which calls them as `raster::…`; they live in `base::colour`.

// ---------------------------------------------------------------------------------------------
// Public types
// ---------------------------------------------------------------------------------------------

/// The frame to render into.
#[derive(Clone, Debug)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// (far, near) in screen depth px (larger = nearer); near must exceed far.
    pub depth_range: (f32, f32),
    /// Linear straight RGBA, `width * height` row-major; None = transparent black.
    pub background: Option<Vec<[f32; 4]>>,
}

/// A texture in linear straight RGBA, row 0 at v = 0. On a mesh, alpha is the share of a
/// pixel's samples the mesh covers (see the module notes), not a blend.
#[derive(Clone, Debug)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<[f32; 4]>,
}

/// A projected, textured triangle mesh (e.g. the head).
#[derive(Clone, Debug)]
pub struct ScreenMesh {
    /// [x px, y px, depth px] per vertex, as `WeakPerspective::project` returns.
    pub positions: Vec<[f32; 3]>,
    /// Texture coordinates per vertex.
    pub uvs: Vec<[f32; 2]>,
    /// Vertex indices, counter-clockwise seen from outside (before projection).
    pub triangles: Vec<[u32; 3]>,
    pub texture: Texture,
}

/// Projected strands: polylines root to tip.
#[derive(Clone, Debug, Default)]
pub struct ScreenStrands {
    /// [x px, y px, depth px] per vertex, all strands concatenated.
    pub points: Vec<[f32; 3]>,
    /// Vertices per strand; they sum to `points.len()`.
    pub counts: Vec<u32>,
    /// Linear straight RGBA per vertex; alpha = 1 - transparency. With `photo`, the rgb is
    /// an offset added to the photo's colour (see [`StrandPhoto`]).
    pub colors: Vec<[f32; 4]>,
    /// Colour from a photo under each fragment, instead of from the vertices alone.
    pub photo: Option<StrandPhoto>,
}

/// Strand colour taken from a photo at every fragment (rule **Photo colour** above): each
/// vertex also has the point where the photo's camera saw it, and a fragment takes the photo
/// at the matching point of the quad built the same way around those points. At the photo's
/// own view that point is the pixel centre itself, so a strand shows the photo exactly
/// where it covers the hair; in other views the colour stays attached to the strand.
#[derive(Clone, Debug)]
pub struct StrandPhoto {
    /// Photo px per vertex (pixel (i, j) centred at (i + 0.5, j + 0.5)).
    pub points: Vec<[f32; 2]>,
    /// The photo, linear straight RGBA (alpha unused).
    pub texture: Texture,
    /// Half the strand width in photo px.
    pub half_width: f32,
    /// HSV adjustment of the photo colour: hue shift (degrees), saturation and value scales,
    /// as [`crate::base::colour::hsv_adjust`]; None = unchanged.
    pub hsv: Option<[f32; 3]>,
}

/// Rasteriser settings.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RasterParams {
    /// MSAA samples per pixel: 4 (default) or 1.
    pub samples: u32,
    /// Strand quad width in px, in (0, [`MAX_STRAND_WIDTH`]].
    pub strand_width: f32,
}

impl Default for RasterParams {
    fn default() -> Self {
        RasterParams {
            samples: 4,
            strand_width: 1.0,
        }
    }
}

/// Largest frame or texture side on the CPU path (the GPU path uses the device limit).
pub const CPU_MAX_DIM: u32 = 16384;

/// Widest strand quad accepted, px.
pub const MAX_STRAND_WIDTH: f32 = 64.0;

/// Segments shorter than this (px, on screen) are skipped: they have no direction.
pub const MIN_SEGMENT_PX: f32 = 1e-4;

// ---------------------------------------------------------------------------------------------
// Host preparation, shared by both paths
// ---------------------------------------------------------------------------------------------

/// Everything a render needs, validated and prepared on the host once for either path.
struct Scene<'a> {
    cfg: Config,
    /// Premultiplied, sanitised.
    background: Option<Vec<[f32; 4]>>,
    /// Sanitised texture of the mesh (present iff `mesh` was given).
    texture: Option<Texture>,
    /// Sanitised photo of the strands' photo colour.
    photo: Option<Texture>,
    tris: Vec<TriRec>,
    /// Every drawable segment, in input order, as its first vertex and strand (the GPU path;
    /// empty on the CPU path). Each is prepared where it is uploaded ([`Scene::seg_rec`]),
    /// so that the host writes its 80 B once, into the GPU's buffer, and keeps 8 B here.
    /// (Listing prepares each segment once more to learn whether it draws: its arithmetic
    /// cost less than writing and reading the 118 MB vector it replaces.)
    drawn: Vec<[u32; 2]>,
    /// The validated strands and how a segment is prepared. The CPU path prepares each
    /// segment in the tile that draws it: materialising 80 B per segment first cost more
    /// than drawing them (1.5M segments, 118 MB).
    src: Option<SegSource<'a>>,
}

/// Validated strands and the preparation [`SegPrep::segment`] applies to each segment.
struct SegSource<'a> {
    s: &'a ScreenStrands,
    prep: SegPrep,
    /// Index of each strand's first vertex.
    starts: Vec<usize>,
}

/// What the CPU tile loop knows of a segment before preparing it, worked out once when it
/// is binned and stored in each tile's list, so that ordering a tile's segments and
/// skipping the hidden ones read that list in order and not the strands' arrays (which the
/// tile visits in an order unrelated to their layout).
#[derive(Clone, Copy)]
pub(super) struct SegCull {
    /// First vertex and strand.
    pub i: u32,
    pub k: u32,
    /// No nearer than the nearest depth [`strand_quad`](crate::stages::strand_raster::strand_quad)
    /// would test (clipping only moves an end along the segment, and its snapping margin
    /// is at most |Δz|·0.01 / 2h); NaN when an end's depth is not finite.
    pub z: f32,
    /// Frame pixel box of the quad widened by a pixel, inclusive.
    pub lo: [i16; 2],
    pub hi: [i16; 2],
}

impl SegCull {
    /// Whether the segment is surely hidden in the tile: its [`SegCull::z`] behind every
    /// sample already drawn over its box. False when unsure (the quad then decides).
    #[inline(always)]
    pub fn hidden<const N: usize>(&self, buf: &TileBuf<N>) -> bool {
        let (x0, y0) = (self.lo[0] as i32 - buf.x0, self.lo[1] as i32 - buf.y0);
        let (x1, y1) = (self.hi[0] as i32 - buf.x0, self.hi[1] as i32 - buf.y0);
        if x1 < 0 || y1 < 0 || x0 >= buf.w || y0 >= buf.h {
            return false;
        }
        buf.hidden(
            x0.max(0),
            y0.max(0),
            x1.min(buf.w - 1),
            y1.min(buf.h - 1),
            self.z,
        )
    }
}

impl SegSource<'_> {
    /// Asks the CPU to fetch what [`Self::seg`] will read for vertex `i` into cache (the
    /// tile draws its segments front to back, so their data is read in an order unrelated
    /// to its layout, and a load missing every cache stalled the tile loop). A hint only.
    #[inline(always)]
    fn prefetch(&self, i: usize) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let s = self.s;
            #[inline(always)]
            fn at<T>(p: &T) {
                // SAFETY: a prefetch never faults, and `p` is a live reference.
                unsafe { _mm_prefetch::<_MM_HINT_T0>((p as *const T).cast()) }
            }
            if i + 1 < s.points.len() && i + 1 < s.colors.len() {
                at(&s.points[i]);
                at(&s.points[i + 1]);
                at(&s.colors[i]);
                at(&s.colors[i + 1]);
            }
            if let Some(o) = s.photo.as_ref().and_then(|ph| ph.points.get(i)) {
                at(o);
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = i;
    }

    /// The cull record of the segment from vertex `i` of strand `k` (see [`SegCull`]), from
    /// its raw end points `a`, `b` and their (finite) pixel bounds `bb`
    /// ([`seg_bounds`](crate::stages::strand_raster::seg_bounds)).
    #[inline(always)]
    fn cull(&self, i: u32, k: u32, a: [f32; 3], b: [f32; 3], bb: [f32; 4]) -> SegCull {
        let (za, zb) = (self.prep.depth.z(a[2]), self.prep.depth.z(b[2]));
        let margin = (za - zb).abs() * self.prep.snap_slope;
        // 1e-6 more: a clipped end's lerped depth may round an ulp below min(za, zb) (it
        // also covers the ulp by which the margin's multiply may round short of a divide).
        let z = za.min(zb) - margin - 1e-6;
        // The box widened by a pixel, floored, clamped to a range every frame fits in
        // (a clamped side lies off the frame, so only its clamped value is ever used).
        // (The floor by truncation and a fix-up: `f32::floor` is a libm call in the binning
        // loop, which is compiled for baseline x86-64.)
        let px = |v: f32| {
            let c = v.clamp(-1.0, CPU_MAX_DIM as f32 + 1.0);
            let t = c as i32;
            (t - ((t as f32 > c) as i32)) as i16
        };
        SegCull {
            i,
            k,
            z: if za.is_finite() && zb.is_finite() {
                z
            } else {
                f32::NAN
            },
            lo: [px(bb[0] - 1.0), px(bb[1] - 1.0)],
            hi: [px(bb[2] + 1.0), px(bb[3] + 1.0)],
        }
    }

    /// The segment from vertex `i` to `i + 1` of strand `k`, prepared; None when skipped.
    #[inline(always)]
    fn seg(&self, i: usize, k: u32) -> Option<SegRec> {
        let s = self.s;
        let o = |i: usize| s.photo.as_ref().map(|ph| ph.points[i]);
        self.prep.segment(
            s.points[i],
            s.points[i + 1],
            s.colors[i],
            s.colors[i + 1],
            (o(i), o(i + 1)),
            k,
        )
    }
}

fn invalid<T>(msg: String) -> Result<T> {
    Err(Error::Invalid(msg))
}

fn check_dims(what: &str, w: u32, h: u32, max_dim: u32) -> Result<()> {
    if w == 0 || h == 0 || w > max_dim || h > max_dim {
        return invalid(format!(
            "{what} is {w}x{h} px; each side must lie in 1..={max_dim} (device limit)"
        ));
    }
    Ok(())
}

/// `t` with its size checked and its texels sanitised.
fn checked_texture(what: &str, t: &Texture, max_dim: u32) -> Result<Texture> {
    check_dims(what, t.width, t.height, max_dim)?;
    let n = t.width as usize * t.height as usize;
    if t.texels.len() != n {
        return invalid(format!(
            "{what} has {} texels, {}x{} needs {n}",
            t.texels.len(),
            t.width,
            t.height
        ));
    }
    Ok(Texture {
        width: t.width,
        height: t.height,
        texels: t.texels.par_iter().map(|&c| sanitise(c)).collect(),
    })
}

fn finite<const N: usize>(v: &[f32; N]) -> bool {
    v.iter().all(|x| x.is_finite())
}

fn sanitise(v: [f32; 4]) -> [f32; 4] {
    v.map(|x| if x.is_finite() { x } else { 0.0 })
}

fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

fn lerp4(a: [f32; 4], b: [f32; 4], t: f32) -> [f32; 4] {
    std::array::from_fn(|i| lerp(a[i], b[i], t))
}

/// Where a clipped end lands: its parameter t on the segment and, when it was moved, the
/// (axis, bound) it now lies on.
type ClipEnd = (f32, Option<(usize, f32)>);

/// Liang-Barsky: the part of p0 + t (p1 - p0), t in [0, 1], inside [lo, hi].
fn clip_segment(p0: [f32; 2], p1: [f32; 2], lo: [f32; 2], hi: [f32; 2]) -> Option<[ClipEnd; 2]> {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    let (mut on0, mut on1) = (None, None);
    for k in 0..2 {
        let (a, d) = (p0[k] as f64, p1[k] as f64 - p0[k] as f64);
        for (p, q, bound) in [(-d, a - lo[k] as f64, lo[k]), (d, hi[k] as f64 - a, hi[k])] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    if r > t1 {
                        return None;
                    }
                    if r > t0 {
                        (t0, on0) = (r, Some((k, bound)));
                    }
                } else {
                    if r < t0 {
                        return None;
                    }
                    if r < t1 {
                        (t1, on1) = (r, Some((k, bound)));
                    }
                }
            }
        }
    }
    Some([(t0 as f32, on0), (t1 as f32, on1)])
}

/// The point at parameter t of segment p0 p1, in f64, put exactly on the clipping bound
/// (with huge inputs the lerp alone would cancel catastrophically).
fn clip_point(p0: [f32; 2], p1: [f32; 2], end: ClipEnd) -> [f32; 2] {
    let t = end.0 as f64;
    let mut q: [f32; 2] =
        std::array::from_fn(|k| (p0[k] as f64 + (p1[k] as f64 - p0[k] as f64) * t) as f32);
    if let Some((k, bound)) = end.1 {
        q[k] = bound;
    }
    q
}

/// Sutherland-Hodgman against one axis-aligned half-plane; vertices are [x, y, z, u, v].
fn clip_poly(poly: &[[f32; 5]], axis: usize, bound: f32, keep_below: bool) -> Vec<[f32; 5]> {
    let inside = |p: &[f32; 5]| {
        if keep_below {
            p[axis] <= bound
        } else {
            p[axis] >= bound
        }
    };
    let mut out = Vec::with_capacity(poly.len() + 2);
    for (i, cur) in poly.iter().enumerate() {
        let prev = &poly[(i + poly.len() - 1) % poly.len()];
        if inside(cur) != inside(prev) {
            let t = (bound as f64 - prev[axis] as f64) / (cur[axis] as f64 - prev[axis] as f64);
            let mut q: [f32; 5] = std::array::from_fn(|k| {
                (prev[k] as f64 + (cur[k] as f64 - prev[k] as f64) * t) as f32
            });
            q[axis] = bound;
            out.push(q);
        }
        if inside(cur) {
            out.push(*cur);
        }
    }
    out
}

impl<'a> Scene<'a> {
    /// `materialise`: also list every drawable segment in [`Scene::drawn`] (the GPU path).
    fn new(
        frame: &Frame,
        mesh: Option<&ScreenMesh>,
        strands: Option<&'a ScreenStrands>,
        p: &RasterParams,
        max_dim: u32,
        materialise: bool,
    ) -> Result<Scene<'a>> {
        let (w, h) = (frame.width, frame.height);
        check_dims("frame", w, h, max_dim)?;
        let (far, near) = frame.depth_range;
        if !(far.is_finite() && near.is_finite() && near > far) {
            return invalid(format!(
                "depth_range (far, near) = ({far}, {near}) must be finite with near > far \
                 (depth grows toward the camera)"
            ));
        }
        if p.samples != 1 && p.samples != 4 {
            return invalid(format!(
                "{} samples per pixel requested; 1 or 4 are supported",
                p.samples
            ));
        }
        if !(p.strand_width > 0.0 && p.strand_width <= MAX_STRAND_WIDTH) {
            return invalid(format!(
                "strand width {} px must lie in (0, {MAX_STRAND_WIDTH}]",
                p.strand_width
            ));
        }
        let n_px = w as usize * h as usize;
        let background = match &frame.background {
            None => None,
            Some(bg) if bg.len() != n_px => {
                return invalid(format!(
                    "background has {} pixels, the {w}x{h} frame needs {n_px}",
                    bg.len()
                ))
            }
            Some(bg) => Some(
                bg.par_iter()
                    .map(|&c| {
                        let c = sanitise(c);
                        let a = c[3].clamp(0.0, 1.0);
                        [c[0] * a, c[1] * a, c[2] * a, a]
                    })
                    .collect(),
            ),
        };
        let cfg = Config::frame(w, h, p.samples, 0.5 * p.strand_width);
        let depth = DepthMap { far, near };
        let guard = 16.0 + 2.0 * p.strand_width;
        let lo = [-guard, -guard];
        let hi = [w as f32 + guard, h as f32 + guard];
        let mut scene = Scene {
            cfg,
            background,
            texture: None,
            photo: None,
            tris: Vec::new(),
            drawn: Vec::new(),
            src: None,
        };
        if let Some(m) = mesh {
            let texture = checked_texture("mesh texture", &m.texture, max_dim)?;
            if m.uvs.len() != m.positions.len() {
                return invalid(format!(
                    "mesh has {} positions but {} uvs",
                    m.positions.len(),
                    m.uvs.len()
                ));
            }
            if let Some(bad) = m
                .triangles
                .iter()
                .flatten()
                .find(|&&i| i as usize >= m.positions.len())
            {
                return invalid(format!(
                    "mesh triangle refers to vertex {bad}, the mesh has {}",
                    m.positions.len()
                ));
            }
            scene.texture = Some(texture);
            scene.tris = m
                .triangles
                .par_iter()
                .flat_map_iter(|tri| prepare_tri(m, tri, &depth, w, h, lo, hi))
                .collect();
        }
        if let Some(s) = strands {
            let total: u64 = s.counts.iter().map(|&c| c as u64).sum();
            if total != s.points.len() as u64 {
                return invalid(format!(
                    "strand counts sum to {total} but there are {} points",
                    s.points.len()
                ));
            }
            if s.colors.len() != s.points.len() {
                return invalid(format!(
                    "strands have {} points but {} colours (one per vertex needed)",
                    s.points.len(),
                    s.colors.len()
                ));
            }
            if let Some(ph) = &s.photo {
                let texture = checked_texture("strand photo", &ph.texture, max_dim)?;
                if ph.points.len() != s.points.len() {
                    return invalid(format!(
                        "strands have {} points but {} photo points",
                        s.points.len(),
                        ph.points.len()
                    ));
                }
                if !(ph.half_width.is_finite() && ph.half_width >= 0.0) {
                    return invalid(format!(
                        "photo half width {} must be finite and >= 0",
                        ph.half_width
                    ));
                }
                scene.cfg.photo = 1;
                scene.cfg.photo_half_width = ph.half_width;
                if let Some([hue, sat, val]) = ph.hsv {
                    if !(hue.is_finite() && sat.is_finite() && val.is_finite()) {
                        return invalid(format!("photo HSV adjustment {:?} is not finite", ph.hsv));
                    }
                    scene.cfg.photo = 2;
                    scene.cfg.hue_deg = hue.rem_euclid(360.0);
                    scene.cfg.saturation = sat;
                    scene.cfg.value = val;
                }
                scene.photo = Some(texture);
            }
            // Segments are addressed by (first vertex, strand) as u32 on both paths.
            if s.points.len() > u32::MAX as usize || s.counts.len() > u32::MAX as usize {
                return invalid(format!(
                    "{} strands with {} points: at most {} of each can be drawn at once",
                    s.counts.len(),
                    s.points.len(),
                    u32::MAX
                ));
            }
            let mut starts = Vec::with_capacity(s.counts.len());
            let mut acc = 0usize;
            for &c in &s.counts {
                starts.push(acc);
                acc += c as usize;
            }
            let src = SegSource {
                s,
                prep: SegPrep {
                    depth,
                    half: cfg.half_width,
                    snap_slope: 0.01 / (2.0 * cfg.half_width).max(MIN_SEGMENT_PX),
                    w: w as f32,
                    h: h as f32,
                    lo,
                    hi,
                },
                starts,
            };
            if materialise {
                let src = &src;
                scene.drawn = (0..s.counts.len())
                    .into_par_iter()
                    .flat_map_iter(|k| {
                        let (a, n) = (src.starts[k], s.counts[k] as usize);
                        (a..(a + n).saturating_sub(1))
                            .filter(move |&i| src.seg(i, k as u32).is_some())
                            .map(move |i| [i as u32, k as u32])
                    })
                    .collect();
            }
            scene.src = Some(src);
        }
        Ok(scene)
    }

    /// The prepared segment of [`Scene::drawn`] entry `at`, its `local` 0.
    fn seg_rec(&self, at: [u32; 2]) -> SegRec {
        self.src
            .as_ref()
            .and_then(|src| src.seg(at[0] as usize, at[1]))
            .expect("a listed segment is drawable (the same preparation listed it)")
    }

    /// What the GPU path orders [`Scene::drawn`] entry `at` by: its first end in px and its
    /// nearer end's depth, from the raw end points (any order gives the same image, so the
    /// preparation's clipping need not be redone for it).
    fn order_ends(&self, at: [u32; 2]) -> ([f32; 2], f32) {
        let src = self
            .src
            .as_ref()
            .expect("listed segments come from strands");
        let (a, b) = (
            src.s.points[at[0] as usize],
            src.s.points[at[0] as usize + 1],
        );
        let z = src.prep.depth.z(a[2]).min(src.prep.depth.z(b[2]));
        ([a[0], a[1]], z)
    }
}

#[derive(Clone, Copy)]
struct DepthMap {
    far: f32,
    near: f32,
}

impl DepthMap {
    fn z(&self, d: f32) -> f32 {
        (self.near - d) / (self.near - self.far)
    }
}

struct SegPrep {
    depth: DepthMap,
    half: f32,
    /// 0.01 px / (2 half), at least [`MIN_SEGMENT_PX`]: times a segment's |Δz|, how far
    /// snapping its corners can move its depth ([`SegSource::cull`]; a multiply there,
    /// not a divide per segment).
    snap_slope: f32,
    w: f32,
    h: f32,
    lo: [f32; 2],
    hi: [f32; 2],
}

impl SegPrep {
    /// (Always inlined: once per segment per tile in the AVX2 tile loop.)
    #[inline(always)]
    fn segment(
        &self,
        a: [f32; 3],
        b: [f32; 3],
        ca: [f32; 4],
        cb: [f32; 4],
        photo: (Option<[f32; 2]>, Option<[f32; 2]>),
        strand: u32,
    ) -> Option<SegRec> {
        if !(finite(&a) && finite(&b) && finite(&ca) && finite(&cb)) {
            return None;
        }
        let (mut oa, mut ob) = (photo.0.unwrap_or([0.0; 2]), photo.1.unwrap_or([0.0; 2]));
        if !(finite(&oa) && finite(&ob)) {
            return None;
        }
        // Both alphas <= 0: every pixel's alpha is <= 0, so no sample is kept on either path.
        if ca[3] <= 0.0 && cb[3] <= 0.0 {
            return None;
        }
        // Quad corners lie within half·√2 of the end points.
        let m = self.half * 1.5 + 1.0;
        if a[0].max(b[0]) + m < 0.0
            || a[0].min(b[0]) - m > self.w
            || a[1].max(b[1]) + m < 0.0
            || a[1].min(b[1]) - m > self.h
        {
            return None;
        }
        let (mut za, mut zb) = (self.depth.z(a[2]), self.depth.z(b[2]));
        // (A huge depth over a tiny range can overflow to infinity: nothing to draw.)
        if !(za.is_finite() && zb.is_finite()) || (za < 0.0 && zb < 0.0) || (za > 1.0 && zb > 1.0) {
            return None;
        }
        let (mut pa, mut pb) = ([a[0], a[1]], [b[0], b[1]]);
        let (mut ca, mut cb) = (ca, cb);
        let outside = |p: [f32; 2]| (0..2).any(|k| p[k] < self.lo[k] || p[k] > self.hi[k]);
        if outside(pa) || outside(pb) {
            let [e0, e1] = clip_segment(pa, pb, self.lo, self.hi)?;
            let (qa, qb, ya, yb, da, db) = (pa, pb, za, zb, ca, cb);
            let (ra, rb) = (oa, ob);
            let lerp2 = |t: f32| [lerp(ra[0], rb[0], t), lerp(ra[1], rb[1], t)];
            if e0.1.is_some() {
                pa = clip_point(qa, qb, e0);
                za = lerp(ya, yb, e0.0);
                ca = lerp4(da, db, e0.0);
                oa = lerp2(e0.0);
            }
            if e1.1.is_some() {
                pb = clip_point(qa, qb, e1);
                zb = lerp(ya, yb, e1.0);
                cb = lerp4(da, db, e1.0);
                ob = lerp2(e1.0);
            }
        }
        let d = [pb[0] - pa[0], pb[1] - pa[1]];
        if d[0] * d[0] + d[1] * d[1] < MIN_SEGMENT_PX * MIN_SEGMENT_PX {
            return None;
        }
        Some(SegRec {
            p0: pa,
            p1: pb,
            z0: za,
            z1: zb,
            strand,
            local: 0,
            c0: ca,
            c1: cb,
            o: [oa[0], oa[1], ob[0], ob[1]],
        })
    }
}

fn prepare_tri(
    m: &ScreenMesh,
    tri: &[u32; 3],
    depth: &DepthMap,
    w: u32,
    h: u32,
    lo: [f32; 2],
    hi: [f32; 2],
) -> Vec<TriRec> {
    let v: [[f32; 5]; 3] = tri.map(|i| {
        let (p, uv) = (m.positions[i as usize], m.uvs[i as usize]);
        [p[0], p[1], depth.z(p[2]), uv[0], uv[1]]
    });
    if !v.iter().all(finite) {
        return Vec::new();
    }
    let min = |k: usize| v.iter().map(|q| q[k]).fold(f32::INFINITY, f32::min);
    let max = |k: usize| v.iter().map(|q| q[k]).fold(f32::NEG_INFINITY, f32::max);
    if max(0) < -1.0 || min(0) > w as f32 + 1.0 || max(1) < -1.0 || min(1) > h as f32 + 1.0 {
        return Vec::new();
    }
    if max(2) < 0.0 || min(2) > 1.0 {
        return Vec::new();
    }
    let rec = |a: &[f32; 5], b: &[f32; 5], c: &[f32; 5]| TriRec {
        a: [a[0], a[1], a[2], a[3]],
        b: [b[0], b[1], b[2], b[3]],
        c: [c[0], c[1], c[2], c[3]],
        v: [a[4], b[4], c[4], 0.0],
    };
    let outside = |p: &[f32; 5]| (0..2).any(|k| p[k] < lo[k] || p[k] > hi[k]);
    if !v.iter().any(outside) {
        return vec![rec(&v[0], &v[1], &v[2])];
    }
    // Clip to the guard band so neither path sees huge coordinates; clipping keeps the
    // winding, and the new edges lie off-screen.
    let mut poly = v.to_vec();
    for (axis, bound, below) in [
        (0, lo[0], false),
        (0, hi[0], true),
        (1, lo[1], false),
        (1, hi[1], true),
    ] {
        if poly.len() < 3 {
            return Vec::new();
        }
        poly = clip_poly(&poly, axis, bound, below);
    }
    (1..poly.len().saturating_sub(1))
        .map(|i| rec(&poly[0], &poly[i], &poly[i + 1]))
        .collect()
}

/// Makes the output straight alpha: rgb / a where a > 0, transparent black elsewhere.
fn unpremultiply(img: &mut [[f32; 4]]) {
    img.par_iter_mut().for_each(|p| {
        if p[3] > 0.0 {
            let inv = 1.0 / p[3];
            for c in &mut p[..3] {
                *c *= inv;
            }
        } else {
            *p = [0.0; 4];
        }
    });
}

// ---------------------------------------------------------------------------------------------
// Entry points
// ---------------------------------------------------------------------------------------------

/// Renders on the engine's backend: wgpu when it has a GPU, else the CPU mirror.
pub fn render(
    engine: &Engine,
    frame: &Frame,
    mesh: Option<&ScreenMesh>,
    strands: Option<&ScreenStrands>,
    p: &RasterParams,
) -> Result<Vec<[f32; 4]>> {
    match engine.gpu() {
        Some(g) => render_gpu(g, frame, mesh, strands, p),
        None => render_cpu(frame, mesh, strands, p),
    }
}

/// The CPU mirror: same image as [`render_gpu`], in parallel over tiles.
pub fn render_cpu(
    frame: &Frame,
    mesh: Option<&ScreenMesh>,
    strands: Option<&ScreenStrands>,
    p: &RasterParams,
) -> Result<Vec<[f32; 4]>> {
    let scene = Scene::new(frame, mesh, strands, p, CPU_MAX_DIM, false)?;
    let mut img = cpu::raster(&scene);
    unpremultiply(&mut img);
    Ok(img)
}

/// Renders with wgpu render pipelines on `ctx`'s device.
pub fn render_gpu(
    ctx: &GpuContext,
    frame: &Frame,
    mesh: Option<&ScreenMesh>,
    strands: Option<&ScreenStrands>,
    p: &RasterParams,
) -> Result<Vec<[f32; 4]>> {
    render_gpu_chunked(ctx, frame, mesh, strands, p, u64::MAX)
}

/// [`render_gpu`] with each draw's storage binding capped at `max_chunk_bytes` (the device
/// limit applies anyway); tests use it to exercise the splitting of large inputs.
#[doc(hidden)]
pub fn render_gpu_chunked(
    ctx: &GpuContext,
    frame: &Frame,
    mesh: Option<&ScreenMesh>,
    strands: Option<&ScreenStrands>,
    p: &RasterParams,
    max_chunk_bytes: u64,
) -> Result<Vec<[f32; 4]>> {
    render_gpu_with(
        ctx,
        frame,
        mesh,
        strands,
        p,
        max_chunk_bytes,
        GpuStrands::Best,
    )
}

/// [`render_gpu`] with the strands drawn by the render pipeline even where the compute
/// passes would draw them (4x MSAA), for tests and benches that compare the two GPU paths.
#[doc(hidden)]
pub fn render_gpu_pipeline(
    ctx: &GpuContext,
    frame: &Frame,
    mesh: Option<&ScreenMesh>,
    strands: Option<&ScreenStrands>,
    p: &RasterParams,
) -> Result<Vec<[f32; 4]>> {
    render_gpu_with(ctx, frame, mesh, strands, p, u64::MAX, GpuStrands::Pipeline)
}

/// Which strand path a GPU render takes: the best the device and frame allow, or one forced.
#[doc(hidden)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GpuStrands {
    Best,
    TwoWalks,
    Pipeline,
}

/// Which GPU path [`render_gpu`] draws these strands with, for tests: `"strand_vis64"` (the
/// compute passes, one walk by 64-bit atomics), `"strand_vis"` (the compute passes in two
/// walks) or `"strand_raster"` (the render pipeline).
#[doc(hidden)]
pub fn gpu_strand_path(
    ctx: &GpuContext,
    frame: &Frame,
    strands: Option<&ScreenStrands>,
    p: &RasterParams,
) -> Result<&'static str> {
    let max_dim = ctx.limits.max_texture_dimension_2d;
    let scene = Scene::new(frame, None, strands, p, max_dim, true)?;
    Ok(gpu::strand_stage(ctx, &scene, GpuStrands::Best).name)
}

/// [`render_gpu_chunked`] with the strands drawn by the path `path` asks for (tests and
/// benches compare them: [`GpuStrands::TwoWalks`] on a device with 64-bit atomics).
#[doc(hidden)]
pub fn render_gpu_with(
    ctx: &GpuContext,
    frame: &Frame,
    mesh: Option<&ScreenMesh>,
    strands: Option<&ScreenStrands>,
    p: &RasterParams,
    max_chunk_bytes: u64,
    path: GpuStrands,
) -> Result<Vec<[f32; 4]>> {
    let scene = Scene::new(
        frame,
        mesh,
        strands,
        p,
        ctx.limits.max_texture_dimension_2d,
        true,
    )?;
    let mut img = gpu::raster(ctx, &scene, max_chunk_bytes, path)?;
    unpremultiply(&mut img);
    Ok(img)
}
