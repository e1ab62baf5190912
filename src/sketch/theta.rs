//! The orientation field Θ of CZ06 Step 1 (§4.1): the minimiser over the free hair pixels of
//!
//! ```text
//! E1 + E2 = Σ (∇_θ I_H)² / 2σθ²  +  Σ_edges (1/2λθ²) (1 − cos 2(θu − θv))
//! ```
//!
//! (Eq. 20-21; an edge joins 4-neighbours on the hair, and costs nothing when both ends are
//! held by the sketch), with the sketch's pixels clamped to the orientation it paints (Eq. 8)
//! and the pixels off the hair left out. With s = |∇I_H|, θo the gradient angle + π/2 and
//! A = s²/4σθ², a pixel's terms are A (1 − cos(2θ − 2θo)) + Σ_u (1/2λθ²)(1 − cos 2(θ − θu)).
//! The paper's Eq. 25 has both signs wrong (as printed the flow climbs this energy; the
//! test `printed_eq25_climbs_the_energy_and_the_corrected_flow_descends` shows it); the
//! descent is dθ/dt = 2A sin(2θo − 2θ) + (1/λθ²) Σ sin(2θu − 2θ) (the paper's coefficients,
//! s²/4σθ² and ½ for λθ = 1, are this flow at half speed; the reading notes' corrected flow
//! halves only the second term). Its nonlinear Gauss-Seidel update, exact per pixel, is
//! 2θv = arg(A e^{2iθo} + (1/2λθ²) Σ e^{2iθu}), run red-black as the WGSL pass `cz_theta_gs`
//! (one colour's pixels never neighbour each other, so each half-sweep is an exact
//! coordinate descent and the energy cannot rise).
//!
//! The paper's own rewrite counts an edge between a free pixel and a sketch pixel once and
//! an edge between two free pixels twice (Σ over v of Σ over its neighbours); here every edge
//! counts once, which is what the update above minimises. The contrast term of E2
//! (−log p(ρ), ρ depending on Θ) is left out of the diffusion, as the paper does.
//!
//! σθ² is the maximum-likelihood value of Eq. 20 under the warm start, coif's Gabor
//! orientation: the mean of (∇_θ I_H)² over the hair. λθ defaults to 0.25, not the 1 the
//! paper's rewrite implies ([`DEFAULT_LAMBDA_THETA`]); the derivative is Scharr-smoothed
//! ([`gradients`]).

use super::prim::Painted;
use crate::analyze::orient::GrayImage;
use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::stages::cz_theta_gs::{self, FIXED, FREE, OFF};

/// Parameters of the diffusion.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ThetaParams {
    /// Most sweeps (one sweep updates both colours). Default 300.
    pub max_sweeps: u32,
    /// Sweeps between convergence checks (each check reads the field back). Default 10.
    pub check_every: u32,
    /// Converged when no pixel turned by more than this over the last `check_every` sweeps,
    /// degrees. Default 0.05°.
    pub tol_deg: f32,
    /// σθ² of Eq. 20; None: the maximum-likelihood value under the warm start.
    pub sigma2: Option<f32>,
    /// λθ of Eq. 10 and 21-22: an edge costs (1 − cos 2Δθ)/4λθ² per end. The paper's
    /// rewrite of the energy implies 1; see `DEFAULT_LAMBDA_THETA` for ours.
    pub lambda_theta: f32,
}

/// λθ by default. With the paper's λθ = 1 and σθ² by maximum likelihood the per-pixel
/// gradients dominate and Θ∅ is noisy: mean error against the ground truth of `coif synth`
/// at 256², seed 1 (long / whorl / sidepart / short) 7.5° / 10.6° / 9.3° / 11.1° with
/// λθ = 1, 4.9° / 6.0° / 6.6° / 6.8° with 0.5, 3.2° / 3.4° / 4.6° / 4.7° with 0.25, against
/// 2.3° / 3.8° / 3.4° / 5.3° for the Gabor field. 0.25 costs more sweeps (100-170) and
/// blurs orientation boundaries more where there is no sketch, which is what the sketch is
/// for. Measured by `tests/it/sketch_pursuit.rs` (`theta_smoothness_scan`, ignored by default).
pub const DEFAULT_LAMBDA_THETA: f32 = 0.25;

