//! The fill-in of the vector field V = (Θ, ρ, d) from the sketch (CZ06 §3.1, Eq. 14-17).
//!
//! - ρ: on the sketch, the painted contrast; off it (Λ_nsk, and a dividing line's scalp
//!   strip, which the sketch paints no flow on) drawn iid from p_nsk (Eq. 14), seeded, then
//!   optionally smoothed by a normalised Gaussian over the drawn pixels (σ 1.5 by default).
//! - Θ and d: the flow of Eq. 16 with the weight schedule of Eq. 17, the `cz_fill` pass run to
//!   convergence (max change of angle per sweep < 0.05° and min weight > 0.9, checked every
//!   [`FillParams::check_every`] sweeps, at most 600 sweeps). On whole hairstyles the cap is
//!   what ends it: Eq. 17's weights diffuse at about 0.05 px² a sweep, so far from every
//!   curve they stay small for thousands of sweeps while the angles have long settled (see
//!   the README, Fill).
//!
//! Two fills, both `cz_fill`:
//! - orientation-only (doubled angles 2θ), clamped on every sketch pixel that carries an
//!   orientation: it gives Θ by default ([`ThetaFrom::Doubled`]). An orientation is what the
//!   sketch always knows, and this fill cannot be bent by a direction flip the sketch does
//!   not mark (two opposite directions side by side make the directed fill rotate Θ by 90°
//!   between them);
//! - directed (τ, period 2π), run when the painted sketch has directions: clamped where τ is
//!   painted; sketch pixels with an orientation but no direction (an undirected curve in a
//!   partly directed sketch) keep their orientation and take the sign their neighbours favour,
//!   with a weight that starts at 0 like a free pixel's, so directions spread only from
//!   directed curves. It gives d: its τ projected on ±Θ (the growth direction is ±(cos Θ,
//!   sin Θ), the sign the one nearer τ). With [`ThetaFrom::Directed`] it gives Θ = τ mod π
//!   too (CZ06's single fill), the doubled fill filling only what it leaves unset.
//!
//! Unset: a hair pixel in a component of the mask that no clamped pixel reaches keeps Θ, d
//! NaN (its weight would stay 0 forever); d is NaN wherever the directed fill did not reach
//! (all of the hair for an undirected sketch). ρ is defined on all hair.

use super::prim::Painted;
use super::{wrap_pi, RhoPrior, VectorField};
use crate::base::rng::Rng;
use crate::base::sentinel::SENTINEL;
use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::stages::{cz_fill, sep_blur};
use serde::Serialize;
use std::collections::VecDeque;
use std::f32::consts::PI;

/// Where Θ comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ThetaFrom {
    /// The orientation-only fill of doubled angles (default).
    Doubled,
    /// The directed fill, τ mod π (CZ06 as printed), where it reaches.
    Directed,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FillParams {
    /// Cap on sweeps (one sweep = a red and a black half-sweep).
    pub max_sweeps: u32,
    /// Convergence is checked every this many sweeps (each check reads the state back).
    pub check_every: u32,
    /// Converged when no pixel's angle moved more than this in the last sweep, degrees ...
    pub tol_deg: f32,
    /// ... and every reached free pixel's weight exceeds this.
    pub min_weight: f32,
    /// σ of the normalised Gaussian smoothing of the ρ drawn off the sketch, px; 0: none.
    pub rho_sigma: f32,
    pub theta_from: ThetaFrom,
}

impl Default for FillParams {
    fn default() -> Self {
        FillParams {
            max_sweeps: 600,
            check_every: 20,
            tol_deg: 0.05,
            min_weight: 0.9,
            rho_sigma: 1.5,
            theta_from: ThetaFrom::Doubled,
        }
    }
}

