//! Each pass on lavapipe against its CPU mirror, with outputs pre-filled with a sentinel and
//! sizes that straddle the workgroup sizes.
//!
//! Tolerances: blurs and resolve 1e-5 absolute + 1e-5 relative (the same sums in another
//! order); the linear fit's moments likewise, its θ within 0.01° (a 3x3 solve in f32 on
//! sums of either order); Gabor responses are direct on the GPU and FFT on the CPU, so the confidence is
//! compared with 1e-3 of its maximum and θ within 0.5°, each on 99.9% of pixels (the issue's
//! acceptance figures). The rest are pixels where two distant orientations answer almost
//! equally and rounding picks the other one; the argmax, and the confidence measured around
//! it, then differ by design.

use crate::common;

use coif::analyze::orient::{orient, OrientParams, SENTINEL};
use coif::gpu::engine::{BufProxy, Engine, Recording};
use coif::stages::{gabor, orient_fit, orient_moments, orient_resolve, sep_blur};
use coif::testing::{
    assert_no_sentinel, compare_angles_mod_pi, compare_f32, compare_f32_fraction,
    compare_f32_nan_eq, Tolerance, PARITY_SIZES,
};

fn run_both(build: impl Fn(&mut Recording) -> Vec<BufProxy>) -> (Vec<Vec<f32>>, Vec<Vec<f32>>) {
    let run = |e: &Engine| {
        let mut rec = Recording::default();
        let outs = build(&mut rec);
        for &o in &outs {
            rec.download(o);
        }
        let dl = e.run(rec).unwrap();
        outs.iter().map(|&o| dl.get::<f32>(o)).collect::<Vec<_>>()
    };
    (run(&common::gpu()), run(&Engine::cpu()))
}

#[test]
fn sep_blur_matches_cpu() {
    for &(w, h) in PARITY_SIZES {
        for (axis, subtract, sigma) in [(0u32, 0u32, 1.5f32), (1, 1, 10.0), (0, 1, 0.4)] {
            let img = common::texture(w, h, 3);
            let other = common::texture(w, h, 4);
            let (g, c) = run_both(|rec| {
                let (radius, weights) = sep_blur::gaussian_weights(sigma);
                let cfg = sep_blur::Config {
                    width: w,
                    height: h,
                    radius,
                    axis,
                    subtract,
                    ..Default::default()
                };
                let u = rec.uniform("cfg", &cfg);
                let wb = rec.upload("w", &weights);
                let s = rec.upload("src", &img.data);
                let m = rec.upload("minus", &other.data);
                let out = rec.alloc("out", w as u64 * h as u64 * 4, SENTINEL);
                rec.dispatch(
                    &sep_blur::STAGE,
                    sep_blur::workgroups(&cfg),
                    &[u, wb, s, m, out],
                    &[],
                );
                vec![out]
            });
            let name = format!("sep_blur {w}x{h} axis {axis} sub {subtract} sigma {sigma}");
            assert_no_sentinel(&name, &g[0]).unwrap();
            compare_f32(&name, &g[0], &c[0], Tolerance::new(1e-5, 1e-5)).unwrap();
        }
    }
}

#[test]
fn gabor_matches_cpu() {
    let k = OrientParams::default().kernel;
    for (&(w, h), final_pass) in PARITY_SIZES.iter().zip([0u32, 1, 2, 1]) {
        let img = common::texture(w, h, 5);
        let mask: Vec<u32> = common::mask(w, h).iter().map(|&m| m as u32).collect();
        let (g, c) = run_both(|rec| {
            let cfg = gabor::Config {
                width: w,
                height: h,
                half: k.half(),
                n_orient: k.n_orient,
                min_response: 1e-5,
                min_contrast: 1e-3,
                final_pass,
                ..Default::default()
            };
            let u = rec.uniform("cfg", &cfg);
            let wb = rec.upload("w", &k.pair_weights_padded());
            let s = rec.upload("src", &img.data);
            let m = rec.upload("mask", &mask);
            let fx = rec.upload("first_dx", &common::texture(w, h, 11).data);
            let fy = rec.upload("first_dy", &common::texture(w, h, 12).data);
            let bytes = w as u64 * h as u64 * 4;
            let outs = [
                rec.alloc("dx", bytes, SENTINEL),
                rec.alloc("dy", bytes, SENTINEL),
                rec.alloc("conf", bytes, SENTINEL),
            ];
            rec.dispatch(
                &gabor::STAGE,
                gabor::workgroups(&cfg),
                &[u, wb, s, m, fx, fy, outs[0], outs[1], outs[2]],
                &k.constants(),
            );
            outs.to_vec()
        });
        let cmax = c[2].iter().fold(0.0f32, |a, &b| a.max(b)).max(1e-12);
        for (i, name) in ["dx", "dy", "conf"].iter().enumerate() {
            let name = format!("gabor {name} {w}x{h} final_pass {final_pass}");
            assert_no_sentinel(&name, &g[i]).unwrap();
            compare_f32_fraction(&name, &g[i], &c[i], Tolerance::new(1e-3 * cmax, 0.0), 0.999)
                .unwrap();
        }
    }
}

