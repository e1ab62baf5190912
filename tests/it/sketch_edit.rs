//! `coif sketch-edit` and `sketch::edit` (issue 17, Deliver 5): each edit does what it says
//! and survives the files; a flipped curve flips the filled direction field on its side
//! and nowhere beyond its neighbourhood, a deleted one changes the field only near it
//! (measured on an oracle sketch of a synthetic portrait); bad sketches and bad edits are
//! refused through the binary with the file and the problem named, nothing written.

use coif::gpu::engine::Engine;
use coif::sketch::edit::{apply, apply_logged, BaseEdit, Edit, Rho, Side};
use coif::sketch::fill::{fill, FillParams};
use coif::sketch::format::{self, load, quantise, save};
use coif::sketch::oracle::oracle_sketch;
use coif::sketch::prim::paint;
use coif::sketch::{
    Base, ColourMap, Curve, Kind, Primitive, RhoPrior, Shading, Sketch, VectorField, AXIS_QUANTUM,
    COLOUR_BINS, STEP,
};
use coif::synth::{synth, Style, SynthParams};
use std::f32::consts::PI;
use std::path::Path;
use std::process::Command;

/// A straight run of `n` primitives from (x, y) along lattice step `k`.
fn line(kind: Kind, x: f32, y: f32, k: i32, n: usize, side: [f32; 2], dirs: [i8; 2]) -> Curve {
    let a = k as f32 * AXIS_QUANTUM;
    Curve {
        kind,
        prims: (0..n)
            .map(|i| Primitive {
                shift: 0.0,
                x: x + STEP * i as f32 * a.cos(),
                y: y + STEP * i as f32 * a.sin(),
                axis: a.rem_euclid(2.0 * PI),
                rho: 8.0,
                side,
            })
            .collect(),
        dirs,
    }
}

fn prior() -> RhoPrior {
    RhoPrior {
        weight: [0.7, 0.3],
        mean: [4.0, 12.0],
        sigma: [1.5, 4.0],
    }
}

fn colour() -> ColourMap {
    ColourMap {
        uv: (0..COLOUR_BINS).map(|i| [4.0 + i as f32, 12.0]).collect(),
    }
}

/// A small sketch with one curve of each kind (and an undecided stream line), 3 bases.
fn small() -> Sketch {
    quantise(&Sketch {
        width: 96,
        height: 80,
        seed: 5,
        curves: vec![
            line(Kind::Stream, 10.0, 10.0, 0, 8, [0.0; 2], [1, 1]),
            line(Kind::Occluding, 10.0, 30.0, 1, 6, [0.0, PI / 3.0], [1, -1]),
            line(Kind::Boundary, 80.0, 10.0, 6, 10, [0.0; 2], [-1, 0]),
            line(Kind::Dividing, 20.0, 60.0, 0, 9, [PI / 2.0; 2], [1, 1]),
            line(Kind::Stream, 60.0, 40.0, 18, 5, [0.0; 2], [0, 0]),
            line(Kind::Source, 40.0, 75.0, 0, 4, [PI / 2.0, 0.0], [1, 0]),
        ],
        rho_off: prior(),
        shading: Shading {
            mean: 40.0,
            bases: vec![
                Base {
                    x: 30.0,
                    y: 30.0,
                    theta: 0.0,
                    sx: 12.0,
                    sy: 6.0,
                    amp: 10.0,
                },
                Base {
                    x: 60.0,
                    y: 50.0,
                    theta: 1.0,
                    sx: 20.0,
                    sy: 8.0,
                    amp: -6.0,
                },
                Base {
                    x: 10.0,
                    y: 70.0,
                    theta: 2.0,
                    sx: 5.0,
                    sy: 5.0,
                    amp: 3.5,
                },
            ],
        },
        colour: colour(),
        region: Vec::new(),
        along_across: None,
    })
}

/// `s` through each file format and back.
fn through_files(s: &Sketch, dir: &Path, what: &str) {
    for ext in ["czs", "json", "svg"] {
        let p = dir.join(format!("{what}.{ext}"));
        save(s, &p).unwrap();
        assert_eq!(&load(&p).unwrap(), s, "{what} through .{ext}");
    }
}

