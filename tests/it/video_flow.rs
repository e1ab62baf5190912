//! Dense flow on orientation fields (`coif::video::flow`): accuracy on synthetic pairs with a
//! known motion (CPU engine), and parity of `flow_down`, `flow_warp`, `flow_solve`,
//! `flow_up` and of the whole `flow()` on lavapipe against the CPU mirrors.
//!
//! Test pairs: frame a is a synthetic portrait (`coif::synth`), frame b is a resampled with
//! Catmull-Rom so that a(q) = b(q + V(q)) for a known smooth V; the orientation of each
//! frame comes from `orient()` on the CPU with the flow's `feature_orient_params()` and no
//! mask (a clip has no per-frame hair mask). The end-point error is measured on a's hair pixels at least 4 px
//! inside the hair mask whose target q + V(q) is at least 4 px inside the image.

use crate::common;

use coif::analyze::orient::{orient, GrayImage};
use coif::gpu::engine::Engine;
use coif::synth::{mask_interior, synth, Style, SynthParams};
use coif::video::flow::{feature_orient_params, flow, orient_features, FlowFeatures, FlowParams};

type Field = dyn Fn(f32, f32) -> [f32; 2];

/// Catmull-Rom sample of `img` at (x, y), clamped to the image.
fn bicubic(img: &GrayImage, x: f32, y: f32) -> f32 {
    let (w, h) = (img.width as i32, img.height as i32);
    let (x0, y0) = (x.floor() as i32, y.floor() as i32);
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let k = |t: f32| {
        let t2 = t * t;
        let t3 = t2 * t;
        [
            0.5 * (-t3 + 2.0 * t2 - t),
            0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
            0.5 * (-3.0 * t3 + 4.0 * t2 + t),
            0.5 * (t3 - t2),
        ]
    };
    let (kx, ky) = (k(fx), k(fy));
    let mut acc = 0.0;
    for (j, wy) in ky.iter().enumerate() {
        let yy = (y0 - 1 + j as i32).clamp(0, h - 1);
        for (i, wx) in kx.iter().enumerate() {
            let xx = (x0 - 1 + i as i32).clamp(0, w - 1);
            acc += wx * wy * img.data[(yy * w + xx) as usize];
        }
    }
    acc
}

/// Frame b with b(q + v(q)) = a(q): each pixel x of b takes a at the point s with
/// s + v(s) = x (fixed-point iteration; v is smooth with a small gradient).
fn warp_frame(a: &GrayImage, v: &Field) -> GrayImage {
    let w = a.width;
    let data = (0..a.width * a.height)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let mut s = [x, y];
            for _ in 0..50 {
                let d = v(s[0], s[1]);
                s = [x - d[0], y - d[1]];
            }
            bicubic(a, s[0], s[1])
        })
        .collect();
    GrayImage {
        width: a.width,
        height: a.height,
        data,
    }
}

struct Pair {
    fa: FlowFeatures,
    fb: FlowFeatures,
    /// True flow at a's pixels.
    truth: Vec<[f32; 2]>,
    /// Pixels where the error is measured.
    eval: Vec<bool>,
    width: u32,
    height: u32,
}

fn make_pair(style: Style, size: u32, v: &Field) -> Pair {
    let case = synth(&SynthParams {
        style,
        seed: 1,
        width: size,
        height: size,
    });
    let a = GrayImage::from_rgb(&case.image);
    let b = warp_frame(&a, v);
    let e = Engine::cpu();
    let op = feature_orient_params();
    let oa = orient(&e, &a, None, &op).unwrap();
    let ob = orient(&e, &b, None, &op).unwrap();
    let inside = mask_interior(&case.mask, 4.0);
    let truth: Vec<[f32; 2]> = (0..size * size)
        .map(|i| v((i % size) as f32, (i / size) as f32))
        .collect();
    let lim = size as f32 - 5.0;
    let eval = (0..(size * size) as usize)
        .map(|i| {
            let (x, y) = ((i as u32 % size) as f32, (i as u32 / size) as f32);
            let t = [x + truth[i][0], y + truth[i][1]];
            inside[i] && t.iter().all(|&c| (4.0..=lim).contains(&c))
        })
        .collect();
    Pair {
        fa: orient_features(&oa),
        fb: orient_features(&ob),
        truth,
        eval,
        width: size,
        height: size,
    }
}

