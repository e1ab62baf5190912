// One 1D pass of the recursive-filter domain transform (Gastal & Oliveira 2011, §4 "RF"):
// one invocation per row (axis 0) or column (axis 1), a causal then an anti-causal
// first-order recursion along it, in place on every plane of `planes`.
//
// Between neighbours k-1 and k the domain-transform distance is
//   d = 1 + ratio * sum_c |guide_c(k) - guide_c(k-1)|      (ratio = sigma_s / sigma_r)
// and the feedback weight is a^d = exp(d * log_a); an edge in the guide makes d large, the
// weight small, and the recursion stops there.

struct Config {
    width: u32,
    height: u32,
    // 0: along rows, 1: along columns.
    axis: u32,
    // Guide channels, each a width*height plane, one after the other.
    channels: u32,
    // Planes filtered together, each width*height, stored one after the other.
    n_planes: u32,
    ratio: f32,
    // ln a, a = exp(-sqrt(2) / sigma_H) for this iteration's sigma_H.
    log_a: f32,
    _pad0: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> guide: array<f32>;
@group(0) @binding(2) var<storage, read_write> planes: array<f32>;

// Pixel index of position k along line `line`.
fn index(line: u32, k: u32) -> u32 {
    if cfg.axis == 0u {
        return line * cfg.width + k;
    }
    return k * cfg.width + line;
}

// Feedback weight between positions k-1 and k.
fn weight(line: u32, k: u32) -> f32 {
    let a = index(line, k - 1u);
    let b = index(line, k);
    let plane = cfg.width * cfg.height;
    var s = 0.0;
    for (var c = 0u; c < cfg.channels; c++) {
        s = s + abs(guide[c * plane + b] - guide[c * plane + a]);
    }
    return exp((1.0 + cfg.ratio * s) * cfg.log_a);
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    var len = cfg.width;
    var lines = cfg.height;
    if cfg.axis == 1u {
        len = cfg.height;
        lines = cfg.width;
    }
    let line = gid.x;
    if line >= lines {
        return;
    }
    let plane = cfg.width * cfg.height;
    for (var k = 1u; k < len; k++) {
        let wk = weight(line, k);
        let i = index(line, k);
        let j = index(line, k - 1u);
        for (var p = 0u; p < cfg.n_planes; p++) {
            let o = p * plane;
            planes[o + i] = planes[o + i] + wk * (planes[o + j] - planes[o + i]);
        }
    }
    for (var kk = 1u; kk < len; kk++) {
        let k = len - 1u - kk;
        // The weight between k and k+1.
        let wk = weight(line, k + 1u);
        let i = index(line, k);
        let j = index(line, k + 1u);
        for (var p = 0u; p < cfg.n_planes; p++) {
            let o = p * plane;
            planes[o + i] = planes[o + i] + wk * (planes[o + j] - planes[o + i]);
        }
    }
}
