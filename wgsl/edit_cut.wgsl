// Cut (C13 appendix A.2), one invocation per strand; see `src/stages/edit_cut.rs`. Writes
// the strand's new vertex count; the host drops the tips and compacts on the CPU.

struct Config {
    n_strands: u32,
    n_segs: u32,
    radius: f32,
    s: f32,
    r00: f32,
    r01: f32,
    r02: f32,
    r10: f32,
    r11: f32,
    r12: f32,
    tx: f32,
    ty: f32,
    seed_lo: u32,
    seed_hi: u32,
    first_strand: u32,
    _pad0: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> segs: array<f32>;
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
@group(0) @binding(3) var<storage, read> xs: array<f32>;
@group(0) @binding(4) var<storage, read_write> counts: array<u32>;

#include "shared/edit_stroke.wgsl"

fn pcg(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

fn project(i: u32) -> vec2<f32> {
    let p = vec3<f32>(xs[3u * i], xs[3u * i + 1u], xs[3u * i + 2u]);
    let vx = cfg.r00 * p.x + cfg.r01 * p.y + cfg.r02 * p.z;
    let vy = cfg.r10 * p.x + cfg.r11 * p.y + cfg.r12 * p.z;
    return vec2<f32>(cfg.s * vx + cfg.tx, -cfg.s * vy + cfg.ty);
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let st = gid.x;
    if st >= cfg.n_strands {
        return;
    }
    let o = offsets[st];
    let n = offsets[st + 1u] - o;
    var keep = n;
    if cfg.radius <= 0.0 {
        // Clean cut: keep up to the vertex before the first crossing.
        var p0 = project(o);
        var done = false;
        for (var k = 0u; k + 1u < n && !done; k++) {
            let p1 = project(o + k + 1u);
            for (var g = 0u; g < cfg.n_segs; g++) {
                let b = 8u * g;
                let a = vec2<f32>(segs[b], segs[b + 1u]);
                let c = vec2<f32>(segs[b + 4u], segs[b + 5u]);
                if seg_crosses(p0, p1, a, c) {
                    keep = k + 1u;
                    done = true;
                    break;
                }
            }
            p0 = p1;
        }
    } else {
        var total = 0.0;
        for (var k = 0u; k < n; k++) {
            let r = stroke_nearest(project(o + k), cfg.n_segs).dist;
            if r < cfg.radius {
                total += 1.0 - r / cfg.radius;
            }
        }
        if total > 0.0 {
            let h = pcg(pcg(cfg.seed_lo ^ pcg(cfg.seed_hi)) + cfg.first_strand + st);
            let target_w = f32(h >> 8u) * (1.0 / 16777216.0) * total;
            var acc = 0.0;
            for (var k = 0u; k < n; k++) {
                let r = stroke_nearest(project(o + k), cfg.n_segs).dist;
                if r < cfg.radius {
                    acc += 1.0 - r / cfg.radius;
                    keep = k + 1u;
                    if acc > target_w {
                        break;
                    }
                }
            }
        }
    }
    counts[st] = keep;
}
