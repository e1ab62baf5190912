// Comb (C13 appendix A.1), one invocation per strand; see `src/stages/edit_comb.rs` for
// the construction. Each vertex within R of the stroke turns the rest of its strand about
// the view axis through it; strands never near the stroke are not written at all.

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
    r20: f32,
    r21: f32,
    r22: f32,
    tx: f32,
    ty: f32,
    _pad0: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
// Stroke segments, 8 floats each (shared/edit_stroke.wgsl).
@group(0) @binding(1) var<storage, read> segs: array<f32>;
// Where each strand starts in `xs` (vertices), plus the end.
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
// Model-space vertices, xyz, edited in place.
@group(0) @binding(3) var<storage, read_write> xs: array<f32>;

#include "shared/edit_stroke.wgsl"

fn vert(i: u32) -> vec3<f32> {
    return vec3<f32>(xs[3u * i], xs[3u * i + 1u], xs[3u * i + 2u]);
}

fn turn(v: vec3<f32>, a: f32) -> vec3<f32> {
    let c = cos(a);
    let s = sin(a);
    return vec3<f32>(c * v.x - s * v.y, s * v.x + c * v.y, v.z);
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let st = gid.x;
    if st >= cfg.n_strands {
        return;
    }
    let o = offsets[st];
    let n = offsets[st + 1u] - o;
    let r0 = vec3<f32>(cfg.r00, cfg.r01, cfg.r02);
    let r1 = vec3<f32>(cfg.r10, cfg.r11, cfg.r12);
    let r2 = vec3<f32>(cfg.r20, cfg.r21, cfg.r22);
    var phi = 0.0;
    var touched = false;
    var prev_orig = vert(o);
    var prev_new = prev_orig;
    for (var k = 0u; k + 1u < n; k++) {
        let next_orig = vert(o + k + 1u);
        let e = next_orig - prev_orig;
        let e0 = vec3<f32>(dot(r0, e), dot(r1, e), dot(r2, e));
        var ev = turn(e0, phi);
        let pk = vec2<f32>(cfg.s * dot(r0, prev_new) + cfg.tx, -cfg.s * dot(r1, prev_new) + cfg.ty);
        let near = stroke_nearest(pk, cfg.n_segs);
        if near.dist < cfg.radius {
            let h = 1.0 - near.dist / cfg.radius;
            let sx = ev.x;
            let sy = -ev.y;
            if sx != 0.0 || sy != 0.0 {
                let t = near.dir;
                let delta = atan2(sx * t.y - sy * t.x, sx * t.x + sy * t.y);
                phi -= h * delta;
                ev = turn(e0, phi);
            }
            touched = true;
        }
        var next_new = next_orig;
        if touched {
            next_new = prev_new + r0 * ev.x + r1 * ev.y + r2 * ev.z;
            let i = o + k + 1u;
            xs[3u * i] = next_new.x;
            xs[3u * i + 1u] = next_new.y;
            xs[3u * i + 2u] = next_new.z;
        }
        prev_orig = next_orig;
        prev_new = next_new;
    }
}
