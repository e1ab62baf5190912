//! The high band from the vector field (CZ06 §3.2): texture whose intensity varies little
//! along Θ and whose gradient across Θ has the magnitude ρ. Gibbs sampling of Eq. 12 is too
//! slow, so, as the paper does: start from white noise and repeat a fixed number of rounds of
//! 1. line-integral convolution along Θ (`cz_lic`: box weights over `half_len` px each way,
//!    RK2 with a sign-consistent tangent, staying on the hair),
//! 2. contrast matching across Θ (`cz_contrast`): measure |∇⊥Θ I| with the derivative the
//!    analysis defines ρ by (`theta::gradients`; bilinear central differences along the
//!    exact normal read 3-6% lower on these textures, so matching them left the band's
//!    contrast 4-12% over ρ as the analysis sees it), smooth it and ρ alike (Gaussian, σ `contrast_sigma`,
//!    `sep_blur`; both 0 off the hair, so the ratio is that of local means over the hair)
//!    and scale the band by ρ_s/ρ_cur, the gain clamped,
//! 3. high-pass (`cz_hipass`): subtract the band's local mean over the hair (normalised
//!    Gaussian, σ `highpass_sigma`, the analysis's σ_L by default).
//!
//! The noise is an integer hash of (seed, pixel) (`cz_noise`), the same on both backends.
//! Everything runs in one recording; only the final re-centring (a sum over the hair) is on
//! the CPU.
//!
//! The domain is the hair where the field has both Θ and ρ; the band is 0 elsewhere (hair
//! the fill could not reach included). The field's growth direction d is not used: the
//! texture of Eq. 12 depends on the orientation only.

use super::VectorField;
use crate::base::sentinel::SENTINEL;
use crate::error::{Error, Result};
use crate::gpu::engine::{BufProxy, Engine, Recording};
use crate::stages::{cz_contrast, cz_hipass, cz_lic, cz_noise, sep_blur};
use serde::Serialize;

#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TextureParams {
    /// Rounds of LIC, contrast matching and high-pass.
    pub rounds: u32,
    /// Streamline length each way of the LIC, px (RK2 steps of ≤ 1 px). 8 rather than the
    /// notes' 3-5: at 4 the streaks read as short worms on 256²-512² portraits; at 8 they
    /// read as strands and follow the field better (README, "coif synth-hair").
    pub half_len: f32,
    /// σ of the smoothing of the measured contrast, px.
    pub contrast_sigma: f32,
    /// Clamp of the gain ρ/ρ_cur per round.
    pub gain_min: f32,
    pub gain_max: f32,
    /// σ of the local mean the high-pass removes, px; 0: only the final re-centring.
    pub highpass_sigma: f32,
}

impl Default for TextureParams {
    fn default() -> Self {
        TextureParams {
            rounds: 8,
            half_len: 8.0,
            contrast_sigma: 1.5,
            gain_min: 0.25,
            gain_max: 4.0,
            highpass_sigma: 8.0,
        }
    }
}

impl TextureParams {
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("texture: {m}")));
        if self.rounds == 0 || self.rounds > 64 {
            return bad(format!("rounds must be in 1..=64, got {}", self.rounds));
        }
        if !(self.half_len.is_finite() && self.half_len > 0.0 && self.half_len <= 64.0) {
            return bad(format!(
                "half_len must be in (0, 64] px, got {}",
                self.half_len
            ));
        }
        if !(self.contrast_sigma.is_finite() && self.contrast_sigma > 0.0) {
            return bad(format!(
                "contrast_sigma must be positive, got {}",
                self.contrast_sigma
            ));
        }
        if !(self.gain_min.is_finite()
            && self.gain_max.is_finite()
            && 0.0 < self.gain_min
            && self.gain_min <= 1.0
            && self.gain_max >= 1.0)
        {
            return bad(format!(
                "the gain clamp must satisfy 0 < min ≤ 1 ≤ max, got [{}, {}]",
                self.gain_min, self.gain_max
            ));
        }
        if !(self.highpass_sigma.is_finite() && (0.0..=64.0).contains(&self.highpass_sigma)) {
            return bad(format!(
                "highpass_sigma must be in [0, 64] px, got {}",
                self.highpass_sigma
            ));
        }
        Ok(())
    }

    /// (steps, step length) of the LIC's RK2 integration.
    pub fn lic_steps(&self) -> (u32, f32) {
        let steps = self.half_len.ceil().max(1.0) as u32;
        (steps, self.half_len / steps as f32)
    }
}

