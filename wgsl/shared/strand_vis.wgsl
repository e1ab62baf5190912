// What the two compute strand rasterisers share (`render/strand_vis.wgsl`, whose header
// gives the passes and why, and `render/strand_vis64.wgsl`): the bindings both declare, the
// quad of a segment and its walk over the pixels, the colour and the resolve. The including
// shader declares the visibility buffers and defines `visit` (what a walk does at a pixel)
// and `holders` (who holds a pixel's four samples: !index, 0 for none).
//
// Coverage is the CPU mirror's (`src/stages/strand_raster.rs`, `strand_quad`): corners
// snapped to 1/256 px, edge functions with the top-left rule evaluated in wrapping i32
// (exact: at the samples a row span visits the true values fit in i32), the quad as one
// convex polygon or, when snapping made it non-convex, as its two triangles; row spans from
// the two long sides. Depth is the same plane in f32 rather than f64 (an ulp apart at most).

#include "shared/raster_common.wgsl"
#include "shared/colour.wgsl"

// One chunk of segments: global index of its first, its count, and invocations per row of
// the dispatch (a chunk may need more than 65535 workgroups in x).
struct Chunk {
    base: u32,
    count: u32,
    row: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> segs: array<Seg>;
@group(0) @binding(2) var photo: texture_2d<f32>;
@group(0) @binding(3) var<uniform> chunk: Chunk;
// Per sample: strand colour as f16 (r, g), (b, 1).
@group(0) @binding(6) var<storage, read_write> cbuf: array<vec2<u32>>;
@group(0) @binding(7) var msaa_color: texture_multisampled_2d<f32>;
@group(0) @binding(8) var msaa_depth: texture_depth_multisampled_2d;
// Per pixel: the resolve, f16 RGBA as (r, g), (b, a).
@group(0) @binding(9) var<storage, read_write> resolved: array<vec2<u32>>;
// Per segment of the chunk, in input order: where the host put it in `segs`.
@group(0) @binding(11) var<storage, read> position: array<u32>;

// Vulkan's standard 4x sample positions, in 1/256 px and in px (`SAMPLE_POSITIONS_4`).
const OFF_I = array<vec2<i32>, 4>(
    vec2<i32>(96, 32), vec2<i32>(224, 96), vec2<i32>(32, 160), vec2<i32>(160, 224)
);
const OFF_F = array<vec2<f32>, 4>(
    vec2<f32>(0.375, 0.125), vec2<f32>(0.875, 0.375), vec2<f32>(0.125, 0.625),
    vec2<f32>(0.625, 0.875)
);

// --- the depth key and the quad walk -------------------------------------------------------

// The depth's bits, which order as the values for z in [0, 1] (-0 taken as +0).
fn key(z: f32) -> u32 {
    return select(bitcast<u32>(z), 0u, z == 0.0);
}

// Whether a mesh was drawn into the depth target; without one every depth is the clear
// value, 1, and `zinit` need not read the multisampled target (a texel fetch per sample is
// dear on a CPU driver).
override mesh_drawn: bool = true;

// The keys of the mesh (or nothing) at the four samples of pixel xy: 2·bits(depth), even.
fn mesh_keys(xy: vec2<u32>) -> vec4<u32> {
    if !mesh_drawn {
        return vec4<u32>(key(1.0) * 2u);
    }
    var z: vec4<u32>;
    for (var s = 0u; s < 4u; s++) {
        z[s] = key(textureLoad(msaa_depth, vec2<i32>(xy), i32(s))) * 2u;
    }
    return z;
}

// Screen px -> framebuffer px through NDC and the viewport, as `raster_common.rs` `Fb::map`.
fn fb_map(p: vec2<f32>) -> vec2<f32> {
    let hw = f32(cfg.width) * 0.5;
    let hh = f32(cfg.height) * 0.5;
    let nx = p.x * cfg.ndc_scale_x - 1.0;
    let ny = 1.0 - p.y * cfg.ndc_scale_y;
    return vec2<f32>(nx * hw + hw, ny * -hh + hh);
}

// To the 1/256 px grid, ties to even (WGSL's round), as the rasteriser snaps.
fn snap(p: vec2<f32>) -> vec2<i32> {
    return vec2<i32>(round(p * 256.0));
}

// Sign of u.x·v.y − u.y·v.x, exact for components below 2^24 in magnitude (65536 px; the
// host keeps frames far inside that): each product split at 2^12 into parts whose sums fit
// i32, then the carries propagated.
fn cross_sign(u: vec2<i32>, v: vec2<i32>) -> i32 {
    let uh = u >> vec2<u32>(12u);
    let ul = u & vec2<i32>(4095);
    let vh = v >> vec2<u32>(12u);
    let vl = v & vec2<i32>(4095);
    // u.x·v.y − u.y·v.x = hi·2^24 + mid·2^12 + lo.
    let hi = uh.x * vh.y - uh.y * vh.x;
    let mid = uh.x * vl.y + ul.x * vh.y - uh.y * vl.x - ul.y * vh.x;
    let lo = ul.x * vl.y - ul.y * vl.x;
    let m = mid + (lo >> 12u);
    let h = hi + (m >> 12u);
    if h != 0 {
        return sign(h);
    }
    return select(0, 1, (m & 4095) != 0 || (lo & 4095) != 0);
}

// Edge functions of a convex polygon: inside when a·X + b·Y + c >= 0 at every edge
// (X, Y in 1/256 px), the top-left rule folded into c. Up to 4 edges; unused ones are
// always inside (a = b = 0, c = 0).
struct Edges {
    a: vec4<i32>,
    b: vec4<i32>,
    c: vec4<i32>,
}

// Edge k from p to q walked with the interior on its positive side (`Poly::new`).
fn edge(p: vec2<i32>, q: vec2<i32>) -> vec3<i32> {
    let dx = q.x - p.x;
    let dy = q.y - p.y;
    let a = -dy;
    let b = dx;
    let top_left = dy < 0 || (dy == 0 && dx > 0);
    return vec3<i32>(a, b, -(a * p.x + b * p.y) - select(1, 0, top_left));
}

fn dir_edge(p: vec2<i32>, q: vec2<i32>, forward: bool) -> vec3<i32> {
    if forward {
        return edge(p, q);
    }
    return edge(q, p);
}

fn edges_from(e0: vec3<i32>, e1: vec3<i32>, e2: vec3<i32>, e3: vec3<i32>) -> Edges {
    return Edges(
        vec4<i32>(e0.x, e1.x, e2.x, e3.x),
        vec4<i32>(e0.y, e1.y, e2.y, e3.y),
        vec4<i32>(e0.z, e1.z, e2.z, e3.z),
    );
}

// The convex quad v0 v1 v2 v3 of area sign `area` (nonzero). (No arrays: a CPU driver keeps
// an array a lane indexes in memory.)
fn quad_edges(v0: vec2<i32>, v1: vec2<i32>, v2: vec2<i32>, v3: vec2<i32>, area: i32) -> Edges {
    let f = area > 0;
    return edges_from(dir_edge(v0, v1, f), dir_edge(v1, v2, f), dir_edge(v2, v3, f), dir_edge(v3, v0, f));
}

// The triangle v0 v1 v2; its fourth edge is always inside (0 >= 0).
fn tri_edges(v0: vec2<i32>, v1: vec2<i32>, v2: vec2<i32>, area: i32) -> Edges {
    let f = area > 0;
    return edges_from(dir_edge(v0, v1, f), dir_edge(v1, v2, f), dir_edge(v2, v0, f), vec3<i32>(0));
}

// Per sample s, a·ox + b·oy of every edge: what a pixel corner's edge values get added.
struct Offs {
    s0: vec4<i32>,
    s1: vec4<i32>,
    s2: vec4<i32>,
    s3: vec4<i32>,
}

fn offs_of(e: Edges) -> Offs {
    return Offs(
        e.a * OFF_I[0].x + e.b * OFF_I[0].y,
        e.a * OFF_I[1].x + e.b * OFF_I[1].y,
        e.a * OFF_I[2].x + e.b * OFF_I[2].y,
        e.a * OFF_I[3].x + e.b * OFF_I[3].y,
    );
}

// Coverage bits of the four samples of the pixel whose corner's edge values are `base`.
fn cover(base: vec4<i32>, o: Offs) -> u32 {
    let z = vec4<i32>(0);
    return select(0u, 1u, all(base + o.s0 >= z)) | select(0u, 2u, all(base + o.s1 >= z))
        | select(0u, 4u, all(base + o.s2 >= z)) | select(0u, 8u, all(base + o.s3 >= z));
}

// A strand's alpha-to-coverage mask (`a2c_mask`): k samples from r on, mod 4.
fn a2c(r: u32, k: u32) -> u32 {
    let run = (1u << k) - 1u;
    return ((run << r) | (run >> (4u - r))) & 15u;
}

// Walks the quad of segment `slot` of the chunk and hands each pixel with a kept sample to
// the including shader's `visit(p, v, ok, index, pick)`: the pixel, the four samples' keys
// 2·bits(z) + 1, which of them are kept with z in [0, 1], the segment's index, and `pick`
// as given here.
fn walk(slot: u32, pick: bool) {
    let s = segs[slot];
    let index = chunk.base + s.local;
    let h = cfg.half_width;
    let d = s.p1 - s.p0;
    let len = sqrt(d.x * d.x + d.y * d.y);
    let u = d / len;
    let e = u * h;
    let nn = vec2<f32>(-u.y * h, u.x * h);
    let start = s.p0 - e;
    let end = s.p1 + e;
    // A, B, C, D = start+, start-, end+, end- (triangles ABC and CBD).
    let qa = snap(fb_map(start + nn));
    let qb = snap(fb_map(start - nn));
    let qc = snap(fb_map(end + nn));
    let qd = snap(fb_map(end - nn));
    let lo = min(min(qa, qb), min(qc, qd)) >> vec2<u32>(8u);
    let hi = max(max(qa, qb), max(qc, qd)) >> vec2<u32>(8u);
    let x0 = max(lo.x, 0);
    let y0 = max(lo.y, 0);
    let x1 = min(hi.x, i32(cfg.width) - 1);
    let y1 = min(hi.y, i32(cfg.height) - 1);
    if x0 > x1 || y0 > y1 {
        return;
    }
    // The quad A C D B when convex (every turn the same way), else the two triangles.
    // Turns of the ring A C D B.
    let turns = vec4<i32>(
        cross_sign(qc - qa, qd - qc),
        cross_sign(qd - qc, qb - qd),
        cross_sign(qb - qd, qa - qb),
        cross_sign(qa - qb, qc - qa),
    );
    let convex = all(turns > vec4<i32>(0)) || all(turns < vec4<i32>(0));
    var poly0 = Edges(vec4<i32>(0), vec4<i32>(0), vec4<i32>(0));
    var poly1 = poly0;
    var np = 0u;
    if convex {
        poly0 = quad_edges(qa, qc, qd, qb, turns.x);
        np = 1u;
    } else {
        let a0 = cross_sign(qb - qa, qc - qa);
        let a1 = cross_sign(qb - qc, qd - qc);
        if a0 != 0 {
            poly0 = tri_edges(qa, qb, qc, a0);
            np = 1u;
        }
        if a1 != 0 {
            if np == 0u {
                poly0 = tri_edges(qc, qb, qd, a1);
            } else {
                poly1 = tri_edges(qc, qb, qd, a1);
            }
            np += 1u;
        }
    }
    if np == 0u {
        return;
    }
    let o0 = offs_of(poly0);
    let o1 = offs_of(poly1);
    // Edge values one pixel to the right.
    let step0 = poly0.a * 256;
    let step1 = poly1.a * 256;
    // Row spans from the long sides A->C and B->D when both run the same way in y.
    let dy_ac = qc.y - qa.y;
    let dy_bd = qd.y - qb.y;
    let by_sides = (dy_ac > 0 && dy_bd > 0) || (dy_ac < 0 && dy_bd < 0);
    let fa = vec2<f32>(qa) / 256.0;
    let fb = vec2<f32>(qb) / 256.0;
    let fc = vec2<f32>(qc) / 256.0;
    let fd = vec2<f32>(qd) / 256.0;
    let sl_ac = (fc.x - fa.x) / (fc.y - fa.y);
    let sl_bd = (fd.x - fb.x) / (fd.y - fb.y);
    // Depth: one plane, z0 along the start cap's edge to z1 along the end cap's.
    let g = u * ((s.z1 - s.z0) / (len + 2.0 * h));
    var zo: vec4<f32>;
    for (var k = 0u; k < 4u; k++) {
        zo[k] = g.x * OFF_F[k].x + g.y * OFF_F[k].y;
    }
    let inv_len2 = 1.0 / (len * len);
    // One loop over the quad's pixels, row after row, rather than a loop per row: the lanes
    // of a CPU driver's SIMD group then each take their own pixel count, not the most rows
    // among them times the widest row among them (a flat segment beside a steep one).
    var py = y0 - 1;
    var px = 1;
    var cx1 = 0;
    var cy = 0.0;
    var e0 = vec4<i32>(0);
    var e1 = vec4<i32>(0);
    loop {
        if px > cx1 {
            py++;
            if py > y1 {
                break;
            }
            var cx0 = x0;
            cx1 = x1;
            if by_sides {
                let yt = f32(py);
                let yb = f32(py + 1);
                let ta = fa.x + sl_ac * (yt - fa.y);
                let ba = fa.x + sl_ac * (yb - fa.y);
                let tb = fb.x + sl_bd * (yt - fb.y);
                let bb = fb.x + sl_bd * (yb - fb.y);
                let l = min(min(ta, ba), min(tb, bb)) - 0.02;
                let r = max(max(ta, ba), max(tb, bb)) + 0.02;
                cx0 = max(cx0, i32(floor(l)));
                cx1 = min(cx1, i32(floor(r)));
            }
            cy = f32(py) + 0.5;
            // Edge values at the corner of the row's first pixel, stepped right (wrapping).
            e0 = poly0.a * (cx0 * 256) + poly0.b * (py * 256) + poly0.c;
            e1 = poly1.a * (cx0 * 256) + poly1.b * (py * 256) + poly1.c;
            px = cx0;
            if px > cx1 {
                continue;
            }
        }
        var cov = cover(e0, o0);
        if np > 1u {
            cov |= cover(e1, o1);
        }
        let x = px;
        px++;
        e0 += step0;
        e1 += step1;
        if cov == 0u {
            continue;
        }
        let cx = f32(x) + 0.5;
        let t = clamp(((cx - s.p0.x) * d.x + (cy - s.p0.y) * d.y) * inv_len2, 0.0, 1.0);
        let alpha = s.c0.a * (1.0 - t) + s.c1.a * t;
        let k = u32(max(i32(clamp(alpha, 0.0, 1.0) * 4.0 + 0.5), 0));
        let rot = (u32(x) + 2u * u32(py) + s.strand) & 3u;
        let mask = cov & a2c(rot, k);
        if mask == 0u {
            continue;
        }
        let zc = s.z0 + g.x * (f32(x) - start.x) + g.y * (f32(py) - start.y);
        let z = vec4<f32>(zc) + zo;
        let keep = vec4<u32>(mask) & vec4<u32>(1u, 2u, 4u, 8u);
        let ok = (keep != vec4<u32>(0u)) & (z >= vec4<f32>(0.0)) & (z <= vec4<f32>(1.0));
        // 2·bits(z) + 1 (-0 as +0), as `key`.
        let v = select(bitcast<vec4<u32>>(z), vec4<u32>(0u), z == vec4<f32>(0.0)) * 2u + 1u;
        visit(u32(py) * cfg.width + u32(x), v, ok, index, pick);
    }
}

fn seg_index(g: vec3<u32>) -> u32 {
    return g.x + g.y * chunk.row;
}

// --- colour ----------------------------------------------------------------------------

fn texel(i: i32, j: i32, dims: vec2<i32>) -> vec4<f32> {
    return textureLoad(photo, vec2<i32>(clamp(i, 0, dims.x - 1), clamp(j, 0, dims.y - 1)), 0);
}

// Bilinear at photo px `o` (texel centres at +0.5), as `raster_common.rs` `bilinear_at`.
fn photo_at(o: vec2<f32>) -> vec3<f32> {
    let dims = vec2<i32>(textureDimensions(photo));
    let st = o - 0.5;
    let f = floor(st);
    let a = st - f;
    let i = i32(f.x);
    let j = i32(f.y);
    let top = mix(texel(i, j, dims), texel(i + 1, j, dims), a.x);
    let bottom = mix(texel(i, j + 1, dims), texel(i + 1, j + 1, dims), a.x);
    return mix(top, bottom, a.y).rgb;
}

// Colour of segment `s` at the centre of pixel (px, py), as `strand_raster.rs` `Shade`.
fn seg_colour(s: Seg, px: u32, py: u32) -> vec3<f32> {
    let d = s.p1 - s.p0;
    let len = sqrt(d.x * d.x + d.y * d.y);
    let r = vec2<f32>(f32(px) + 0.5, f32(py) + 0.5) - s.p0;
    let t_raw = (r.x * d.x + r.y * d.y) * (1.0 / (len * len));
    let t = clamp(t_raw, 0.0, 1.0);
    var c = s.c0.rgb * (1.0 - t) + s.c1.rgb * t;
    if cfg.photo != 0u {
        let h = cfg.half_width;
        let u = d / len;
        // The signed width fraction: (c - p0)·n / h².
        let nl = vec2<f32>(-u.y * h, u.x * h) / (h * h);
        let l = r.x * nl.x + r.y * nl.y;
        let od = s.o.zw - s.o.xy;
        let ol = sqrt(od.x * od.x + od.y * od.y);
        var on = vec2<f32>(0.0);
        if ol > 1e-6 {
            on = vec2<f32>(-od.y / ol, od.x / ol) * cfg.photo_half_width;
        }
        var p = clamp(photo_at(s.o.xy + od * t_raw + on * l), vec3<f32>(0.0), vec3<f32>(1.0));
        if cfg.photo == 2u {
            p = hsv_adjust_linear(p, cfg.hue_deg, cfg.saturation, cfg.value);
        }
        c = clamp(p + c, vec3<f32>(0.0), vec3<f32>(1.0));
    }
    return c;
}

// f32 -> f16 precision rounding toward zero, ±65504 at most (`colour::f16_store`; finite x).
fn f16_rtz(v: f32) -> f32 {
    let x = clamp(v, -65504.0, 65504.0);
    if abs(x) >= 6.1035156e-5 {
        return bitcast<f32>(bitcast<u32>(x) & 0xffffe000u);
    }
    return trunc(x * 16777216.0) / 16777216.0;
}

// The f16 bits of x, which `f16_rtz` has made exactly representable. By hand rather than
// `pack2x16float`, which naga gates behind a float16 capability.
fn f16_bits(x: f32) -> u32 {
    let b = bitcast<u32>(x);
    let sign = (b >> 16u) & 0x8000u;
    let a = abs(x);
    if a >= 6.1035156e-5 {
        return sign | ((((b >> 23u) & 0xffu) - 112u) << 10u) | ((b >> 13u) & 0x3ffu);
    }
    // Subnormal: a·2^24 is an integer below 1024.
    return sign | u32(a * 16777216.0);
}

fn f16_pair(a: f32, b: f32) -> u32 {
    return f16_bits(a) | (f16_bits(b) << 16u);
}

// The value of f16 bits `h` (finite).
fn f16_value(h: u32) -> f32 {
    let e = (h >> 10u) & 0x1fu;
    let m = h & 0x3ffu;
    if e == 0u {
        return select(1.0, -1.0, (h & 0x8000u) != 0u) * (f32(m) / 16777216.0);
    }
    return bitcast<f32>(((h & 0x8000u) << 16u) | ((e + 112u) << 23u) | (m << 13u));
}

// The colour at pixel xy of the segment of this chunk with index `local`, rounded toward
// zero to f16 as the target stores it; `last` and `c` keep the previous sample's holder and
// colour (a pixel's samples mostly share one).
fn held_colour(local: u32, xy: vec2<u32>, last: ptr<function, u32>, c: ptr<function, vec3<f32>>) -> vec3<f32> {
    if local != *last {
        *c = seg_colour(segs[position[local]], xy.x, xy.y);
        *last = local;
    }
    let v = *c;
    return vec3<f32>(f16_rtz(v.r), f16_rtz(v.g), f16_rtz(v.b));
}

// Per sample: the holder's !index, 0 for none, from the including shader's `holders`.
@compute @workgroup_size(8, 8)
fn colour(@builtin(global_invocation_id) g: vec3<u32>) {
    if g.x >= cfg.width || g.y >= cfg.height {
        return;
    }
    let p = g.y * cfg.width + g.x;
    let held = holders(p);
    var last = 0xffffffffu;
    var c = vec3<f32>(0.0);
    for (var s = 0u; s < 4u; s++) {
        if held[s] == 0u {
            continue;
        }
        let local = ~held[s] - chunk.base;
        if local >= chunk.count {
            continue;
        }
        let q = held_colour(local, g.xy, &last, &c);
        cbuf[p * 4u + s] = vec2<u32>(f16_pair(q.r, q.g), f16_pair(q.b, 1.0));
    }
}

// --- resolve --------------------------------------------------------------------------

@compute @workgroup_size(8, 8)
fn resolve(@builtin(global_invocation_id) g: vec3<u32>) {
    if g.x >= cfg.width || g.y >= cfg.height {
        return;
    }
    let p = g.y * cfg.width + g.x;
    let held = holders(p);
    var acc = vec4<f32>(-0.0);
    for (var s = 0u; s < 4u; s++) {
        if held[s] != 0u {
            let q = cbuf[p * 4u + s];
            acc += vec4<f32>(
                f16_value(q.x & 0xffffu),
                f16_value(q.x >> 16u),
                f16_value(q.y & 0xffffu),
                f16_value(q.y >> 16u),
            );
        } else {
            acc += textureLoad(msaa_color, vec2<i32>(g.xy), i32(s));
        }
    }
    store_mean(p, acc);
}

// The mean of the four f16 samples summed in `acc`, stored as the f16 target does (toward
// zero).
fn store_mean(p: u32, acc: vec4<f32>) {
    let m = acc * 0.25;
    resolved[p] = vec2<u32>(
        f16_pair(f16_rtz(m.x), f16_rtz(m.y)),
        f16_pair(f16_rtz(m.z), f16_rtz(m.w)),
    );
}

// --- colour and resolve in one pass ----------------------------------------------------

// `colour` then `resolve` for a frame whose segments are one chunk: each held sample's
// colour rounded to f16 as `colour` stores it and summed as `resolve` reads it back (an f16
// value is an f32 exactly), without the per-sample colour buffer between them.
@compute @workgroup_size(8, 8)
fn shade(@builtin(global_invocation_id) g: vec3<u32>) {
    if g.x >= cfg.width || g.y >= cfg.height {
        return;
    }
    let p = g.y * cfg.width + g.x;
    let held = holders(p);
    var last = 0xffffffffu;
    var c = vec3<f32>(0.0);
    var acc = vec4<f32>(-0.0);
    for (var s = 0u; s < 4u; s++) {
        if held[s] != 0u {
            acc += vec4<f32>(held_colour(~held[s] - chunk.base, g.xy, &last, &c), 1.0);
        } else {
            acc += textureLoad(msaa_color, vec2<i32>(g.xy), i32(s));
        }
    }
    store_mean(p, acc);
}