impl FillParams {
    pub fn validate(&self) -> Result<()> {
        if self.check_every == 0 {
            return Err(Error::Invalid("fill: check_every must be ≥ 1".into()));
        }
        if !(self.tol_deg.is_finite() && self.tol_deg > 0.0) {
            return Err(Error::Invalid(format!(
                "fill: tolerance must be positive, got {}°",
                self.tol_deg
            )));
        }
        if !(self.min_weight.is_finite() && (0.0..1.0).contains(&self.min_weight)) {
            return Err(Error::Invalid(format!(
                "fill: min_weight must be in [0, 1), got {}",
                self.min_weight
            )));
        }
        if !(self.rho_sigma.is_finite() && self.rho_sigma >= 0.0) {
            return Err(Error::Invalid(format!(
                "fill: rho_sigma must be ≥ 0, got {}",
                self.rho_sigma
            )));
        }
        Ok(())
    }
}

/// Which angles a fill diffuses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Directions τ, period 2π.
    Directed,
    /// Doubled orientations 2θ.
    Orientation,
}

/// How one fill ended.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Convergence {
    pub mode: Mode,
    pub sweeps: u32,
    /// Largest change of angle in the last sweep over the free pixels, degrees (of τ, or
    /// of θ for the orientation fill).
    pub max_delta_deg: f32,
    /// Smallest weight over the free pixels the sketch reaches (1 if there are none).
    pub min_weight: f32,
    pub converged: bool,
    /// Clamped pixels, free pixels the sketch reaches, hair pixels it cannot reach.
    pub clamped: usize,
    pub reached: usize,
    pub unreached: usize,
}

/// Both fills' endings (None: not run).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FillReport {
    pub orientation: Option<Convergence>,
    pub directed: Option<Convergence>,
}

/// One fill's state, as the `cz_fill` pass reads and writes it.
#[derive(Clone, Debug)]
pub struct FillState {
    pub width: u32,
    pub height: u32,
    pub mode: Mode,
    /// Per pixel [`cz_fill::OFF`], `FREE`, `CLAMPED` or `AXIS`.
    pub kind: Vec<u32>,
    /// Orientation of `AXIS` pixels, [0, π); 0 elsewhere.
    pub cons: Vec<f32>,
    /// τ or 2θ in [0, 2π); meaningful where `weight` > 0.
    pub ang: Vec<f32>,
    pub weight: Vec<f32>,
}

impl FillState {
    /// The orientation-only fill: clamped on every hair pixel the sketch gives a Θ.
    pub fn orientation(painted: &Painted, hair: &[bool]) -> FillState {
        let n = hair.len();
        let (mut kind, mut ang, mut weight) = (vec![cz_fill::OFF; n], vec![0.0; n], vec![0.0; n]);
        for k in 0..n {
            if !hair[k] {
                continue;
            }
            let t = painted.theta[k];
            if t.is_finite() {
                kind[k] = cz_fill::CLAMPED;
                ang[k] = (2.0 * wrap_pi(t)).rem_euclid(2.0 * PI);
                weight[k] = 1.0;
            } else {
                kind[k] = cz_fill::FREE;
            }
        }
        let mut s = FillState {
            width: painted.width,
            height: painted.height,
            mode: Mode::Orientation,
            kind,
            cons: vec![0.0; n],
            ang,
            weight,
        };
        s.drop_unreached();
        s
    }

    /// The directed fill: clamped where τ is painted; sketch pixels with Θ but no τ are
    /// `AXIS` (weight 0 at first). None when the sketch paints no direction on the hair.
    pub fn directed(painted: &Painted, hair: &[bool]) -> Option<FillState> {
        let n = hair.len();
        let (mut kind, mut cons) = (vec![cz_fill::OFF; n], vec![0.0; n]);
        let (mut ang, mut weight) = (vec![0.0; n], vec![0.0; n]);
        let mut any = false;
        for k in 0..n {
            if !hair[k] {
                continue;
            }
            let (t, tau) = (painted.theta[k], painted.tau[k]);
            if tau.is_finite() {
                kind[k] = cz_fill::CLAMPED;
                ang[k] = tau.rem_euclid(2.0 * PI);
                weight[k] = 1.0;
                any = true;
            } else if t.is_finite() {
                kind[k] = cz_fill::AXIS;
                cons[k] = wrap_pi(t);
            } else {
                kind[k] = cz_fill::FREE;
            }
        }
        if !any {
            return None;
        }
        let mut s = FillState {
            width: painted.width,
            height: painted.height,
            mode: Mode::Directed,
            kind,
            cons,
            ang,
            weight,
        };
        s.drop_unreached();
        Some(s)
    }

