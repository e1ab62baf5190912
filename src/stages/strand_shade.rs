//! Per-vertex strand shading (C13 §4: highlights after Marschner et al. 2003, HSV recolour):
//! one invocation per vertex computes the strand tangent by central differences, recolours
//! the base colour in HSV and adds the highlight of every light. The CPU mirror below reads
//! like `wgsl/strand_shade.wgsl`, function for function (its sRGB and HSV functions, which
//! the shader includes from `wgsl/shared/colour.wgsl`, are in [`crate::base::colour::shader`]);
//! `crate::render::shade` is the host.
//!
//! Only `+ - * /`, `sqrt`, `exp`, `exp2`/`log2` (through [`pow_pos`]) and `floor` are used:
//! Mesa lowers `asin`/`acos` to short polynomials (errors near 1e-4), so both sides use the
//! same Abramowitz-Stegun arcsine ([`asin_as`]) and trigonometric identities instead.

use crate::base::colour::shader::hsv_adjust_linear;
use crate::base::colour::unit_or_zero;
use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use glam::Vec3;
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "strand_shade",
    wgsl: include_str!("../../wgsl/strand_shade.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: strand_shade_cpu,
};

/// Invocations per workgroup (1D).
pub const WORKGROUP: u32 = 64;

/// `Config::model` values.
pub const MODEL_MARSCHNER: u32 = 0;
pub const MODEL_KAJIYA_KAY: u32 = 1;

/// Bits of the per-vertex neighbour word: the vertex has a predecessor / successor in its
/// strand. Tangents never cross strands, so no strand offsets are needed on the device.
pub const HAS_PREV: u32 = 1;
pub const HAS_NEXT: u32 = 2;

/// Central differences shorter than 1 nm (squared, m²) count as degenerate tangents.
pub const MIN_LEN2: f32 = 1e-18;

/// Index of refraction of hair, Marschner et al. 2003 Table 1 (η = 1.55).
/// F0 = ((η - 1) / (η + 1))² for Schlick's Fresnel approximation (Karis 2016).
pub const F0: f32 = 0.046_520_57;
/// sqrt(2π), the normalisation of the unit-area Gaussian.
pub const SQRT_2PI: f32 = 2.506_628_3;
/// Kajiya-Kay specular weights of the primary (light-coloured) and secondary (hair-coloured)
/// highlights, Scheuermann 2004. 0.1 matches the peak of the Marschner R lobe
/// (π · M_R(0) · N_R(0) ≈ π · 3.05 · 0.25 · F0 ≈ 0.11 at β_R = 7.5°), so the two models give
/// highlights of similar strength for the same `amount`.
pub const KK_SPEC1: f32 = 0.1;
pub const KK_SPEC2: f32 = 0.1;

/// Everything a dispatch needs; all members 4-byte scalars so WGSL and encase agree.
#[derive(Clone, Copy, Debug, Default, PartialEq, encase::ShaderType)]
pub struct Config {
    pub n_vertices: u32,
    /// Invocations per dispatch row (`workgroups[0] * WORKGROUP`): vertex = y * stride + x.
    pub row_stride: u32,
    pub n_lights: u32,
    /// [`MODEL_MARSCHNER`] or [`MODEL_KAJIYA_KAY`].
    pub model: u32,
    /// Highlight scale (0 = no highlight).
    pub amount: f32,
    /// Weight of the Kajiya-Kay diffuse factor on the base colour (0 = base colour as is).
    pub diffuse: f32,
    /// 1 to apply the HSV adjustment, 0 to leave the base colour bit-exact.
    pub recolour: u32,
    /// Hue shift in degrees, reduced to [0, 360) by the host.
    pub hue_deg: f32,
    pub sat_scale: f32,
    pub val_scale: f32,
    /// Longitudinal shift α_R and width β_R of the R lobe, radians.
    pub alpha_r: f32,
    pub beta_r: f32,
    /// Unit direction toward the camera, model space.
    pub view_x: f32,
    pub view_y: f32,
    pub view_z: f32,
    pub _pad0: u32,
}

