//! Texture synthesis of the high band from the vector field (CZ06 §3.2;
//! `coif::sketch::texture`).
//!
//! - Parity of the passes `cz_noise`, `cz_lic`, `cz_contrast` (all three modes) and `cz_hipass` on
//!   lavapipe against their CPU mirrors (the shared sampling in `shared/cz_tex.wgsl`) at 1×1, 63×65 and 200×120, and of the whole
//!   `synthesise` at 63×65. Tolerances: the noise bit-identical; each other pass's output
//!   within 1e-5 of the mirror's relative to the input's largest magnitude (a few f32 ulps
//!   of rounding and fused multiply-adds through ≤ 9 bilinear samples); the whole synthesis
//!   (8 rounds, each re-measuring its own output) within 1e-3 relative.
//! - On fields filled from the oracle sketches of `coif synth` long, short and whorl at 256²
//!   and on the field `coif sketch` makes of the chelsea crop: (a) the Gabor orientation
//!   (`coif orient`'s) of mid-gray + I_H against the field's Θ ≥ 5 px inside the mask
//!   (target mean ≤ 5°), (b) mean |∇⊥I_H| / mean ρ (target [0.9, 1.1]), (c) Σ(∇_θ I)² /
//!   Σ(∇⊥ I)² (target ≤ 0.2), all printed.
//! - Determinism: same seed, same bits; another seed, another image.
//! - The measuring helpers fail on textures that do not follow the field.

use crate::common;

use coif::analyze::orient::{orient, GrayImage, OrientParams};
use coif::gpu::engine::{BufProxy, Engine, Recording};
use coif::sketch::fill::{self, FillParams};
use coif::sketch::prim::paint;
use coif::sketch::texture::{self, texture_stats, Inputs, TextureParams, TextureStats};
use coif::sketch::{RhoPrior, VectorField};
use coif::stages::{cz_contrast, cz_hipass, cz_lic, cz_noise};
use coif::synth::{mask_interior, synth, Style, SynthParams};
use std::f32::consts::PI;
use std::time::Instant;

/// Mean orientation error in degrees of `theta` against `truth` over `keep` (NaN in `theta`
/// counts as 90°: an orientation the measure could not find is wrong).
fn mean_err_deg(theta: &[f32], truth: &[f32], keep: &[bool]) -> f64 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for k in 0..keep.len() {
        if keep[k] && truth[k].is_finite() {
            s += if theta[k].is_finite() {
                let e = (theta[k] - truth[k]).rem_euclid(PI);
                e.min(PI - e).to_degrees() as f64
            } else {
                90.0
            };
            n += 1;
        }
    }
    s / n as f64
}

/// (a): the Gabor orientation of mid-gray + `band` (L* units, so /100 in [0, 1]) against Θ.
fn gabor_err(engine: &Engine, band: &[f32], v: &VectorField, hair: &[bool], keep: &[bool]) -> f64 {
    let img = GrayImage {
        width: v.width,
        height: v.height,
        data: band.iter().map(|&b| 0.5 + b / 100.0).collect(),
    };
    let mask: Vec<u8> = hair.iter().map(|&h| h as u8).collect();
    let o = orient(engine, &img, Some(&mask), &OrientParams::default()).unwrap();
    mean_err_deg(&o.theta, &v.theta, keep)
}

/// The field `coif synth-hair` would fill from the oracle sketch of a synthetic case.
fn oracle_field(
    engine: &Engine,
    style: Style,
    seed: u64,
    size: u32,
) -> (VectorField, Vec<bool>, Vec<bool>, image::RgbImage) {
    use coif::sketch::oracle::oracle_sketch;
    let case = synth(&SynthParams {
        style,
        seed,
        width: size,
        height: size,
    });
    let hair: Vec<bool> = case.mask.as_raw().iter().map(|&v| v > 127).collect();
    let painted = paint(&oracle_sketch(&case), size, size, Some(&hair));
    // A p_nsk like the ones the pursuit fits on these cases (L* units).
    let prior = RhoPrior {
        weight: [0.7, 0.3],
        mean: [4.0, 9.0],
        sigma: [1.5, 3.0],
    };
    let v = fill::fill(
        engine,
        &painted,
        &hair,
        &prior,
        seed,
        &FillParams::default(),
    )
    .unwrap();
    let inner = mask_interior(&case.mask, 5.0);
    (v, hair, inner, case.image)
}

