//! Dense flow V_i between consecutive frames, matched on their orientation fields (C13 §3:
//! "computed by matching the orientation fields", not the colours).
//!
//! **Features.** Each frame's [`OrientMap`] becomes a 2-channel image
//! `w · (cos 2θ, sin 2θ)` ([`orient_features`]): the double angle makes θ and θ + π the same
//! point, and the weight `w` (the confidence, normalised) makes pixels without a reliable
//! orientation contribute nothing to the data term.
//!
//! **Method.** Variational coarse-to-fine flow after Brox et al. 2004, with the choices
//! below (measured on the synthetic pairs of `tests/it/video_flow.rs`):
//! * pyramid by factor 2 (`flow_down`, a [1 3 3 1] tent per axis); the coarsest level's
//!   shorter side is at least [`FlowParams::min_size`];
//! * per level, [`FlowParams::warps`] warping steps (`flow_warp`): b sampled at q + u(q),
//!   the residual linearised on both channels, derivatives averaged between warped b and a;
//! * per warp, [`FlowParams::iters`] red-black SOR sweeps (`flow_solve`, two dispatches
//!   each) of a robust energy: Charbonnier data term on the 2-channel residual plus α times
//!   a Charbonnier (TV-like, per link) smoothness, non-linearity lagged per sweep (IRLS);
//! * the flow doubled onto the next finer level (`flow_up`);
//! * at the finest level, the last warping step matched on the strand texture alone
//!   ([`FlowFeatures`] says why).
//!
//! Measured on those pairs and on the synthetic clips of `coif synth-video`
//! (`benches/flow_epe.rs`, 256², EPE on hair): the features are described and measured at
//! [`orient_features`] and [`feature_orient_params`]; α = 0.5 is a compromise between the
//! clips' small, smooth motion (α = 1: 0.23/0.13/0.15 px on long/whorl/sidepart, every 3rd
//! pair of seed 1, against 0.25/0.13/0.16 at 0.5) and the 3° turn of the test pairs (2.0 px at
//! α = 1, 0.38 at 0.5, 0.09 at 0.3). With the earlier features, quadratic and Charbonnier
//! smoothness were within 0.03 px on the test pairs (the robust one is kept for motion
//! boundaries) and 15 sweeps per warp within 0.02 px of 30 and 60 (on the clips too).
//!
//! Orientation features alone leave the motion along a straight strand unobserved (the
//! aperture problem): the smoothness term carries it in from where the strands curve, cross
//! or end, which is why α is not small. The data term is the orientation field only; no
//! gray-level term is added.
//!
//! Everything runs in one [`Recording`]: the CPU mirrors or the GPU replay the same passes.

use crate::analyze::orient::{OrientMap, OrientParams};
use crate::error::{Error, Result};
use crate::gpu::engine::{BufProxy, Engine, Recording};
use crate::stages::{flow_down, flow_solve, flow_up, flow_warp};

/// Fill word of the buffers every pass writes in full before anything reads them.
use crate::base::sentinel::SENTINEL;

/// Parameters of [`flow`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FlowParams {
    /// Most pyramid levels, the full-size level included. Fewer are used when halving again
    /// would make the shorter side smaller than `min_size`.
    pub levels: u32,
    /// Smallest shorter side of a pyramid level, in pixels.
    pub min_size: u32,
    /// Warping steps (re-linearisations) per level.
    pub warps: u32,
    /// Red-black SOR sweeps per warping step.
    pub iters: u32,
    /// Smoothness weight α, relative to the squared feature gradient (features are in
    /// [-1, 1]).
    pub alpha: f32,
    /// Charbonnier scale of the 2-channel data residual; 0 makes the data term quadratic.
    pub eps_data: f32,
    /// Charbonnier scale of the flow difference between 4-neighbours, in pixels of the
    /// level; 0 makes the smoothness quadratic (Horn–Schunck).
    pub eps_smooth: f32,
    /// SOR over-relaxation factor in (0, 2).
    pub omega: f32,
    /// Warping steps of the finest level, its last ones, that match the texture features
    /// ([`FlowFeatures::fine`]) rather than the mixed ones; at most `warps`.
    pub fine_warps: u32,
}

