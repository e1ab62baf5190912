// Bilinear sample of a 2-vector field stored interleaved (x, y per pixel, row-major) in the
// storage array `field` of a `cfg.width` x `cfg.height` image; positions are clamped to the
// pixel centres at the border. The mirror is `crate::stages::warp_compose::sample2`.
fn field_at(i: u32) -> vec2<f32> {
    return vec2<f32>(field[2u * i], field[2u * i + 1u]);
}

fn sample2(p: vec2<f32>) -> vec2<f32> {
    let w = f32(cfg.width);
    let h = f32(cfg.height);
    let x = clamp(p.x, 0.0, w - 1.0);
    let y = clamp(p.y, 0.0, h - 1.0);
    let x0 = u32(floor(x));
    let y0 = u32(floor(y));
    let x1 = min(x0 + 1u, cfg.width - 1u);
    let y1 = min(y0 + 1u, cfg.height - 1u);
    let fx = x - f32(x0);
    let fy = y - f32(y0);
    let a = field_at(y0 * cfg.width + x0);
    let b = field_at(y0 * cfg.width + x1);
    let c = field_at(y1 * cfg.width + x0);
    let d = field_at(y1 * cfg.width + x1);
    let top = a + (b - a) * fx;
    let bot = c + (d - c) * fx;
    return top + (bot - top) * fy;
}
