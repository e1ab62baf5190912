//! `coif sketch` end to end (CZ06 §4, issue 16): the whole analysis on synthetic portraits
//! with ground truth and on real photographs, the figures the issue asks for printed, the
//! command's files and its errors.

use coif::eval::metrics::erode;
use coif::gpu::engine::Engine;
use coif::sketch::run::{analyse, SketchInputs, SketchParams, SketchResult};
use coif::sketch::samples::{self, Sample};
use coif::sketch::{format, swc};
use coif::synth::{synth, Style, SynthCase, SynthParams};
use std::path::Path;
use std::process::Command;

fn case_at(style: Style, seed: u64, size: u32) -> SynthCase {
    synth(&SynthParams {
        style,
        seed,
        width: size,
        height: size,
    })
}

fn case(style: Style, seed: u64) -> SynthCase {
    case_at(style, seed, 256)
}

fn hair_of(c: &SynthCase) -> Vec<bool> {
    c.mask.pixels().map(|p| p[0] > 127).collect()
}

fn run(c: &SynthCase, strokes: bool) -> SketchResult {
    let hair = hair_of(c);
    let inp = SketchInputs {
        image: &c.image,
        hair: &hair,
        strokes: strokes.then_some(&c.strokes),
    };
    analyse(&Engine::cpu(), &inp, &SketchParams::default()).unwrap()
}

/// Mean orientation error (degrees) of `theta` against `truth` over `keep`; unset counts 90°.
fn mean_err(theta: &[f32], truth: &[f32], keep: &[bool]) -> (f64, usize) {
    coif::eval::metrics::mean_orient_error_deg(theta, truth, keep)
}

/// Share of hair pixels whose growth direction agrees (positive dot product) with the truth;
/// an undecided pixel disagrees.
fn dir_agreement(dir: &[[f32; 2]], gt_dir: &[f32], hair: &[bool]) -> f64 {
    let (mut good, mut n) = (0usize, 0usize);
    for i in 0..hair.len() {
        let g = [gt_dir[2 * i], gt_dir[2 * i + 1]];
        if !hair[i] || !g[0].is_finite() {
            continue;
        }
        n += 1;
        let d = dir[i];
        good += (d[0] * g[0] + d[1] * g[1] > 0.0) as usize;
    }
    good as f64 / n.max(1) as f64
}

/// The growth directions the fill gives for `curves` (directed) on the sketch's lattice.
fn filled_dirs(r: &SketchResult, curves: Vec<coif::sketch::Curve>, hair: &[bool]) -> Vec<[f32; 2]> {
    let s = format::quantise(&coif::sketch::Sketch {
        curves,
        ..r.sketch.clone()
    });
    let painted = coif::sketch::prim::paint(&s.curves, s.width, s.height, Some(hair));
    coif::sketch::fill::fill(
        &Engine::cpu(),
        &painted,
        hair,
        &s.rho_off,
        s.seed,
        &SketchParams::default().fill,
    )
    .unwrap()
    .dir
}

