//! Strand file formats against the real hairutil/CT2Hair files in tests/data/strands/.

use coif::error::Error;
use coif::hair::strands::StrandSet;
use coif::io::strands::{self, Format, UpAxis, UsdOptions};
use std::path::{Path, PathBuf};
use std::process::Command;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/strands")
        .join(name)
}

fn bytes(name: &str) -> Vec<u8> {
    std::fs::read(data(name)).unwrap()
}

/// Every value as bits, so -0.0 vs 0.0 or any rounding shows up as a difference.
#[derive(Debug, PartialEq)]
struct Bits {
    counts: Vec<u32>,
    points: Vec<u32>,
    thickness: Option<Vec<u32>>,
    transparency: Option<Vec<u32>>,
    colors: Option<Vec<u32>>,
}

fn bits(s: &StrandSet) -> Bits {
    let b = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    Bits {
        counts: s.counts.clone(),
        points: b(s.points.as_flattened()),
        thickness: s.thickness.as_deref().map(b),
        transparency: s.transparency.as_deref().map(b),
        colors: s.colors.as_deref().map(|c| b(c.as_flattened())),
    }
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}
fn le_f32(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

#[test]
fn bangs_hair_data_and_ascii_ply_agree() {
    let hair = strands::read(&data("Bangs_100.hair")).unwrap();
    let dat = strands::read(&data("Bangs_100.data")).unwrap();
    let ply = strands::read(&data("Bangs_100_ascii.ply")).unwrap();

    // Independent of the reader: segments and first/last point straight from the bytes.
    let raw = bytes("Bangs_100.hair");
    assert_eq!(
        (le_u32(&raw, 4), le_u32(&raw, 8), le_u32(&raw, 12)),
        (100, 1165, 3)
    );
    let seg0 = u16::from_le_bytes([raw[128], raw[129]]) as u32;
    assert_eq!(hair.counts[0], seg0 + 1);
    assert_eq!(
        hair.points[0],
        [le_f32(&raw, 328), le_f32(&raw, 332), le_f32(&raw, 336)]
    );
    let last = raw.len() - 12;
    assert_eq!(
        hair.points[1164],
        [
            le_f32(&raw, last),
            le_f32(&raw, last + 4),
            le_f32(&raw, last + 8)
        ]
    );

    assert_eq!(hair.len(), 100);
    assert_eq!(hair.points.len(), 1165);
    assert_eq!(hair.counts.iter().sum::<u32>(), 1165);
    assert_eq!(hair.counts, dat.counts);
    assert_eq!(hair.counts, ply.counts);
    // The ascii PLY prints 9 significant digits, enough to give back every f32 exactly.
    assert_eq!(bits(&hair).points, bits(&dat).points);
    assert_eq!(bits(&hair).points, bits(&ply).points);

    // flags = 3: the absent arrays take the header defaults (thickness 1, transparency 0, white).
    assert!(hair.thickness.as_ref().unwrap().iter().all(|&t| t == 1.0));
    assert!(hair
        .transparency
        .as_ref()
        .unwrap()
        .iter()
        .all(|&t| t == 0.0));
    assert!(hair.colors.as_ref().unwrap().iter().all(|&c| c == [1.0; 3]));
    assert!(dat.thickness.is_none() && dat.colors.is_none());
    // The ascii PLY carries uchar colours: first line "... 40 139 94".
    assert_eq!(
        ply.colors.as_ref().unwrap()[0],
        [40.0 / 255.0, 139.0 / 255.0, 94.0 / 255.0]
    );
    hair.validate().unwrap();
    let (lo, hi) = hair.bounds();
    assert!(lo
        .iter()
        .zip(hi)
        .all(|(l, h)| *l > 0.0 && h < 300.0 && *l < h));
}

/// A minimal reader of the `.usda` this crate writes (the real USD library is checked below).
fn parse_usda(text: &str) -> StrandSet {
    fn array<'t>(text: &'t str, decl: &str) -> Option<&'t str> {
        let at = text.find(&format!("{decl} = ["))? + decl.len() + 4;
        let end = at + text[at..].find(']').unwrap();
        Some(&text[at..end])
    }
    fn floats(body: &str) -> Vec<f32> {
        body.split(|c: char| c == ',' || c == '(' || c == ')' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(|t| t.parse().unwrap())
            .collect()
    }
    fn triples(v: Vec<f32>) -> Vec<[f32; 3]> {
        v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
    }
    assert!(text.contains("uniform token type = \"linear\""));
    let counts = array(text, "int[] curveVertexCounts")
        .unwrap()
        .split(", ")
        .map(|t| t.parse().unwrap())
        .collect();
    let points = triples(floats(array(text, "point3f[] points").unwrap()));
    let widths = floats(array(text, "float[] widths").unwrap());
    let mut s = StrandSet::new(points, counts);
    if widths.len() == s.points.len() {
        s.thickness = Some(widths);
    }
    s.colors = array(text, "color3f[] primvars:displayColor").map(|b| triples(floats(b)));
    s.transparency = array(text, "float[] primvars:displayOpacity")
        .map(|b| floats(b).into_iter().map(|o| 1.0 - o).collect());
    s
}

