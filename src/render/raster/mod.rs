//! Strand rasteriser (C13 §4): one frame = an optional background image, then an optional
//! textured triangle mesh (the head), then the strands as screen-aligned quads, all
//! depth-tested in one multisampled target with alpha-to-coverage and no depth sorting.
//! Two implementations give the same image: wgpu render pipelines ([`render_gpu`],
//! `wgsl/strand_raster.wgsl`, `wgsl/mesh_raster.wgsl`) and a CPU mirror ([`render_cpu`],
//! tiled, rayon-parallel) that evaluates coverage exactly as a Vulkan rasteriser does.
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
//! - **Mesh**: opaque; back faces culled (front faces are counter-clockwise as the image is
//!   viewed, which is what a mesh counter-clockwise from outside gives after the camera's y
//!   flip); bilinear texture with clamp-to-edge, texel (i, j) centred at
//!   uv ((i + 0.5) / W, (j + 0.5) / H), row 0 at v = 0. Triangles with a non-finite vertex
//!   or uv are skipped.
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

use crate::error::{Error, Result};
use crate::gpu::GpuContext;
use crate::Engine;
use rayon::prelude::*;

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

/// A texture in linear straight RGBA, row 0 at v = 0.
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
    /// as [`crate::render::shade::hsv_adjust`]; None = unchanged.
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

/// Vulkan's standard 4x sample positions within a pixel (x right, y down).
pub const SAMPLE_POSITIONS_4: [[f32; 2]; 4] = [
    [0.375, 0.125],
    [0.875, 0.375],
    [0.125, 0.625],
    [0.625, 0.875],
];

/// Largest frame or texture side on the CPU path (the GPU path uses the device limit).
pub const CPU_MAX_DIM: u32 = 16384;

/// Widest strand quad accepted, px.
pub const MAX_STRAND_WIDTH: f32 = 64.0;

/// Segments shorter than this (px, on screen) are skipped: they have no direction.
pub const MIN_SEGMENT_PX: f32 = 1e-4;

/// Sub-pixel grid vertices snap to (8 bits, as lavapipe).
const SUBPIXEL: f32 = 256.0;

/// CPU tile side in pixels: big enough that few segments straddle two tiles (each is set
/// up once per tile), small enough for a tile's samples (128² x 4 x 20 B) to stay in L2.
const TILE: u32 = 128;

// ---------------------------------------------------------------------------------------------
// sRGB and f16
// ---------------------------------------------------------------------------------------------

/// 8-bit sRGB code to linear light, with the exact sRGB transfer function.
pub fn srgb_to_linear(v: u8) -> f32 {
    let c = v as f64 / 255.0;
    let l = if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    };
    l as f32
}

fn linear_to_srgb_unit(l: f32) -> f64 {
    // NaN counts as 0.
    let l = if l > 0.0 { (l as f64).min(1.0) } else { 0.0 };
    if l <= 0.0031308 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

/// Linear light to the nearest 8-bit sRGB code (clamped to [0, 1]; NaN gives 0).
pub fn linear_to_srgb(l: f32) -> u8 {
    (linear_to_srgb_unit(l) * 255.0).round() as u8
}

/// Linear light to the nearest 16-bit sRGB code (clamped to [0, 1]; NaN gives 0).
pub fn linear_to_srgb16(l: f32) -> u16 {
    (linear_to_srgb_unit(l) * 65535.0).round() as u16
}

fn unit_alpha(a: f32) -> f64 {
    if a > 0.0 {
        (a as f64).min(1.0)
    } else {
        0.0
    }
}

/// Straight linear RGBA to 8-bit sRGB RGBA (alpha stays linear), e.g. for a PNG.
pub fn to_rgba8(img: &[[f32; 4]]) -> Vec<u8> {
    let mut out = vec![0u8; img.len() * 4];
    out.par_chunks_mut(4 * 4096)
        .zip(img.par_chunks(4096))
        .for_each(|(o, px)| {
            for (o, p) in o.chunks_exact_mut(4).zip(px) {
                for c in 0..3 {
                    o[c] = linear_to_srgb(p[c]);
                }
                o[3] = (unit_alpha(p[3]) * 255.0).round() as u8;
            }
        });
    out
}

/// Straight linear RGBA to 16-bit sRGB RGBA (alpha stays linear), e.g. for a 16-bit PNG.
pub fn to_rgba16(img: &[[f32; 4]]) -> Vec<u16> {
    let mut out = vec![0u16; img.len() * 4];
    out.par_chunks_mut(4 * 4096)
        .zip(img.par_chunks(4096))
        .for_each(|(o, px)| {
            for (o, p) in o.chunks_exact_mut(4).zip(px) {
                for c in 0..3 {
                    o[c] = linear_to_srgb16(p[c]);
                }
                o[3] = (unit_alpha(p[3]) * 65535.0).round() as u16;
            }
        });
    out
}

/// IEEE binary16 bits of `x`, rounded to nearest, ties to even (overflow gives infinity).
pub fn f32_to_f16_bits(x: f32) -> u16 {
    let b = x.to_bits();
    let sign = ((b >> 16) & 0x8000) as u16;
    let exp = ((b >> 23) & 0xff) as i32;
    let man = b & 0x7f_ffff;
    if exp == 0xff {
        let nan = if man != 0 {
            0x200 | (man >> 13) as u16
        } else {
            0
        };
        return sign | 0x7c00 | nan;
    }
    let e = exp - 127 + 15;
    if e >= 0x1f {
        return sign | 0x7c00;
    }
    let (half, rem, halfway) = if e <= 0 {
        // Subnormal half: value = m · 2^-24 with m = mantissa (implicit 1) >> (14 - e).
        if e < -10 {
            return sign;
        }
        let m = man | 0x80_0000;
        let shift = (14 - e) as u32;
        (m >> shift, m & ((1 << shift) - 1), 1u32 << (shift - 1))
    } else {
        (((e as u32) << 10) | (man >> 13), man & 0x1fff, 0x1000)
    };
    let up = rem > halfway || (rem == halfway && half & 1 == 1);
    // A carry out of the mantissa correctly bumps the exponent (up to infinity).
    sign | (half + up as u32) as u16
}

/// The f32 value of IEEE binary16 bits.
pub fn f16_bits_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0f32 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as u32;
    let man = (h & 0x3ff) as u32;
    match exp {
        0 => sign * man as f32 * (1.0 / 16_777_216.0),
        0x1f => f32::from_bits(((h as u32 & 0x8000) << 16) | 0x7f80_0000 | (man << 13)),
        _ => f32::from_bits(((h as u32 & 0x8000) << 16) | ((exp + 112) << 23) | (man << 13)),
    }
}

