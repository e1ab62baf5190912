// Horizontal half of the local linear fit of the double-angle field (orient_fit is the
// vertical half and the solve). For the weight w = |(dx, dy)| and the weighted vectors
// (dx, dy), writes the Gaussian moments along x that the fit's normal equations need:
// planes [Σ g w, Σ g u w, Σ g u² w, Σ g dx, Σ g u dx, Σ g dy, Σ g u dy], u = t / σ the
// offset in sigmas. Zero outside the image: a missing sample is no data, not an edge copy.
//
// With `power` below 1 the weights are flattened first (the robust fit's guide round uses it so
// one high-contrast line across the flow, a parting's scalp line, cannot dominate the guide).
// With `robust` set, each sample's weight is first divided by 1 + (Δ/δ)², Δ the angle
// between its orientation and a previous fit's θ at the same pixel (`guide`): one step of
// iteratively reweighted least squares with a Cauchy loss, so lines that are not hair flow
// (a parting's scalp line, a crossing strand) lose their say.
//
// Each invocation computes OUT_PER_INV consecutive outputs along the row from one sliding
// window of loads (lavapipe charges ~3 ns per buffer access; arithmetic is cheap).

struct Config {
    width: u32,
    height: u32,
    radius: u32,
    // Length of one weight segment: PAD + 2 * radius + 1 + PAD.
    seg_len: u32,
    // 1: reweight by the guide (δ = delta, radians of θ); 0: `guide` is not read.
    robust: u32,
    delta: f32,
    // Each sample's weight w is first raised to this power (its vector scaled by
    // w^(power - 1)); 1 leaves it.
    power: f32,
    _pad1: u32,
}

const OUT_PER_INV: u32 = 4u;
const PAD: u32 = 4u;

@group(0) @binding(0) var<uniform> cfg: Config;
// Three segments (g, g u, g u²), each 2 * radius + 1 taps padded with PAD zeros on both sides:
// tap t of output j is seg[PAD + k - j] for window index k.
@group(0) @binding(1) var<storage, read> weights: array<f32>;
@group(0) @binding(2) var<storage, read> dx: array<f32>;
@group(0) @binding(3) var<storage, read> dy: array<f32>;
// Read only when cfg.robust == 1: the previous fit's θ per pixel.
@group(0) @binding(4) var<storage, read> guide: array<f32>;
@group(0) @binding(5) var<storage, read_write> out: array<f32>;

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
        var vx = dx[i];
        var vy = dy[i];
        var w = sqrt(vx * vx + vy * vy);
        if cfg.power != 1.0 && w > 0.0 {
            let s = pow(w, cfg.power - 1.0);
            vx = vx * s;
            vy = vy * s;
            w = sqrt(vx * vx + vy * vy);
        }
        if cfg.robust == 1u && w > 0.0 {
            let t = guide[i];
            let c = clamp((vx * cos(2.0 * t) + vy * sin(2.0 * t)) / w, -1.0, 1.0);
            let d = 0.5 * acos(c) / cfg.delta;
            let k = 1.0 / (1.0 + d * d);
            vx = vx * k;
            vy = vy * k;
        }
        let m = sqrt(vx * vx + vy * vy);
        for (var j = 0u; j < OUT_PER_INV; j++) {
            let t = PAD + k - j;
            let g0 = weights[t];
            let g1 = weights[l + t];
            let g2 = weights[2u * l + t];
            acc[j][0] += g0 * m;
            acc[j][1] += g1 * m;
            acc[j][2] += g2 * m;
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
