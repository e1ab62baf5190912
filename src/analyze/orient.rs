//! Orientation stage (C13 §2.1 after Chai et al. 2012): DoG prefilter, Gabor bank, iterative
//! refinement on the confidence map, confidence-weighted smoothing of the double-angle field.
//!
//! The host records the passes; the engine runs them on the GPU or on the CPU mirrors. Images
//! whose buffers would exceed the largest binding are processed in tiles with a halo wide
//! enough that every kept pixel sees the same neighbourhood as in one piece.

use crate::error::{Error, Result};
use crate::gpu::engine::{BufProxy, Engine, Recording};
use crate::stages::{gabor, orient_fit, orient_moments, orient_resolve, sep_blur};

/// The fill word of output buffers (kept here for the callers that name it from this stage).
pub use crate::base::sentinel::SENTINEL;

/// Parameters of the orientation stage; defaults from DESIGN.md and C13 / Chai 2012.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct OrientParams {
    /// Fine and coarse sigmas of the difference-of-Gaussians prefilter; coarse 0 disables it.
    pub dog_sigma_fine: f32,
    pub dog_sigma_coarse: f32,
    pub kernel: gabor::Kernel,
    /// Refinement passes: the Gabor bank re-applied to the previous confidence map.
    pub refine_iters: u32,
    /// Sigma of the confidence-weighted smoothing of the double-angle field; 0 disables it.
    pub smooth_sigma: f32,
    /// What the smoothing fits to the double-angle field in its window.
    pub smooth_fit: SmoothFit,
    /// What weights the first pass's orientations in the smoothing.
    pub smooth_weight: SmoothWeight,
    /// Scale δ in degrees of the linear fit's robust second round (each orientation's weight
    /// divided by 1 + (Δ/δ)², Δ its angle to the first round's fit); 0: one round.
    pub smooth_robust_deg: f32,
    /// The robust fit's first round (its guide) weighs each orientation by its weight to
    /// this power: below 1, one high-contrast line across the flow (a parting's scalp line)
    /// cannot carry the guide, so the second round can tell it from the hair. Unused with
    /// one round.
    pub smooth_guide_power: f32,
    /// Radius (px) within which a whorl's spiral model replaces the smoothed field (blended
    /// out to twice it; see [`crate::analyze::singular`]); 0: no model. Used only with
    /// smoothing.
    pub singular_radius: f32,
    /// Responses at or below this are treated as no texture (confidence 0). Input gray
    /// values are in [0, 1].
    pub min_response: f32,
    /// A pixel whose responses spread by at most this share of the strongest is isotropic
    /// (flat, or only the kernels' DC response): no orientation, confidence 0.
    pub min_contrast: f32,
}

/// The model the smoothing fits to the confidence-weighted double-angle field in each
/// Gaussian window.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    clap::ValueEnum,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum SmoothFit {
    /// The weighted mean (a blur of w·(cos 2θ, sin 2θ)): leans toward the strongest strands
    /// in the window, which in a turning field is an angle error.
    Constant,
    /// A weighted least-squares plane (intercept and slope) per pixel, its intercept taken:
    /// unbiased to first order wherever the weight sits in the window.
    #[default]
    Linear,
}

/// The weight of each pixel's orientation (from the image, the first Gabor pass) in the
/// smoothing. The output confidence is the refined one either way.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    clap::ValueEnum,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum SmoothWeight {
    /// The image confidence squared (w0²): what the local linear fit prefers.
    #[default]
    Image,
    /// The image confidence times the last refinement pass's confidence (C13's "refined
    /// reciprocally"): what the weighted mean preferred.
    Refined,
}

/// Ridge on the linear fit's slope terms, in units of the window's second moment (σ²): keeps
/// a window whose weight lies along one strand from extrapolating (≤ 0.01° on the synthetic
/// cases against no ridge).
pub const FIT_RIDGE: f32 = 0.02;

impl Default for OrientParams {
    fn default() -> Self {
        OrientParams {
            dog_sigma_fine: 0.4,
            dog_sigma_coarse: 10.0,
            kernel: gabor::Kernel {
                sigma_x: 1.8,
                sigma_y: 2.4,
                lambda: 4.0,
                ksize: 17,
                n_orient: 32,
            },
            refine_iters: 3,
            smooth_sigma: 4.0,
            smooth_fit: SmoothFit::Linear,
            smooth_weight: SmoothWeight::Image,
            smooth_robust_deg: 5.0,
            smooth_guide_power: 0.25,
            singular_radius: 8.0,
            min_response: 1e-5,
            min_contrast: 1e-3,
        }
    }
}