struct Figures {
    gabor: f64,
    stats: TextureStats,
    secs: f64,
}

fn measure(engine: &Engine, v: &VectorField, hair: &[bool], inner: &[bool]) -> Figures {
    let t = Instant::now();
    let band = texture::synthesise(engine, v, hair, 7, &TextureParams::default()).unwrap();
    let secs = t.elapsed().as_secs_f64();
    Figures {
        gabor: gabor_err(engine, &band, v, hair, inner),
        stats: texture_stats(&band, v, hair),
        secs,
    }
}

fn line(name: &str, f: &Figures) -> String {
    let s = &f.stats;
    format!(
        "{name:>10}: (a) Gabor Θ error {:.2}°  (b) contrast ratio {:.3} (bilinear ±1 px: {:.3}; \
         mean ρ {:.2})  (c) along/across {:.3}  over {} px; synthesise {:.2} s",
        f.gabor,
        s.contrast_ratio,
        s.contrast_ratio_bilinear,
        s.mean_rho,
        s.along_across,
        s.pixels,
        f.secs
    )
}

// ---------------------------------------------------------------- parity

/// A smooth, turning orientation field with a hole in the hair (so the domain's edge is
/// exercised), noise to convolve and contrasts.
struct Fixture {
    w: u32,
    h: u32,
    hair: Vec<bool>,
    field: VectorField,
    src: Vec<f32>,
}

fn fixture(w: u32, h: u32) -> Fixture {
    let n = (w * h) as usize;
    let hair: Vec<bool> = common::mask(w, h).iter().map(|&m| m != 0).collect();
    let theta: Vec<f32> = (0..n)
        .map(|k| {
            let (x, y) = ((k % w as usize) as f32, (k / w as usize) as f32);
            (0.4 + 0.02 * x + 0.03 * y + 0.5 * (x / 13.0).sin()).rem_euclid(PI)
        })
        .collect();
    let rho: Vec<f32> = (0..n)
        .map(|k| 2.0 + 8.0 * common::hash01(k as u64, 3))
        .collect();
    let src: Vec<f32> = (0..n)
        .map(|k| 10.0 * (common::hash01(k as u64, 5) - 0.5))
        .collect();
    Fixture {
        w,
        h,
        hair,
        field: VectorField {
            width: w,
            height: h,
            theta,
            rho,
            dir: vec![[f32::NAN; 2]; n],
        },
        src,
    }
}

const SIZES: [(u32, u32); 3] = [(1, 1), (63, 65), (200, 120)];

