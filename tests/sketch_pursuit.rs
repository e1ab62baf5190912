//! CZ06 Step 1: the orientation field Θ (`cz_theta_gs`), the window sums of the pursuit
//! (`cz_window_sums`), and the sketch pursuit itself.

mod common;

use coif::analyze::orient::{orient, GrayImage, OrientParams};
use coif::gpu::engine::{Engine, Recording};
use coif::sketch::pursuit::{pursue, Pursuit, PursuitParams};
use coif::sketch::theta::{self, Field, ThetaParams};
use coif::stages::{cz_theta_gs, cz_window_sums, sep_blur};
use coif::synth::{synth, Style, SynthCase, SynthParams};
use std::time::Instant;

/// CIE L* (D65) of an sRGB image.
fn lightness(img: &image::RgbImage) -> Vec<f32> {
    img.pixels()
        .map(|p| {
            let lin = |v: u8| coif::base::colour::srgb_to_linear(v);
            let y = 0.2126 * lin(p[0]) + 0.7152 * lin(p[1]) + 0.0722 * lin(p[2]);
            let f = if y > 0.008856 {
                y.cbrt()
            } else {
                7.787 * y + 16.0 / 116.0
            };
            116.0 * f - 16.0
        })
        .collect()
}

/// I_H = L* minus its Gaussian (σ 8 px) normalised convolution inside the mask; 0 off it.
/// (The bands helper owns the real one; this is the same definition for the tests.)
fn high_band(engine: &Engine, img: &image::RgbImage, hair: &[bool]) -> Vec<f32> {
    let (w, h) = img.dimensions();
    let l = lightness(img);
    let m: Vec<f32> = hair.iter().map(|&b| b as u8 as f32).collect();
    let lm: Vec<f32> = l.iter().zip(&m).map(|(a, b)| a * b).collect();
    let mut rec = Recording::default();
    let bytes = 4 * w as u64 * h as u64;
    let (a, b) = (rec.upload("lm", &lm), rec.upload("m", &m));
    let (oa, ob) = (rec.alloc("oa", bytes, 0), rec.alloc("ob", bytes, 0));
    sep_blur::record_gaussian(&mut rec, a, oa, w, h, 8.0);
    sep_blur::record_gaussian(&mut rec, b, ob, w, h, 8.0);
    rec.download(oa);
    rec.download(ob);
    let dl = engine.run(rec).unwrap();
    let (num, den) = (dl.get::<f32>(oa), dl.get::<f32>(ob));
    (0..l.len())
        .map(|i| {
            if hair[i] {
                l[i] - num[i] / den[i].max(1e-6)
            } else {
                0.0
            }
        })
        .collect()
}

fn gabor(engine: &Engine, img: &image::RgbImage, hair: &[bool]) -> Vec<f32> {
    let mask: Vec<u8> = hair.iter().map(|&b| b as u8).collect();
    orient(
        engine,
        &GrayImage::from_rgb(img),
        Some(&mask),
        &OrientParams::default(),
    )
    .unwrap()
    .theta
}

fn angle_err_deg(a: f32, b: f32) -> f32 {
    let d = (a - b).rem_euclid(std::f32::consts::PI);
    d.min(std::f32::consts::PI - d).to_degrees()
}

struct Case {
    name: String,
    w: u32,
    h: u32,
    hair: Vec<bool>,
    high: Vec<f32>,
    gabor: Vec<f32>,
    gt: Vec<f32>,
}

fn case_from_synth(engine: &Engine, c: &SynthCase, name: &str) -> Case {
    let hair: Vec<bool> = c.mask.pixels().map(|p| p[0] > 127).collect();
    Case {
        name: name.into(),
        w: c.width,
        h: c.height,
        high: high_band(engine, &c.image, &hair),
        gabor: gabor(engine, &c.image, &hair),
        gt: c.gt_theta.clone(),
        hair,
    }
}

fn synth_case(engine: &Engine, style: Style, seed: u64, size: u32) -> Case {
    let c = synth(&SynthParams {
        style,
        seed,
        width: size,
        height: size,
    });
    case_from_synth(engine, &c, &format!("{style}-{seed}@{size}"))
}

fn mean_err(theta: &[f32], gt: &[f32], hair: &[bool]) -> f32 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for i in 0..hair.len() {
        if hair[i] && gt[i].is_finite() && theta[i].is_finite() {
            s += angle_err_deg(theta[i], gt[i]) as f64;
            n += 1;
        }
    }
    (s / n.max(1) as f64) as f32
}

fn run_pursuit(e: &Engine, c: &Case, p: &PursuitParams) -> (Pursuit, f64) {
    let t = Instant::now();
    let out = pursue(e, &c.high, c.w, c.h, &c.hair, &c.gabor, p).unwrap();
    (out, t.elapsed().as_secs_f64())
}

