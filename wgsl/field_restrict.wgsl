// Restriction of the mixed residual to the next coarser level: each coarse cell (2x2x2
// fine children, cell-centred) takes the mean of its in-H children's [r1, r2] as its
// right-hand side, and its unknowns start the coarse correction at zero. The mean is
// consistent with the rediscretised coarse operator (σ/4 per level, averaged penalty).
#include "shared/field_cfg.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> cellw_f: array<f32>;
@group(0) @binding(2) var<storage, read> cellw_c: array<f32>;
@group(0) @binding(3) var<storage, read> r: array<f32>;
@group(0) @binding(4) var<storage, read_write> fc: array<f32>;
@group(0) @binding(5) var<storage, read_write> uvc: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.cnx || gid.y >= cfg.cny || gid.z >= cfg.cnz {
        return;
    }
    let ic = gid.x + cfg.cnx * (gid.y + cfg.cny * gid.z);
    var s1 = vec3<f32>(0.0);
    var s2 = vec3<f32>(0.0);
    if cellw_c[ic] >= 0.0 {
        var n = 0.0;
        for (var c = 0u; c < 8u; c = c + 1u) {
            let x = 2u * gid.x + (c & 1u);
            let y = 2u * gid.y + ((c >> 1u) & 1u);
            let z = 2u * gid.z + (c >> 2u);
            if x < cfg.nx && y < cfg.ny && z < cfg.nz {
                let i = x + cfg.nx * (y + cfg.ny * z);
                if cellw_f[i] >= 0.0 {
                    let b = 6u * i;
                    s1 = s1 + vec3<f32>(r[b], r[b + 1u], r[b + 2u]);
                    s2 = s2 + vec3<f32>(r[b + 3u], r[b + 4u], r[b + 5u]);
                    n = n + 1.0;
                }
            }
        }
        // A coarse cell is in H exactly when one of its children is, so n >= 1.
        s1 = s1 / n;
        s2 = s2 / n;
    }
    let b = 6u * ic;
    fc[b] = s1.x;
    fc[b + 1u] = s1.y;
    fc[b + 2u] = s1.z;
    fc[b + 3u] = s2.x;
    fc[b + 4u] = s2.y;
    fc[b + 5u] = s2.z;
    for (var k = 0u; k < 6u; k = k + 1u) {
        uvc[b + k] = 0.0;
    }
}
