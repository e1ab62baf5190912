// Improved Perlin noise at given points: the wind's noise on its own, so that it can be
// checked against the reference (see `src/stages/noise_eval.rs`).

struct Config {
    n: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
// Doubled Perlin permutation (512).
@group(0) @binding(1) var<storage, read> perm: array<u32>;
// xyz per point.
@group(0) @binding(2) var<storage, read> points: array<f32>;
@group(0) @binding(3) var<storage, read_write> values: array<f32>;

#include "shared/noise.wgsl"

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= cfg.n {
        return;
    }
    values[i] = perlin(points[3u * i], points[3u * i + 1u], points[3u * i + 2u]);
}