/// Issue 16's figures on the four synthetic styles at 512², all printed first. Asserted
/// where this build reaches the thresholds: SW's energy against ICM and prior-only,
/// the fill ≤ 6°, directions ≥ 95% (whorl 90%) except on the side part, ≤ 1 KiB except on
/// the long case (both measured short and reported).
#[test]
fn synthetic_cases_sketch_fill_and_directions() {
    println!(
        "{:<9} {:>6} {:>6} {:>6} {:>8} {:>7} {:>7} {:>7} {:>9} {:>9} {:>9}",
        "style",
        "curves",
        "czs B",
        "curv B",
        "fill err",
        "dir SW",
        "dir pri",
        "strokes",
        "E swc",
        "E icm",
        "E prior"
    );
    let mut rows = Vec::new();
    for style in [Style::Long, Style::SidePart, Style::Short, Style::Whorl] {
        // 512², the synthetic portraits' default and the size λ_NC is set for (20-80
        // curves); at 256² the same hair has a quarter of the pixels and few curves.
        let c = case_at(style, 1, 512);
        let hair = hair_of(&c);
        let r = run(&c, false);
        let sizes = format::czs_sizes(&r.sketch);
        let inner = erode(&c.mask, 5);
        let (fill_err, _) = mean_err(&r.field.theta, &c.gt_theta, &inner);
        let agree = dir_agreement(&r.field.dir, &c.gt_dir, &hair);
        let with = run(&c, true);
        let agree_strokes = dir_agreement(&with.field.dir, &c.gt_dir, &hair);
        let d = |m| {
            swc::directions(
                &r.undirected,
                &r.theta,
                &hair,
                512,
                512,
                &[],
                &SketchParams::default().swc,
                m,
            )
            .unwrap()
        };
        let (ds, di, dp) = (
            d(swc::Method::Swc),
            d(swc::Method::Icm),
            d(swc::Method::Prior),
        );
        let agree_prior =
            dir_agreement(&filled_dirs(&r, dp.curves.clone(), &hair), &c.gt_dir, &hair);
        // The ablation again with the prior at κ 1 over the parting (the default until
        // 2026-12-06): printed, see README (Step 2).
        let strong = swc::SwcParams {
            prior: swc::DirPrior {
                crown: swc::Crown::Parting,
                kappa: 1.0,
                ..swc::DirPrior::default()
            },
            ..SketchParams::default().swc
        };
        let g = |m| {
            let d =
                swc::directions(&r.undirected, &r.theta, &hair, 512, 512, &[], &strong, m).unwrap();
            dir_agreement(&filled_dirs(&r, d.curves, &hair), &c.gt_dir, &hair)
        };
        let (gen_sw, gen_prior) = (g(swc::Method::Swc), g(swc::Method::Prior));
        println!(
            "{:<9} {:>6} {:>6} {:>6} {:>7.2}° {:>6.1}% {:>6.1}% {:>6.1}% {:>9.1} {:>9.1} {:>9.1}",
            style.name(),
            r.sketch.curves.len(),
            sizes.total,
            sizes.curves,
            fill_err,
            100.0 * agree,
            100.0 * agree_prior,
            100.0 * agree_strokes,
            ds.energy,
            di.energy,
            dp.energy
        );
        println!(
            "{:<9} prior κ 1 over the parting: dir SW {:.1}%, prior-only {:.1}% ({:+.1} points)",
            style.name(),
            100.0 * gen_sw,
            100.0 * gen_prior,
            100.0 * (gen_sw - gen_prior)
        );
        rows.push((
            style,
            (sizes.total, sizes.curves),
            fill_err,
            agree,
            agree_prior,
            agree_strokes,
            ds.energy,
            di.energy,
            dp.energy,
        ));
    }
    for (style, (bytes, curve_bytes), fill_err, agree, agree_prior, agree_strokes, es, ei, ep) in
        rows
    {
        assert!(
            es <= ei + 1e-6 && es <= ep + 1e-6,
            "{style}: SW {es} ICM {ei} prior {ep}"
        );
        assert!(fill_err <= 6.0, "{style}: fill {fill_err:.2}°");
        // With the prior at κ 1 the side part was 92.6% (crown over the mask's centroid: the
        // hair between the parting and the centroid sent toward the centroid) or 99.2% (crown
        // over the parting), and the prior alone did as well as the sampler; at the weak
        // default κ the curves' compatibility carries the parting's side (README, Step 2).
        let floor = if style == Style::Whorl { 0.90 } else { 0.95 };
        assert!(agree >= floor, "{style}: directions {:.1}%", 100.0 * agree);
        assert!(
            agree_strokes >= 0.98,
            "{style}: directions with the strokes clamped {:.1}%",
            100.0 * agree_strokes
        );
        // The "SW ≥ 5 points better than prior-only on the side part".
        if style == Style::SidePart {
            assert!(
                agree >= agree_prior + 0.05,
                "side part: SW {:.1}% against prior-only {:.1}%",
                100.0 * agree,
                100.0 * agree_prior
            );
        }
        // Every style within the 1 KiB (the long case's 78 curves at 999 B since
        // `.czs` version 5 and the orientation stage's fit, 59 at 770 B by the sketch target).
        assert!(bytes <= 1024, "{style}: {bytes} B");
        // And its sketch part within the 600 B, the long case's by the sketch
        // target (815 B at λ_B 0, 586 B at 3.5).
        assert!(curve_bytes <= 600, "{style}: curves {curve_bytes} B");
    }
}