/// Largest |a − b| over the largest |reference|.
fn rel_diff(a: &[f32], b: &[f32], scale_of: &[f32]) -> f32 {
    let scale = scale_of
        .iter()
        .fold(0.0f32, |m, v| m.max(v.abs()))
        .max(1e-30);
    a.iter()
        .zip(b)
        .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

/// Runs one dispatch of `stage` on `engine`: `inputs` uploaded in binding order after the
/// uniform, the output allocated last.
fn run_one<C: encase::ShaderType + encase::internal::WriteInto>(
    engine: &Engine,
    stage: &'static coif::gpu::engine::StageDef,
    wg: [u32; 3],
    cfg: &C,
    inputs: &[&[u32]],
    n: usize,
) -> Vec<f32> {
    let mut rec = Recording::default();
    let mut binds: Vec<BufProxy> = vec![rec.uniform("test.cfg", cfg)];
    for i in inputs {
        binds.push(rec.upload("test.in", i));
    }
    let out = rec.alloc("test.out", 4 * n as u64, coif::base::sentinel::SENTINEL);
    binds.push(out);
    rec.dispatch(stage, wg, &binds, &[]);
    rec.download(out);
    engine.run(rec).unwrap().get::<f32>(out)
}

fn words(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn tang_words(inp: &Inputs) -> Vec<u32> {
    inp.tang
        .iter()
        .flat_map(|t| [t[0].to_bits(), t[1].to_bits()])
        .collect()
}

#[test]
fn cz_noise_is_bit_identical() {
    let (gpu, cpu) = (common::gpu(), Engine::cpu());
    for (w, h) in SIZES {
        let f = fixture(w, h);
        let inp = Inputs::new(&f.field, &f.hair).unwrap();
        let cfg = cz_noise::Config::new(w, h, 0x1234_5678_9abc_def0, 12.5);
        let run = |e: &Engine| {
            run_one(
                e,
                &cz_noise::STAGE,
                cz_noise::workgroups(&cfg),
                &cfg,
                &[&inp.flags],
                inp.flags.len(),
            )
        };
        let (g, c) = (run(&gpu), run(&cpu));
        let same = g
            .iter()
            .zip(&c)
            .filter(|(a, b)| a.to_bits() == b.to_bits())
            .count();
        println!(
            "cz_noise {w}x{h}: {same} of {} values bit-identical",
            g.len()
        );
        assert_eq!(same, g.len(), "{w}x{h}");
        // Off the domain 0, on it within the amplitude.
        for (v, &f) in c.iter().zip(&inp.flags) {
            assert!(if f == 0 { *v == 0.0 } else { v.abs() <= 12.5 });
        }
    }
}

#[test]
fn cz_lic_parity() {
    let (gpu, cpu) = (common::gpu(), Engine::cpu());
    for (w, h) in SIZES {
        let f = fixture(w, h);
        let inp = Inputs::new(&f.field, &f.hair).unwrap();
        let (steps, step) = TextureParams::default().lic_steps();
        let cfg = cz_lic::Config {
            width: w,
            height: h,
            steps,
            h: step,
        };
        let (fl, tg, sr) = (inp.flags.clone(), tang_words(&inp), words(&f.src));
        let run = |e: &Engine| {
            run_one(
                e,
                &cz_lic::STAGE,
                cz_lic::workgroups(&cfg),
                &cfg,
                &[&fl, &tg, &sr],
                fl.len(),
            )
        };
        let (g, c) = (run(&gpu), run(&cpu));
        let d = rel_diff(&g, &c, &f.src);
        println!("cz_lic {w}x{h}: max |gpu − cpu| / max |src| = {d:.2e} (tolerance 1e-5)");
        assert!(d <= 1e-5, "{w}x{h}: {d}");
        // The convolution averages: it cannot leave the input's range, and it smooths.
        if w > 1 {
            let var = |v: &[f32]| v.iter().map(|x| (x * x) as f64).sum::<f64>();
            assert!(var(&c) < 0.5 * var(&f.src), "{w}x{h}: LIC did not smooth");
        }
    }
}

#[test]
fn cz_contrast_parity() {
    let (gpu, cpu) = (common::gpu(), Engine::cpu());
    for (w, h) in SIZES {
        let f = fixture(w, h);
        let inp = Inputs::new(&f.field, &f.hair).unwrap();
        let n = inp.flags.len();
        let (fl, tg, sr) = (inp.flags.clone(), tang_words(&inp), words(&f.src));
        // ρ_cur with some zeros, so the gain_max branch runs.
        let cur: Vec<f32> = (0..n)
            .map(|k| {
                let r = common::hash01(k as u64, 9);
                if r < 0.05 {
                    0.0
                } else {
                    0.5 + 12.0 * r
                }
            })
            .collect();
        let (rs, cs) = (words(&inp.rho), words(&cur));
        for mode in [
            cz_contrast::MEASURE,
            cz_contrast::GAIN,
            cz_contrast::MEASURE_GRADIENT,
        ] {
            let cfg = cz_contrast::Config {
                width: w,
                height: h,
                mode,
                gain_min: 0.25,
                gain_max: 4.0,
                ..Default::default()
            };
            let run = |e: &Engine| {
                run_one(
                    e,
                    &cz_contrast::STAGE,
                    cz_contrast::workgroups(&cfg),
                    &cfg,
                    &[&fl, &tg, &sr, &rs, &cs],
                    n,
                )
            };
            let (g, c) = (run(&gpu), run(&cpu));
            let d = rel_diff(&g, &c, &f.src);
            println!("cz_contrast {w}x{h} mode {mode}: max |gpu − cpu| / max |src| = {d:.2e} (tolerance 1e-5)");
            assert!(d <= 1e-5, "{w}x{h} mode {mode}: {d}");
        }
    }
}

#[test]
fn cz_hipass_parity() {
    let (gpu, cpu) = (common::gpu(), Engine::cpu());
    for (w, h) in SIZES {
        let f = fixture(w, h);
        let inp = Inputs::new(&f.field, &f.hair).unwrap();
        let n = inp.flags.len();
        let num: Vec<f32> = (0..n)
            .map(|k| 3.0 * (common::hash01(k as u64, 13) - 0.5))
            .collect();
        let den: Vec<f32> = (0..n)
            .map(|k| 0.05 + common::hash01(k as u64, 17))
            .collect();
        let cfg = cz_hipass::Config {
            width: w,
            height: h,
            ..Default::default()
        };
        let ins = [inp.flags.clone(), words(&f.src), words(&num), words(&den)];
        let refs: Vec<&[u32]> = ins.iter().map(|v| v.as_slice()).collect();
        let run = |e: &Engine| {
            run_one(
                e,
                &cz_hipass::STAGE,
                cz_hipass::workgroups(&cfg),
                &cfg,
                &refs,
                n,
            )
        };
        let (g, c) = (run(&gpu), run(&cpu));
        let scale: Vec<f32> = (0..n)
            .map(|k| f.src[k].abs() + (num[k] / den[k]).abs())
            .collect();
        let d = rel_diff(&g, &c, &scale);
        println!(
            "cz_hipass {w}x{h}: max |gpu − cpu| / max |src − num/den| = {d:.2e} (tolerance 1e-5)"
        );
        assert!(d <= 1e-5, "{w}x{h}: {d}");
    }
}

#[test]
fn synthesise_parity() {
    let (gpu, cpu) = (common::gpu(), Engine::cpu());
    let f = fixture(63, 65);
    let p = TextureParams::default();
    let g = texture::synthesise(&gpu, &f.field, &f.hair, 3, &p).unwrap();
    let c = texture::synthesise(&cpu, &f.field, &f.hair, 3, &p).unwrap();
    let d = rel_diff(&g, &c, &c);
    println!(
        "{} vs {}: synthesise {}x{}, {} rounds: max |gpu − cpu| / max |I_H| = {d:.2e} (tolerance 1e-3)",
        gpu.describe(),
        cpu.describe(),
        f.w,
        f.h,
        p.rounds
    );
    assert!(d <= 1e-3, "{d}");
}

// ---------------------------------------------------------------- behaviour

#[test]
fn same_seed_same_bits_other_seed_other_image() {
    let e = Engine::cpu();
    let f = fixture(96, 80);
    let p = TextureParams::default();
    let a = texture::synthesise(&e, &f.field, &f.hair, 11, &p).unwrap();
    let b = texture::synthesise(&e, &f.field, &f.hair, 11, &p).unwrap();
    let c = texture::synthesise(&e, &f.field, &f.hair, 12, &p).unwrap();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&b), "same seed, different bits");
    let on: Vec<usize> = (0..a.len()).filter(|&k| f.hair[k]).collect();
    let differ = on.iter().filter(|&&k| a[k] != c[k]).count();
    let dot: f64 = on.iter().map(|&k| (a[k] * c[k]) as f64).sum();
    let norm = |v: &[f32]| on.iter().map(|&k| (v[k] * v[k]) as f64).sum::<f64>().sqrt();
    let corr = dot / (norm(&a) * norm(&c));
    println!(
        "seeds 11 and 12: {differ} of {} hair px differ, correlation {corr:.3}",
        on.len()
    );
    assert!(differ as f64 > 0.99 * on.len() as f64 && corr.abs() < 0.2);
    // Zero mean over the hair, 0 off it.
    let mean = on.iter().map(|&k| a[k] as f64).sum::<f64>() / on.len() as f64;
    assert!(mean.abs() < 1e-4, "{mean}");
    assert!((0..a.len()).all(|k| f.hair[k] || a[k] == 0.0));
}