impl Default for FlowParams {
    fn default() -> Self {
        FlowParams {
            levels: 6,
            min_size: 16,
            warps: 3,
            iters: 15,
            alpha: 0.5,
            eps_data: 0.05,
            eps_smooth: 0.1,
            omega: 1.8,
            fine_warps: 1,
        }
    }
}

impl FlowParams {
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(m));
        if !(1..=16).contains(&self.levels) {
            return bad(format!("flow levels {} must be in 1..=16", self.levels));
        }
        if self.min_size == 0 {
            return bad("flow min_size must be at least 1".into());
        }
        if self.warps == 0 || self.warps > 64 {
            return bad(format!("flow warps {} must be in 1..=64", self.warps));
        }
        if self.fine_warps > self.warps {
            return bad(format!(
                "flow fine_warps {} is more than its warps {}",
                self.fine_warps, self.warps
            ));
        }
        if self.iters > 10_000 {
            return bad(format!("flow iters {} is over 10000", self.iters));
        }
        if !(self.alpha.is_finite() && self.alpha > 0.0) {
            return bad(format!(
                "flow alpha must be a positive number, got {}",
                self.alpha
            ));
        }
        for (name, v) in [("eps_data", self.eps_data), ("eps_smooth", self.eps_smooth)] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("flow {name} must be finite and >= 0, got {v}"));
            }
        }
        if !(self.omega > 0.0 && self.omega < 2.0) {
            return bad(format!("flow omega {} must be in (0, 2)", self.omega));
        }
        Ok(())
    }

    /// Sizes of the pyramid levels, finest first.
    pub fn pyramid(&self, width: u32, height: u32) -> Vec<(u32, u32)> {
        let mut sizes = vec![(width, height)];
        while (sizes.len() as u32) < self.levels {
            let (w, h) = *sizes.last().unwrap();
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            if nw.min(nh) < self.min_size || (nw, nh) == (w, h) {
                break;
            }
            sizes.push((nw, nh));
        }
        sizes
    }
}

/// Share of the positive confidences at or below the normalising confidence of
/// [`orient_features`] (the median).
pub const FEATURE_QUANTILE: f64 = 0.5;

/// Radius in pixels of the box over which [`orient_features`] takes the local mean
/// confidence.
pub const FEATURE_TEXTURE_RADIUS: usize = 8;

/// Knee of the texture weight of [`orient_features`]: r / (r + K), r the confidence over its
/// local mean.
pub const FEATURE_TEXTURE_KNEE: f32 = 4.0;

/// Share of the texture weight in the weight of [`orient_features`]; the rest is the
/// clamped confidence.
pub const FEATURE_TEXTURE_MIX: f32 = 0.5;

/// The orientation parameters of the matched features: the defaults without the refinement
/// passes and without the confidence-weighted smoothing of the double-angle field. Both make
/// a better still-image orientation but flatten the strand-scale structure that pins the
/// motion: on the synthetic clips (256², seed 1) θ with the defaults changes by under 1°
/// between frames whether or not frame b is warped by the true motion.
pub fn feature_orient_params() -> OrientParams {
    OrientParams {
        refine_iters: 0,
        smooth_sigma: 0.0,
        ..OrientParams::default()
    }
}