#[test]
fn real_photos_stay_small_and_the_fill_follows_the_dense_field() {
    let mut rows = Vec::new();
    for s in Sample::ALL {
        let img = samples::load(s).unwrap();
        let inp = SketchInputs {
            image: &img.image,
            hair: &img.hair,
            strokes: None,
        };
        let r = analyse(&Engine::cpu(), &inp, &SketchParams::default()).unwrap();
        let (w, h) = img.image.dimensions();
        let mask = image::GrayImage::from_fn(w, h, |x, y| {
            image::Luma([if img.hair[(y * w + x) as usize] {
                255
            } else {
                0
            }])
        });
        let inner = erode(&mask, 5);
        let (err, n) = mean_err(&r.field.theta, &r.theta, &inner);
        let sizes = format::czs_sizes(&r.sketch);
        let png = png_bytes_of_hair(&img.image, &img.hair);
        println!(
            "{:<10} {}x{}: {} curves, .czs {} B (sketch {} B), hair PNG {} B ({:.0}x), fill vs dense Θ {:.2}° over {} px",
            img.name,
            w,
            h,
            r.sketch.curves.len(),
            sizes.total,
            sizes.curves,
            png,
            png as f64 / sizes.total as f64,
            err,
            n
        );
        let fields: Vec<String> = sizes
            .fields
            .iter()
            .map(|(f, b)| format!("{f} {b:.0}"))
            .collect();
        println!(
            "{:<10} range-coded bytes by field: {}",
            img.name,
            fields.join(", ")
        );
        if let Some(b) = &r.budget {
            println!(
                "{:<10} budget: {} {} B, met {}, λ_B {} (tries {:?})",
                img.name, b.kind, b.max_bytes, b.met, b.lambda_b, b.tries
            );
        }
        if let Some(t) = &r.sketch_target {
            println!(
                "{:<10} sketch target: {} B, met {}, {} of {} curves kept (rounds: curves, curve \
                 B, file B, fill°: {:?})",
                img.name, t.target_bytes, t.met, t.curves_kept, t.curves_pursued, t.rounds
            );
        }
        rows.push((img.name, sizes.total, sizes.curves, err));
    }
    // Every file within the 1 KiB and every sketch part within its 600 B, the
    // raccoon crop's (all partings and tufts, 171 curves and 1226 B as pursued) by the sketch
    // target's pruning; every fill within the 12° (the astronaut's since the
    // orientation stage's guide power).
    for (name, bytes, curves, err) in rows {
        assert!(err <= 12.0, "{name}: fill vs dense Θ {err:.2}°");
        assert!(bytes <= 1024, "{name}: {bytes} B");
        assert!(curves <= 600, "{name}: sketch part {curves} B");
    }
}