/// What the passes read about the field, checked.
pub struct Inputs {
    pub width: u32,
    pub height: u32,
    /// 1 on the domain (hair with Θ and ρ).
    pub flags: Vec<u32>,
    /// (cos Θ, sin Θ) on the domain, 0 elsewhere.
    pub tang: Vec<[f32; 2]>,
    /// ρ on the domain, 0 elsewhere.
    pub rho: Vec<f32>,
    pub pixels: usize,
}

impl Inputs {
    pub fn new(field: &VectorField, hair: &[bool]) -> Result<Inputs> {
        let (w, h) = (field.width, field.height);
        let n = w as usize * h as usize;
        if n == 0 {
            return Err(Error::Invalid(
                "texture: the field is empty (0 pixels)".into(),
            ));
        }
        if hair.len() != n || field.theta.len() != n || field.rho.len() != n {
            return Err(Error::Invalid(format!(
                "texture: a {w}x{h} field ({n} px) with Θ of {} px, ρ of {} px and a hair \
                 mask of {} px",
                field.theta.len(),
                field.rho.len(),
                hair.len()
            )));
        }
        let (mut flags, mut tang, mut rho) = (vec![0u32; n], vec![[0.0f32; 2]; n], vec![0.0; n]);
        for k in 0..n {
            let (t, r) = (field.theta[k], field.rho[k]);
            if hair[k] && t.is_finite() && r.is_finite() {
                if r < 0.0 {
                    return Err(Error::Invalid(format!(
                        "texture: ρ = {r} < 0 at pixel ({}, {}); a contrast is a magnitude",
                        k % w as usize,
                        k / w as usize
                    )));
                }
                flags[k] = 1;
                tang[k] = [t.cos(), t.sin()];
                rho[k] = r;
            }
        }
        let pixels = flags.iter().filter(|&&f| f != 0).count();
        if pixels == 0 {
            return Err(Error::Invalid(
                "texture: no hair pixel has both Θ and ρ: nothing to synthesise".into(),
            ));
        }
        Ok(Inputs {
            width: w,
            height: h,
            flags,
            tang,
            rho,
            pixels,
        })
    }

    fn domain_f32(&self) -> Vec<f32> {
        self.flags.iter().map(|&f| f as f32).collect()
    }
}

/// The buffers every round binds.
struct Bufs {
    flags: BufProxy,
    tang: BufProxy,
    rho: BufProxy,
}

fn upload(rec: &mut Recording, inp: &Inputs) -> Bufs {
    Bufs {
        flags: rec.upload("coif.texture.flags", &inp.flags),
        tang: rec.upload("coif.texture.tang", &inp.tang),
        rho: rec.upload("coif.texture.rho", &inp.rho),
    }
}

fn record_lic(
    rec: &mut Recording,
    inp: &Inputs,
    b: &Bufs,
    steps: u32,
    h: f32,
    src: BufProxy,
    dst: BufProxy,
) {
    let cfg = cz_lic::Config {
        width: inp.width,
        height: inp.height,
        steps,
        h,
    };
    let u = rec.uniform("coif.cz_lic.cfg", &cfg);
    rec.dispatch(
        &cz_lic::STAGE,
        cz_lic::workgroups(&cfg),
        &[u, b.flags, b.tang, src, dst],
        &[],
    );
}

