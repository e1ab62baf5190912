//! `coif synth-hair` end to end (CZ06 §3, issue 17): image → sketch → image on synthetic
//! portraits and real crops, the figures the issue asks for printed, the golden on
//! lavapipe, the command's files and errors.

use coif::analyze::orient::{orient, GrayImage, OrientParams};
use coif::eval::metrics::{erode, mean_orient_error_deg, ssim_region};
use coif::gpu::engine::{BackendChoice, Engine};
use coif::sketch::run::{analyse, SketchInputs, SketchParams, SketchResult};
use coif::sketch::samples::{self, Sample};
use coif::sketch::synth::{synthesise, SynthParams, Synthesis};
use coif::sketch::{format, region, texture, Curve, Sketch};
use coif::synth::{synth, Style, SynthParams as CaseParams};
use image::RgbImage;
use std::path::Path;
use std::process::Command;

fn case(style: Style, seed: u64, size: u32) -> (RgbImage, Vec<bool>) {
    let c = synth(&CaseParams {
        style,
        seed,
        width: size,
        height: size,
    });
    let hair = c.mask.pixels().map(|p| p[0] > 127).collect();
    (c.image, hair)
}

fn analysis_of(image: &RgbImage, hair: &[bool]) -> SketchResult {
    let inp = SketchInputs {
        image,
        hair,
        strokes: None,
    };
    analyse(&Engine::cpu(), &inp, &SketchParams::default()).unwrap()
}

fn sketch_of(image: &RgbImage, hair: &[bool]) -> Sketch {
    analysis_of(image, hair).sketch
}

/// Σ(∇_θ I_H)² / Σ(∇⊥ I_H)² of an analysed image under its own Step-1 Θ: how coherent its
/// texture is along the flow, the scale against which the pursuit's E1 weighs orientation
/// evidence (σθ², Eq. 20).
fn along_across_analysed(r: &SketchResult) -> f64 {
    let (w, h) = (r.bands.width, r.bands.height);
    let field = coif::sketch::VectorField {
        width: w,
        height: h,
        theta: r.theta.clone(),
        rho: r.field.rho.clone(),
        dir: r.field.dir.clone(),
    };
    texture::texture_stats(&r.bands.high, &field, &r.hair).along_across
}

/// The sketch as the file stores it (what `synth-hair` reads).
fn through_czs(s: &Sketch) -> Sketch {
    format::from_czs(&format::to_czs(s), Path::new("mem.czs")).unwrap()
}

fn mask_image(hair: &[bool], w: u32, h: u32) -> image::GrayImage {
    image::GrayImage::from_fn(w, h, |x, y| {
        image::Luma([if hair[(y * w + x) as usize] { 255 } else { 0 }])
    })
}

/// L* of an sRGB image, W*H.
fn lightness(img: &RgbImage) -> Vec<f32> {
    img.pixels()
        .map(|p| coif::sketch::bands::rgb_to_luv(p.0)[0])
        .collect()
}

/// Mean Gabor-orientation error (degrees) of the synthesised image against the field it
/// was synthesised along, over hair at least 3 px inside the region.
fn texture_follows(r: &Synthesis, w: u32, h: u32) -> f64 {
    let gray = GrayImage::from_rgb(&r.image);
    let mask8: Vec<u8> = r.hair.iter().map(|&m| m as u8).collect();
    let o = orient(
        &Engine::cpu(),
        &gray,
        Some(&mask8),
        &OrientParams::default(),
    )
    .unwrap();
    let inner = erode(&mask_image(&r.hair, w, h), 3);
    mean_orient_error_deg(&o.theta, &r.field.theta, &inner).0
}

/// The points of a curve every `step` px along its chain of centres.
fn samples_along(c: &Curve, step: f32) -> Vec<[f32; 2]> {
    let mut out = vec![[c.prims[0].x, c.prims[0].y]];
    for w in c.prims.windows(2) {
        let (a, b) = ([w[0].x, w[0].y], [w[1].x, w[1].y]);
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let n = (len / step).ceil().max(1.0) as usize;
        for k in 1..=n {
            let t = k as f32 / n as f32;
            out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
        }
    }
    out
}

fn seg_dist(p: [f32; 2], a: [f32; 2], b: [f32; 2]) -> f32 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

