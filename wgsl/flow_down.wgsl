// Halves a 2-channel image for the flow pyramid. Coarse pixel (X, Y) sits at fine
// (2X + 0.5, 2Y + 0.5) and averages the 4x4 fine pixels around it with the separable
// [1 3 3 1] / 8 kernel (the tent of the x2 scale: it anti-aliases without shifting the
// image), clamp to edge. `flow_up` uses the same pixel-centre mapping.

struct Config {
    src_w: u32,
    src_h: u32,
    dst_w: u32,
    dst_h: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> src: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> dst: array<vec2<f32>>;

const TAPS = array<f32, 4>(0.125, 0.375, 0.375, 0.125);

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.dst_w || gid.y >= cfg.dst_h {
        return;
    }
    let x0 = 2 * i32(gid.x) - 1;
    let y0 = 2 * i32(gid.y) - 1;
    var acc = vec2<f32>(0.0);
    for (var j = 0; j < 4; j++) {
        let y = u32(clamp(y0 + j, 0, i32(cfg.src_h) - 1));
        var row = vec2<f32>(0.0);
        for (var i = 0; i < 4; i++) {
            let x = u32(clamp(x0 + i, 0, i32(cfg.src_w) - 1));
            row = row + TAPS[i] * src[y * cfg.src_w + x];
        }
        acc = acc + TAPS[j] * row;
    }
    dst[gid.y * cfg.dst_w + gid.x] = acc;
}
