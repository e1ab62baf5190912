// Patch distance of every target's current nearest neighbour, after the image changed (a
// vote) or the field was initialised: exact integer SSD over the image-clipped patch.
#include "shared/pm_common.wgsl"

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> flags: array<u32>;
@group(0) @binding(2) var<storage, read> px: array<u32>;
@group(0) @binding(3) var<storage, read> nnf: array<u32>;
@group(0) @binding(4) var<storage, read_write> cost: array<u32>;

#include "shared/pm_ssd.wgsl"

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