/// Share of the length of `first`'s curves that lies within `tol` px of some curve of
/// `second` (a curve of one primitive counts as a point).
fn length_within(first: &[Curve], second: &[Curve], tol: f32) -> f64 {
    let segs: Vec<([f32; 2], [f32; 2])> = second
        .iter()
        .flat_map(|c| {
            let pts: Vec<[f32; 2]> = c.prims.iter().map(|p| [p.x, p.y]).collect();
            if pts.len() == 1 {
                vec![(pts[0], pts[0])]
            } else {
                pts.windows(2).map(|w| (w[0], w[1])).collect()
            }
        })
        .collect();
    let (mut near, mut all) = (0usize, 0usize);
    for c in first {
        for p in samples_along(c, 1.0) {
            all += 1;
            near += segs.iter().any(|&(a, b)| seg_dist(p, a, b) <= tol) as usize;
        }
    }
    near as f64 / all.max(1) as f64
}

#[test]
fn the_curve_distance_helper_tells_near_from_far() {
    let c = |x0: f32, y: f32| Curve {
        kind: coif::sketch::Kind::Stream,
        prims: (0..6)
            .map(|k| coif::sketch::Primitive {
                shift: 0.0,
                x: x0 + 5.0 * k as f32,
                y,
                axis: 0.0,
                rho: 1.0,
                side: [0.0; 2],
            })
            .collect(),
        dirs: [1, 1],
    };
    assert_eq!(length_within(&[c(0.0, 10.0)], &[c(0.0, 12.0)], 3.0), 1.0);
    assert_eq!(length_within(&[c(0.0, 10.0)], &[c(0.0, 14.0)], 3.0), 0.0);
    let half = length_within(&[c(0.0, 10.0)], &[c(12.5, 10.0)], 3.0);
    assert!(half > 0.4 && half < 0.7, "{half}");
}

/// The texture follows the field and its contrast matches ρ, on synthetic portraits and a
/// real crop; image → sketch → image → sketch keeps the curves; the full-image PSNR and
/// SSIM over the hair are reported.
#[test]
fn synthesis_follows_the_sketch_and_round_trips() {
    let mut inputs: Vec<(&str, RgbImage, Vec<bool>)> = Vec::new();
    for (name, style) in [("long", Style::Long), ("short", Style::Short)] {
        let (img, hair) = case(style, 1, 256);
        inputs.push((name, img, hair));
    }
    let chelsea = samples::load(Sample::Chelsea).unwrap();
    inputs.push(("chelsea", chelsea.image, chelsea.hair));
    println!(
        "{:<8} {:>6} {:>8} {:>8} {:>8} {:>7} {:>7} {:>7} {:>7} {:>6} {:>7} {:>7} {:>7}",
        "input",
        "curves",
        "orient°",
        "ρ ratio",
        "along/x",
        "PSNR",
        "SSIM",
        "2nd→1st",
        "1st→2nd",
        "s",
        "curves2",
        "a/x in",
        "a/x syn"
    );
    let engine = Engine::cpu();
    let mut rows = Vec::new();
    for (name, img, hair) in &inputs {
        let (w, h) = img.dimensions();
        let first = analysis_of(img, hair);
        let s = through_czs(&first.sketch);
        let t = std::time::Instant::now();
        let r = synthesise(&engine, &s, None, &SynthParams::default()).unwrap();
        let secs = t.elapsed().as_secs_f64();
        let err = texture_follows(&r, w, h);
        let st = texture::texture_stats(&r.high, &r.field, &r.hair);
        // Against the input: a new noise draw, so reported only.
        let psnr = coif::render::psnr_region(img, &r.image, &r.hair);
        let ssim = ssim_region(
            &lightness(img),
            &lightness(&r.image),
            w as usize,
            h as usize,
            &r.hair,
            100.0,
        );
        // The round trip: the synthesised image analysed again, inside the sketch's region.
        // The figure: the second sketch's curves within 3 px of the first's on ≥ 90%
        // of their length; and the other way round (how much of the first is found again).
        let second = analysis_of(&r.image, &r.hair);
        let again = &second.sketch;
        let within = length_within(&again.curves, &s.curves, 3.0);
        let recall = length_within(&s.curves, &again.curves, 3.0);
        // Why the round trip can add curves: the texture along the flow, photo against
        // synthesis, each under the Θ its own analysis found (README, "coif synth-hair").
        let (ax_in, ax_syn) = (
            along_across_analysed(&first),
            along_across_analysed(&second),
        );
        println!(
            "{name:<8} {:>6} {err:>8.2} {:>8.3} {:>8.3} {psnr:>7.2} {ssim:>7.3} {:>6.1}% {:>6.1}% {secs:>6.2} {:>7} {ax_in:>7.3} {ax_syn:>7.3}",
            s.curves.len(),
            st.contrast_ratio,
            st.along_across,
            100.0 * within,
            100.0 * recall,
            again.curves.len()
        );
        rows.push((*name, err, st.contrast_ratio, st.along_across, within));
    }
    // Without the grain (the band as LIC leaves it) short hair's round trip was 75%: LIC
    // leaves the band an order of magnitude more coherent along Θ than the photo (0.009
    // against 0.105), so the second analysis's E1 weighs every orientation cue more and a
    // 3-curve sketch gains a curve where a streak ends. The grain restores the photo's ratio
    // (stored in the sketch); the comparison is printed here (README, "coif synth-hair").
    {
        let (name, img, hair) = &inputs[1];
        assert_eq!(*name, "short");
        let first = analysis_of(img, hair);
        let s = through_czs(&first.sketch);
        let off = SynthParams {
            grain: false,
            ..Default::default()
        };
        let r = synthesise(&engine, &s, None, &off).unwrap();
        let again = analysis_of(&r.image, &r.hair).sketch;
        println!(
            "short without grain: {:.1}% of the second sketch within 3 px of the first ({} curves)",
            100.0 * length_within(&again.curves, &s.curves, 3.0),
            again.curves.len()
        );
    }
    // Targets of the issue: orientation ≤ 5°, contrast within 10%, along/across ≤ 0.2, and
    // the second sketch's curves within 3 px of the first's on ≥ 90% of their length.
    for (name, err, ratio, along, within) in rows {
        assert!(
            err <= 5.0,
            "{name}: orientation of the texture {err:.2}° from the field"
        );
        assert!(
            (0.9..=1.1).contains(&ratio),
            "{name}: contrast ratio {ratio:.3}"
        );
        assert!(along <= 0.2, "{name}: along/across {along:.3}");
        assert!(
            within >= 0.9,
            "{name}: {:.1}% of the second sketch's length within 3 px of the first",
            100.0 * within
        );
    }
}

