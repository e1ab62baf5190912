// One warping step of the coarse-to-fine flow (Brox et al. 2004): frame b is sampled at
// q + u(q) for the current flow u, and the data term of pixel q is linearised there on the
// 2-channel feature images (channel c = w (cos 2θ, sin 2θ) of the orientation field):
//   r_c(U) = It_c + Ix_c (U.x - u.x) + Iy_c (U.y - u.y) = c0_c + Ix_c U.x + Iy_c U.y
// with It = b(q + u) - a(q) and the spatial derivatives averaged between the warped b and a
// (central differences; the average halves the bias of either alone).
//
// An orientation field is not carried like brightness: under the motion q -> q + u(q) a
// strand's tangent t turns to J t, J = I + ∇u (a head turning by 3° turns every θ by 3°,
// which moves the double-angle features by 2 sin 3° ≈ 0.1, more than the residual of a
// 1-px misalignment). So a's feature is transported before it is compared: θ is read back
// from the double angle, its tangent mapped by J (central differences of the current flow)
// and re-encoded with the same weight. J comes from the flow of the previous warp or level
// and is held fixed while `flow_solve` runs (lagged, like the warp itself). The pass writes
// (Ix, Iy, c0), each a vec2 over the two channels, so `flow_solve` can re-weight the
// residual at the current U without resampling. Where q + u leaves the image the pixel has
// no data term (all zero) and `flow_solve` fills it by smoothness.
//
// The bilinear samples of b at q + u and q + u ± (1, 0), (0, 1) share one 4x4 texel window,
// loaded once (on lavapipe each buffer access costs ~3 ns, arithmetic almost nothing).

struct Config {
    width: u32,
    height: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> a: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> b: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read> flow: array<vec2<f32>>;
// (Ix, Iy, c0) per pixel.
@group(0) @binding(4) var<storage, read_write> deriv: array<vec2<f32>>;

fn clamped(x: i32, y: i32) -> u32 {
    let cx = u32(clamp(x, 0, i32(cfg.width) - 1));
    let cy = u32(clamp(y, 0, i32(cfg.height) - 1));
    return cy * cfg.width + cx;
}

fn a_at(x: i32, y: i32) -> vec2<f32> {
    return a[clamped(x, y)];
}

fn flow_at(x: i32, y: i32) -> vec2<f32> {
    return flow[clamped(x, y)];
}

// The double-angle feature `f` = w (cos 2θ, sin 2θ) of a tangent mapped by the matrix with
// columns `c0`, `c1`, same weight w.
fn transport(f: vec2<f32>, c0: vec2<f32>, c1: vec2<f32>) -> vec2<f32> {
    let w = length(f);
    if w <= 0.0 {
        return vec2<f32>(0.0);
    }
    let th = 0.5 * atan2(f.y, f.x);
    let t = cos(th) * c0 + sin(th) * c1;
    let n2 = dot(t, t);
    if n2 <= 0.0 {
        return f;
    }
    return (w / n2) * vec2<f32>(t.x * t.x - t.y * t.y, 2.0 * t.x * t.y);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    let u = flow[i];
    let p = vec2<f32>(f32(gid.x), f32(gid.y)) + u;
    let hi = vec2<f32>(f32(cfg.width - 1u), f32(cfg.height - 1u));
    if !(p.x >= 0.0 && p.y >= 0.0 && p.x <= hi.x && p.y <= hi.y) {
        deriv[3u * i] = vec2<f32>(0.0);
        deriv[3u * i + 1u] = vec2<f32>(0.0);
        deriv[3u * i + 2u] = vec2<f32>(0.0);
        return;
    }
    let x0 = i32(floor(p.x));
    let y0 = i32(floor(p.y));
    let f = p - vec2<f32>(f32(x0), f32(y0));
    // Texels x0-1 .. x0+2, y0-1 .. y0+2, clamped (equal to clamping the sample coordinates).
    var t: array<vec2<f32>, 16>;
    for (var j = 0; j < 4; j++) {
        let yy = u32(clamp(y0 - 1 + j, 0, i32(cfg.height) - 1));
        for (var k = 0; k < 4; k++) {
            let xx = u32(clamp(x0 - 1 + k, 0, i32(cfg.width) - 1));
            t[4 * j + k] = b[yy * cfg.width + xx];
        }
    }
    // Bilinear sample with its top-left texel at window (k, j).
    var s: array<vec2<f32>, 5>;
    let offs = array<vec2<i32>, 5>(
        vec2<i32>(1, 1), vec2<i32>(2, 1), vec2<i32>(0, 1), vec2<i32>(1, 2), vec2<i32>(1, 0)
    );
    for (var n = 0; n < 5; n++) {
        let o = 4 * offs[n].y + offs[n].x;
        let top = mix(t[o], t[o + 1], f.x);
        let bot = mix(t[o + 4], t[o + 5], f.x);
        s[n] = mix(top, bot, f.y);
    }
    let x = i32(gid.x);
    let y = i32(gid.y);
    let ax = 0.5 * (a_at(x + 1, y) - a_at(x - 1, y));
    let ay = 0.5 * (a_at(x, y + 1) - a_at(x, y - 1));
    let ix = 0.5 * (0.5 * (s[1] - s[2]) + ax);
    let iy = 0.5 * (0.5 * (s[3] - s[4]) + ay);
    // Columns of J = I + ∇u.
    let du_dx = 0.5 * (flow_at(x + 1, y) - flow_at(x - 1, y));
    let du_dy = 0.5 * (flow_at(x, y + 1) - flow_at(x, y - 1));
    let at = transport(a[i], vec2<f32>(1.0, 0.0) + du_dx, vec2<f32>(0.0, 1.0) + du_dy);
    let it = s[0] - at;
    deriv[3u * i] = ix;
    deriv[3u * i + 1u] = iy;
    deriv[3u * i + 2u] = it - ix * u.x - iy * u.y;
}