/// `wgsl/shared/orient_theta.wgsl` (θ from a double-angle vector) is an include, not a pass:
/// its lavapipe parity is that of the two passes built on it, `orient_resolve` and
/// `orient_fit` below, against their mirrors (which share `orient_resolve::resolve_theta`).
/// This holds only while both passes still include it.
#[test]
fn orient_theta_is_compared_through_the_passes_that_include_it() {
    for st in [&orient_resolve::STAGE, &orient_fit::STAGE] {
        assert!(
            st.wgsl.contains("#include \"shared/orient_theta.wgsl\""),
            "{} no longer includes shared/orient_theta.wgsl: compare that file another way",
            st.name
        );
    }
}

#[test]
fn orient_resolve_matches_cpu() {
    for &(w, h) in PARITY_SIZES {
        let n = (w * h) as usize;
        let dx: Vec<f32> = (0..n).map(|i| common::hash01(i as u64, 1) - 0.5).collect();
        let mut dy: Vec<f32> = (0..n).map(|i| common::hash01(i as u64, 2) - 0.5).collect();
        dy[0] = 0.0; // the zero vector has its own rule
        let mut dx0 = dx.clone();
        dx0[0] = 0.0;
        let conf: Vec<f32> = (0..n).map(|i| common::hash01(i as u64, 3)).collect();
        let mask: Vec<u32> = common::mask(w, h).iter().map(|&m| m as u32).collect();
        let (g, c) = run_both(|rec| {
            let cfg = orient_resolve::Config {
                width: w,
                height: h,
                ..Default::default()
            };
            let u = rec.uniform("cfg", &cfg);
            let b = [
                rec.upload("dx", &dx0),
                rec.upload("dy", &dy),
                rec.upload("conf", &conf),
                rec.upload("mask", &mask),
            ];
            let t = rec.alloc("theta", n as u64 * 4, SENTINEL);
            let co = rec.alloc("conf_out", n as u64 * 4, SENTINEL);
            rec.dispatch(
                &orient_resolve::STAGE,
                orient_resolve::workgroups(&cfg),
                &[u, b[0], b[1], b[2], b[3], t, co],
                &[],
            );
            vec![t, co]
        });
        let name = format!("orient_resolve {w}x{h}");
        assert_no_sentinel(&name, &g[1]).unwrap();
        // θ is NaN off the mask by design, so the sentinel check goes through the NaN-aware
        // compare: a sentinel NaN would still differ from the CPU's plain NaN in the count
        // of written pixels below.
        compare_f32_nan_eq(&name, &g[0], &c[0], Tolerance::new(1e-5, 1e-5)).unwrap();
        let written = g[0].iter().filter(|v| v.to_bits() != SENTINEL).count();
        assert_eq!(written, n, "{name}: theta not written everywhere");
        compare_f32(&name, &g[1], &c[1], Tolerance::new(0.0, 0.0)).unwrap();
    }
}

/// Smooth vector fields with a hole of zeros (as the Gabor pass leaves off the mask).
fn fit_inputs(w: u32, h: u32) -> (Vec<f32>, Vec<f32>) {
    let (a, b) = (common::texture(w, h, 21), common::texture(w, h, 22));
    let hole = |i: usize| {
        let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
        (x - 0.3 * w as f32).hypot(y - 0.6 * h as f32) < 0.15 * w.min(h) as f32
    };
    let f = |v: &[f32]| -> Vec<f32> {
        (0..v.len())
            .map(|i| if hole(i) { 0.0 } else { v[i] - 0.4 })
            .collect()
    };
    (f(&a.data), f(&b.data))
}