    /// Hair the clamped pixels cannot reach through 4-neighbours would keep weight 0 for
    /// ever: it leaves the domain, so convergence is judged where the fill can act.
    /// Sequential BFS, one pass over the image: CPU.
    fn drop_unreached(&mut self) {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut seen: Vec<bool> = self.kind.iter().map(|&c| c == cz_fill::CLAMPED).collect();
        let mut queue: VecDeque<usize> = (0..w * h).filter(|&k| seen[k]).collect();
        while let Some(k) = queue.pop_front() {
            let (x, y) = (k % w, k / w);
            let nb = [
                (x > 0).then(|| k - 1),
                (x + 1 < w).then(|| k + 1),
                (y > 0).then(|| k - w),
                (y + 1 < h).then(|| k + w),
            ];
            for j in nb.into_iter().flatten() {
                if !seen[j] && self.kind[j] != cz_fill::OFF {
                    seen[j] = true;
                    queue.push_back(j);
                }
            }
        }
        for (kind, seen) in self.kind.iter_mut().zip(seen) {
            if !seen {
                *kind = cz_fill::OFF;
            }
        }
    }

    fn free(&self, k: usize) -> bool {
        self.kind[k] == cz_fill::FREE || self.kind[k] == cz_fill::AXIS
    }

    /// Whether pixel k has an angle (clamped, or reached).
    pub fn is_set(&self, k: usize) -> bool {
        self.kind[k] != cz_fill::OFF && self.weight[k] > 0.0
    }

    /// The output angle at k: τ, or θ for the orientation fill; NaN where unset.
    pub fn angle(&self, k: usize) -> f32 {
        if !self.is_set(k) {
            return f32::NAN;
        }
        match self.mode {
            Mode::Directed => self.ang[k],
            Mode::Orientation => wrap_pi(0.5 * self.ang[k]),
        }
    }
}

/// Runs `sweeps` sweeps of `cz_fill` on `state` in one recording and returns each pixel's
/// change of angle in the last sweep (radians of τ or θ; 0 where not updated). The pass holds
/// angles as unit vectors: they are converted here, once per call.
pub fn run_sweeps(engine: &Engine, state: &mut FillState, sweeps: u32) -> Result<Vec<f32>> {
    let n = state.kind.len();
    if n == 0 || n != (state.width as usize) * (state.height as usize) {
        return Err(Error::Invalid(format!(
            "fill: state of {} px for a {}x{} image",
            n, state.width, state.height
        )));
    }
    let unit = |a: f32| [a.cos(), a.sin()];
    let dir: Vec<[f32; 2]> = state.ang.iter().map(|&a| unit(a)).collect();
    let cons: Vec<[f32; 2]> = (0..n)
        .map(|k| match state.kind[k] {
            cz_fill::AXIS => unit(state.cons[k]),
            _ => [0.0; 2],
        })
        .collect();
    let mut rec = Recording::default();
    let kind = rec.upload("coif.cz_fill.kind", &state.kind);
    let cons = rec.upload("coif.cz_fill.cons", &cons);
    let dirb = rec.upload("coif.cz_fill.dir", &dir);
    let wt = rec.upload("coif.cz_fill.weight", &state.weight);
    let delta = rec.alloc("coif.cz_fill.delta", 4 * n as u64, 0);
    let cfgs = [0u32, 1].map(|colour| cz_fill::Config {
        width: state.width,
        height: state.height,
        colour,
    });
    let us = cfgs.map(|c| rec.uniform("coif.cz_fill.cfg", &c));
    for _ in 0..sweeps {
        for (cfg, u) in cfgs.iter().zip(us) {
            rec.dispatch(
                &cz_fill::STAGE,
                cz_fill::workgroups(cfg),
                &[u, kind, cons, dirb, wt, delta],
                &[],
            );
        }
    }
    rec.download(dirb);
    rec.download(wt);
    rec.download(delta);
    let out = engine.run(rec)?;
    let dir = out.get::<[f32; 2]>(dirb);
    state.weight = out.get::<f32>(wt);
    // Clamped pixels keep their angle exactly; the others take the vector's.
    for (k, e) in dir.iter().enumerate() {
        let c = state.kind[k];
        if c != cz_fill::OFF && c != cz_fill::CLAMPED && state.weight[k] > 0.0 {
            let r = e[1].atan2(e[0]).rem_euclid(2.0 * PI);
            state.ang[k] = if r < 2.0 * PI { r } else { 0.0 };
        }
    }
    // The chord between unit vectors to the angle between them; θ is half the doubled angle.
    let scale = if state.mode == Mode::Orientation {
        0.5
    } else {
        1.0
    };
    Ok(out
        .get::<f32>(delta)
        .into_iter()
        .map(|c| scale * 2.0 * (0.5 * c).clamp(0.0, 1.0).asin())
        .collect())
}

