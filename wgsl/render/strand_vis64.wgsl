// Strand rasteriser as compute passes (C13 §4) for devices with 64-bit atomic min/max
// (`SHADER_INT64_ATOMIC_MIN_MAX`; lavapipe has them): the image of `strand_vis.wgsl`, whose
// header gives the passes and why, with its `depth` and `pick` done in one walk. A sample
// holds the u64 (key << 32) | index, key = 2·bits(z) + 1 as there, so one atomicMin keeps the
// nearest key and, among exact ties, the lowest index: what `depth` then `pick` decide in two
// walks over every segment's quad. The quad, its walk, colour and resolve are
// `shared/strand_vis.wgsl`.
//
// Passes (host: `src/render/raster/gpu/vis.rs`):
// 1. `zinit`   per pixel: every sample holds (2·bits(mesh depth) << 32) | 0xffffffff. Mesh
//              keys are even, strand keys odd, so a strand never ties the mesh.
// 2. `depth`   per segment: every covered, kept sample with z in [0, 1] does
//              atomicMin(zbuf, (2·bits(z) + 1) << 32 | index) where a plain read of the
//              sample does not already hold a smaller value.
// 3. `colour`  and 4. `resolve` as in `strand_vis.wgsl`, the holder of a sample being the
//              index of an odd key.

#include "shared/strand_vis.wgsl"

// Per sample (pixel-major, 4 per pixel): (key << 32) | index of the holder.
@group(0) @binding(4) var<storage, read_write> zbuf: array<atomic<u64>>;
// The same buffer read and written plainly, a pixel as two vec4s (lo, hi of samples 0 and
// 1, then of 2 and 3): a gathered load costs a fraction of an atomic one on a CPU driver.
// Values only fall, so a stale read holds a larger value than the latest, and can only send
// a sample to an atomic minimum that changes nothing.
@group(0) @binding(10) var<storage, read_write> zplain: array<vec4<u32>>;

@compute @workgroup_size(8, 8)
fn zinit(@builtin(global_invocation_id) g: vec3<u32>) {
    if g.x >= cfg.width || g.y >= cfg.height {
        return;
    }
    let z = mesh_keys(g.xy);
    let p = g.y * cfg.width + g.x;
    let none = 0xffffffffu;
    zplain[2u * p] = vec4<u32>(none, z[0], none, z[1]);
    zplain[2u * p + 1u] = vec4<u32>(none, z[2], none, z[3]);
}

// Lowers the values of pixel p's samples to (v << 32) | index where that is smaller.
fn visit(p: u32, v: vec4<u32>, ok: vec4<bool>, index: u32, pick: bool) {
    let a = zplain[2u * p];
    let b = zplain[2u * p + 1u];
    let hi = vec4<u32>(a.y, a.w, b.y, b.w);
    let lo = vec4<u32>(a.x, a.z, b.x, b.z);
    let hit = ok & ((v < hi) | ((v == hi) & (vec4<u32>(index) < lo)));
    if !any(hit) {
        return;
    }
    for (var sm = 0u; sm < 4u; sm++) {
        if hit[sm] {
            atomicMin(&zbuf[p * 4u + sm], (u64(v[sm]) << 32u) | u64(index));
        }
    }
}

// !index where a strand's (odd) key holds the sample, 0 where the mesh or nothing does.
fn holders(p: u32) -> vec4<u32> {
    let a = zplain[2u * p];
    let b = zplain[2u * p + 1u];
    let strand = (vec4<u32>(a.y, a.w, b.y, b.w) & vec4<u32>(1u)) != vec4<u32>(0u);
    return select(vec4<u32>(0u), ~vec4<u32>(a.x, a.z, b.x, b.z), strand);
}

@compute @workgroup_size(64)
fn depth(@builtin(global_invocation_id) g: vec3<u32>) {
    let local = seg_index(g);
    if local < chunk.count {
        walk(local, false);
    }
}
