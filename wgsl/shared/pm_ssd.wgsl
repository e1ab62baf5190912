// Patch distances of `pm_cost.wgsl` and `pm_search.wgsl`; needs `cfg` and `UNKNOWN`
// (shared/pm_common.wgsl) and the including shader's `px` binding (packed pixel words).
// Squared difference of two packed 10-bit sqrt-encoded RGB words; 0 for an unknown target
// word (sources are always known).
fn sq(a: u32, b: u32) -> u32 {
    if (a & UNKNOWN) != 0u {
        return 0u;
    }
    let d0 = i32(a & 1023u) - i32(b & 1023u);
    let d1 = i32((a >> 10u) & 1023u) - i32((b >> 10u) & 1023u);
    let d2 = i32(a >> 20u) - i32(b >> 20u);
    return u32(d0 * d0 + d1 * d1 + d2 * d2);
}

// Exact integer SSD between the known pixels of the image-clipped patch at target (x, y) and
// the patch at source (sx, sy). Stops after a row once the sum reaches `limit`: callers only
// test `< limit`.
fn ssd(x: i32, y: i32, sx: i32, sy: i32, limit: u32) -> u32 {
    let w = i32(cfg.width);
    let r = i32(cfg.radius);
    let x0 = max(-r, -x);
    let x1 = min(r, w - 1 - x);
    let y0 = max(-r, -y);
    let y1 = min(r, i32(cfg.height) - 1 - y);
    var acc = 0u;
    for (var dy = y0; dy <= y1; dy++) {
        let t = (y + dy) * w + x;
        let s = (sy + dy) * w + sx;
        for (var dx = x0; dx <= x1; dx++) {
            acc += sq(px[u32(t + dx)], px[u32(s + dx)]);
        }
        if acc >= limit {
            return acc;
        }
    }
    return acc;
}