/// Sweeps `state` until it converges (see [`FillParams`]) or reaches the cap.
pub fn diffuse(engine: &Engine, state: &mut FillState, p: &FillParams) -> Result<Convergence> {
    p.validate()?;
    let n = state.kind.len();
    let clamped = (0..n)
        .filter(|&k| state.kind[k] == cz_fill::CLAMPED)
        .count();
    let reached = (0..n).filter(|&k| state.free(k)).count();
    let mut c = Convergence {
        mode: state.mode,
        sweeps: 0,
        max_delta_deg: 0.0,
        min_weight: 1.0,
        converged: reached == 0,
        clamped,
        reached,
        unreached: 0,
    };
    while !c.converged && c.sweeps < p.max_sweeps {
        let k = p.check_every.min(p.max_sweeps - c.sweeps);
        let delta = run_sweeps(engine, state, k)?;
        c.sweeps += k;
        let (mut dmax, mut wmin) = (0.0f32, 1.0f32);
        for i in (0..n).filter(|&i| state.free(i)) {
            dmax = dmax.max(delta[i]);
            wmin = wmin.min(state.weight[i]);
        }
        c.max_delta_deg = dmax.to_degrees();
        c.min_weight = wmin;
        c.converged = c.max_delta_deg < p.tol_deg && wmin > p.min_weight;
    }
    log::debug!(
        "fill ({:?}): {} sweeps, last max change {:.3}°, min weight {:.3}, converged {}",
        c.mode,
        c.sweeps,
        c.max_delta_deg,
        c.min_weight,
        c.converged
    );
    Ok(c)
}

fn check_inputs(painted: &Painted, hair: &[bool], rho_off: &RhoPrior) -> Result<()> {
    let n = painted.width as usize * painted.height as usize;
    if n == 0 {
        return Err(Error::Invalid("fill: the image is empty (0 pixels)".into()));
    }
    if hair.len() != n {
        return Err(Error::Invalid(format!(
            "fill: the hair mask has {} px, the sketch is {}x{} ({n} px)",
            hair.len(),
            painted.width,
            painted.height
        )));
    }
    let lens = [
        painted.theta.len(),
        painted.tau.len(),
        painted.rho.len(),
        painted.on.len(),
        painted.curve.len(),
    ];
    if lens.iter().any(|&l| l != n) {
        return Err(Error::Invalid(format!(
            "fill: the painted sketch's layers have {lens:?} px, not {n}"
        )));
    }
    if !hair.iter().any(|&b| b) {
        return Err(Error::Invalid("fill: the hair mask is empty".into()));
    }
    let ok = rho_off.weight.iter().all(|w| w.is_finite() && *w >= 0.0)
        && rho_off.weight.iter().sum::<f32>() > 0.0
        && rho_off.mean.iter().all(|m| m.is_finite())
        && rho_off.sigma.iter().all(|s| s.is_finite() && *s >= 0.0);
    if !ok {
        return Err(Error::Invalid(format!(
            "fill: p_nsk needs finite means, weights ≥ 0 with a positive sum and σ ≥ 0, got {rho_off:?}"
        )));
    }
    Ok(())
}

