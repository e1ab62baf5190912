// Eq. (7) of C13, one invocation per strand vertex; see `src/stages/strand_warp.rs`.
// Vertices are in head model space, so the head's rigid motion M_i is the frame's camera:
// v_i = v_r + β·lift_i(W_i), W_i = W*_i(p_r) − (p'_i − p_r), p_r = C_r(v_r), p'_i = C_i(v_r).

struct Config {
    width: u32,
    height: u32,
    n_verts: u32,
    _pad0: u32,
    // Reference camera: scale, first two rotation rows, translation.
    rs: f32,
    r00: f32,
    r01: f32,
    r02: f32,
    r10: f32,
    r11: f32,
    r12: f32,
    rtx: f32,
    rty: f32,
    // Frame camera.
    fs: f32,
    i00: f32,
    i01: f32,
    i02: f32,
    i10: f32,
    i11: f32,
    i12: f32,
    itx: f32,
    ity: f32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> xs: array<f32>;
@group(0) @binding(2) var<storage, read> beta: array<f32>;
@group(0) @binding(3) var<storage, read> field: array<f32>;
@group(0) @binding(4) var<storage, read_write> xout: array<f32>;

#include "shared/field_sample.wgsl"

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= cfg.n_verts {
        return;
    }
    let v = vec3<f32>(xs[3u * k], xs[3u * k + 1u], xs[3u * k + 2u]);
    let rx = vec3<f32>(cfg.r00, cfg.r01, cfg.r02);
    let ry = vec3<f32>(cfg.r10, cfg.r11, cfg.r12);
    let ix = vec3<f32>(cfg.i00, cfg.i01, cfg.i02);
    let iy = vec3<f32>(cfg.i10, cfg.i11, cfg.i12);
    let pr = vec2<f32>(cfg.rs * dot(rx, v) + cfg.rtx, -cfg.rs * dot(ry, v) + cfg.rty);
    let pi = vec2<f32>(cfg.fs * dot(ix, v) + cfg.itx, -cfg.fs * dot(iy, v) + cfg.ity);
    let wi = sample2(pr) - (pi - pr);
    // Image px -> view (x right, y up, no depth change) -> model.
    let d = (wi.x * ix - wi.y * iy) / cfg.fs;
    let o = v + beta[k] * d;
    xout[3u * k] = o.x;
    xout[3u * k + 1u] = o.y;
    xout[3u * k + 2u] = o.z;
}
