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
//   the corner, exactly the pixels `sketch::prim::window` visits. With the paper's
//   approximation (Θ+ ≈ Θ: the field around the window is not re-diffused, and the edges
//   leaving the window are left as they are) a side's gain is linear in its sums and in
//   z = (cos 2θ, sin 2θ) of the orientation θ it paints (Eq. 27):
//     gain(θ) = Σ base (+ Σ llr) − t(θ)ᵀ (Σ T) t(θ) = K + G·z,
//   base = E1 + half the smoothness of the pixels the window takes, llr = log p_sk − log
//   p_nsk of their contrast (stream lines only unless `llr_all`), T the structure tensor
//   over 2σθ². θ is a dictionary angle refined by r·3.75°, r in −8..7,
//   toward ½ arg G, the tensor's along-flow eigenvector (the gain falls with the angle from
//   it, so the allowed r nearest to it is the best). Every kind and side variant is scored
//   and the best δ = gain − λ_NC is kept with its code: axis step (0..23) | kind << 5 |
//   variant << 8 | (r_left + 8) << 11 | (r_right + 8) << 15. The host rescores the best
//   positions exactly.
//
// Maps (each width*height): 0 Txx, 1 Txy, 2 Tyy (over 2σθ², 0 where taken), 3 base, 4 llr (0
// where taken), 5 hair (1/0).

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
    // 1: the contrast term scores every kind's pixels (Eq. 21 as printed); 0: stream lines'.
    llr_all: u32,
    // 1: refine side angles by up to ±30° in 3.75° steps; 0: the pure dictionary.
    refine: u32,
    _pad1: u32,
}

const N_MAPS: u32 = 6u;
const NEG: f32 = -3.0e38;
const PI: f32 = 3.14159265358979;

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> maps: array<f32>;
@group(0) @binding(2) var<storage, read_write> prefix: array<f32>;
// (dy, dx0, dx1, 0): pixels (x + dx, y + dy) for dx in dx0..dx1.
@group(0) @binding(3) var<storage, read> runs: array<vec4<i32>>;
// Per stencil (k * 2 + shape) * 2 + side: (first run, runs, pixels, 0).
@group(0) @binding(4) var<storage, read> stencils: array<vec4<u32>>;
// (cos 2θ, sin 2θ) of θ = j·3.75°, j in 0..48.
@group(0) @binding(5) var<storage, read> ztab: array<vec2<f32>>;
@group(0) @binding(6) var<storage, read_write> best: array<f32>;
@group(0) @binding(7) var<storage, read_write> code: array<u32>;

fn stencil(k: u32, shape: u32, side: u32) -> u32 {
    return (k * 2u + shape) * 2u + side;
}

// Sums of the maps over stencil `st` at corner (cx, cy).
fn box_sums(st: u32, cx: i32, cy: i32) -> array<f32, 6> {
    var acc: array<f32, 6>;
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
        for (var m = 0u; m < N_MAPS; m++) {
            let row = (m * cfg.height + u32(y)) * (cfg.width + 1u);
            acc[m] = acc[m] + (prefix[row + xb] - prefix[row + xa]);
        }
    }
    return acc;
}

// A side's gain as K + G·z, and the orientation that maximises it in 3.75° units.
struct SideFit {
    k: f32,
    g: vec2<f32>,
    jstar: f32,
}

fn side_fit(inner: array<f32, 6>, llr: bool) -> SideFit {
    var f: SideFit;
    f.k = inner[3] - 0.5 * (inner[0] + inner[2]);
    if llr {
        f.k = f.k + inner[4];
    }
    f.g = vec2<f32>(-0.5 * (inner[0] - inner[2]), -inner[1]);
    f.jstar = atan2(f.g.y, f.g.x) * (24.0 / PI);
    return f;
}

// (gain, r + 8) of a side painting the dictionary orientation `base` (3.75° units) refined
// by sign·r: sign −1 on a left side (θ = axis − side angle), +1 on a right side.
fn side_gain(f: SideFit, base: i32, sign: i32) -> vec2<f32> {
    var r = 0;
    if cfg.refine == 1u {
        var o = f.jstar - f32(base);
        o = o - 48.0 * floor((o + 24.0) / 48.0);
        r = clamp(i32(floor(f32(sign) * o + 0.5)), -8, 7);
    }
    let j = ((base + sign * r) % 48 + 48) % 48;
    return vec2<f32>(f.k + dot(f.g, ztab[j]), f32(r + 8));
}