/// Workgroups covering `n` vertices, at most `max_x` per row (65535 on every backend), and
/// the row stride to put in [`Config::row_stride`].
pub fn workgroups(n: u32, max_x: u32) -> ([u32; 3], u32) {
    let groups = crate::gpu::engine::groups(n, WORKGROUP);
    let gx = groups.min(max_x.max(1));
    ([gx, groups.div_ceil(gx), 1], gx * WORKGROUP)
}

fn strand_shade_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_points, g_nbr, g_base, g_lights) = (
        b[1].get::<f32>(),
        b[2].get::<u32>(),
        b[3].get::<[f32; 4]>(),
        b[4].get::<[f32; 4]>(),
    );
    // Plain slices: the RefCell guards are not Sync, the data is.
    let (points, nbr): (&[f32], &[u32]) = (&g_points, &g_nbr);
    let (base, lights): (&[[f32; 4]], &[[f32; 4]]) = (&g_base, &g_lights);
    let mut out = b[5].get_mut::<[f32; 4]>();
    let n = cfg.n_vertices as usize;
    let point = |i: usize| Vec3::new(points[3 * i], points[3 * i + 1], points[3 * i + 2]);
    out[..n].par_iter_mut().enumerate().for_each(|(i, o)| {
        let prev = if nbr[i] & HAS_PREV != 0 { i - 1 } else { i };
        let next = if nbr[i] & HAS_NEXT != 0 { i + 1 } else { i };
        *o = shade_vertex(&cfg, lights, point(prev), point(next), base[i]);
    });
}

/// True for NaN or ±∞ (by bits, as the shader does, so no fast-math folding can hide it).
pub fn not_finite(x: f32) -> bool {
    x.to_bits() & 0x7f80_0000 == 0x7f80_0000
}

/// One vertex: `prev`/`next` are its neighbours in the strand (itself at an end).
pub fn shade_vertex(
    cfg: &Config,
    lights: &[[f32; 4]],
    prev: Vec3,
    next: Vec3,
    base: [f32; 4],
) -> [f32; 4] {
    let mut rgb = Vec3::new(
        unit_or_zero(base[0]),
        unit_or_zero(base[1]),
        unit_or_zero(base[2]),
    );
    let alpha = unit_or_zero(base[3]);
    if cfg.recolour != 0 {
        rgb = hsv_adjust_linear(rgb, cfg.hue_deg, cfg.sat_scale, cfg.val_scale);
    }
    let d = next - prev;
    let len2 = d.dot(d);
    // Degenerate or non-finite tangent: no lighting, the (recoloured) base colour stays.
    if not_finite(len2) || len2 <= MIN_LEN2 {
        return [rgb.x, rgb.y, rgb.z, alpha];
    }
    let t = d / len2.sqrt();
    let v = Vec3::new(cfg.view_x, cfg.view_y, cfg.view_z);
    let mut diff = Vec3::ZERO;
    let mut spec = Vec3::ZERO;
    for k in 0..cfg.n_lights as usize {
        let l = Vec3::new(lights[2 * k][0], lights[2 * k][1], lights[2 * k][2]);
        let e = Vec3::new(
            lights[2 * k + 1][0],
            lights[2 * k + 1][1],
            lights[2 * k + 1][2],
        );
        let sin_i = t.dot(l).clamp(-1.0, 1.0);
        // cos θ_i = sin(t, l): the Kajiya-Kay diffuse factor and Marschner's projected width.
        let cos_i = (1.0 - sin_i * sin_i).max(0.0).sqrt();
        diff += e * cos_i;
        if cfg.amount > 0.0 {
            let s = if cfg.model == MODEL_MARSCHNER {
                marschner(t, l, v, rgb, cfg.alpha_r, cfg.beta_r) * (std::f32::consts::PI * cos_i)
            } else {
                kajiya_kay(t, l, v, rgb, cfg.alpha_r, cfg.beta_r)
            };
            spec += e * s;
        }
    }
    let lit = rgb * (Vec3::splat(1.0 - cfg.diffuse) + diff * cfg.diffuse) + spec * cfg.amount;
    let o = lit.clamp(Vec3::ZERO, Vec3::ONE);
    [o.x, o.y, o.z, alpha]
}

