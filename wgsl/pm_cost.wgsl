// Patch distance of every target's current nearest neighbour, after the image changed (a
// vote) or the field was initialised: exact integer SSD over the image-clipped patch.
struct Config {
    width: u32,
    height: u32,
    radius: u32,
    seed: u32,
    pass_id: u32,
    step: u32,
    search_radius: u32,
    fallback: u32,
    coarse_width: u32,
    coarse_height: u32,
    vote_k: f32,
    layer: u32,
}

// Per-pixel flags (pm_common.rs): to fill, has a nearest neighbour, may be a source.
const HOLE: u32 = 1u;
const TARGET: u32 = 2u;
const SOURCE: u32 = 4u;
const NONE: u32 = 0xffffffffu;
// Matching word of a pixel whose colour is not known yet; flags >> LAYER_SHIFT = peel layer.
const UNKNOWN: u32 = 0x80000000u;
const LAYER_SHIFT: u32 = 8u;

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> flags: array<u32>;
@group(0) @binding(2) var<storage, read> px: array<u32>;
@group(0) @binding(3) var<storage, read> nnf: array<u32>;
@group(0) @binding(4) var<storage, read_write> cost: array<u32>;

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

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    if (flags[i] & TARGET) == 0u {
        cost[i] = 0u;
        return;
    }
    let s = nnf[i];
    cost[i] = ssd(i32(gid.x), i32(gid.y), i32(s & 0xffffu), i32(s >> 16u), 0xffffffffu);
}