#[test]
fn each_edit_does_what_it_says_through_the_files() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let s = small();
    through_files(&s, d, "input");
    let n = s.curves.len();

    // Delete: the curve goes, the others stay as they were, in order.
    let q = apply(&s, &[Edit::Delete(2)]).unwrap();
    through_files(&q, d, "delete");
    let mut want = s.curves.clone();
    want.remove(2);
    assert_eq!(q.curves, want);
    assert_eq!(q.shading, s.shading);

    // Flip: labels negated on the sides asked, nothing else.
    for (i, side, dirs) in [
        (0, Side::Both, [-1, -1]),
        (1, Side::Both, [-1, 1]),
        (1, Side::Left, [-1, -1]),
        (1, Side::Right, [1, 1]),
        (2, Side::Both, [1, 0]),
        (2, Side::Left, [1, 0]),
        (5, Side::Both, [-1, 0]),
    ] {
        let q = apply(&s, &[Edit::Flip(i, side)]).unwrap();
        through_files(&q, d, "flip");
        assert_eq!(q.curves[i].dirs, dirs, "flip {i} {side:?}");
        assert_eq!(q.curves[i].prims, s.curves[i].prims);
        let mut back = q.clone();
        back.curves[i].dirs = s.curves[i].dirs;
        assert_eq!(back, s, "flip {i} {side:?} changed something else");
        // Flipping twice is the identity.
        let twice = apply(&s, &[Edit::Flip(i, side), Edit::Flip(i, side)]).unwrap();
        assert_eq!(twice, s);
    }
    // Flips the kinds do not allow.
    for (e, needle) in [
        (Edit::Flip(3, Side::Both), "dividing line"),
        (Edit::Flip(0, Side::Left), "share one direction"),
        (Edit::Flip(2, Side::Right), "no right direction"),
        (Edit::Flip(4, Side::Both), "undecided"),
    ] {
        let m = apply(&s, std::slice::from_ref(&e)).unwrap_err().to_string();
        assert!(m.contains(needle), "{e}: {m}");
        println!("refused: {m}");
    }

    // Move: every centre by the displacement rounded to whole pixels.
    let q = apply(&s, &[Edit::Move(1, [7.0, -3.4])]).unwrap();
    through_files(&q, d, "move");
    for (a, b) in s.curves[1].prims.iter().zip(&q.curves[1].prims) {
        assert!((b.x - a.x - 7.0).abs() < 1e-4 && (b.y - a.y + 3.0).abs() < 1e-4);
        assert_eq!((a.axis, a.rho, a.side), (b.axis, b.rho, b.side));
    }
    let m = apply(&s, &[Edit::Move(2, [40.0, 0.0])])
        .unwrap_err()
        .to_string();
    assert!(m.contains("outside the 96x80 image"), "{m}");

    // Contrast: scaled or set, on the ρ levels.
    let q = apply(&s, &[Edit::Contrast(0, Rho::Scale(2.0))]).unwrap();
    through_files(&q, d, "contrast");
    // ρ levels are 2^(4/7) apart: the nearest is within half a step in log scale.
    let half_step = 0.5 * (4.0f32 / 7.0) * 2f32.ln();
    assert!(q.curves[0]
        .prims
        .iter()
        .all(|p| (p.rho / 16.0).ln().abs() <= half_step));
    let q = apply(&s, &[Edit::Contrast(0, Rho::Set(30.0))]).unwrap();
    let level = q.curves[0].prims[0].rho;
    assert!(q.curves[0].prims.iter().all(|p| p.rho == level));
    assert!((level / 30.0).ln().abs() <= half_step, "{level}");

    // Bases: set fields snap to the shading lattice; delete; add.
    let e = BaseEdit {
        amp: Some(-12.3),
        x: Some(50.0),
        theta: Some(PI / 4.0),
        ..Default::default()
    };
    let q = apply(&s, &[Edit::Base(1, e)]).unwrap();
    through_files(&q, d, "base");
    let b = q.shading.bases[1];
    assert_eq!((b.amp, b.x, b.y), (-12.5, 50.0, s.shading.bases[1].y));
    assert!((b.theta - PI / 4.0).abs() < 1e-6);
    assert_eq!((b.sx, b.sy), (s.shading.bases[1].sx, s.shading.bases[1].sy));
    let q = apply(&s, &[Edit::DeleteBase(0)]).unwrap();
    through_files(&q, d, "delete-base");
    assert_eq!(q.shading.bases, s.shading.bases[1..].to_vec());
    let nb = Base {
        x: 45.0,
        y: 33.0,
        theta: 0.3,
        sx: 9.0,
        sy: 14.0,
        amp: 7.2,
    };
    let q = apply(&s, &[Edit::AddBase(nb)]).unwrap();
    through_files(&q, d, "add-base");
    let b = *q.shading.bases.last().unwrap();
    assert_eq!((b.x, b.y, b.amp), (46.0, 34.0, 7.0));

    // Add: a drawn arc lands on the lattice near the line.
    let arc: Vec<[f32; 2]> = (0..=40)
        .map(|i| {
            let a = i as f32 / 40.0 * 1.2;
            [30.0 + 30.0 * a.sin(), 20.0 + 30.0 - 30.0 * a.cos()]
        })
        .collect();
    let (c, worst) =
        coif::sketch::edit::curve_from_points(Kind::Occluding, &arc, 8.0, [0.0, PI / 3.0], [1, 1])
            .unwrap();
    let q = apply(&s, &[Edit::Add(c)]).unwrap();
    through_files(&q, d, "add");
    assert_eq!(q.curves.len(), n + 1);
    let added = &q.curves[n];
    let far = added
        .prims
        .iter()
        .map(|p| {
            arc.iter()
                .map(|a| (a[0] - p.x).hypot(a[1] - p.y))
                .fold(f32::INFINITY, f32::min)
        })
        .fold(0.0f32, f32::max);
    println!(
        "drawn arc (radius 30 px, {:.0} px long): {} primitives, within {worst:.2} px of the \
         line at equal arc length, {far:.2} px of the line",
        30.0 * 1.2,
        added.prims.len()
    );
    assert!(far < 2.0, "{far}");
    assert_eq!(added.kind, Kind::Occluding);

    // Out-of-range indices name the edit and the count.
    for e in [
        Edit::Delete(n),
        Edit::Flip(99, Side::Both),
        Edit::Move(n, [1.0, 1.0]),
        Edit::Contrast(n + 3, Rho::Scale(2.0)),
        Edit::Base(3, BaseEdit::default()),
        Edit::DeleteBase(7),
    ] {
        let m = apply(&s, &[Edit::Delete(0), e.clone()])
            .unwrap_err()
            .to_string();
        assert!(
            m.starts_with("edit 2 (") && m.contains("there is no"),
            "{m}"
        );
    }
    // Non-finite values.
    let m = apply(&s, &[Edit::Contrast(0, Rho::Set(f32::NAN))])
        .unwrap_err()
        .to_string();
    assert!(m.contains("not a finite number"), "{m}");
    let mut nan_base = nb;
    nan_base.sx = f32::INFINITY;
    let m = apply(&s, &[Edit::AddBase(nan_base)])
        .unwrap_err()
        .to_string();
    assert!(m.contains("shading base 3: sx is inf"), "{m}");

    // The along/across ratio: set (snapped as the files store it), removed, refused when
    // not a positive number.
    let q = apply(&s, &[Edit::AlongAcross(Some(0.1))]).unwrap();
    let t = q.along_across.unwrap();
    assert!((t / 0.1 - 1.0).abs() < 0.023, "{t}");
    assert_eq!(
        apply(&q, &[Edit::AlongAcross(None)]).unwrap().along_across,
        None
    );
    for bad in [0.0, -0.1, f32::NAN, f32::INFINITY] {
        let m = apply(&s, &[Edit::AlongAcross(Some(bad))])
            .unwrap_err()
            .to_string();
        assert!(m.contains("must be a positive number"), "{m}");
    }

    // Edits run in order: a deletion renumbers the curves after it.
    let (q, log) = apply_logged(&s, &[Edit::Delete(0), Edit::Flip(0, Side::Left)]).unwrap();
    assert_eq!(q.curves[0].dirs, [-1, -1]);
    assert_eq!(q.curves[0].kind, Kind::Occluding);
    println!("{}", log.join("\n"));
}

