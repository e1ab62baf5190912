//! RGB Gaussian mixtures (full covariance) for the segmentation's colour models.

use crate::base::rng::Rng;
use rayon::prelude::*;

/// Variance added to every covariance diagonal (8-bit RGB units): keeps flat regions and
/// quantised colours from producing singular Gaussians.
pub(super) const COV_REG: f64 = 4.0;
/// EM steps after k-means, and per re-estimation round.
pub(super) const EM_STEPS: usize = 4;
pub(super) const KMEANS_STEPS: usize = 8;

#[derive(Clone, Debug)]
pub(super) struct Gauss {
    mean: [f64; 3],
    /// Lower-triangular Cholesky factor of the covariance.
    chol: [[f64; 3]; 3],
    /// log weight - 0.5 * log det(cov) - 1.5 * log(2 pi).
    log_norm: f64,
}

#[derive(Clone, Debug)]
pub(super) struct Gmm {
    comps: Vec<Gauss>,
}

impl Gmm {
    /// k-means++ initialisation, Lloyd steps, then EM.
    pub(super) fn fit(xs: &[[f32; 3]], k: usize, rng: &mut Rng) -> Gmm {
        let k = k.min(xs.len()).max(1);
        let mut centres: Vec<[f64; 3]> = vec![to64(xs[rng.below(xs.len() as u32) as usize])];
        let mut d2: Vec<f64> = xs.iter().map(|x| dist2(to64(*x), centres[0])).collect();
        while centres.len() < k {
            let sum: f64 = d2.iter().sum();
            if sum <= 0.0 {
                break; // fewer distinct colours than components
            }
            let mut t = rng.next_f32() as f64 * sum;
            let mut pick = xs.len() - 1;
            for (i, d) in d2.iter().enumerate() {
                t -= d;
                if t < 0.0 {
                    pick = i;
                    break;
                }
            }
            let c = to64(xs[pick]);
            for (d, x) in d2.iter_mut().zip(xs) {
                *d = d.min(dist2(to64(*x), c));
            }
            centres.push(c);
        }
        let mut assign = vec![0usize; xs.len()];
        for _ in 0..KMEANS_STEPS {
            for (a, x) in assign.iter_mut().zip(xs) {
                let x = to64(*x);
                *a = (0..centres.len())
                    .min_by(|&i, &j| dist2(x, centres[i]).total_cmp(&dist2(x, centres[j])))
                    .unwrap_or(0);
            }
            let mut sum = vec![[0.0f64; 3]; centres.len()];
            let mut cnt = vec![0usize; centres.len()];
            for (&a, x) in assign.iter().zip(xs) {
                for c in 0..3 {
                    sum[a][c] += x[c] as f64;
                }
                cnt[a] += 1;
            }
            for (i, c) in centres.iter_mut().enumerate() {
                if cnt[i] > 0 {
                    *c = sum[i].map(|s| s / cnt[i] as f64);
                }
            }
        }
        // Hard responsibilities from k-means start EM.
        let resp: Vec<Vec<f64>> = (0..centres.len())
            .map(|c| assign.iter().map(|&a| (a == c) as u8 as f64).collect())
            .collect();
        let mut g = Gmm::m_step(xs, &resp);
        g.refine(xs);
        g
    }

    /// EM steps on `xs` starting from the current components.
    pub(super) fn refine(&mut self, xs: &[[f32; 3]]) {
        for _ in 0..EM_STEPS {
            let k = self.comps.len();
            let mut resp = vec![vec![0.0f64; xs.len()]; k];
            let mut lp = vec![0.0f64; k];
            for (i, x) in xs.iter().enumerate() {
                let x = to64(*x);
                for (c, g) in self.comps.iter().enumerate() {
                    lp[c] = g.log_pdf(x);
                }
                let m = lp.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
                let s: f64 = lp.iter().map(|l| (l - m).exp()).sum();
                for c in 0..k {
                    resp[c][i] = (lp[c] - m).exp() / s;
                }
            }
            *self = Gmm::m_step(xs, &resp);
        }
    }