/// ρ over the hair: painted on the sketch, drawn from `rho_off` elsewhere (clamped at 0,
/// a contrast is a magnitude), then the drawn part smoothed at `sigma` by a normalised
/// Gaussian over the drawn pixels (the `sep_blur` pass). NaN off the hair.
pub fn sample_rho(
    engine: &Engine,
    painted: &Painted,
    hair: &[bool],
    rho_off: &RhoPrior,
    seed: u64,
    sigma: f32,
) -> Result<Vec<f32>> {
    check_inputs(painted, hair, rho_off)?;
    let (w, h) = (painted.width, painted.height);
    let n = hair.len();
    let mut rng = Rng::new(seed).fork(0x0072_686f);
    let p0 = rho_off.weight[0] / (rho_off.weight[0] + rho_off.weight[1]);
    let mut rho = vec![f32::NAN; n];
    let mut drawn = vec![0.0f32; n];
    for k in 0..n {
        if !hair[k] {
            continue;
        }
        if painted.rho[k].is_finite() {
            rho[k] = painted.rho[k];
            continue;
        }
        let c = (rng.next_f32() >= p0) as usize;
        rho[k] = (rho_off.mean[c] + rho_off.sigma[c] * rng.normal_f32()).max(0.0);
        drawn[k] = 1.0;
    }
    if sigma > 0.0 && drawn.iter().any(|&d| d > 0.0) {
        let num: Vec<f32> = (0..n)
            .map(|k| if drawn[k] > 0.0 { rho[k] } else { 0.0 })
            .collect();
        let mut rec = Recording::default();
        let nb = rec.upload("coif.fill.rho_num", &num);
        let db = rec.upload("coif.fill.rho_den", &drawn);
        let nb_out = rec.alloc("coif.fill.rho_num_s", 4 * n as u64, SENTINEL);
        let db_out = rec.alloc("coif.fill.rho_den_s", 4 * n as u64, SENTINEL);
        sep_blur::record_gaussian(&mut rec, nb, nb_out, w, h, sigma);
        sep_blur::record_gaussian(&mut rec, db, db_out, w, h, sigma);
        rec.download(nb_out);
        rec.download(db_out);
        let out = engine.run(rec)?;
        let (sn, sd) = (out.get::<f32>(nb_out), out.get::<f32>(db_out));
        for k in 0..n {
            // The pixel itself is in the drawn set, so the denominator is > 0.
            if drawn[k] > 0.0 && sd[k] > 0.0 {
                rho[k] = sn[k] / sd[k];
            }
        }
    }
    Ok(rho)
}

/// V from the painted sketch (Eq. 14-17), with both fills' endings.
pub fn fill_report(
    engine: &Engine,
    painted: &Painted,
    hair: &[bool],
    rho_off: &RhoPrior,
    seed: u64,
    p: &FillParams,
) -> Result<(VectorField, FillReport)> {
    check_inputs(painted, hair, rho_off)?;
    p.validate()?;
    let n = hair.len();
    let mut report = FillReport::default();

    let mut directed = FillState::directed(painted, hair);
    if let Some(s) = directed.as_mut() {
        let mut c = diffuse(engine, s, p)?;
        c.unreached = (0..n).filter(|&k| hair[k] && !s.is_set(k)).count();
        report.directed = Some(c);
    }
    let tau: Vec<f32> = match &directed {
        Some(s) => (0..n).map(|k| s.angle(k)).collect(),
        None => vec![f32::NAN; n],
    };

    let mut theta = vec![f32::NAN; n];
    if p.theta_from == ThetaFrom::Directed {
        for k in 0..n {
            if tau[k].is_finite() {
                theta[k] = wrap_pi(tau[k]);
            }
        }
    }
    // The doubled fill gives Θ, or fills in what the directed one left unset.
    if (0..n).any(|k| hair[k] && theta[k].is_nan()) {
        let mut s = FillState::orientation(painted, hair);
        let mut c = diffuse(engine, &mut s, p)?;
        c.unreached = (0..n).filter(|&k| hair[k] && !s.is_set(k)).count();
        report.orientation = Some(c);
        for (k, t) in theta.iter_mut().enumerate() {
            if t.is_nan() {
                *t = s.angle(k);
            }
        }
    }

    // d: τ projected on ±Θ.
    let mut dir = vec![[f32::NAN; 2]; n];
    for k in 0..n {
        let (t, tau) = (theta[k], tau[k]);
        if t.is_finite() && tau.is_finite() {
            let s = if (tau - t).cos() >= 0.0 { 1.0 } else { -1.0 };
            dir[k] = [s * t.cos(), s * t.sin()];
        }
    }
    let rho = sample_rho(engine, painted, hair, rho_off, seed, p.rho_sigma)?;
    Ok((
        VectorField {
            width: painted.width,
            height: painted.height,
            theta,
            rho,
            dir,
        },
        report,
    ))
}