/// One sketch and seed give one image; another seed another image with the same field.
#[test]
fn seeds_are_deterministic_and_draw_different_but_similar_images() {
    let (img, hair) = case(Style::Long, 2, 128);
    let s = through_czs(&sketch_of(&img, &hair));
    let engine = Engine::cpu();
    let a = synthesise(&engine, &s, None, &SynthParams::default()).unwrap();
    let b = synthesise(&engine, &s, None, &SynthParams::default()).unwrap();
    assert_eq!(a.image, b.image);
    let other = SynthParams {
        seed: Some(s.seed + 1),
        ..Default::default()
    };
    let c = synthesise(&engine, &s, None, &other).unwrap();
    assert_ne!(a.image, c.image);
    let (e_a, e_c) = (texture_follows(&a, 128, 128), texture_follows(&c, 128, 128));
    println!(
        "orientation of the texture at 128²: seed {}: {e_a:.2}°, seed {}: {e_c:.2}°",
        s.seed,
        s.seed + 1
    );
    assert!((e_a - e_c).abs() < 2.0, "{e_a:.2}° vs {e_c:.2}°");
    // The region the file stores reproduces the mask it was traced from.
    // (1.5 px outline tolerance: 0.96 at 128², 0.99 at 512², see the README.)
    let j = region::iou(&a.hair, &hair);
    println!("region IoU with the mask: {j:.4}");
    assert!(j > 0.95, "{j}");
}

/// The synthesis at 256² on lavapipe against its golden, and against the cpu backend.
#[test]
fn synthesis_golden_on_lavapipe() {
    let (img, hair) = case(Style::Long, 1, 256);
    let s = through_czs(&sketch_of(&img, &hair));
    let gpu = Engine::new(BackendChoice::Gpu).unwrap();
    let g = synthesise(&gpu, &s, None, &SynthParams::default()).unwrap();
    let c = synthesise(&Engine::cpu(), &s, None, &SynthParams::default()).unwrap();
    let (mut worst, mut sum) = (0u8, 0u64);
    for (p, q) in g.image.pixels().zip(c.image.pixels()) {
        for k in 0..3 {
            let d = p[k].abs_diff(q[k]);
            worst = worst.max(d);
            sum += d as u64;
        }
    }
    println!(
        "lavapipe vs cpu: max {worst}, mean {:.4} per channel",
        sum as f64 / (3 * 256 * 256) as f64
    );
    coif::testing::check_golden_rgb("sketch_synth_hair_long_256", &g.image).unwrap();
}

