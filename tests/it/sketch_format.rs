//! The sketch's files: `.czs`, `sketch.json` and `sketch.svg` give the same sketch, `.czs`
//! stays small, and damaged files are refused with errors naming the file and the problem.

use coif::base::rng::Rng;
use coif::sketch::format::{
    czs_sizes, from_czs, from_json, from_svg, load, on_chain, quantise, save, to_czs, to_json,
    to_svg, validate_json,
};
use coif::sketch::{
    Base, ColourMap, Curve, Kind, Primitive, RhoPrior, Shading, Sketch, AXIS_QUANTUM, COLOUR_BINS,
};
use std::f32::consts::PI;
use std::path::Path;

/// A sketch of `n_curves` curves of about `n_prims` primitives, off the lattice (the files
/// quantise it), with `n_bases` shading bases.
fn random_sketch(
    seed: u64,
    w: u32,
    h: u32,
    n_curves: usize,
    n_prims: usize,
    n_bases: usize,
) -> Sketch {
    let mut r = Rng::new(seed);
    let mut curves = Vec::new();
    for _ in 0..n_curves {
        let kind = Kind::ALL[r.below(5) as usize];
        let n = if n_prims <= 1 {
            1
        } else {
            n_prims - 1 + r.below(3) as usize
        };
        // Started far enough inside that the walk stays in the image (the readers refuse
        // centres more than a step outside it).
        let m = |n_px: u32| (5.0 * n as f32).min(0.5 * n_px as f32);
        let (mut x, mut y) = (
            r.range_f32(m(w), w as f32 - m(w)),
            r.range_f32(m(h), h as f32 - m(h)),
        );
        let mut axis = r.range_f32(0.0, 2.0 * PI);
        let mut prims = Vec::new();
        for k in 0..n {
            if k > 0 {
                axis += (r.below(3) as f32 - 1.0) * AXIS_QUANTUM + r.range_f32(-0.1, 0.1);
                x += 5.0 * axis.cos();
                y += 5.0 * axis.sin();
            }
            let side = [(); 2].map(|_| match r.below(5) {
                0 => 0.0,
                1 => PI / 3.0,
                2 => PI / 2.0,
                3 => 2.0 * PI / 3.0,
                _ => r.range_f32(-0.5, 2.7),
            });
            prims.push(Primitive {
                shift: 0.0,
                x,
                y,
                axis: axis.rem_euclid(2.0 * PI),
                rho: (r.normal_f32() * 1.5 + 1.5).exp(),
                side,
            });
        }
        let dirs = [(); 2].map(|_| r.below(3) as i8 - 1);
        curves.push(Curve { kind, prims, dirs });
    }
    // Half the occluding lines off their chains (a stream of their own, so the other draws
    // are as before), some shifts off the ¼ px lattice or past ±2 px for quantising to snap.
    let mut rs = Rng::new(seed ^ 0x5eed_5417);
    for c in curves.iter_mut().filter(|c| c.kind == Kind::Occluding) {
        if rs.below(2) == 0 {
            for p in &mut c.prims {
                p.shift = match rs.below(4) {
                    0 => 0.0,
                    1 => rs.range_f32(-2.4, 2.4),
                    _ => (rs.below(17) as f32 - 8.0) * 0.25,
                };
                let n = p.left_normal();
                p.x += p.shift * n[0];
                p.y += p.shift * n[1];
            }
        }
    }
    let bases = (0..n_bases)
        .map(|_| Base {
            x: r.range_f32(0.0, w as f32),
            y: r.range_f32(0.0, h as f32),
            theta: r.range_f32(0.0, PI),
            sx: r.range_f32(4.0, 64.0),
            sy: r.range_f32(4.0, 64.0),
            amp: r.range_f32(-40.0, 40.0),
        })
        .collect();
    let colour = ColourMap {
        uv: (0..COLOUR_BINS)
            .map(|i| {
                [
                    5.0 + i as f32 * 1.3 + r.range_f32(-2.0, 2.0),
                    10.0 + r.range_f32(-8.0, 8.0),
                ]
            })
            .collect(),
    };
    Sketch {
        width: w,
        height: h,
        seed: r.next_u32() as u64 * 7919,
        curves,
        rho_off: RhoPrior {
            weight: [0.7, 0.3],
            mean: [r.range_f32(0.5, 4.0), r.range_f32(4.0, 20.0)],
            sigma: [r.range_f32(0.2, 2.0), r.range_f32(1.0, 8.0)],
        },
        shading: Shading {
            mean: r.range_f32(10.0, 90.0),
            bases,
        },
        colour,
        region: random_region(&mut r, w, h),
        // None one time in four; else from 3e-4 to 1.6 (over 1 is stored as 1).
        along_across: (r.below(4) != 0).then(|| r.range_f32(-8.0, 0.5).exp()),
    }
}