/// `iterations` LIC passes of `src` along the field with streamlines of `half_len` px each
/// way (the first step of [`synthesise`], on its own: for the bench and the tests).
pub fn lic(
    engine: &Engine,
    field: &VectorField,
    hair: &[bool],
    src: &[f32],
    half_len: f32,
    iterations: u32,
) -> Result<Vec<f32>> {
    let inp = Inputs::new(field, hair)?;
    let p = TextureParams {
        half_len,
        ..Default::default()
    };
    p.validate()?;
    if src.len() != inp.flags.len() {
        return Err(Error::Invalid(format!(
            "texture: an image of {} px for a {}x{} field",
            src.len(),
            inp.width,
            inp.height
        )));
    }
    let (steps, h) = p.lic_steps();
    let n = inp.flags.len() as u64;
    let mut rec = Recording::default();
    let b = upload(&mut rec, &inp);
    let mut cur = rec.upload("coif.texture.src", src);
    let mut other = rec.alloc("coif.texture.lic", 4 * n, SENTINEL);
    for _ in 0..iterations {
        record_lic(&mut rec, &inp, &b, steps, h, cur, other);
        std::mem::swap(&mut cur, &mut other);
    }
    rec.download(cur);
    Ok(engine.run(rec)?.get::<f32>(cur))
}

/// The high band I_H for `field` (L* units, zero mean over the domain, 0 off it): see the
/// module docs. Same inputs and seed → the same bits on a backend.
pub fn synthesise(
    engine: &Engine,
    field: &VectorField,
    hair: &[bool],
    seed: u64,
    p: &TextureParams,
) -> Result<Vec<f32>> {
    p.validate()?;
    let inp = Inputs::new(field, hair)?;
    let (w, h) = (inp.width, inp.height);
    let n = inp.flags.len();
    let bytes = 4 * n as u64;
    let mean_rho = inp.rho.iter().map(|&r| r as f64).sum::<f64>() / inp.pixels as f64;

    let mut rec = Recording::default();
    let b = upload(&mut rec, &inp);
    // ρ blurred as the measured contrast will be (ρ is 0 off the domain).
    let rho_s = rec.alloc("coif.texture.rho_s", bytes, SENTINEL);
    sep_blur::record_gaussian(&mut rec, b.rho, rho_s, w, h, p.contrast_sigma);
    // The normaliser of the high-pass's masked blur: the domain indicator blurred.
    let den_hp = (p.highpass_sigma > 0.0).then(|| {
        let dom = rec.upload("coif.texture.domain", &inp.domain_f32());
        let d = rec.alloc("coif.texture.den_highpass", bytes, SENTINEL);
        sep_blur::record_gaussian(&mut rec, dom, d, w, h, p.highpass_sigma);
        d
    });

    // Uniform noise of half-width a has mean |central difference| ≈ a/3: start near ρ.
    let ncfg = cz_noise::Config::new(w, h, seed, (3.0 * mean_rho) as f32);
    let nu = rec.uniform("coif.cz_noise.cfg", &ncfg);
    let mut cur = rec.alloc("coif.texture.band", bytes, SENTINEL);
    rec.dispatch(
        &cz_noise::STAGE,
        cz_noise::workgroups(&ncfg),
        &[nu, b.flags, cur],
        &[],
    );
    let mut other = rec.alloc("coif.texture.band2", bytes, SENTINEL);
    let meas = rec.alloc("coif.texture.measure", bytes, SENTINEL);
    let meas_s = rec.alloc("coif.texture.measure_s", bytes, SENTINEL);
    let mean = rec.alloc("coif.texture.mean", bytes, SENTINEL);

    let (steps, step) = p.lic_steps();
    let ccfg = |mode| cz_contrast::Config {
        width: w,
        height: h,
        mode,
        gain_min: p.gain_min,
        gain_max: p.gain_max,
        ..Default::default()
    };
    let (cm, cg) = (ccfg(cz_contrast::MEASURE_GRADIENT), ccfg(cz_contrast::GAIN));
    let (um, ug) = (
        rec.uniform("coif.cz_contrast.cfg", &cm),
        rec.uniform("coif.cz_contrast.cfg", &cg),
    );
    let hcfg = cz_hipass::Config {
        width: w,
        height: h,
        ..Default::default()
    };
    let uh = rec.uniform("coif.cz_hipass.cfg", &hcfg);
    for _ in 0..p.rounds {
        record_lic(&mut rec, &inp, &b, steps, step, cur, other);
        std::mem::swap(&mut cur, &mut other);
        // The measure's unused bindings (ρ_s, ρ_cur) still need buffers.
        rec.dispatch(
            &cz_contrast::STAGE,
            cz_contrast::workgroups(&cm),
            &[um, b.flags, b.tang, cur, rho_s, rho_s, meas],
            &[],
        );
        sep_blur::record_gaussian(&mut rec, meas, meas_s, w, h, p.contrast_sigma);
        rec.dispatch(
            &cz_contrast::STAGE,
            cz_contrast::workgroups(&cg),
            &[ug, b.flags, b.tang, cur, rho_s, meas_s, other],
            &[],
        );
        std::mem::swap(&mut cur, &mut other);
        if let Some(den) = den_hp {
            // `cur` is 0 off the domain, so its plain blur is the masked numerator.
            sep_blur::record_gaussian(&mut rec, cur, mean, w, h, p.highpass_sigma);
            rec.dispatch(
                &cz_hipass::STAGE,
                cz_hipass::workgroups(&hcfg),
                &[uh, b.flags, cur, mean, den, other],
                &[],
            );
            std::mem::swap(&mut cur, &mut other);
        }
    }
    rec.download(cur);
    let mut band = engine.run(rec)?.get::<f32>(cur);

    // Re-centre: one sum over the hair, sequential in f64 so it is deterministic: CPU.
    let sum: f64 = (0..n)
        .filter(|&k| inp.flags[k] != 0)
        .map(|k| band[k] as f64)
        .sum();
    let m = (sum / inp.pixels as f64) as f32;
    for (v, &f) in band.iter_mut().zip(&inp.flags) {
        *v = if f != 0 { *v - m } else { 0.0 };
    }
    Ok(band)
}

