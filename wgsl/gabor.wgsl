// Gabor filter bank (C13 §2.1 after Chai et al. 2012): per pixel, the responses of
// N_ORIENT even Gabor kernels, negative responses clamped to 0, the orientation of the
// strongest (refined by a parabola through its neighbours) and a Paris et al. 2004 style
// confidence from the spread of the responses around that maximum.
//
// Output is the double-angle vector conf * (cos 2θ, sin 2θ) plus conf itself: the double
// angle makes θ and θ + π the same, so the field can be smoothed linearly afterwards.
//
// The kernel is even, K(d) = K(-d), so each pair of taps shares one weight: the loop adds
// the two texels first, which halves the multiplies. Taps are the outer loop and
// orientations the inner one, so each texel is loaded once and used by all N_ORIENT
// accumulators held in registers.

override N_ORIENT: u32 = 32u;
// N_ORIENT / 4: accumulators are vec4s so one uniform load feeds four orientations.
override N_VEC: u32 = 8u;
// (ksize*ksize + 1) / 2: the centre tap plus one of each symmetric pair.
override N_PAIRS: u32 = 145u;

const MAX_ORIENT: u32 = 64u;
const PI: f32 = 3.14159265358979;

struct Config {
    width: u32,
    height: u32,
    // ksize / 2
    half: u32,
    n_orient: u32,
    // Responses at or below this are rounding noise: no orientation, confidence 0.
    min_response: f32,
    // A pixel whose responses spread by at most this share of the strongest is isotropic
    // (flat or DC only): no orientation, confidence 0.
    min_contrast: f32,
    // 1 on the last refinement pass: instead of its own orientation, write the first pass's
    // double-angle vector (orientation from the image, weighted by the image confidence)
    // times this pass's refined confidence, zeroed off the hair mask. The refined confidence
    // is what marks reliable strand pixels; the mask keeps the face and background edges out
    // of the smoothing that follows. 2: the same, weighted by the first pass's own
    // confidence |first| instead (w0² in all), which the local linear fit prefers.
    final_pass: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
// Pair-major: weights[j * N_VEC + q] holds orientations 4q..4q+3 of pair j. Pair 0 is the
// centre with half its weight. A uniform buffer, because lavapipe loads a dynamically
// uniform address once per SIMD batch instead of once per lane (6x faster than storage).
@group(0) @binding(1) var<uniform> weights: array<vec4<f32>, 4096>;
@group(0) @binding(2) var<storage, read> src: array<f32>;
// Read only when cfg.final_pass == 1: the hair mask (one word per pixel, nonzero on hair)
// and the first pass's double-angle output.
@group(0) @binding(3) var<storage, read> mask: array<u32>;
@group(0) @binding(4) var<storage, read> first_dx: array<f32>;
@group(0) @binding(5) var<storage, read> first_dy: array<f32>;
@group(0) @binding(6) var<storage, read_write> out_dx: array<f32>;
@group(0) @binding(7) var<storage, read_write> out_dy: array<f32>;
@group(0) @binding(8) var<storage, read_write> out_conf: array<f32>;

fn load(x: i32, y: i32) -> f32 {
    let cx = u32(clamp(x, 0, i32(cfg.width) - 1));
    let cy = u32(clamp(y, 0, i32(cfg.height) - 1));
    return src[cy * cfg.width + cx];
}

// Offset of pair j: j = 0 is the centre; then (1..=h, 0); then rows dy = 1..=h, dx = -h..=h.
fn pair_offset(j: u32) -> vec2<i32> {
    if j == 0u {
        return vec2<i32>(0, 0);
    }
    let h = cfg.half;
    let idx = j - 1u;
    if idx < h {
        return vec2<i32>(i32(idx) + 1, 0);
    }
    let r = idx - h;
    let w = 2u * h + 1u;
    return vec2<i32>(i32(r % w) - i32(h), i32(r / w) + 1);
}

fn ang_dist(a: f32, b: f32) -> f32 {
    let d = abs(a - b) % PI;
    return min(d, PI - d);
}

// Outputs per invocation along x: each uniform weight load then feeds PX pixels, which
// halves the dominant cost on lavapipe (more pixels spill the accumulators and lose).
const PX: u32 = 2u;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let x0 = gid.x * PX;
    if x0 >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let y = i32(gid.y);
    let xa = i32(x0);
    let xb = xa + 1;
    var acc_a: array<vec4<f32>, 16>;
    var acc_b: array<vec4<f32>, 16>;
    for (var q = 0u; q < N_VEC; q++) {
        acc_a[q] = vec4<f32>(0.0);
        acc_b[q] = vec4<f32>(0.0);
    }
    for (var j = 0u; j < N_PAIRS; j++) {
        let d = pair_offset(j);
        let sa = load(xa + d.x, y + d.y) + load(xa - d.x, y - d.y);
        let sb = load(xb + d.x, y + d.y) + load(xb - d.x, y - d.y);
        let base = j * N_VEC;
        for (var q = 0u; q < N_VEC; q++) {
            let w = weights[base + q];
            acc_a[q] += w * sa;
            acc_b[q] += w * sb;
        }
    }
    finish(acc_a, gid.y * cfg.width + x0);
    if x0 + 1u < cfg.width {
        finish(acc_b, gid.y * cfg.width + x0 + 1u);
    }
}