/// x^y for y > 0 as the GPU computes it, with x floored at 1e-6 so 0^y and log2(0) never
/// appear (1e-6^y is below f32 resolution for the exponents used here).
pub fn pow_pos(x: f32, y: f32) -> f32 {
    (y * x.max(1e-6).log2()).exp2()
}

/// arcsin after Abramowitz and Stegun 4.4.46 (|error| ≤ 2e-8 on [-1, 1]).
#[allow(
    clippy::excessive_precision,
    reason = "the published coefficients, digit for digit as in the shader"
)]
pub fn asin_as(x: f32) -> f32 {
    let a = x.abs();
    let p = ((((((-0.001_262_491_1 * a + 0.006_670_090_1) * a - 0.017_088_125_6) * a
        + 0.030_891_881)
        * a
        - 0.050_174_304_6)
        * a
        + 0.088_978_987_4)
        * a
        - 0.214_598_801_6)
        * a
        + 1.570_796_305;
    let r = std::f32::consts::FRAC_PI_2 - (1.0 - a).max(0.0).sqrt() * p;
    if x < 0.0 {
        -r
    } else {
        r
    }
}

/// Unit-area Gaussian of standard deviation `beta` at `x`.
pub fn gauss(beta: f32, x: f32) -> f32 {
    (-0.5 * x * x / (beta * beta)).exp() / (SQRT_2PI * beta)
}

/// Schlick's Fresnel reflectance for η = 1.55 at incidence cosine `c`.
pub fn fresnel(c: f32) -> f32 {
    let m = 1.0 - c.clamp(0.0, 1.0);
    let m2 = m * m;
    F0 + (1.0 - F0) * m2 * m2 * m
}

/// The three Marschner lobes for unit tangent `t`, unit directions toward the light `l` and
/// the viewer `v`, absorption colour `c` (linear RGB), R-lobe shift/width `alpha`/`beta`
/// (radians). Values are the scattering function S_p (per steradian, before the cos θ_i
/// projection and the light's irradiance).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lobes {
    pub r: f32,
    pub tt: Vec3,
    pub trt: Vec3,
}

/// Marschner et al. 2003 with Karis 2016's real-time azimuthal terms:
/// S = Σ_p M_p(θ_h) · N_p(φ) · A_p, M_p = unit Gaussian g(β_p, θ_h − α_p) with
/// α_TT = −α_R/2, α_TRT = −3α_R/2, β_TT = β_R/2, β_TRT = 2β_R (Marschner Table 1), and
///  - R:   N·A = ¼ cos(φ/2) · F(√(½ + ½ l·v))
///  - TT:  N = exp(−3.65 cos φ − 3.98), A = (1 − F(cos θ_d √(1 − h²)))² · c^(½√(1 − (h/η')²) / cos θ_d),
///    h = cos(φ/2)(1 + (0.6 − 0.8 cos φ)/η'), η' = 1.19/cos θ_d + 0.36 cos θ_d
///  - TRT: N = exp(17 cos φ − 16.78), A = (1 − f)² f · c^(0.8 / cos θ_d), f = F(½ cos θ_d)
///
/// where c is the hair colour standing in for the absorption (Karis 2016, "Physically Based
/// Hair Shading in Unreal", SIGGRAPH course). Like Karis, the 1/cos² θ_d factor of Marschner's
/// S is dropped: it blows up at grazing angles and moves the R peak off θ_h = α_R.
pub fn marschner_lobes(t: Vec3, l: Vec3, v: Vec3, c: Vec3, alpha: f32, beta: f32) -> Lobes {
    let sin_i = t.dot(l).clamp(-1.0, 1.0);
    let sin_r = t.dot(v).clamp(-1.0, 1.0);
    let cos_i = (1.0 - sin_i * sin_i).max(0.0).sqrt();
    let cos_r = (1.0 - sin_r * sin_r).max(0.0).sqrt();
    let theta_h = 0.5 * (asin_as(sin_i) + asin_as(sin_r));
    // cos θ_d = cos((θ_r − θ_i)/2) = √((1 + cos(θ_r − θ_i))/2), floored so 1/cos θ_d is finite.
    let cos_d = (0.5 + 0.5 * (cos_r * cos_i + sin_r * sin_i))
        .max(0.0)
        .sqrt()
        .max(1e-3);
    // Relative azimuth φ from the projections on the normal plane; along the fibre it is
    // undefined and taken as 0 (the R/TRT side).
    let lp = l - t * sin_i;
    let vp = v - t * sin_r;
    let den = (lp.dot(lp) * vp.dot(vp)).sqrt();
    let cos_phi = if den > 1e-8 {
        (lp.dot(vp) / den).clamp(-1.0, 1.0)
    } else {
        1.0
    };
    let cos_half_phi = (0.5 + 0.5 * cos_phi).clamp(0.0, 1.0).sqrt();

    let m_r = gauss(beta, theta_h - alpha);
    let r = m_r * 0.25 * cos_half_phi * fresnel((0.5 + 0.5 * l.dot(v)).clamp(0.0, 1.0).sqrt());

    let m_tt = gauss(0.5 * beta, theta_h + 0.5 * alpha);
    let a = 1.0 / (1.19 / cos_d + 0.36 * cos_d);
    let h = cos_half_phi * (1.0 + a * (0.6 - 0.8 * cos_phi));
    let f_tt = fresnel(cos_d * (1.0 - h * h).clamp(0.0, 1.0).sqrt());
    let e_tt = 0.5 * (1.0 - (h * a) * (h * a)).clamp(0.0, 1.0).sqrt() / cos_d;
    let a_tt = (1.0 - f_tt) * (1.0 - f_tt);
    let n_tt = (-3.65 * cos_phi - 3.98).exp();
    let tt = pow3(c, e_tt) * (m_tt * n_tt * a_tt);

    let m_trt = gauss(2.0 * beta, theta_h + 1.5 * alpha);
    let f_trt = fresnel(0.5 * cos_d);
    let a_trt = (1.0 - f_trt) * (1.0 - f_trt) * f_trt;
    let n_trt = (17.0 * cos_phi - 16.78).exp();
    let trt = pow3(c, 0.8 / cos_d) * (m_trt * n_trt * a_trt);
    Lobes { r, tt, trt }
}