/// IEEE binary16 bits of `x`, rounded toward zero (overflow gives the largest finite value),
/// as lavapipe converts when it writes an f32 colour into an Rgba16Float target.
pub fn f32_to_f16_bits_rtz(x: f32) -> u16 {
    let b = x.to_bits();
    let sign = ((b >> 16) & 0x8000) as u16;
    let exp = ((b >> 23) & 0xff) as i32;
    let man = b & 0x7f_ffff;
    if exp == 0xff {
        return f32_to_f16_bits(x);
    }
    let e = exp - 127 + 15;
    if e >= 0x1f {
        return sign | 0x7bff;
    }
    if e <= 0 {
        if e < -10 {
            return sign;
        }
        return sign | ((man | 0x80_0000) >> (14 - e) as u32) as u16;
    }
    sign | (((e as u32) << 10) | (man >> 13)) as u16
}

/// The value a render-target write keeps: f16, truncated (see [`f32_to_f16_bits_rtz`]).
/// Equal to `f16_bits_to_f32(f32_to_f16_bits_rtz(x))`, computed in the f32 domain (the
/// resolve calls it for every sample channel): in the f16 normal range truncation keeps the
/// top 10 mantissa bits, below it the f16 quantum is 2^-24.
#[inline]
fn f16_store(x: f32) -> f32 {
    let a = x.abs();
    if a >= 6.103_515_6e-5 {
        if a > 65504.0 {
            return if x.is_nan() {
                f32::NAN
            } else {
                65504.0f32.copysign(x)
            };
        }
        f32::from_bits(x.to_bits() & 0xffff_e000)
    } else {
        // |x| < 2^-14: x·2^24 < 1024 is exact, truncate it (toward zero) and scale back.
        (x * 16_777_216.0).trunc() * (1.0 / 16_777_216.0)
    }
}

// ---------------------------------------------------------------------------------------------
// Host preparation, shared by both paths
// ---------------------------------------------------------------------------------------------

/// One strand segment as both paths see it (the WGSL `Seg`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SegRec {
    pub p0: [f32; 2],
    pub p1: [f32; 2],
    /// Depth-buffer values in [0, 1] (0 = near); may lie outside, then clipped.
    pub z0: f32,
    pub z1: f32,
    pub strand: u32,
    pub _pad: u32,
    pub c0: [f32; 4],
    pub c1: [f32; 4],
    /// Photo points of the two ends (o0.xy, o1.xy); zero without a photo.
    pub o: [f32; 4],
}

/// One mesh triangle as both paths see it (the WGSL `Tri`): corners (x, y, z, u), then v.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TriRec {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub c: [f32; 4],
    pub v: [f32; 4],
}

/// The uniform of both shaders (WGSL `Config`).
#[derive(Clone, Copy, Debug, PartialEq, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub samples: u32,
    pub half_width: f32,
    pub ndc_scale_x: f32,
    pub ndc_scale_y: f32,
    /// 0: vertex colours; 1: photo colour; 2: photo colour with the HSV adjustment.
    pub photo: u32,
    pub photo_half_width: f32,
    pub hue_deg: f32,
    pub saturation: f32,
    pub value: f32,
    pub _pad: u32,
}

/// Everything a render needs, validated and prepared on the host once for either path.
struct Scene {
    cfg: Config,
    /// Premultiplied, sanitised.
    background: Option<Vec<[f32; 4]>>,
    /// Sanitised texture of the mesh (present iff `mesh` was given).
    texture: Option<Texture>,
    /// Sanitised photo of the strands' photo colour.
    photo: Option<Texture>,
    tris: Vec<TriRec>,
    segs: Vec<SegRec>,
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

impl Scene {
    fn new(
        frame: &Frame,
        mesh: Option<&ScreenMesh>,
        strands: Option<&ScreenStrands>,
        p: &RasterParams,
        max_dim: u32,
    ) -> Result<Scene> {
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
        let cfg = Config {
            width: w,
            height: h,
            samples: p.samples,
            half_width: 0.5 * p.strand_width,
            ndc_scale_x: 2.0 / w as f32,
            ndc_scale_y: 2.0 / h as f32,
            photo: 0,
            photo_half_width: 0.0,
            hue_deg: 0.0,
            saturation: 1.0,
            value: 1.0,
            _pad: 0,
        };
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
            segs: Vec::new(),
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
            let opoint = |i: usize| s.photo.as_ref().map(|ph| ph.points[i]);
            let mut starts = Vec::with_capacity(s.counts.len());
            let mut acc = 0usize;
            for &c in &s.counts {
                starts.push(acc);
                acc += c as usize;
            }
            let prep = SegPrep {
                depth,
                half: cfg.half_width,
                w: w as f32,
                h: h as f32,
                lo,
                hi,
            };
            scene.segs = (0..s.counts.len())
                .into_par_iter()
                .flat_map_iter(|k| {
                    let (a, n) = (starts[k], s.counts[k] as usize);
                    let prep = &prep;
                    (a..(a + n).saturating_sub(1)).filter_map(move |i| {
                        prep.segment(
                            s.points[i],
                            s.points[i + 1],
                            s.colors[i],
                            s.colors[i + 1],
                            (opoint(i), opoint(i + 1)),
                            k as u32,
                        )
                    })
                })
                .collect();
        }
        Ok(scene)
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
    w: f32,
    h: f32,
    lo: [f32; 2],
    hi: [f32; 2],
}

impl SegPrep {
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
            _pad: 0,
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

/// The CPU mirror: same image as [`render_gpu`], in parallel over 64² tiles.
pub fn render_cpu(
    frame: &Frame,
    mesh: Option<&ScreenMesh>,
    strands: Option<&ScreenStrands>,
    p: &RasterParams,
) -> Result<Vec<[f32; 4]>> {
    let scene = Scene::new(frame, mesh, strands, p, CPU_MAX_DIM)?;
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
    let scene = Scene::new(frame, mesh, strands, p, ctx.limits.max_texture_dimension_2d)?;
    let mut img = gpu::raster(ctx, &scene, max_chunk_bytes)?;
    unpremultiply(&mut img);
    Ok(img)
}

// ---------------------------------------------------------------------------------------------
// GPU path
// ---------------------------------------------------------------------------------------------

mod gpu {
    use super::*;
    use wgpu::util::DeviceExt;

    pub const STRAND_WGSL: &str = include_str!("../../../wgsl/render/strand_raster.wgsl");
    pub const MESH_WGSL: &str = include_str!("../../../wgsl/render/mesh_raster.wgsl");
    const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
    const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

    fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
        wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }
    }