impl Default for ThetaParams {
    fn default() -> Self {
        ThetaParams {
            max_sweeps: 300,
            check_every: 10,
            tol_deg: 0.05,
            sigma2: None,
            lambda_theta: DEFAULT_LAMBDA_THETA,
        }
    }
}

impl ThetaParams {
    pub fn validate(&self) -> Result<()> {
        if self.check_every == 0 || self.check_every > 1000 {
            return Err(Error::Invalid(format!(
                "theta: check_every {} must be in 1..=1000",
                self.check_every
            )));
        }
        if self.max_sweeps > 100_000 {
            return Err(Error::Invalid(format!(
                "theta: max_sweeps {} is over 100000",
                self.max_sweeps
            )));
        }
        if !(self.tol_deg.is_finite() && self.tol_deg >= 0.0) {
            return Err(Error::Invalid(format!(
                "theta: tol_deg {} must be a number ≥ 0",
                self.tol_deg
            )));
        }
        if !(self.lambda_theta.is_finite()
            && self.lambda_theta >= 0.05
            && self.lambda_theta <= 100.0)
        {
            return Err(Error::Invalid(format!(
                "theta: lambda_theta {} must be in [0.05, 100]",
                self.lambda_theta
            )));
        }
        if let Some(s) = self.sigma2 {
            if !(s.is_finite() && s > 0.0) {
                return Err(Error::Invalid(format!(
                    "theta: sigma2 {s} must be a positive number"
                )));
            }
        }
        Ok(())
    }
}

/// The image side of the energy: gradients of I_H and the diffusion's data term.
#[derive(Clone, Debug)]
pub struct Field {
    pub width: u32,
    pub height: u32,
    pub hair: Vec<bool>,
    /// Central differences of I_H at ±1 px; a neighbour off the hair or the image is
    /// replaced by the pixel itself (a one-sided difference at the border).
    pub gx: Vec<f32>,
    pub gy: Vec<f32>,
    pub sigma2: f32,
    /// 1/λθ²: an edge costs `smooth`·½(1 − cos 2Δθ).
    pub smooth: f32,
    /// A = s²/4σθ² per pixel.
    pub a: Vec<f32>,
    /// A e^{2iθo} = −(gx² − gy², 2 gx gy)/4σθ² per pixel.
    pub data: Vec<[f32; 2]>,
}

/// Checks the common inputs and returns w*h.
fn check_inputs(high: &[f32], width: u32, height: u32, hair: &[bool]) -> Result<usize> {
    let n = width as usize * height as usize;
    if n == 0 {
        return Err(Error::Invalid(
            "theta: the image is empty (0 pixels)".into(),
        ));
    }
    if high.len() != n || hair.len() != n {
        return Err(Error::Invalid(format!(
            "theta: the image is {width}x{height} ({n} pixels) but the band has {} values and \
             the hair mask {}",
            high.len(),
            hair.len()
        )));
    }
    if !hair.iter().any(|&h| h) {
        return Err(Error::Invalid("theta: the hair mask is empty".into()));
    }
    if high.iter().zip(hair).any(|(v, &h)| h && !v.is_finite()) {
        return Err(Error::Invalid(
            "theta: the band has NaN or infinite values on the hair".into(),
        ));
    }
    Ok(n)
}

/// (gx, gy) of `high`: the project's one derivative for I_H (E1, ρ, the structure tensor).
/// Scharr-smoothed central differences: (I(x+1) − I(x−1))/2 averaged over rows y−1, y, y+1
/// with weights 3/16, 10/16, 3/16, and the same transposed for y; a neighbour off the hair or
/// the image takes the pixel's own value. Plain central differences are strongly anisotropic
/// on hair whose texture period nears 2-3 px: on `coif synth` long at 256² the orientation
/// of the raw gradient is off by 17.6° (s²-weighted mean) against 8.3° with this kernel, and
/// Θ∅ by 7.5° against 3.2° (λθ = 0.25).
pub fn gradients(high: &[f32], width: u32, height: u32, hair: &[bool]) -> (Vec<f32>, Vec<f32>) {
    let (w, h) = (width as usize, height as usize);
    let mut gx = vec![0.0f32; w * h];
    let mut gy = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if hair[i] {
                [gx[i], gy[i]] = gradient_at(high, width, height, x, y, |j| hair[j]);
            }
        }
    }
    (gx, gy)
}

