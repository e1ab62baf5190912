// Coarsest-level direct solve: v = A⁻¹ g with the dense inverse of A = σ² L² + P over the
// level's compact cell list (a few hundred cells), written into the v part of uv. The u
// rows follow by one field_smooth pass in mode 1 per colour.
#include "shared/field_cfg.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> cells: array<u32>;
// Row-major count x count.
@group(0) @binding(2) var<storage, read> inv: array<f32>;
@group(0) @binding(3) var<storage, read> g: array<f32>;
@group(0) @binding(4) var<storage, read_write> uv: array<f32>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let r = gid.x;
    if r >= cfg.count {
        return;
    }
    var s = vec3<f32>(0.0);
    let row = r * cfg.count;
    for (var k = 0u; k < cfg.count; k = k + 1u) {
        s = s + inv[row + k] * vec3<f32>(g[3u * k], g[3u * k + 1u], g[3u * k + 2u]);
    }
    let b = 6u * cells[r];
    uv[b + 3u] = s.x;
    uv[b + 4u] = s.y;
    uv[b + 5u] = s.z;
}
