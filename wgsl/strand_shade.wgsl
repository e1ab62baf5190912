// Per-vertex strand shading (C13 §4): tangent by central differences along the strand
// (one-sided at the ends), base colour recoloured in HSV of its sRGB encoding, then
//   out = base' * (1 - diffuse + diffuse * Σ_k E_k cos θ_i) + amount * Σ_k E_k * spec_k
// with spec_k the Marschner et al. 2003 lobes (Karis 2016 azimuthal terms) times π cos θ_i,
// or Kajiya-Kay with two shifted highlights (Scheuermann 2004). Every constant and formula is
// documented on the CPU mirror, `src/stages/strand_shade.rs`, which this file follows line by
// line. Only arithmetic, sqrt, exp, exp2/log2 and floor: Mesa's asin is a coarse polynomial,
// so asin_as below is the same Abramowitz-Stegun fit the mirror uses.

struct Config {
    n_vertices: u32,
    row_stride: u32,
    n_lights: u32,
    model: u32,
    amount: f32,
    diffuse: f32,
    recolour: u32,
    hue_deg: f32,
    sat_scale: f32,
    val_scale: f32,
    alpha_r: f32,
    beta_r: f32,
    view_x: f32,
    view_y: f32,
    view_z: f32,
    _pad0: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
// Model-space positions, 3 floats per vertex.
@group(0) @binding(1) var<storage, read> points: array<f32>;
// Per vertex: bit 0 = has a predecessor in its strand, bit 1 = has a successor.
@group(0) @binding(2) var<storage, read> nbr: array<u32>;
// Linear straight RGBA per vertex.
@group(0) @binding(3) var<storage, read> base: array<vec4<f32>>;
// Two per light: (unit direction toward the light, model space, 0), (colour * intensity, 0).
@group(0) @binding(4) var<storage, read> lights: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> out: array<vec4<f32>>;

const PI: f32 = 3.14159265358979;
const HALF_PI: f32 = 1.57079632679490;
const F0: f32 = 0.04652057;
const SQRT_2PI: f32 = 2.5066283;
const KK_SPEC1: f32 = 0.1;
const KK_SPEC2: f32 = 0.1;
const MIN_LEN2: f32 = 1e-18;
const MODEL_MARSCHNER: u32 = 0u;

fn not_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) == 0x7f800000u;
}

fn is_nan(x: f32) -> bool {
    let b = bitcast<u32>(x);
    return (b & 0x7f800000u) == 0x7f800000u && (b & 0x007fffffu) != 0u;
}

fn unit_or_zero(x: f32) -> f32 {
    return select(clamp(x, 0.0, 1.0), 0.0, is_nan(x));
}

fn pow_pos(x: f32, y: f32) -> f32 {
    return exp2(y * log2(max(x, 1e-6)));
}

fn pow3(c: vec3<f32>, e: f32) -> vec3<f32> {
    return vec3<f32>(pow_pos(c.x, e), pow_pos(c.y, e), pow_pos(c.z, e));
}

fn asin_as(x: f32) -> f32 {
    let a = abs(x);
    let p = ((((((-0.0012624911 * a + 0.0066700901) * a - 0.0170881256) * a
        + 0.030891881) * a - 0.0501743046) * a + 0.0889789874) * a - 0.2145988016) * a
        + 1.570796305;
    let r = HALF_PI - sqrt(max(1.0 - a, 0.0)) * p;
    return select(r, -r, x < 0.0);
}

fn gauss(beta: f32, x: f32) -> f32 {
    return exp(-0.5 * x * x / (beta * beta)) / (SQRT_2PI * beta);
}

fn fresnel(c: f32) -> f32 {
    let m = 1.0 - clamp(c, 0.0, 1.0);
    let m2 = m * m;
    return F0 + (1.0 - F0) * m2 * m2 * m;
}