impl OrientParams {
    pub fn validate(&self) -> Result<()> {
        let k = &self.kernel;
        let bad = |m: String| Err(Error::Invalid(m));
        if k.n_orient < 4 || k.n_orient > gabor::MAX_ORIENT || !k.n_orient.is_multiple_of(4) {
            return bad(format!(
                "--orientations {} must be a multiple of 4 in 4..={}",
                k.n_orient,
                gabor::MAX_ORIENT
            ));
        }
        if k.ksize < 3 || k.ksize.is_multiple_of(2) || k.ksize > 63 {
            return bad(format!("--ksize {} must be odd and in 3..=63", k.ksize));
        }
        if (k.n_pairs() * k.n_orient) as usize > gabor::WEIGHT_CAPACITY {
            return bad(format!(
                "--ksize {} with {} orientations needs {} weights; the bank holds {} \
                 (one 64 KiB uniform buffer)",
                k.ksize,
                k.n_orient,
                k.n_pairs() * k.n_orient,
                gabor::WEIGHT_CAPACITY
            ));
        }
        for (name, v) in [
            ("--sigma-x", k.sigma_x),
            ("--sigma-y", k.sigma_y),
            ("--lambda", k.lambda),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("{name} must be a positive number, got {v}"));
            }
        }
        for (name, v) in [
            ("--dog-fine", self.dog_sigma_fine),
            ("--dog-coarse", self.dog_sigma_coarse),
            ("--smooth", self.smooth_sigma),
            ("--smooth-robust", self.smooth_robust_deg),
            ("--singular-radius", self.singular_radius),
        ] {
            if !(v.is_finite() && (0.0..=64.0).contains(&v)) {
                return bad(format!("{name} must be in 0..=64, got {v}"));
            }
        }
        let gp = self.smooth_guide_power;
        if !(gp.is_finite() && (0.0..=2.0).contains(&gp)) {
            return bad(format!("--smooth-guide-power must be in 0..=2, got {gp}"));
        }
        if self.dog_sigma_coarse > 0.0 && self.dog_sigma_fine <= 0.0 {
            return bad("--dog-fine must be positive when --dog-coarse is".into());
        }
        if self.refine_iters > 16 {
            return bad(format!("--refine {} is over 16", self.refine_iters));
        }
        Ok(())
    }

    /// The Gabor pass's uniform for a `width` x `height` image (an ordinary, non-final pass).
    pub fn gabor_config(&self, width: u32, height: u32) -> gabor::Config {
        gabor::Config {
            width,
            height,
            half: self.kernel.half(),
            n_orient: self.kernel.n_orient,
            min_response: self.min_response,
            min_contrast: self.min_contrast,
            ..Default::default()
        }
    }

    /// Buffers of one pixel's worth the smoothing holds: the blur's 2x2, or the linear
    /// fit's moment planes (one binding).
    fn smooth_planes(&self) -> u64 {
        match (self.smooth_sigma > 0.0, self.smooth_fit) {
            (false, _) => 0,
            (true, SmoothFit::Constant) => 4,
            (true, SmoothFit::Linear) => orient_moments::PLANES as u64,
        }
    }

    /// Pixels a tile needs beyond what it keeps so kept pixels match a one-piece run.
    pub fn halo(&self) -> u32 {
        let blur_r = |s: f32| {
            if s > 0.0 {
                (3.0 * s).ceil().max(1.0) as u32
            } else {
                0
            }
        };
        let dog = if self.dog_sigma_coarse > 0.0 {
            blur_r(self.dog_sigma_coarse).max(blur_r(self.dog_sigma_fine))
        } else {
            0
        };
        dog + (self.refine_iters + 1) * self.kernel.half() + blur_r(self.smooth_sigma)
    }
}

/// A single-channel f32 image, row-major.
#[derive(Clone, Debug)]
pub struct GrayImage {
    pub width: u32,
    pub height: u32,
    pub data: Vec<f32>,
}