fn read_back(path: &Path) -> StrandSet {
    if path.extension().unwrap() == "usda" {
        parse_usda(&std::fs::read_to_string(path).unwrap())
    } else {
        strands::read(path).unwrap()
    }
}

#[test]
fn every_format_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    for src_name in ["Bangs_100.hair", "Curly_100.ply", "Bangs_100_ascii.ply"] {
        let src = strands::read(&data(src_name)).unwrap();
        let want = bits(&src);
        for out in ["hair", "data", "ply", "ascii.ply", "obj", "usda"] {
            let path = dir.path().join(format!("rt.{out}"));
            if out == "ascii.ply" {
                strands::write_ply_ascii(&path, &src).unwrap();
                assert!(std::fs::read(&path)
                    .unwrap()
                    .starts_with(b"ply\nformat ascii 1.0\n"));
            } else {
                strands::write(&path, &src).unwrap();
            }
            let got = bits(&read_back(&path));
            let ctx = format!("{src_name} -> {out}");
            assert_eq!(got.counts, want.counts, "{ctx}");
            assert_eq!(got.points, want.points, "{ctx}");
            match out {
                // PLY carries every attribute (colours as uchar: the sources' are uchar or 1.0).
                "ply" | "ascii.ply" => assert_eq!(got, want, "{ctx}"),
                "data" => {
                    assert!(
                        got.thickness.is_none()
                            && got.transparency.is_none()
                            && got.colors.is_none()
                    )
                }
                "obj" => {
                    assert_eq!(got.colors, want.colors, "{ctx}");
                    assert!(got.thickness.is_none() && got.transparency.is_none());
                }
                "hair" | "usda" => {
                    assert_eq!(got.colors, want.colors, "{ctx}");
                    if want.thickness.is_some() {
                        assert_eq!(got.thickness, want.thickness, "{ctx}");
                    }
                    if want.transparency.is_some() {
                        assert_eq!(got.transparency, want.transparency, "{ctx}");
                    }
                }
                _ => unreachable!(),
            }
        }
    }
}

#[test]
fn written_hair_and_data_match_the_original_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let set = strands::read(&data("Bangs_100.hair")).unwrap();
    let hair = dir.path().join("b.hair");
    strands::write(&hair, &set).unwrap();
    let (orig, ours) = (bytes("Bangs_100.hair"), std::fs::read(&hair).unwrap());
    // Uniform per-vertex arrays go back into the header defaults, so flags stay 3 and only
    // the 88-byte info text differs.
    assert_eq!(ours[..40], orig[..40]);
    assert_eq!(ours[128..], orig[128..]);
    let dat = dir.path().join("b.data");
    strands::write(&dat, &set).unwrap();
    assert_eq!(std::fs::read(&dat).unwrap(), bytes("Bangs_100.data"));

    // Varying attributes are written per vertex (flags 1|2|4|8|16) and read back exactly.
    let mut v = set.clone();
    let n = v.points.len();
    v.thickness = Some((0..n).map(|i| 0.01 * i as f32).collect());
    v.transparency = Some((0..n).map(|i| (i % 7) as f32 / 7.0).collect());
    v.colors = Some((0..n).map(|i| [i as f32 / n as f32, 0.5, 0.25]).collect());
    strands::write(&hair, &v).unwrap();
    let raw = std::fs::read(&hair).unwrap();
    assert_eq!(le_u32(&raw, 12), 31);
    assert_eq!(raw.len(), 128 + 200 + n * (12 + 4 + 4 + 12));
    assert_eq!(bits(&strands::read(&hair).unwrap()), bits(&v));
}

