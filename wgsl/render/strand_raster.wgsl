// Strand rasteriser (C13 §4): every segment (p_k, p_k+1) of a strand is drawn as a
// screen-aligned quad `strand_width` px across, extended by half a width past both ends so
// that the quads of consecutive segments overlap at bends (no gaps, no joins needed).
// Vertex pulling: 6 vertices per segment, segment = vertex_index / 6; the host has already
// dropped non-finite, zero-length and invisible segments and clipped long ones to a guard
// band, so nothing here needs a NaN test. Depth-tested (Less, written), no sorting.
//
// Alpha-to-coverage is done HERE, not by the pipeline: hardware A2C maps alpha to a sample
// mask in an implementation-defined way (dithered or not, per driver), which would make
// golden images depend on the GPU. Rule (mirrored in `raster.rs`): k = floor(alpha·N + 0.5)
// samples are kept, taken in the order r, r+1, ... (mod N) with the per-pixel, per-strand
// rotation r = (x + 2·y + strand) mod N. Colour is per pixel (evaluated at the pixel centre),
// coverage and depth per sample.
//
// Mirrored by `raster.rs` (`cpu_quad`): keep the arithmetic below in step with it.

struct Config {
    width: u32,
    height: u32,
    samples: u32,
    half_width: f32,
    // 2 / width and 2 / height: screen px -> NDC.
    ndc_scale_x: f32,
    ndc_scale_y: f32,
    _pad0: u32,
    _pad1: u32,
}

// Host-prepared segment (`SegRec`): screen px, depth already mapped to [0, 1] (0 = near).
struct Seg {
    p0: vec2<f32>,
    p1: vec2<f32>,
    z0: f32,
    z1: f32,
    strand: u32,
    _pad: u32,
    c0: vec4<f32>,
    c1: vec4<f32>,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> segs: array<Seg>;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    // Position along the segment (0 at p0, 1 at p1), affine in screen space.
    @location(0) @interpolate(linear) t: f32,
    @location(1) @interpolate(flat) c0: vec4<f32>,
    @location(2) @interpolate(flat) c1: vec4<f32>,
    @location(3) @interpolate(flat) strand: u32,
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VsOut {
    let s = segs[vi / 6u];
    // Corners A = (start, +n), B = (start, -n), C = (end, +n), D = (end, -n); triangles ABC, CBD.
    let k = vi % 6u;
    let at_end = k == 2u || k == 3u || k == 5u;
    let plus = k == 0u || k == 2u || k == 3u;
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
    out.c0 = s.c0;
    out.c1 = s.c1;
    out.strand = s.strand;
    return out;
}

struct FsOut {
    @location(0) color: vec4<f32>,
    @builtin(sample_mask) mask: u32,
}

@fragment
fn fs_main(in: VsOut) -> FsOut {
    let c = mix(in.c0, in.c1, clamp(in.t, 0.0, 1.0));
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