#[test]
fn bad_input_is_refused() {
    let e = Engine::cpu();
    let f = fixture(20, 16);
    let p = TextureParams::default();
    let msg = texture::synthesise(&e, &f.field, &f.hair[1..], 1, &p)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("hair mask"), "{msg}");
    let none = vec![false; f.hair.len()];
    let msg = texture::synthesise(&e, &f.field, &none, 1, &p)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("nothing to synthesise"), "{msg}");
    for bad in [
        TextureParams { rounds: 0, ..p },
        TextureParams { half_len: 0.0, ..p },
        TextureParams {
            half_len: f32::NAN,
            ..p
        },
        TextureParams { gain_min: 2.0, ..p },
        TextureParams {
            contrast_sigma: -1.0,
            ..p
        },
    ] {
        assert!(
            texture::synthesise(&e, &f.field, &f.hair, 1, &bad).is_err(),
            "{bad:?}"
        );
    }
    let mut neg = f.field.clone();
    neg.rho[f.hair.iter().position(|&h| h).unwrap()] = -1.0;
    assert!(texture::synthesise(&e, &neg, &f.hair, 1, &p).is_err());
}

/// A uniform horizontal field over a w×h image of all hair, ρ = `rho` everywhere.
fn flat_field(w: u32, h: u32, theta: f32, rho: f32) -> (VectorField, Vec<bool>) {
    let n = (w * h) as usize;
    (
        VectorField {
            width: w,
            height: h,
            theta: vec![theta; n],
            rho: vec![rho; n],
            dir: vec![[f32::NAN; 2]; n],
        },
        vec![true; n],
    )
}