/// How well a band follows a field, over the domain (hair with Θ and ρ).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TextureStats {
    /// mean |∇⊥Θ I| / mean ρ, with the project's derivative (`theta::gradients`, the one
    /// the analysis measures ρ with).
    pub contrast_ratio: f64,
    /// Σ(∇_θ I)² / Σ(∇⊥ I)², same derivative.
    pub along_across: f64,
    /// mean |∇⊥Θ I| with the derivative the contrast pass matches (central differences of
    /// bilinear samples at ±1 px), over mean ρ.
    pub contrast_ratio_bilinear: f64,
    pub mean_across: f64,
    pub mean_rho: f64,
    /// Domain pixels.
    pub pixels: usize,
}

/// [`TextureStats`] of `img` (W*H) against `field` over `hair`. A measurement for tests and
/// reports, not fed from files: sizes that disagree are a caller's bug and panic; an empty
/// domain gives NaN ratios and 0 pixels. Light (one pass of differences and sums): CPU.
pub fn texture_stats(img: &[f32], field: &VectorField, hair: &[bool]) -> TextureStats {
    let n = field.width as usize * field.height as usize;
    assert!(
        img.len() == n && hair.len() == n && field.theta.len() == n && field.rho.len() == n,
        "texture_stats: image {} px, hair {} px, Θ {} px, ρ {} px for a {}x{} field",
        img.len(),
        hair.len(),
        field.theta.len(),
        field.rho.len(),
        field.width,
        field.height
    );
    let inp = match Inputs::new(field, hair) {
        Ok(i) => i,
        Err(_) => {
            return TextureStats {
                contrast_ratio: f64::NAN,
                along_across: f64::NAN,
                contrast_ratio_bilinear: f64::NAN,
                mean_across: f64::NAN,
                mean_rho: f64::NAN,
                pixels: 0,
            }
        }
    };
    let dom: Vec<bool> = inp.flags.iter().map(|&f| f != 0).collect();
    let (gx, gy) = super::theta::gradients(img, inp.width, inp.height, &dom);
    let d = crate::stages::cz_tex::Domain {
        width: inp.width,
        height: inp.height,
        flags: &inp.flags,
        tang: &inp.tang,
        src: img,
    };
    let w = inp.width as usize;
    let (mut across, mut across2, mut along2, mut bil, mut rho) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
    for k in (0..n).filter(|&k| dom[k]) {
        let [c, s] = inp.tang[k];
        let a = (-gx[k] * s + gy[k] * c) as f64;
        let l = (gx[k] * c + gy[k] * s) as f64;
        across += a.abs();
        across2 += a * a;
        along2 += l * l;
        rho += inp.rho[k] as f64;
        let p = [(k % w) as f32 + 0.5, (k / w) as f32 + 0.5];
        bil += crate::stages::cz_contrast::across(&d, k, p, [-s, c]) as f64;
    }
    let np = inp.pixels as f64;
    TextureStats {
        contrast_ratio: across / rho,
        along_across: along2 / across2,
        contrast_ratio_bilinear: bil / rho,
        mean_across: across / np,
        mean_rho: rho / np,
        pixels: inp.pixels,
    }
}