/// The matched features of one frame ([`FlowFeatures`]), each image `w · (cos 2θ, sin 2θ)` per
/// pixel, `[0, 0]` where θ is NaN or the confidence c is not positive, with
/// `w = (1 − m) · min(c / c_med, 1) + m · r / (r + K)`, `r = c / mean_R(c)`:
/// c_med the [`FEATURE_QUANTILE`] quantile of the positive confidences, mean_R the box mean
/// of radius R = [`FEATURE_TEXTURE_RADIUS`] (c counted 0 where θ is NaN),
/// K = [`FEATURE_TEXTURE_KNEE`], m = [`FEATURE_TEXTURE_MIX`] for the coarse levels and
/// [`FEATURE_FINE_MIX`] for the finest.
///
/// Why two terms. θ is smooth across the hair, so the clamped term alone (the earlier
/// feature) is nearly flat over half the pixels and matches sub-pixel motion poorly; the
/// confidence varies strand by strand, and that texture, carried by the motion, is what the
/// data term can pin to a fraction of a pixel. Dividing it by its local mean removes the
/// slow changes of the Gabor confidence with the strand angle to the pixel grid and with the
/// lighting; r / (r + K) bounds the few hot pixels. The texture alone loses the large
/// motions (the 3° turn of `tests/it/video_flow.rs`: 1.5 px EPE), where the smooth θ term
/// guides the coarse levels, hence the mix. Measured with `benches/flow_epe.rs` (seed-1
/// clips, 256², every 3rd pair, EPE on hair long/whorl/sidepart): clamped only (with the
/// default orientation parameters) 0.27/0.15/0.18 px at its best α (1 to 3); texture only
/// (m = 1, α = 0.3) 0.23/0.10/0.13 but 1.5 px on the 3° turn; the mix at α = 0.5
/// 0.25/0.13/0.16 and 0.38 px on the 3° turn.
pub fn orient_features(o: &OrientMap) -> FlowFeatures {
    let [coarse, fine] = feature_images(o, [FEATURE_TEXTURE_MIX, FEATURE_FINE_MIX]);
    FlowFeatures { coarse, fine }
}

/// The matched features of one frame, both `w · (cos 2θ, sin 2θ)` as [`orient_features`]
/// describes: the pyramid is built from `coarse` (texture share [`FEATURE_TEXTURE_MIX`]),
/// and the finest level's last [`FlowParams::fine_warps`] warping steps match `fine`
/// (share [`FEATURE_FINE_MIX`]).
///
/// Why two. The smooth θ term guides the coarse levels to large motions, which the
/// strand texture alone loses; but once the motion left is a fraction of a pixel, the θ
/// term is what holds the flow back: a field of parallel strands barely changes its θ when
/// it moves, so it pulls the estimate toward zero (on the 21-frame whorl clips the mixed
/// features carried 0.44-0.47 of the true motion, along and across the strands alike).
/// Measured with `benches/flow_epe.rs` (`coif synth-video --frames 21`, 256², seeds 1 and
/// 2, EPE on hair, α 0.5), the mix at every step → the texture in the last of the finest
/// level's 3 steps: whorl 0.116 / 0.110 → 0.099 / 0.085 px, long 0.241 / 0.229 → 0.227 /
/// 0.218, side part 0.170 / 0.190 → 0.148 / 0.172. In all 3 steps the clips gain more
/// (0.093 / 0.080, 0.219 / 0.213, 0.127 / 0.164) but the 3° turn of
/// `tests/it/video_flow.rs` (5 px a frame) loses: 0.38 → 0.72 px (2 of 3 steps: 0.59; the
/// last step only: 0.47).
#[derive(Clone, Debug, PartialEq)]
pub struct FlowFeatures {
    pub coarse: Vec<[f32; 2]>,
    pub fine: Vec<[f32; 2]>,
}

impl FlowFeatures {
    /// The same image at every level (tests and synthetic features).
    pub fn same(v: Vec<[f32; 2]>) -> FlowFeatures {
        FlowFeatures {
            coarse: v.clone(),
            fine: v,
        }
    }
}

/// Texture share of the finest level's features ([`FlowFeatures::fine`]): the texture alone.
pub const FEATURE_FINE_MIX: f32 = 1.0;