#[test]
fn the_measures_fail_on_texture_that_does_not_follow() {
    // Stripes along x (Θ = 0), period 16 px, amplitude A: |∂y I| has the mean
    // A sin(2π/16) · mean|cos| = A · 0.3827 · 0.6407 (16 phases at half-pixel offsets).
    let (w, h, a) = (64u32, 64u32, 10.0f32);
    let expect = a * (2.0 * PI / 16.0).sin() * 0.6407;
    let (v, hair) = flat_field(w, h, 0.0, expect);
    let along: Vec<f32> = (0..w * h)
        .map(|k| a * (2.0 * PI * ((k / w) as f32 + 0.5) / 16.0).sin())
        .collect();
    let across: Vec<f32> = (0..w * h)
        .map(|k| a * (2.0 * PI * ((k % w) as f32 + 0.5) / 16.0).sin())
        .collect();
    let s = texture_stats(&along, &v, &hair);
    println!("stripes along Θ: {s:?}");
    // The first and last rows take one-sided differences, which lose at most their whole
    // share: 2 rows of 64, 3.1%. The along term is not quite 0 at the first and last columns,
    // where `theta::gradients` gives an off-image neighbour the pixel's own value.
    assert!(
        (s.contrast_ratio - 1.0).abs() < 0.032 && s.along_across < 1e-3,
        "{s:?}"
    );
    let twice: Vec<f32> = along.iter().map(|x| 2.0 * x).collect();
    let s2 = texture_stats(&twice, &v, &hair);
    let sx = texture_stats(&across, &v, &hair);
    println!("twice the contrast: {s2:?}\nstripes across Θ: {sx:?}");
    assert!(!(0.9..=1.1).contains(&s2.contrast_ratio), "{s2:?}");
    assert!(sx.along_across > 0.2, "{sx:?}");

    // The orientation check: the Gabor Θ of a synthesised band is far from a field turned 90°.
    let e = Engine::cpu();
    let f = fixture(96, 96);
    let band = texture::synthesise(&e, &f.field, &f.hair, 2, &TextureParams::default()).unwrap();
    let inner: Vec<bool> = {
        let m = image::GrayImage::from_raw(96, 96, f.hair.iter().map(|&b| 255 * b as u8).collect())
            .unwrap();
        mask_interior(&m, 5.0)
    };
    let right = gabor_err(&e, &band, &f.field, &f.hair, &inner);
    let mut turned = f.field.clone();
    turned
        .theta
        .iter_mut()
        .for_each(|t| *t = (*t + PI / 2.0).rem_euclid(PI));
    let wrong = gabor_err(&e, &band, &turned, &f.hair, &inner);
    println!("Gabor Θ error on the fixture: {right:.2}° against its field, {wrong:.2}° against it turned 90°");
    assert!(right < 10.0 && wrong > 60.0);
}