#[test]
fn curly_colours_survive() {
    let curly = strands::read(&data("Curly_100.ply")).unwrap();
    assert_eq!((curly.len(), curly.points.len()), (100, 2528));
    // Independent of the reader: vertex rows are 3 floats + 3 uchar after the header.
    let raw = bytes("Curly_100.ply");
    let body = raw.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let colors = curly.colors.as_ref().unwrap();
    for (i, c) in colors.iter().enumerate() {
        let row = &raw[body + 15 * i..body + 15 * (i + 1)];
        assert_eq!(curly.points[i][0], le_f32(row, 0));
        assert_eq!(
            *c,
            [0, 1, 2].map(|k| row[12 + k] as f32 / 255.0),
            "vertex {i}"
        );
    }
    // One colour per strand in this file: check strands are uniform and distinct.
    let mut start = 0;
    let mut per_strand = Vec::new();
    for &c in &curly.counts {
        let s = &colors[start..start + c as usize];
        assert!(s.iter().all(|x| *x == s[0]));
        per_strand.push(s[0].map(f32::to_bits));
        start += c as usize;
    }
    per_strand.sort();
    per_strand.dedup();
    assert!(
        per_strand.len() > 90,
        "{} distinct strand colours",
        per_strand.len()
    );

    let dir = tempfile::tempdir().unwrap();
    for ext in ["ply", "hair", "obj"] {
        let p = dir.path().join(format!("c.{ext}"));
        strands::write(&p, &curly).unwrap();
        assert_eq!(
            strands::read(&p).unwrap().colors.as_ref(),
            Some(colors),
            "{ext}"
        );
    }
}

const NO_USD: &str =
    "the USD check needs usd-core: run `pip install usd-core` (python3 -c 'import pxr' failed)";

/// Opens a written stage with the real USD library and returns its report lines.
fn usd_report(path: &Path) -> Vec<String> {
    let probe = Command::new("python3").args(["-c", "import pxr"]).output();
    match probe {
        Ok(o) if o.status.success() => {}
        Ok(o) => panic!("{NO_USD}\n{}", String::from_utf8_lossy(&o.stderr)),
        Err(e) => panic!("{NO_USD}; python3 did not start: {e}"),
    }
    let script = r#"
import sys
from pxr import Usd, UsdGeom
stage = Usd.Stage.Open(sys.argv[1])
prim = stage.GetDefaultPrim()
curves = UsdGeom.BasisCurves(prim)
counts = curves.GetCurveVertexCountsAttr().Get()
points = curves.GetPointsAttr().Get()
print("type", curves.GetTypeAttr().Get())
print("curves", curves.GetCurveCount(), len(counts), sum(counts))
print("points", len(points))
print("mpu", repr(UsdGeom.GetStageMetersPerUnit(stage)))
print("up", UsdGeom.GetStageUpAxis(stage))
colors = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
if colors.HasValue():
    print("colors", len(colors.Get()), colors.GetInterpolation())
else:
    print("colors none")
computed = UsdGeom.Boundable.ComputeExtentFromPlugins(curves, Usd.TimeCode.Default())
stored = curves.GetExtentAttr().Get()
print("extent", max(abs(a[k] - b[k]) for a, b in zip(computed, stored) for k in range(3)))
for p in points:
    print("p", repr(p[0]), repr(p[1]), repr(p[2]))
"#;
    let out = Command::new("python3")
        .args(["-c", script])
        .arg(path)
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "USD could not open {}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(String::from)
        .collect()
}

