// One level of a Gaussian pyramid: the 5-tap binomial filter [1 4 6 4 1]/16 in x and y,
// clamp-to-edge, sampled at every second pixel. Pixel centres sit at integer coordinates, so
// pixel (x, y) of the coarse level is pixel (2x, 2y) of the fine one: p_coarse = p_fine / 2.
// All levels of a pyramid live in one buffer; this pass reads the region at `src_off` and
// writes the one at `dst_off`.

struct Config {
    src_w: u32,
    src_h: u32,
    dst_w: u32,
    dst_h: u32,
    src_off: u32,
    dst_off: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read_write> pyr: array<f32>;

const TAPS = array<f32, 5>(0.0625, 0.25, 0.375, 0.25, 0.0625);

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.dst_w || gid.y >= cfg.dst_h {
        return;
    }
    var acc = 0.0;
    for (var j = 0; j < 5; j++) {
        let y = u32(clamp(2 * i32(gid.y) + j - 2, 0, i32(cfg.src_h) - 1));
        var row = 0.0;
        for (var i = 0; i < 5; i++) {
            let x = u32(clamp(2 * i32(gid.x) + i - 2, 0, i32(cfg.src_w) - 1));
            row = row + TAPS[i] * pyr[cfg.src_off + y * cfg.src_w + x];
        }
        acc = acc + TAPS[j] * row;
    }
    pyr[cfg.dst_off + gid.y * cfg.dst_w + gid.x] = acc;
}