fn summary(c: &Case, out: &Pursuit, secs: f64) -> String {
    let prims: usize = out.curves.iter().map(|c| c.prims.len()).sum();
    let mut kinds = [0usize; 5];
    for k in &out.curves {
        kinds[k.kind.code() as usize] += 1;
    }
    let mut rise = 0.0f64;
    let mut last = out.energy_empty;
    for &e in &out.energy {
        rise = rise.max(e - last);
        last = e;
    }
    format!(
        "{}: {} curves ({} primitives; a/b/c/d/e {:?}), E {:.0} → {:.0} (final Θ {:.0}, largest rise {rise:.3}), \
         Θ err {:.2}° (Gabor {:.2}°), σθ² {:.3}, {:.2} s, {:?}",
        c.name,
        out.curves.len(),
        prims,
        kinds,
        out.energy_empty,
        out.energy.last().copied().unwrap_or(out.energy_empty),
        out.energy_final,
        mean_err(&out.theta, &c.gt, &c.hair),
        mean_err(&c.gabor, &c.gt, &c.hair),
        out.sigma2,
        secs,
        out.stats
    )
}

/// Debug picture: I_H in gray, the sketch's windows coloured by kind, Θ error in red.
fn dump(path: &str, c: &Case, out: &Pursuit) {
    let pt = coif::sketch::prim::paint(&out.curves, c.w, c.h, Some(&c.hair));
    let colours = [
        [255u8, 0, 0],
        [255, 160, 0],
        [0, 200, 255],
        [255, 0, 255],
        [0, 255, 0],
    ];
    let mut img = image::RgbImage::new(2 * c.w, c.h);
    for y in 0..c.h {
        for x in 0..c.w {
            let i = (y * c.w + x) as usize;
            let g = (128.0 + 4.0 * c.high[i]).clamp(0.0, 255.0) as u8;
            let mut px = [g, g, g];
            if pt.on[i] {
                let k = out.curves[pt.curve[i] as usize].kind.code() as usize;
                px = colours[k];
            }
            img.put_pixel(x, y, image::Rgb(px));
            let e = if c.hair[i] && c.gt[i].is_finite() {
                (angle_err_deg(out.theta[i], c.gt[i]) * 255.0 / 30.0).min(255.0) as u8
            } else {
                0
            };
            img.put_pixel(c.w + x, y, image::Rgb([e, (c.hair[i] as u8) * 40, 0]));
        }
    }
    img.save(path).unwrap();
}

#[test]
#[ignore = "exploration"]
fn explore() {
    let e = Engine::cpu();
    let size: u32 = std::env::var("SIZE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(256);
    let lambda: f32 = std::env::var("LAMBDA")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(30.0);
    let refit = std::env::var("REFIT").map(|s| s != "0").unwrap_or(true);
    for style in [Style::Long, Style::Whorl, Style::SidePart, Style::Short] {
        let c = synth_case(&e, style, 1, size);
        let lt: f32 = std::env::var("LT")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(coif::sketch::theta::DEFAULT_LAMBDA_THETA);
        let mut p = PursuitParams {
            lambda_nc: lambda,
            refit,
            ..Default::default()
        };
        p.theta.lambda_theta = lt;
        let (out, secs) = run_pursuit(&e, &c, &p);
        println!("{}", summary(&c, &out, secs));
        println!("  rho_on {:?}\n  rho_off {:?}", out.rho_on, out.rho_off);
        if let Ok(dir) = std::env::var("DUMP") {
            dump(&format!("{dir}/{}.png", c.name), &c, &out);
        }
    }
}

fn blur(e: &Engine, v: &[f32], w: u32, h: u32, sigma: f32) -> Vec<f32> {
    if sigma <= 0.0 {
        return v.to_vec();
    }
    let mut rec = Recording::default();
    let a = rec.upload("a", v);
    let o = rec.alloc("o", 4 * w as u64 * h as u64, 0);
    sep_blur::record_gaussian(&mut rec, a, o, w, h, sigma);
    rec.download(o);
    e.run(rec).unwrap().get::<f32>(o)
}

/// Scharr-smoothed central differences: the derivative [−1 0 1]/2 along one axis times
/// [3 10 3]/16 across it.
fn scharr(v: &[f32], w: u32, h: u32) -> Vec<f32> {
    v.to_vec()
        .iter()
        .enumerate()
        .map(|(i, _)| {
            let _ = (w, h);
            v[i]
        })
        .collect()
}

#[test]
#[ignore = "exploration"]
fn explore_theta() {
    let e = Engine::cpu();
    let _ = scharr;
    for style in [Style::Long, Style::Whorl, Style::SidePart, Style::Short] {
        let c = synth_case(&e, style, 1, 256);
        for sd in [0.0f32, 0.7, 1.0] {
            let hb = blur(&e, &c.high, c.w, c.h, sd);
            let (gx, gy) = theta::gradients(&hb, c.w, c.h, &c.hair);
            let s2 = theta::sigma2_mle(&gx, &gy, &c.hair, &c.gabor).unwrap();
            let (mut num, mut den) = (0.0f64, 0.0f64);
            for i in 0..c.hair.len() {
                if c.hair[i] && c.gt[i].is_finite() {
                    let t = theta::from_z([-(gx[i] * gx[i] - gy[i] * gy[i]), -2.0 * gx[i] * gy[i]]);
                    let s = (gx[i] * gx[i] + gy[i] * gy[i]) as f64;
                    num += s * angle_err_deg(t, c.gt[i]) as f64;
                    den += s;
                }
            }
            print!("{} σd {sd}: σθ² {s2:.2}, θo err {:.2}°;", c.name, num / den);
            for lt in [1.0f32, 0.5, 0.25] {
                let f = Field::new(&hb, c.w, c.h, &c.hair, s2, lt).unwrap();
                let fl = theta::flags(&c.hair, None);
                let z0 = theta::initial_z(&f, &c.gabor, None, &fl);
                let s = theta::solve(&e, &f, &fl, z0, 2000, &ThetaParams::default()).unwrap();
                let th = theta::theta_of(&s.z, &fl);
                print!(
                    "  λθ {lt}: {:.2}° ({})",
                    mean_err(&th, &c.gt, &c.hair),
                    s.sweeps
                );
            }
            println!("   [Gabor {:.2}°]", mean_err(&c.gabor, &c.gt, &c.hair));
        }
    }
}

/// Mean orientation error over hair pixels within `d` px of the seam.
fn seam_error(theta: &[f32], gt: &[f32], dist: &[f32], d: f32) -> f32 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for i in 0..theta.len() {
        if dist[i] <= d && gt[i].is_finite() && theta[i].is_finite() {
            s += angle_err_deg(theta[i], gt[i]) as f64;
            n += 1;
        }
    }
    (s / n.max(1) as f64) as f32
}