#[test]
fn usd_library_reads_the_written_stage() {
    let dir = tempfile::tempdir().unwrap();
    let curly = strands::read(&data("Curly_100.ply")).unwrap();
    let path = dir.path().join("curly.usda");
    strands::write(&path, &curly).unwrap();
    let lines = usd_report(&path);
    assert_eq!(lines[0], "type linear");
    assert_eq!(lines[1], "curves 100 100 2528");
    assert_eq!(lines[2], "points 2528");
    assert_eq!(lines[3], "mpu 0.001");
    assert_eq!(lines[4], "up Y");
    assert_eq!(lines[5], "colors 2528 vertex");
    let extent_err: f64 = lines[6].strip_prefix("extent ").unwrap().parse().unwrap();
    assert!(
        extent_err < 1e-3,
        "stored extent differs from USD's by {extent_err}"
    );
    // USD hands back the very f32 values written.
    let pts: Vec<[f32; 3]> = lines[7..]
        .iter()
        .map(|l| {
            let v: Vec<f64> = l[2..].split(' ').map(|t| t.parse().unwrap()).collect();
            [v[0] as f32, v[1] as f32, v[2] as f32]
        })
        .collect();
    assert_eq!(
        bits(&StrandSet::new(pts, curly.counts.clone())).points,
        bits(&curly).points
    );

    // Options reach the stage metadata; a set without colours or thickness still opens.
    let bangs = strands::read(&data("Bangs_100.data")).unwrap();
    let path = dir.path().join("bangs.usda");
    let opts = UsdOptions {
        meters_per_unit: 0.01,
        up_axis: UpAxis::Z,
        default_width: 0.2,
        prim_name: "bangs".into(),
    };
    strands::write_usda(&path, &bangs, &opts).unwrap();
    let lines = usd_report(&path);
    assert_eq!(lines[1], "curves 100 100 1165");
    assert_eq!(lines[3], "mpu 0.01");
    assert_eq!(lines[4], "up Z");
    assert_eq!(lines[5], "colors none");
}

fn bad_file_msg(r: coif::error::Result<StrandSet>, path: &Path) -> String {
    match r {
        Err(Error::BadFile { path: p, msg }) => {
            assert_eq!(p, path);
            msg
        }
        other => panic!("expected BadFile for {}, got {other:?}", path.display()),
    }
}

