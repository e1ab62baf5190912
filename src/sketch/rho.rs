//! The contrast priors of CZ06 Eq. 5-6: p_sk (on the sketch) and p_nsk (off it), each a
//! mixture of two Gaussians over ρ = |∇⊥Θ I_H|, fitted by EM. Before any sketch exists they
//! are fitted to the hair's ρ split at a quantile (the top share standing for the sketch);
//! the pursuit refits them once from the pixels its first sketch covers. 1-D EM over at most
//! a few ten thousand values: CPU.

use super::RhoPrior;
use crate::error::{Error, Result};

/// Values EM looks at: larger sets are thinned by a fixed stride (deterministic).
const MAX_SAMPLES: usize = 1 << 16;
const MAX_ITERS: usize = 200;
const LN_SQRT_2PI: f64 = 0.918_938_533_204_672_7;

impl RhoPrior {
    /// log p(ρ) under the mixture.
    pub fn log_density(&self, rho: f32) -> f32 {
        let x = rho as f64;
        let l = |k: usize| {
            let (w, m, s) = (
                self.weight[k] as f64,
                self.mean[k] as f64,
                self.sigma[k] as f64,
            );
            if w <= 0.0 {
                return f64::NEG_INFINITY;
            }
            w.ln() - s.ln() - LN_SQRT_2PI - 0.5 * ((x - m) / s).powi(2)
        };
        let (a, b) = (l(0), l(1));
        let hi = a.max(b);
        (hi + ((a - hi).exp() + (b - hi).exp()).ln()) as f32
    }

    /// A two-component Gaussian mixture fitted to `values` by EM, started from their split
    /// at the median. Standard deviations are floored at 1% of the values' spread (and
    /// 1e-6) so a component cannot collapse on repeated values.
    pub fn fit_em(values: &[f32]) -> Result<RhoPrior> {
        let finite: Vec<f64> = values
            .iter()
            .filter(|v| v.is_finite())
            .map(|&v| v as f64)
            .collect();
        if finite.is_empty() {
            return Err(Error::Invalid(
                "contrast prior: no finite ρ values to fit".into(),
            ));
        }
        let step = finite.len().div_ceil(MAX_SAMPLES);
        let mut x: Vec<f64> = finite.iter().step_by(step).copied().collect();
        x.sort_by(f64::total_cmp);
        let n = x.len() as f64;
        let mean_all = x.iter().sum::<f64>() / n;
        let sd_all = (x.iter().map(|v| (v - mean_all).powi(2)).sum::<f64>() / n).sqrt();
        let floor = (0.01 * sd_all).max(1e-6);
        let half = (x.len() / 2).max(1);
        let stats = |s: &[f64]| {
            if s.is_empty() {
                return (mean_all, sd_all.max(floor));
            }
            let m = s.iter().sum::<f64>() / s.len() as f64;
            let v = s.iter().map(|v| (v - m).powi(2)).sum::<f64>() / s.len() as f64;
            (m, v.sqrt().max(floor))
        };
        let (m0, s0) = stats(&x[..half]);
        let (m1, s1) = stats(&x[half..]);
        let (mut w, mut m, mut s) = ([0.5f64, 0.5], [m0, m1], [s0, s1]);
        let mut last = f64::NEG_INFINITY;
        for _ in 0..MAX_ITERS {
            let (mut r0, mut r1) = ([0.0f64; 3], [0.0f64; 3]);
            let mut ll = 0.0;
            for &v in &x {
                let l0 = w[0].ln() - s[0].ln() - 0.5 * ((v - m[0]) / s[0]).powi(2);
                let l1 = w[1].ln() - s[1].ln() - 0.5 * ((v - m[1]) / s[1]).powi(2);
                let hi = l0.max(l1);
                let (e0, e1) = ((l0 - hi).exp(), (l1 - hi).exp());
                let g0 = e0 / (e0 + e1);
                ll += hi + (e0 + e1).ln();
                r0[0] += g0;
                r0[1] += g0 * v;
                r0[2] += g0 * v * v;
                r1[0] += 1.0 - g0;
                r1[1] += (1.0 - g0) * v;
                r1[2] += (1.0 - g0) * v * v;
            }
            for (k, r) in [r0, r1].into_iter().enumerate() {
                if r[0] < 1e-9 {
                    // An empty component: park it on the whole set with a tiny weight.
                    w[k] = 1e-9;
                    m[k] = mean_all;
                    s[k] = sd_all.max(floor);
                    continue;
                }
                w[k] = r[0] / n;
                m[k] = r[1] / r[0];
                s[k] = (r[2] / r[0] - m[k] * m[k]).max(0.0).sqrt().max(floor);
            }
            if (ll - last).abs() <= 1e-9 * ll.abs().max(1.0) {
                break;
            }
            last = ll;
        }
        // Component 0 is the lower mean, so priors print and compare in one order.
        let order = if m[0] <= m[1] { [0, 1] } else { [1, 0] };
        Ok(RhoPrior {
            weight: order.map(|k| w[k] as f32),
            mean: order.map(|k| m[k] as f32),
            sigma: order.map(|k| s[k] as f32),
        })
    }
}

/// ρ = |∇⊥θ I| = |−gx sin θ + gy cos θ| per pixel; NaN where θ is NaN.
pub fn rho_field(gx: &[f32], gy: &[f32], theta: &[f32]) -> Vec<f32> {
    theta
        .iter()
        .zip(gx.iter().zip(gy))
        .map(|(&t, (&x, &y))| (-x * t.sin() + y * t.cos()).abs())
        .collect()
}