/// Up to two random polygons (star-shaped around a point), some vertices off the image so
/// that quantising clamps them; none at all in one case of three (the whole image).
fn random_region(r: &mut Rng, w: u32, h: u32) -> coif::sketch::Region {
    let n = r.below(3) as usize;
    (0..n)
        .map(|_| {
            let (cx, cy) = (r.range_f32(0.0, w as f32), r.range_f32(0.0, h as f32));
            let k = 3 + r.below(20) as usize;
            (0..k)
                .map(|i| {
                    let a = i as f32 / k as f32 * 2.0 * PI;
                    let rad = r.range_f32(5.0, 0.4 * w.min(h) as f32);
                    [
                        (cx + rad * a.cos()).round().max(0.0) as u32,
                        (cy + rad * a.sin()).round().max(0.0) as u32,
                    ]
                })
                .collect()
        })
        .collect()
}

/// Every file gives back the quantised sketch, and chains of files do too.
fn check_round_trips(s: &Sketch, what: &str) {
    let q = quantise(s);
    assert_eq!(quantise(&q), q, "{what}: quantise is not idempotent");
    let p = Path::new("x");
    let czs = from_czs(&to_czs(s), p).unwrap();
    assert_eq!(czs, q, "{what}: czs");
    let json = from_json(&to_json(s), p).unwrap();
    assert_eq!(json, q, "{what}: json");
    let svg = from_svg(&to_svg(s), p).unwrap();
    assert_eq!(svg, q, "{what}: svg");
    let chain = from_svg(
        &to_svg(&from_json(&to_json(&from_czs(&to_czs(&q), p).unwrap()), p).unwrap()),
        p,
    )
    .unwrap();
    assert_eq!(chain, q, "{what}: czs -> json -> svg");
    let back = from_czs(
        &to_czs(&from_json(&to_json(&from_svg(&to_svg(&q), p).unwrap()), p).unwrap()),
        p,
    )
    .unwrap();
    assert_eq!(back, q, "{what}: svg -> json -> czs");
    // Quantising keeps the geometry of the lattice: the snapped centres are within a pixel
    // of a lattice input's (checked on the first centre, which is only rounded).
    for (a, b) in s
        .curves
        .iter()
        .filter(|c| !c.prims.is_empty())
        .zip(&q.curves)
    {
        // (The chain's start: an occluding line's centres lie off it by their shifts.)
        let (pa, pb) = (on_chain(&a.prims[0]), on_chain(&b.prims[0]));
        assert!(
            (pa[0].clamp(0.0, s.width as f32) - pb[0]).abs() <= 0.5
                && (pa[1].clamp(0.0, s.height as f32) - pb[1]).abs() <= 0.5,
            "{what}: start moved"
        );
        assert_eq!(a.prims.len(), b.prims.len());
    }
}

#[test]
fn random_sketches_round_trip() {
    for seed in 0..40 {
        let s = random_sketch(seed, 300 + seed as u32 * 7, 200 + seed as u32 * 3, 12, 6, 8);
        check_round_trips(&s, &format!("seed {seed}"));
    }
}

