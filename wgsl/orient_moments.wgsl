// Horizontal half of the local linear fit of the double-angle field (orient_fit is the
// vertical half and the solve). For the weight w = |(dx, dy)| and the weighted vectors
// (dx, dy), writes the Gaussian moments along x that the fit's normal equations need:
// planes [Σ g w, Σ g u w, Σ g u² w, Σ g dx, Σ g u dx, Σ g dy, Σ g u dy], u = t / σ the
// offset in sigmas. Zero outside the image: a missing sample is no data, not an edge copy.
//
// Each invocation computes OUT_PER_INV consecutive outputs along the row from one sliding
// window of loads (lavapipe charges ~3 ns per buffer access; arithmetic is cheap).

struct Config {
    width: u32,
    height: u32,
    radius: u32,
    // Length of one weight segment: PAD + 2 * radius + 1 + PAD.
    seg_len: u32,
}

const OUT_PER_INV: u32 = 4u;
const PAD: u32 = 4u;

@group(0) @binding(0) var<uniform> cfg: Config;
// Three segments (g, g u, g u²), each 2 * radius + 1 taps padded with PAD zeros on both sides:
// tap t of output j is seg[PAD + k - j] for window index k.
@group(0) @binding(1) var<storage, read> weights: array<f32>;
@group(0) @binding(2) var<storage, read> dx: array<f32>;
@group(0) @binding(3) var<storage, read> dy: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let first = gid.x * OUT_PER_INV;
    let y = gid.y;
    if first >= cfg.width || y >= cfg.height {
        return;
    }
    let r = i32(cfg.radius);
    let l = cfg.seg_len;
    var acc: array<array<f32, 7>, OUT_PER_INV>;
    for (var j = 0u; j < OUT_PER_INV; j++) {
        for (var q = 0u; q < 7u; q++) {
            acc[j][q] = 0.0;
        }
    }
    let n_window = u32(2 * r) + OUT_PER_INV;
    for (var k = 0u; k < n_window; k++) {
        let x = i32(first) - r + i32(k);
        if x < 0 || x >= i32(cfg.width) {
            continue;
        }
        let i = y * cfg.width + u32(x);
        let vx = dx[i];
        let vy = dy[i];
        let w = sqrt(vx * vx + vy * vy);
        for (var j = 0u; j < OUT_PER_INV; j++) {
            let t = PAD + k - j;
            let g0 = weights[t];
            let g1 = weights[l + t];
            let g2 = weights[2u * l + t];
            acc[j][0] += g0 * w;
            acc[j][1] += g1 * w;
            acc[j][2] += g2 * w;
            acc[j][3] += g0 * vx;
            acc[j][4] += g1 * vx;
            acc[j][5] += g0 * vy;
            acc[j][6] += g1 * vy;
        }
    }
    let n = cfg.width * cfg.height;
    for (var j = 0u; j < OUT_PER_INV; j++) {
        let x = first + j;
        if x < cfg.width {
            let i = y * cfg.width + x;
            for (var q = 0u; q < 7u; q++) {
                out[q * n + i] = acc[j][q];
            }
        }
    }
}