impl GrayImage {
    /// Rec. 709 luma of an 8-bit sRGB image, in [0, 1].
    pub fn from_rgb(img: &image::RgbImage) -> Self {
        let data = img
            .pixels()
            .map(|p| (0.2126 * p[0] as f32 + 0.7152 * p[1] as f32 + 0.0722 * p[2] as f32) / 255.0)
            .collect();
        GrayImage {
            width: img.width(),
            height: img.height(),
            data,
        }
    }

    fn crop(&self, x0: u32, y0: u32, w: u32, h: u32) -> Vec<f32> {
        let mut out = Vec::with_capacity((w * h) as usize);
        for y in y0..y0 + h {
            let s = (y * self.width + x0) as usize;
            out.extend_from_slice(&self.data[s..s + w as usize]);
        }
        out
    }
}

/// Orientation θ in [0, π) (x right, y down; NaN off the mask) and confidence (0 off it).
#[derive(Clone, Debug)]
pub struct OrientMap {
    pub width: u32,
    pub height: u32,
    pub theta: Vec<f32>,
    pub confidence: Vec<f32>,
    /// The whorls whose spiral model the field carries ([`crate::analyze::singular`]).
    pub whorls: Vec<crate::analyze::singular::Whorl>,
}

fn blur(
    rec: &mut Recording,
    src: BufProxy,
    minus: Option<BufProxy>,
    sigma: f32,
    w: u32,
    h: u32,
) -> BufProxy {
    let (radius, weights) = sep_blur::gaussian_weights(sigma);
    let wbuf = rec.upload("coif.blur.weights", &weights);
    let bytes = w as u64 * h as u64 * 4;
    let tmp = rec.alloc("coif.blur.tmp", bytes, SENTINEL);
    let out = rec.alloc("coif.blur.out", bytes, SENTINEL);
    for (axis, from, to) in [(0u32, src, tmp), (1, tmp, out)] {
        let sub = axis == 1 && minus.is_some();
        let cfg = sep_blur::Config {
            width: w,
            height: h,
            radius,
            axis,
            subtract: sub as u32,
            ..Default::default()
        };
        let ubuf = rec.uniform("coif.blur.cfg", &cfg);
        // An unused binding still needs a buffer; `from` is as good as any.
        let m = if sub { minus.unwrap() } else { from };
        rec.dispatch(
            &sep_blur::STAGE,
            sep_blur::workgroups(&cfg),
            &[ubuf, wbuf, from, m, to],
            &[],
        );
    }
    out
}