#[test]
fn bad_files_are_named_errors() {
    let dir = tempfile::tempdir().unwrap();
    let put = |name: &str, b: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, b).unwrap();
        p
    };
    let mut hair = bytes("Bangs_100.hair");
    hair[3] = b'X';
    let p = put("magic.hair", &hair);
    assert!(bad_file_msg(strands::read(&p), &p).contains("magic"));

    let mut hair = bytes("Bangs_100.hair");
    hair[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    let p = put("points.hair", &hair);
    assert!(bad_file_msg(strands::read(&p), &p).contains("needing"));
    let mut hair = bytes("Bangs_100.hair");
    hair[4..8].copy_from_slice(&0u32.to_le_bytes());
    let p = put("zero.hair", &hair);
    assert!(bad_file_msg(strands::read(&p), &p).contains("zero strands"));

    let mut d = 1_000_000i32.to_le_bytes().to_vec();
    d.extend_from_slice(&[0; 64]);
    let p = put("count.data", &d);
    assert!(bad_file_msg(strands::read(&p), &p).contains("exceeds the file size"));
    let p = put("zero.data", &0i32.to_le_bytes());
    assert!(bad_file_msg(strands::read(&p), &p).contains("at least one strand"));
    let mut d = bytes("Bangs_100.data");
    d[8..12].copy_from_slice(&f32::NAN.to_le_bytes());
    let p = put("nan.data", &d);
    assert!(bad_file_msg(strands::read(&p), &p).contains("not finite"));

    let p = data("Bangs_head.ply");
    assert!(bad_file_msg(strands::read(&p), &p).contains("mesh"));
    for (name, text) in [
        ("noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"),
        ("type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n"),
        ("orphan.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n"),
        ("nofmt.ply", "ply\nelement vertex 1\nproperty float x\nend_header\n"),
        ("big.ply", "ply\nformat ascii 1.0\nelement vertex 99999999999\nproperty float x\nproperty float y\nproperty float z\nelement edge 0\nproperty int vertex1\nproperty int vertex2\nend_header\n1 2 3\n"),
        ("empty.ply", "ply\nformat ascii 1.0\nelement foo 99999999999\nelement edge 0\nend_header\n"),
    ] {
        let p = put(name, text.as_bytes());
        bad_file_msg(strands::read(&p), &p);
    }

    // Write-side errors name the output file too.
    let long = StrandSet::new(vec![[0.0; 3]; 65537], vec![65537]);
    let p = dir.path().join("long.hair");
    let e = strands::write(&p, &long).unwrap_err();
    assert!(
        matches!(&e, Error::BadFile { path, msg } if *path == p && msg.contains("65536")),
        "{e}"
    );
    assert!(!p.exists());
    // 65536 vertices (65535 segments) is the largest that fits.
    let max = StrandSet::new(vec![[0.0; 3]; 65536], vec![65536]);
    strands::write(&p, &max).unwrap();
    assert_eq!(strands::read(&p).unwrap().counts, [65536]);

    let mut nan = StrandSet::new(vec![[0.0; 3], [1.0, f32::INFINITY, 0.0]], vec![2]);
    for ext in ["hair", "data", "ply", "obj", "usda"] {
        let p = dir.path().join(format!("nan.{ext}"));
        assert!(
            matches!(strands::write(&p, &nan), Err(Error::BadFile { .. })),
            "{ext}"
        );
        assert!(matches!(
            strands::write(&p, &StrandSet::default()),
            Err(Error::BadFile { .. })
        ));
    }
    nan.points[1][1] = 1.0;
    strands::write(&dir.path().join("ok.obj"), &nan).unwrap();

    // A name without a strand extension (a pipe has none) is told by content.
    let p = dir.path().join("x.txt");
    std::fs::write(&p, b"neither HAIR, ply, OBJ nor .data").unwrap();
    assert!(bad_file_msg(strands::read(&p), &p).contains("cannot tell the strand format"));
    std::fs::copy(dir.path().join("ok.obj"), &p).unwrap();
    assert_eq!(strands::read(&p).unwrap().counts, [2]);
    assert!(matches!(
        strands::read(&dir.path().join("missing.hair")),
        Err(Error::Io { .. })
    ));
    let p = dir.path().join("x.usda");
    strands::write(&p, &nan).unwrap();
    assert!(bad_file_msg(strands::read(&p), &p).contains("not supported"));
}

/// Tiny xorshift so the random inputs are the same on every run.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
}

#[test]
fn truncated_and_random_input_is_an_error_not_a_panic() {
    let name = Path::new("fuzz");
    for (file, format) in [
        ("Bangs_100.hair", Format::Hair),
        ("Bangs_100.data", Format::Data),
        ("Bangs_100_ascii.ply", Format::Ply),
        ("Curly_100.ply", Format::Ply),
        ("Bangs_head.ply", Format::Ply),
    ] {
        let b = bytes(file);
        let full_ok = strands::decode(&b, format, name).is_ok();
        let cuts = (0..b.len().min(2048))
            .chain((2048..b.len()).step_by(61))
            .chain(b.len().saturating_sub(64)..b.len());
        for k in cuts {
            let r = strands::decode(&b[..k], format, name);
            // Dropping only trailing whitespace of an ascii file leaves a complete file.
            let only_ws_cut = b[k..].iter().all(u8::is_ascii_whitespace);
            assert!(
                r.is_err() || (full_ok && only_ws_cut),
                "{file} cut at {k} decoded"
            );
        }
    }

    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let prefixes: [&[u8]; 4] = [
        b"",
        b"HAIR",
        b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement edge 2\nproperty int vertex1\nproperty int vertex2\nend_header\n",
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement strand 1\nproperty uchar nsegs\nend_header\n",
    ];
    for round in 0..400 {
        let prefix = prefixes[round % prefixes.len()];
        let len = (rng.next() % 600) as usize;
        let mut b = prefix.to_vec();
        b.extend((0..len).map(|_| rng.next() as u8));
        for format in [Format::Hair, Format::Data, Format::Ply, Format::Obj] {
            assert!(
                strands::decode(&b, format, name).is_err(),
                "{format:?} accepted random bytes"
            );
        }
    }

    // Corrupted real files may decode or not, but must never panic.
    for (file, format) in [
        ("Bangs_100.hair", Format::Hair),
        ("Curly_100.ply", Format::Ply),
        ("Bangs_100.data", Format::Data),
    ] {
        let orig = bytes(file);
        for _ in 0..300 {
            let mut b = orig.clone();
            for _ in 0..1 + rng.next() % 4 {
                let at = (rng.next() % b.len() as u64) as usize;
                b[at] = rng.next() as u8;
            }
            let _ = strands::decode(&b, format, name);
        }
    }
}

