// One PatchMatch pass (Barnes et al. 2009) over a level, in a parallel form: every target
// reads the previous field (nnf_in) and writes its own entry of nnf_out, so there is no scan
// order. Propagation: the four neighbours at distance `step` offer their match shifted back
// by the same offset (jump-flood style; the host runs steps K, K/2, ..., 1 so a good match
// crosses the level in log2 K passes, as Barnes' sequential scan does in one). Random search
// (in the step-1 pass): around the match v0 after propagation, one draw in each window of
// half-side search_radius·α^i with α = 1/2, down to 1 px. A candidate replaces the best
// only with a strictly smaller SSD, in a fixed order, so ties resolve the same on the CPU.
#include "shared/pm_common.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> flags: array<u32>;
@group(0) @binding(2) var<storage, read> px: array<u32>;
@group(0) @binding(3) var<storage, read> nnf_in: array<u32>;
@group(0) @binding(4) var<storage, read> cost_in: array<u32>;
@group(0) @binding(5) var<storage, read_write> nnf_out: array<u32>;
@group(0) @binding(6) var<storage, read_write> cost_out: array<u32>;

#include "shared/pm_rand.wgsl"

#include "shared/pm_ssd.wgsl"

// Tries source centre (sx, sy) for target (x, y).
fn consider(x: i32, y: i32, sx: i32, sy: i32, best: ptr<function, u32>, bc: ptr<function, u32>) {
    let r = i32(cfg.radius);
    if sx < r || sy < r || sx >= i32(cfg.width) - r || sy >= i32(cfg.height) - r {
        return;
    }
    let cand = u32(sx) | (u32(sy) << 16u);
    if cand == *best || (flags[u32(sy) * cfg.width + u32(sx)] & SOURCE) == 0u {
        return;
    }
    let c = ssd(x, y, sx, sy, *bc);
    if c < *bc {
        *best = cand;
        *bc = c;
    }
}

// The neighbour at (x + dx, y + dy) offers its match shifted back by (dx, dy).
fn propagate(x: i32, y: i32, dx: i32, dy: i32, best: ptr<function, u32>, bc: ptr<function, u32>) {
    let qx = x + dx;
    let qy = y + dy;
    if qx < 0 || qy < 0 || qx >= i32(cfg.width) || qy >= i32(cfg.height) {
        return;
    }
    let qn = nnf_in[u32(qy) * cfg.width + u32(qx)];
    if qn == NONE {
        return;
    }
    consider(x, y, i32(qn & 0xffffu) - dx, i32(qn >> 16u) - dy, best, bc);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    if (flags[i] & TARGET) == 0u {
        nnf_out[i] = NONE;
        cost_out[i] = 0u;
        return;
    }
    let x = i32(gid.x);
    let y = i32(gid.y);
    var best = nnf_in[i];
    var bc = cost_in[i];
    if cfg.step > 0u {
        let s = i32(cfg.step);
        propagate(x, y, -s, 0, &best, &bc);
        propagate(x, y, s, 0, &best, &bc);
        propagate(x, y, 0, -s, &best, &bc);
        propagate(x, y, 0, s, &best, &bc);
    }
    let r = i32(cfg.radius);
    let cx = i32(best & 0xffffu);
    let cy = i32(best >> 16u);
    var rad = i32(cfg.search_radius);
    var k = 0u;
    while rad >= 1 {
        let h1 = rand(i, k);
        let h2 = hash(h1);
        let span = u32(2 * rad + 1);
        let sx = clamp(cx + i32(h1 % span) - rad, r, i32(cfg.width) - 1 - r);
        let sy = clamp(cy + i32(h2 % span) - rad, r, i32(cfg.height) - 1 - r);
        consider(x, y, sx, sy, &best, &bc);
        rad = rad / 2;
        k += 1u;
    }
    nnf_out[i] = best;
    cost_out[i] = bc;
}
