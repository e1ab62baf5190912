// Right-hand side of the coarsest level's direct solve. Eliminating u = σ L v - f1 from the
// mixed form leaves (σ² L² + P) v = f2 + σ L f1, whose inverse the host precomputed.
// One invocation per in-H cell of the compact list; output g is 3 floats per list entry.
#include "shared/field_cfg.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> cells: array<u32>;
@group(0) @binding(2) var<storage, read> f: array<f32>;
@group(0) @binding(3) var<storage, read_write> g: array<f32>;
// Link weights to the +x, +y, +z neighbour, 3 per cell (0: no link). 1 between fine H
// cells; on coarse levels the fine links between the two blocks / 4, so blocks that touch
// only through cells the fine level keeps apart stay apart.
@group(0) @binding(4) var<storage, read> links: array<f32>;

fn add_nb(j: u32, w: f32, s: ptr<function, vec3<f32>>, d: ptr<function, f32>) {
    if w > 0.0 {
        let b = 6u * j;
        *s = *s + w * vec3<f32>(f[b], f[b + 1u], f[b + 2u]);
        *d = *d + w;
    }
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= cfg.count {
        return;
    }
    let i = cells[k];
    let x = i % cfg.nx;
    let y = (i / cfg.nx) % cfg.ny;
    let z = i / (cfg.nx * cfg.ny);
    let sy = cfg.nx;
    let sz = cfg.nx * cfg.ny;
    var s = vec3<f32>(0.0);
    var d = 0.0;
    if x > 0u { add_nb(i - 1u, links[3u * (i - 1u)], &s, &d); }
    if x + 1u < cfg.nx { add_nb(i + 1u, links[3u * i], &s, &d); }
    if y > 0u { add_nb(i - sy, links[3u * (i - sy) + 1u], &s, &d); }
    if y + 1u < cfg.ny { add_nb(i + sy, links[3u * i + 1u], &s, &d); }
    if z > 0u { add_nb(i - sz, links[3u * (i - sz) + 2u], &s, &d); }
    if z + 1u < cfg.nz { add_nb(i + sz, links[3u * i + 2u], &s, &d); }
    let b = 6u * i;
    let f1 = vec3<f32>(f[b], f[b + 1u], f[b + 2u]);
    let out = vec3<f32>(f[b + 3u], f[b + 4u], f[b + 5u]) + cfg.sigma * (s - d * f1);
    g[3u * k] = out.x;
    g[3u * k + 1u] = out.y;
    g[3u * k + 2u] = out.z;
}
