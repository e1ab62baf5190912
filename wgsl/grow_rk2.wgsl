// Strand growth in a 3D direction field (C13 §2.2, "Initial Hair Tracing"): one invocation
// per strand, second-order Runge-Kutta (midpoint) with the step along the normalised,
// trilinearly interpolated field, so every step has length `step` (half a cell in C13).
//
// Positions are grid coordinates (cell centre = index + 0.5). Per step, from p:
//   v1 = D(p);               stop if |v1| <= min_speed
//   m  = p + (0.5·step·sign) · v1/|v1|
//   v2 = D(m);               stop if |v2| <= min_speed
//   q  = p + (step·sign) · v2/|v2|
//   stop if the cell holding q (floor q) is outside the grid or not in H; else p = q.
// The root (the seed) is always vertex 0; every `record_every` steps a vertex is stored, and
// the last position is stored too when growth stops between two records. `sign` = -1 traces
// against D (used for the backward half of refinement candidates).
//
// The CPU mirror (src/stages/grow_rk2.rs) does the same f32 operations in the same order.

struct Config {
    nx: u32,
    ny: u32,
    nz: u32,
    n_strands: u32,
    max_steps: u32,
    record_every: u32,
    max_verts: u32,
    step: f32,
    min_speed: f32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
// D, interleaved (x, y, z) per cell.
@group(0) @binding(1) var<storage, read> dir: array<f32>;
// H, nonzero inside the hair volume.
@group(0) @binding(2) var<storage, read> vol: array<u32>;
// Roots, interleaved (x, y, z) per strand, in grid coordinates.
@group(0) @binding(3) var<storage, read> seeds: array<f32>;
// +1 or -1 per strand.
@group(0) @binding(4) var<storage, read> signs: array<f32>;
// max_verts vertices per strand, interleaved (x, y, z).
@group(0) @binding(5) var<storage, read_write> verts: array<f32>;
@group(0) @binding(6) var<storage, read_write> counts: array<u32>;

fn fetch(i: i32, j: i32, k: i32) -> vec3<f32> {
    let c = 3u * (u32(i) + cfg.nx * (u32(j) + cfg.ny * u32(k)));
    return vec3<f32>(dir[c], dir[c + 1u], dir[c + 2u]);
}

fn lerp3(a: vec3<f32>, b: vec3<f32>, t: f32) -> vec3<f32> {
    return a + (b - a) * t;
}

// Trilinear interpolation between cell centres, clamped to the border cells.
fn sample(g: vec3<f32>) -> vec3<f32> {
    let x = g - vec3<f32>(0.5);
    let b = floor(x);
    let f = x - b;
    let hi = vec3<i32>(i32(cfg.nx) - 1, i32(cfg.ny) - 1, i32(cfg.nz) - 1);
    let bi = vec3<i32>(b);
    let i0 = clamp(bi, vec3<i32>(0), hi);
    let i1 = clamp(bi + vec3<i32>(1), vec3<i32>(0), hi);
    let c00 = lerp3(fetch(i0.x, i0.y, i0.z), fetch(i1.x, i0.y, i0.z), f.x);
    let c10 = lerp3(fetch(i0.x, i1.y, i0.z), fetch(i1.x, i1.y, i0.z), f.x);
    let c01 = lerp3(fetch(i0.x, i0.y, i1.z), fetch(i1.x, i0.y, i1.z), f.x);
    let c11 = lerp3(fetch(i0.x, i1.y, i1.z), fetch(i1.x, i1.y, i1.z), f.x);
    let c0 = lerp3(c00, c10, f.y);
    let c1 = lerp3(c01, c11, f.y);
    return lerp3(c0, c1, f.z);
}

fn norm(v: vec3<f32>) -> f32 {
    return sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
}

fn in_volume(q: vec3<f32>) -> bool {
    let n = vec3<f32>(f32(cfg.nx), f32(cfg.ny), f32(cfg.nz));
    if !(q.x >= 0.0 && q.y >= 0.0 && q.z >= 0.0 && q.x < n.x && q.y < n.y && q.z < n.z) {
        return false;
    }
    let c = vec3<u32>(floor(q));
    return vol[c.x + cfg.nx * (c.y + cfg.ny * c.z)] != 0u;
}

fn store(s: u32, k: u32, p: vec3<f32>) {
    let o = 3u * (s * cfg.max_verts + k);
    verts[o] = p.x;
    verts[o + 1u] = p.y;
    verts[o + 2u] = p.z;
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x;
    if s >= cfg.n_strands {
        return;
    }
    var p = vec3<f32>(seeds[3u * s], seeds[3u * s + 1u], seeds[3u * s + 2u]);
    let h = cfg.step * signs[s];
    let hh = 0.5 * h;
    store(s, 0u, p);
    var count = 1u;
    var pending = 0u;
    for (var k = 0u; k < cfg.max_steps; k = k + 1u) {
        let v1 = sample(p);
        let l1 = norm(v1);
        if !(l1 > cfg.min_speed) {
            break;
        }
        let m = p + (v1 / l1) * hh;
        let v2 = sample(m);
        let l2 = norm(v2);
        if !(l2 > cfg.min_speed) {
            break;
        }
        let q = p + (v2 / l2) * h;
        if !in_volume(q) {
            break;
        }
        p = q;
        pending = pending + 1u;
        if pending == cfg.record_every {
            store(s, count, p);
            count = count + 1u;
            pending = 0u;
        }
    }
    if pending > 0u {
        store(s, count, p);
        count = count + 1u;
    }
    counts[s] = count;
}