    fn storage_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
        wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }
    }

    fn texture_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
        wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        }
    }

    struct Pipe {
        layout: wgpu::BindGroupLayout,
        pipeline: wgpu::RenderPipeline,
    }

    #[allow(clippy::too_many_arguments)]
    fn pipe(
        d: &wgpu::Device,
        label: &str,
        module: &wgpu::ShaderModule,
        vs: &str,
        fs: &str,
        entries: &[wgpu::BindGroupLayoutEntry],
        cull: Option<wgpu::Face>,
        depth_write: bool,
        compare: wgpu::CompareFunction,
        samples: u32,
    ) -> Pipe {
        let layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries,
        });
        let pl = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = d.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(&pl),
            vertex: wgpu::VertexState {
                module,
                entry_point: Some(vs),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                strip_index_format: None,
                front_face: wgpu::FrontFace::Ccw,
                cull_mode: cull,
                unclipped_depth: false,
                polygon_mode: wgpu::PolygonMode::Fill,
                conservative: false,
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(depth_write),
                depth_compare: Some(compare),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            // Alpha-to-coverage is done by the strand shader itself (deterministic rule).
            multisample: wgpu::MultisampleState {
                count: samples,
                mask: !0,
                alpha_to_coverage_enabled: false,
            },
            fragment: Some(wgpu::FragmentState {
                module,
                entry_point: Some(fs),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: COLOR_FORMAT,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        Pipe { layout, pipeline }
    }

    fn texture_rgba32(
        ctx: &GpuContext,
        label: &str,
        w: u32,
        h: u32,
        texels: &[[f32; 4]],
    ) -> wgpu::TextureView {
        let size = wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        };
        let tex = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        ctx.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &tex,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytemuck::cast_slice(texels),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(w * 16),
                rows_per_image: Some(h),
            },
            size,
        );
        tex.create_view(&Default::default())
    }

    fn target(
        ctx: &GpuContext,
        label: &str,
        w: u32,
        h: u32,
        samples: u32,
        format: wgpu::TextureFormat,
        usage: wgpu::TextureUsages,
    ) -> wgpu::Texture {
        ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: samples,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    }

    /// Storage buffers of at most `chunk_bytes` each, with their item counts.
    fn chunks<T: bytemuck::Pod>(
        ctx: &GpuContext,
        label: &str,
        items: &[T],
        chunk_bytes: u64,
    ) -> Vec<(wgpu::Buffer, u32)> {
        let per = (chunk_bytes / std::mem::size_of::<T>() as u64).clamp(1, u32::MAX as u64 / 6);
        items
            .chunks(per as usize)
            .map(|c| {
                let buf = ctx
                    .device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some(label),
                        contents: bytemuck::cast_slice(c),
                        usage: wgpu::BufferUsages::STORAGE,
                    });
                (buf, c.len() as u32)
            })
            .collect()
    }

    pub fn raster(ctx: &GpuContext, s: &Scene, max_chunk_bytes: u64) -> Result<Vec<[f32; 4]>> {
        let d = &ctx.device;
        let (w, h, n) = (s.cfg.width, s.cfg.height, s.cfg.samples);
        let bytes_per_row = (w * 8).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let readback_bytes = bytes_per_row as u64 * h as u64;
        if readback_bytes > ctx.limits.max_buffer_size {
            return Err(Error::TooLarge {
                what: format!("read-back of a {w}x{h} frame"),
                needed: readback_bytes,
                limit: ctx.limits.max_buffer_size,
                limit_name: "largest buffer".into(),
            });
        }
        let chunk_bytes = ctx.max_binding_bytes().min(max_chunk_bytes);
        let validation = d.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = d.push_error_scope(wgpu::ErrorFilter::OutOfMemory);

        let strand_module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("strand_raster"),
            source: wgpu::ShaderSource::Wgsl(STRAND_WGSL.into()),
        });
        let mesh_module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("mesh_raster"),
            source: wgpu::ShaderSource::Wgsl(MESH_WGSL.into()),
        });
        let less = wgpu::CompareFunction::Less;
        let mut ub = encase::UniformBuffer::new(Vec::<u8>::new());
        ub.write(&s.cfg).expect("uniform fits in memory");
        let uniform = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("raster.config"),
            contents: &ub.into_inner(),
            usage: wgpu::BufferUsages::UNIFORM,
        });

        let msaa = n > 1;
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
        let color = target(
            ctx,
            "raster.color",
            w,
            h,
            n,
            COLOR_FORMAT,
            if msaa {
                attach
            } else {
                attach | wgpu::TextureUsages::COPY_SRC
            },
        );
        let resolve = msaa.then(|| {
            target(
                ctx,
                "raster.resolve",
                w,
                h,
                1,
                COLOR_FORMAT,
                attach | wgpu::TextureUsages::COPY_SRC,
            )
        });
        let depth = target(ctx, "raster.depth", w, h, n, DEPTH_FORMAT, attach);
        let color_view = color.create_view(&Default::default());
        let resolve_view = resolve.as_ref().map(|t| t.create_view(&Default::default()));
        let depth_view = depth.create_view(&Default::default());

        // Background: one bind group, one full-screen triangle.
        let background = s.background.as_ref().map(|bg| {
            let p = pipe(
                d,
                "raster.background",
                &mesh_module,
                "vs_background",
                "fs_background",
                &[texture_entry(2)],
                None,
                false,
                wgpu::CompareFunction::Always,
                n,
            );
            let view = texture_rgba32(ctx, "raster.background", w, h, bg);
            let bg = d.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("raster.background"),
                layout: &p.layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&view),
                }],
            });
            (p, bg)
        });
        let mesh = match (&s.texture, s.tris.is_empty()) {
            (Some(t), false) => {
                let p = pipe(
                    d,
                    "raster.mesh",
                    &mesh_module,
                    "vs_mesh",
                    "fs_mesh",
                    &[uniform_entry(0), storage_entry(1), texture_entry(2)],
                    Some(wgpu::Face::Back),
                    true,
                    less,
                    n,
                );
                let view = texture_rgba32(ctx, "raster.texture", t.width, t.height, &t.texels);
                let groups: Vec<(wgpu::BindGroup, u32)> =
                    chunks(ctx, "raster.tris", &s.tris, chunk_bytes)
                        .into_iter()
                        .map(|(buf, count)| {
                            let bg = d.create_bind_group(&wgpu::BindGroupDescriptor {
                                label: Some("raster.mesh"),
                                layout: &p.layout,
                                entries: &[
                                    wgpu::BindGroupEntry {
                                        binding: 0,
                                        resource: uniform.as_entire_binding(),
                                    },
                                    wgpu::BindGroupEntry {
                                        binding: 1,
                                        resource: buf.as_entire_binding(),
                                    },
                                    wgpu::BindGroupEntry {
                                        binding: 2,
                                        resource: wgpu::BindingResource::TextureView(&view),
                                    },
                                ],
                            });
                            (bg, count)
                        })
                        .collect();
                Some((p, groups))
            }
            _ => None,
        };
        let strands = (!s.segs.is_empty()).then(|| {
            let p = pipe(
                d,
                "raster.strands",
                &strand_module,
                "vs_main",
                "fs_main",
                &[uniform_entry(0), storage_entry(1), texture_entry(2)],
                None,
                true,
                less,
                n,
            );
            // The shader only reads the photo when `cfg.photo` says so; a 1x1 texture stands
            // in otherwise (the layout needs a binding).
            let photo = match &s.photo {
                Some(t) => texture_rgba32(ctx, "raster.photo", t.width, t.height, &t.texels),
                None => texture_rgba32(ctx, "raster.photo", 1, 1, &[[0.0; 4]]),
            };
            let groups: Vec<(wgpu::BindGroup, u32)> =
                chunks(ctx, "raster.segments", &s.segs, chunk_bytes)
                    .into_iter()
                    .map(|(buf, count)| {
                        let bg = d.create_bind_group(&wgpu::BindGroupDescriptor {
                            label: Some("raster.strands"),
                            layout: &p.layout,
                            entries: &[
                                wgpu::BindGroupEntry {
                                    binding: 0,
                                    resource: uniform.as_entire_binding(),
                                },
                                wgpu::BindGroupEntry {
                                    binding: 1,
                                    resource: buf.as_entire_binding(),
                                },
                                wgpu::BindGroupEntry {
                                    binding: 2,
                                    resource: wgpu::BindingResource::TextureView(&photo),
                                },
                            ],
                        });
                        (bg, count)
                    })
                    .collect();
            (p, groups)
        });

        let mut encoder = d.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("raster"),
        });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("raster"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &color_view,
                    depth_slice: None,
                    resolve_target: resolve_view.as_ref(),
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: if msaa {
                            wgpu::StoreOp::Discard
                        } else {
                            wgpu::StoreOp::Store
                        },
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if let Some((p, bg)) = &background {
                pass.set_pipeline(&p.pipeline);
                pass.set_bind_group(0, bg, &[]);
                pass.draw(0..3, 0..1);
            }
            // Mesh before strands, chunks in input order: the draw order the CPU mirrors.
            for (p, groups, per) in [
                mesh.as_ref().map(|(p, g)| (p, g, 3u32)),
                strands.as_ref().map(|(p, g)| (p, g, 6u32)),
            ]
            .into_iter()
            .flatten()
            {
                pass.set_pipeline(&p.pipeline);
                for (bg, count) in groups {
                    pass.set_bind_group(0, bg, &[]);
                    pass.draw(0..per * count, 0..1);
                }
            }
        }
        let readback = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("raster.readback"),
            size: readback_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: resolve.as_ref().unwrap_or(&color),
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(bytes_per_row),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        ctx.queue.submit([encoder.finish()]);
        readback.slice(..).map_async(wgpu::MapMode::Read, |_| {});
        d.poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("device poll failed: {e}")))?;
        if let Some(e) = pollster::block_on(oom.pop()) {
            return Err(Error::Gpu(format!("raster: {e}")));
        }
        if let Some(e) = pollster::block_on(validation.pop()) {
            return Err(Error::Gpu(format!("raster: {e}")));
        }
        ctx.check_errors()?;
        let view = readback
            .slice(..)
            .get_mapped_range()
            .map_err(|e| Error::Gpu(format!("cannot map the read-back buffer: {e}")))?;
        let mut img = vec![[0.0f32; 4]; w as usize * h as usize];
        img.par_chunks_mut(w as usize)
            .enumerate()
            .for_each(|(y, row)| {
                let start = y * bytes_per_row as usize;
                let src: &[u8] = &view[start..start + w as usize * 8];
                for (x, px) in row.iter_mut().enumerate() {
                    *px = std::array::from_fn(|c| {
                        let o = x * 8 + c * 2;
                        f16_bits_to_f32(u16::from_le_bytes([src[o], src[o + 1]]))
                    });
                }
            });
        Ok(img)
    }
}

