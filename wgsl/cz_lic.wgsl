// CZ06 §3.2, texture synthesis, step 1: line-integral convolution (Cabral and Leedom 1993)
// along the orientation field Θ. Each domain pixel averages `src` with box weights over its
// streamline, `steps` RK2 (midpoint) steps of `h` px each way. Θ is an orientation: the
// tangent at every evaluation is turned to agree with the previous one (sign-consistent), and
// it is bilinear over the domain so a path is continuous in its start. A streamline stops
// before a step that would leave the domain (hair with Θ), or where the tangent vanishes.
// Off the domain the output is 0. CPU mirror: `src/stages/cz_lic.rs`.

struct Config {
    width: u32,
    height: u32,
    steps: u32,
    h: f32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> flags: array<u32>;
@group(0) @binding(2) var<storage, read> tang: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read> src: array<f32>;
@group(0) @binding(4) var<storage, read_write> dst: array<f32>;

#include "shared/cz_tex.wgsl"

// Tangents shorter than this (taps that cancel) end a streamline.
const MIN_LEN: f32 = 1e-3;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    if flags[i] == 0u {
        dst[i] = 0.0;
        return;
    }
    let p0 = vec2<f32>(f32(gid.x) + 0.5, f32(gid.y) + 0.5);
    var sum = src[i];
    var count = 1.0;
    for (var side = 0; side < 2; side++) {
        var p = p0;
        var prev = tang[i];
        if side == 1 {
            prev = -prev;
        }
        for (var s = 0u; s < cfg.steps; s++) {
            let t1 = tex_tangent(p, prev);
            let l1 = length(t1);
            if l1 < MIN_LEN {
                break;
            }
            let d1 = t1 / l1;
            let pm = p + (0.5 * cfg.h) * d1;
            if tex_pixel(pm) < 0 {
                break;
            }
            let t2 = tex_tangent(pm, d1);
            let l2 = length(t2);
            if l2 < MIN_LEN {
                break;
            }
            let d2 = t2 / l2;
            let pn = p + cfg.h * d2;
            if tex_pixel(pn) < 0 {
                break;
            }
            let v = tex_value(pn);
            sum = sum + v.x / v.y;
            count = count + 1.0;
            p = pn;
            prev = d2;
        }
    }
    dst[i] = sum / count;
}