fn coif() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coif"))
}

fn run_ok(args: &[&str]) -> String {
    let out = coif().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The command fails, its message contains each needle, and `out` was not written.
fn run_fails(args: &[&str], needles: &[&str], out: &Path) -> String {
    let o = coif().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "succeeded: {args:?}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: expected {n:?} in: {err}");
    }
    assert!(!out.exists(), "{args:?} wrote {}", out.display());
    err
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn the_command_applies_edits_in_its_order_and_prints_them() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let base = small();
    let input = d.join("in.json");
    save(&base, &input).unwrap();
    // A drawing as Inkscape saves one (a path of straight segments, in a layer).
    let drawing = d.join("line.svg");
    std::fs::write(
        &drawing,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"96\" height=\"80\" \
         viewBox=\"0 0 96 80\">\n<g id=\"layer1\"><path style=\"fill:none;stroke:#000\" \
         d=\"M 50,20 L 70,22 L 85,35\"/></g></svg>\n",
    )
    .unwrap();
    // A JSON curve in sketch.json's form and a drawn one.
    let curve_json = d.join("curves.json");
    std::fs::write(
        &curve_json,
        r#"[{"kind": "e", "dirs": [1, 1], "start": [5, 40],
             "prims": [{"axis": 0, "sides": [0, 0], "rho": 11.887954},
                       {"axis": 15, "sides": [0, 0], "rho": 11.887954}]},
            {"kind": "b", "points": [[70, 60], [90, 60]], "rho": 4}]"#,
    )
    .unwrap();
    let out = d.join("out.czs");
    let stdout = run_ok(&[
        "sketch-edit",
        "--sketch",
        s(&input),
        "--out",
        s(&out),
        "--delete",
        "0",
        "--flip",
        "1:r",
        "--move",
        "4:-3,2",
        "--delete",
        "3",
        "--contrast",
        "5:=20",
        "--add",
        &format!("{}:c", s(&drawing)),
        "--add",
        s(&curve_json),
        "--base",
        "2:amp=-4,theta=45",
        "--delete-base",
        "0",
        "--add-base",
        "20,20,90,8,16,-5",
    ]);
    println!("{stdout}");
    let q = load(&out).unwrap();
    // Indices refer to the input: curves 0 and 3 go, the rest keep their edits.
    let mut want = base.clone();
    want.curves[1].dirs = [1, 1];
    for p in &mut want.curves[4].prims {
        p.x -= 3.0;
        p.y += 2.0;
    }
    for p in &mut want.curves[5].prims {
        p.rho = 20.0;
    }
    want.shading.bases[2].amp = -4.0;
    want.shading.bases[2].theta = PI / 4.0;
    want.shading.bases.remove(0);
    want.shading.bases.push(Base {
        x: 20.0,
        y: 20.0,
        theta: PI / 2.0,
        sx: 8.0,
        sy: 16.0,
        amp: -5.0,
    });
    want.curves.remove(3);
    want.curves.remove(0);
    let kept = want.curves.len();
    let want = quantise(&want);
    assert_eq!(q.curves[..kept], want.curves[..], "kept curves");
    assert_eq!(q.shading, want.shading);
    // Added: the drawing as an occluding line, then the two JSON curves.
    assert_eq!(q.curves.len(), kept + 3);
    let drawn = &q.curves[kept];
    assert_eq!(drawn.kind, Kind::Occluding);
    assert_eq!((drawn.prims[0].x, drawn.prims[0].y), (50.0, 20.0));
    let last = drawn.prims.last().unwrap();
    assert!(
        (last.x - 85.0).hypot(last.y - 35.0) < 3.0,
        "the drawn line ends at ({}, {})",
        last.x,
        last.y
    );
    let lat = &q.curves[kept + 1];
    assert_eq!((lat.kind, lat.prims.len()), (Kind::Stream, 2));
    assert_eq!(
        (lat.prims[1].x, lat.prims[1].y),
        (
            5.0 + 5.0 * (PI / 12.0).cos(),
            40.0 + 5.0 * (PI / 12.0).sin()
        )
    );
    let src = &q.curves[kept + 2];
    assert_eq!(
        (src.kind, src.prims.len(), src.dirs),
        (Kind::Source, 5, [1, 0])
    );
    // What changed is printed, one line per edit.
    for needle in [
        "deleted curve 3",
        "deleted curve 0",
        "flipped curve 1",
        "moved curve 4 (e, 5 primitives) by (-3, 2) px",
        "curve 5",
        "added curve",
        "shading base 2",
        "deleted shading base 0",
        "added shading base",
    ] {
        assert!(stdout.contains(needle), "{needle} not in {stdout}");
    }
    // Adding a whole sketch's curves (sketch.svg form).
    let svg = d.join("other.svg");
    save(&small(), &svg).unwrap();
    let out2 = d.join("out2.svg");
    run_ok(&[
        "sketch-edit",
        "--sketch",
        s(&input),
        "--out",
        s(&out2),
        "--add",
        s(&svg),
    ]);
    let q2 = load(&out2).unwrap();
    assert_eq!(q2.curves.len(), 2 * base.curves.len());
    assert_eq!(q2.curves[base.curves.len()..], base.curves[..]);
}