// Argmax, sub-bin refinement and confidence of one pixel; writes its three outputs.
fn finish(acc4: array<vec4<f32>, 16>, i: u32) {
    var acc: array<f32, MAX_ORIENT>;
    for (var q = 0u; q < N_VEC; q++) {
        acc[4u * q] = acc4[q].x;
        acc[4u * q + 1u] = acc4[q].y;
        acc[4u * q + 2u] = acc4[q].z;
        acc[4u * q + 3u] = acc4[q].w;
    }
    // Strongest clamped response; the first one wins ties.
    var best = 0u;
    var rmax = max(acc[0], 0.0);
    var rmin = rmax;
    for (var o = 1u; o < N_ORIENT; o++) {
        let r = max(acc[o], 0.0);
        if r > rmax {
            rmax = r;
            best = o;
        }
        rmin = min(rmin, r);
    }
    var dx = 0.0;
    var dy = 0.0;
    var conf = 0.0;
    if rmax > cfg.min_response && rmax - rmin > cfg.min_contrast * rmax {
        let n = N_ORIENT;
        let a = max(acc[(best + n - 1u) % n], 0.0);
        let c = max(acc[(best + 1u) % n], 0.0);
        let denom = a - 2.0 * rmax + c;
        var delta = 0.0;
        if denom < 0.0 {
            delta = clamp(0.5 * (a - c) / denom, -0.5, 0.5);
        }
        let step = PI / f32(n);
        var theta = (f32(best) + delta) * step;
        theta = theta - PI * floor(theta / PI);
        var num = 0.0;
        var den = 0.0;
        for (var o = 0u; o < N_ORIENT; o++) {
            let d = ang_dist(f32(o) * step, theta);
            let diff = max(acc[o], 0.0) - rmax;
            num = num + d * d * diff * diff;
            den = den + d * d;
        }
        conf = sqrt(num / max(den, 1e-12));
        dx = conf * cos(2.0 * theta);
        dy = conf * sin(2.0 * theta);
    }
    if cfg.final_pass != 0u {
        var keep = 0.0;
        if mask[i] != 0u {
            keep = conf;
            if cfg.final_pass == 2u {
                keep = length(vec2<f32>(first_dx[i], first_dy[i]));
            }
        }
        dx = keep * first_dx[i];
        dy = keep * first_dy[i];
    }
    out_dx[i] = dx;
    out_dy[i] = dy;
    out_conf[i] = conf;
}