/// The gradient of [`gradients`] at pixel (x, y): central differences at ±1 px smoothed
/// across by (3, 10, 3)/16, a tap off the image or where `inside` is false replaced by the
/// pixel's own value. Also what texture synthesis matches ρ with (`cz_contrast`, mode 2).
pub fn gradient_at(
    src: &[f32],
    width: u32,
    height: u32,
    x: usize,
    y: usize,
    inside: impl Fn(usize) -> bool,
) -> [f32; 2] {
    const ACROSS: [f32; 3] = [3.0 / 16.0, 10.0 / 16.0, 3.0 / 16.0];
    let (w, h) = (width as i64, height as i64);
    let i = y * width as usize + x;
    let at = |xx: i64, yy: i64| {
        if xx < 0 || yy < 0 || xx >= w || yy >= h {
            return src[i];
        }
        let j = (yy * w + xx) as usize;
        if inside(j) {
            src[j]
        } else {
            src[i]
        }
    };
    let (xi, yi) = (x as i64, y as i64);
    let (mut sx, mut sy) = (0.0f32, 0.0f32);
    for (k, &c) in ACROSS.iter().enumerate() {
        let o = k as i64 - 1;
        sx += c * 0.5 * (at(xi + 1, yi + o) - at(xi - 1, yi + o));
        sy += c * 0.5 * (at(xi + o, yi + 1) - at(xi + o, yi - 1));
    }
    [sx, sy]
}

/// σθ² by maximum likelihood (Eq. 20) under `theta`: the mean of (∇_θ I)² over the hair
/// pixels where θ is a number. Fails on a band without gradients along Θ (a uniform image).
pub fn sigma2_mle(gx: &[f32], gy: &[f32], hair: &[bool], theta: &[f32]) -> Result<f32> {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for i in 0..hair.len() {
        if hair[i] && theta[i].is_finite() {
            let g = gx[i] as f64 * (theta[i] as f64).cos() + gy[i] as f64 * (theta[i] as f64).sin();
            sum += g * g;
            n += 1;
        }
    }
    let s = if n > 0 { sum / n as f64 } else { 0.0 };
    if s.is_nan() || s <= 1e-12 {
        return Err(Error::Invalid(
            "theta: the hair region has no texture (the band is uniform along the warm-start \
             orientation, σθ² = 0); an image of hair is needed"
                .into(),
        ));
    }
    Ok(s as f32)
}

impl Field {
    pub fn new(
        high: &[f32],
        width: u32,
        height: u32,
        hair: &[bool],
        sigma2: f32,
        lambda_theta: f32,
    ) -> Result<Field> {
        check_inputs(high, width, height, hair)?;
        if !(lambda_theta.is_finite() && lambda_theta > 0.0) {
            return Err(Error::Invalid(format!(
                "theta: λθ {lambda_theta} must be a positive number"
            )));
        }
        if !(sigma2.is_finite() && sigma2 > 0.0) {
            return Err(Error::Invalid(format!(
                "theta: σθ² {sigma2} must be a positive number"
            )));
        }
        let (gx, gy) = gradients(high, width, height, hair);
        let k = 1.0 / (4.0 * sigma2);
        let a = gx
            .iter()
            .zip(&gy)
            .map(|(x, y)| (x * x + y * y) * k)
            .collect();
        let data = gx
            .iter()
            .zip(&gy)
            .map(|(x, y)| [-(x * x - y * y) * k, -(2.0 * x * y) * k])
            .collect();
        Ok(Field {
            width,
            height,
            hair: hair.to_vec(),
            gx,
            gy,
            sigma2,
            smooth: 1.0 / (lambda_theta * lambda_theta),
            a,
            data,
        })
    }

    pub fn len(&self) -> usize {
        self.hair.len()
    }

    pub fn is_empty(&self) -> bool {
        self.hair.is_empty()
    }

    /// The cost of an edge between double-angle vectors a and b.
    #[inline]
    pub fn edge(&self, a: [f32; 2], b: [f32; 2]) -> f32 {
        self.smooth * 0.5 * (1.0 - (a[0] * b[0] + a[1] * b[1]))
    }