#[doc(hidden)]
pub use gpu::{MESH_WGSL, STRAND_WGSL};

// ---------------------------------------------------------------------------------------------
// CPU mirror
// ---------------------------------------------------------------------------------------------

// Edges x samples loops index several arrays in lockstep over const-generic sizes; plain
// index loops read (and unroll) best there.
#[allow(clippy::needless_range_loop)]
mod cpu {
    use super::*;

    /// Screen px -> framebuffer px through NDC and the viewport transform, with the f32
    /// operations the vertex shader and the (y-flipped) Vulkan viewport perform.
    struct Fb {
        sx: f32,
        sy: f32,
        hw: f32,
        hh: f32,
    }

    impl Fb {
        fn new(c: &Config) -> Fb {
            Fb {
                sx: c.ndc_scale_x,
                sy: c.ndc_scale_y,
                hw: c.width as f32 * 0.5,
                hh: c.height as f32 * 0.5,
            }
        }

        #[inline]
        fn map(&self, p: [f32; 2]) -> [f32; 2] {
            let nx = p[0] * self.sx - 1.0;
            let ny = 1.0 - p[1] * self.sy;
            [nx * self.hw + self.hw, ny * -self.hh + self.hh]
        }
    }

    /// Round to the 1/256 px grid, ties to even (as lavapipe), without a libm call: adding
    /// 1.5·2^52 leaves no fraction bits, so the FPU's own round-to-nearest-even does it.
    #[inline]
    fn snap(v: f32) -> i64 {
        const MAGIC: f64 = 6_755_399_441_055_744.0;
        ((v * SUBPIXEL) as f64 + MAGIC - MAGIC) as i64
    }

    /// floor(v) as i32 without a libm call (x86-64's baseline has no rounding instruction).
    #[inline]
    fn floor_i32(v: f64) -> i32 {
        let i = v as i32;
        i - ((i as f64) > v) as i32
    }

    /// The alpha-to-coverage mask: k <= n samples starting at r, in order (mod n), for
    /// n = 1 or 4 (powers of two).
    #[inline]
    fn a2c_mask(n: u32, r: u32, k: u32) -> u32 {
        let run = (1u32 << k) - 1;
        ((run << r) | (run >> (n - r))) & ((1u32 << n) - 1)
    }

    /// Sample positions of an N-sample pixel, in 1/256 px and in px.
    fn sample_offsets<const N: usize>() -> ([[i64; 2]; N], [[f64; 2]; N]) {
        let pos: [[f32; 2]; N] = std::array::from_fn(|s| {
            if N == 4 {
                SAMPLE_POSITIONS_4[s]
            } else {
                [0.5, 0.5]
            }
        });
        (
            pos.map(|p| p.map(|v| (v * SUBPIXEL) as i64)),
            pos.map(|p| p.map(|v| v as f64)),
        )
    }

    /// A convex polygon of E edges set up for fixed-point coverage: a triangle, or a strand
    /// quad when the two triangles' union provably equals it (see `strand_quad`).
    struct Poly<const E: usize, const N: usize> {
        /// Edge k: inside when a·X + b·Y + c >= 0 (X, Y in 1/256 px); the top-left rule is
        /// folded into c.
        a: [i64; E],
        b: [i64; E],
        c: [i64; E],
        /// Per edge, per sample: a·ox + b·oy.
        so: [[i64; N]; E],
        /// Inclusive pixel bounding box.
        bbox: [i32; 4],
    }