#[test]
fn edge_cases_round_trip() {
    let base = random_sketch(99, 256, 256, 0, 1, 0);
    check_round_trips(&base, "zero curves, zero bases");
    let mut one = random_sketch(5, 64, 48, 1, 1, 1);
    assert_eq!(one.curves[0].prims.len(), 1);
    check_round_trips(&one, "one primitive");
    one.seed = u64::MAX;
    one.width = 1;
    one.height = 1;
    check_round_trips(&one, "1x1, largest seed");
    // Every kind, directed and undirected, and only dictionary side angles (no refinement
    // bits).
    for kind in Kind::ALL {
        for dirs in [[0, 0], [1, -1], [-1, 1]] {
            let mut s = random_sketch(7, 128, 96, 3, 4, 2);
            for c in &mut s.curves {
                c.kind = kind;
                c.dirs = dirs;
                for p in &mut c.prims {
                    p.side = [PI / 3.0, PI / 2.0];
                }
            }
            check_round_trips(&s, &format!("{kind:?} {dirs:?}"));
            let q = quantise(&s);
            let want = match kind {
                Kind::Boundary | Kind::Source => [dirs[0], 0],
                Kind::Occluding => dirs,
                Kind::Dividing => [1, 1],
                Kind::Stream => [dirs[0], dirs[0]],
            };
            assert!(q.curves.iter().all(|c| c.dirs == want), "{kind:?} {dirs:?}");
        }
    }
    // A curve without primitives is dropped; one that turns sharply is bent to ±15°.
    let mut s = random_sketch(8, 100, 100, 2, 3, 0);
    s.curves[0].prims.clear();
    let a = s.curves[1].prims[0].axis;
    s.curves[1].prims[1].axis = a + 4.0 * AXIS_QUANTUM;
    let q = quantise(&s);
    assert_eq!(q.curves.len(), 1);
    let turn = (q.curves[0].prims[1].axis - q.curves[0].prims[0].axis).rem_euclid(2.0 * PI);
    assert!((turn - AXIS_QUANTUM).abs() < 1e-5, "{turn}");
    check_round_trips(&s, "empty curve, sharp turn");
}

#[test]
fn lattice_curves_keep_their_geometry() {
    // A curve built the pursuit's way (integer start, 15° axes, 5 px steps along the new
    // axis) is stored without moving any centre.
    let mut prims = Vec::new();
    let (mut x, mut y, mut k) = (40.0f32, 30.0f32, 5i32);
    for (i, t) in [0, 1, 1, 0, -1, -1, -1, 0].iter().enumerate() {
        if i > 0 {
            k += t;
            let a = k as f32 * AXIS_QUANTUM;
            x += 5.0 * a.cos();
            y += 5.0 * a.sin();
        }
        prims.push(Primitive {
            shift: 0.0,
            x,
            y,
            axis: (k as f32 * AXIS_QUANTUM).rem_euclid(2.0 * PI),
            rho: 8.0,
            side: [0.0, PI / 2.0],
        });
    }
    let mut s = random_sketch(1, 100, 100, 0, 1, 0);
    s.curves.push(Curve {
        kind: Kind::Occluding,
        prims: prims.clone(),
        dirs: [1, -1],
    });
    let q = from_czs(&to_czs(&s), Path::new("x")).unwrap();
    for (a, b) in prims.iter().zip(&q.curves[0].prims) {
        assert!(
            (a.x - b.x).abs() < 1e-4 && (a.y - b.y).abs() < 1e-4,
            "{a:?} vs {b:?}"
        );
        assert!((a.axis - b.axis).abs() < 1e-5);
        assert_eq!((a.rho, a.side), (b.rho, b.side));
    }
}

