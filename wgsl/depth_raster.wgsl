// Depth rasterisation of triangles in volume space (C13 §2.1: "the initial hair model and the
// head model are rasterized together from both the front and back views to generate two depth
// maps"). One invocation per triangle walks the triangle's pixel bounding box, clamped to the
// image, and keeps per pixel centre (i + 0.5, j + 0.5) the largest depth (front, nearest the
// camera) and the smallest (back) through atomicMax / atomicMin on an order-preserving u32
// encoding of f32. Both are order independent, so the result does not depend on scheduling.
//
// Coverage is exact: x and y are snapped to 1/16 px and the edge functions are evaluated in
// i32. The host rejects triangles whose bounding box spans 2048 px or more, so every factor
// of an edge function is below 2^15 in magnitude and no product or difference overflows; the
// shader skips such triangles too. A pixel centre exactly on an edge belongs to the triangle
// for which the edge is a top or left edge (the D3D top-left rule), so a shared edge is
// covered exactly once. Depth is interpolated barycentrically in f32 from the same integer
// edge values. The CPU mirror (src/stages/depth_raster.rs) does the identical arithmetic.

struct Config {
    width: u32,
    height: u32,
    n_tris: u32,
    // Workgroups along x of the dispatch (large meshes are dispatched as a 2D grid).
    groups_x: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
// x, y, z per vertex, volume space (px).
@group(0) @binding(1) var<storage, read> verts: array<f32>;
// Three vertex indices per triangle.
@group(0) @binding(2) var<storage, read> tris: array<u32>;
// Encoded depths, W*H each; front starts at 0 (empty), back at 0xffffffff (empty).
@group(0) @binding(3) var<storage, read_write> front: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read_write> back: array<atomic<u32>>;

const SUB: f32 = 16.0;
// Largest allowed bounding-box span of a triangle, in 1/16 px: 2^15 - 1.
const MAX_SPAN: i32 = 32767;

fn snap(v: f32) -> i32 {
    return i32(round(v * SUB));
}

// Monotonic f32 -> u32: negative values bit-flipped, positive ones with the sign bit set.
fn encode(z: f32) -> u32 {
    let b = bitcast<u32>(z);
    if (b & 0x80000000u) != 0u {
        return ~b;
    }
    return b | 0x80000000u;
}

// Twice the signed area of (a, b, p), in 1/256 px^2; positive when p is on the inner side of
// a -> b for the winding the host normalises to.
fn edge(a: vec2<i32>, b: vec2<i32>, p: vec2<i32>) -> i32 {
    return (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
}

// 0 for a top or left edge (centres on it are inside), 1 otherwise (they are outside).
fn bias(a: vec2<i32>, b: vec2<i32>) -> i32 {
    let d = b - a;
    if d.y < 0 || (d.y == 0 && d.x > 0) {
        return 0;
    }
    return 1;
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.x + gid.y * cfg.groups_x * 64u;
    if t >= cfg.n_tris {
        return;
    }
    let i0 = tris[3u * t];
    var i1 = tris[3u * t + 1u];
    var i2 = tris[3u * t + 2u];
    let p0 = vec2<i32>(snap(verts[3u * i0]), snap(verts[3u * i0 + 1u]));
    var p1 = vec2<i32>(snap(verts[3u * i1]), snap(verts[3u * i1 + 1u]));
    var p2 = vec2<i32>(snap(verts[3u * i2]), snap(verts[3u * i2 + 1u]));
    let lo = min(p0, min(p1, p2));
    let hi = max(p0, max(p1, p2));
    if hi.x - lo.x > MAX_SPAN || hi.y - lo.y > MAX_SPAN {
        return;
    }
    var area = edge(p0, p1, p2);
    if area == 0 {
        return;
    }
    if area < 0 {
        // One winding for every triangle, so "inside" is the same sign for all edges.
        let tp = p1;
        p1 = p2;
        p2 = tp;
        let ti = i1;
        i1 = i2;
        i2 = ti;
        area = -area;
    }
    let z0 = verts[3u * i0 + 2u];
    let dz1 = verts[3u * i1 + 2u] - z0;
    let dz2 = verts[3u * i2 + 2u] - z0;
    let b01 = bias(p0, p1);
    let b12 = bias(p1, p2);
    let b20 = bias(p2, p0);
    let fa = f32(area);
    // Pixel i has its centre at 16 i + 8 in 1/16 px: the first and last centres in the box.
    let x_lo = max((lo.x - 8 + 15) >> 4u, 0);
    let x_hi = min((hi.x - 8) >> 4u, i32(cfg.width) - 1);
    let y_lo = max((lo.y - 8 + 15) >> 4u, 0);
    let y_hi = min((hi.y - 8) >> 4u, i32(cfg.height) - 1);
    for (var y = y_lo; y <= y_hi; y++) {
        for (var x = x_lo; x <= x_hi; x++) {
            let p = vec2<i32>(16 * x + 8, 16 * y + 8);
            let w0 = edge(p1, p2, p);
            let w1 = edge(p2, p0, p);
            let w2 = edge(p0, p1, p);
            if w0 - b12 < 0 || w1 - b20 < 0 || w2 - b01 < 0 {
                continue;
            }
            let z = z0 + (f32(w1) * dz1 + f32(w2) * dz2) / fa;
            let e = encode(z);
            let idx = u32(y) * cfg.width + u32(x);
            atomicMax(&front[idx], e);
            atomicMin(&back[idx], e);
        }
    }
}