/// The PNG size of the photo's hair region (non-hair black), the reference for the
/// sketch's compactness.
/// The web portraits of issue 19 (human hair; the hair region is the reference mask drawn by
/// hand): each sketch within issue 16's 1 KiB and its fill within 12° of Step 1's dense Θ;
/// the curves' bytes against its 600 B printed.
#[test]
fn web_portraits_stay_small() {
    for name in crate::segment_real::PORTRAITS {
        let r = crate::segment_real::load(name);
        let (w, h) = r.image.dimensions();
        let inp = SketchInputs {
            image: &r.image,
            hair: &r.mask,
            strokes: None,
        };
        let s = analyse(&Engine::cpu(), &inp, &SketchParams::default()).unwrap();
        let mask = r.mask_image();
        let (err, n) = mean_err(&s.field.theta, &s.theta, &erode(&mask, 5));
        let sizes = format::czs_sizes(&s.sketch);
        let png = png_bytes_of_hair(&r.image, &r.mask);
        println!(
            "{name:<7} {w}x{h}: {} curves, .czs {} B (curves {} B: {} 600 B), hair PNG {png} B \
             ({:.0}x), fill vs dense Θ {err:.2}° over {n} px ({} 12°)",
            s.sketch.curves.len(),
            sizes.total,
            sizes.curves,
            if sizes.curves <= 600 {
                "within"
            } else {
                "NOT within"
            },
            png as f64 / sizes.total as f64,
            if err <= 12.0 { "within" } else { "NOT within" },
        );
        assert!(sizes.total <= 1024, "{name}: {} B", sizes.total);
        // With the fill target's help where the default curve penalty leaves dark hair
        // unexplained (the short hair: 16.3° at λ_NC 40, 10.6° at 20).
        assert!(err <= 12.0, "{name}: fill vs dense Θ {err:.2}°");
    }
}

fn png_bytes_of_hair(img: &image::RgbImage, hair: &[bool]) -> usize {
    let w = img.width();
    let masked = image::RgbImage::from_fn(w, img.height(), |x, y| {
        if hair[(y * w + x) as usize] {
            *img.get_pixel(x, y)
        } else {
            image::Rgb([0, 0, 0])
        }
    });
    let mut buf = std::io::Cursor::new(Vec::new());
    masked.write_to(&mut buf, image::ImageFormat::Png).unwrap();
    buf.into_inner().len()
}

fn coif() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coif"))
}

fn write_case(dir: &Path) -> SynthCase {
    let c = case(Style::Long, 1);
    c.write(dir).unwrap();
    c
}

#[test]
fn the_command_writes_every_file_and_they_agree() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    write_case(&d.join("case"));
    let mut sizes = Vec::new();
    for (name, extra) in [
        ("sk", None),
        ("dict", Some("--dictionary-sides")),
        ("prior", Some("--prior-weight=0.7")),
    ] {
        let out = sketch_case(d, name, extra.as_slice());
        succeeded(&out);
        println!("{}", String::from_utf8_lossy(&out.stdout));
        let dir = d.join(name);
        for f in [
            "hair.czs",
            "sketch.json",
            "sketch.svg",
            "theta.npy",
            "vector.npy",
            "rho.npy",
            "sketch.png",
            "field.png",
            "energy.png",
            "shading.png",
            "report.json",
        ] {
            assert!(dir.join(f).is_file(), "{name}: {f} missing");
        }
        let a = format::load(&dir.join("hair.czs")).unwrap();
        let b = format::load(&dir.join("sketch.json")).unwrap();
        let c = format::load(&dir.join("sketch.svg")).unwrap();
        assert_eq!(a, b);
        assert_eq!(a, c);
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap())
                .unwrap();
        assert_eq!(report["curves"].as_u64().unwrap() as usize, a.curves.len());
        let bytes = std::fs::metadata(dir.join("hair.czs")).unwrap().len();
        assert_eq!(report["bytes"]["total"].as_u64().unwrap(), bytes);
        // The range-coded part by field: every field named, the curves' starts charged.
        let fields = report["bytes"]["fields"].as_object().unwrap();
        assert_eq!(fields.len(), 13, "{fields:?}");
        assert!(fields["start"].as_f64().unwrap() > 0.0, "{fields:?}");
        // The direction prior the run used.
        let kappa = if name == "prior" { 0.7 } else { 0.2 };
        assert_eq!(report["crown"], "centroid");
        assert!((report["prior_weight"].as_f64().unwrap() - kappa).abs() < 1e-6);
        if name == "dict" {
            // Every side on the dictionary {0, π/3, π/2, 2π/3}.
            use std::f32::consts::PI;
            let dict = [0.0, PI / 3.0, PI / 2.0, 2.0 * PI / 3.0];
            for p in a.curves.iter().flat_map(|c| &c.prims) {
                for s in p.side {
                    assert!(
                        dict.iter().any(|d| (s.abs() - d).abs() < 1e-3),
                        "side {s} off the dictionary"
                    );
                }
            }
        }
        sizes.push(bytes);
    }
    assert!(sizes[1] < sizes[0], "dictionary sides {sizes:?} B");
}

