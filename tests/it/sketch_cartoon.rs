//! `coif cartoon` (CZ06 Fig. 17, issue 17): the brush geometry (Catmull-Rom through the key
//! points, its exact Bézier form, narrowed ends), the rendering on the CPU mirror and on
//! lavapipe, the golden, the SVG, and the command's files and errors.

use crate::common;

use coif::gpu::engine::Engine;
use coif::sketch::cartoon::{
    bezier_point, brushes, catmull_rom_bezier, catmull_rom_point, catmull_rom_spline, key_points,
    render, skeleton, to_svg, CartoonParams, Style,
};
use coif::sketch::format;
use coif::sketch::oracle::oracle_sketch;
use coif::sketch::{ColourMap, RhoPrior, Shading, Sketch, COLOUR_BINS};
use coif::synth::{synth, Style as SynthStyle, SynthParams};
use std::path::Path;
use std::process::Command;

/// The quantised oracle sketch of the long-hair synthetic portrait at `size`², seed 1.
fn synth_sketch(size: u32) -> (Sketch, image::RgbImage) {
    let case = synth(&SynthParams {
        style: SynthStyle::Long,
        seed: 1,
        width: size,
        height: size,
    });
    let s = Sketch {
        width: size,
        height: size,
        seed: 1,
        curves: oracle_sketch(&case),
        rho_off: RhoPrior {
            weight: [0.7, 0.3],
            mean: [4.0, 12.0],
            sigma: [1.5, 4.0],
        },
        shading: Shading {
            mean: 40.0,
            bases: Vec::new(),
        },
        colour: ColourMap {
            uv: vec![[8.0, 12.0]; COLOUR_BINS],
        },
        region: Vec::new(),
        along_across: None,
    };
    (format::quantise(&s), case.image)
}

