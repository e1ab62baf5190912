// Eq. (6) of C13, one invocation per pixel of the reference frame; see
// `src/stages/warp_compose.rs`. W*_i(p) = a·W†_i(p) + (1 − a)·[W*_{i−1}(p) + V_i(p + W*_{i−1}(p))]
// with a = ½ in the paper; a = 0 gives flow alone, a = 1 features alone. A W† of 1e30 or
// more is unknown (no feature reaches the pixel).

struct Config {
    width: u32,
    height: u32,
    alpha: f32,
    _pad0: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> wdag: array<f32>;
@group(0) @binding(2) var<storage, read> wprev: array<f32>;
@group(0) @binding(3) var<storage, read> field: array<f32>;
@group(0) @binding(4) var<storage, read_write> wout: array<f32>;

#include "shared/field_sample.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    let prev = vec2<f32>(wprev[2u * i], wprev[2u * i + 1u]);
    let dag = vec2<f32>(wdag[2u * i], wdag[2u * i + 1u]);
    let q = vec2<f32>(f32(gid.x), f32(gid.y)) + prev;
    let flowed = prev + sample2(q);
    // No feature reaches the pixel: the flow alone carries it.
    var o = flowed;
    if abs(dag.x) < 1e30 {
        o = cfg.alpha * dag + (1.0 - cfg.alpha) * flowed;
    }
    wout[2u * i] = o.x;
    wout[2u * i + 1u] = o.y;
}
