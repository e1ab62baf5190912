// Residual of the mixed form of C13 Eq. (3) on one level (see field_smooth.wgsl):
//   r1 = f1 - (-u + σ L v),   r2 = f2 - (σ L u + p v)
// written for every cell (zero outside H), so a coarse restriction can read it blindly.
#include "shared/field_cfg.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> cellw: array<f32>;
@group(0) @binding(2) var<storage, read> f: array<f32>;
@group(0) @binding(3) var<storage, read> uv: array<f32>;
// [r1.xyz, r2.xyz] per cell.
@group(0) @binding(4) var<storage, read_write> r: array<f32>;
// Link weights to the +x, +y, +z neighbour, 3 per cell (0: no link). 1 between fine H
// cells; on coarse levels the fine links between the two blocks / 4, so blocks that touch
// only through cells the fine level keeps apart stay apart.
@group(0) @binding(5) var<storage, read> links: array<f32>;

#include "shared/field_uv_nb.wgsl"

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let x = gid.x;
    let y = gid.y;
    let z = gid.z;
    if x >= cfg.nx || y >= cfg.ny || z >= cfg.nz {
        return;
    }
    let i = x + cfg.nx * (y + cfg.ny * z);
    let b = 6u * i;
    let p = cellw[i];
    if p < 0.0 {
        for (var k = 0u; k < 6u; k = k + 1u) {
            r[b + k] = 0.0;
        }
        return;
    }
    let sy = cfg.nx;
    let sz = cfg.nx * cfg.ny;
    var su = vec3<f32>(0.0);
    var sv = vec3<f32>(0.0);
    var d = 0.0;
    if x > 0u { add_nb(i - 1u, links[3u * (i - 1u)], &su, &sv, &d); }
    if x + 1u < cfg.nx { add_nb(i + 1u, links[3u * i], &su, &sv, &d); }
    if y > 0u { add_nb(i - sy, links[3u * (i - sy) + 1u], &su, &sv, &d); }
    if y + 1u < cfg.ny { add_nb(i + sy, links[3u * i + 1u], &su, &sv, &d); }
    if z > 0u { add_nb(i - sz, links[3u * (i - sz) + 2u], &su, &sv, &d); }
    if z + 1u < cfg.nz { add_nb(i + sz, links[3u * i + 2u], &su, &sv, &d); }
    let u = vec3<f32>(uv[b], uv[b + 1u], uv[b + 2u]);
    let v = vec3<f32>(uv[b + 3u], uv[b + 4u], uv[b + 5u]);
    let r1 = vec3<f32>(f[b], f[b + 1u], f[b + 2u]) - (cfg.sigma * (sv - d * v) - u);
    let r2 = vec3<f32>(f[b + 3u], f[b + 4u], f[b + 5u]) - (cfg.sigma * (su - d * u) + p * v);
    r[b] = r1.x;
    r[b + 1u] = r1.y;
    r[b + 2u] = r1.z;
    r[b + 3u] = r2.x;
    r[b + 4u] = r2.y;
    r[b + 5u] = r2.z;
}
