//! Edge-aware spreading of sparse displacements into a dense field (W†_i of C13 §3).
//!
//! C13 spreads the motion of the reliable points with the edge-aware diffusion of Lang et
//! al. 2012; this uses the domain transform of Gastal & Oliveira 2011 (recursive-filter
//! variant, the filter Lang et al. build on): each sample's displacement, times its bilinear
//! splat weight, and the weight itself are filtered with the same edge-aware filter, and the
//! first is divided by the second ("normalised convolution"). Where every sample agrees the
//! result is that value exactly (up to rounding); across strong edges of the guide the
//! recursion hardly passes, so motions on either side stay apart.

use crate::analyze::orient::GrayImage;
use crate::base::sentinel::SENTINEL;
use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::stages::{dt_filter, sep_blur};

/// Parameters of [`spread`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct DiffuseParams {
    /// Spatial extent in pixels. Features are a few pixels to tens of pixels apart; the fill
    /// must reach across such gaps, so this is several spacings.
    pub sigma_s: f32,
    /// Range extent in guide units (channels in [0, 1]): a guide step of this size counts as
    /// `sigma_s` pixels of distance.
    pub sigma_r: f32,
    /// Gaussian blur of the guide before its edges are measured (0: none). The filter is to
    /// stop at region boundaries (hair against face or background), not at every strand:
    /// on raw hair texture each strand edge adds tens of pixels of distance and the weights
    /// of a few strands away underflow.
    pub guide_sigma: f32,
    /// Horizontal + vertical pass pairs, with sigma halving each time (G&O 2011 Eq. 14); 3
    /// removes most of the stripe artefacts of a single pair.
    pub iterations: u32,
}

impl Default for DiffuseParams {
    fn default() -> Self {
        DiffuseParams {
            sigma_s: 40.0,
            sigma_r: 0.1,
            guide_sigma: 2.0,
            iterations: 3,
        }
    }
}

impl DiffuseParams {
    pub fn validate(&self) -> Result<()> {
        if !(self.sigma_s.is_finite() && self.sigma_s > 0.0) {
            return Err(Error::Invalid(format!(
                "diffusion sigma_s must be a positive number of pixels, got {}",
                self.sigma_s
            )));
        }
        if !(self.sigma_r.is_finite() && self.sigma_r > 0.0) {
            return Err(Error::Invalid(format!(
                "diffusion sigma_r must be positive, got {}",
                self.sigma_r
            )));
        }
        if !(self.guide_sigma.is_finite() && (0.0..=32.0).contains(&self.guide_sigma)) {
            return Err(Error::Invalid(format!(
                "diffusion guide_sigma must be in 0..=32 pixels, got {}",
                self.guide_sigma
            )));
        }
        if !(1..=16).contains(&self.iterations) {
            return Err(Error::Invalid(format!(
                "diffusion iterations must be in 1..=16, got {}",
                self.iterations
            )));
        }
        Ok(())
    }

    /// The feedback coefficient a = exp(-√2 / σ_H,k) of iteration `k` (0-based), with
    /// σ_H,k = σ_s √3 2^(N-k-1) / √(4^N - 1) (G&O 2011 Eq. 14), as ln a.
    pub fn log_a(&self, k: u32) -> f32 {
        let n = self.iterations as f64;
        let sigma_k = self.sigma_s as f64 * 3f64.sqrt() * 2f64.powf(n - k as f64 - 1.0)
            / (4f64.powf(n) - 1.0).sqrt();
        (-(2f64.sqrt()) / sigma_k) as f32
    }
}

/// The edge guide: `channels` planes of width*height values (row-major), one after the other.
#[derive(Clone, Debug)]
pub struct Guide {
    pub width: u32,
    pub height: u32,
    pub channels: u32,
    pub data: Vec<f32>,
}

impl Guide {
    /// An 8-bit colour image, channels in [0, 1]: colour edges separate motions that luma
    /// alone would merge (hair against skin of similar brightness).
    pub fn from_rgb(img: &image::RgbImage) -> Self {
        Guide {
            width: img.width(),
            height: img.height(),
            channels: 3,
            data: (0..3)
                .flat_map(|c| img.pixels().map(move |p| p[c] as f32 / 255.0))
                .collect(),
        }
    }

    pub fn from_gray(img: &GrayImage) -> Self {
        Guide {
            width: img.width,
            height: img.height,
            channels: 1,
            data: img.data.clone(),
        }
    }
}

