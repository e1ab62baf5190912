//! The fill-in of V from the sketch (CZ06 §3.1, Eq. 14-17; `coif::sketch::fill`).
//!
//! - `cz_fill` on lavapipe against its CPU mirror at sizes that straddle the 8×8 workgroups
//!   (with half the x range per thread): 1×1, 63×65, 200×120. Tolerance: after 40 sweeps
//!   every set angle within 1e-3 rad of the mirror's (circularly), weights within 1e-5, the
//!   same pixels set; then the whole `fill` at 63×65 with Θ within 1e-3 rad.
//! - From the oracle sketch (`coif::sketch::oracle`, traced from the ground truth) of
//!   `coif synth` cases at 256²: the filled Θ against gt_theta on pixels ≥ 5 px inside the
//!   mask (target: mean ≤ 6°), the share of hair pixels whose filled direction agrees with
//!   gt_dir, and the fills' convergence (target: the weight schedule reaches min w > 0.9
//!   within the 600-sweep cap). Every figure is printed.

mod common;

use coif::gpu::engine::Engine;
use coif::sketch::fill::{self, FillParams, FillState, Mode};
use coif::sketch::prim::paint;
use coif::sketch::{wrap_pi, Curve, Kind, Primitive, RhoPrior};
use coif::stages::cz_fill;
use std::f32::consts::PI;

fn hash01(i: u64, seed: u64) -> f32 {
    common::hash01(i, seed)
}

/// A state with scattered clamped pixels on a smooth field, a few axis-constrained ones
/// (directed mode) and holes in the domain, so every branch of the pass runs.
fn scattered_state(w: u32, h: u32, mode: Mode) -> FillState {
    let n = (w * h) as usize;
    let field = |k: usize| {
        let (x, y) = ((k % w as usize) as f32, (k / w as usize) as f32);
        0.5 + 0.013 * x + 0.021 * y + 0.3 * (x / 17.0).sin()
    };
    let (mut kind, mut cons) = (vec![cz_fill::OFF; n], vec![0.0f32; n]);
    let (mut ang, mut weight) = (vec![0.0f32; n], vec![0.0f32; n]);
    for k in 0..n {
        let r = hash01(k as u64, 11);
        let tau = field(k);
        kind[k] = if r > 0.96 {
            cz_fill::OFF
        } else if r < 0.06 || n == 1 {
            cz_fill::CLAMPED
        } else if r < 0.1 && mode == Mode::Directed {
            cz_fill::AXIS
        } else {
            cz_fill::FREE
        };
        match kind[k] {
            cz_fill::CLAMPED => {
                weight[k] = 1.0;
                ang[k] = match mode {
                    Mode::Directed => tau.rem_euclid(2.0 * PI),
                    Mode::Orientation => (2.0 * wrap_pi(tau)).rem_euclid(2.0 * PI),
                };
            }
            cz_fill::AXIS => cons[k] = wrap_pi(tau),
            _ => {}
        }
    }
    FillState {
        width: w,
        height: h,
        mode,
        kind,
        cons,
        ang,
        weight,
    }
}

fn circ(a: f32, b: f32) -> f32 {
    let e = (a - b).rem_euclid(2.0 * PI);
    e.min(2.0 * PI - e)
}

