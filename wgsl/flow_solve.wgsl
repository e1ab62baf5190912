// One red-black half-sweep of SOR on the flow energy of one warping step,
//   E(U) = Σ_q ψ_d(|r(U_q)|²) + α Σ_{q~q'} ψ_s(|U_q - U_q'|²),
// r the 2-channel linearised residual from `flow_warp`, ψ(s²) = ε² (sqrt(1 + s²/ε²) - 1)
// the Charbonnier penalty scaled so that it is quadratic (s²/2) for s << ε and its weight
// ψ'(s²) = 1/(2 sqrt(1 + s²/ε²)) is 1/2 at 0 (ε = 0 selects the quadratic itself). The
// non-linearity is lagged (IRLS): the weights are taken at the current U, then each pixel
// of one colour solves its 2x2 normal equations
//   (w_d J + α Σ_j w_j) U = -w_d J0 + α Σ_j w_j U_j,
// J = Σ_c g_c g_cᵀ, J0 = Σ_c c0_c g_c, g_c = (Ix_c, Iy_c), over the 4-neighbours j (the
// per-link weight w_j of the robust smoothness is symmetric, so this is the gradient of E),
// and moves U by ω times the step. Neighbours all have the other colour: in place, race-free.
// Threads cover half the row: x = 2 gid.x + ((y + colour) & 1).

struct Config {
    width: u32,
    height: u32,
    colour: u32,
    _pad0: u32,
    alpha: f32,
    eps_data: f32,
    eps_smooth: f32,
    omega: f32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
// (Ix, Iy, c0) per pixel, from `flow_warp`.
@group(0) @binding(1) var<storage, read> deriv: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> flow: array<vec2<f32>>;

// Robust weight 1/sqrt(1 + s2/eps²); 1 (quadratic) when eps is 0.
fn robust(s2: f32, eps: f32) -> f32 {
    if eps > 0.0 {
        return inverseSqrt(1.0 + s2 / (eps * eps));
    }
    return 1.0;
}

fn add_nb(j: u32, u: vec2<f32>, sw: ptr<function, f32>, su: ptr<function, vec2<f32>>) {
    let uj = flow[j];
    let d = u - uj;
    let w = robust(dot(d, d), cfg.eps_smooth);
    *sw = *sw + w;
    *su = *su + w * uj;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let y = gid.y;
    let x = 2u * gid.x + ((y + cfg.colour) & 1u);
    if x >= cfg.width || y >= cfg.height {
        return;
    }
    let i = y * cfg.width + x;
    let u = flow[i];
    let ix = deriv[3u * i];
    let iy = deriv[3u * i + 1u];
    let c0 = deriv[3u * i + 2u];
    let r = c0 + ix * u.x + iy * u.y;
    let wd = robust(dot(r, r), cfg.eps_data);
    var sw = 0.0;
    var su = vec2<f32>(0.0);
    if x > 0u { add_nb(i - 1u, u, &sw, &su); }
    if x + 1u < cfg.width { add_nb(i + 1u, u, &sw, &su); }
    if y > 0u { add_nb(i - cfg.width, u, &sw, &su); }
    if y + 1u < cfg.height { add_nb(i + cfg.width, u, &sw, &su); }
    let s = cfg.alpha * sw;
    let a00 = wd * dot(ix, ix) + s;
    let a01 = wd * dot(ix, iy);
    let a11 = wd * dot(iy, iy) + s;
    let b0 = -wd * dot(c0, ix) + cfg.alpha * su.x;
    let b1 = -wd * dot(c0, iy) + cfg.alpha * su.y;
    let det = a00 * a11 - a01 * a01;
    if det > 0.0 {
        let un = vec2<f32>(a11 * b0 - a01 * b1, a00 * b1 - a01 * b0) / det;
        flow[i] = u + cfg.omega * (un - u);
    }
}