/// (mean EPE, 90th percentile EPE, mean |V|) over the evaluated pixels.
fn epe(pair: &Pair, got: &[[f32; 2]]) -> (f64, f64, f64) {
    let mut errs = Vec::new();
    let mut mag = 0.0f64;
    for (i, &g) in got.iter().enumerate() {
        if pair.eval[i] {
            let t = pair.truth[i];
            errs.push(((g[0] - t[0]).hypot(g[1] - t[1])) as f64);
            mag += (t[0].hypot(t[1])) as f64;
        }
    }
    assert!(errs.len() > 1000, "only {} evaluated pixels", errs.len());
    let n = errs.len() as f64;
    let mean = errs.iter().sum::<f64>() / n;
    errs.sort_by(f64::total_cmp);
    (mean, errs[(0.9 * (n - 1.0)) as usize], mag / n)
}

struct Epe {
    mean: f64,
    p90: f64,
}

fn run_case(name: &str, style: Style, size: u32, v: &Field, p: &FlowParams) -> Epe {
    let pair = make_pair(style, size, v);
    let t = std::time::Instant::now();
    let got = flow(
        &Engine::cpu(),
        &pair.fa,
        &pair.fb,
        pair.width,
        pair.height,
        p,
    )
    .unwrap();
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let zero = vec![[0.0f32; 2]; got.len()];
    let (m0, _, mag) = epe(&pair, &zero);
    let (m, p90, _) = epe(&pair, &got);
    println!(
        "{name} ({style}, {size}²): mean |V| {mag:.3} px, EPE mean {m:.3} px, p90 {p90:.3} px \
         (zero flow: {m0:.3}), flow {ms:.0} ms on cpu"
    );
    Epe { mean: m, p90 }
}

fn translation(_x: f32, _y: f32) -> [f32; 2] {
    [2.5, 0.0]
}

/// Rotation by `deg` about `c`.
fn rotation(c: [f32; 2], deg: f32) -> impl Fn(f32, f32) -> [f32; 2] {
    move |x: f32, y: f32| {
        let (s, co) = deg.to_radians().sin_cos();
        let (dx, dy) = (x - c[0], y - c[1]);
        [co * dx - s * dy + c[0] - x, s * dx + co * dy + c[1] - y]
    }
}

/// A smooth non-rigid field: up to ~2.3 px, local rotation and stretch up to ~4%.
fn nonrigid(x: f32, y: f32) -> [f32; 2] {
    [
        1.5 * (x / 40.0).sin() + 0.8 * (y / 55.0).cos(),
        1.2 * (y / 35.0 + 0.5).sin() - 0.7 * (x / 60.0).cos(),
    ]
}

/// Sub-pixel accuracy is the bar for a flow that Eq. (6) integrates over tens of frames:
/// mean EPE under 0.5 px and 90% of the hair pixels under 1 px, on two styles.
#[test]
fn flow_recovers_known_motion_on_hair() {
    let p = FlowParams::default();
    let rot = rotation([128.0, 100.0], 3.0);
    let cases: [(&str, &Field); 3] = [
        ("translation 2.5 px", &translation),
        ("rotation 3°", &rot),
        ("non-rigid", &nonrigid),
    ];
    let mut failures = Vec::new();
    for style in [Style::Long, Style::Whorl] {
        for (name, v) in cases {
            let r = run_case(name, style, 256, v, &p);
            if !(r.mean < 0.5 && r.p90 < 1.0) {
                failures.push(format!(
                    "{name} ({style}): mean {:.3}, p90 {:.3}",
                    r.mean, r.p90
                ));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "EPE over 0.5 px mean / 1 px p90: {failures:?}"
    );
}

// ---- Parity: lavapipe against the CPU mirrors ----------------------------------------------

use coif::base::sentinel::SENTINEL;
use coif::gpu::engine::{BufProxy, Recording};
use coif::stages::{flow_down, flow_solve, flow_up, flow_warp};
use coif::testing::{assert_no_sentinel, compare_f32, Tolerance};

/// Sizes straddling the 8x8 workgroups (odd, non-square), within lavapipe's patience.
const SIZES: &[(u32, u32)] = &[(1, 1), (63, 65), (96, 72)];

fn run_both(build: impl Fn(&mut Recording) -> BufProxy) -> (Vec<f32>, Vec<f32>) {
    let run = |e: &Engine| {
        let mut rec = Recording::default();
        let out = build(&mut rec);
        rec.download(out);
        e.run(rec).unwrap().get::<f32>(out)
    };
    (run(&common::gpu()), run(&Engine::cpu()))
}

/// A smooth 2-channel feature image with stripes, like `orient_features` of hair.
fn features(w: u32, h: u32, seed: u64) -> Vec<[f32; 2]> {
    let t = common::texture(w, h, seed);
    t.data
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let th = 0.8 * v + 0.01 * (i as u32 % w) as f32;
            [v * (2.0 * th).cos(), v * (2.0 * th).sin()]
        })
        .collect()
}

