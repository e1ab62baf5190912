// PatchMatch (Barnes et al. 2009) nearest-neighbour field initialisation for one pyramid
// level. Every target pixel (its patch overlaps the hole) gets a source patch centre:
// upsampled from the coarser level's field when there is one (2 s + the pixel's offset in its
// 2x2 block, Wexler et al. 2007), else, or when that lands on no valid source, uniformly
// random draws from the integer hash (the same numbers on the CPU mirror), then a fixed
// fallback source. Non-targets get NONE.
#include "shared/pm_common.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> flags: array<u32>;
// The coarser level's field (coarse_width x coarse_height); unused for random init.
@group(0) @binding(2) var<storage, read> coarse_nnf: array<u32>;
@group(0) @binding(3) var<storage, read_write> nnf: array<u32>;

#include "shared/pm_rand.wgsl"

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