    /// (∇_θ I)²/2σθ² at pixel i for the orientation with double-angle vector z.
    #[inline]
    pub fn e1(&self, i: usize, z: [f32; 2]) -> f32 {
        (self.a[i] - (self.data[i][0] * z[0] + self.data[i][1] * z[1])).max(0.0)
    }

    /// ρ = |∇⊥θ I| at pixel i for the orientation with double-angle vector z.
    #[inline]
    pub fn rho(&self, i: usize, z: [f32; 2]) -> f32 {
        let s2 = self.gx[i] * self.gx[i] + self.gy[i] * self.gy[i];
        (s2 - 2.0 * self.sigma2 * self.e1(i, z)).max(0.0).sqrt()
    }
}

/// (cos 2θ, sin 2θ).
pub fn to_z(theta: f32) -> [f32; 2] {
    [(2.0 * theta).cos(), (2.0 * theta).sin()]
}

/// The orientation in [0, π) of a double-angle vector.
pub fn from_z(z: [f32; 2]) -> f32 {
    super::wrap_pi(0.5 * z[1].atan2(z[0]))
}

/// Pixel flags for the pass: off the hair, free, or fixed where `painted` gives a θ.
pub fn flags(hair: &[bool], painted: Option<&Painted>) -> Vec<u32> {
    hair.iter()
        .enumerate()
        .map(|(i, &h)| {
            if !h {
                OFF
            } else if painted.is_some_and(|p| p.theta[i].is_finite()) {
                FIXED
            } else {
                FREE
            }
        })
        .collect()
}

/// The starting field: `warm` on the free pixels (where it is NaN, the pixel's own data
/// direction, or θ = 0 without one), the painted θ on fixed ones, zero off the hair.
pub fn initial_z(
    field: &Field,
    warm: &[f32],
    painted: Option<&Painted>,
    flags: &[u32],
) -> Vec<[f32; 2]> {
    (0..flags.len())
        .map(|i| match flags[i] {
            OFF => [0.0, 0.0],
            FIXED => to_z(
                painted
                    .expect("fixed pixels come from a painted sketch")
                    .theta[i],
            ),
            _ if warm[i].is_finite() => to_z(warm[i]),
            _ => {
                let d = field.data[i];
                let n = d[0].hypot(d[1]);
                if n > 0.0 {
                    [d[0] / n, d[1] / n]
                } else {
                    [1.0, 0.0]
                }
            }
        })
        .collect()
}

/// Runs `n` sweeps from `z` and returns the field.
pub fn sweeps(
    engine: &Engine,
    field: &Field,
    flags: &[u32],
    z: &[[f32; 2]],
    n: u32,
) -> Result<Vec<[f32; 2]>> {
    let mut rec = Recording::default();
    let (w, h) = (field.width, field.height);
    let data = rec.upload("coif.cz_theta.data", &field.data);
    let fl = rec.upload("coif.cz_theta.flags", flags);
    let a = rec.upload("coif.cz_theta.a", z);
    let b = rec.alloc(
        "coif.cz_theta.b",
        8 * w as u64 * h as u64,
        crate::base::sentinel::SENTINEL,
    );
    let cfgs = [0u32, 1].map(|parity| cz_theta_gs::Config {
        width: w,
        height: h,
        parity,
        half_smooth: 0.5 * field.smooth,
    });
    let u = cfgs.map(|c| rec.uniform("coif.cz_theta.cfg", &c));
    for _ in 0..n {
        rec.dispatch(
            &cz_theta_gs::STAGE,
            cz_theta_gs::workgroups(&cfgs[0]),
            &[u[0], data, fl, a, b],
            &[],
        );
        rec.dispatch(
            &cz_theta_gs::STAGE,
            cz_theta_gs::workgroups(&cfgs[1]),
            &[u[1], data, fl, b, a],
            &[],
        );
    }
    rec.download(a);
    let out = engine.run(rec)?.get::<[f32; 2]>(a);
    Ok(out[..flags.len()].to_vec())
}

/// A converged (or capped) diffusion.
#[derive(Clone, Debug)]
pub struct Solved {
    pub z: Vec<[f32; 2]>,
    pub sweeps: u32,
    pub converged: bool,
}