/// A smooth flow of a few pixels, leaving the image on one side.
fn test_flow(w: u32, h: u32) -> Vec<[f32; 2]> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            [
                3.0 + 2.0 * (y / 17.0).sin(),
                -1.5 + 1.2 * (x / 13.0).cos() + 0.03 * x,
            ]
        })
        .collect()
}

fn check(name: &str, g: &[f32], c: &[f32], tol: Tolerance) {
    assert_no_sentinel(name, g).unwrap();
    let st = compare_f32(name, g, c, tol).unwrap_or_else(|m| panic!("{m}"));
    println!("{name}: {st}");
}

#[test]
fn flow_down_matches_cpu() {
    for &(w, h) in SIZES {
        let f = features(w, h, 1);
        let cfg = flow_down::Config::halving(w, h);
        let (g, c) = run_both(|rec| {
            let u = rec.uniform("cfg", &cfg);
            let s = rec.upload("src", &f);
            let o = rec.alloc("dst", (cfg.dst_w * cfg.dst_h) as u64 * 8, SENTINEL);
            rec.dispatch(
                &flow_down::STAGE,
                flow_down::workgroups(&cfg),
                &[u, s, o],
                &[],
            );
            o
        });
        check(
            &format!("flow_down {w}x{h}"),
            &g,
            &c,
            Tolerance::new(1e-6, 1e-5),
        );
    }
}

#[test]
fn flow_up_matches_cpu() {
    for &(w, h) in SIZES {
        let cfg = flow_up::Config {
            src_w: w.div_ceil(2),
            src_h: h.div_ceil(2),
            dst_w: w,
            dst_h: h,
        };
        let coarse = test_flow(cfg.src_w, cfg.src_h);
        let (g, c) = run_both(|rec| {
            let u = rec.uniform("cfg", &cfg);
            let s = rec.upload("src", &coarse);
            let o = rec.alloc("dst", (w * h) as u64 * 8, SENTINEL);
            rec.dispatch(&flow_up::STAGE, flow_up::workgroups(&cfg), &[u, s, o], &[]);
            o
        });
        check(
            &format!("flow_up {w}x{h}"),
            &g,
            &c,
            Tolerance::new(1e-5, 1e-5),
        );
    }
}

#[test]
fn flow_warp_matches_cpu() {
    for &(w, h) in SIZES {
        let (a, b, uv) = (features(w, h, 2), features(w, h, 3), test_flow(w, h));
        let cfg = flow_warp::Config {
            width: w,
            height: h,
            ..Default::default()
        };
        let (g, c) = run_both(|rec| {
            let u = rec.uniform("cfg", &cfg);
            let (ba, bb, bf) = (
                rec.upload("a", &a),
                rec.upload("b", &b),
                rec.upload("f", &uv),
            );
            let o = rec.alloc("deriv", (w * h) as u64 * 24, SENTINEL);
            rec.dispatch(
                &flow_warp::STAGE,
                flow_warp::workgroups(&cfg),
                &[u, ba, bb, bf, o],
                &[],
            );
            o
        });
        // c0 = It - Ix u: a difference of terms up to ~10, so 1e-5 relative of those.
        check(
            &format!("flow_warp {w}x{h}"),
            &g,
            &c,
            Tolerance::new(1e-4, 1e-4),
        );
    }
}