/// [`orient_features`]' images, one per texture share in `mixes` (m in its formula): the
/// confidence quantile, the box mean and the double angle are worked out once for all.
fn feature_images<const K: usize>(o: &OrientMap, mixes: [f32; K]) -> [Vec<[f32; 2]>; K] {
    let n = o.theta.len();
    let valid = |t: f32, c: f32| t.is_finite() && c.is_finite() && c > 0.0;
    let mut conf: Vec<f32> = o
        .theta
        .iter()
        .zip(&o.confidence)
        .filter(|(t, c)| valid(**t, **c))
        .map(|(_, &c)| c)
        .collect();
    if conf.is_empty() {
        return std::array::from_fn(|_| vec![[0.0; 2]; n]);
    }
    let k = ((conf.len() - 1) as f64 * FEATURE_QUANTILE).round() as usize;
    let (_, &mut scale, _) = conf.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    let c0: Vec<f32> = o
        .theta
        .iter()
        .zip(&o.confidence)
        .map(|(&t, &c)| if valid(t, c) { c } else { 0.0 })
        .collect();
    let local = box_mean(
        &c0,
        o.width as usize,
        o.height as usize,
        FEATURE_TEXTURE_RADIUS,
    );
    let mut out: [Vec<[f32; 2]>; K] = std::array::from_fn(|_| Vec::with_capacity(n));
    for ((&t, &c), &m) in o.theta.iter().zip(&c0).zip(&local) {
        if c > 0.0 && m > 0.0 {
            let r = c / m;
            // What every share has in common, once (the same values: only the shares'
            // own products are left in the loop).
            let (clamped, knee) = ((c / scale).min(1.0), r + FEATURE_TEXTURE_KNEE);
            let (cos, sin) = ((2.0 * t).cos(), (2.0 * t).sin());
            for (img, &mix) in out.iter_mut().zip(&mixes) {
                let w = (1.0 - mix) * clamped + mix * r / knee;
                img.push([w * cos, w * sin]);
            }
        } else {
            for img in &mut out {
                img.push([0.0; 2]);
            }
        }
    }
    out
}

/// Mean of `v` (width × height, row-major) over the (2r+1)² box around each pixel, clipped
/// to the image. Stays on the CPU: two prefix-sum passes, O(1) per pixel, once per frame.
fn box_mean(v: &[f32], width: usize, height: usize, r: usize) -> Vec<f32> {
    // One pass along lines of length n, element i of line k at k * step + i * stride.
    let pass = |src: &[f32], n: usize, stride: usize, lines: usize, step: usize| {
        let mut out = vec![0.0f32; src.len()];
        let mut pre = vec![0.0f64; n + 1];
        for k in 0..lines {
            for i in 0..n {
                pre[i + 1] = pre[i] + src[k * step + i * stride] as f64;
            }
            for i in 0..n {
                let (a, b) = (i.saturating_sub(r), (i + r + 1).min(n));
                out[k * step + i * stride] = ((pre[b] - pre[a]) / (b - a) as f64) as f32;
            }
        }
        out
    };
    let rows = pass(v, width, 1, height, width);
    pass(&rows, height, width, width, 1)
}

/// Records the whole coarse-to-fine flow and returns the full-size flow buffer.
pub fn record_flow(
    rec: &mut Recording,
    a: &FlowFeatures,
    b: &FlowFeatures,
    width: u32,
    height: u32,
    p: &FlowParams,
) -> BufProxy {
    let sizes = p.pyramid(width, height);
    let px = |(w, h): (u32, u32)| w as u64 * h as u64;
    let mut pa = vec![rec.upload("coif.flow.a", &a.coarse)];
    let mut pb = vec![rec.upload("coif.flow.b", &b.coarse)];
    // The finest level's last steps match the texture features instead (see
    // `FlowFeatures`); uploaded only when some step uses them.
    let fine = (p.fine_warps > 0).then(|| {
        (
            rec.upload("coif.flow.a_fine", &a.fine),
            rec.upload("coif.flow.b_fine", &b.fine),
        )
    });
    for l in 1..sizes.len() {
        let (w, h) = sizes[l - 1];
        let cfg = flow_down::Config::halving(w, h);
        let u = rec.uniform("coif.flow.down.cfg", &cfg);
        for pyr in [&mut pa, &mut pb] {
            let out = rec.alloc("coif.flow.level", px(sizes[l]) * 8, SENTINEL);
            rec.dispatch(
                &flow_down::STAGE,
                flow_down::workgroups(&cfg),
                &[u, pyr[l - 1], out],
                &[],
            );
            pyr.push(out);
        }
    }
    let coarsest = sizes.len() - 1;
    // The coarsest level starts from zero motion.
    let mut flow = rec.alloc("coif.flow.uv", px(sizes[coarsest]) * 8, 0);
    for l in (0..sizes.len()).rev() {
        let (w, h) = sizes[l];
        if l < coarsest {
            let (cw, ch) = sizes[l + 1];
            let cfg = flow_up::Config {
                src_w: cw,
                src_h: ch,
                dst_w: w,
                dst_h: h,
            };
            let u = rec.uniform("coif.flow.up.cfg", &cfg);
            let fine = rec.alloc("coif.flow.uv", px((w, h)) * 8, SENTINEL);
            rec.dispatch(
                &flow_up::STAGE,
                flow_up::workgroups(&cfg),
                &[u, flow, fine],
                &[],
            );
            flow = fine;
        }
        let wcfg = flow_warp::Config {
            width: w,
            height: h,
            ..Default::default()
        };
        let wu = rec.uniform("coif.flow.warp.cfg", &wcfg);
        let deriv = rec.alloc(
            "coif.flow.deriv",
            px((w, h)) * 8 * flow_warp::DERIV_PER_PX as u64,
            SENTINEL,
        );
        let scfg = |colour| flow_solve::Config {
            width: w,
            height: h,
            colour,
            alpha: p.alpha,
            eps_data: p.eps_data,
            eps_smooth: p.eps_smooth,
            omega: p.omega,
            ..Default::default()
        };
        let su = [0, 1].map(|c| rec.uniform("coif.flow.solve.cfg", &scfg(c)));
        for k in 0..p.warps {
            // The finest level's last `fine_warps` steps match the texture features.
            let (la, lb) = match fine {
                Some(f) if l == 0 && k + p.fine_warps >= p.warps => f,
                _ => (pa[l], pb[l]),
            };
            rec.dispatch(
                &flow_warp::STAGE,
                flow_warp::workgroups(&wcfg),
                &[wu, la, lb, flow, deriv],
                &[],
            );
            for _ in 0..p.iters {
                for u in su {
                    rec.dispatch(
                        &flow_solve::STAGE,
                        flow_solve::workgroups(&scfg(0)),
                        &[u, deriv, flow],
                        &[],
                    );
                }
            }
        }
    }
    flow
}