/// Records the whole stage for one tile and returns (theta, confidence) buffers.
fn record_tile(
    rec: &mut Recording,
    p: &OrientParams,
    gray: &[f32],
    mask: &[u32],
    w: u32,
    h: u32,
) -> (BufProxy, BufProxy) {
    let bytes = w as u64 * h as u64 * 4;
    let src = rec.upload("coif.orient.gray", gray);
    let cur = if p.dog_sigma_coarse > 0.0 {
        let coarse = blur(rec, src, None, p.dog_sigma_coarse, w, h);
        blur(rec, src, Some(coarse), p.dog_sigma_fine, w, h)
    } else {
        src
    };
    let k = &p.kernel;
    let weights = rec.upload("coif.gabor.weights", &k.pair_weights_padded());
    let cfg = p.gabor_config(w, h);
    let ubuf = rec.uniform("coif.gabor.cfg", &cfg);
    let last_cfg = rec.uniform(
        "coif.gabor.cfg.final",
        &gabor::Config {
            final_pass: match p.smooth_weight {
                SmoothWeight::Refined => 1,
                SmoothWeight::Image => 2,
            },
            ..cfg
        },
    );
    let mbuf = rec.upload("coif.orient.mask", mask);
    let constants = k.constants();
    let pass = |rec: &mut Recording, u, src, first: Option<(BufProxy, BufProxy)>| {
        let outs = [
            rec.alloc("coif.gabor.dx", bytes, SENTINEL),
            rec.alloc("coif.gabor.dy", bytes, SENTINEL),
            rec.alloc("coif.gabor.conf", bytes, SENTINEL),
        ];
        // Unread bindings still need a buffer; the source is as good as any.
        let (fx, fy) = first.unwrap_or((src, src));
        rec.dispatch(
            &gabor::STAGE,
            gabor::workgroups(&cfg),
            &[u, weights, src, mbuf, fx, fy, outs[0], outs[1], outs[2]],
            &constants,
        );
        outs
    };
    // Pass 0 filters the image; refinement passes filter the previous confidence map, and
    // the last one weights pass 0's orientation by the refined confidence (C13 §2.1: the
    // orientation and confidence maps refined reciprocally).
    let [dx0, dy0, mut conf] = pass(rec, ubuf, cur, None);
    for _ in 1..p.refine_iters {
        conf = pass(rec, ubuf, conf, None)[2];
    }
    // With no refinement the final pass re-filters the image, so the weight is w0².
    let last_src = if p.refine_iters == 0 { cur } else { conf };
    let [mut dx, mut dy, conf] = pass(rec, last_cfg, last_src, Some((dx0, dy0)));
    if p.smooth_sigma > 0.0 && p.smooth_fit == SmoothFit::Linear {
        return record_fit(rec, p, [dx, dy, conf, mbuf], w, h);
    }
    if p.smooth_sigma > 0.0 {
        dx = blur(rec, dx, None, p.smooth_sigma, w, h);
        dy = blur(rec, dy, None, p.smooth_sigma, w, h);
    }
    let rcfg = orient_resolve::Config {
        width: w,
        height: h,
        ..Default::default()
    };
    let rbuf = rec.uniform("coif.resolve.cfg", &rcfg);
    let theta = rec.alloc("coif.orient.theta", bytes, SENTINEL);
    let conf_out = rec.alloc("coif.orient.conf", bytes, SENTINEL);
    rec.dispatch(
        &orient_resolve::STAGE,
        orient_resolve::workgroups(&rcfg),
        &[rbuf, dx, dy, conf, mbuf, theta, conf_out],
        &[],
    );
    rec.download(theta);
    rec.download(conf_out);
    (theta, conf_out)
}

/// Records the local linear fit of the double-angle field (dx, dy) in Gaussian windows of
/// `p.smooth_sigma`, with its robust second round when `p.smooth_robust_deg` > 0 (the first
/// round, its guide, then weighs by the weights to `p.smooth_guide_power`), and
/// returns (theta, confidence) as [`record_tile`].
fn record_fit(
    rec: &mut Recording,
    p: &OrientParams,
    [dx, dy, conf, mask]: [BufProxy; 4],
    w: u32,
    h: u32,
) -> (BufProxy, BufProxy) {
    let bytes = w as u64 * h as u64 * 4;
    let (radius, seg_len, weights) = orient_moments::fit_weights(p.smooth_sigma);
    let wbuf = rec.upload("coif.fit.weights", &weights);
    let planes = rec.alloc(
        "coif.fit.moments",
        bytes * orient_moments::PLANES as u64,
        SENTINEL,
    );
    let fcfg = orient_fit::Config {
        width: w,
        height: h,
        radius,
        seg_len,
        ridge: FIT_RIDGE,
        ..Default::default()
    };
    let fu = rec.uniform("coif.fit.cfg", &fcfg);
    // (robust δ, weight power) per round.
    let rounds: &[(Option<f32>, f32)] = if p.smooth_robust_deg > 0.0 {
        &[
            (None, p.smooth_guide_power),
            (Some(p.smooth_robust_deg.to_radians()), 1.0),
        ]
    } else {
        &[(None, 1.0)]
    };
    let mut guide = None;
    let mut out = (dx, dx);
    for &(delta, power) in rounds {
        let mcfg = orient_moments::Config {
            width: w,
            height: h,
            radius,
            seg_len,
            robust: delta.is_some() as u32,
            delta: delta.unwrap_or(0.0),
            power,
            ..Default::default()
        };
        let mu = rec.uniform("coif.fit.moments.cfg", &mcfg);
        // Unread when not robust; `dx` is as good a buffer as any.
        let g = guide.unwrap_or(dx);
        rec.dispatch(
            &orient_moments::STAGE,
            orient_moments::workgroups(&mcfg),
            &[mu, wbuf, dx, dy, g, planes],
            &[],
        );
        let theta = rec.alloc("coif.orient.theta", bytes, SENTINEL);
        let conf_out = rec.alloc("coif.orient.conf", bytes, SENTINEL);
        rec.dispatch(
            &orient_fit::STAGE,
            orient_fit::workgroups(&fcfg),
            &[fu, wbuf, planes, conf, mask, theta, conf_out],
            &[],
        );
        guide = Some(theta);
        out = (theta, conf_out);
    }
    rec.download(out.0);
    rec.download(out.1);
    out
}