#[test]
fn flow_solve_matches_cpu() {
    for &(w, h) in SIZES {
        let (a, b, uv) = (features(w, h, 4), features(w, h, 5), test_flow(w, h));
        let p = FlowParams::default();
        // Derivatives from the CPU warp, so both sides solve the same system.
        let deriv = {
            let mut rec = Recording::default();
            let cfg = flow_warp::Config {
                width: w,
                height: h,
                ..Default::default()
            };
            let u = rec.uniform("cfg", &cfg);
            let (ba, bb, bf) = (
                rec.upload("a", &a),
                rec.upload("b", &b),
                rec.upload("f", &uv),
            );
            let o = rec.alloc("deriv", (w * h) as u64 * 24, SENTINEL);
            rec.dispatch(
                &flow_warp::STAGE,
                flow_warp::workgroups(&cfg),
                &[u, ba, bb, bf, o],
                &[],
            );
            rec.download(o);
            Engine::cpu().run(rec).unwrap().get::<[f32; 2]>(o)
        };
        for colour in [0u32, 1] {
            let cfg = flow_solve::Config {
                width: w,
                height: h,
                colour,
                alpha: p.alpha,
                eps_data: p.eps_data,
                eps_smooth: p.eps_smooth,
                omega: p.omega,
                ..Default::default()
            };
            let (g, c) = run_both(|rec| {
                let u = rec.uniform("cfg", &cfg);
                let d = rec.upload("deriv", &deriv);
                let f = rec.upload("flow", &uv);
                rec.dispatch(
                    &flow_solve::STAGE,
                    flow_solve::workgroups(&cfg),
                    &[u, d, f],
                    &[],
                );
                f
            });
            // One half-sweep must move the flow, or the comparison says little.
            let moved = g
                .iter()
                .zip(uv.iter().flatten())
                .filter(|(a, b)| a != b)
                .count();
            assert!(w * h == 1 || moved > (w * h) as usize / 2, "{moved} moved");
            check(
                &format!("flow_solve {w}x{h} colour {colour}"),
                &g,
                &c,
                Tolerance::new(1e-4, 1e-4),
            );
        }
    }
}

/// The whole coarse-to-fine recording (4 passes, hundreds of dispatches): rounding
/// differences pass through the non-linear solve, so the bar is 1e-3 px (measured: ~5e-6).
#[test]
fn flow_matches_cpu() {
    let (w, h) = (96, 80);
    // b(q + (2, 1)) = a(q): a shifted by whole pixels, edges clamped; the finest level's
    // features another image moved the same way.
    let shift = |a: &[[f32; 2]]| -> Vec<[f32; 2]> {
        (0..w * h)
            .map(|i: u32| {
                let (x, y) = ((i % w).saturating_sub(2), (i / w).saturating_sub(1));
                a[(y * w + x) as usize]
            })
            .collect()
    };
    let (coarse, fine) = (features(w, h, 6), features(w, h, 7));
    let b = FlowFeatures {
        coarse: shift(&coarse),
        fine: shift(&fine),
    };
    let a = FlowFeatures { coarse, fine };
    let p = FlowParams::default();
    let g = flow(&common::gpu(), &a, &b, w, h, &p).unwrap();
    let c = flow(&Engine::cpu(), &a, &b, w, h, &p).unwrap();
    let flat = |v: &[[f32; 2]]| v.iter().flatten().copied().collect::<Vec<f32>>();
    let max_c = flat(&c).iter().fold(0.0f32, |m, v| m.max(v.abs()));
    assert!(max_c > 0.5, "the test flow should move ({max_c} px)");
    check(
        &format!("flow() {w}x{h}, {} levels", p.pyramid(w, h).len()),
        &flat(&g),
        &flat(&c),
        Tolerance::abs(1e-3),
    );
}