/// `--max-bytes` raises the primitive penalty until `hair.czs` fits, says how in
/// `report.json`, and refuses a budget that not even a sketch without curves meets.
#[test]
fn a_byte_budget_is_met_or_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    write_case(&d.join("case"));
    let run = |name: &str, budget: Option<u64>| {
        let flag = budget.map(|b| format!("--max-bytes={b}"));
        sketch_case(d, name, flag.as_slice())
    };
    let czs = |name: &str| {
        std::fs::metadata(d.join(name).join("hair.czs"))
            .unwrap()
            .len()
    };
    assert!(run("free", None).status.success());
    let free = czs("free");
    let budget = free * 3 / 4;
    let out = run("fit", Some(budget));
    succeeded(&out);
    let got = czs("fit");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("fit/report.json")).unwrap()).unwrap();
    let b = &report["budget"];
    println!("{free} B free, budget {budget} B: {got} B, {b}");
    assert!(got <= budget, "{got} B over the budget of {budget} B");
    assert_eq!(b["max_bytes"].as_u64(), Some(budget));
    assert!(b["lambda_b"].as_f64().unwrap() > 0.0, "{b}");
    let tries = b["tries"].as_array().unwrap();
    assert_eq!(tries[0][1].as_u64(), Some(free), "{b}");
    assert!(tries.iter().any(|t| t[1].as_u64() == Some(got)), "{b}");
    // A budget the sketch already meets leaves it as it is.
    assert!(run("roomy", Some(free)).status.success());
    assert_eq!(
        std::fs::read(d.join("roomy/hair.czs")).unwrap(),
        std::fs::read(d.join("free/hair.czs")).unwrap()
    );
    // Too small for the region, shading and colour map alone; and no budget at all.
    let out = run("tiny", Some(16));
    assert_eq!(out.status.code(), Some(64));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("16 B cannot be met"), "{err}");
    assert!(!d.join("tiny").exists());
    assert_eq!(run("zero", Some(0)).status.code(), Some(64));
}

/// The default target (`--target-bytes`, 1024) is met (by the sketch target's pruning, or
/// λ_B where that stops short), but one that not even a sketch without curves meets keeps
/// the sketch as pursued, with a warning and `met: false` in `report.json`, where
/// `--max-bytes` refuses; 0 turns it off.
#[test]
fn a_byte_target_out_of_reach_keeps_the_sketch_and_warns() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    write_case(&d.join("case"));
    let run = |name: &str, extra: &[&str]| sketch_case(d, name, extra);
    let off = run("off", &["--target-bytes", "0"]);
    succeeded(&off);
    let report = |name: &str| report_in(&d.join(name));
    assert!(report("off")["budget"].is_null());
    let out = run("tiny", &["--target-bytes", "16"]);
    succeeded(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("over the 16 B target") && err.contains("image.png"),
        "{err}"
    );
    let b = &report("tiny")["budget"];
    assert_eq!(b["kind"], "target", "{b}");
    assert_eq!(b["met"], false, "{b}");
    assert_eq!(
        std::fs::read(d.join("tiny/hair.czs")).unwrap(),
        std::fs::read(d.join("off/hair.czs")).unwrap()
    );
    // Within reach, it is met as a budget is.
    let free = std::fs::metadata(d.join("off/hair.czs")).unwrap().len();
    let aim = free * 3 / 4;
    succeeded(&run("fit", &["--target-bytes", &aim.to_string()]));
    let b = &report("fit")["budget"];
    assert_eq!(b["met"], true, "{b}");
    let got = std::fs::metadata(d.join("fit/hair.czs")).unwrap().len();
    assert!(got <= aim, "{got} B over the target of {aim} B");
}

