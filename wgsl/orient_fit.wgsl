// Vertical half of the local linear fit of the double-angle field, and the solve (see
// orient_moments). Per pixel, the weighted least-squares fit v(q) ≈ a + B (q − p) of the
// unit double-angle vectors in a Gaussian window, weights w; θ = ½ atan2 of the intercept a.
// A weighted mean (the constant fit) leans toward wherever the weight sits in the window,
// and in a field that turns across the window that is an angle error; the slope term
// takes that lean out. The slope's diagonal gets a ridge (ridge · Σ g w), so a window
// whose weight lies along one line falls back toward the mean instead of extrapolating.
// NaN off the mask, 0 where the window has no weight (as orient_resolve).

struct Config {
    width: u32,
    height: u32,
    radius: u32,
    seg_len: u32,
    ridge: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

const OUT_PER_INV: u32 = 4u;
const PAD: u32 = 4u;
#include "shared/orient_theta.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> weights: array<f32>;
// orient_moments' seven planes.
@group(0) @binding(2) var<storage, read> hm: array<f32>;
@group(0) @binding(3) var<storage, read> conf: array<f32>;
// One word per pixel: nonzero on hair.
@group(0) @binding(4) var<storage, read> mask: array<u32>;
@group(0) @binding(5) var<storage, read_write> out_theta: array<f32>;
@group(0) @binding(6) var<storage, read_write> out_conf: array<f32>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let x = gid.x;
    let first = gid.y * OUT_PER_INV;
    if x >= cfg.width || first >= cfg.height {
        return;
    }
    let n = cfg.width * cfg.height;
    let r = i32(cfg.radius);
    let l = cfg.seg_len;
    // Per output: m00 m10 m20 m01 m11 m02, rx0 rx1 rx2, ry0 ry1 ry2.
    var acc: array<array<f32, 12>, OUT_PER_INV>;
    for (var j = 0u; j < OUT_PER_INV; j++) {
        for (var q = 0u; q < 12u; q++) {
            acc[j][q] = 0.0;
        }
    }
    let n_window = u32(2 * r) + OUT_PER_INV;
    for (var k = 0u; k < n_window; k++) {
        let y = i32(first) - r + i32(k);
        if y < 0 || y >= i32(cfg.height) {
            continue;
        }
        let i = u32(y) * cfg.width + x;
        let w0 = hm[i];
        let w1 = hm[n + i];
        let w2 = hm[2u * n + i];
        let x0 = hm[3u * n + i];
        let x1 = hm[4u * n + i];
        let y0 = hm[5u * n + i];
        let y1 = hm[6u * n + i];
        for (var j = 0u; j < OUT_PER_INV; j++) {
            let t = PAD + k - j;
            let g0 = weights[t];
            let g1 = weights[l + t];
            let g2 = weights[2u * l + t];
            acc[j][0] += g0 * w0;
            acc[j][1] += g0 * w1;
            acc[j][2] += g0 * w2;
            acc[j][3] += g1 * w0;
            acc[j][4] += g1 * w1;
            acc[j][5] += g2 * w0;
            acc[j][6] += g0 * x0;
            acc[j][7] += g0 * x1;
            acc[j][8] += g1 * x0;
            acc[j][9] += g0 * y0;
            acc[j][10] += g0 * y1;
            acc[j][11] += g1 * y0;
        }
    }
    for (var j = 0u; j < OUT_PER_INV; j++) {
        let y = first + j;
        if y >= cfg.height {
            continue;
        }
        let i = y * cfg.width + x;
        if mask[i] == 0u {
            out_theta[i] = bitcast<f32>(0x7fc00000u);
            out_conf[i] = 0.0;
            continue;
        }
        let m = acc[j];
        var theta = 0.0;
        if m[0] > 0.0 {
            // Normal equations over the weight: [1 a b; a c d; b d e].
            let a = m[1] / m[0];
            let b = m[3] / m[0];
            let c = m[2] / m[0] + cfg.ridge;
            let d = m[4] / m[0];
            let e = m[5] / m[0] + cfg.ridge;
            // First row of the adjugate; the determinant is positive, so it scales a alone.
            let c0 = c * e - d * d;
            let c1 = d * b - a * e;
            let c2 = a * d - c * b;
            let ax = c0 * m[6] + c1 * m[7] + c2 * m[8];
            let ay = c0 * m[9] + c1 * m[10] + c2 * m[11];
            theta = resolve_theta(ax, ay);
        }
        out_theta[i] = theta;
        out_conf[i] = conf[i];
    }
}