#[test]
fn cz_fill_parity() {
    let gpu = common::gpu();
    let cpu = Engine::cpu();
    let sweeps = 40;
    for (w, h) in [(1u32, 1u32), (63, 65), (200, 120)] {
        for mode in [Mode::Directed, Mode::Orientation] {
            let s0 = scattered_state(w, h, mode);
            let (mut g, mut c) = (s0.clone(), s0.clone());
            let dg = fill::run_sweeps(&gpu, &mut g, sweeps).unwrap();
            let dc = fill::run_sweeps(&cpu, &mut c, sweeps).unwrap();
            let (mut ang_max, mut w_max, mut d_max, mut set) = (0.0f32, 0.0f32, 0.0f32, 0);
            for k in 0..(w * h) as usize {
                assert_eq!(
                    g.is_set(k),
                    c.is_set(k),
                    "{w}x{h} {mode:?}: pixel {k} set on one side only"
                );
                w_max = w_max.max((g.weight[k] - c.weight[k]).abs());
                d_max = d_max.max((dg[k] - dc[k]).abs());
                if c.is_set(k) {
                    set += 1;
                    ang_max = ang_max.max(circ(g.ang[k], c.ang[k]));
                }
            }
            println!(
                "cz_fill {w}x{h} {mode:?}, {sweeps} sweeps: {set} px set, max |Δangle| \
                 {ang_max:.2e} rad, max |Δw| {w_max:.2e}, max |Δdelta| {d_max:.2e}"
            );
            assert!(ang_max <= 1e-3, "{w}x{h} {mode:?}: angles {ang_max}");
            assert!(w_max <= 1e-5, "{w}x{h} {mode:?}: weights {w_max}");
            assert!(d_max <= 1e-3, "{w}x{h} {mode:?}: deltas {d_max}");
        }
    }

    // The whole fill (both fills to convergence or the cap, ρ drawn and smoothed).
    let (w, h) = (63u32, 65u32);
    let hair: Vec<bool> = common::mask(w, h).iter().map(|&m| m != 0).collect();
    let curves: Vec<Curve> = (0..4)
        .map(|i| {
            let axis = (i as f32 * 15.0).to_radians();
            Curve {
                kind: Kind::Stream,
                prims: (0..8)
                    .map(|j| Primitive {
                        x: 3.0 + 5.0 * j as f32 * axis.cos(),
                        y: 4.0 + 15.0 * i as f32 + 5.0 * j as f32 * axis.sin(),
                        axis,
                        rho: 9.0,
                        side: [0.0; 2],
                    })
                    .collect(),
                dirs: if i == 3 { [0, 0] } else { [1, 1] },
            }
        })
        .collect();
    let painted = paint(&curves, w, h, Some(&hair));
    let prior = RhoPrior {
        weight: [0.6, 0.4],
        mean: [3.0, 8.0],
        sigma: [1.0, 2.0],
    };
    let p = FillParams::default();
    let (vg, rg) = fill::fill_report(&gpu, &painted, &hair, &prior, 5, &p).unwrap();
    let (vc, rc) = fill::fill_report(&cpu, &painted, &hair, &prior, 5, &p).unwrap();
    println!("gpu {rg:?}\ncpu {rc:?}");
    let (mut t_max, mut r_max, mut d_max) = (0.0f32, 0.0f32, 0.0f32);
    for k in 0..(w * h) as usize {
        assert_eq!(vg.theta[k].is_nan(), vc.theta[k].is_nan(), "theta set at {k}");
        assert_eq!(vg.dir[k][0].is_nan(), vc.dir[k][0].is_nan(), "dir set at {k}");
        assert_eq!(vg.rho[k].is_nan(), vc.rho[k].is_nan(), "rho set at {k}");
        if vc.theta[k].is_finite() {
            let e = (vg.theta[k] - vc.theta[k]).abs();
            t_max = t_max.max(e.min(PI - e));
        }
        if vc.dir[k][0].is_finite() {
            d_max = d_max
                .max((vg.dir[k][0] - vc.dir[k][0]).abs())
                .max((vg.dir[k][1] - vc.dir[k][1]).abs());
        }
        if vc.rho[k].is_finite() {
            r_max = r_max.max((vg.rho[k] - vc.rho[k]).abs());
        }
    }
    println!("fill {w}x{h}: max |ΔΘ| {t_max:.2e} rad, max |Δd| {d_max:.2e}, max |Δρ| {r_max:.2e}");
    assert!(t_max <= 1e-3 && d_max <= 1e-3, "Θ {t_max}, d {d_max}");
    assert!(r_max <= 1e-4, "ρ {r_max}");
}