/// The fill target: off, the curve penalty stays as given; out of reach, the penalty is
/// halved down to its floor, the closest fill kept and a warning names the photo; within
/// reach at the first try, nothing changes; the report holds the fill's error every time,
/// and a bad target is refused.
#[test]
fn a_fill_target_lowers_the_curve_penalty_until_the_fill_follows() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    write_case(&d.join("case"));
    let run = |name: &str, extra: &[&str]| sketch_case(d, name, extra);
    let report = |name: &str| report_in(&d.join(name));
    let o = run("off", &["--target-fill", "0"]);
    succeeded(&o);
    let f = &report("off")["fill"];
    // The summary line gives the fill's error as the report does.
    let said = printed(&o);
    let figure = format!(
        "fill {:.2}° from the dense field",
        f["error_deg"].as_f64().unwrap()
    );
    assert!(said.contains(&figure), "{said}");
    assert!(f["target"].is_null(), "{f}");
    let free = f["error_deg"].as_f64().unwrap();
    assert!(free > 0.0 && f["pixels"].as_u64().unwrap() > 0, "{f}");
    // Within reach: the default run is the same sketch.
    succeeded(&run("easy", &["--target-fill", &format!("{}", free + 1.0)]));
    let t = &report("easy")["fill"]["target"];
    assert_eq!(t["met"], true, "{t}");
    assert_eq!(t["tries"].as_array().unwrap().len(), 1, "{t}");
    assert_eq!(
        std::fs::read(d.join("easy/hair.czs")).unwrap(),
        std::fs::read(d.join("off/hair.czs")).unwrap()
    );
    // Out of reach: 40, 20, 10, 5; the closest kept.
    let out = run("hard", &["--target-fill", "0.01"]);
    succeeded(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("over the 0.01° target") && err.contains("image.png"),
        "{err}"
    );
    let f = &report("hard")["fill"];
    let t = &f["target"];
    assert_eq!(t["met"], false, "{t}");
    let tries = t["tries"].as_array().unwrap();
    let lambdas: Vec<f64> = tries.iter().map(|x| x[0].as_f64().unwrap()).collect();
    assert_eq!(lambdas, [40.0, 20.0, 10.0, 5.0], "{t}");
    let best = tries
        .iter()
        .map(|x| x[1].as_f64().unwrap())
        .fold(f64::INFINITY, f64::min);
    assert_eq!(f["error_deg"].as_f64().unwrap(), best, "{f}");
    assert!(best <= free, "{best} > {free}");
    refused(d, "--target-fill", &["-1", "nan", "x"]);
}

/// The sketch target (issue 16's 600 B for the sketch part): off, it leaves the sketch as
/// pursued; a target under the sketch's curves drops the curves the fill needs least until
/// they fit and says so; one out of reach prunes only as far as the fill target allows,
/// with every round in the report.
#[test]
fn a_sketch_target_prunes_the_curves_the_fill_needs_least() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    write_case(&d.join("case"));
    let run = |name: &str, extra: &[&str]| sketch_case(d, name, extra);
    let report = |name: &str| report_in(&d.join(name));
    let czs = |name: &str| std::fs::read(d.join(name).join("hair.czs")).unwrap();
    succeeded(&run("off", &["--target-sketch-bytes", "0"]));
    assert!(report("off")["sketch_target"].is_null());
    let curves = |name: &str| report(name)["bytes"]["curves"].as_u64().unwrap();
    let fill = |name: &str| report(name)["fill"]["error_deg"].as_f64().unwrap();
    let c0 = curves("off");
    // Within reach at once: the same sketch.
    succeeded(&run("easy", &["--target-sketch-bytes", &format!("{c0}")]));
    let t = &report("easy")["sketch_target"];
    assert_eq!(t["met"], true, "{t}");
    assert_eq!(t["rounds"].as_array().unwrap().len(), 1, "{t}");
    assert_eq!(czs("easy"), czs("off"));
    // A fifth under: curves dropped until the sketch part fits, the fill within 12°.
    let target = c0 * 4 / 5;
    let o = run("tight", &["--target-sketch-bytes", &format!("{target}")]);
    succeeded(&o);
    let said = printed(&o);
    let t = &report("tight")["sketch_target"];
    assert_eq!(t["met"], true, "{t}");
    assert!(curves("tight") <= target, "{} > {target}", curves("tight"));
    let rounds = t["rounds"].as_array().unwrap();
    assert_eq!(rounds[0][1].as_u64().unwrap(), c0, "{t}");
    let (pursued, kept) = (
        t["curves_pursued"].as_u64().unwrap(),
        t["curves_kept"].as_u64().unwrap(),
    );
    assert!(kept < pursued, "{t}");
    assert_eq!(report("tight")["curves"].as_u64().unwrap(), kept, "{t}");
    assert!(fill("tight") <= 12.0, "{}", fill("tight"));
    assert!(
        said.contains(&format!(
            "{kept} of {pursued} curves kept, the ones the fill needs most, to bring the sketch \
             part within {target} B"
        )),
        "{said}"
    );
    // Out of reach: pruned only as far as the fill's 12° allows.
    let o = run("hard", &["--target-sketch-bytes", "1"]);
    succeeded(&o);
    let said = printed(&o);
    let t = &report("hard")["sketch_target"];
    assert_eq!(t["met"], false, "{t}");
    assert!(curves("hard") < curves("tight"), "{t}");
    for r in t["rounds"].as_array().unwrap() {
        assert!(r[3].as_f64().unwrap() <= 12.0, "{t}");
    }
    assert!(said.contains("(not reached"), "{said}");
    refused(d, "--target-sketch-bytes", &["-1", "x"]);
}

