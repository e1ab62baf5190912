// One red-black half-sweep of collective Gauss-Seidel on the mixed form of C13 Eq. (3):
//   row u:  -u_i + σ (Σ_j v_j - d_i v_i) = f1_i        (u = σ L v)
//   row v:   σ (Σ_j u_j - d_i u_i) + p_i v_i = f2_i    (σ L u + p v = b)
// over the linked 6-neighbours j (weights w_ij, d_i = Σ_j w_ij; sums are weighted). Each cell of one colour solves its 2x2 system for
// (u_i, v_i) with the other colour held; the neighbours all have the other colour, so the
// update is in place and race-free. Relaxing (u, v) together is what makes this a good
// smoother for the bi-Laplacian (plain point smoothing of L² smooths poorly).
// mode 1 relaxes the u rows only (v held): used after the coarsest direct solve for v.
// Threads cover half the x range: x = 2 gid.x + ((y + z + colour) & 1).
#include "shared/field_cfg.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
// -1 outside H, else the penalty weight p >= 0.
@group(0) @binding(1) var<storage, read> cellw: array<f32>;
// Right-hand sides [f1.xyz, f2.xyz] per cell.
@group(0) @binding(2) var<storage, read> f: array<f32>;
// Unknowns [u.xyz, v.xyz] per cell.
@group(0) @binding(3) var<storage, read_write> uv: array<f32>;
// Link weights to the +x, +y, +z neighbour, 3 per cell (0: no link). 1 between fine H
// cells; on coarse levels the fine links between the two blocks / 4, so blocks that touch
// only through cells the fine level keeps apart stay apart.
@group(0) @binding(4) var<storage, read> links: array<f32>;

#include "shared/field_uv_nb.wgsl"

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let y = gid.y;
    let z = gid.z;
    let x = 2u * gid.x + ((y + z + cfg.colour) & 1u);
    if x >= cfg.nx || y >= cfg.ny || z >= cfg.nz {
        return;
    }
    let i = x + cfg.nx * (y + cfg.ny * z);
    let p = cellw[i];
    if p < 0.0 {
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
    let b = 6u * i;
    let g1 = vec3<f32>(f[b], f[b + 1u], f[b + 2u]) - cfg.sigma * sv;
    let g2 = vec3<f32>(f[b + 3u], f[b + 4u], f[b + 5u]) - cfg.sigma * su;
    let sd = cfg.sigma * d;
    var u: vec3<f32>;
    var v: vec3<f32>;
    if cfg.mode == 1u {
        v = vec3<f32>(uv[b + 3u], uv[b + 4u], uv[b + 5u]);
        u = -g1 - sd * v;
    } else {
        let det = -p - sd * sd;
        if det != 0.0 {
            u = (p * g1 + sd * g2) / det;
            v = (sd * g1 - g2) / det;
        } else {
            // An isolated unconstrained cell: v is free, take 0.
            u = -g1;
            v = vec3<f32>(0.0);
        }
    }
    uv[b] = u.x;
    uv[b + 1u] = u.y;
    uv[b + 2u] = u.z;
    uv[b + 3u] = v.x;
    uv[b + 4u] = v.y;
    uv[b + 5u] = v.z;
}