/// Mean of `v` over the hair pixels of the (2r+1)² box around each pixel (NaN where the
/// box holds no hair pixel with a number).
pub fn local_mean(v: &[f32], hair: &[bool], width: u32, height: u32, r: usize) -> Vec<f32> {
    let (w, h) = (width as usize, height as usize);
    let ok = |i: usize| hair[i] && v[i].is_finite();
    // Row sums then column sums of (value, count).
    let mut rows = vec![(0.0f64, 0u32); w * h];
    for y in 0..h {
        for x in 0..w {
            let (mut s, mut n) = (0.0f64, 0u32);
            for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                let i = y * w + xx;
                if ok(i) {
                    s += v[i] as f64;
                    n += 1;
                }
            }
            rows[y * w + x] = (s, n);
        }
    }
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (mut s, mut n) = (0.0f64, 0u32);
            for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                let (a, b) = rows[yy * w + x];
                s += a;
                n += b;
            }
            if n > 0 {
                (s / n as f64) as f32
            } else {
                f32::NAN
            }
        })
        .collect()
}

/// (p_sk, p_nsk) before any sketch: the hair pixels split at the `quantile` (e.g. 0.8) of
/// their local contrast (the mean ρ over the 5×5 box, about a primitive's window), p_sk
/// fitted to the ρ of the pixels above it and p_nsk to the rest. A split of the pixels'
/// own ρ would leave p_sk without a lower tail (its fit sees only the top values), and a
/// sketch window always holds low-ρ pixels (a strand's ridge, the gaps): at 256² on `coif
/// synth` hair one such pixel then costs ~25 energy units and no window can join the sketch.
pub fn fit_split(
    rho: &[f32],
    hair: &[bool],
    width: u32,
    height: u32,
    quantile: f32,
) -> Result<(RhoPrior, RhoPrior)> {
    let local = local_mean(rho, hair, width, height, 2);
    let mut l: Vec<f32> = (0..rho.len())
        .filter(|&i| hair[i] && rho[i].is_finite() && local[i].is_finite())
        .map(|i| local[i])
        .collect();
    if l.len() < 8 {
        return Err(Error::Invalid(format!(
            "contrast prior: {} hair pixels with a contrast, need at least 8",
            l.len()
        )));
    }
    l.sort_by(f32::total_cmp);
    let cut = l[((l.len() as f32 * quantile) as usize).clamp(1, l.len() - 1)];
    let on: Vec<bool> = local.iter().map(|&v| v >= cut).collect();
    let (sk, nsk): (Vec<f32>, Vec<f32>) = {
        let pick = |want: bool| -> Vec<f32> {
            (0..rho.len())
                .filter(|&i| hair[i] && rho[i].is_finite() && local[i].is_finite() && on[i] == want)
                .map(|i| rho[i])
                .collect()
        };
        (pick(true), pick(false))
    };
    if sk.len() < 4 || nsk.len() < 4 {
        return Err(Error::Invalid(
            "contrast prior: the hair's contrast is uniform; cannot split it".into(),
        ));
    }
    Ok((RhoPrior::fit_em(&sk)?, RhoPrior::fit_em(&nsk)?))
}

/// (p_sk, p_nsk) refitted from a sketch: ρ on the hair pixels `on` marks, and on the rest.
/// Either set with fewer than 4 values keeps its `fallback` prior.
pub fn fit_sets(
    rho: &[f32],
    hair: &[bool],
    on: &[bool],
    fallback: (RhoPrior, RhoPrior),
) -> Result<(RhoPrior, RhoPrior)> {
    let pick = |want: bool| -> Vec<f32> {
        rho.iter()
            .zip(hair.iter().zip(on))
            .filter(|(r, (&h, &o))| h && o == want && r.is_finite())
            .map(|(&r, _)| r)
            .collect()
    };
    let (sk, nsk) = (pick(true), pick(false));
    Ok((
        if sk.len() >= 4 {
            RhoPrior::fit_em(&sk)?
        } else {
            fallback.0
        },
        if nsk.len() >= 4 {
            RhoPrior::fit_em(&nsk)?
        } else {
            fallback.1
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn em_recovers_two_gaussians() {
        // Box-Muller draws from 0.3 N(2, 0.5) + 0.7 N(8, 1.5), from a fixed LCG.
        let mut s = 12345u64;
        let mut u = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut v = Vec::new();
        for i in 0..20000 {
            let g = (-2.0 * u().ln()).sqrt() * (std::f64::consts::TAU * u()).cos();
            v.push(if i % 10 < 3 {
                2.0 + 0.5 * g
            } else {
                8.0 + 1.5 * g
            } as f32);
        }
        let p = RhoPrior::fit_em(&v).unwrap();
        assert!((p.weight[0] - 0.3).abs() < 0.02, "{p:?}");
        assert!(
            (p.mean[0] - 2.0).abs() < 0.05 && (p.mean[1] - 8.0).abs() < 0.1,
            "{p:?}"
        );
        assert!(
            (p.sigma[0] - 0.5).abs() < 0.05 && (p.sigma[1] - 1.5).abs() < 0.1,
            "{p:?}"
        );
        // The density integrates to one.
        let dx = 0.01f32;
        let total: f32 = (-500..2000)
            .map(|i| p.log_density(i as f32 * dx).exp() * dx)
            .sum();
        assert!((total - 1.0).abs() < 1e-3, "{total}");
    }
}