/// Flow from frame a to frame b on a's pixels, `a(q) ≈ b(q + V(q))`, in pixels (x right,
/// y down), from their features ([`orient_features`]). Defined at every pixel: where
/// neither frame has an orientation the smoothness term fills it in from around.
pub fn flow(
    engine: &Engine,
    a: &FlowFeatures,
    b: &FlowFeatures,
    width: u32,
    height: u32,
    p: &FlowParams,
) -> Result<Vec<[f32; 2]>> {
    p.validate()?;
    if width == 0 || height == 0 {
        return Err(Error::Invalid(
            "flow: the frames are empty (0 pixels)".into(),
        ));
    }
    let n = width as usize * height as usize;
    let images = [
        ("a", &a.coarse),
        ("a (fine)", &a.fine),
        ("b", &b.coarse),
        ("b (fine)", &b.fine),
    ];
    for (name, img) in images {
        if img.len() != n {
            return Err(Error::Invalid(format!(
                "flow: frame {name} has {} feature pixels, {width}x{height} needs {n}",
                img.len()
            )));
        }
        if img.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Error::Invalid(format!(
                "flow: frame {name}'s features have NaN or infinite values"
            )));
        }
    }
    let mut rec = Recording::default();
    let out = record_flow(&mut rec, a, b, width, height, p);
    rec.download(out);
    Ok(engine.run(rec)?.get::<[f32; 2]>(out))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Parameters out of range are refused with the field named; the defaults pass.
    #[test]
    fn bad_parameters_are_refused() {
        assert!(FlowParams::default().validate().is_ok());
        let bad = [
            FlowParams {
                fine_warps: 4,
                ..FlowParams::default()
            },
            FlowParams {
                warps: 0,
                ..FlowParams::default()
            },
            FlowParams {
                alpha: f32::NAN,
                ..FlowParams::default()
            },
        ];
        for (p, field) in bad.iter().zip(["fine_warps", "warps", "alpha"]) {
            let e = p.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{p:?}: {e}");
        }
    }

    /// A flow whose features are not the frame's size is refused before anything runs.
    #[test]
    fn features_of_the_wrong_size_are_refused() {
        let ok = FlowFeatures::same(vec![[0.0; 2]; 12]);
        let short = FlowFeatures {
            coarse: vec![[0.0; 2]; 12],
            fine: vec![[0.0; 2]; 11],
        };
        let e = flow(&Engine::cpu(), &ok, &short, 4, 3, &FlowParams::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("b (fine)"), "{e}");
    }
}
