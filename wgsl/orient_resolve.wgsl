// Orientation from the (smoothed) double-angle field: θ = ½ atan2, in [0, π), x right and
// y down; NaN outside the hair mask, where the confidence is 0.

struct Config {
    width: u32,
    height: u32,
    _pad0: u32,
    _pad1: u32,
}

#include "shared/orient_theta.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> dx: array<f32>;
@group(0) @binding(2) var<storage, read> dy: array<f32>;
@group(0) @binding(3) var<storage, read> conf: array<f32>;
// One word per pixel: nonzero on hair.
@group(0) @binding(4) var<storage, read> mask: array<u32>;
@group(0) @binding(5) var<storage, read_write> out_theta: array<f32>;
@group(0) @binding(6) var<storage, read_write> out_conf: array<f32>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    if mask[i] == 0u {
        out_theta[i] = bitcast<f32>(0x7fc00000u);
        out_conf[i] = 0.0;
        return;
    }
    out_theta[i] = resolve_theta(dx[i], dy[i]);
    out_conf[i] = conf[i];
}
