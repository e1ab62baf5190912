// Oriented box sums over the windows of CZ06's primitives and, from them, the best energy
// drop δ of a new curve's first primitive at each birth position (Eq. 24, 26-27).
//
// mode 0: row prefix sums of the per-pixel maps (one invocation per row and map; a short
//   sequential scan, so every window sum below is two loads per window row).
// mode 1: one invocation per birth position (x, y) = (i·stride + stride/2, j·stride +
//   stride/2), integer pixel corners. For each of the 12 axis orientations k·15° the
//   windows of both shapes (7 along × 5 across, split at the axis; 7 × 6 for a dividing
//   line, whose 2-px middle strip carries no flow) are sums over stencil rows: `runs` holds
//   (dy, dx0, dx1) per row, the pixel offsets of a digital rotated rectangle relative to
//   the corner, exactly the pixels `sketch::prim::window` visits. A side's gain is linear in
//   its sums:
//     gain(θ) = Σ base − t(θ)ᵀ (Σ T) t(θ) − w (κ ½ (Σ_ring n − Σ_ring z·e^{2iθ}) − Σ_ring o)
//   (base = E1 + half the smoothness + log p_sk/p_nsk of the pixels the window takes; T the
//   structure tensor over 2σθ²; κ = 1/λθ²; the ring the pixels of a window one pixel larger, weighted
//   by w = boundary edges per ring pixel, for the smoothness the window's border will cost).
//   Every kind and side variant of the dictionary is scored and the best δ = gain − λ_NC is
//   kept with its code: axis step (0..23) | kind << 5 | variant << 8.
//
// Maps (each width*height): 0 Txx, 1 Txy, 2 Tyy (over 2σθ², 0 where taken), 3 base (0 where
// taken), 4 hair (1/0), 5 n (1 on free hair), 6 n·cos 2θ, 7 n·sin 2θ, 8 half the mean edge
// cost at the pixel (hair).

struct Config {
    width: u32,
    height: u32,
    mode: u32,
    stride: u32,
    nx: u32,
    ny: u32,
    lambda_nc: f32,
    // a, b: the non-hair side may hold at most this share of hair pixels ...
    spill: f32,
    // ... and the hair side at least this share.
    hair_min: f32,
    // 1/λθ², the weight of the smoothness terms.
    smooth: f32,
    _pad1: u32,
    _pad2: u32,
}

const N_MAPS: u32 = 9u;
const NEG: f32 = -3.0e38;

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> maps: array<f32>;
@group(0) @binding(2) var<storage, read_write> prefix: array<f32>;
// (dy, dx0, dx1, 0): pixels (x + dx, y + dy) for dx in dx0..dx1.
@group(0) @binding(3) var<storage, read> runs: array<vec4<i32>>;
// Per stencil ((k * 2 + shape) * 2 + outer) * 2 + side: (first run, runs, pixels, bits of
// the ring weight).
@group(0) @binding(4) var<storage, read> stencils: array<vec4<u32>>;
// (cos, sin) of j·15°, j in 0..24.
@group(0) @binding(5) var<storage, read> trig: array<vec2<f32>>;
@group(0) @binding(6) var<storage, read_write> best: array<f32>;
@group(0) @binding(7) var<storage, read_write> code: array<u32>;

fn stencil(k: u32, shape: u32, outer: u32, side: u32) -> u32 {
    return ((k * 2u + shape) * 2u + outer) * 2u + side;
}

// Sums of maps m0..N_MAPS over stencil `st` at corner (cx, cy); the others stay 0.
fn box_sums(st: u32, cx: i32, cy: i32, m0: u32) -> array<f32, 9> {
    var acc: array<f32, 9>;
    for (var m = 0u; m < N_MAPS; m++) {
        acc[m] = 0.0;
    }
    let e = stencils[st];
    let w = i32(cfg.width);
    for (var q = 0u; q < e.y; q++) {
        let r = runs[e.x + q];
        let y = cy + r.x;
        if y < 0 || y >= i32(cfg.height) {
            continue;
        }
        let xa = u32(clamp(cx + r.y, 0, w));
        let xb = u32(clamp(cx + r.z, 0, w));
        if xb <= xa {
            continue;
        }
        for (var m = m0; m < N_MAPS; m++) {
            let row = (m * cfg.height + u32(y)) * (cfg.width + 1u);
            acc[m] = acc[m] + (prefix[row + xb] - prefix[row + xa]);
        }
    }
    return acc;
}

// One side's gain with flow orientation t = (cos θ, sin θ).
fn gain(inner: array<f32, 9>, ring: vec4<f32>, w: f32, t: vec2<f32>) -> f32 {
    let c = t.x;
    let s = t.y;
    let q = c * c * inner[0] + 2.0 * c * s * inner[1] + s * s * inner[2];
    let c2 = c * c - s * s;
    let s2 = 2.0 * c * s;
    let ring_new = 0.5 * (ring.x - (ring.y * c2 + ring.z * s2));
    return inner[3] - q - w * (cfg.smooth * ring_new - ring.w);
}

fn ring_of(inner: array<f32, 9>, outer: array<f32, 9>) -> vec4<f32> {
    return vec4<f32>(outer[5] - inner[5], outer[6] - inner[6], outer[7] - inner[7], outer[8] - inner[8]);
}