/// V from the painted sketch (CZ06 §3.1, Eq. 14-17): see the module docs.
pub fn fill(
    engine: &Engine,
    painted: &Painted,
    hair: &[bool],
    rho_off: &RhoPrior,
    seed: u64,
    p: &FillParams,
) -> Result<VectorField> {
    fill_report(engine, painted, hair, rho_off, seed, p).map(|(v, _)| v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sketch::prim::paint;
    use crate::sketch::Curve;

    fn prior() -> RhoPrior {
        RhoPrior {
            weight: [0.7, 0.3],
            mean: [4.0, 12.0],
            sigma: [1.0, 3.0],
        }
    }

    fn stream(y: f32, axis: f32, dir: i8, x0: f32, n: usize) -> Curve {
        Curve::straight(x0, y, axis, n, 5.0, 20.0, dir)
    }

    #[test]
    fn a_uniform_sketch_fills_uniformly() {
        let (w, h) = (48u32, 40u32);
        let hair = vec![true; (w * h) as usize];
        let curves = [stream(8.0, 0.0, 1, 4.0, 9), stream(30.0, 0.0, 1, 4.0, 9)];
        let painted = paint(&curves, w, h, Some(&hair));
        let (v, r) = fill_report(
            &Engine::cpu(),
            &painted,
            &hair,
            &prior(),
            3,
            &FillParams::default(),
        )
        .unwrap();
        let o = r.orientation.unwrap();
        let d = r.directed.unwrap();
        // The weights spread slowly (Eq. 17 relaxes by 0.2 a sweep): between curves 22 px
        // apart they do not reach 0.9 within 600 sweeps, while the angles are long settled.
        println!("{o:?}\n{d:?}");
        assert!(
            o.max_delta_deg < 0.05 && d.max_delta_deg < 0.05,
            "{o:?} {d:?}"
        );
        assert_eq!((o.reached, d.reached), (1552, 1552));
        for k in 0..(w * h) as usize {
            assert!(
                v.theta[k].min(PI - v.theta[k]) < 1e-3,
                "{k}: {}",
                v.theta[k]
            );
            assert!((v.dir[k][0] - 1.0).abs() < 1e-3, "{k}: {:?}", v.dir[k]);
            assert!(v.rho[k] >= 0.0);
        }
        // Painted ρ on the sketch, drawn and smoothed off it.
        let on = painted.rho.iter().position(|r| r.is_finite()).unwrap();
        assert_eq!(v.rho[on], 20.0);
        let off: Vec<f32> = (0..v.rho.len())
            .filter(|&k| painted.rho[k].is_nan())
            .map(|k| v.rho[k])
            .collect();
        let mean = off.iter().sum::<f32>() / off.len() as f32;
        assert!((mean - (0.7 * 4.0 + 0.3 * 12.0)).abs() < 0.5, "{mean}");
    }

    #[test]
    fn convergence_needs_both_the_angles_and_the_weights() {
        // Curves 6 px apart: every free pixel is within 1 px of the sketch, the weights pass
        // 0.9 quickly. Wider apart, not within a cap of 40 sweeps.
        let run = |gap: f32, cap: u32| {
            let (w, h) = (30u32, 8 + gap as u32);
            let hair = vec![true; (w * h) as usize];
            let curves = [
                stream(2.0, 0.1, 1, 2.0, 6),
                stream(2.0 + gap, 0.1, 1, 2.0, 6),
            ];
            let painted = paint(&curves, w, h, Some(&hair));
            let mut s = FillState::orientation(&painted, &hair);
            let p = FillParams {
                max_sweeps: cap,
                check_every: 10,
                ..Default::default()
            };
            diffuse(&Engine::cpu(), &mut s, &p).unwrap()
        };
        let near = run(6.0, 600);
        let far = run(20.0, 40);
        println!("{near:?}\n{far:?}");
        assert!(near.converged && near.min_weight > 0.9 && near.sweeps < 600);
        assert!(!far.converged && far.sweeps == 40 && far.min_weight < 0.9);
    }

    #[test]
    fn undirected_sketch_gives_theta_and_no_direction() {
        let (w, h) = (40u32, 30u32);
        let hair = vec![true; (w * h) as usize];
        let curves = [stream(6.0, 0.3, 0, 4.0, 6)];
        let painted = paint(&curves, w, h, Some(&hair));
        let (v, r) = fill_report(
            &Engine::cpu(),
            &painted,
            &hair,
            &prior(),
            1,
            &FillParams::default(),
        )
        .unwrap();
        assert!(r.directed.is_none());
        assert!(v.dir.iter().all(|d| d[0].is_nan()));
        assert!(v.theta.iter().all(|t| (t - 0.3).abs() < 1e-3));
    }

    #[test]
    fn unreachable_hair_stays_unset_and_bad_input_is_refused() {
        let (w, h) = (30u32, 20u32);
        // Two hair blocks split by a non-hair column; the sketch is in the left one.
        let hair: Vec<bool> = (0..w * h).map(|k| k % w != 15).collect();
        let curves = [stream(10.0, 0.0, 1, 3.0, 2)];
        let painted = paint(&curves, w, h, Some(&hair));
        let e = Engine::cpu();
        let (v, r) = fill_report(&e, &painted, &hair, &prior(), 1, &FillParams::default()).unwrap();
        let o = r.orientation.unwrap();
        assert_eq!(o.unreached, 14 * 20);
        for k in 0..(w * h) as usize {
            assert_eq!(v.theta[k].is_nan(), k % 30 >= 15, "{k}");
        }
        assert!(fill(
            &e,
            &painted,
            &hair[1..],
            &prior(),
            1,
            &FillParams::default()
        )
        .is_err());
        let bad = RhoPrior {
            weight: [0.0, 0.0],
            ..prior()
        };
        assert!(fill(&e, &painted, &hair, &bad, 1, &FillParams::default()).is_err());
        let none = vec![false; hair.len()];
        let msg = fill(&e, &painted, &none, &prior(), 1, &FillParams::default())
            .unwrap_err()
            .to_string();
        assert!(msg.contains("empty"), "{msg}");
    }

    #[test]
    fn axis_pixels_take_the_sign_of_their_neighbours() {
        // A directed curve pointing +x and an undirected one below it pointing −x along its
        // traversal: the undirected one's pixels keep Θ = 0 and take τ = 0 from the fill.
        let (w, h) = (40u32, 24u32);
        let hair = vec![true; (w * h) as usize];
        let mut back = stream(16.0, PI, 0, 36.0, 7);
        back.dirs = [0, 0];
        let curves = [stream(6.0, 0.0, 1, 4.0, 7), back];
        let painted = paint(&curves, w, h, Some(&hair));
        let v = fill(
            &Engine::cpu(),
            &painted,
            &hair,
            &prior(),
            1,
            &FillParams::default(),
        )
        .unwrap();
        let k = 16 * w as usize + 20;
        assert!(painted.theta[k].is_finite() && painted.tau[k].is_nan());
        assert!((v.dir[k][0] - 1.0).abs() < 1e-3, "{:?}", v.dir[k]);
    }
}