/// Sweeps from `z` until no pixel turns by more than `tol_deg` over `check_every` sweeps,
/// or `max_sweeps`.
pub fn solve(
    engine: &Engine,
    field: &Field,
    flags: &[u32],
    z: Vec<[f32; 2]>,
    max_sweeps: u32,
    p: &ThetaParams,
) -> Result<Solved> {
    // Two double-angle unit vectors differ by at most tol in θ when their dot product is at
    // least cos(2 tol).
    let min_dot = (2.0 * p.tol_deg.to_radians()).cos();
    let mut cur = z;
    let mut done = 0;
    while done < max_sweeps {
        let n = p.check_every.min(max_sweeps - done);
        let next = sweeps(engine, field, flags, &cur, n)?;
        done += n;
        let moved = next
            .iter()
            .zip(&cur)
            .zip(flags)
            .any(|((a, b), &f)| f == FREE && a[0] * b[0] + a[1] * b[1] < min_dot);
        cur = next;
        if !moved {
            return Ok(Solved {
                z: cur,
                sweeps: done,
                converged: true,
            });
        }
    }
    Ok(Solved {
        z: cur,
        sweeps: done,
        converged: false,
    })
}

/// E1 + the smoothness term of E2 over the hair for the field `z` (fixed pixels included in
/// E1; an edge between two fixed pixels costs nothing): what the sweeps lower.
pub fn energy(field: &Field, flags: &[u32], z: &[[f32; 2]]) -> f64 {
    let (w, h) = (field.width as usize, field.height as usize);
    let mut e = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if flags[i] == OFF {
                continue;
            }
            e += field.e1(i, z[i]) as f64;
            for j in [(x + 1 < w).then_some(i + 1), (y + 1 < h).then_some(i + w)]
                .into_iter()
                .flatten()
            {
                if flags[j] == OFF || (flags[i] == FIXED && flags[j] == FIXED) {
                    continue;
                }
                e += field.edge(z[i], z[j]) as f64;
            }
        }
    }
    e
}

/// Θ in [0, π) from the double-angle field; NaN off the hair.
pub fn theta_of(z: &[[f32; 2]], flags: &[u32]) -> Vec<f32> {
    z.iter()
        .zip(flags)
        .map(|(&v, &f)| if f == OFF { f32::NAN } else { from_z(v) })
        .collect()
}

/// Θ of CZ06 Step 1 (Eq. 25 corrected): `high` is the high band I_H (L* units), `hair` the
/// mask, `painted` the sketch's V_sk (its θ clamps the field), `warm`
/// the starting orientation (coif's Gabor field, `crate::analyze::orient::orient`). σθ² is
/// `p.sigma2` or the maximum-likelihood value under `warm`. Returns θ in [0, π), NaN off
/// the hair.
pub fn diffuse(
    engine: &Engine,
    high: &GrayImage,
    hair: &[bool],
    painted: Option<&Painted>,
    warm: &[f32],
    p: &ThetaParams,
) -> Result<Vec<f32>> {
    p.validate()?;
    let (width, height) = (high.width, high.height);
    let high = &high.data;
    let n = check_inputs(high, width, height, hair)?;
    if warm.len() != n {
        return Err(Error::Invalid(format!(
            "theta: the warm start has {} values, the image {n} pixels",
            warm.len()
        )));
    }
    if let Some(pt) = painted {
        if (pt.width, pt.height) != (width, height) {
            return Err(Error::Invalid(format!(
                "theta: the sketch is painted on {}x{}, the image is {width}x{height}",
                pt.width, pt.height
            )));
        }
    }
    let sigma2 = match p.sigma2 {
        Some(s) => s,
        None => {
            let (gx, gy) = gradients(high, width, height, hair);
            sigma2_mle(&gx, &gy, hair, warm)?
        }
    };
    let field = Field::new(high, width, height, hair, sigma2, p.lambda_theta)?;
    let fl = flags(hair, painted);
    let z0 = initial_z(&field, warm, painted, &fl);
    let solved = solve(engine, &field, &fl, z0, p.max_sweeps, p)?;
    Ok(theta_of(&solved.z, &fl))
}