#[test]
fn bad_sketches_and_bad_edits_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let good = small();
    let out = d.join("out.czs");
    let edit = ["--flip", "0"];
    let cmd = |input: &Path| -> Vec<String> {
        let mut v: Vec<String> = vec![
            "sketch-edit".into(),
            "--sketch".into(),
            s(input).into(),
            "--out".into(),
            s(&out).into(),
        ];
        v.extend(edit.iter().map(|x| x.to_string()));
        v
    };
    let fails = |args: Vec<String>, needles: &[&str]| {
        let a: Vec<&str> = args.iter().map(|x| x.as_str()).collect();
        let m = run_fails(&a, needles, &out);
        println!("{}", m.trim());
    };

    // Zero curves: the files load (coif sketch may find none), editing refuses.
    let empty = d.join("empty.json");
    save(
        &Sketch {
            curves: vec![],
            ..good.clone()
        },
        &empty,
    )
    .unwrap();
    assert!(load(&empty).unwrap().curves.is_empty());
    fails(cmd(&empty), &["empty.json", "no curves"]);

    // A curve running out of the image (hand-edited sketch.json: start at the right edge,
    // heading right).
    let json = format::to_json(&good);
    let mut v: serde_json::Value = serde_json::from_str(&json).unwrap();
    v["curves"][0]["start"] = serde_json::json!([90, 10]);
    let outside = d.join("outside.json");
    std::fs::write(&outside, v.to_string()).unwrap();
    fails(
        cmd(&outside),
        &[
            "outside.json",
            "curve 0, primitive 3",
            "outside the 96x80 image",
        ],
    );
    // The same in a .czs (written from code, which does not check).
    let mut off = good.clone();
    for p in &mut off.curves[0].prims {
        p.x += 70.0;
    }
    let off_czs = d.join("outside.czs");
    std::fs::write(&off_czs, format::to_czs(&off)).unwrap();
    fails(cmd(&off_czs), &["outside.czs", "outside the 96x80 image"]);

    // NaN in the colour map, by hand in sketch.json.
    let text = format::to_json(&good);
    let at = text.find("\"uv\"").unwrap();
    let open = at + text[at..].find("[\n").unwrap() + 1;
    let num_start = open
        + text[open..]
            .find(|c: char| c.is_ascii_digit() || c == '-')
            .unwrap();
    let num_end = num_start + text[num_start..].find([',', '\n']).unwrap();
    let nan = d.join("nan.json");
    std::fs::write(
        &nan,
        format!("{}NaN{}", &text[..num_start], &text[num_end..]),
    )
    .unwrap();
    fails(cmd(&nan), &["nan.json", "NaN", "not a number"]);
    // null there is a schema failure at its place.
    let null = d.join("null.json");
    std::fs::write(
        &null,
        format!("{}null{}", &text[..num_start], &text[num_end..]),
    )
    .unwrap();
    fails(cmd(&null), &["null.json", "/colour/uv/0"]);
    // A colour map of the wrong length.
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["colour"]["uv"].as_array_mut().unwrap().truncate(10);
    let short = d.join("short.json");
    std::fs::write(&short, v.to_string()).unwrap();
    fails(cmd(&short), &["short.json", "/colour/uv"]);

    // An SVG that is not a sketch: a plain Inkscape drawing.
    let plain = d.join("drawing.svg");
    std::fs::write(
        &plain,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" xmlns:inkscape=\
         \"http://www.inkscape.org/namespaces/inkscape\" width=\"96\" height=\"80\">\
         <g inkscape:label=\"Layer 1\" inkscape:groupmode=\"layer\">\
         <path d=\"M 10,10 L 50,40\" style=\"stroke:#000\"/></g></svg>",
    )
    .unwrap();
    fails(cmd(&plain), &["drawing.svg", "not a coif sketch"]);

    // Out-of-range indices, impossible flips, malformed options.
    let input = d.join("in.czs");
    save(&good, &input).unwrap();
    let with = |extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = vec![
            "sketch-edit".into(),
            "--sketch".into(),
            s(&input).into(),
            "--out".into(),
            s(&out).into(),
        ];
        v.extend(extra.iter().map(|x| x.to_string()));
        v
    };
    fails(
        with(&["--flip", "17"]),
        &["in.czs", "there is no curve 17", "6 curves (0 to 5)"],
    );
    fails(
        with(&["--delete-base", "3"]),
        &["in.czs", "no shading base 3"],
    );
    fails(with(&["--flip", "3"]), &["in.czs", "dividing line"]);
    fails(
        with(&["--move", "2:40,0"]),
        &["in.czs", "outside the 96x80 image"],
    );
    fails(
        with(&["--delete", "1", "--delete", "1"]),
        &["--delete 1 is given twice"],
    );
    fails(
        with(&["--contrast", "1:x"]),
        &["--contrast 1:x", "not a finite number"],
    );
    fails(with(&["--base", "0:size=3"]), &["unknown field \"size\""]);
    for bad in ["x", "0", "nan"] {
        fails(
            with(&["--along-across", bad]),
            &["--along-across", "not a positive number or \"none\""],
        );
    }
    // The ratio alone is an edit; "none" removes it.
    let set = with(&["--along-across", "0.2"]);
    let set: Vec<&str> = set.iter().map(|x| x.as_str()).collect();
    run_ok(&set);
    let t = load(&out).unwrap().along_across.unwrap();
    assert!((t / 0.2 - 1.0).abs() < 0.023, "{t}");
    let none = with(&["--along-across", "none"]);
    let none: Vec<&str> = none.iter().map(|x| x.as_str()).collect();
    run_ok(&none);
    assert_eq!(load(&out).unwrap().along_across, None);
    std::fs::remove_file(&out).unwrap();
    fails(
        with(&["--add", s(&d.join("missing.svg"))]),
        &["missing.svg"],
    );
    fails(with(&[]), &["at least one edit"]);
    let all: Vec<String> = (0..6)
        .flat_map(|i| ["--delete".into(), i.to_string()])
        .collect();
    let all: Vec<&str> = all.iter().map(|x| x.as_str()).collect();
    fails(with(&all), &["in.czs", "delete every curve"]);
}

