//! Strand shading: GPU (lavapipe) against the CPU mirror, the physics of the lobes, the
//! `amount` slider, HSV recolouring and bad input.
//!
//! Parity tolerance: 1e-5 absolute on every RGBA channel (outputs are in [0, 1]). Both sides
//! run the same formulas in f32; they differ only in the rounding of exp/exp2/log2/pow and
//! fused multiply-adds on the GPU.

use coif::base::colour::{self, hsv_adjust};
use coif::base::rng::Rng;
use coif::gpu::engine::{BackendChoice, Engine, Recording};
use coif::hair::head::WeakPerspective;
use coif::render::shade::{
    self, kajiya_kay, marschner_lobes, neighbour_flags, shade, shade_model_space, view_dir, Light,
    ShadeParams, ShadingModel,
};
use coif::stages::strand_shade::{self, Config};
use coif::testing::{assert_no_sentinel, compare_f32, Tolerance};
use glam::{Mat3, Vec2, Vec3};

const TOL: Tolerance = Tolerance::abs(1e-5);

fn gpu() -> Engine {
    Engine::new(BackendChoice::Gpu).unwrap_or_else(|e| {
        panic!("{e}\nthe GPU tests need a Vulkan adapter: apt-get install mesa-vulkan-drivers")
    })
}

struct Scene {
    points: Vec<[f32; 3]>,
    counts: Vec<u32>,
    base: Vec<[f32; 4]>,
}