#[test]
fn orient_moments_matches_cpu() {
    for &(w, h) in PARITY_SIZES {
        // Plain, robust against a guide θ (acos and the trigonometry in another library:
        // 1e-4), and with the weights flattened by a power (pow in another library: 1e-4).
        for (sigma, robust, power, tol) in [
            (1.0f32, 0u32, 1.0f32, 1e-5f32),
            (4.0, 0, 1.0, 1e-5),
            (4.0, 1, 1.0, 1e-4),
            (4.0, 0, 0.25, 1e-4),
            (4.0, 1, 0.25, 1e-4),
        ] {
            let (dx, dy) = fit_inputs(w, h);
            let guide: Vec<f32> = common::texture(w, h, 23)
                .data
                .iter()
                .map(|v| v * std::f32::consts::PI)
                .collect();
            let (g, c) = run_both(|rec| {
                let (radius, seg_len, weights) = orient_moments::fit_weights(sigma);
                let cfg = orient_moments::Config {
                    width: w,
                    height: h,
                    radius,
                    seg_len,
                    robust,
                    delta: 5f32.to_radians(),
                    power,
                    ..Default::default()
                };
                let u = rec.uniform("cfg", &cfg);
                let wb = rec.upload("w", &weights);
                let bx = rec.upload("dx", &dx);
                let by = rec.upload("dy", &dy);
                let gb = rec.upload("guide", &guide);
                let n = w as u64 * h as u64;
                let out = rec.alloc("out", n * 4 * orient_moments::PLANES as u64, SENTINEL);
                rec.dispatch(
                    &orient_moments::STAGE,
                    orient_moments::workgroups(&cfg),
                    &[u, wb, bx, by, gb, out],
                    &[],
                );
                vec![out]
            });
            let name =
                format!("orient_moments {w}x{h} sigma {sigma} robust {robust} power {power}");
            assert_no_sentinel(&name, &g[0]).unwrap();
            compare_f32(&name, &g[0], &c[0], Tolerance::new(tol, tol)).unwrap();
        }
    }
}

#[test]
fn orient_fit_matches_cpu() {
    for &(w, h) in PARITY_SIZES {
        let n = (w * h) as usize;
        // The moments of real fields (orient_moments on the CPU), so the solve sees windows
        // as the stage does: full, partial at the hole's and the image's edges, and empty.
        let (dx, dy) = fit_inputs(w, h);
        let sigma = 4.0f32;
        let (radius, seg_len, weights) = orient_moments::fit_weights(sigma);
        let mut rec = Recording::default();
        let mcfg = orient_moments::Config {
            width: w,
            height: h,
            radius,
            seg_len,
            ..Default::default()
        };
        let u = rec.uniform("cfg", &mcfg);
        let wb = rec.upload("w", &weights);
        let (bx, by) = (rec.upload("dx", &dx), rec.upload("dy", &dy));
        let out = rec.alloc("m", n as u64 * 4 * orient_moments::PLANES as u64, SENTINEL);
        rec.dispatch(
            &orient_moments::STAGE,
            orient_moments::workgroups(&mcfg),
            &[u, wb, bx, by, bx, out],
            &[],
        );
        rec.download(out);
        let planes = Engine::cpu().run(rec).unwrap().get::<f32>(out);
        let conf: Vec<f32> = (0..n).map(|i| common::hash01(i as u64, 3)).collect();
        let mask: Vec<u32> = common::mask(w, h).iter().map(|&m| m as u32).collect();
        let (g, c) = run_both(|rec| {
            let cfg = orient_fit::Config {
                width: w,
                height: h,
                radius,
                seg_len,
                ridge: coif::analyze::orient::FIT_RIDGE,
                ..Default::default()
            };
            let u = rec.uniform("cfg", &cfg);
            let b = [
                rec.upload("w", &weights),
                rec.upload("planes", &planes),
                rec.upload("conf", &conf),
                rec.upload("mask", &mask),
            ];
            let t = rec.alloc("theta", n as u64 * 4, SENTINEL);
            let co = rec.alloc("conf_out", n as u64 * 4, SENTINEL);
            rec.dispatch(
                &orient_fit::STAGE,
                orient_fit::workgroups(&cfg),
                &[u, b[0], b[1], b[2], b[3], t, co],
                &[],
            );
            vec![t, co]
        });
        let name = format!("orient_fit {w}x{h}");
        assert_no_sentinel(&name, &g[1]).unwrap();
        let written = g[0].iter().filter(|v| v.to_bits() != SENTINEL).count();
        assert_eq!(written, n, "{name}: theta not written everywhere");
        compare_angles_mod_pi(&name, &g[0], &c[0], 0.01f32.to_radians(), 1.0).unwrap();
        compare_f32(&name, &g[1], &c[1], Tolerance::new(0.0, 0.0)).unwrap();
    }
}