#[test]
fn czs_is_small() {
    println!(
        "{:<26} {:>6} {:>6} {:>7} {:>6} {:>6}",
        "30 curves x 8 prims", "header", "curves", "shading", "colour", "total"
    );
    for (name, discrete) in [("refined sides", false), ("dictionary sides", true)] {
        let mut worst = 0;
        for seed in 0..10 {
            let mut s = random_sketch(1000 + seed, 512, 512, 30, 8, 10);
            // The curves' budget; a real mask's outline is measured in tests/it/sketch_cli.rs.
            s.region.clear();
            for c in &mut s.curves {
                c.prims.truncate(8);
                while c.prims.len() < 8 {
                    let mut p = *c.prims.last().unwrap();
                    p.x += 5.0 * p.axis.cos();
                    p.y += 5.0 * p.axis.sin();
                    c.prims.push(p);
                }
                if discrete {
                    for p in &mut c.prims {
                        p.side = [0.0, PI / 2.0];
                    }
                }
            }
            let z = czs_sizes(&s);
            assert_eq!(z.total, to_czs(&s).len());
            assert_eq!(
                z.header + z.curves + z.shading + z.colour + z.region,
                z.total
            );
            if seed == 0 {
                println!(
                    "{:<26} {:>6} {:>6} {:>7} {:>6} {:>6}",
                    name, z.header, z.curves, z.shading, z.colour, z.total
                );
            }
            worst = worst.max(z.total);
        }
        println!("{name}: largest of 10 random sketches {worst} bytes");
        assert!(worst <= 1024, "{name}: {worst} bytes");
    }
}

fn err(r: coif::error::Result<Sketch>) -> String {
    let m = r.expect_err("a damaged file was accepted").to_string();
    assert!(
        m.starts_with("bad.file: "),
        "the error does not name the file: {m}"
    );
    m
}