/// Curly random-walk strands from roots on a 10 cm sphere, 2 mm steps, 1 to 40 vertices,
/// with the awkward cases planted: a single-vertex strand, a strand whose points coincide,
/// repeated points, NaN and infinite positions, and NaN/∞/out-of-range colours.
fn scene(seed: u64, n_strands: usize) -> Scene {
    let mut rng = Rng::new(seed);
    let (mut points, mut counts, mut base) = (Vec::new(), Vec::new(), Vec::new());
    for s in 0..n_strands {
        let n = match s {
            0 => 1,
            1 => 2,
            _ => 1 + rng.below(40),
        };
        let root = Vec3::new(
            rng.range_f32(-1.0, 1.0),
            rng.range_f32(-1.0, 1.0),
            rng.range_f32(-1.0, 1.0),
        )
        .normalize_or(Vec3::Y)
            * 0.1;
        let mut dir = root.normalize();
        let mut p = root;
        for j in 0..n {
            let q = match s {
                3 => root, // every point equal: degenerate tangents throughout
                _ => p,
            };
            points.push(q.to_array());
            base.push([
                rng.range_f32(-0.1, 1.1),
                rng.range_f32(0.0, 1.0),
                rng.range_f32(0.0, 1.0),
                rng.range_f32(0.0, 1.0),
            ]);
            // Repeated point: a zero-length segment inside strand 4.
            if !(s == 4 && j == 2) {
                let turn = Vec3::new(
                    rng.range_f32(-0.6, 0.6),
                    rng.range_f32(-0.6, 0.6),
                    rng.range_f32(-0.6, 0.6),
                );
                dir = (dir + turn).normalize_or(Vec3::X);
                p += dir * 0.002;
            }
        }
        counts.push(n);
    }
    let nv = points.len();
    points[nv / 3] = [f32::NAN, 0.0, 0.0];
    points[nv / 2][1] = f32::INFINITY;
    base[7] = [f32::NAN, 0.5, 0.5, 1.0];
    base[8] = [0.5, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
    base[nv - 1] = [f32::NAN; 4];
    Scene {
        points,
        counts,
        base,
    }
}

fn lights_model() -> Vec<Light> {
    vec![
        Light {
            dir: [0.3, 0.6, 1.0],
            ..Default::default()
        },
        // A back light: drives the TT lobe.
        Light {
            dir: [0.1, 0.3, -1.0],
            color: [1.0, 0.9, 0.7],
            intensity: 1.5,
        },
        Light {
            dir: [-1.0, 0.0, 0.2],
            color: [0.2, 0.4, 1.0],
            intensity: 0.7,
        },
    ]
}

fn params_set() -> Vec<(&'static str, ShadeParams)> {
    vec![
        (
            "marschner recolour",
            ShadeParams {
                amount: 1.0,
                lights: lights_model(),
                hue: 30.0,
                saturation: 1.2,
                value: 0.9,
                ..Default::default()
            },
        ),
        (
            "kajiya-kay diffuse",
            ShadeParams {
                model: ShadingModel::KajiyaKay,
                amount: 2.0,
                diffuse: 0.5,
                lights: lights_model(),
                ..Default::default()
            },
        ),
        (
            "marschner grey full diffuse",
            ShadeParams {
                amount: 0.6,
                diffuse: 1.0,
                lights: lights_model(),
                hue: -400.0,
                saturation: 0.0,
                value: 1.3,
                alpha_r_deg: -10.0,
                beta_r_deg: 5.0,
                ..Default::default()
            },
        ),
    ]
}

fn flat(v: &[[f32; 4]]) -> Vec<f32> {
    v.iter().flatten().copied().collect()
}

fn assert_finite(name: &str, v: &[[f32; 4]]) {
    if let Some(i) = v.iter().position(|c| c.iter().any(|x| !x.is_finite())) {
        panic!("{name}: vertex {i} is {:?}", v[i]);
    }
}

#[test]
fn strand_shade_matches_cpu() {
    let sc = scene(11, 200);
    println!("{} strands, {} vertices", sc.counts.len(), sc.points.len());
    let view = [0.2f32, 0.1, 0.97];
    let (g, c) = (gpu(), Engine::cpu());
    for (name, p) in params_set() {
        let a = shade_model_space(&g, &sc.points, &sc.counts, &sc.base, view, &p).unwrap();
        let b = shade_model_space(&c, &sc.points, &sc.counts, &sc.base, view, &p).unwrap();
        assert_no_sentinel(name, &flat(&a)).unwrap();
        assert_finite(name, &a);
        assert_finite(name, &b);
        let stats = compare_f32(name, &flat(&a), &flat(&b), TOL).unwrap();
        println!("{name}: {stats}");
        let lit = b
            .iter()
            .zip(&sc.base)
            .filter(|(o, i)| (o[0] - i[0]).abs() > 1e-3)
            .count();
        assert!(lit > sc.points.len() / 4, "{name}: only {lit} vertices lit");
    }
}

/// The stage on its own with a 2D dispatch (7 workgroups per row), so the row stride and the
/// bounds check of the last partial row are exercised at a small size.
#[test]
fn strand_shade_2d_dispatch_matches_cpu() {
    let sc = scene(12, 60);
    let n = sc.points.len() as u32;
    let (wg, row_stride) = strand_shade::workgroups(n, 7);
    assert!(wg[1] > 1 && wg[0] * wg[1] * 64 > n, "{wg:?} for {n}");
    let light = [[0.0f32, 0.6, 0.8, 0.0], [1.0, 1.0, 1.0, 0.0]];
    let cfg = Config {
        n_vertices: n,
        row_stride,
        n_lights: 1,
        model: strand_shade::MODEL_MARSCHNER,
        amount: 1.0,
        recolour: 1,
        hue_deg: 200.0,
        sat_scale: 0.8,
        val_scale: 1.1,
        alpha_r: (-7.5f32).to_radians(),
        beta_r: 7.5f32.to_radians(),
        view_z: 1.0,
        ..Default::default()
    };
    let nbr = neighbour_flags(&sc.counts);
    let run = |e: &Engine| {
        let mut rec = Recording::default();
        let u = rec.uniform("cfg", &cfg);
        let b = [
            rec.upload("points", &sc.points),
            rec.upload("nbr", &nbr),
            rec.upload("base", &sc.base),
            rec.upload("lights", &light),
        ];
        // One vertex more than dispatched: it must keep its sentinel.
        let o = rec.alloc("out", 16 * (n as u64 + 1), coif::analyze::orient::SENTINEL);
        rec.dispatch(
            &strand_shade::STAGE,
            wg,
            &[u, b[0], b[1], b[2], b[3], o],
            &[],
        );
        rec.download(o);
        e.run(rec).unwrap().get::<f32>(o)
    };
    let (a, b) = (run(&gpu()), run(&Engine::cpu()));
    let m = 4 * n as usize;
    assert_no_sentinel("strand_shade 2d", &a[..m]).unwrap();
    assert!(a[m..]
        .iter()
        .all(|x| x.to_bits() == coif::analyze::orient::SENTINEL));
    let stats = compare_f32("strand_shade 2d", &a[..m], &b[..m], TOL).unwrap();
    println!("2d dispatch: {stats}");
}

/// Amount 0 with identity HSV and no diffuse weight returns the input colours bit for bit
/// on both backends (a re-render at amount 0 reproduces the photo), degenerate vertices
/// included.
#[test]
fn amount_zero_returns_base_exactly() {
    let mut sc = scene(13, 120);
    let mut rng = Rng::new(5);
    for c in &mut sc.base {
        *c = [
            rng.next_f32(),
            rng.next_f32(),
            rng.next_f32(),
            rng.next_f32(),
        ];
    }
    for model in [ShadingModel::Marschner, ShadingModel::KajiyaKay] {
        let p = ShadeParams {
            model,
            amount: 0.0,
            lights: lights_model(),
            ..Default::default()
        };
        for e in [gpu(), Engine::cpu()] {
            let out =
                shade_model_space(&e, &sc.points, &sc.counts, &sc.base, [0., 0., 1.], &p).unwrap();
            assert_eq!(out, sc.base, "{model:?} on {}", e.describe());
        }
    }
}

/// Light and view in the plane of the strand and one normal (φ = 0), view elevation θ_r
/// scanned in 0.05° steps: the highlight of a black strand (the R lobe alone: TT and TRT are
/// absorbed) peaks where (θ_i + θ_r)/2 = α_R. End to end through `shade_model_space`.
#[test]
fn r_lobe_peaks_at_alpha_r() {
    let e = Engine::cpu();
    let (t, n) = (Vec3::Y, Vec3::Z);
    let pts = [[0.0, -0.01, 0.0], [0.0, 0.0, 0.0], [0.0, 0.01, 0.0]];
    let dir = |deg: f32| n * deg.to_radians().cos() + t * deg.to_radians().sin();
    for alpha in [-5.0f32, -7.5, -10.0] {
        for theta_i in [-30.0f32, 0.0, 25.0] {
            let p = ShadeParams {
                amount: 1.0,
                alpha_r_deg: alpha,
                lights: vec![Light {
                    dir: dir(theta_i).into(),
                    ..Default::default()
                }],
                ..Default::default()
            };
            let mut best = (f32::MIN, 0.0);
            for k in 0..=3000 {
                let theta_r = -75.0 + 0.05 * k as f32;
                let out = shade_model_space(
                    &e,
                    &pts,
                    &[3],
                    &[[0.0, 0.0, 0.0, 1.0]; 3],
                    dir(theta_r).into(),
                    &p,
                )
                .unwrap();
                if out[1][0] > best.0 {
                    best = (out[1][0], theta_r);
                }
            }
            let theta_h = 0.5 * (theta_i + best.1);
            println!(
                "α_R {alpha}°, θ_i {theta_i}°: peak at θ_h {theta_h:.2}° (value {:.4})",
                best.0
            );
            assert!(best.0 > 0.02, "no highlight");
            assert!((theta_h - alpha).abs() < 1.0, "peak at θ_h {theta_h}°");
        }
    }
    // The lobe alone, also off the φ = 0 plane: same longitudinal peak.
    for phi in [0.0f32, 60.0, 120.0] {
        let l = Vec3::new(0.0, 20f32.to_radians().sin(), 20f32.to_radians().cos());
        let mut best = (f32::MIN, 0.0);
        for k in 0..=3000 {
            let th = (-75.0 + 0.05 * k as f32).to_radians();
            let ph = phi.to_radians();
            let v = Vec3::new(th.cos() * ph.sin(), th.sin(), th.cos() * ph.cos());
            let r = marschner_lobes(t, l, v, Vec3::splat(0.3), -0.1309, 0.1309).r;
            if r > best.0 {
                best = (r, th.to_degrees());
            }
        }
        let theta_h = 0.5 * (20.0 + best.1);
        println!("φ {phi}°: R peak at θ_h {theta_h:.2}°");
        assert!(
            (theta_h + 7.5).abs() < 1.0,
            "φ {phi}°: R peak at θ_h {theta_h}°"
        );
    }
}

/// View fixed across the strand, light swept around it at the elevation where M_TT peaks:
/// transmission is strongest with the light straight behind (φ = 180°) and dominates there.
#[test]
fn tt_strongest_for_back_lighting() {
    let (t, v) = (Vec3::Y, Vec3::Z);
    let c = Vec3::new(0.6, 0.4, 0.2);
    let (alpha, beta) = ((-7.5f32).to_radians(), 7.5f32.to_radians());
    let theta_i = -alpha; // θ_h = α_TT = −α_R/2 with θ_r = 0
    let at = |phi_deg: f32| {
        let ph = phi_deg.to_radians();
        let l = Vec3::new(
            theta_i.cos() * ph.sin(),
            theta_i.sin(),
            theta_i.cos() * ph.cos(),
        );
        marschner_lobes(t, l, v, c, alpha, beta)
    };
    let lum = |x: Vec3| (x.x + x.y + x.z) / 3.0;
    let mut best = (f32::MIN, 0.0);
    for k in 0..720 {
        let phi = 0.5 * k as f32;
        let tt = lum(at(phi).tt);
        if tt > best.0 {
            best = (tt, phi);
        }
    }
    let back = at(180.0);
    let front = at(0.0);
    println!(
        "TT peak at φ {}°; back: R {:.4} TT {:.4} TRT {:.4}; front TT {:.2e}",
        best.1,
        back.r,
        lum(back.tt),
        lum(back.trt),
        lum(front.tt)
    );
    assert!((best.1 - 180.0).abs() <= 1.0, "TT peak at φ {}°", best.1);
    assert!(lum(back.tt) > 100.0 * lum(front.tt));
    assert!(lum(back.tt) > back.r && lum(back.tt) > lum(back.trt));
    // Light through red-brown hair comes out redder than it went in.
    assert!(back.tt.x > back.tt.y && back.tt.y > back.tt.z);
}

/// Kajiya-Kay without shift: the highlight of a view scan peaks where t·h = 0, i.e. at the
/// mirror direction θ_r = −θ_i. End to end.
#[test]
fn kajiya_kay_peaks_where_t_dot_h_is_zero() {
    let e = Engine::cpu();
    let (t, n) = (Vec3::Y, Vec3::Z);
    let pts = [[0.0, 0.0, 0.0], [0.0, 0.01, 0.0]];
    let dir = |deg: f32| n * deg.to_radians().cos() + t * deg.to_radians().sin();
    for theta_i in [-40.0f32, 10.0, 35.0] {
        let l = dir(theta_i);
        let p = ShadeParams {
            model: ShadingModel::KajiyaKay,
            amount: 1.0,
            alpha_r_deg: 0.0,
            lights: vec![Light {
                dir: l.into(),
                ..Default::default()
            }],
            ..Default::default()
        };
        let mut best = (f32::MIN, 0.0);
        for k in 0..=3000 {
            let theta_r = -75.0 + 0.05 * k as f32;
            let out =
                shade_model_space(&e, &pts, &[2], &[[0.0; 4]; 2], dir(theta_r).into(), &p).unwrap();
            if out[0][0] > best.0 {
                best = (out[0][0], theta_r);
            }
        }
        let h = (l + dir(best.1)).normalize();
        println!(
            "θ_i {theta_i}°: KK peak at θ_r {:.2}°, t·h {:.2e}",
            best.1,
            t.dot(h)
        );
        assert!(t.dot(h).abs() < 1f32.to_radians().sin());
        assert!((best.0 - 0.1).abs() < 1e-3, "peak {}", best.0);
    }
    // The secondary lobe sits at −1.5 α_R and takes the hair colour.
    let (alpha, beta) = (-0.1309f32, 0.1309f32);
    let l = dir(0.0);
    let red = Vec3::new(1.0, 0.0, 0.0);
    let sec = |deg: f32| {
        let s = kajiya_kay(t, l, dir(deg), red, alpha, beta);
        s.x - s.y // primary is grey, so this is the secondary alone
    };
    // t·h = sin(θ) with θ ≈ θ_r/2 for θ_i = 0: the secondary peaks near θ_r = −3 α.
    let peak = (0..=2000)
        .map(|k| -50.0 + 0.05 * k as f32)
        .max_by(|a, b| sec(*a).total_cmp(&sec(*b)))
        .unwrap();
    let theta = (t.dot((l + dir(peak)).normalize())).asin().to_degrees();
    println!("secondary peak at asin(t·h) = {theta:.2}°");
    assert!((theta + 1.5 * alpha.to_degrees()).abs() < 0.5);
}

/// The highlight is linear in `amount`: out(a) − out(0) = a · (out(1) − out(0)), while no
/// channel clips (dark hair, so the sums stay below 1).
#[test]
fn highlight_scales_linearly_with_amount() {
    let mut sc = scene(14, 80);
    let mut rng = Rng::new(6);
    for c in &mut sc.base {
        *c = [
            0.02 + 0.05 * rng.next_f32(),
            0.02 + 0.03 * rng.next_f32(),
            0.01 + 0.02 * rng.next_f32(),
            1.0,
        ];
    }
    let e = Engine::cpu();
    for model in [ShadingModel::Marschner, ShadingModel::KajiyaKay] {
        // No back light: a backlit TT glow clips (it reaches several times the base colour).
        let lights = vec![lights_model()[0], lights_model()[2]];
        let run = |amount: f32| {
            let p = ShadeParams {
                model,
                amount,
                lights: lights.clone(),
                ..Default::default()
            };
            shade_model_space(&e, &sc.points, &sc.counts, &sc.base, [0.0, 0.3, 1.0], &p).unwrap()
        };
        let (o0, o1) = (run(0.0), run(1.0));
        let max1 = o1
            .iter()
            .flat_map(|c| &c[..3])
            .fold(0.0f32, |m, &x| m.max(x));
        assert!(max1 < 1.0, "{model:?}: clipped ({max1})");
        let peak = o1
            .iter()
            .zip(&o0)
            .map(|(a, b)| a[0] - b[0])
            .fold(0.0f32, f32::max);
        assert!(peak > 0.03, "{model:?}: highlight only {peak}");
        for a in [0.25f32, 0.5, 2.0] {
            let oa = run(a);
            let err = (0..oa.len())
                .flat_map(|i| (0..3).map(move |k| (i, k)))
                .map(|(i, k)| ((oa[i][k] - o0[i][k]) - a * (o1[i][k] - o0[i][k])).abs())
                .fold(0.0f32, f32::max);
            println!("{model:?} amount {a}: max deviation from linear {err:.2e}");
            assert!(err < 2e-6, "{model:?} amount {a}: {err}");
        }
    }
}

#[test]
fn hsv_round_trip_is_identity() {
    let mut worst = 0.0f32;
    let steps = 24;
    for r in 0..=steps {
        for g in 0..=steps {
            for b in 0..=steps {
                let c = [r, g, b].map(|x| (x as f32 / steps as f32).powi(2));
                for hue in [0.0f32, 360.0, -720.0] {
                    let o = hsv_adjust(c, hue, 1.0, 1.0);
                    for k in 0..3 {
                        worst = worst.max((o[k] - c[k]).abs());
                    }
                }
            }
        }
    }
    println!("HSV round trip: max error {worst:.2e}");
    assert!(worst <= 1e-6, "{worst}");
}

#[test]
fn hsv_hue_saturation_value() {
    let close = |a: [f32; 3], b: [f32; 3]| (0..3).all(|k| (a[k] - b[k]).abs() <= 1e-6);
    let red = [1.0, 0.0, 0.0];
    assert!(close(hsv_adjust(red, 120.0, 1.0, 1.0), [0.0, 1.0, 0.0]));
    assert!(close(hsv_adjust(red, 240.0, 1.0, 1.0), [0.0, 0.0, 1.0]));
    assert!(close(hsv_adjust(red, -120.0, 1.0, 1.0), [0.0, 0.0, 1.0]));
    assert!(close(
        hsv_adjust([0.0, 1.0, 0.0], 120.0, 1.0, 1.0),
        [0.0, 0.0, 1.0]
    ));
    // Yellow is half way: hue 60° in the displayed colour.
    assert!(close(hsv_adjust(red, 60.0, 1.0, 1.0), [1.0, 1.0, 0.0]));
    let brown = [0.2, 0.08, 0.03];
    // Saturation 0: a grey at the value (max channel) of the displayed colour.
    let g = hsv_adjust(brown, 0.0, 0.0, 1.0);
    assert!(
        g[0] == g[1] && g[1] == g[2] && (g[0] - 0.2).abs() < 1e-6,
        "{g:?}"
    );
    // Value scale clamps at 1 (max channel 1) and 0 gives black.
    let v = hsv_adjust(brown, 0.0, 1.0, 10.0);
    assert!((v[0] - 1.0).abs() < 1e-6, "{v:?}");
    assert_eq!(hsv_adjust(brown, 0.0, 1.0, 0.0), [0.0; 3]);
    // Saturation scale clamps at 1: the min channel goes to 0, the max stays.
    let s = hsv_adjust(brown, 0.0, 10.0, 1.0);
    assert!(s[2] == 0.0 && (s[0] - 0.2).abs() < 1e-6, "{s:?}");
    // The value of the displayed colour halves (not the linear one).
    let h = hsv_adjust([0.5; 3], 0.0, 1.0, 0.5);
    let enc = |x: f32| colour::shader::linear_to_srgb(x);
    assert!((enc(h[0]) - 0.5 * enc(0.5)).abs() < 1e-6, "{h:?}");
    // NaN in, finite out.
    assert!(hsv_adjust([f32::NAN, 0.5, 2.0], 45.0, 1.5, 1.2)
        .iter()
        .all(|x| x.is_finite()));
}

/// Shading at amount 0 recolours each vertex exactly as `hsv_adjust` does, on both backends
/// (to the parity tolerance on the GPU).
#[test]
fn recolour_in_pipeline_matches_hsv_adjust() {
    let sc = scene(15, 60);
    let p = ShadeParams {
        lights: lights_model(),
        hue: 75.0,
        saturation: 0.7,
        value: 1.2,
        ..Default::default()
    };
    let want: Vec<[f32; 4]> = sc
        .base
        .iter()
        .map(|c| {
            let o = hsv_adjust([c[0], c[1], c[2]], 75.0, 0.7, 1.2);
            let a = if c[3].is_nan() {
                0.0
            } else {
                c[3].clamp(0.0, 1.0)
            };
            [o[0], o[1], o[2], a]
        })
        .collect();
    let cpu = shade_model_space(
        &Engine::cpu(),
        &sc.points,
        &sc.counts,
        &sc.base,
        [0., 0., 1.],
        &p,
    )
    .unwrap();
    assert_eq!(cpu, want);
    let g = shade_model_space(&gpu(), &sc.points, &sc.counts, &sc.base, [0., 0., 1.], &p).unwrap();
    compare_f32("recolour gpu", &flat(&g), &flat(&want), TOL).unwrap();
}

/// Degenerate tangents keep the (sanitised) base colour; NaN colours and positions never
/// give NaN, on both backends.
#[test]
fn degenerate_tangents_and_nan_inputs() {
    let nan = f32::NAN;
    let points = [
        [0.0, 0.0, 0.0], // strand 0: one vertex
        [0.1, 0.1, 0.1], // strand 1: two equal points
        [0.1, 0.1, 0.1],
        [nan, 0.0, 0.0], // strand 2: NaN, ∞, fine, fine
        [0.0, f32::INFINITY, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.01, 0.0],
    ];
    let counts = [1, 2, 4];
    let base = [
        [0.2, 0.3, 0.4, 1.0],
        [nan, 0.3, 0.4, nan],
        [0.2, nan, 0.4, 0.5],
        [0.2, 0.3, 0.4, 1.0],
        [0.2, 0.3, 0.4, 1.0],
        [1.5, -0.5, f32::INFINITY, 1.0],
        [0.2, 0.3, 0.4, 1.0],
    ];
    let p = ShadeParams {
        amount: 1.0,
        diffuse: 1.0,
        lights: vec![Light {
            dir: [0.0, 1.0, 1.0],
            ..Default::default()
        }],
        ..Default::default()
    };
    for e in [gpu(), Engine::cpu()] {
        let out = shade_model_space(&e, &points, &counts, &base, [0.0, 0.0, 1.0], &p).unwrap();
        assert_finite(&e.describe(), &out);
        // Vertices 0-4 have no usable tangent (4's neighbours are NaN and ∞): colour kept.
        assert_eq!(out[0], [0.2, 0.3, 0.4, 1.0]);
        assert_eq!(out[1], [0.0, 0.3, 0.4, 0.0]);
        assert_eq!(out[2], [0.2, 0.0, 0.4, 0.5]);
        assert_eq!(out[3], [0.2, 0.3, 0.4, 1.0]);
        assert_eq!(out[4], [0.2, 0.3, 0.4, 1.0]);
        // Vertex 6 has a tangent (one-sided): it is shaded.
        assert_ne!(out[6], [0.2, 0.3, 0.4, 1.0]);
        assert!(out[5].iter().all(|x| (0.0..=1.0).contains(x)));
    }
}

/// `shade` takes view-space lights: rotating the model and the camera together changes
/// nothing, and the view direction is the camera's depth axis in model space.
#[test]
fn view_space_lights_follow_the_camera() {
    let sc = scene(16, 50);
    let p = ShadeParams {
        amount: 1.0,
        lights: vec![
            Light::default(),
            "0.1,0.2,-1,1.5,1,0.8,0.6".parse().unwrap(),
        ],
        ..Default::default()
    };
    let q = Mat3::from_euler(glam::EulerRot::YXZ, 0.5, -0.2, 0.1);
    let cam = WeakPerspective::new(900.0, Mat3::from_rotation_y(-0.3), Vec2::new(256.0, 300.0));
    // Depth = s · (p · view_dir).
    let pt = Vec3::new(0.03, -0.02, 0.05);
    assert!((cam.project(pt).z - cam.s * pt.dot(view_dir(&cam))).abs() < 1e-4);
    assert_eq!(
        view_dir(&WeakPerspective::frontal(1.0, Vec2::ZERO)),
        Vec3::Z
    );
    let moved: Vec<[f32; 3]> = sc
        .points
        .iter()
        .map(|&x| (q * Vec3::from(x)).to_array())
        .collect();
    let cam2 = WeakPerspective::new(cam.s, cam.r * q.transpose(), cam.t);
    let e = Engine::cpu();
    let a = shade(&e, &sc.points, &sc.counts, &sc.base, &cam, &p).unwrap();
    let b = shade(&e, &moved, &sc.counts, &sc.base, &cam2, &p).unwrap();
    compare_f32(
        "rotated together",
        &flat(&b),
        &flat(&a),
        Tolerance::abs(2e-4),
    )
    .unwrap();
    // And a different camera on the same model does change the highlights.
    let c = shade(&e, &sc.points, &sc.counts, &sc.base, &cam2, &p).unwrap();
    assert!(compare_f32("other view", &flat(&c), &flat(&a), Tolerance::abs(1e-3)).is_err());
}

/// Runs split at strand boundaries (small binding limit) give the same colours as one run.
#[test]
fn chunked_runs_match_one_run() {
    let sc = scene(17, 150);
    let p = ShadeParams {
        amount: 1.0,
        lights: lights_model(),
        hue: 10.0,
        ..Default::default()
    };
    let whole = shade_model_space(
        &Engine::cpu(),
        &sc.points,
        &sc.counts,
        &sc.base,
        [0., 0., 1.],
        &p,
    )
    .unwrap();
    let mut small = Engine::cpu();
    small.set_max_binding_bytes(16 * 100);
    let parts =
        shade_model_space(&small, &sc.points, &sc.counts, &sc.base, [0., 0., 1.], &p).unwrap();
    assert_eq!(parts, whole);
    small.set_max_binding_bytes(16 * 10);
    let long = vec![[0.0f32; 3]; 20];
    let err = shade_model_space(&small, &long, &[20], &[[0.0; 4]; 20], [0., 0., 1.], &p);
    assert!(matches!(err, Err(coif::Error::TooLarge { .. })), "{err:?}");
}

#[test]
fn bad_parameters_are_rejected() {
    let e = Engine::cpu();
    let pts = [[0.0f32; 3]; 2];
    let base = [[0.5f32; 4]; 2];
    let run = |p: &ShadeParams, counts: &[u32], base: &[[f32; 4]], view: [f32; 3]| {
        shade_model_space(&e, &pts, counts, base, view, p)
            .unwrap_err()
            .to_string()
    };
    let ok = ShadeParams::default();
    let with = |f: &dyn Fn(&mut ShadeParams)| {
        let mut p = ok.clone();
        f(&mut p);
        p
    };
    let z = [0.0, 0.0, 1.0];
    for (p, want) in [
        (with(&|p| p.amount = -1.0), "amount"),
        (with(&|p| p.amount = f32::NAN), "amount"),
        (with(&|p| p.diffuse = 1.5), "diffuse"),
        (with(&|p| p.hue = f32::INFINITY), "hue"),
        (with(&|p| p.saturation = -0.1), "saturation"),
        (with(&|p| p.value = f32::NAN), "value"),
        (with(&|p| p.beta_r_deg = 0.0), "beta_r"),
        (with(&|p| p.lights[0].dir = [0.0; 3]), "light direction"),
        (with(&|p| p.lights[0].intensity = -1.0), "intensity"),
    ] {
        let msg = run(&p, &[2], &base, z);
        assert!(msg.contains(want), "{msg:?} lacks {want:?}");
    }
    assert!(run(&ok, &[3], &base, z).contains("sum to 3"));
    assert!(run(&ok, &[2], &base[..1], z).contains("base colours"));
    assert!(run(&ok, &[2], &base, [0.0; 3]).contains("view direction"));
    assert!(run(&ok, &[2], &base, [f32::NAN, 0.0, 1.0]).contains("view direction"));
    for bad in ["1,2", "a,b,c", "0,0,0", "1,0,0,1,1,1"] {
        assert!(bad.parse::<Light>().is_err(), "{bad}");
    }
    let l: Light = "0.3, 0.6, 1".parse().unwrap();
    assert_eq!(l, Light::default());
    // Nothing to shade is not an error.
    let none = shade_model_space(&e, &[], &[], &[], z, &ok).unwrap();
    assert!(none.is_empty());
    assert_eq!(shade::DEFAULT_LIGHT_DIR, [0.3, 0.6, 1.0]);
}