#[test]
fn texture_follows_the_oracle_field() {
    let engine = Engine::cpu();
    let mut lines = Vec::new();
    let mut short = Vec::new();
    for style in [Style::Long, Style::Short, Style::Whorl] {
        let (v, hair, inner, photo) = oracle_field(&engine, style, 1, 256);
        let f = measure(&engine, &v, &hair, &inner);
        lines.push(line(&style.to_string(), &f));
        // For scale: the same measure on the synthetic photo the field was sketched from.
        let mask: Vec<u8> = hair.iter().map(|&h| h as u8).collect();
        let o = orient(
            &engine,
            &GrayImage::from_rgb(&photo),
            Some(&mask),
            &OrientParams::default(),
        )
        .unwrap();
        lines.push(format!(
            "{:>10}  (the Gabor Θ of the synthetic photo itself against the same field: {:.2}°)",
            "",
            mean_err_deg(&o.theta, &v.theta, &inner)
        ));
        check(&style.to_string(), &f, &mut short);
    }
    println!(
        "texture from the oracle sketch's field, 256², seed 7:\n{}\ntargets (a) ≤ 5°, (b) in [0.9, 1.1], (c) ≤ 0.2: {}",
        lines.join("\n"),
        if short.is_empty() { "all met".to_string() } else { format!("not met: {}", short.join(", ")) }
    );
}

/// Asserts the targets that hold and sanity bounds where they do not (see the report);
/// collects what falls short.
fn check(name: &str, f: &Figures, short: &mut Vec<String>) {
    let s = &f.stats;
    if f.gabor > 5.0 {
        short.push(format!("{name} (a) {:.2}°", f.gabor));
    }
    if !(0.9..=1.1).contains(&s.contrast_ratio) {
        short.push(format!("{name} (b) {:.3}", s.contrast_ratio));
    }
    if s.along_across > 0.2 {
        short.push(format!("{name} (c) {:.3}", s.along_across));
    }
    // (a): the 5°, and a sanity bound of 8° on fields with a singular point (a whorl
    // centre), where Gabor's 17 px kernel itself averages across the turn.
    assert!(f.gabor <= 8.0, "{name}: Gabor Θ error {:.2}°", f.gabor);
    assert!((0.9..=1.1).contains(&s.contrast_ratio), "{name}: {s:?}");
    assert!(s.along_across <= 0.2, "{name}: {s:?}");
}