    impl<const E: usize, const N: usize> Poly<E, N> {
        /// `v` in order around a convex polygon, either way round. None when the area is 0
        /// and, with `cull_back`, for back faces (positive area in y-down fb coordinates =
        /// clockwise in NDC).
        fn new(v: [[i64; 2]; E], cull_back: bool, offs: &[[i64; 2]; N]) -> Option<Self> {
            let area: i64 = (0..E)
                .map(|k| {
                    let (p, q) = (v[k], v[(k + 1) % E]);
                    p[0] * q[1] - q[0] * p[1]
                })
                .sum();
            if area == 0 || (cull_back && area > 0) {
                return None;
            }
            let (mut a, mut b, mut c) = ([0i64; E], [0i64; E], [0i64; E]);
            let mut so = [[0i64; N]; E];
            for k in 0..E {
                // Walk the edges with the interior on the positive side.
                let (p, q) = if area > 0 {
                    (v[k], v[(k + 1) % E])
                } else {
                    (v[(k + 1) % E], v[k])
                };
                let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
                a[k] = -dy;
                b[k] = dx;
                // Top edge (horizontal, interior below) or left edge (interior to the right)
                // include their samples; other edges exclude them.
                let top_left = dy < 0 || (dy == 0 && dx > 0);
                c[k] = -(a[k] * p[0] + b[k] * p[1]) - if top_left { 0 } else { 1 };
                for (s, o) in offs.iter().enumerate() {
                    so[k][s] = a[k] * o[0] + b[k] * o[1];
                }
            }
            let mut bbox = [i32::MAX, i32::MAX, i32::MIN, i32::MIN];
            for p in &v {
                let (x, y) = (p[0].div_euclid(256) as i32, p[1].div_euclid(256) as i32);
                bbox = [
                    bbox[0].min(x),
                    bbox[1].min(y),
                    bbox[2].max(x),
                    bbox[3].max(y),
                ];
            }
            Some(Poly { a, b, c, so, bbox })
        }

        /// Edge values at the corner of pixel (px, py); add [`Poly::step`] per pixel right.
        #[inline]
        fn edges(&self, px: i32, py: i32) -> [i64; E] {
            let (x, y) = (px as i64 * 256, py as i64 * 256);
            std::array::from_fn(|k| self.a[k] * x + self.b[k] * y + self.c[k])
        }

        #[inline]
        fn step(&self) -> [i64; E] {
            self.a.map(|a| a * 256)
        }

        /// Bit s set when sample s of the pixel whose corner has edge values `e` is covered.
        /// Branch-free: coverage is data-dependent and mispredictions dominated.
        #[inline]
        fn mask(&self, e: &[i64; E]) -> u32 {
            let mut m = 0;
            for s in 0..N {
                let mut inside = true;
                for k in 0..E {
                    inside &= e[k] + self.so[k][s] >= 0;
                }
                m |= (inside as u32) << s;
            }
            m
        }

        /// The same set-up in i32, valid while every edge value visited fits (see
        /// `strand_quad`): then 4 samples go through one SIMD compare.
        fn narrow(&self) -> ([[i32; N]; E], [i32; E]) {
            (
                self.so.map(|r| r.map(|v| v as i32)),
                self.step().map(|v| v as i32),
            )
        }
    }

    /// [`Poly::mask`] on i32 edge values.
    #[inline]
    fn mask32<const E: usize, const N: usize>(e: &[i32; E], so: &[[i32; N]; E]) -> u32 {
        let mut m = 0;
        for s in 0..N {
            let mut inside = true;
            for k in 0..E {
                inside &= e[k].wrapping_add(so[k][s]) >= 0;
            }
            m |= (inside as u32) << s;
        }
        m
    }

    /// Screen-linear interpolation over a triangle's float corners (fb px).
    struct Bary {
        v0: [f64; 2],
        e1: [f64; 2],
        e2: [f64; 2],
        inv_den: f64,
    }

    impl Bary {
        fn new(fl: [[f32; 2]; 3]) -> Bary {
            let f = fl.map(|p| p.map(|x| x as f64));
            let e1 = [f[1][0] - f[0][0], f[1][1] - f[0][1]];
            let e2 = [f[2][0] - f[0][0], f[2][1] - f[0][1]];
            let den = e1[0] * e2[1] - e2[0] * e1[1];
            Bary {
                v0: f[0],
                e1,
                e2,
                inv_den: if den != 0.0 { 1.0 / den } else { 0.0 },
            }
        }

        /// The value interpolated from the corners' `val` at (x, y).
        fn interp(&self, val: [f32; 3], x: f64, y: f64) -> f64 {
            let (dx, dy) = (x - self.v0[0], y - self.v0[1]);
            let l1 = (dx * self.e2[1] - self.e2[0] * dy) * self.inv_den;
            let l2 = (self.e1[0] * dy - dx * self.e1[1]) * self.inv_den;
            let v = val.map(|v| v as f64);
            v[0] + l1 * (v[1] - v[0]) + l2 * (v[2] - v[0])
        }

        /// The same interpolation as a plane.
        fn plane(&self, val: [f32; 3]) -> Plane {
            let c = self.interp(val, 0.0, 0.0);
            Plane {
                c,
                gx: self.interp(val, 1.0, 0.0) - c,
                gy: self.interp(val, 0.0, 1.0) - c,
            }
        }
    }

    /// v = c + gx·x + gy·y (fb px).
    #[derive(Clone, Copy)]
    struct Plane {
        c: f64,
        gx: f64,
        gy: f64,
    }

    impl Plane {
        /// The plane at the N sample positions of pixel (px, py), given the per-sample
        /// offsets `gx·ox + gy·oy`.
        #[inline]
        fn samples<const N: usize>(&self, px: i32, py: i32, off: &[f64; N]) -> [f32; N] {
            let zc = self.c + self.gx * px as f64 + self.gy * py as f64;
            std::array::from_fn(|i| (zc + off[i]) as f32)
        }

        fn offsets<const N: usize>(&self, offs: &[[f64; 2]; N]) -> [f64; N] {
            std::array::from_fn(|i| self.gx * offs[i][0] + self.gy * offs[i][1])
        }
    }

    /// Clamp-to-edge bilinear fetch with the f32 operations of `fs_mesh`.
    fn sample_bilinear(t: &Texture, uv: [f32; 2]) -> [f32; 4] {
        let s = uv[0] * t.width as f32 - 0.5;
        let r = uv[1] * t.height as f32 - 0.5;
        bilinear_at(t, s, r)
    }

    /// The same fetch at texel coordinates (s, r) = px - 0.5.
    fn bilinear_at(t: &Texture, s: f32, r: f32) -> [f32; 4] {
        let (w, h) = (t.width as i32, t.height as i32);
        let (fs, fr) = (s.floor(), r.floor());
        let (ax, ay) = (s - fs, r - fr);
        let (i, j) = (fs as i32, fr as i32);
        let tex = |i: i32, j: i32| {
            let (i, j) = (i.clamp(0, w - 1), j.clamp(0, h - 1));
            t.texels[(j * w + i) as usize]
        };
        let mix = |a: [f32; 4], b: [f32; 4], t: f32| -> [f32; 4] {
            std::array::from_fn(|k| a[k] * (1.0 - t) + b[k] * t)
        };
        let (i1, j1) = (i.saturating_add(1), j.saturating_add(1));
        let top = mix(tex(i, j), tex(i1, j), ax);
        let bottom = mix(tex(i, j1), tex(i1, j1), ax);
        mix(top, bottom, ay)
    }