#[test]
fn ply_edge_variant_and_big_endian() {
    let name = Path::new("edges.ply");
    // Strands stored out of order: 3→0→4 and 1→2, plus vertex 5 on no edge (an empty root).
    let text = "ply\r\nformat ascii 1.0\r\nelement vertex 6\r\nproperty float x\r\nproperty float y\r\nproperty float z\r\nproperty float red\r\nproperty float green\r\nproperty float blue\r\nelement edge 3\r\nproperty int vertex1\r\nproperty int vertex2\r\nend_header\r\n\
        0 0 0 0.5 0 0\n1 0 0 0 0.5 0\n2 0 0 0 0 0.5\n3 0 0 1 1 1\n4 0 0 0 0 0\n5 0 0 0.25 0.25 0.25\n0 4\n3 0\n1 2\n";
    let s = strands::decode(text.as_bytes(), Format::Ply, name).unwrap();
    assert_eq!(s.counts, [2, 3, 1]);
    let xs: Vec<f32> = s.points.iter().map(|p| p[0]).collect();
    assert_eq!(xs, [1.0, 2.0, 3.0, 0.0, 4.0, 5.0]);
    assert_eq!(s.colors.as_ref().unwrap()[2], [1.0, 1.0, 1.0]);
    assert_eq!(s.colors.as_ref().unwrap()[3], [0.5, 0.0, 0.0]);

    let bad = |edges: &str| {
        let t = text.replace(
            "3\r\nproperty int vertex1",
            &format!("{}\r\nproperty int vertex1", edges.lines().count()),
        );
        let t = t.replace("0 4\n3 0\n1 2\n", edges);
        strands::decode(t.as_bytes(), Format::Ply, name)
            .unwrap_err()
            .to_string()
    };
    assert!(bad("0 1\n0 2\n").contains("branching"));
    assert!(bad("0 2\n1 2\n").contains("merge"));
    assert!(bad("0 1\n1 2\n2 0\n").contains("cycle"));
    assert!(bad("0 9\n").contains("outside"));

    // The same two-strand shape as big-endian binary with ushort colours.
    let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty float y\nproperty float z\nproperty ushort red\nproperty ushort green\nproperty ushort blue\nelement edge 1\nproperty uint vertex1\nproperty uint vertex2\nend_header\n".to_vec();
    for i in 0..3u16 {
        b.extend_from_slice(&f64::from(i).to_be_bytes());
        b.extend_from_slice(&1.5f32.to_be_bytes());
        b.extend_from_slice(&(-2.0f32).to_be_bytes());
        for c in [65535u16, 0, 13107] {
            b.extend_from_slice(&c.to_be_bytes());
        }
    }
    b.extend_from_slice(&1u32.to_be_bytes());
    b.extend_from_slice(&2u32.to_be_bytes());
    let s = strands::decode(&b, Format::Ply, name).unwrap();
    assert_eq!(s.counts, [1, 2]);
    assert_eq!(
        s.points,
        [[0.0, 1.5, -2.0], [1.0, 1.5, -2.0], [2.0, 1.5, -2.0]]
    );
    assert_eq!(s.colors.unwrap()[0], [1.0, 0.0, 0.2]);

    // The strand variant's edges must agree with its nsegs.
    let t = std::fs::read_to_string(data("Bangs_100_ascii.ply")).unwrap();
    let t = t.replacen("\n0 1\n", "\n0 2\n", 1);
    assert!(strands::decode(t.as_bytes(), Format::Ply, name)
        .unwrap_err()
        .to_string()
        .contains("do not match"));
}