/// Largest tile side (kept pixels) whose padded tile has at most `max_px` pixels.
fn tile_side(max_px: u64, halo: u32) -> Option<u32> {
    let side = (max_px as f64).sqrt().floor() as u64;
    let keep = side.checked_sub(2 * halo as u64)?;
    (keep >= 16).then_some(keep.min(u32::MAX as u64) as u32)
}

/// Memory the cpu backend's tiles may take: past about 1500² px a tile gains little (the
/// halo is already under 20% of it) and an 8000² image must fit in a few GiB. A constant,
/// not a share of the budget, so results depend on the image and the options alone.
pub const CPU_TILE_BYTES: u64 = 1 << 30;

/// Bytes per pixel of a `w` x `h` tile on the cpu backend, from what holds them: the
/// recording's buffers (gray, DoG 2x2, mask, 3 per Gabor pass, smoothing 2x2 or the linear
/// fit's moment planes, theta and
/// confidence: 4 B each), their downloads (twice: the run's copy and the caller's), the
/// host's crop and mask (8 B); and, per pixel of the FFT size, the bank's kernel spectra
/// (n/2 complex), the responses (n f32), the image's spectrum and a product with its inverse's
/// transposes (4 complex).
pub fn cpu_bytes_per_px(p: &OrientParams, w: u32, h: u32) -> f64 {
    let passes = p.refine_iters as u64 + 1;
    // The robust round's first theta and confidence.
    let robust = 2 * (p.smooth_fit == SmoothFit::Linear && p.smooth_robust_deg > 0.0) as u64;
    let buffers = 4 * (1 + 4 + 1 + 3 * passes + p.smooth_planes() + robust + 2) + 2 * 8 + 8;
    let half = p.kernel.half() as usize;
    let (fw, fh) = (
        gabor::fft_size(w as usize + 2 * half),
        gabor::fft_size(h as usize + 2 * half),
    );
    let fft_ratio = (fw * fh) as f64 / (w as f64 * h as f64);
    let n = p.kernel.n_orient as u64;
    let gabor = (n / 2) * 8 + n * 4 + 4 * 8;
    buffers as f64 + fft_ratio * gabor as f64
}

/// The padded tile size (w, h, tiles) [`orient`] uses for a `w` x `h` image on `engine`.
pub fn tiling(engine: &Engine, w: u32, h: u32, p: &OrientParams) -> Result<(u32, u32, usize)> {
    let halo = p.halo();
    let limit = engine.max_binding_bytes();
    // The largest binding is the linear fit's moment planes where it runs.
    let mut max_px = limit / (4 * p.smooth_planes().max(1));
    if !engine.is_gpu() {
        // The FFT size of a large tile is within a few % of it; 1.1 bounds the ratio.
        let per_px = cpu_bytes_per_px(p, 4096, 4096) * 1.1;
        max_px = max_px.min((CPU_TILE_BYTES as f64 / per_px) as u64);
    }
    let (tw, th) = if w as u64 * h as u64 <= max_px {
        (w, h)
    } else {
        let side = tile_side(max_px, halo).ok_or_else(|| Error::TooLarge {
            what: format!(
                "an orientation tile of {0}x{0} px (16 kept + a {1} px halo each side)",
                16 + 2 * halo,
                halo
            ),
            needed: (16 + 2 * halo as u64).pow(2) * 4 * p.smooth_planes().max(1),
            limit,
            limit_name: "largest buffer binding".into(),
            unit: "bytes",
        })?;
        (side.min(w), side.min(h))
    };
    let tiles = w.div_ceil(tw) as usize * h.div_ceil(th) as usize;
    Ok((tw, th, tiles))
}