// ---------------------------------------------------------------------------------------
// The field: a flip and a deletion change it only near the curve.

struct Case {
    sketch: Sketch,
    hair: Vec<bool>,
}

/// The oracle sketch of a 256² synthetic portrait (long hair, seed 1), on the lattice.
fn oracle_case() -> Case {
    let case = synth(&SynthParams {
        style: Style::Long,
        seed: 1,
        width: 256,
        height: 256,
    });
    let hair: Vec<bool> = case.mask.as_raw().iter().map(|&v| v > 127).collect();
    let sketch = quantise(&Sketch {
        width: case.width,
        height: case.height,
        seed: 1,
        curves: oracle_sketch(&case),
        rho_off: prior(),
        shading: Shading::default(),
        colour: colour(),
        region: Vec::new(),
        along_across: None,
    });
    Case { sketch, hair }
}

fn field(s: &Sketch, hair: &[bool]) -> VectorField {
    let painted = paint(&s.curves, s.width, s.height, Some(hair));
    fill(
        &Engine::cpu(),
        &painted,
        hair,
        &s.rho_off,
        s.seed,
        &FillParams::default(),
    )
    .unwrap()
}

/// Distance from every pixel centre to curve `c`: to the chain of its centres, extended
/// half a window (3.5 px) beyond each end.
fn distance_to_curve(c: &Curve, w: u32, h: u32) -> Vec<f32> {
    let mut pts: Vec<[f32; 2]> = c.prims.iter().map(|p| [p.x, p.y]).collect();
    let (f, l) = (c.prims[0], c.prims[c.prims.len() - 1]);
    pts.insert(0, [f.x - 3.5 * f.axis.cos(), f.y - 3.5 * f.axis.sin()]);
    pts.push([l.x + 3.5 * l.axis.cos(), l.y + 3.5 * l.axis.sin()]);
    let mut out = vec![f32::INFINITY; (w * h) as usize];
    for j in 0..h {
        for i in 0..w {
            let q = [i as f32 + 0.5, j as f32 + 0.5];
            let mut best = f32::INFINITY;
            for s in pts.windows(2) {
                let (a, b) = (s[0], s[1]);
                let ab = [b[0] - a[0], b[1] - a[1]];
                let len2 = ab[0] * ab[0] + ab[1] * ab[1];
                let t = if len2 > 0.0 {
                    (((q[0] - a[0]) * ab[0] + (q[1] - a[1]) * ab[1]) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let p = [a[0] + t * ab[0], a[1] + t * ab[1]];
                best = best.min((q[0] - p[0]).hypot(q[1] - p[1]));
            }
            out[(j * w + i) as usize] = best;
        }
    }
    out
}

/// The stream lines of `s`, longest first (ties: lower index first).
fn longest_streams(s: &Sketch) -> Vec<usize> {
    let mut v: Vec<usize> = (0..s.curves.len())
        .filter(|&i| s.curves[i].kind == Kind::Stream && s.curves[i].dirs[0] != 0)
        .collect();
    v.sort_by_key(|&i| (std::cmp::Reverse(s.curves[i].prims.len()), i));
    v
}

fn flipped(a: [f32; 2], b: [f32; 2]) -> bool {
    a[0] * b[0] + a[1] * b[1] < 0.0
}

/// Θ moved by more than 5°, the direction reversed, or one of them set in only one field.
fn changed(a: &VectorField, b: &VectorField, k: usize) -> bool {
    let (ta, tb) = (a.theta[k], b.theta[k]);
    if ta.is_nan() != tb.is_nan() || a.dir[k][0].is_nan() != b.dir[k][0].is_nan() {
        return true;
    }
    let dt = coif::synth::orientation_error_deg(ta, tb);
    dt > 5.0 || (!a.dir[k][0].is_nan() && flipped(a.dir[k], b.dir[k]))
}

/// Shares over the hair: (in curve i's region: pixels nearer to it than to any other curve
/// and within `near` px of it, the share `pred` holds on; beyond `far` px of it, the share
/// `pred` holds on; the two counts).
fn shares(
    s: &Sketch,
    hair: &[bool],
    i: usize,
    near: f32,
    far: f32,
    pred: impl Fn(usize) -> bool,
) -> (f64, f64, usize, usize) {
    let (w, h) = (s.width, s.height);
    let mine = distance_to_curve(&s.curves[i], w, h);
    let mut others = vec![f32::INFINITY; mine.len()];
    for (j, c) in s.curves.iter().enumerate() {
        if j != i {
            for (o, d) in others.iter_mut().zip(distance_to_curve(c, w, h)) {
                *o = o.min(d);
            }
        }
    }
    let (mut nh, mut nn, mut fh, mut fnn) = (0usize, 0usize, 0usize, 0usize);
    for k in 0..mine.len() {
        if !hair[k] {
            continue;
        }
        if mine[k] < others[k] && mine[k] <= near {
            nn += 1;
            nh += pred(k) as usize;
        }
        if mine[k] > far {
            fnn += 1;
            fh += pred(k) as usize;
        }
    }
    (
        nh as f64 / nn.max(1) as f64,
        fh as f64 / fnn.max(1) as f64,
        nn,
        fnn,
    )
}

/// The oracle spaces stream lines 14 px apart at 256²: a curve's own region reaches about
/// 7 px to each side, and beyond 2 spacings lie its neighbours and the hair they pin.
const SPACING: f32 = 14.0;

#[test]
fn a_flip_flips_the_field_on_its_side_only_and_a_deletion_changes_it_only_near() {
    let c = oracle_case();
    let s = &c.sketch;
    let v0 = field(s, &c.hair);
    let streams = longest_streams(s);
    println!(
        "oracle sketch of long/1 at 256²: {} curves, {} stream lines (longest {} primitives)",
        s.curves.len(),
        streams.len(),
        s.curves[streams[0]].prims.len()
    );
    println!(
        "{:<8} {:>5} {:>6} {:>14} {:>9} {:>10} {:>10} {:>10}",
        "edit", "curve", "prims", "region px", "in region", "> 14 px", "> 28 px", "> 42 px"
    );
    let mut first = None;
    for (rank, &i) in streams.iter().take(3).enumerate() {
        // Flip: share of the curve's region whose direction reversed; beyond R, share changed.
        let q = apply(s, &[Edit::Flip(i, Side::Both)]).unwrap();
        let v1 = field(&q, &c.hair);
        let flip_pred = |k: usize| !v0.dir[k][0].is_nan() && flipped(v0.dir[k], v1.dir[k]);
        let chg = |k: usize| changed(&v0, &v1, k);
        let (near, _, nn, _) = shares(s, &c.hair, i, SPACING, f32::INFINITY, flip_pred);
        let far: Vec<f64> = [1.0, 2.0, 3.0]
            .iter()
            .map(|m| shares(s, &c.hair, i, 0.0, m * SPACING, chg).1)
            .collect();
        println!(
            "{:<8} {:>5} {:>6} {:>14} {:>8.1}% {:>9.2}% {:>9.2}% {:>9.2}%",
            "flip",
            i,
            s.curves[i].prims.len(),
            nn,
            100.0 * near,
            100.0 * far[0],
            100.0 * far[1],
            100.0 * far[2]
        );
        // Delete: the share of the region that changed, and beyond R.
        let q = apply(s, &[Edit::Delete(i)]).unwrap();
        let v2 = field(&q, &c.hair);
        let chg2 = |k: usize| changed(&v0, &v2, k);
        let (near2, _, _, _) = shares(s, &c.hair, i, SPACING, f32::INFINITY, chg2);
        let far2: Vec<f64> = [1.0, 2.0, 3.0]
            .iter()
            .map(|m| shares(s, &c.hair, i, 0.0, m * SPACING, chg2).1)
            .collect();
        println!(
            "{:<8} {:>5} {:>6} {:>14} {:>8.1}% {:>9.2}% {:>9.2}% {:>9.2}%",
            "delete",
            i,
            s.curves[i].prims.len(),
            nn,
            100.0 * near2,
            100.0 * far2[0],
            100.0 * far2[1],
            100.0 * far2[2]
        );
        if rank == 0 {
            first = Some((near, far[1], far2[1]));
        }
    }
    // Asserted on the longest stream line: its region flips (≥ 90%), and beyond two
    // spacings (its neighbours) ≤ 2% of the hair changes under a flip or a deletion.
    let (near, far_flip, far_del) = first.unwrap();
    assert!(
        near >= 0.90,
        "flip: {:.1}% of the region flipped",
        100.0 * near
    );
    assert!(
        far_flip <= 0.02,
        "flip: {:.2}% beyond 28 px",
        100.0 * far_flip
    );
    assert!(
        far_del <= 0.02,
        "delete: {:.2}% beyond 28 px",
        100.0 * far_del
    );
}
