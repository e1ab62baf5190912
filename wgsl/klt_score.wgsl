// Shi–Tomasi corner score (KLT feature detection): the smaller eigenvalue of the structure
// tensor of the image gradient averaged over a (2r+1)² window with Gaussian weights of sigma
// r/2 (a box window would give a plateau, not a peak, around a corner). Gradients are central differences with clamp-to-edge addressing.
// The host selects local maxima on the CPU.

struct Config {
    width: u32,
    height: u32,
    // Window half size r.
    radius: u32,
    min_iso: f32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> gray: array<f32>;
@group(0) @binding(2) var<storage, read_write> score: array<f32>;

fn px(x: i32, y: i32) -> f32 {
    let xx = u32(clamp(x, 0, i32(cfg.width) - 1));
    let yy = u32(clamp(y, 0, i32(cfg.height) - 1));
    return gray[yy * cfg.width + xx];
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let r = i32(cfg.radius);
    var sxx = 0.0;
    var sxy = 0.0;
    var syy = 0.0;
    var wsum = 0.0;
    let k = -2.0 / f32(r * r);
    for (var dy = -r; dy <= r; dy++) {
        for (var dx = -r; dx <= r; dx++) {
            let x = i32(gid.x) + dx;
            let y = i32(gid.y) + dy;
            let gx = 0.5 * (px(x + 1, y) - px(x - 1, y));
            let gy = 0.5 * (px(x, y + 1) - px(x, y - 1));
            let wt = exp(k * f32(dx * dx + dy * dy));
            sxx = sxx + wt * gx * gx;
            sxy = sxy + wt * gx * gy;
            syy = syy + wt * gy * gy;
            wsum = wsum + wt;
        }
    }
    let n = wsum;
    let a = sxx / n;
    let b = sxy / n;
    let c = syy / n;
    let h = 0.5 * (a - c);
    let root = sqrt(h * h + b * b);
    let lo = 0.5 * (a + c) - root;
    let hi = 0.5 * (a + c) + root;
    var s = lo;
    if !(lo >= cfg.min_iso * hi) {
        s = 0.0;
    }
    score[gid.y * cfg.width + gid.x] = s;
}