/// Σ(∇_θ I)² / Σ(∇⊥ I)² of `high` under `theta` over the hair pixels where Θ is defined,
/// with the project's derivative (`theta::gradients`): Eq. 12's along-Θ variance relative
/// to the contrast across, what the analysis stores in a sketch (`Sketch::along_across`)
/// and the grain restores. None without such a pixel or without any gradient across.
pub fn along_across(high: &[f32], theta: &[f32], hair: &[bool], w: u32, h: u32) -> Option<f32> {
    let dom: Vec<bool> = hair
        .iter()
        .zip(theta)
        .map(|(&m, t)| m && t.is_finite())
        .collect();
    let (gx, gy) = super::theta::gradients(high, w, h, &dom);
    let (mut along, mut across) = (0.0f64, 0.0f64);
    for k in (0..dom.len()).filter(|&k| dom[k]) {
        let (c, s) = (theta[k].cos(), theta[k].sin());
        let (a, x) = (gx[k] * c + gy[k] * s, -gx[k] * s + gy[k] * c);
        along += (a * a) as f64;
        across += (x * x) as f64;
    }
    (across > 0.0).then(|| (along / across) as f32)
}

/// What [`add_grain`] did.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Grain {
    /// The sketch's along/across ratio (the target).
    pub target: f32,
    /// The band's ratio under the field before and after.
    pub before: f32,
    pub after: f32,
    /// The grain's amplitude (L*, before the final rescaling) and that rescaling.
    pub amplitude: f32,
    pub rescale: f32,
}

/// Seed tag of the grain's noise (another draw than the band's).
const GRAIN_TAG: u64 = 0x6772_6169_6e00_0000;