#[test]
fn obj_polylines() {
    let text =
        "# comment\no hair\nv 0 0 0\nv 1 0 0\nv 2 0 0\nvt 0 0\nl 1/1 2/1\nv 3 0 0\nl -2 -1\nl 2\n";
    let s = strands::decode(text.as_bytes(), Format::Obj, Path::new("a.obj")).unwrap();
    assert_eq!(s.counts, [2, 2, 1]);
    assert_eq!(
        s.points.iter().map(|p| p[0]).collect::<Vec<_>>(),
        [0.0, 1.0, 2.0, 3.0, 1.0]
    );
    assert!(s.colors.is_none());
    for bad in [
        "v 0 0 0\n",
        "v 0 0 0\nl 2\n",
        "v 0 0 0\nl 0\n",
        "v 0 0\nl 1\n",
        "v 0 0 0\nl\n",
    ] {
        assert!(
            strands::decode(bad.as_bytes(), Format::Obj, Path::new("b.obj")).is_err(),
            "{bad:?}"
        );
    }
}

#[test]
fn one_vertex_strands_survive_every_format() {
    let mut s = StrandSet::new(
        vec![
            [1.0, 2.0, 3.0],
            [4.0, 5.0, 6.0],
            [7.0, 8.0, 9.0],
            [-1.0, -0.0, 0.5],
        ],
        vec![1, 2, 1],
    );
    s.colors = Some(vec![
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
    ]);
    let dir = tempfile::tempdir().unwrap();
    for out in ["hair", "data", "ply", "ascii.ply", "obj", "usda"] {
        let path = dir.path().join(format!("roots.{out}"));
        if out == "ascii.ply" {
            strands::write_ply_ascii(&path, &s).unwrap();
        } else {
            strands::write(&path, &s).unwrap();
        }
        let back = read_back(&path);
        assert_eq!(back.counts, s.counts, "{out}");
        assert_eq!(bits(&back).points, bits(&s).points, "{out}");
        if out != "data" {
            assert_eq!(back.colors, s.colors, "{out}");
        }
    }
    let raw = std::fs::read(dir.path().join("roots.data")).unwrap();
    assert_eq!(raw.len(), 4 + 3 * 4 + 4 * 12);
    assert_eq!(le_u32(&raw, 4), 1);
}

#[test]
fn strand_access_validation_and_bounds() {
    let mut s = StrandSet::new(
        vec![[0.0, 1.0, 2.0], [3.0, -1.0, 5.0], [1.0, 1.0, 1.0]],
        vec![2, 1],
    );
    assert_eq!(s.strand(1), &[[1.0, 1.0, 1.0]]);
    assert_eq!(s.strands().map(<[_]>::len).collect::<Vec<_>>(), [2, 1]);
    assert_eq!(s.bounds(), ([0.0, -1.0, 1.0], [3.0, 1.0, 5.0]));
    s.validate().unwrap();
    s.thickness = Some(vec![1.0; 2]);
    assert!(s
        .validate()
        .unwrap_err()
        .to_string()
        .contains("thickness has 2 values"));
    s.thickness = Some(vec![1.0, f32::NAN, 1.0]);
    assert!(s.validate().is_err());
    s.thickness = None;
    s.counts = vec![2, 2];
    assert!(s.validate().unwrap_err().to_string().contains("sum to 4"));
    s.counts = vec![3, 0];
    assert!(s
        .validate()
        .unwrap_err()
        .to_string()
        .contains("no vertices"));
    assert!(StrandSet::default().validate().is_err());
    assert_eq!(Format::from_path(Path::new("A.PLY")).unwrap(), Format::Ply);
    assert_eq!(
        Format::from_path(Path::new("x.usda")).unwrap().extension(),
        "usda"
    );
}