/// Each of `values` for `flag` is refused (exit 64) with nothing written.
fn refused(d: &Path, flag: &str, values: &[&str]) {
    for v in values {
        let o = sketch_case(d, "bad", &[format!("{flag}={v}")]);
        assert_eq!(
            o.status.code(),
            Some(64),
            "{flag}={v}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    assert!(!d.join("bad").exists());
}

/// The `report.json` in `dir`.
fn report_in(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap()
}

/// What a run printed, stdout then stderr.
fn printed(o: &std::process::Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// `coif sketch` on the case [`write_case`] wrote under `d`, into `d/name`.
fn sketch_case(
    d: &Path,
    name: &str,
    extra: &[impl AsRef<std::ffi::OsStr>],
) -> std::process::Output {
    coif()
        .args(["sketch", "--backend", "cpu", "--image"])
        .arg(d.join("case/image.png"))
        .arg("--mask")
        .arg(d.join("case/mask.png"))
        .arg("--out")
        .arg(d.join(name))
        .args(extra)
        .output()
        .unwrap()
}

/// A run that must succeed; its error output is the failure's message.
fn succeeded(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn fails_with(args: &[&std::ffi::OsStr], needle: &str) {
    let out = coif().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "succeeded: {args:?}");
    assert!(
        err.contains(needle),
        "{args:?}: expected {needle:?} in: {err}"
    );
}

#[test]
fn bad_inputs_are_refused_with_the_file_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    write_case(&d.join("case"));
    let img = d.join("case/image.png");
    let os = |p: &Path| p.as_os_str().to_owned();
    // An empty mask.
    let empty = d.join("empty.png");
    image::GrayImage::new(256, 256).save(&empty).unwrap();
    let out = d.join("o");
    fails_with(
        &[
            "sketch".as_ref(),
            "--backend".as_ref(),
            "cpu".as_ref(),
            "--image".as_ref(),
            &os(&img),
            "--mask".as_ref(),
            &os(&empty),
            "--out".as_ref(),
            &os(&out),
        ],
        "empty",
    );
    // A mask of another size.
    let small = d.join("small.png");
    image::GrayImage::from_pixel(100, 80, image::Luma([255]))
        .save(&small)
        .unwrap();
    fails_with(
        &[
            "sketch".as_ref(),
            "--backend".as_ref(),
            "cpu".as_ref(),
            "--image".as_ref(),
            &os(&img),
            "--mask".as_ref(),
            &os(&small),
            "--out".as_ref(),
            &os(&out),
        ],
        "small.png",
    );
    // A uniform image.
    let flat = d.join("flat.png");
    image::RgbImage::from_pixel(64, 64, image::Rgb([90, 60, 40]))
        .save(&flat)
        .unwrap();
    fails_with(
        &[
            "sketch".as_ref(),
            "--backend".as_ref(),
            "cpu".as_ref(),
            "--image".as_ref(),
            &os(&flat),
            "--whole".as_ref(),
            "--out".as_ref(),
            &os(&out),
        ],
        "uniform",
    );
    // No hair region at all.
    fails_with(
        &[
            "sketch".as_ref(),
            "--image".as_ref(),
            &os(&img),
            "--out".as_ref(),
            &os(&out),
        ],
        "--mask, --strokes or --whole",
    );
    // Penalties that are no costs, a prior without weight, a crown the prior does not know.
    for (flag, needle) in [
        ("--curve-penalty=-1", "curve penalty"),
        ("--primitive-penalty=-0.5", "primitive penalty"),
        ("--primitive-penalty=NaN", "primitive penalty"),
        (
            "--prior-weight=0",
            "expected a finite number > 0, got \"0\"",
        ),
        ("--prior-weight=inf", "expected a finite number > 0"),
        (
            "--crown=top",
            "unknown crown \"top\" (expected one of parting, centroid)",
        ),
    ] {
        fails_with(
            &[
                "sketch".as_ref(),
                "--image".as_ref(),
                &os(&img),
                "--whole".as_ref(),
                flag.as_ref(),
                "--out".as_ref(),
                &os(&out),
            ],
            needle,
        );
    }
    assert!(!out.exists(), "a refused run left {}", out.display());
}

#[test]
fn convert_round_trips_and_refuses_damaged_files() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let c = case(Style::Long, 2);
    let r = run(&c, false);
    let czs = d.join("hair.czs");
    format::save(&r.sketch, &czs).unwrap();
    for (from, to) in [
        ("hair.czs", "a.svg"),
        ("a.svg", "b.json"),
        ("b.json", "c.czs"),
    ] {
        let out = coif()
            .arg("sketch-convert")
            .arg("--sketch")
            .arg(d.join(from))
            .arg("--out")
            .arg(d.join(to))
            .output()
            .unwrap();
        succeeded(&out);
    }
    assert_eq!(
        std::fs::read(&czs).unwrap(),
        std::fs::read(d.join("c.czs")).unwrap()
    );
    // A truncated and a corrupted .czs, and a sketch.json that fails its schema.
    let bytes = std::fs::read(&czs).unwrap();
    std::fs::write(d.join("cut.czs"), &bytes[..bytes.len() / 2]).unwrap();
    let mut flipped = bytes.clone();
    let k = bytes.len() / 2;
    flipped[k] ^= 0x10;
    std::fs::write(d.join("flip.czs"), &flipped).unwrap();
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("b.json")).unwrap()).unwrap();
    json["width"] = serde_json::json!("wide");
    std::fs::write(d.join("bad.json"), json.to_string()).unwrap();
    for bad in ["cut.czs", "flip.czs", "bad.json"] {
        let p = d.join(bad);
        let out = d.join(format!("{bad}.svg"));
        fails_with(
            &[
                "sketch-convert".as_ref(),
                "--sketch".as_ref(),
                p.as_os_str(),
                "--out".as_ref(),
                out.as_os_str(),
            ],
            bad,
        );
        assert!(!out.exists());
    }
}

/// `sketch.png` of a synthetic portrait at 256² on the cpu backend (the analysis is
/// deterministic there; lavapipe rounds Θ differently and may pick other curves).
#[test]
fn sketch_picture_golden() {
    let c = case(Style::Long, 1);
    let r = run(&c, false);
    let backdrop = coif::io::vis::dimmed(&c.image, 0.45);
    let img = coif::sketch::vis::sketch_picture(&backdrop, &r.sketch);
    coif::testing::check_golden_rgb("sketch_synth_long_256", &img).unwrap();
}