    /// One tile's samples: colour (premultiplied, pixel-major) and depth.
    struct TileBuf<const N: usize> {
        x0: i32,
        y0: i32,
        w: i32,
        h: i32,
        color: Vec<[[f32; 4]; N]>,
        depth: Vec<[f32; N]>,
    }

    impl<const N: usize> TileBuf<N> {
        /// Depth-tests and writes the samples in `mask` of tile pixel (lx, ly): `Less`
        /// against the buffer, and outside [0, 1] nothing (the GPU clips the primitive).
        /// Branch-free selects, for the same reason as `Tri::mask`.
        #[inline]
        fn write(&mut self, lx: i32, ly: i32, mask: u32, c: [f32; 4], z: [f32; N]) {
            let i = (ly * self.w + lx) as usize;
            let (depth, color) = (&mut self.depth[i], &mut self.color[i]);
            for s in 0..N {
                let zs = z[s];
                let pass = ((mask >> s) & 1 == 1) & (0.0..=1.0).contains(&zs) & (zs < depth[s]);
                depth[s] = if pass { zs } else { depth[s] };
                let m = 0u32.wrapping_sub(pass as u32);
                for k in 0..4 {
                    color[s][k] =
                        f32::from_bits((c[k].to_bits() & m) | (color[s][k].to_bits() & !m));
                }
            }
        }

        /// Pixel range of `bbox` inside the tile, as local coordinates.
        fn clip(&self, bbox: [i32; 4]) -> Option<(i32, i32, i32, i32)> {
            let x0 = (bbox[0] - self.x0).max(0);
            let y0 = (bbox[1] - self.y0).max(0);
            let x1 = (bbox[2] - self.x0).min(self.w - 1);
            let y1 = (bbox[3] - self.y0).min(self.h - 1);
            (x0 <= x1 && y0 <= y1).then_some((x0, y0, x1, y1))
        }
    }

    /// Conservative pixel bounding box of a strand quad (for binning only): its corners lie
    /// within half·√2 of the end points, plus rounding and snapping.
    fn seg_bounds(s: &SegRec, half: f32) -> [f32; 4] {
        let m = half * 1.415 + 0.01;
        [
            s.p0[0].min(s.p1[0]) - m,
            s.p0[1].min(s.p1[1]) - m,
            s.p0[0].max(s.p1[0]) + m,
            s.p0[1].max(s.p1[1]) + m,
        ]
    }

    fn tri_bounds(t: &TriRec) -> [f32; 4] {
        let xs = [t.a[0], t.b[0], t.c[0]];
        let ys = [t.a[1], t.b[1], t.c[1]];
        let min = |v: [f32; 3]| v[0].min(v[1]).min(v[2]) - 1.0;
        let max = |v: [f32; 3]| v[0].max(v[1]).max(v[2]) + 1.0;
        [min(xs), min(ys), max(xs), max(ys)]
    }

    /// Per tile, the indices of the items whose bounds touch it, in input order (the draw
    /// order the depth tie rule needs).
    fn bin(bounds: &[[f32; 4]], tiles_x: u32, tiles_y: u32) -> Vec<Vec<u32>> {
        let ranges: Vec<[u32; 4]> = bounds
            .par_iter()
            .map(|b| {
                let t = |v: f32, n: u32| ((v / TILE as f32).max(0.0) as u32).min(n - 1);
                [
                    t(b[0], tiles_x),
                    t(b[1], tiles_y),
                    t(b[2], tiles_x),
                    t(b[3], tiles_y),
                ]
            })
            .collect();
        let mut bins = vec![Vec::new(); (tiles_x * tiles_y) as usize];
        for (i, r) in ranges.iter().enumerate() {
            for ty in r[1]..=r[3] {
                for tx in r[0]..=r[2] {
                    bins[(ty * tiles_x + tx) as usize].push(i as u32);
                }
            }
        }
        bins
    }

    /// The premultiplied MSAA resolve of the scene, row-major.
    pub fn raster(s: &Scene) -> Vec<[f32; 4]> {
        match s.cfg.samples {
            1 => raster_n::<1>(s),
            _ => raster_n::<4>(s),
        }
    }

    fn raster_n<const N: usize>(s: &Scene) -> Vec<[f32; 4]> {
        let (w, h) = (s.cfg.width, s.cfg.height);
        let (tiles_x, tiles_y) = (w.div_ceil(TILE), h.div_ceil(TILE));
        let half = s.cfg.half_width;
        let seg_bins = bin(
            &s.segs
                .par_iter()
                .map(|q| seg_bounds(q, half))
                .collect::<Vec<_>>(),
            tiles_x,
            tiles_y,
        );
        let tri_bins = bin(
            &s.tris.par_iter().map(tri_bounds).collect::<Vec<_>>(),
            tiles_x,
            tiles_y,
        );
        let tiles: Vec<Vec<[f32; 4]>> = (0..tiles_x * tiles_y)
            .into_par_iter()
            .map(|t| {
                let i = t as usize;
                tile::<N>(s, t % tiles_x, t / tiles_x, &tri_bins[i], &seg_bins[i])
            })
            .collect();
        let mut img = vec![[0.0f32; 4]; w as usize * h as usize];
        for (t, px) in tiles.iter().enumerate() {
            let t = t as u32;
            let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
            let tw = TILE.min(w - x0) as usize;
            for (ly, row) in px.chunks(tw).enumerate() {
                let o = (y0 as usize + ly) * w as usize + x0 as usize;
                img[o..o + tw].copy_from_slice(row);
            }
        }
        img
    }

    fn tile<const N: usize>(
        s: &Scene,
        tx: u32,
        ty: u32,
        tris: &[u32],
        segs: &[u32],
    ) -> Vec<[f32; 4]> {
        let cfg = &s.cfg;
        let (x0, y0) = ((tx * TILE) as i32, (ty * TILE) as i32);
        let tw = (TILE as i32).min(cfg.width as i32 - x0);
        let th = (TILE as i32).min(cfg.height as i32 - y0);
        let npx = (tw * th) as usize;
        let mut buf = TileBuf::<N> {
            x0,
            y0,
            w: tw,
            h: th,
            color: Vec::with_capacity(npx),
            depth: Vec::with_capacity(npx),
        };
        match &s.background {
            Some(bg) => {
                for ly in 0..th {
                    let o = ((y0 + ly) as usize) * cfg.width as usize + x0 as usize;
                    buf.color
                        .extend(bg[o..o + tw as usize].iter().map(|&c| [c; N]));
                }
            }
            None => buf.color.resize(npx, [[0.0; 4]; N]),
        }
        buf.depth.resize(npx, [1.0; N]);
        let offs = sample_offsets::<N>();
        let fb = Fb::new(cfg);
        if let Some(tex) = &s.texture {
            for &i in tris {
                mesh_tri(&mut buf, &s.tris[i as usize], tex, &fb, &offs);
            }
        }
        for &i in segs {
            strand_quad(
                &mut buf,
                &s.segs[i as usize],
                cfg,
                s.photo.as_ref().filter(|_| cfg.photo != 0),
                &fb,
                &offs,
            );
        }
        // Resolve: f16 samples (the target format), f32 mean, f16 result, as lavapipe.
        let inv = 1.0 / N as f32;
        buf.color
            .iter()
            .map(|px| {
                let mut acc = [0.0f32; 4];
                for c in px {
                    for k in 0..4 {
                        acc[k] += f16_store(c[k]);
                    }
                }
                acc.map(|v| f16_store(v * inv))
            })
            .collect()
    }