fn pow3(c: Vec3, e: f32) -> Vec3 {
    Vec3::new(pow_pos(c.x, e), pow_pos(c.y, e), pow_pos(c.z, e))
}

/// Sum of the Marschner lobes, as the shader adds them.
pub fn marschner(t: Vec3, l: Vec3, v: Vec3, c: Vec3, alpha: f32, beta: f32) -> Vec3 {
    let s = marschner_lobes(t, l, v, c, alpha, beta);
    Vec3::splat(s.r) + s.tt + s.trt
}

/// Kajiya-Kay specular with Scheuermann's two shifted highlights: with θ = asin(t·h),
/// h = normalize(l + v), the lobes are cos^p(θ − α): primary at α = α_R (light-coloured),
/// secondary at −1.5 α_R tinted by the hair colour (where Marschner puts R and TRT). The
/// exponents give each lobe the width of its Marschner Gaussian (cos^p x ≈ exp(−p x²/2),
/// so p = 1/β²): p₁ = 1/β_R², p₂ = 1/(2β_R)². Shifting θ is Scheuermann's tangent shift
/// taken along the normal in the (t, h) plane. Light exactly opposite the viewer: no lobe.
pub fn kajiya_kay(t: Vec3, l: Vec3, v: Vec3, c: Vec3, alpha: f32, beta: f32) -> Vec3 {
    let hv = l + v;
    let n2 = hv.dot(hv);
    if n2 < 1e-12 {
        return Vec3::ZERO;
    }
    let s = t.dot(hv / n2.sqrt()).clamp(-1.0, 1.0);
    let co = (1.0 - s * s).max(0.0).sqrt();
    // cos(θ − a) = cos θ cos a + sin θ sin a, with cos θ ≥ 0 since θ ∈ [−π/2, π/2].
    let a2 = -1.5 * alpha;
    let c1 = (co * alpha.cos() + s * alpha.sin()).max(0.0);
    let c2 = (co * a2.cos() + s * a2.sin()).max(0.0);
    let p1 = 1.0 / (beta * beta);
    let p2 = 0.25 * p1;
    Vec3::splat(KK_SPEC1 * pow_pos(c1, p1)) + c * (KK_SPEC2 * pow_pos(c2, p2))
}