fn marschner(t: vec3<f32>, l: vec3<f32>, v: vec3<f32>, c: vec3<f32>, alpha: f32, beta: f32) -> vec3<f32> {
    let sin_i = clamp(dot(t, l), -1.0, 1.0);
    let sin_r = clamp(dot(t, v), -1.0, 1.0);
    let cos_i = sqrt(max(1.0 - sin_i * sin_i, 0.0));
    let cos_r = sqrt(max(1.0 - sin_r * sin_r, 0.0));
    let theta_h = 0.5 * (asin_as(sin_i) + asin_as(sin_r));
    let cos_d = max(sqrt(max(0.5 + 0.5 * (cos_r * cos_i + sin_r * sin_i), 0.0)), 1e-3);
    let lp = l - t * sin_i;
    let vp = v - t * sin_r;
    let den = sqrt(dot(lp, lp) * dot(vp, vp));
    var cos_phi = 1.0;
    if den > 1e-8 {
        cos_phi = clamp(dot(lp, vp) / den, -1.0, 1.0);
    }
    let cos_half_phi = sqrt(clamp(0.5 + 0.5 * cos_phi, 0.0, 1.0));

    let m_r = gauss(beta, theta_h - alpha);
    let r = m_r * 0.25 * cos_half_phi * fresnel(sqrt(clamp(0.5 + 0.5 * dot(l, v), 0.0, 1.0)));

    let m_tt = gauss(0.5 * beta, theta_h + 0.5 * alpha);
    let a = 1.0 / (1.19 / cos_d + 0.36 * cos_d);
    let h = cos_half_phi * (1.0 + a * (0.6 - 0.8 * cos_phi));
    let f_tt = fresnel(cos_d * sqrt(clamp(1.0 - h * h, 0.0, 1.0)));
    let e_tt = 0.5 * sqrt(clamp(1.0 - (h * a) * (h * a), 0.0, 1.0)) / cos_d;
    let a_tt = (1.0 - f_tt) * (1.0 - f_tt);
    let n_tt = exp(-3.65 * cos_phi - 3.98);
    let tt = pow3(c, e_tt) * (m_tt * n_tt * a_tt);

    let m_trt = gauss(2.0 * beta, theta_h + 1.5 * alpha);
    let f_trt = fresnel(0.5 * cos_d);
    let a_trt = (1.0 - f_trt) * (1.0 - f_trt) * f_trt;
    let n_trt = exp(17.0 * cos_phi - 16.78);
    let trt = pow3(c, 0.8 / cos_d) * (m_trt * n_trt * a_trt);
    return vec3<f32>(r) + tt + trt;
}

fn kajiya_kay(t: vec3<f32>, l: vec3<f32>, v: vec3<f32>, c: vec3<f32>, alpha: f32, beta: f32) -> vec3<f32> {
    let hv = l + v;
    let n2 = dot(hv, hv);
    if n2 < 1e-12 {
        return vec3<f32>(0.0);
    }
    let s = clamp(dot(t, hv / sqrt(n2)), -1.0, 1.0);
    let co = sqrt(max(1.0 - s * s, 0.0));
    let a2 = -1.5 * alpha;
    let c1 = max(co * cos(alpha) + s * sin(alpha), 0.0);
    let c2 = max(co * cos(a2) + s * sin(a2), 0.0);
    let p1 = 1.0 / (beta * beta);
    let p2 = 0.25 * p1;
    return vec3<f32>(KK_SPEC1 * pow_pos(c1, p1)) + c * (KK_SPEC2 * pow_pos(c2, p2));
}

#include "shared/colour.wgsl"

fn point(i: u32) -> vec3<f32> {
    return vec3<f32>(points[3u * i], points[3u * i + 1u], points[3u * i + 2u]);
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.y * cfg.row_stride + gid.x;
    if i >= cfg.n_vertices {
        return;
    }
    let b = base[i];
    var rgb = vec3<f32>(unit_or_zero(b.x), unit_or_zero(b.y), unit_or_zero(b.z));
    let alpha = unit_or_zero(b.w);
    if cfg.recolour != 0u {
        rgb = hsv_adjust_linear(rgb, cfg.hue_deg, cfg.sat_scale, cfg.val_scale);
    }
    let f = nbr[i];
    var prev = i;
    var next = i;
    if (f & 1u) != 0u {
        prev = i - 1u;
    }
    if (f & 2u) != 0u {
        next = i + 1u;
    }
    let d = point(next) - point(prev);
    let len2 = dot(d, d);
    // Degenerate or non-finite tangent: no lighting, the (recoloured) base colour stays.
    if not_finite(len2) || len2 <= MIN_LEN2 {
        out[i] = vec4<f32>(rgb, alpha);
        return;
    }
    let t = d / sqrt(len2);
    let v = vec3<f32>(cfg.view_x, cfg.view_y, cfg.view_z);
    var diff = vec3<f32>(0.0);
    var spec = vec3<f32>(0.0);
    for (var k = 0u; k < cfg.n_lights; k++) {
        let l = lights[2u * k].xyz;
        let e = lights[2u * k + 1u].xyz;
        let sin_i = clamp(dot(t, l), -1.0, 1.0);
        let cos_i = sqrt(max(1.0 - sin_i * sin_i, 0.0));
        diff += e * cos_i;
        if cfg.amount > 0.0 {
            var s: vec3<f32>;
            if cfg.model == MODEL_MARSCHNER {
                s = marschner(t, l, v, rgb, cfg.alpha_r, cfg.beta_r) * (PI * cos_i);
            } else {
                s = kajiya_kay(t, l, v, rgb, cfg.alpha_r, cfg.beta_r);
            }
            spec += e * s;
        }
    }
    let lit = rgb * (vec3<f32>(1.0 - cfg.diffuse) + diff * cfg.diffuse) + spec * cfg.amount;
    out[i] = vec4<f32>(clamp(lit, vec3<f32>(0.0), vec3<f32>(1.0)), alpha);
}
