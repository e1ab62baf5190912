// Strand rasteriser (C13 §4): every segment (p_k, p_k+1) of a strand is drawn as a
// screen-aligned quad `strand_width` px across, extended by half a width past both ends so
// that the quads of consecutive segments overlap at bends (no gaps, no joins needed).
// Vertex pulling: one instance per segment, drawn as a 4-vertex triangle strip (corners
// A B C D: triangles ABC and BDC, the same two as CBD); the host has already
// dropped non-finite, zero-length and invisible segments and clipped long ones to a guard
// band, so nothing here needs a NaN test. Depth-tested (Less, written), no sorting.
//
// Alpha-to-coverage is done HERE, not by the pipeline: hardware A2C maps alpha to a sample
// mask in an implementation-defined way (dithered or not, per driver), which would make
// golden images depend on the GPU. Rule (mirrored in `strand_raster.rs`): k =
// floor(alpha·N + 0.5) samples are kept, taken in the order r, r+1, ... (mod N) with the
// per-pixel, per-strand rotation r = (x + 2·y + strand) mod N. Colour is per pixel (evaluated at the pixel centre),
// coverage and depth per sample.
//
// Photo colour (cfg.photo != 0): the corners also get photo points built like the screen
// corners around the ends' photo points o0, o1; the fragment samples the photo (bilinear,
// clamp-to-edge, by hand as `mesh_raster.wgsl`) at its interpolated point, HSV-adjusts it
// when cfg.photo == 2, and adds the vertex colour (an offset). At the photo's own view the
// point is the pixel centre, so covered hair shows the photo itself.
//
// Mirrored by `src/stages/strand_raster.rs` (`strand_quad`): keep the arithmetic below in
// step with it.

#include "shared/raster_common.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> segs: array<Seg>;
@group(0) @binding(2) var photo: texture_2d<f32>;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    // Position along the segment (0 at p0, 1 at p1), affine in screen space.
    @location(0) @interpolate(linear) t: f32,
    @location(1) @interpolate(flat) c0: vec4<f32>,
    @location(2) @interpolate(flat) c1: vec4<f32>,
    @location(3) @interpolate(flat) strand: u32,
    @location(4) @interpolate(linear) o: vec2<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) k: u32, @builtin(instance_index) seg: u32) -> VsOut {
    let s = segs[seg];
    // Corners k = 0..3: A = (start, +n), B = (start, -n), C = (end, +n), D = (end, -n); the
    // strip makes triangles ABC and BDC.
    let at_end = k >= 2u;
    let plus = (k & 1u) == 0u;
    let h = cfg.half_width;
    let d = s.p1 - s.p0;
    let len = sqrt(d.x * d.x + d.y * d.y);
    let u = d / len;
    let e = u * h;
    let n = vec2<f32>(-u.y, u.x) * h;
    let base = select(s.p0 - e, s.p1 + e, at_end);
    let p = select(base - n, base + n, plus);
    // Depth is constant across the width and along each end cap's extension, so the quad is
    // one plane and a steep short segment never extrapolates its depth.
    let z = select(s.z0, s.z1, at_end);
    var out: VsOut;
    out.pos = vec4<f32>(p.x * cfg.ndc_scale_x - 1.0, 1.0 - p.y * cfg.ndc_scale_y, z, 1.0);
    out.t = select(-h / len, 1.0 + h / len, at_end);
    out.o = vec2<f32>(0.0);
    if cfg.photo != 0u {
        let od = s.o.zw - s.o.xy;
        let ol = sqrt(od.x * od.x + od.y * od.y);
        var on = vec2<f32>(0.0);
        if ol > 1e-6 {
            on = vec2<f32>(-od.y / ol, od.x / ol) * cfg.photo_half_width;
        }
        out.o = s.o.xy + od * out.t + select(-on, on, plus);
    }
    out.c0 = s.c0;
    out.c1 = s.c1;
    out.strand = s.strand;
    return out;
}

struct FsOut {
    @location(0) color: vec4<f32>,
    @builtin(sample_mask) mask: u32,
}

fn texel(i: i32, j: i32, dims: vec2<i32>) -> vec4<f32> {
    return textureLoad(photo, vec2<i32>(clamp(i, 0, dims.x - 1), clamp(j, 0, dims.y - 1)), 0);
}

// Bilinear at photo px `o` (texel centres at +0.5), as `raster_common.rs` `bilinear_at`.
fn photo_at(o: vec2<f32>) -> vec3<f32> {
    let dims = vec2<i32>(textureDimensions(photo));
    let s = o.x - 0.5;
    let t = o.y - 0.5;
    let fs = floor(s);
    let ft = floor(t);
    let ax = s - fs;
    let ay = t - ft;
    let i = i32(fs);
    let j = i32(ft);
    let top = mix(texel(i, j, dims), texel(i + 1, j, dims), ax);
    let bottom = mix(texel(i, j + 1, dims), texel(i + 1, j + 1, dims), ax);
    return mix(top, bottom, ay).rgb;
}

// The HSV adjustment shared with `strand_shade.wgsl` (and `colour::hsv_adjust`).
#include "shared/colour.wgsl"

@fragment
fn fs_main(in: VsOut) -> FsOut {
    var c = mix(in.c0, in.c1, clamp(in.t, 0.0, 1.0));
    if cfg.photo != 0u {
        var p = clamp(photo_at(in.o), vec3<f32>(0.0), vec3<f32>(1.0));
        if cfg.photo == 2u {
            p = hsv_adjust_linear(p, cfg.hue_deg, cfg.saturation, cfg.value);
        }
        c = vec4<f32>(clamp(p + c.rgb, vec3<f32>(0.0), vec3<f32>(1.0)), c.a);
    }
    let n = cfg.samples;
    let k = u32(floor(clamp(c.a, 0.0, 1.0) * f32(n) + 0.5));
    if k == 0u {
        discard;
    }
    // in.pos.xy is the pixel centre (no per-sample shading), so this is the pixel index.
    let px = vec2<u32>(in.pos.xy);
    let r = (px.x + 2u * px.y + in.strand) % n;
    var mask = 0u;
    for (var i = 0u; i < k; i++) {
        mask |= 1u << ((r + i) % n);
    }
    var out: FsOut;
    // Each covered sample becomes opaque strand colour; the resolve averages the samples.
    out.color = vec4<f32>(c.rgb, 1.0);
    out.mask = mask;
    return out;
}