fn code_of(axis: u32, kind: u32, variant: u32, l: vec2<f32>, r: vec2<f32>) -> u32 {
    return axis | (kind << 5u) | (variant << 8u) | (u32(l.y) << 11u) | (u32(r.y) << 15u);
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
    // Side angles π/3, π/2, 2π/3 in 3.75° units.
    let phi = array<i32, 3>(16, 24, 32);
    let none = vec2<f32>(0.0, 8.0);
    var top = NEG;
    var top_code = 0xffffffffu;
    for (var k = 0u; k < 12u; k++) {
        let a = i32(4u * k);
        // Shape 0: 7 × 5, sides split at the axis.
        let il = box_sums(stencil(k, 0u, 0u), cx, cy);
        let ir = box_sums(stencil(k, 0u, 1u), cx, cy);
        let all = cfg.llr_all == 1u;
        let fl = side_fit(il, all);
        let fr = side_fit(ir, all);
        let nl = f32(stencils[stencil(k, 0u, 0u)].z);
        let nr = f32(stencils[stencil(k, 0u, 1u)].z);
        var cand = array<f32, 24>();
        var codes = array<u32, 24>();
        var n = 0u;
        if il[5] >= nl - 0.5 && ir[5] >= nr - 0.5 {
            // e: stream line, both sides along the axis (axes k and k + 12 are the same).
            let le = side_gain(side_fit(il, true), a, -1);
            let re = side_gain(side_fit(ir, true), a, 1);
            cand[n] = le.x + re.x;
            codes[n] = code_of(k, 4u, 0u, le, re);
            n++;
            let l0 = side_gain(fl, a, -1);
            let r0 = side_gain(fr, a, 1);
            // c: occluding line, one side along the axis, the other turned by φ.
            for (var f = 0u; f < 3u; f++) {
                let r1 = side_gain(fr, a + phi[f], 1);
                cand[n] = l0.x + r1.x;
                codes[n] = code_of(k, 2u, f, l0, r1);
                n++;
                let l1 = side_gain(fl, a - phi[f], -1);
                cand[n] = l1.x + r0.x;
                codes[n] = code_of(k, 2u, 3u + f, l1, r0);
                n++;
            }
        }
        // a, b with hair on the left of axis k (the right is the non-hair side) ...
        if il[5] >= cfg.hair_min * nl && ir[5] <= cfg.spill * nr {
            let l0 = side_gain(fl, a, -1);
            cand[n] = l0.x;
            codes[n] = code_of(k, 0u, 0u, l0, none);
            n++;
            for (var f = 0u; f < 3u; f++) {
                let l1 = side_gain(fl, a - phi[f], -1);
                cand[n] = l1.x;
                codes[n] = code_of(k, 1u, f, l1, none);
                n++;
            }
        }
        // ... and on the left of axis k + 12, which is the right side of axis k.
        if ir[5] >= cfg.hair_min * nr && il[5] <= cfg.spill * nl {
            let l0 = side_gain(fr, a, -1);
            cand[n] = l0.x;
            codes[n] = code_of(k + 12u, 0u, 0u, l0, none);
            n++;
            for (var f = 0u; f < 3u; f++) {
                let l1 = side_gain(fr, a - phi[f], -1);
                cand[n] = l1.x;
                codes[n] = code_of(k + 12u, 1u, f, l1, none);
                n++;
            }
        }
        // Shape 1: 7 × 6 with the strip, d: dividing line, sides turned by φ away from it.
        let jl = box_sums(stencil(k, 1u, 0u), cx, cy);
        let jr = box_sums(stencil(k, 1u, 1u), cx, cy);
        let ml = f32(stencils[stencil(k, 1u, 0u)].z);
        let mr = f32(stencils[stencil(k, 1u, 1u)].z);
        if jl[5] >= ml - 0.5 && jr[5] >= mr - 0.5 {
            let gl = side_fit(jl, all);
            let gr = side_fit(jr, all);
            for (var f = 0u; f < 3u; f++) {
                let l1 = side_gain(gl, a - phi[f], -1);
                let r1 = side_gain(gr, a + phi[f], 1);
                cand[n] = l1.x + r1.x;
                codes[n] = code_of(k, 3u, f, l1, r1);
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