    /// Weighted means and covariances; components with (almost) no weight are dropped.
    pub(super) fn m_step(xs: &[[f32; 3]], resp: &[Vec<f64>]) -> Gmm {
        let n = xs.len() as f64;
        let mut comps = Vec::new();
        for r in resp {
            let wsum: f64 = r.iter().sum();
            if wsum < 1e-3 * n.max(1.0) || wsum < 1.0 {
                continue;
            }
            let mut mean = [0.0f64; 3];
            for (x, &ri) in xs.iter().zip(r) {
                for c in 0..3 {
                    mean[c] += ri * x[c] as f64;
                }
            }
            mean = mean.map(|m| m / wsum);
            let mut cov = [[0.0f64; 3]; 3];
            for (x, &ri) in xs.iter().zip(r) {
                let d = [
                    x[0] as f64 - mean[0],
                    x[1] as f64 - mean[1],
                    x[2] as f64 - mean[2],
                ];
                for (a, row) in cov.iter_mut().enumerate() {
                    for (b, v) in row.iter_mut().enumerate() {
                        *v += ri * d[a] * d[b];
                    }
                }
            }
            for (a, row) in cov.iter_mut().enumerate() {
                row.iter_mut().for_each(|v| *v /= wsum);
                row[a] += COV_REG;
            }
            let chol = cholesky(&cov);
            let log_det = 2.0 * (0..3).map(|i| chol[i][i].ln()).sum::<f64>();
            comps.push(Gauss {
                mean,
                chol,
                log_norm: (wsum / n).ln() - 0.5 * log_det - 1.5 * (2.0 * std::f64::consts::PI).ln(),
            });
        }
        if comps.is_empty() {
            // Unreachable for non-empty input (weights sum to n), but stay total.
            comps.push(Gauss {
                mean: [127.5; 3],
                chol: [[128.0, 0.0, 0.0], [0.0, 128.0, 0.0], [0.0, 0.0, 128.0]],
                log_norm: -3.0 * 128f64.ln() - 1.5 * (2.0 * std::f64::consts::PI).ln(),
            });
        }
        Gmm { comps }
    }

    /// Negative log likelihood of a colour.
    pub(super) fn nll(&self, x: [f32; 3]) -> f32 {
        let x = to64(x);
        // Streaming log-sum-exp: no per-call buffer.
        let (mut m, mut s) = (f64::NEG_INFINITY, 0.0f64);
        for g in &self.comps {
            let l = g.log_pdf(x);
            if l > m {
                s = s * (m - l).exp() + 1.0;
                m = l;
            } else {
                s += (l - m).exp();
            }
        }
        -(m + s.ln()) as f32
    }
}

impl Gauss {
    pub(super) fn log_pdf(&self, x: [f64; 3]) -> f64 {
        // Solve L z = x - mean; the Mahalanobis distance is |z|^2.
        let l = &self.chol;
        let d = [
            x[0] - self.mean[0],
            x[1] - self.mean[1],
            x[2] - self.mean[2],
        ];
        let z0 = d[0] / l[0][0];
        let z1 = (d[1] - l[1][0] * z0) / l[1][1];
        let z2 = (d[2] - l[2][0] * z0 - l[2][1] * z1) / l[2][2];
        self.log_norm - 0.5 * (z0 * z0 + z1 * z1 + z2 * z2)
    }
}

/// Cholesky factor of a symmetric positive definite 3x3 matrix (positive definite here
/// because of the diagonal regulariser).
pub(super) fn cholesky(a: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut l = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            if i == j {
                l[i][i] = (a[i][i] - s).max(1e-9).sqrt();
            } else {
                l[i][j] = (a[i][j] - s) / l[j][j];
            }
        }
    }
    l
}

pub(super) fn to64(x: [f32; 3]) -> [f64; 3] {
    [x[0] as f64, x[1] as f64, x[2] as f64]
}

pub(super) fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

/// Per-pixel -log likelihood under the hair and background models. Capped so that one
/// outlier colour cannot outweigh any amount of smoothness.
pub(super) fn data_terms(rgb: &[[f32; 3]], fg: &Gmm, bg: &Gmm) -> (Vec<f32>, Vec<f32>) {
    const CAP: f32 = 60.0;
    rgb.par_iter()
        .map(|&c| (fg.nll(c).min(CAP), bg.nll(c).min(CAP)))
        .unzip()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    pub(super) fn gmm_separates_two_clusters() {
        let mut rng = Rng::new(3);
        let xs: Vec<[f32; 3]> = (0..2000)
            .map(|i| {
                let c = if i % 2 == 0 { 40.0 } else { 200.0 };
                [
                    c + 5.0 * rng.normal_f32(),
                    c + 5.0 * rng.normal_f32(),
                    c + 5.0 * rng.normal_f32(),
                ]
            })
            .collect();
        let g = Gmm::fit(&xs, 2, &mut rng);
        assert_eq!(g.comps.len(), 2);
        let mut means: Vec<f64> = g.comps.iter().map(|c| c.mean[0]).collect();
        means.sort_by(f64::total_cmp);
        assert!(
            (means[0] - 40.0).abs() < 1.0 && (means[1] - 200.0).abs() < 1.0,
            "{means:?}"
        );
        // A colour at a cluster centre is far likelier than one in between.
        assert!(g.nll([40.0; 3]) + 10.0 < g.nll([120.0; 3]));
    }
}
