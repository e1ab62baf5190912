// PatchMatch (Barnes et al. 2009) nearest-neighbour field initialisation for one pyramid
// level. Every target pixel (its patch overlaps the hole) gets a source patch centre:
// upsampled from the coarser level's field when there is one (2 s + the pixel's offset in its
// 2x2 block, Wexler et al. 2007), else, or when that lands on no valid source, uniformly
// random draws from the integer hash (the same numbers on the CPU mirror), then a fixed
// fallback source. Non-targets get NONE.
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
// The coarser level's field (coarse_width x coarse_height); unused for random init.
@group(0) @binding(2) var<storage, read> coarse_nnf: array<u32>;
@group(0) @binding(3) var<storage, read_write> nnf: array<u32>;

// Chris Wellons' lowbias32; rand() keys it by seed, pass, pixel and draw (pm_common.rs).
fn hash(x0: u32) -> u32 {
    var x = x0;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

fn rand(pixel: u32, k: u32) -> u32 {
    return hash(cfg.seed ^ hash(cfg.pass_id ^ hash(pixel ^ hash(k))));
}

fn valid_source(x: i32, y: i32) -> bool {
    let r = i32(cfg.radius);
    if x < r || y < r || x >= i32(cfg.width) - r || y >= i32(cfg.height) - r {
        return false;
    }
    return (flags[u32(y) * cfg.width + u32(x)] & SOURCE) != 0u;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    if (flags[i] & TARGET) == 0u {
        nnf[i] = NONE;
        return;
    }
    var cand = NONE;
    if cfg.coarse_width > 0u {
        let cx = min(gid.x / 2u, cfg.coarse_width - 1u);
        let cy = min(gid.y / 2u, cfg.coarse_height - 1u);
        let pn = coarse_nnf[cy * cfg.coarse_width + cx];
        if pn != NONE {
            let sx = 2 * i32(pn & 0xffffu) + i32(gid.x) - 2 * i32(cx);
            let sy = 2 * i32(pn >> 16u) + i32(gid.y) - 2 * i32(cy);
            if valid_source(sx, sy) {
                cand = u32(sx) | (u32(sy) << 16u);
            }
        }
    }
    if cand == NONE {
        let r = cfg.radius;
        for (var k = 0u; k < 16u; k++) {
            let h1 = rand(i, k);
            let h2 = hash(h1);
            let sx = r + h1 % (cfg.width - 2u * r);
            let sy = r + h2 % (cfg.height - 2u * r);
            if (flags[sy * cfg.width + sx] & SOURCE) != 0u {
                cand = sx | (sy << 16u);
                break;
            }
        }
    }
    if cand == NONE {
        cand = cfg.fallback;
    }
    nnf[i] = cand;
}