/// Restores the along-Θ variation Eq. 12 gives the high band (`target`, the ratio
/// Σ(∇_θ I)²/Σ(∇⊥ I)² the analysis measured on the photo) where line-integral convolution
/// left too little: LIC averages along Θ, so a synthesised band is an order of magnitude
/// more coherent than hair in a photo (0.009 against 0.105 on short hair, 0.017 against
/// 0.180 on the chelsea crop), and a second analysis then sees curves in every streak end.
/// The grain is seeded noise (`cz_noise`'s hash) high-passed twice by a 3x3 box, (1 − B)²:
/// pixel-scale, where the derivative that measures the ratio sees it, with little energy
/// at the Gabor bank's 4 px wavelength, so the texture's orientation moves little (white
/// noise cost the chelsea crop 1.6° of it, (1 − B) 0.7°, (1 − B)² 0.4°). Its amplitude k
/// solves ratio(band + k·grain) = target exactly (the derivative is linear, so the ratio
/// is a quotient of two quadratics in k), then the band is rescaled so that its mean
/// contrast across Θ, matched to ρ, is what it was. A band already at or above the target
/// is left alone (None). Light (two 3x3 passes and sums over the pixels): CPU.
pub fn add_grain(
    band: &mut [f32],
    field: &VectorField,
    hair: &[bool],
    seed: u64,
    target: f32,
) -> Option<Grain> {
    if !(target.is_finite() && target > 0.0) {
        return None;
    }
    let inp = Inputs::new(field, hair).ok()?;
    let (w, h) = (inp.width, inp.height);
    let (wu, hu) = (w as usize, h as usize);
    let n = wu * hu;
    let dom: Vec<bool> = inp.flags.iter().map(|&f| f != 0).collect();
    let cfg = cz_noise::Config::new(w, h, seed ^ GRAIN_TAG, 1.0);
    let mut g: Vec<f32> = (0..n)
        .map(|k| {
            if dom[k] {
                cz_noise::noise_at(&cfg, k as u32)
            } else {
                0.0
            }
        })
        .collect();
    for _ in 0..2 {
        let b = crate::base::filter::box_mean(&g, wu, hu, 1);
        for (v, m) in g.iter_mut().zip(b) {
            *v -= m;
        }
    }
    for (v, &d) in g.iter_mut().zip(&dom) {
        if !d {
            *v = 0.0;
        }
    }
    let (bx, by) = super::theta::gradients(band, w, h, &dom);
    let (nx, ny) = super::theta::gradients(&g, w, h, &dom);
    // Along and across components of both gradients, and the sums the ratio needs.
    let (mut a_bb, mut a_bg, mut a_gg, mut x_bb, mut x_bg, mut x_gg) =
        (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
    let comp = |k: usize, gx: &[f32], gy: &[f32]| {
        let [c, s] = inp.tang[k];
        (
            (gx[k] * c + gy[k] * s) as f64,
            (-gx[k] * s + gy[k] * c) as f64,
        )
    };
    // The across components, kept for the rescaling below.
    let mut across = Vec::with_capacity(inp.pixels);
    for k in (0..n).filter(|&k| dom[k]) {
        let (ab, xb) = comp(k, &bx, &by);
        let (ag, xg) = comp(k, &nx, &ny);
        across.push((xb, xg));
        a_bb += ab * ab;
        a_bg += ab * ag;
        a_gg += ag * ag;
        x_bb += xb * xb;
        x_bg += xb * xg;
        x_gg += xg * xg;
    }
    if x_bb <= 0.0 {
        return None;
    }
    let t = target as f64;
    let before = a_bb / x_bb;
    if before >= t {
        return None;
    }
    // (a_gg − t x_gg) k² + 2 (a_bg − t x_bg) k + (a_bb − t x_bb) = 0: the constant term is
    // negative here, so with a positive leading coefficient there is one positive root.
    let (qa, qb, qc) = (a_gg - t * x_gg, 2.0 * (a_bg - t * x_bg), a_bb - t * x_bb);
    if qa <= 0.0 {
        return None;
    }
    let k = (-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
    if !(k.is_finite() && k > 0.0) {
        return None;
    }
    // Mean |∇⊥| before and after, to keep the contrast the band was matched to.
    let (mut m0, mut m1) = (0.0f64, 0.0f64);
    for &(xb, xg) in &across {
        m0 += xb.abs();
        m1 += (xb + k * xg).abs();
    }
    let rescale = if m1 > 0.0 { (m0 / m1) as f32 } else { 1.0 };
    let kf = k as f32;
    for ((v, q), &d) in band.iter_mut().zip(&g).zip(&dom) {
        if d {
            *v = rescale * (*v + kf * q);
        }
    }
    // Zero mean over the domain again (sequential f64, deterministic).
    let sum: f64 = (0..n).filter(|&k| dom[k]).map(|k| band[k] as f64).sum();
    let m = (sum / inp.pixels as f64) as f32;
    for (v, &d) in band.iter_mut().zip(&dom) {
        if d {
            *v -= m;
        }
    }
    let after = (a_bb + 2.0 * k * a_bg + k * k * a_gg) / (x_bb + 2.0 * k * x_bg + k * k * x_gg);
    Some(Grain {
        target,
        before: before as f32,
        after: after as f32,
        amplitude: kf,
        rescale,
    })
}