fn coif() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coif"))
}

fn fails_with(args: &[&std::ffi::OsStr], needles: &[&str]) {
    let o = coif().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{args:?} succeeded");
    for n in needles {
        assert!(err.contains(n), "{args:?}: {err}");
    }
}

#[test]
fn the_command_writes_the_image_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (img, hair) = case(Style::Long, 2, 128);
    let s = sketch_of(&img, &hair);
    assert!(!s.curves.is_empty());
    format::save(&s, &d.join("hair.czs")).unwrap();
    img.save(d.join("photo.png")).unwrap();
    let o = coif()
        .args(["synth-hair", "--backend", "cpu", "--sketch"])
        .arg(d.join("hair.czs"))
        .arg("--out")
        .arg(d.join("hair.png"))
        .arg("--over")
        .arg(d.join("photo.png"))
        .arg("--layers")
        .arg(d.join("layers"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let said = |o: &std::process::Output| {
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
    };
    assert!(said(&o).contains("grain: along/across"), "{}", said(&o));
    let out = image::open(d.join("hair.png")).unwrap().to_rgb8();
    assert_eq!(out.dimensions(), (128, 128));
    // Without grain: another image, and the report says so.
    let o = coif()
        .args(["synth-hair", "--backend", "cpu", "--no-grain", "--sketch"])
        .arg(d.join("hair.czs"))
        .arg("--out")
        .arg(d.join("plain.png"))
        .arg("--over")
        .arg(d.join("photo.png"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", said(&o));
    assert!(said(&o).contains("grain: off"), "{}", said(&o));
    assert_ne!(image::open(d.join("plain.png")).unwrap().to_rgb8(), out);
    // Off the hair the photo shows through.
    let off = (0..128 * 128)
        .find(|&i| !region::fill(&s.region, 128, 128)[i])
        .unwrap();
    let (x, y) = ((off % 128) as u32, (off / 128) as u32);
    assert_eq!(out.get_pixel(x, y), img.get_pixel(x, y));
    for f in [
        "theta.npy",
        "vector.npy",
        "rho.npy",
        "low.npy",
        "high.npy",
        "field.png",
    ] {
        assert!(d.join("layers").join(f).is_file(), "{f}");
    }
    // JPEG by extension, from the SVG.
    format::save(&s, &d.join("sketch.svg")).unwrap();
    let o = coif()
        .args(["synth-hair", "--backend", "cpu", "--seed", "9", "--sketch"])
        .arg(d.join("sketch.svg"))
        .arg("--out")
        .arg(d.join("hair.jpg"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        &std::fs::read(d.join("hair.jpg")).unwrap()[..2],
        &[0xFF, 0xD8]
    );

    let sk = d.join("hair.czs");
    let os = |p: &Path| p.as_os_str().to_owned();
    // The output's type, the photo's size, an empty sketch, a drawing that is not a sketch.
    fails_with(
        &[
            "synth-hair".as_ref(),
            "--sketch".as_ref(),
            &os(&sk),
            "--out".as_ref(),
            &os(&d.join("x.bmp")),
        ],
        &["x.bmp", ".png or .jpg"],
    );
    assert!(!d.join("x.bmp").exists());
    image::RgbImage::new(64, 64)
        .save(d.join("small.png"))
        .unwrap();
    fails_with(
        &[
            "synth-hair".as_ref(),
            "--sketch".as_ref(),
            &os(&sk),
            "--out".as_ref(),
            &os(&d.join("y.png")),
            "--over".as_ref(),
            &os(&d.join("small.png")),
        ],
        &["small.png", "64x64"],
    );
    let mut empty = s.clone();
    empty.curves.clear();
    format::save(&empty, &d.join("empty.json")).unwrap();
    fails_with(
        &[
            "synth-hair".as_ref(),
            "--sketch".as_ref(),
            &os(&d.join("empty.json")),
            "--out".as_ref(),
            &os(&d.join("z.png")),
        ],
        &["empty.json", "no curves"],
    );
    std::fs::write(
        d.join("drawing.svg"),
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"10\" height=\"10\"><path d=\"M 1 1 L 5 5\"/></svg>",
    )
    .unwrap();
    fails_with(
        &[
            "synth-hair".as_ref(),
            "--sketch".as_ref(),
            &os(&d.join("drawing.svg")),
            "--out".as_ref(),
            &os(&d.join("z.png")),
        ],
        &["drawing.svg", "not a coif sketch"],
    );
    assert!(!d.join("y.png").exists() && !d.join("z.png").exists());
}
