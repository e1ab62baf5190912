// CZ06 §3.2, texture synthesis, step 2: contrast matching across Θ. Two modes:
//  0 (measure): out = |∇⊥Θ src| on the domain, 0 off it: the central difference
//    (src(p + n) − src(p − n)) / 2 of bilinear samples at ±1 px along n = (−sin Θ, cos Θ);
//    where one side has no domain tap (the hair's edge), the one-sided difference with the
//    pixel's own value (a difference over 1 px, so not halved); with neither, 0.
//  1 (gain): out = src · clamp(ρ_s / ρ_cur, gain_min, gain_max): the field's ρ and the
//    measured contrast, both blurred by the same Gaussian (`sep_blur`, 0 off the domain, so
//    their ratio is the ratio of their local means over the domain). Scaling the local
//    deviation of a zero-mean band is scaling the band. The gain is local but smooth: a gain
//    that varied pixel to pixel with the iid draws of ρ off the sketch would add I·∇g to the
//    gradient (mean |∇⊥I| 1.16-1.19 ρ on the synthetic cases against 1.02-1.05 smoothed).
//    Where ρ_cur is 0 the gain is gain_max.
//  2 (measure, the analysis's derivative): out = |∇⊥Θ src| with the gradient that ρ is
//    defined by (`sketch::theta::gradients`): central differences at ±1 px smoothed across
//    by (3, 10, 3)/16, taps off the image or the domain replaced by the pixel's own value,
//    projected on n. Matching with the derivative ρ was measured with keeps the band's
//    contrast at ρ under that derivative, not under another one.
// Off the domain the output is 0. CPU mirror: `src/stages/cz_contrast.rs`.

struct Config {
    width: u32,
    height: u32,
    mode: u32,
    gain_min: f32,
    gain_max: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> flags: array<u32>;
@group(0) @binding(2) var<storage, read> tang: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read> src: array<f32>;
// Mode 1 only: the blurred ρ and the blurred measure.
@group(0) @binding(4) var<storage, read> rho_s: array<f32>;
@group(0) @binding(5) var<storage, read> cur_s: array<f32>;
@group(0) @binding(6) var<storage, read_write> out: array<f32>;

#include "shared/cz_tex.wgsl"

// |∇⊥Θ src| at pixel i, centre p, across-unit n (see the header).
fn across(i: u32, p: vec2<f32>, n: vec2<f32>) -> f32 {
    let a = tex_value(p + n);
    let b = tex_value(p - n);
    if a.y > 0.0 && b.y > 0.0 {
        return abs(0.5 * (a.x / a.y - b.x / b.y));
    }
    if a.y > 0.0 {
        return abs(a.x / a.y - src[i]);
    }
    if b.y > 0.0 {
        return abs(src[i] - b.x / b.y);
    }
    return 0.0;
}

// The pixel's value, or `own` where (x, y) is off the image or the domain.
fn tap(x: i32, y: i32, own: f32) -> f32 {
    if x < 0 || y < 0 || x >= i32(cfg.width) || y >= i32(cfg.height) {
        return own;
    }
    let j = u32(y) * cfg.width + u32(x);
    if flags[j] == 0u {
        return own;
    }
    return src[j];
}

// |∇⊥Θ src| by the analysis's derivative (mode 2, see the header).
fn across_gradient(i: u32, x: i32, y: i32, n: vec2<f32>) -> f32 {
    let own = src[i];
    var sx = 0.0;
    var sy = 0.0;
    for (var k = 0; k < 3; k++) {
        let o = k - 1;
        let c = select(3.0 / 16.0, 10.0 / 16.0, k == 1);
        sx += c * 0.5 * (tap(x + 1, y + o, own) - tap(x - 1, y + o, own));
        sy += c * 0.5 * (tap(x + o, y + 1, own) - tap(x + o, y - 1, own));
    }
    return abs(sx * n.x + sy * n.y);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    if flags[i] == 0u {
        out[i] = 0.0;
        return;
    }
    if cfg.mode == 0u {
        let t = tang[i];
        let n = vec2<f32>(-t.y, t.x);
        let p = vec2<f32>(f32(gid.x) + 0.5, f32(gid.y) + 0.5);
        out[i] = across(i, p, n);
        return;
    }
    if cfg.mode == 2u {
        let t = tang[i];
        out[i] = across_gradient(i, i32(gid.x), i32(gid.y), vec2<f32>(-t.y, t.x));
        return;
    }
    var g = cfg.gain_max;
    let cur = cur_s[i];
    if cur > 0.0 {
        g = clamp(rho_s[i] / cur, cfg.gain_min, cfg.gain_max);
    }
    out[i] = src[i] * g;
}
