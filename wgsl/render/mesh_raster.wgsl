// Textured head mesh and background for the strand renderer (C13 §4), drawn before the
// strands into the same multisampled target.
//
// Mesh: host-prepared triangles (`TriRec`, non-indexed, vertex pulling), depth test Less +
// write, back faces culled (front = counter-clockwise in NDC, i.e. counter-clockwise as the
// image is viewed). Texture: bilinear with clamp-to-edge done by hand with textureLoad, so
// the weights are full f32 and the CPU mirror (`src/stages/mesh_raster.rs`, `sample_bilinear`) reproduces
// them; hardware filtering may use as few as 8 fractional bits. Texel (i, j) has its centre
// at uv ((i + 0.5) / W, (j + 0.5) / H), row 0 at v = 0. The mesh is opaque: texel alpha is
// ignored.
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

@fragment
fn fs_mesh(in: VsOut) -> @location(0) vec4<f32> {
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
    return vec4<f32>(c.rgb, 1.0);
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