    type Offsets<const N: usize> = ([[i64; 2]; N], [[f64; 2]; N]);

    fn mesh_tri<const N: usize>(
        buf: &mut TileBuf<N>,
        t: &TriRec,
        tex: &Texture,
        fb: &Fb,
        offs: &Offsets<N>,
    ) {
        let corners = [t.a, t.b, t.c];
        let fl = corners.map(|q| fb.map([q[0], q[1]]));
        let fx = fl.map(|p| p.map(snap));
        let Some(tri) = Poly::<3, N>::new(fx, true, &offs.0) else {
            return;
        };
        let Some((lx0, ly0, lx1, ly1)) = buf.clip(tri.bbox) else {
            return;
        };
        let bary = Bary::new(fl);
        let zp = bary.plane(corners.map(|q| q[2]));
        let z_off = zp.offsets(&offs.1);
        let (us, vs) = (corners.map(|q| q[3]), [t.v[0], t.v[1], t.v[2]]);
        let step = tri.step();
        for ly in ly0..=ly1 {
            let py = buf.y0 + ly;
            let mut e = tri.edges(buf.x0 + lx0, py);
            for lx in lx0..=lx1 {
                let px = buf.x0 + lx;
                let cov = tri.mask(&e);
                for k in 0..3 {
                    e[k] += step[k];
                }
                if cov == 0 {
                    continue;
                }
                let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
                let uv = [
                    bary.interp(us, cx, cy) as f32,
                    bary.interp(vs, cx, cy) as f32,
                ];
                let c = sample_bilinear(tex, uv);
                let z = zp.samples(px, py, &z_off);
                buf.write(lx, ly, cov, [c[0], c[1], c[2], 1.0], z);
            }
        }
    }

