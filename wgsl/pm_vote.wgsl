// Voting step of Wexler et al. 2007: each hole pixel becomes the weighted average of the
// pixels that the overlapping target patches' nearest neighbours put on it. Patch q weighs
// exp(-vote_k (m_q - m_min)), m_q = its SSD per pixel (integer division, exact on both
// backends) and m_min the best among the patches covering this pixel, so the weights never
// all underflow; vote_k = 0 gives the plain average (used right after upsampling the field,
// before any distance is known). Sources lie entirely outside the hole, so the pass reads
// only known pixels and writes only hole pixels: rgb and px are updated in place.
// Onion peel (coarsest level, layer > 0): only the hole pixels of that layer are written, and
// a patch's distance counts its known pixels only (outside the hole or in earlier layers),
// its weight scaled by their share; patches with none do not vote.
#include "shared/pm_common.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> flags: array<u32>;
@group(0) @binding(2) var<storage, read> nnf: array<u32>;
@group(0) @binding(3) var<storage, read> cost: array<u32>;
// Linear RGB (w unused) and the packed matching word of every pixel.
@group(0) @binding(4) var<storage, read_write> rgb: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> px: array<u32>;

fn patch_count(x: i32, y: i32) -> u32 {
    let r = i32(cfg.radius);
    let nx = min(x + r, i32(cfg.width) - 1) - max(x - r, 0) + 1;
    let ny = min(y + r, i32(cfg.height) - 1) - max(y - r, 0) + 1;
    return u32(nx * ny);
}

// Pixels of the patch at (x, y) whose colour is known while peel layer cfg.layer is filled:
// outside the hole, or in an earlier layer.
fn known_count(x: i32, y: i32) -> u32 {
    let r = i32(cfg.radius);
    var n = 0u;
    for (var yy = max(y - r, 0); yy <= min(y + r, i32(cfg.height) - 1); yy++) {
        for (var xx = max(x - r, 0); xx <= min(x + r, i32(cfg.width) - 1); xx++) {
            let f = flags[u32(yy) * cfg.width + u32(xx)];
            if (f & HOLE) == 0u || (f >> LAYER_SHIFT) < cfg.layer {
                n += 1u;
            }
        }
    }
    return n;
}

// Mean SSD per known pixel of the patch at (x, y), and its share of known pixels.
fn patch_stats(q: u32, x: i32, y: i32) -> vec2<u32> {
    var n = patch_count(x, y);
    if cfg.layer > 0u {
        n = known_count(x, y);
        if n == 0u {
            return vec2<u32>(0xffffffffu, 0u);
        }
    }
    return vec2<u32>(cost[q] / n, n);
}

fn pack(c: vec3<f32>) -> u32 {
    let q = vec3<u32>(round(sqrt(clamp(c, vec3<f32>(0.0), vec3<f32>(1.0))) * 1023.0));
    return q.x | (q.y << 10u) | (q.z << 20u);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    let f = flags[i];
    if (f & HOLE) == 0u || (cfg.layer > 0u && (f >> LAYER_SHIFT) != cfg.layer) {
        return;
    }
    let x = i32(gid.x);
    let y = i32(gid.y);
    let r = i32(cfg.radius);
    let qx0 = max(x - r, 0);
    let qx1 = min(x + r, i32(cfg.width) - 1);
    let qy0 = max(y - r, 0);
    let qy1 = min(y + r, i32(cfg.height) - 1);
    var m_min = 0xffffffffu;
    if cfg.vote_k > 0.0 {
        for (var qy = qy0; qy <= qy1; qy++) {
            for (var qx = qx0; qx <= qx1; qx++) {
                let q = u32(qy) * cfg.width + u32(qx);
                if nnf[q] != NONE {
                    m_min = min(m_min, patch_stats(q, qx, qy).x);
                }
            }
        }
    }
    var acc = vec3<f32>(0.0);
    var wsum = 0.0;
    for (var qy = qy0; qy <= qy1; qy++) {
        for (var qx = qx0; qx <= qx1; qx++) {
            let q = u32(qy) * cfg.width + u32(qx);
            let s = nnf[q];
            if s == NONE {
                continue;
            }
            var wt = 1.0;
            if cfg.vote_k > 0.0 {
                let st = patch_stats(q, qx, qy);
                if st.y == 0u {
                    continue;
                }
                wt = exp(-cfg.vote_k * f32(st.x - m_min));
                if cfg.layer > 0u {
                    // A patch that sees few known pixels is a weak witness.
                    wt *= f32(st.y) / f32(patch_count(qx, qy));
                }
            }
            let sx = i32(s & 0xffffu) + x - qx;
            let sy = i32(s >> 16u) + y - qy;
            acc += wt * rgb[u32(sy) * cfg.width + u32(sx)].xyz;
            wsum += wt;
        }
    }
    if wsum > 0.0 {
        let c = acc / wsum;
        rgb[i] = vec4<f32>(c, 1.0);
        px[i] = pack(c);
    }
}