/// Peak bytes of one tile of [`orient`] for a `w` x `h` image on `engine` (the host's
/// side on the GPU: uploads and downloads).
pub fn tile_bytes(engine: &Engine, w: u32, h: u32, p: &OrientParams) -> Result<u64> {
    let (tw, th, tiles) = tiling(engine, w, h, p)?;
    let halo = if tiles > 1 { 2 * p.halo() } else { 0 };
    let (pw, ph) = ((tw + halo).min(w), (th + halo).min(h));
    let per_px = if engine.is_gpu() {
        8.0 + 2.0 * 8.0
    } else {
        cpu_bytes_per_px(p, pw, ph)
    };
    Ok((per_px * pw as f64 * ph as f64) as u64)
}

/// Runs the orientation stage. `mask` (one byte per pixel, nonzero on hair) limits the
/// output; without it every pixel is hair.
pub fn orient(
    engine: &Engine,
    img: &GrayImage,
    mask: Option<&[u8]>,
    p: &OrientParams,
) -> Result<OrientMap> {
    p.validate()?;
    let (w, h) = (img.width, img.height);
    if w == 0 || h == 0 {
        return Err(Error::Invalid("the image is empty (0 pixels)".into()));
    }
    if let Some(m) = mask {
        if m.len() != (w * h) as usize {
            return Err(Error::Invalid(format!(
                "mask has {} pixels, image has {}",
                m.len(),
                w * h
            )));
        }
    }
    if img.data.iter().any(|v| !v.is_finite()) {
        return Err(Error::Invalid(
            "the image has NaN or infinite values".into(),
        ));
    }
    let halo = p.halo();
    let (tw, th, _) = tiling(engine, w, h, p)?;
    let mut out = OrientMap {
        width: w,
        height: h,
        theta: vec![f32::NAN; (w * h) as usize],
        confidence: vec![0.0; (w * h) as usize],
        whorls: Vec::new(),
    };
    let tiles: Vec<(u32, u32)> = (0..h.div_ceil(th))
        .flat_map(|ty| (0..w.div_ceil(tw)).map(move |tx| (tx * tw, ty * th)))
        .collect();
    if tiles.len() > 1 {
        log::info!(
            "orientation: {}x{} image in {} tiles of {}x{} (+{} px halo) to stay within {} B per \
             binding{}",
            w,
            h,
            tiles.len(),
            tw,
            th,
            halo,
            engine.max_binding_bytes(),
            if engine.is_gpu() {
                String::new()
            } else {
                format!(" and {CPU_TILE_BYTES} B per tile")
            }
        );
    }
    for (x0, y0) in tiles {
        let (x1, y1) = ((x0 + tw).min(w), (y0 + th).min(h));
        let (px0, py0) = (x0.saturating_sub(halo), y0.saturating_sub(halo));
        let (px1, py1) = ((x1 + halo).min(w), (y1 + halo).min(h));
        let (pw, ph) = (px1 - px0, py1 - py0);
        let gray = img.crop(px0, py0, pw, ph);
        let mut tmask = vec![1u32; (pw * ph) as usize];
        if let Some(m) = mask {
            for y in 0..ph {
                for x in 0..pw {
                    tmask[(y * pw + x) as usize] =
                        (m[((py0 + y) * w + px0 + x) as usize] != 0) as u32;
                }
            }
        }
        let mut rec = Recording::default();
        let (tb, cb) = record_tile(&mut rec, p, &gray, &tmask, pw, ph);
        let dl = engine.run(rec)?;
        let (theta, conf) = (dl.get::<f32>(tb), dl.get::<f32>(cb));
        for y in y0..y1 {
            for x in x0..x1 {
                let s = ((y - py0) * pw + (x - px0)) as usize;
                let d = (y * w + x) as usize;
                out.theta[d] = theta[s];
                out.confidence[d] = conf[s];
            }
        }
    }
    // On the whole image, after the tiles: a whorl may straddle two.
    if p.smooth_sigma > 0.0 && p.singular_radius > 0.0 {
        let whorls = crate::analyze::singular::find(&out, p.singular_radius);
        for wh in &whorls {
            log::debug!(
                "orientation: whorl at ({:.1}, {:.1}), twist {:.1}°, ring residual {:.1}°",
                wh.centre[0],
                wh.centre[1],
                wh.twist.to_degrees(),
                wh.residual_deg
            );
        }
        crate::analyze::singular::apply(&mut out, &whorls, p.singular_radius);
        out.whorls = whorls;
    }
    Ok(out)
}