fn dist(a: [f32; 2], b: [f32; 2]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// Mean absolute difference (levels of 255) and largest channel difference of two images.
fn image_diff(a: &image::RgbImage, b: &image::RgbImage) -> (f64, u8, f64) {
    let (mut sum, mut max, mut over) = (0u64, 0u8, 0usize);
    for (p, q) in a.pixels().zip(b.pixels()) {
        let mut px_max = 0u8;
        for k in 0..3 {
            let d = p[k].abs_diff(q[k]);
            sum += d as u64;
            px_max = px_max.max(d);
        }
        max = max.max(px_max);
        over += (px_max > 2) as usize;
    }
    let n = a.pixels().len();
    (sum as f64 / (3 * n) as f64, max, over as f64 / n as f64)
}

#[test]
fn catmull_rom_passes_through_the_key_points_and_matches_its_beziers() {
    let (s, _) = synth_sketch(256);
    let (mut worst_key, mut worst_bez, mut segs) = (0.0f32, 0.0f32, 0usize);
    for c in &s.curves {
        let pts = key_points(c);
        let sk = skeleton(c);
        assert_eq!(
            sk.len(),
            pts.len() - 1,
            "one segment per pair of key points"
        );
        for (k, b) in sk.iter().enumerate() {
            worst_key = worst_key
                .max(dist(b[0], pts[k]))
                .max(dist(b[3], pts[k + 1]));
        }
    }
    // The pyramid and the Bézier on random 4-point windows, including uneven spacing.
    for i in 0..2000u64 {
        let r = |j: u64| common::hash01(i * 8 + j, 7) * 100.0;
        let p = [[r(0), r(1)], [r(2), r(3)], [r(4), r(5)], [r(6), r(7)]];
        let b = catmull_rom_bezier(p);
        for k in 0..=16 {
            let s = k as f32 / 16.0;
            let d = dist(catmull_rom_point(p, s), bezier_point(&b, s));
            worst_bez = worst_bez.max(d / 100.0);
        }
        worst_key = worst_key
            .max(dist(catmull_rom_point(p, 0.0), p[1]))
            .max(dist(catmull_rom_point(p, 1.0), p[2]));
        segs += 1;
    }
    // And through a whole spline.
    let pts = [
        [0.0, 0.0],
        [10.0, 2.0],
        [11.0, 9.0],
        [30.0, 30.0],
        [31.0, 30.5],
    ];
    let sp = catmull_rom_spline(&pts, [-5.0, 0.0], [40.0, 31.0]);
    for (k, b) in sp.iter().enumerate() {
        worst_key = worst_key
            .max(dist(b[0], pts[k]))
            .max(dist(b[3], pts[k + 1]));
    }
    println!(
        "catmull-rom: {} curves; key points missed by {worst_key:.2e} px at most; \
         pyramid vs Bezier over {segs} random segments: {worst_bez:.2e} of the extent at most",
        s.curves.len()
    );
    assert!(worst_key < 1e-3, "key point missed by {worst_key} px");
    assert!(
        worst_bez < 1e-4,
        "Bezier differs by {worst_bez} of the extent"
    );
}

/// Width of a brush across its outline at arc-length fraction t of its left boundary.
fn width_at(b: &coif::sketch::cartoon::Brush, t: f32) -> f32 {
    let n = b.left.len();
    let i = ((t * n as f32) as usize).min(n - 1);
    let s = t * n as f32 - i as f32;
    dist(bezier_point(&b.left[i], s), bezier_point(&b.right[i], s))
}

#[test]
fn brush_ends_are_narrowed() {
    let (s, _) = synth_sketch(256);
    for style in [Style::Ink, Style::Direction] {
        let p = CartoonParams {
            style,
            ..Default::default()
        };
        let bs = brushes(&s, &p);
        assert_eq!(bs.len(), s.curves.len());
        let (mut end_max, mut mid_min, mut end_mean, mut mid_mean) = (0.0f32, f32::MAX, 0.0, 0.0);
        for b in &bs {
            let (l, r) = (&b.left, &b.right);
            let ends = dist(l[0][0], r[0][0]).max(dist(l[l.len() - 1][3], r[r.len() - 1][3]));
            let near = width_at(b, 0.05).max(width_at(b, 0.95));
            let mid = width_at(b, 0.5);
            assert!(ends < 1e-3, "curve {}: tip {ends} px wide", b.curve);
            assert!(
                near < mid,
                "curve {}: {near} px near an end, {mid} mid",
                b.curve
            );
            end_max = end_max.max(near);
            mid_min = mid_min.min(mid);
            end_mean += near / bs.len() as f32;
            mid_mean += mid / bs.len() as f32;
        }
        println!(
            "{}: outline width at 5 %/95 % of the stroke {end_mean:.2} px mean ({end_max:.2} \
             max), at the middle {mid_mean:.2} px mean ({mid_min:.2} min); tips 0",
            style.name()
        );
    }
}

#[test]
fn cpu_and_lavapipe_cartoons_agree() {
    let (s, photo) = synth_sketch(256);
    let gpu = common::gpu();
    let out = std::env::var_os("COIF_CARTOON_OUT");
    for (style, over) in [
        (Style::Ink, false),
        (Style::Type, false),
        (Style::Direction, true),
    ] {
        let p = CartoonParams {
            style,
            ..Default::default()
        };
        let over = over.then_some(&photo);
        let a = render(&Engine::cpu(), &s, &p, over).unwrap();
        let b = render(&gpu, &s, &p, over).unwrap();
        let (mean, max, share) = image_diff(&a, &b);
        println!(
            "{} cpu vs lavapipe at 256²: mean {mean:.4}, max {max} levels, {:.3} % of pixels \
             beyond 2 levels",
            style.name(),
            100.0 * share
        );
        if let Some(dir) = &out {
            a.save(Path::new(dir).join(format!("cartoon_{}.png", style.name())))
                .unwrap();
        }
        // The raster parity tolerance of tests/it/raster.rs: ≥ 99 % of pixels within 2/255.
        assert!(share <= 0.01, "{} differs", style.name());
    }
}

/// `sketch_cartoon_256.png`: the direction style on paper, rendered on lavapipe.
#[test]
fn cartoon_golden() {
    let (s, _) = synth_sketch(256);
    let p = CartoonParams {
        style: Style::Direction,
        ..Default::default()
    };
    let img = render(&common::gpu(), &s, &p, None).unwrap();
    coif::testing::check_golden_rgb("sketch_cartoon_256", &img).unwrap();
}

#[test]
fn svg_parses_with_one_path_per_curve() {
    let (s, _) = synth_sketch(256);
    for style in [Style::Ink, Style::Type, Style::Direction] {
        let p = CartoonParams {
            style,
            ..Default::default()
        };
        let text = to_svg(&s, &p);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let root = doc.root_element();
        assert_eq!(root.tag_name().name(), "svg");
        assert_eq!(root.attribute("viewBox"), Some("0 0 256 256"));
        let paths: Vec<_> = doc
            .descendants()
            .filter(|n| n.has_tag_name("path"))
            .collect();
        assert_eq!(paths.len(), s.curves.len(), "{}", style.name());
        let mut seen = vec![false; s.curves.len()];
        let bs = brushes(&s, &p);
        let mut cubics = 0usize;
        for (n, b) in paths.iter().zip(&bs) {
            let k: usize = n.attribute("data-curve").unwrap().parse().unwrap();
            assert_eq!(k, b.curve);
            assert!(!seen[k], "curve {k} drawn twice");
            seen[k] = true;
            let kind = n.attribute("data-kind").unwrap();
            assert_eq!(kind, s.curves[k].kind.letter().to_string());
            let d = n.attribute("d").unwrap();
            let c = d.matches('C').count();
            assert_eq!(c, b.left.len() + b.right.len());
            assert_eq!(d.matches('M').count(), 1 + b.arrows.len());
            // The outline starts at the stroke's first tip, the skeleton's start.
            let nums: Vec<f32> = d
                .split_whitespace()
                .skip(1)
                .take(2)
                .map(|v| v.parse().unwrap())
                .collect();
            assert!(dist([nums[0], nums[1]], b.skeleton[0][0]) < 2e-3);
            // A stroke whose colour varies is filled by its own gradient, with a stop per
            // boundary segment in non-decreasing order; others by one colour.
            let fill = n.attribute("fill").unwrap();
            if b.colours.iter().any(|c| *c != b.colours[0]) {
                assert_eq!(fill, format!("url(#cz-g{k})"));
                let g = doc
                    .descendants()
                    .find(|g| g.attribute("id") == Some(&format!("cz-g{k}")[..]))
                    .expect("the gradient");
                let offs: Vec<f32> = g
                    .children()
                    .filter(|c| c.has_tag_name("stop"))
                    .map(|c| c.attribute("offset").unwrap().parse().unwrap())
                    .collect();
                assert_eq!(offs.len(), b.left.len());
                assert!(offs.windows(2).all(|w| w[0] <= w[1]), "{offs:?}");
            } else {
                assert!(fill.starts_with('#'), "{fill}");
            }
            cubics += c;
        }
        println!(
            "{} svg: {} paths, {cubics} cubic segments, {} bytes",
            style.name(),
            paths.len(),
            text.len()
        );
    }
}

fn coif() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coif"))
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
fn the_command_writes_png_and_svg_and_refuses_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let (s, photo) = synth_sketch(256);
    let czs = d.join("hair.czs");
    format::save(&s, &czs).unwrap();
    let photo_path = d.join("photo.png");
    photo.save(&photo_path).unwrap();
    for (out, over, style) in [
        ("c.png", false, "ink"),
        ("c.svg", false, "type"),
        ("over.png", true, "direction"),
        ("over.svg", true, "direction"),
    ] {
        let mut cmd = coif();
        cmd.args(["cartoon", "--backend", "cpu", "--style", style, "--sketch"])
            .arg(&czs)
            .arg("--out")
            .arg(d.join(out));
        if over {
            cmd.arg("--over").arg(&photo_path);
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // The PNG is the library's render; the SVG its text.
    let png = image::open(d.join("c.png")).unwrap().to_rgb8();
    let want = render(&Engine::cpu(), &s, &CartoonParams::default(), None).unwrap();
    assert_eq!(png, want);
    let p = CartoonParams {
        style: Style::Type,
        ..Default::default()
    };
    assert_eq!(
        std::fs::read_to_string(d.join("c.svg")).unwrap(),
        to_svg(&s, &p)
    );
    let over_png = image::open(d.join("over.png")).unwrap().to_rgb8();
    let (mean, _, _) = image_diff(&over_png, &photo);
    assert!(
        mean > 0.0 && mean < 40.0,
        "drawn over the photo: mean change {mean}"
    );
    let over_svg = std::fs::read_to_string(d.join("over.svg")).unwrap();
    assert!(over_svg.contains("href=\"photo.png\""));
    roxmltree::Document::parse(&over_svg).unwrap();
    // No temporary files are left behind.
    let names: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 6, "{names:?}");

    let os = |p: &Path| p.as_os_str().to_owned();
    let out = d.join("bad.png");
    let run = |sketch: &Path, extra: &[&str], needle: &str| {
        let mut args = vec![
            "cartoon".into(),
            "--backend".into(),
            "cpu".into(),
            "--sketch".into(),
            os(sketch),
            "--out".into(),
            os(&out),
        ];
        args.extend(extra.iter().map(|&e| e.into()));
        let refs: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        fails_with(&refs, needle);
        assert!(!out.exists());
    };
    // An unreadable sketch: missing, and corrupted.
    run(&d.join("missing.czs"), &[], "missing.czs");
    let bytes = std::fs::read(&czs).unwrap();
    let cut = d.join("cut.czs");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    run(&cut, &[], "cut.czs");
    // A backdrop of the wrong size.
    let small = d.join("small.png");
    image::RgbImage::new(100, 80).save(&small).unwrap();
    run(&czs, &["--over", small.to_str().unwrap()], "small.png");
    run(&czs, &["--over", small.to_str().unwrap()], "100x80");
    // An unknown style.
    run(&czs, &["--style", "pencil"], "pencil");
    // A sketch without curves.
    let empty = d.join("empty.json");
    let mut none = s.clone();
    none.curves.clear();
    std::fs::write(&empty, format::to_json(&none)).unwrap();
    run(&empty, &[], "empty.json");
    // An output that is none of .png, .jpg and .svg.
    fails_with(
        &[
            "cartoon".as_ref(),
            "--sketch".as_ref(),
            czs.as_os_str(),
            "--out".as_ref(),
            d.join("c.tiff").as_os_str(),
        ],
        ".png, .jpg or .svg",
    );
}
