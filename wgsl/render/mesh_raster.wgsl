// Textured head mesh and background for the strand renderer (C13 §4), drawn before the
// strands into the same multisampled target.
//
// Mesh: host-prepared triangles (`TriRec`, non-indexed, vertex pulling), depth test Less +
// write, back faces culled (front = counter-clockwise in NDC, i.e. counter-clockwise as the
// image is viewed). Texture: bilinear with clamp-to-edge done by hand with textureLoad, so
// the weights are full f32 and the CPU mirror (`src/stages/mesh_raster.rs`, `sample_bilinear`) reproduces
// them; hardware filtering may use as few as 8 fractional bits. Texel (i, j) has its centre
// at uv ((i + 0.5) / W, (j + 0.5) / H), row 0 at v = 0. Texel alpha is coverage, not blending: the
// fragment keeps `coverage_mask(alpha)` of its samples, so a texture can cut the mesh's outline along its own pixels, anti-aliased like a triangle
// edge, and what the mesh keeps stays opaque and depth-tested.
//
// Background: one full-screen triangle copies the pixel's (premultiplied) background colour
// into every sample, without touching depth.

#include "shared/raster_common.wgsl"

// Corner k is (x, y, depth in [0, 1], u) in screen px; `v` holds the three v coordinates.
struct Tri {
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
    v: vec4<f32>,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> tris: array<Tri>;
@group(0) @binding(2) var tex: texture_2d<f32>;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) @interpolate(linear) uv: vec2<f32>,
}

@vertex
fn vs_mesh(@builtin(vertex_index) vi: u32) -> VsOut {
    let t = tris[vi / 3u];
    let k = vi % 3u;
    let q = select(select(t.a, t.b, k == 1u), t.c, k == 2u);
    let v = select(select(t.v.x, t.v.y, k == 1u), t.v.z, k == 2u);
    var out: VsOut;
    out.pos = vec4<f32>(q.x * cfg.ndc_scale_x - 1.0, 1.0 - q.y * cfg.ndc_scale_y, q.z, 1.0);
    out.uv = vec2<f32>(q.w, v);
    return out;
}

fn texel(i: i32, j: i32, dims: vec2<i32>) -> vec4<f32> {
    return textureLoad(tex, vec2<i32>(clamp(i, 0, dims.x - 1), clamp(j, 0, dims.y - 1)), 0);
}

// The samples a fragment keeps for texture alpha `a`, by the strands' alpha-to-coverage rule
// (`strand_raster.wgsl`) without the strand term: k = floor(a·N + 0.5) samples from
// r = (x + 2·y) mod N on, so a soft edge becomes a dithered, anti-aliased one.
fn coverage_mask(a: f32, px: vec2<u32>) -> u32 {
    let n = cfg.samples;
    let k = u32(floor(clamp(a, 0.0, 1.0) * f32(n) + 0.5));
    let r = (px.x + 2u * px.y) % n;
    var mask = 0u;
    for (var i = 0u; i < k; i++) {
        mask |= 1u << ((r + i) % n);
    }
    return mask;
}

struct MeshOut {
    @location(0) colour: vec4<f32>,
    @builtin(sample_mask) mask: u32,
}

@fragment
fn fs_mesh(in: VsOut) -> MeshOut {
    let dims = vec2<i32>(textureDimensions(tex));
    let s = in.uv.x * f32(dims.x) - 0.5;
    let t = in.uv.y * f32(dims.y) - 0.5;
    let fs = floor(s);
    let ft = floor(t);
    let ax = s - fs;
    let ay = t - ft;
    let i = i32(fs);
    let j = i32(ft);
    let top = mix(texel(i, j, dims), texel(i + 1, j, dims), ax);
    let bottom = mix(texel(i, j + 1, dims), texel(i + 1, j + 1, dims), ax);
    let c = mix(top, bottom, ay);
    // in.pos.xy is the pixel centre (no per-sample shading), so this is the pixel index.
    return MeshOut(vec4<f32>(c.rgb, 1.0), coverage_mask(c.a, vec2<u32>(in.pos.xy)));
}

@vertex
fn vs_background(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the whole viewport.
    let x = f32(i32(vi & 1u) * 4 - 1);
    let y = f32(i32(vi >> 1u) * 4 - 1);
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn fs_background(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    return textureLoad(tex, vec2<i32>(pos.xy), 0);
}