#[test]
fn texture_follows_a_real_field() {
    use coif::sketch::run::{analyse, SketchInputs, SketchParams};
    use coif::sketch::samples::{load, Sample};
    let engine = Engine::cpu();
    let img = load(Sample::Chelsea).unwrap();
    let t = Instant::now();
    let r = analyse(
        &engine,
        &SketchInputs {
            image: &img.image,
            hair: &img.hair,
            strokes: None,
        },
        &SketchParams::default(),
    )
    .unwrap();
    let sketch_secs = t.elapsed().as_secs_f64();
    let (w, h) = img.image.dimensions();
    let mask = image::GrayImage::from_raw(w, h, img.hair.iter().map(|&b| 255 * b as u8).collect())
        .unwrap();
    let inner = mask_interior(&mask, 5.0);
    let f = measure(&engine, &r.field, &img.hair, &inner);
    println!(
        "chelsea {w}x{h}, its field from `coif sketch` ({} curves, {sketch_secs:.1} s):\n{}",
        r.sketch.curves.len(),
        line("chelsea", &f)
    );
    let mut short = Vec::new();
    check("chelsea", &f, &mut short);
    println!(
        "targets: {}",
        if short.is_empty() {
            "all met".to_string()
        } else {
            format!("not met: {}", short.join(", "))
        }
    );
}

/// The grain brings a band's along/across ratio to the target exactly, keeps its mean
/// contrast across Θ, is seeded, and leaves a band already at the target alone.
#[test]
fn grain_reaches_the_along_across_target_and_keeps_the_contrast() {
    let e = Engine::cpu();
    let f = fixture(96, 96);
    let band = texture::synthesise(&e, &f.field, &f.hair, 4, &TextureParams::default()).unwrap();
    let s0 = texture_stats(&band, &f.field, &f.hair);
    for target in [0.05f32, 0.105, 0.18] {
        let mut g = band.clone();
        let r = texture::add_grain(&mut g, &f.field, &f.hair, 4, target).expect("grain added");
        let s1 = texture_stats(&g, &f.field, &f.hair);
        println!(
            "target {target}: along/across {:.4} -> {:.4} (reported {:.4}), mean across {:.4} -> {:.4}, amplitude {:.3}",
            s0.along_across, s1.along_across, r.after, s0.mean_across, s1.mean_across, r.amplitude
        );
        assert!(
            (s1.along_across - target as f64).abs() < 1e-3 * target as f64,
            "{s1:?}"
        );
        assert!((r.after - target).abs() < 1e-3 * target);
        assert!(
            (s1.mean_across / s0.mean_across - 1.0).abs() < 1e-4,
            "{s1:?}"
        );
        // Zero mean over the domain, nothing off it.
        let dom: Vec<usize> = (0..g.len()).filter(|&k| f.hair[k]).collect();
        let mean = dom.iter().map(|&k| g[k] as f64).sum::<f64>() / dom.len() as f64;
        assert!(mean.abs() < 1e-4, "{mean}");
        assert!((0..g.len()).all(|k| f.hair[k] || g[k] == 0.0));
        // Seeded: the same seed the same grain, another seed another.
        let mut again = band.clone();
        texture::add_grain(&mut again, &f.field, &f.hair, 4, target).unwrap();
        assert_eq!(g, again);
        let mut other = band.clone();
        texture::add_grain(&mut other, &f.field, &f.hair, 5, target).unwrap();
        assert_ne!(g, other);
    }
    // At or below the band's own ratio, or not a positive number: nothing to add.
    for t in [
        s0.along_across as f32 * 0.5,
        0.0,
        -1.0,
        f32::NAN,
        f32::INFINITY,
    ] {
        let mut g = band.clone();
        assert!(
            texture::add_grain(&mut g, &f.field, &f.hair, 4, t).is_none(),
            "{t}"
        );
        assert_eq!(g, band);
    }
    // The analysis's measure agrees with the stats' on the same Θ.
    let a = texture::along_across(&band, &f.field.theta, &f.hair, 96, 96).unwrap();
    assert!(
        (a as f64 - s0.along_across).abs() < 1e-4 * s0.along_across.max(1e-3),
        "{a} vs {}",
        s0.along_across
    );
}