    /// What a covered strand pixel needs once its raster coverage is known.
    struct Shade<'a, const N: usize> {
        p0: [f32; 2],
        d: [f32; 2],
        inv_len2: f32,
        c0: [f32; 4],
        c1: [f32; 4],
        strand: u32,
        zp: Plane,
        z_off: [f64; N],
        /// Photo colour: the photo, o0, o1 - o0, n_o, the screen normal n / h² (so that
        /// (c - p0)·it is the signed width fraction), the mode and the HSV settings.
        photo: Option<PhotoShade<'a>>,
    }

    struct PhotoShade<'a> {
        tex: &'a Texture,
        o0: [f32; 2],
        od: [f32; 2],
        on: [f32; 2],
        nl: [f32; 2],
        hsv: Option<[f32; 3]>,
    }

    impl<const N: usize> Shade<'_, N> {
        #[inline(always)]
        fn pixel(&self, buf: &mut TileBuf<N>, lx: i32, ly: i32, cov: u32) {
            let n = N as u32;
            let (px, py) = (buf.x0 + lx, buf.y0 + ly);
            // Colour at the pixel centre: position along the segment, clamped.
            let (cx, cy) = (px as f32 + 0.5, py as f32 + 0.5);
            let (rx, ry) = (cx - self.p0[0], cy - self.p0[1]);
            let t_raw = (rx * self.d[0] + ry * self.d[1]) * self.inv_len2;
            let t = t_raw.clamp(0.0, 1.0);
            let mut col: [f32; 4] =
                std::array::from_fn(|k| self.c0[k] * (1.0 - t) + self.c1[k] * t);
            if let Some(ph) = &self.photo {
                let l = rx * ph.nl[0] + ry * ph.nl[1];
                let o: [f32; 2] =
                    std::array::from_fn(|k| ph.o0[k] + ph.od[k] * t_raw + ph.on[k] * l);
                let p = bilinear_at(ph.tex, o[0] - 0.5, o[1] - 0.5);
                let p = [p[0], p[1], p[2]].map(|v| v.clamp(0.0, 1.0));
                let p = match ph.hsv {
                    Some([hue, sat, val]) => crate::render::shade::hsv_adjust(p, hue, sat, val),
                    None => p,
                };
                for k in 0..3 {
                    col[k] = (p[k] + col[k]).clamp(0.0, 1.0);
                }
            }
            // Alpha-to-coverage (see the WGSL): keep floor(alpha·N + 0.5) samples.
            let k = (col[3].clamp(0.0, 1.0) * n as f32 + 0.5) as u32;
            let r = (px as u32)
                .wrapping_add(2u32.wrapping_mul(py as u32))
                .wrapping_add(self.strand)
                & (n - 1);
            let mask = cov & a2c_mask(n, r, k);
            if mask != 0 {
                let z = self.zp.samples(px, py, &self.z_off);
                buf.write(lx, ly, mask, [col[0], col[1], col[2], 1.0], z);
            }
        }
    }

    /// Rasterises the pixels of `pieces` (convex polygons whose coverage masks are OR-ed)
    /// inside `bbox`, shading the covered tile pixels.
    #[allow(clippy::too_many_arguments)]
    fn scan<const E: usize, const N: usize>(
        buf: &mut TileBuf<N>,
        pieces: &[Poly<E, N>],
        bbox: [i32; 4],
        rows: (i32, i32),
        cols: (i32, i32),
        span: &impl Fn(i32) -> Option<(i32, i32)>,
        shade: &Shade<N>,
    ) {
        // Polygons up to 64 px a side keep every edge value at their pixels within ±2^31
        // (|a|, |b| <= 64·256 and offsets <= 66·256 from the edge), so the hot loop runs in
        // i32, 4 samples per SIMD compare.
        let narrow = bbox[2] - bbox[0] <= 64 && bbox[3] - bbox[1] <= 64;
        let np = pieces.len().min(2);
        let small: [([[i32; N]; E], [i32; E]); 2] =
            [0, 1].map(|i| pieces.get(i).map_or(([[0; N]; E], [0; E]), |p| p.narrow()));
        for ly in rows.0..=rows.1 {
            let py = buf.y0 + ly;
            let Some((sx0, sx1)) = span(py) else {
                continue;
            };
            let lx0 = cols.0.max(sx0 - buf.x0);
            let lx1 = cols.1.min(sx1 - buf.x0);
            if lx0 > lx1 {
                continue;
            }
            let px0 = buf.x0 + lx0;
            if narrow {
                let mut e: [[i32; E]; 2] = [0, 1].map(|i| {
                    pieces
                        .get(i)
                        .map_or([0; E], |p| p.edges(px0, py).map(|v| v as i32))
                });
                for lx in lx0..=lx1 {
                    let mut cov = 0;
                    for (i, (so, st)) in small[..np].iter().enumerate() {
                        cov |= mask32(&e[i], so);
                        for k in 0..E {
                            e[i][k] = e[i][k].wrapping_add(st[k]);
                        }
                    }
                    if cov != 0 {
                        shade.pixel(buf, lx, ly, cov);
                    }
                }
            } else {
                let mut e: [[i64; E]; 2] =
                    [0, 1].map(|i| pieces.get(i).map_or([0; E], |p| p.edges(px0, py)));
                for lx in lx0..=lx1 {
                    let mut cov = 0;
                    for (i, p) in pieces.iter().enumerate() {
                        cov |= p.mask(&e[i]);
                        let st = p.step();
                        for k in 0..E {
                            e[i][k] += st[k];
                        }
                    }
                    if cov != 0 {
                        shade.pixel(buf, lx, ly, cov);
                    }
                }
            }
        }
    }

    fn strand_quad<const N: usize>(
        buf: &mut TileBuf<N>,
        s: &SegRec,
        cfg: &Config,
        photo: Option<&Texture>,
        fb: &Fb,
        offs: &Offsets<N>,
    ) {
        // The vertex shader's corner construction, operation for operation.
        let h = cfg.half_width;
        let d = [s.p1[0] - s.p0[0], s.p1[1] - s.p0[1]];
        let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
        let u = [d[0] / len, d[1] / len];
        let e = [u[0] * h, u[1] * h];
        let nn = [-u[1] * h, u[0] * h];
        let start = [s.p0[0] - e[0], s.p0[1] - e[1]];
        let end = [s.p1[0] + e[0], s.p1[1] + e[1]];
        let plus = |p: [f32; 2]| [p[0] + nn[0], p[1] + nn[1]];
        let minus = |p: [f32; 2]| [p[0] - nn[0], p[1] - nn[1]];
        // A, B, C, D = start+, start-, end+, end-; the GPU draws triangles ABC and CBD.
        let fx = [plus(start), minus(start), plus(end), minus(end)].map(|p| fb.map(p).map(snap));
        let [qa, qb, qc, qd] = fx;
        let bbox = fx
            .iter()
            .fold([i32::MAX, i32::MAX, i32::MIN, i32::MIN], |m, p| {
                let (x, y) = (p[0].div_euclid(256) as i32, p[1].div_euclid(256) as i32);
                [m[0].min(x), m[1].min(y), m[2].max(x), m[3].max(y)]
            });
        let Some((lx_min, ly0, lx_max, ly1)) = buf.clip(bbox) else {
            return;
        };
        // Depth: one plane over the quad, z0 along the start cap's edge to z1 along the end
        // cap's edge (what the GPU interpolates from the corners), in screen px.
        let (gz, zl) = ((s.z1 - s.z0) as f64, (len + 2.0 * h) as f64);
        let (ux, uy) = (u[0] as f64 * gz / zl, u[1] as f64 * gz / zl);
        let zp = Plane {
            c: s.z0 as f64 - ux * start[0] as f64 - uy * start[1] as f64,
            gx: ux,
            gy: uy,
        };
        let z_off = zp.offsets(&offs.1);
        // Row spans from the two long sides A->C and B->D: when both run the same way in y,
        // every point of the quad lies between them, so a row's columns are bounded by the
        // sides' x at the row's top and bottom. Otherwise (sides near horizontal, where
        // snapping may tilt them apart) the bounding box is used.
        let to_px = |q: [i64; 2]| q.map(|v| v as f64 / SUBPIXEL as f64);
        let (a, b, c, dd) = (to_px(qa), to_px(qb), to_px(qc), to_px(qd));
        let (dy_ac, dy_bd) = (qc[1] - qa[1], qd[1] - qb[1]);
        let by_sides = (dy_ac > 0 && dy_bd > 0) || (dy_ac < 0 && dy_bd < 0);
        let (sl_ac, sl_bd) = (
            (c[0] - a[0]) / (c[1] - a[1]),
            (dd[0] - b[0]) / (dd[1] - b[1]),
        );
        let span = |py: i32| -> Option<(i32, i32)> {
            if !by_sides {
                return Some((bbox[0], bbox[2]));
            }
            let (y0, y1) = (py as f64, py as f64 + 1.0);
            let xs = [
                a[0] + sl_ac * (y0 - a[1]),
                a[0] + sl_ac * (y1 - a[1]),
                b[0] + sl_bd * (y0 - b[1]),
                b[0] + sl_bd * (y1 - b[1]),
            ];
            let lo = xs
                .iter()
                .fold(f64::INFINITY, |m, &v| if v < m { v } else { m });
            let hi = xs
                .iter()
                .fold(f64::NEG_INFINITY, |m, &v| if v > m { v } else { m });
            Some((
                floor_i32(lo.max(bbox[0] as f64) - 1e-6),
                floor_i32(hi.min(bbox[2] as f64 + 1.0) + 1e-6),
            ))
        };
        let shade = Shade {
            p0: s.p0,
            d,
            inv_len2: 1.0 / (len * len),
            c0: s.c0,
            c1: s.c1,
            strand: s.strand,
            zp,
            z_off,
            photo: photo.map(|tex| {
                let o0 = [s.o[0], s.o[1]];
                let od = [s.o[2] - s.o[0], s.o[3] - s.o[1]];
                let ol = (od[0] * od[0] + od[1] * od[1]).sqrt();
                let hp = cfg.photo_half_width;
                let on = if ol > 1e-6 {
                    [-od[1] / ol * hp, od[0] / ol * hp]
                } else {
                    [0.0; 2]
                };
                PhotoShade {
                    tex,
                    o0,
                    od,
                    on,
                    nl: [nn[0] / (h * h), nn[1] / (h * h)],
                    hsv: (cfg.photo == 2).then_some([cfg.hue_deg, cfg.saturation, cfg.value]),
                }
            }),
        };
        let (rows, cols) = ((ly0, ly1), (lx_min, lx_max));
        // The quad A C D B as one convex polygon covers exactly the samples of ABC ∪ CBD:
        // the top-left rule equals nudging a sample by (ε, ε²) and testing strictly, and the
        // nudged sample never lies on the diagonal, so it is in the quad iff it is in one of
        // the triangles. That needs a convex quad; snapping can break it for very thin quads,
        // and then the two triangles are used.
        let convex = {
            let ring = [qa, qc, qd, qb];
            let turns: [i64; 4] = std::array::from_fn(|k| {
                let (p, q, r) = (ring[k], ring[(k + 1) % 4], ring[(k + 2) % 4]);
                (q[0] - p[0]) * (r[1] - q[1]) - (q[1] - p[1]) * (r[0] - q[0])
            });
            turns.iter().all(|&t| t > 0) || turns.iter().all(|&t| t < 0)
        };
        if convex {
            if let Some(quad) = Poly::<4, N>::new([qa, qc, qd, qb], false, &offs.0) {
                scan(buf, &[quad], bbox, rows, cols, &span, &shade);
            }
        } else {
            let tris: Vec<Poly<3, N>> = [[qa, qb, qc], [qc, qb, qd]]
                .into_iter()
                .filter_map(|t| Poly::new(t, false, &offs.0))
                .collect();
            scan(buf, &tris, bbox, rows, cols, &span, &shade);
        }
    }
}