#[test]
fn whole_orientation_stage_matches_cpu() {
    let p = OrientParams::default();
    let gpu = common::gpu();
    let cpu = Engine::cpu();
    for &(w, h) in PARITY_SIZES {
        let img = common::texture(w, h, 7);
        let mask = common::mask(w, h);
        let g = orient(&gpu, &img, Some(&mask), &p).unwrap();
        let c = orient(&cpu, &img, Some(&mask), &p).unwrap();
        let name = format!("orientation {w}x{h}");
        let st =
            compare_angles_mod_pi(&name, &g.theta, &c.theta, 0.5f32.to_radians(), 0.999).unwrap();
        let cmax = c
            .confidence
            .iter()
            .fold(0.0f32, |a, &b| a.max(b))
            .max(1e-12);
        let st2 = compare_f32_fraction(
            &format!("confidence {w}x{h}"),
            &g.confidence,
            &c.confidence,
            Tolerance::new(1e-3 * cmax, 0.0),
            0.999,
        )
        .unwrap();
        println!("{name}: theta {st}; confidence {st2}");
    }
}

#[test]
fn tiled_run_matches_one_piece() {
    // A binding limit far below the image forces several tiles with halos (the largest
    // binding is the linear fit's moment planes).
    let p = OrientParams::default();
    let (w, h) = (300, 220);
    let img = common::texture(w, h, 9);
    let mask = common::mask(w, h);
    for mut engine in [Engine::cpu(), common::gpu()] {
        let whole = orient(&engine, &img, Some(&mask), &p).unwrap();
        let side = 2 * p.halo() as u64 + 64;
        engine.set_max_binding_bytes(side * side * 4 * orient_moments::PLANES as u64);
        let tiled = orient(&engine, &img, Some(&mask), &p).unwrap();
        compare_angles_mod_pi(
            "tiled theta",
            &tiled.theta,
            &whole.theta,
            0.5f32.to_radians(),
            0.999,
        )
        .unwrap();
        let cmax = whole.confidence.iter().fold(0.0f32, |a, &b| a.max(b));
        compare_f32(
            "tiled confidence",
            &tiled.confidence,
            &whole.confidence,
            Tolerance::new(1e-4 * cmax, 0.0),
        )
        .unwrap();
    }
}

#[test]
fn binding_too_small_for_any_tile_is_a_clear_error() {
    let mut engine = Engine::cpu();
    engine.set_max_binding_bytes(1000);
    let img = common::texture(64, 64, 1);
    let err = orient(&engine, &img, None, &OrientParams::default()).unwrap_err();
    let msg = err.to_string();
    assert!(
        matches!(err, coif::Error::TooLarge { .. }) && msg.contains("1000 bytes"),
        "{msg}"
    );
}

#[test]
fn dir_diffuse_matches_cpu() {
    use coif::stages::dir_diffuse;
    for (&(w, h), use_orient) in PARITY_SIZES.iter().zip([1u32, 0, 1, 1]) {
        let n = (w * h) as usize;
        let mask: Vec<u32> = common::mask(w, h).iter().map(|&m| m as u32).collect();
        let mut theta: Vec<f32> = (0..n)
            .map(|i| std::f32::consts::PI * common::hash01(i as u64, 21))
            .collect();
        theta[n / 2] = f32::NAN; // off-hair orientation is NaN and must be ignored
        let known: Vec<f32> = (0..2 * n)
            .map(|i| common::hash01(i as u64, 22) - 0.5)
            .collect();
        let known_w: Vec<f32> = (0..n)
            .map(|i| {
                if common::hash01(i as u64, 23) < 0.1 {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        let start: Vec<f32> = (0..2 * n)
            .map(|i| common::hash01(i as u64, 24) - 0.5)
            .collect();
        let (g, c) = run_both(|rec| {
            let cfg = dir_diffuse::Config {
                width: w,
                height: h,
                lambda: 10.0,
                use_orient,
            };
            let u = rec.uniform("cfg", &cfg);
            let b = [
                rec.upload("tangent", &dir_diffuse::tangents(&theta)),
                rec.upload("mask", &mask),
                rec.upload("known", &known),
                rec.upload("known_w", &known_w),
            ];
            let mut a = rec.upload("a", &start);
            let mut d = rec.alloc("b", 8 * n as u64, SENTINEL);
            // Three sweeps: ping-pong buffers as the host runs them.
            for _ in 0..3 {
                rec.dispatch(
                    &dir_diffuse::STAGE,
                    dir_diffuse::workgroups(&cfg),
                    &[u, b[0], b[1], b[2], b[3], a, d],
                    &[],
                );
                std::mem::swap(&mut a, &mut d);
            }
            // After an odd number of sweeps `a` holds the last result and `d` the previous.
            vec![a, d]
        });
        let name = format!("dir_diffuse {w}x{h} orient {use_orient}");
        assert_no_sentinel(&name, &g[0]).unwrap();
        compare_f32(&name, &g[0], &c[0], Tolerance::new(1e-5, 1e-4)).unwrap();
    }
}
