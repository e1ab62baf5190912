// Doubles a flow field onto the next finer pyramid level: fine pixel x sits at coarse
// (x - 0.5) / 2 (the mapping of `flow_down`), the coarse flow is sampled there bilinearly
// (clamped to the coarse image) and scaled by 2, the ratio of the pixel sizes.

struct Config {
    src_w: u32,
    src_h: u32,
    dst_w: u32,
    dst_h: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> src: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> dst: array<vec2<f32>>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.dst_w || gid.y >= cfg.dst_h {
        return;
    }
    let cx = clamp((f32(gid.x) - 0.5) * 0.5, 0.0, f32(cfg.src_w - 1u));
    let cy = clamp((f32(gid.y) - 0.5) * 0.5, 0.0, f32(cfg.src_h - 1u));
    let x0 = u32(floor(cx));
    let y0 = u32(floor(cy));
    let fx = cx - f32(x0);
    let fy = cy - f32(y0);
    let x1 = min(x0 + 1u, cfg.src_w - 1u);
    let y1 = min(y0 + 1u, cfg.src_h - 1u);
    let top = mix(src[y0 * cfg.src_w + x0], src[y0 * cfg.src_w + x1], fx);
    let bot = mix(src[y1 * cfg.src_w + x0], src[y1 * cfg.src_w + x1], fx);
    dst[gid.y * cfg.dst_w + gid.x] = 2.0 * mix(top, bot, fy);
}