/// Spreads sparse displacements into a dense field on the guide's pixels, edge-aware with
/// respect to `guide` (the reference frame). `samples` are (position on the reference frame,
/// displacement), in pixels. Each sample is splatted bilinearly (on the CPU: a handful of
/// samples, a sequential scatter), then (d·w, w) is filtered with the domain transform and
/// d·w divided by w. A pixel no sample reaches (filtered weight underflows) is NaN; with no
/// samples at all, every pixel is.
pub fn spread(
    engine: &Engine,
    guide: &Guide,
    samples: &[([f32; 2], [f32; 2])],
    p: &DiffuseParams,
) -> Result<Vec<[f32; 2]>> {
    p.validate()?;
    let (w, h) = (guide.width, guide.height);
    let n = w as usize * h as usize;
    if n == 0 {
        return Err(Error::Invalid("the guide image is empty (0 pixels)".into()));
    }
    if guide.channels == 0 || guide.data.len() != n * guide.channels as usize {
        return Err(Error::Invalid(format!(
            "guide has {} values, expected {} pixels x {} channels",
            guide.data.len(),
            n,
            guide.channels
        )));
    }
    if guide.data.iter().any(|v| !v.is_finite()) {
        return Err(Error::Invalid(
            "the guide image has NaN or infinite values".into(),
        ));
    }
    let planes = splat(w, h, samples)?;
    if samples.is_empty() {
        return Ok(vec![[f32::NAN; 2]; n]);
    }
    let blurred;
    let guide = if p.guide_sigma > 0.0 {
        blurred = blur_guide(engine, guide, p.guide_sigma)?;
        &blurred
    } else {
        guide
    };
    let mut rec = Recording::default();
    let gbuf = rec.upload("coif.dt.guide", &guide.data);
    let pbuf = rec.upload("coif.dt.planes", &planes);
    for k in 0..p.iterations {
        for axis in [0u32, 1] {
            let cfg = dt_filter::Config {
                width: w,
                height: h,
                axis,
                channels: guide.channels,
                n_planes: 3,
                ratio: p.sigma_s / p.sigma_r,
                log_a: p.log_a(k),
                ..Default::default()
            };
            let u = rec.uniform("coif.dt.cfg", &cfg);
            rec.dispatch(
                &dt_filter::STAGE,
                dt_filter::workgroups(&cfg),
                &[u, gbuf, pbuf],
                &[],
            );
        }
    }
    rec.download(pbuf);
    let out: Vec<f32> = engine.run(rec)?.get(pbuf);
    if out.iter().any(|v| v.to_bits() == SENTINEL) {
        return Err(Error::Gpu("dt_filter left planes unwritten".into()));
    }
    Ok(normalise(&out, n))
}

/// The guide's planes each blurred by `sigma` (`sep_blur`, one engine run); a second run
/// filters with them, since `sep_blur` reads and writes whole buffers from offset 0.
pub fn blur_guide(engine: &Engine, guide: &Guide, sigma: f32) -> Result<Guide> {
    let (w, h) = (guide.width, guide.height);
    let n = w as usize * h as usize;
    let mut rec = Recording::default();
    let mut outs = Vec::new();
    for c in 0..guide.channels as usize {
        let src = rec.upload("coif.dt.guide_plane", &guide.data[c * n..(c + 1) * n]);
        let out = rec.alloc("coif.dt.guide_blurred", n as u64 * 4, SENTINEL);
        sep_blur::record_gaussian(&mut rec, src, out, w, h, sigma);
        rec.download(out);
        outs.push(out);
    }
    let dl = engine.run(rec)?;
    let mut data = Vec::with_capacity(guide.data.len());
    for out in outs {
        data.extend(dl.get::<f32>(out));
    }
    if data.iter().any(|v| v.to_bits() == SENTINEL) {
        return Err(Error::Gpu("sep_blur left guide pixels unwritten".into()));
    }
    Ok(Guide { data, ..*guide })
}

/// Bilinear splat of (dx·w, dy·w, w) into three planes. Samples outside the image, or with a
/// non-finite position or displacement, are refused: they would say nothing true.
pub fn splat(width: u32, height: u32, samples: &[([f32; 2], [f32; 2])]) -> Result<Vec<f32>> {
    let (w, h) = (width as usize, height as usize);
    let n = w * h;
    let mut planes = vec![0.0f32; 3 * n];
    for (k, &(pos, d)) in samples.iter().enumerate() {
        if !(pos.iter().chain(d.iter()).all(|v| v.is_finite())) {
            return Err(Error::Invalid(format!(
                "sample {k} has a non-finite position or displacement ({pos:?}, {d:?})"
            )));
        }
        let inside =
            (0.0..=(w - 1) as f32).contains(&pos[0]) && (0.0..=(h - 1) as f32).contains(&pos[1]);
        if !inside {
            return Err(Error::Invalid(format!(
                "sample {k} at ({}, {}) is outside the {width}x{height} image",
                pos[0], pos[1]
            )));
        }
        let (x0, y0) = (pos[0].floor() as usize, pos[1].floor() as usize);
        let (fx, fy) = (pos[0] - x0 as f32, pos[1] - y0 as f32);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        for (x, y, wt) in [
            (x0, y0, (1.0 - fx) * (1.0 - fy)),
            (x1, y0, fx * (1.0 - fy)),
            (x0, y1, (1.0 - fx) * fy),
            (x1, y1, fx * fy),
        ] {
            let i = y * w + x;
            planes[i] += wt * d[0];
            planes[n + i] += wt * d[1];
            planes[2 * n + i] += wt;
        }
    }
    Ok(planes)
}

/// Filtered (d·w, w) planes to displacements; NaN where the weight underflowed.
fn normalise(planes: &[f32], n: usize) -> Vec<[f32; 2]> {
    (0..n)
        .map(|i| {
            let wt = planes[2 * n + i];
            if wt > 1e-30 {
                [planes[i] / wt, planes[n + i] / wt]
            } else {
                [f32::NAN; 2]
            }
        })
        .collect()
}
