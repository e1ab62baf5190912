// Strand rasteriser as compute passes (C13 §4), the GPU path for 4x MSAA frames with
// strands: the same image rules as `strand_raster.wgsl` (see `src/render/raster/mod.rs`),
// but each segment is one invocation that walks its own quad's pixels, and the depth test
// is two atomic passes over a per-sample visibility buffer instead of the fixed-function
// rasteriser. Why: a software Vulkan (lavapipe) spends most of a hair frame on per-vertex
// records and on fragment shader invocations for quads a pixel or two wide (llvmpipe shades
// whole 4x4 blocks); here a segment costs its own covered samples and nothing more.
// Compute rasterisation of strands is what hair renderers do on real GPUs too.
//
// This file is the path for devices without 64-bit atomics; `strand_vis64.wgsl` does passes
// 2 and 3 in one where the device has them. What both share (the quad, its walk, colour and
// resolve) is `shared/strand_vis.wgsl`.
//
// Passes (host: `src/render/raster/gpu/vis.rs`, which also orders each chunk's segments by
// tile and front to back; background and mesh are drawn first by the render pipelines of
// `mesh_raster.wgsl` into a stored MSAA colour and depth target):
// 1. `zinit`   per pixel: zbuf = 2·bits(mesh depth), ibuf = 0 (nothing), per sample.
// 2. `depth`   per segment: every covered, kept sample with z in [0, 1] does
//              atomicMin(zbuf, 2·bits(z) + 1). Positive f32 order as their bits; the
//              doubling makes `Less` against the mesh strict (a strand needs 2b+1 < 2m, that
//              is b < m) while strands tying each other stay equal.
// 3. `pick`    per segment: where its value equals zbuf, atomicMax(ibuf, !index): the lowest
//              index among exact ties wins, as drawing in input order with `Less` gives
//              (so the order the walks run in changes nothing); segments `depth` never
//              found level or nearer are skipped (`candidate`).
// 4. `colour`  per pixel: a sample held by a segment of this chunk gets its colour at the
//              pixel centre (f16, rounded toward zero as the target stores it).
// 5. `resolve` per pixel: the mean of the four samples (strand colour or the MSAA target's
//              background/mesh colour) in f32, stored in f16 as the target does.
// Passes 2-4 run once per chunk of segments (the device's binding limit); when the segments
// fit one chunk, 4 and 5 are one pass, `shade` (`shared/strand_vis.wgsl`).

#include "shared/strand_vis.wgsl"

// Per sample (pixel-major, 4 per pixel): the depth key and !index of the holder (0: none).
@group(0) @binding(4) var<storage, read_write> zbuf: array<atomic<u32>>;
@group(0) @binding(5) var<storage, read_write> ibuf: array<atomic<u32>>;
// The same buffers as `zbuf` and `ibuf`, a pixel's four samples at a time, read and written
// plainly: a gathered load costs a fraction of an atomic one on a CPU driver, where atomics
// go lane by lane. Plain accesses happen only where no atomic one can race them, except in
// `depth`, where a stale read only ever holds a larger key than the latest (keys only
// fall), so it can only send a sample to an atomic minimum that changes nothing.
@group(0) @binding(10) var<storage, read_write> zplain: array<vec4<u32>>;
@group(0) @binding(12) var<storage, read_write> iplain: array<vec4<u32>>;
// Per segment of the chunk: 1 when `depth` found it level with or nearer than what a sample
// held at the time. Keys only fall, so a segment without the flag holds no sample at the end
// and `pick` skips it.
@group(0) @binding(13) var<storage, read_write> candidate: array<u32>;

// Set by `visit` in `depth`: some sample's key was level with this segment's or farther.
var<private> level: bool;

@compute @workgroup_size(8, 8)
fn zinit(@builtin(global_invocation_id) g: vec3<u32>) {
    if g.x >= cfg.width || g.y >= cfg.height {
        return;
    }
    let z = mesh_keys(g.xy);
    let p = g.y * cfg.width + g.x;
    zplain[p] = z;
    iplain[p] = vec4<u32>(0u);
}

// Lowers the keys of pixel p's samples (`pick` false) or claims those whose key is the
// segment's (`pick` true).
fn visit(p: u32, v: vec4<u32>, ok: vec4<bool>, index: u32, pick: bool) {
    // One 16-byte load for the pixel's four keys.
    let held = zplain[p];
    var hit: vec4<bool>;
    if pick {
        hit = ok & (v == held);
    } else {
        hit = ok & (v < held);
        level |= any(ok & (v == held));
    }
    if !any(hit) {
        return;
    }
    level = true;
    for (var sm = 0u; sm < 4u; sm++) {
        if hit[sm] {
            if pick {
                atomicMax(&ibuf[p * 4u + sm], ~index);
            } else {
                atomicMin(&zbuf[p * 4u + sm], v[sm]);
            }
        }
    }
}

fn holders(p: u32) -> vec4<u32> {
    return iplain[p];
}

@compute @workgroup_size(64)
fn depth(@builtin(global_invocation_id) g: vec3<u32>) {
    let local = seg_index(g);
    if local < chunk.count {
        level = false;
        walk(local, false);
        if level {
            candidate[local] = 1u;
        }
    }
}

@compute @workgroup_size(64)
fn pick(@builtin(global_invocation_id) g: vec3<u32>) {
    let local = seg_index(g);
    if local < chunk.count && candidate[local] != 0u {
        walk(local, true);
    }
}