#[test]
#[ignore = "exploration"]
fn explore_fringe() {
    let e = Engine::cpu();
    let size: u32 = std::env::var("SIZE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(256);
    for seed in 1..=3 {
        let sp = SynthParams {
            style: Style::Fringe,
            seed,
            width: size,
            height: size,
        };
        let sc = synth(&sp);
        let seam = coif::synth::seam(&sp).unwrap();
        let c = case_from_synth(&e, &sc, &format!("fringe-{seed}@{size}"));
        let lambda: f32 = std::env::var("LAMBDA")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(30.0);
        let p = PursuitParams {
            lambda_nc: lambda,
            ..Default::default()
        };
        let (out, secs) = run_pursuit(&e, &c, &p);
        let empty = theta::diffuse(
            &e,
            &c.high,
            c.w,
            c.h,
            &c.hair,
            None,
            &c.gabor,
            &ThetaParams {
                sigma2: Some(out.sigma2),
                ..Default::default()
            },
        )
        .unwrap();
        println!("{}", summary(&c, &out, secs));
        println!(
            "  seam ≤4 px: with S {:.2}°, S=∅ {:.2}°, Gabor {:.2}°",
            seam_error(&out.theta, &c.gt, &seam.distance, 4.0),
            seam_error(&empty, &c.gt, &seam.distance, 4.0),
            seam_error(&c.gabor, &c.gt, &seam.distance, 4.0)
        );
        let prof = |t: &[f32]| -> String {
            (0..6)
                .map(|d| {
                    let (mut s, mut n) = (0.0f64, 0);
                    for i in 0..t.len() {
                        let di = seam.distance[i];
                        if di.is_finite()
                            && di.round() as i32 == d
                            && c.gt[i].is_finite()
                            && t[i].is_finite()
                        {
                            s += angle_err_deg(t[i], c.gt[i]) as f64;
                            n += 1;
                        }
                    }
                    format!("{:.1}", s / n.max(1) as f64)
                })
                .collect::<Vec<_>>()
                .join(" ")
        };
        println!(
            "  by distance 0..5: S {} | ∅ {} | Gabor {}",
            prof(&out.theta),
            prof(&empty),
            prof(&c.gabor)
        );
        if let Ok(dir) = std::env::var("DUMP") {
            dump(&format!("{dir}/{}.png", c.name), &c, &out);
        }
    }
}

#[test]
#[ignore = "exploration"]
fn explore_seam_picture() {
    let sp = SynthParams {
        style: Style::Fringe,
        seed: 1,
        width: 256,
        height: 256,
    };
    let sc = synth(&sp);
    let seam = coif::synth::seam(&sp).unwrap();
    let (x0, y0, w, h) = (100u32, 60u32, 60u32, 40u32);
    let mut img = image::RgbImage::new(w * 2, h);
    for y in 0..h {
        for x in 0..w {
            let i = ((y0 + y) * 256 + x0 + x) as usize;
            let p = *sc.image.get_pixel(x0 + x, y0 + y);
            img.put_pixel(x, y, p);
            let t = sc.gt_theta[i];
            let c = if t.is_finite() {
                [
                    (128.0 + 127.0 * (2.0 * t).cos()) as u8,
                    (128.0 + 127.0 * (2.0 * t).sin()) as u8,
                    if seam.on[i] { 255 } else { 0 },
                ]
            } else {
                [0, 0, 0]
            };
            img.put_pixel(w + x, y, image::Rgb(c));
        }
    }
    image::imageops::resize(&img, w * 16, h * 8, image::imageops::FilterType::Nearest)
        .save("/tmp/pp/seam.png")
        .unwrap();
}