#[test]
fn truncated_czs_fails_cleanly_at_every_byte() {
    let s = random_sketch(3, 320, 240, 20, 7, 10);
    let bytes = to_czs(&s);
    let p = Path::new("bad.file");
    for n in 0..bytes.len() {
        let m = err(from_czs(&bytes[..n], p));
        assert!(
            m.contains("truncated") || (n == 0 && m.contains("empty")),
            "{n} bytes: {m}"
        );
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(err(from_czs(&longer, p)).contains("after the end"));
    println!("{} truncations refused", bytes.len());
}

#[test]
fn corrupted_czs_is_detected() {
    let s = random_sketch(4, 320, 240, 20, 7, 10);
    let bytes = to_czs(&s);
    let p = Path::new("bad.file");
    let mut kinds = std::collections::BTreeMap::<String, usize>::new();
    let mut note = |m: String| {
        let key = m
            .trim_start_matches("bad.file: ")
            .split([':', '('])
            .next()
            .unwrap()
            .trim()
            .to_string();
        *kinds.entry(key).or_default() += 1;
    };
    // Every single bit flip.
    for bit in 0..bytes.len() * 8 {
        let mut b = bytes.clone();
        b[bit / 8] ^= 0x80 >> (bit % 8);
        note(err(from_czs(&b, p)));
    }
    // Random bursts of 2 to 16 flips.
    let mut r = Rng::new(11);
    for _ in 0..3000 {
        let mut b = bytes.clone();
        for _ in 0..2 + r.below(15) {
            let bit = r.below(b.len() as u32 * 8) as usize;
            b[bit / 8] ^= 0x80 >> (bit % 8);
        }
        if b != bytes {
            note(err(from_czs(&b, p)));
        }
    }
    println!("refused corruptions by message: {kinds:?}");
    // A file with a valid checksum but impossible content (a kind code of 7) is refused
    // by the parser too: rebuild the checksum over a flipped kind.
    let q = quantise(&random_sketch(5, 64, 64, 1, 2, 0));
    let good = to_czs(&q);
    let mut found = false;
    for bit in 0..(good.len() - 4) * 8 {
        let mut b = good.clone();
        b[bit / 8] ^= 0x80 >> (bit % 8);
        let n = b.len();
        let crc = crc32(&b[..n - 4]);
        b[n - 4..].copy_from_slice(&crc.to_le_bytes());
        if let Err(e) = from_czs(&b, p) {
            let m = e.to_string();
            assert!(m.starts_with("bad.file: "), "{m}");
            found |= m.contains("corrupted: curve 0 has kind code");
        }
    }
    assert!(found, "no flip gave an invalid kind code");
}

/// The CRC-32 of `.czs` (IEEE, reflected), to forge checksums in the test above.
fn crc32(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

#[test]
fn bad_json_and_svg_are_refused() {
    let p = Path::new("bad.file");
    let mut s = random_sketch(6, 200, 100, 3, 3, 2);
    // Curve 0 an occluding line off its chain.
    s.curves[0].kind = Kind::Occluding;
    for p in &mut s.curves[0].prims {
        p.shift = 0.5;
        let n = p.left_normal();
        p.x += 0.5 * n[0];
        p.y += 0.5 * n[1];
    }
    let good: serde_json::Value = serde_json::from_str(&to_json(&s)).unwrap();
    validate_json(&good).unwrap();
    assert!(err(from_json("{\"format\": ", p)).contains("malformed JSON"));
    let mut cases: Vec<(serde_json::Value, &str)> = Vec::new();
    let mut v = good.clone();
    v["curves"][0]["kind"] = "z".into();
    cases.push((v, "/curves/0/kind"));
    let mut v = good.clone();
    v["curves"][1]["prims"][0]["axis"] = 20.into();
    cases.push((v, "/curves/1/prims/0/axis"));
    let mut v = good.clone();
    v.as_object_mut().unwrap().remove("shading");
    cases.push((v, "shading"));
    let mut v = good.clone();
    v["colour"]["uv"].as_array_mut().unwrap().pop();
    cases.push((v, "/colour/uv"));
    let mut v = good.clone();
    v["version"] = 5.into();
    cases.push((v, "/version"));
    // An occluding line's shift: off the ¼ px lattice, and past ±2 px.
    let occluding = good["curves"]
        .as_array()
        .unwrap()
        .iter()
        .position(|c| c["kind"] == "c")
        .expect("the sketch has an occluding line");
    for bad in [0.3, 2.25] {
        let mut v = good.clone();
        v["curves"][occluding]["prims"][0]["shift"] = bad.into();
        cases.push((v, "shift"));
    }
    let mut v = good.clone();
    v["along_across"] = (-0.1).into();
    cases.push((v, "/along_across"));
    let mut v = good.clone();
    v["along_across"] = "0.1".into();
    cases.push((v, "/along_across"));
    let mut v = good.clone();
    v["region"] = serde_json::json!([[[0, 0], [4, 0]]]);
    cases.push((v, "/region/0"));
    let mut v = good.clone();
    v["shading"]["bases"][0]["amp"] = 100.0.into();
    cases.push((v, "/shading/bases/0/amp"));
    let mut v = good.clone();
    v["extra"] = 1.into();
    cases.push((v, "extra"));
    for (v, needle) in cases {
        let m = err(from_json(&v.to_string(), p));
        assert!(m.contains("schema") && m.contains(needle), "{needle}: {m}");
    }
    // Valid by the schema, but a curve that turns 30° at once.
    let mut v = good.clone();
    let prims = v["curves"][0]["prims"].as_array_mut().unwrap();
    let a = prims[0]["axis"].as_u64().unwrap();
    prims[1]["axis"] = ((a + 30) % 360).into();
    let m = err(from_json(&v.to_string(), p));
    assert!(
        m.contains("curve 0, primitive 1") && m.contains("turns"),
        "{m}"
    );
    // Valid by the schema, but a shift on a stream line.
    let mut v = good.clone();
    let stream = good["curves"]
        .as_array()
        .unwrap()
        .iter()
        .position(|c| c["kind"] != "c")
        .expect("the sketch has a curve of another kind");
    v["curves"][stream]["prims"][0]["shift"] = 0.5.into();
    let m = err(from_json(&v.to_string(), p));
    assert!(
        m.contains(&format!("curve {stream}, primitive 0")) && m.contains("only occluding"),
        "{m}"
    );
    // SVG.
    let svg = to_svg(&s);
    // An occluding line's data-shift: a number short, off the ¼ px lattice; on a stream line.
    let key = " data-shift=\"";
    let at = svg.find(key).expect("an occluding line is off its chain") + key.len();
    let end = at + svg[at..].find('"').unwrap();
    let list: Vec<&str> = svg[at..end].split(' ').collect();
    let with = |l: &[&str]| format!("{}{}{}", &svg[..at], l.join(" "), &svg[end..]);
    let m = err(from_svg(&with(&list[1..]), p));
    assert!(m.contains("data-shift") && m.contains("expected"), "{m}");
    let mut off = list.clone();
    off[0] = "0.3";
    let m = err(from_svg(&with(&off), p));
    assert!(
        m.contains("data-shift 0.3") && m.contains("multiples"),
        "{m}"
    );
    let other = format!(
        "<polyline class=\"cz-{}\"",
        good["curves"][stream]["kind"].as_str().unwrap()
    );
    let m = err(from_svg(
        &svg.replacen(&other, &format!("{other} data-shift=\"0.5\""), 1),
        p,
    ));
    assert!(m.contains("only occluding"), "{m}");
    assert!(err(from_svg("<svg", p)).contains("malformed XML"));
    assert!(err(from_svg("<html/>", p)).contains("not an SVG"));
    assert!(
        err(from_svg("<svg xmlns=\"http://www.w3.org/2000/svg\"/>", p))
            .contains("not a coif sketch")
    );
    let m = err(from_svg(
        &svg.replacen("<polyline class=\"cz-", "<polyline class=\"zz-", 1),
        p,
    ));
    assert!(m.contains("curve 0") && m.contains("names no kind"), "{m}");
    let m = err(from_svg(&svg.replacen("points=\"", "points=\"1,x ", 1), p));
    assert!(m.contains("points") && m.contains("not a number"), "{m}");
    let m = err(from_svg(
        &svg.replacen("<polyline ", "<polyline transform=\"skew(3)\" ", 1),
        p,
    ));
    assert!(
        m.contains("curve 0") && m.contains("skew with 1 numbers"),
        "{m}"
    );
    let m = err(from_svg(
        &svg.replacen("data-rho=\"", "data-rho=\"1 ", 1),
        p,
    ));
    assert!(m.contains("data-rho") && m.contains("expected"), "{m}");
    let mut with = s.clone();
    with.along_across = Some(0.1);
    let svg = to_svg(&with);
    assert_eq!(from_svg(&svg, p).unwrap(), quantise(&with));
    let key = "data-along-across=\"";
    let at = svg.find(key).expect("the ratio is written") + key.len();
    let end = at + svg[at..].find('"').unwrap();
    for bad in ["NaN", "-0.5", "0", "x"] {
        let m = err(from_svg(&format!("{}{bad}{}", &svg[..at], &svg[end..]), p));
        assert!(
            m.contains("data-along-across") && m.contains("not a positive number"),
            "{bad}: {m}"
        );
    }
}

#[test]
fn files_load_by_extension_and_the_svg_importer_reads_the_svg() {
    let dir = tempfile::tempdir().unwrap();
    let s = random_sketch(12, 256, 200, 9, 5, 4);
    let q = quantise(&s);
    for name in ["hair.czs", "sketch.json", "sketch.svg"] {
        let path = dir.path().join(name);
        save(&s, &path).unwrap();
        assert_eq!(load(&path).unwrap(), q, "{name}");
    }
    let strokes = coif::io::import::strokes_from_svg(&dir.path().join("sketch.svg")).unwrap();
    assert_eq!(strokes.strokes.len(), q.curves.len());
    for (st, c) in strokes.strokes.iter().zip(&q.curves) {
        assert_eq!(st.points.len(), c.prims.len() + 2);
        // The importer's points are the centres (between the lead-in and lead-out).
        for (pt, p) in st.points[1..].iter().zip(&c.prims) {
            // (An occluding line's chain, under its centres placed off it.)
            let [x, y] = coif::sketch::format::on_chain(p);
            assert!((pt[0] - x).abs() < 1e-3 && (pt[1] - y).abs() < 1e-3);
        }
    }
    let other = dir.path().join("sketch.txt");
    std::fs::write(&other, "x").unwrap();
    let m = load(&other).unwrap_err().to_string();
    assert!(
        m.contains("sketch.txt") && m.contains(".czs, .json or .svg"),
        "{m}"
    );
    let m = load(&dir.path().join("missing.czs"))
        .unwrap_err()
        .to_string();
    assert!(m.contains("missing.czs"), "{m}");
}

#[test]
fn inkscape_saves_and_moves_are_read() {
    let dir = coif::sketch::samples::data_dir().join("inkscape");
    let written = load(&dir.join("written.svg")).unwrap();
    assert_eq!(written.curves.len(), 5);
    assert_eq!(written.shading.bases.len(), 10);
    // Opened and saved by Inkscape: the same sketch.
    assert_eq!(load(&dir.join("resaved.svg")).unwrap(), written);
    // Moved in Inkscape (a transform on the polyline; the ellipse rewritten as rotate(θ)
    // about the origin with new cx, cy): the moves are read, nothing else changes.
    let moved = load(&dir.join("moved.svg")).unwrap();
    let mut want = written.clone();
    for p in &mut want.curves[1].prims {
        p.x += 10.0;
        p.y += 3.0;
    }
    want.shading.bases[0].x += 8.0;
    want.shading.bases[0].y -= 4.0;
    let want = quantise(&want);
    assert_eq!(moved, want);
    let strokes = coif::io::import::strokes_from_svg(&dir.join("moved.svg")).unwrap();
    assert_eq!(strokes.strokes.len(), 5);
}

/// The region path as Inkscape rewrites it (relative commands, h/v, implicit linetos, a
/// translate on the element) reads back as the same polygons; an arc is refused by name.
#[test]
fn region_paths_from_an_editor_are_read() {
    let p = Path::new("edited.svg");
    let mut s = random_sketch(21, 120, 90, 2, 3, 1);
    s.region = vec![
        vec![[10, 10], [60, 10], [60, 40], [10, 40]],
        vec![[20, 20], [30, 20], [30, 30]],
    ];
    let q = quantise(&s);
    let svg = to_svg(&s);
    let d = svg
        .split(" d=\"")
        .nth(1)
        .and_then(|t| t.split('"').next())
        .unwrap()
        .to_string();
    let edited = svg.replace(
        &format!(" d=\"{d}\""),
        " transform=\"translate(5,-5)\" d=\"m 5,15 h 5e1 v 3e+1 l -50-0 z m 10,10 10,0 0,10 z\"",
    );
    assert_eq!(from_svg(&edited, p).unwrap(), q);
    let arc = svg.replace(&format!(" d=\"{d}\""), " d=\"M 1 1 A 5 5 0 0 1 20 20 Z\"");
    let m = from_svg(&arc, p).unwrap_err().to_string();
    assert!(m.contains("edited.svg") && m.contains("'A'"), "{m}");
    let far = svg.replace(&format!(" d=\"{d}\""), " d=\"M 1 1 L 500 1 L 1 40 Z\"");
    let m = from_svg(&far, p).unwrap_err().to_string();
    assert!(m.contains("outside the 120x90 image"), "{m}");
}
