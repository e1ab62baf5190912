// Prolongation of the coarse correction: fine cell centres sit at 1/4 and 3/4 of a coarse
// cell, so cell-centred trilinear interpolation weighs the parent 3/4 and the neighbour on
// the child's side 1/4 per axis. Coarse cells outside the coarse H drop out and the weights
// are renormalised (the parent is always in H, so the sum is >= 27/64). Trilinear (order 2)
// with a mean restriction (order 1) satisfies m_P + m_R > 2 for each Laplacian block.
#include "shared/field_cfg.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> cellw_f: array<f32>;
@group(0) @binding(2) var<storage, read> cellw_c: array<f32>;
@group(0) @binding(3) var<storage, read> uvc: array<f32>;
@group(0) @binding(4) var<storage, read_write> uv: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let x = gid.x;
    let y = gid.y;
    let z = gid.z;
    if x >= cfg.nx || y >= cfg.ny || z >= cfg.nz {
        return;
    }
    let i = x + cfg.nx * (y + cfg.ny * z);
    if cellw_f[i] < 0.0 {
        return;
    }
    let p = vec3<i32>(i32(x >> 1u), i32(y >> 1u), i32(z >> 1u));
    // The neighbour is on the child's side: -1 for an even child, +1 for an odd one.
    let o = vec3<i32>(i32(x & 1u) * 2 - 1, i32(y & 1u) * 2 - 1, i32(z & 1u) * 2 - 1);
    let cd = vec3<i32>(i32(cfg.cnx), i32(cfg.cny), i32(cfg.cnz));
    var su = vec3<f32>(0.0);
    var sv = vec3<f32>(0.0);
    var ws = 0.0;
    for (var c = 0u; c < 8u; c = c + 1u) {
        let s = vec3<i32>(i32(c & 1u), i32((c >> 1u) & 1u), i32(c >> 2u));
        let q = p + s * o;
        if any(q < vec3<i32>(0)) || any(q >= cd) {
            continue;
        }
        let ic = u32(q.x) + cfg.cnx * (u32(q.y) + cfg.cny * u32(q.z));
        if cellw_c[ic] < 0.0 {
            continue;
        }
        let w = select(0.75, 0.25, s.x == 1) * select(0.75, 0.25, s.y == 1)
            * select(0.75, 0.25, s.z == 1);
        let b = 6u * ic;
        su = su + w * vec3<f32>(uvc[b], uvc[b + 1u], uvc[b + 2u]);
        sv = sv + w * vec3<f32>(uvc[b + 3u], uvc[b + 4u], uvc[b + 5u]);
        ws = ws + w;
    }
    let b = 6u * i;
    su = su / ws;
    sv = sv / ws;
    uv[b] = uv[b] + su.x;
    uv[b + 1u] = uv[b + 1u] + su.y;
    uv[b + 2u] = uv[b + 2u] + su.z;
    uv[b + 3u] = uv[b + 3u] + sv.x;
    uv[b + 4u] = uv[b + 4u] + sv.y;
    uv[b + 5u] = uv[b + 5u] + sv.z;
}