fn prefix_rows(row: u32, m: u32) {
    if row >= cfg.height || m >= N_MAPS {
        return;
    }
    let src = m * cfg.width * cfg.height + row * cfg.width;
    let dst = (m * cfg.height + row) * (cfg.width + 1u);
    var acc = 0.0;
    prefix[dst] = 0.0;
    for (var x = 0u; x < cfg.width; x++) {
        acc = acc + maps[src + x];
        prefix[dst + x + 1u] = acc;
    }
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if cfg.mode == 0u {
        prefix_rows(gid.x, gid.y);
        return;
    }
    if gid.x >= cfg.nx || gid.y >= cfg.ny {
        return;
    }
    let cx = i32(gid.x * cfg.stride + cfg.stride / 2u);
    let cy = i32(gid.y * cfg.stride + cfg.stride / 2u);
    // Side angles π/3, π/2, 2π/3 in 15° steps.
    let phi = array<u32, 3>(4u, 6u, 8u);
    var top = NEG;
    var top_code = 0xffffffffu;
    for (var k = 0u; k < 12u; k++) {
        let t0 = trig[k];
        // Shape 0: 7 × 5, sides split at the axis.
        let il = box_sums(stencil(k, 0u, 0u, 0u), cx, cy, 0u);
        let ir = box_sums(stencil(k, 0u, 0u, 1u), cx, cy, 0u);
        let rl = ring_of(il, box_sums(stencil(k, 0u, 1u, 0u), cx, cy, 5u));
        let rr = ring_of(ir, box_sums(stencil(k, 0u, 1u, 1u), cx, cy, 5u));
        let wl = bitcast<f32>(stencils[stencil(k, 0u, 1u, 0u)].w);
        let wr = bitcast<f32>(stencils[stencil(k, 0u, 1u, 1u)].w);
        let nl = f32(stencils[stencil(k, 0u, 0u, 0u)].z);
        let nr = f32(stencils[stencil(k, 0u, 0u, 1u)].z);
        var cand = array<f32, 24>();
        var codes = array<u32, 24>();
        var n = 0u;
        if il[4] >= nl - 0.5 && ir[4] >= nr - 0.5 {
            // e: stream line, both sides along the axis (axes k and k + 12 are the same).
            cand[n] = gain(il, rl, wl, t0) + gain(ir, rr, wr, t0);
            codes[n] = k | (4u << 5u);
            n++;
            // c: occluding line, one side along the axis, the other turned by φ.
            for (var f = 0u; f < 3u; f++) {
                let p = phi[f];
                cand[n] = gain(il, rl, wl, t0) + gain(ir, rr, wr, trig[(k + p) % 24u]);
                codes[n] = k | (2u << 5u) | (f << 8u);
                n++;
                cand[n] = gain(il, rl, wl, trig[(k + 24u - p) % 24u]) + gain(ir, rr, wr, t0);
                codes[n] = k | (2u << 5u) | ((3u + f) << 8u);
                n++;
            }
        }
        // a, b with hair on the left of axis k (the right is the non-hair side) ...
        if il[4] >= cfg.hair_min * nl && ir[4] <= cfg.spill * nr {
            cand[n] = gain(il, rl, wl, t0);
            codes[n] = k;
            n++;
            for (var f = 0u; f < 3u; f++) {
                cand[n] = gain(il, rl, wl, trig[(k + 24u - phi[f]) % 24u]);
                codes[n] = k | (1u << 5u) | (f << 8u);
                n++;
            }
        }
        // ... and on the left of axis k + 12, the right side of axis k.
        if ir[4] >= cfg.hair_min * nr && il[4] <= cfg.spill * nl {
            cand[n] = gain(ir, rr, wr, t0);
            codes[n] = k + 12u;
            n++;
            for (var f = 0u; f < 3u; f++) {
                cand[n] = gain(ir, rr, wr, trig[(k + 24u - phi[f]) % 24u]);
                codes[n] = (k + 12u) | (1u << 5u) | (f << 8u);
                n++;
            }
        }
        // Shape 1: 7 × 6 with the strip, d: dividing line, sides turned by φ away from it.
        let jl = box_sums(stencil(k, 1u, 0u, 0u), cx, cy, 0u);
        let jr = box_sums(stencil(k, 1u, 0u, 1u), cx, cy, 0u);
        let ml = f32(stencils[stencil(k, 1u, 0u, 0u)].z);
        let mr = f32(stencils[stencil(k, 1u, 0u, 1u)].z);
        if jl[4] >= ml - 0.5 && jr[4] >= mr - 0.5 {
            let sl = ring_of(jl, box_sums(stencil(k, 1u, 1u, 0u), cx, cy, 5u));
            let sr = ring_of(jr, box_sums(stencil(k, 1u, 1u, 1u), cx, cy, 5u));
            let vl = bitcast<f32>(stencils[stencil(k, 1u, 1u, 0u)].w);
            let vr = bitcast<f32>(stencils[stencil(k, 1u, 1u, 1u)].w);
            for (var f = 0u; f < 3u; f++) {
                let p = phi[f];
                cand[n] = gain(jl, sl, vl, trig[(k + 24u - p) % 24u]) + gain(jr, sr, vr, trig[(k + p) % 24u]);
                codes[n] = k | (3u << 5u) | (f << 8u);
                n++;
            }
        }
        for (var q = 0u; q < n; q++) {
            let d = cand[q] - cfg.lambda_nc;
            if d > top {
                top = d;
                top_code = codes[q];
            }
        }
    }
    let o = gid.y * cfg.nx + gid.x;
    best[o] = top;
    code[o] = top_code;
}
