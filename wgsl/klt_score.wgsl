// Shi–Tomasi corner score (KLT feature detection): the smaller eigenvalue of the structure
// tensor of the image gradient averaged over a (2r+1)² box window (the box of OpenCV's
// cornerMinEigenVal). Gradients are central differences with clamp-to-edge addressing.
// The host selects local maxima on the CPU.

struct Config {
    width: u32,
    height: u32,
    // Window half size r.
    radius: u32,
    _pad0: u32,
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
    for (var dy = -r; dy <= r; dy++) {
        for (var dx = -r; dx <= r; dx++) {
            let x = i32(gid.x) + dx;
            let y = i32(gid.y) + dy;
            let gx = 0.5 * (px(x + 1, y) - px(x - 1, y));
            let gy = 0.5 * (px(x, y + 1) - px(x, y - 1));
            sxx = sxx + gx * gx;
            sxy = sxy + gx * gy;
            syy = syy + gy * gy;
        }
    }
    let n = f32((2 * r + 1) * (2 * r + 1));
    let a = sxx / n;
    let b = sxy / n;
    let c = syy / n;
    let h = 0.5 * (a - c);
    score[gid.y * cfg.width + gid.x] = 0.5 * (a + c) - sqrt(h * h + b * b);
}
