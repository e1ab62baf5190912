// Separable convolution along one axis with clamp-to-edge addressing; optionally subtracts a
// second image (for the difference-of-Gaussians prefilter).
//
// Each invocation computes OUT_PER_INV consecutive outputs along the axis from one sliding
// window of loads: on lavapipe every buffer access costs ~3 ns while arithmetic is cheap,
// so reusing each loaded value for several outputs is what makes the pass fast.

struct Config {
    width: u32,
    height: u32,
    radius: u32,
    // 0: along x (rows), 1: along y (columns).
    axis: u32,
    // 1: write conv(src) - minus, 0: write conv(src).
    subtract: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

const OUT_PER_INV: u32 = 8u;

@group(0) @binding(0) var<uniform> cfg: Config;
// 2*radius+1 taps, padded with OUT_PER_INV zeros on both sides so the inner loop needs no
// branch: tap t of output j is weights[OUT_PER_INV + t - j].
@group(0) @binding(1) var<storage, read> weights: array<f32>;
@group(0) @binding(2) var<storage, read> src: array<f32>;
@group(0) @binding(3) var<storage, read> minus: array<f32>;
@group(0) @binding(4) var<storage, read_write> dst: array<f32>;

fn load(along: i32, across: u32) -> f32 {
    if cfg.axis == 0u {
        let x = u32(clamp(along, 0, i32(cfg.width) - 1));
        return src[across * cfg.width + x];
    }
    let y = u32(clamp(along, 0, i32(cfg.height) - 1));
    return src[y * cfg.width + across];
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    var len_along = cfg.width;
    var len_across = cfg.height;
    if cfg.axis == 1u {
        len_along = cfg.height;
        len_across = cfg.width;
    }
    let first = gid.x * OUT_PER_INV;
    let across = gid.y;
    if first >= len_along || across >= len_across {
        return;
    }
    let r = i32(cfg.radius);
    var acc: array<f32, OUT_PER_INV>;
    for (var j = 0u; j < OUT_PER_INV; j++) {
        acc[j] = 0.0;
    }
    // Window positions first-r .. first+OUT_PER_INV-1+r; window index k = pos - (first - r).
    let n_window = u32(2 * r) + OUT_PER_INV;
    for (var k = 0u; k < n_window; k++) {
        let v = load(i32(first) - r + i32(k), across);
        for (var j = 0u; j < OUT_PER_INV; j++) {
            // Tap index t = k - j in 0..=2r; outside it the padded weight is 0.
            acc[j] = acc[j] + weights[OUT_PER_INV + k - j] * v;
        }
    }
    for (var j = 0u; j < OUT_PER_INV; j++) {
        let pos = first + j;
        if pos < len_along {
            var idx = across * cfg.width + pos;
            if cfg.axis == 1u {
                idx = pos * cfg.width + across;
            }
            var out = acc[j];
            if cfg.subtract == 1u {
                out = out - minus[idx];
            }
            dst[idx] = out;
        }
    }
}
