//! Validation before work (issue 18, Deliver 4 and the "Silent nonsense" and exit-code
//! defects of its Why): each test runs the real binary on an input that was accepted, or
//! refused with the wrong code, before the fix.

use crate::common;
use std::path::PathBuf;

use common::{fails, stderr};
use std::process::{Command, Output};

fn coif(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_coif"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("coif runs")
}

struct Case {
    dir: tempfile::TempDir,
}

impl Case {
    /// A synthetic portrait (`coif synth`): image.png, mask.png, strokes.json, landmarks.json.
    fn synth() -> Self {
        let c = Case {
            dir: tempfile::tempdir().unwrap(),
        };
        let o = coif(&[
            "synth",
            "--out",
            &c.s("case"),
            "--style",
            "sidepart",
            "--seed",
            "1",
            "--size",
            "160",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        c
    }
    fn p(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }
    fn s(&self, name: &str) -> String {
        self.p(name).display().to_string()
    }
    fn analyze(&self, strokes: &str, out: &str) -> Output {
        coif(&[
            "analyze",
            "--image",
            &self.s("case/image.png"),
            "--strokes",
            &self.s(strokes),
            "--mask",
            &self.s("case/mask.png"),
            "--out",
            &self.s(out),
            "--backend",
            "cpu",
        ])
    }
}

/// One good stroke from the synthetic case first, then `bad`, so the bad one is stroke 1.
fn strokes_with(c: &Case, bad: &[[f32; 2]]) -> String {
    let good: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(c.p("case/strokes.json")).unwrap()).unwrap();
    let first = good["strokes"][0].clone();
    serde_json::json!({"version": 1, "strokes": [first, {"kind": "direction", "points": bad}]})
        .to_string()
}

#[test]
fn degenerate_direction_strokes_are_refused_in_every_format() {
    let c = Case::synth();
    let equal = [[80.0, 40.0]; 3];
    std::fs::write(c.p("equal.json"), strokes_with(&c, &equal)).unwrap();
    // Half a pixel in all: no direction at the pixel grid's resolution.
    std::fs::write(
        c.p("short.json"),
        strokes_with(&c, &[[80.0, 40.0], [80.25, 40.0], [80.5, 40.0]]),
    )
    .unwrap();
    let labelme = serde_json::json!({
        "version": "5.0.1",
        "imageWidth": 160,
        "imageHeight": 160,
        "shapes": [
            {"label": "hair", "shape_type": "linestrip", "points": [[60, 30], [70, 60]]},
            {"label": "hair", "shape_type": "linestrip", "points": equal},
        ],
    });
    std::fs::write(c.p("labelme.json"), labelme.to_string()).unwrap();
    std::fs::write(
        c.p("s.svg"),
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="160" height="160">
             <polyline points="60,30 70,60"/><polyline points="80,40 80,40 80,40"/></svg>"#,
    )
    .unwrap();
    for (name, why) in [
        ("equal.json", "zero length"),
        ("short.json", "0.500 px"),
        ("labelme.json", "zero length"),
        ("s.svg", "zero length"),
    ] {
        let o = c.analyze(name, "an");
        fails(&o, 65, &[name, "stroke 1", "degenerate", why]);
        assert!(!c.p("an").exists(), "{name}: a refused run wrote output");
    }
    // The good stroke alone still runs: the check is on the stroke, not the file.
    let good: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(c.p("case/strokes.json")).unwrap()).unwrap();
    let one = serde_json::json!({"version": 1, "strokes": [good["strokes"][0]]});
    std::fs::write(c.p("one.json"), one.to_string()).unwrap();
    let o = c.analyze("one.json", "an");
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_png_given_as_strokes_is_a_bad_file() {
    let c = Case::synth();
    let o = c.analyze("case/image.png", "an");
    fails(&o, 65, &["image.png", "not UTF-8"]);
}

/// CRC-32 (ISO-HDLC, as PNG uses), bitwise.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

fn png_chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut body = kind.to_vec();
    body.extend(data);
    let mut out = (data.len() as u32).to_be_bytes().to_vec();
    out.extend(&body);
    out.extend(crc32(&body).to_be_bytes());
    out
}

/// An 8-bit RGB PNG that says it is `w` x `h` but holds one byte of pixel data: enough
/// for a reader of the header, and small however large it claims to be.
fn png_header(w: u32, h: u32) -> Vec<u8> {
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 2, 0, 0, 0]);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend(png_chunk(b"IHDR", &ihdr));
    // zlib's stream of the one byte 0.
    out.extend(png_chunk(b"IDAT", &[0x78, 0x9c, 0x63, 0, 0, 0, 1, 0, 1]));
    out.extend(png_chunk(b"IEND", &[]));
    out
}

#[test]
fn the_image_size_limit_counts_pixels() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926, "the CRC's check value");
    let c = Case::synth();
    std::fs::write(c.p("huge.png"), png_header(20_000, 20_000)).unwrap();
    let o = coif(&[
        "orient",
        "--image",
        &c.s("huge.png"),
        "--out",
        &c.s("o"),
        "--backend",
        "cpu",
    ]);
    fails(&o, 65, &["huge.png", "20000x20000", "400000000 pixels"]);
    assert!(!stderr(&o).contains("bytes"), "{}", stderr(&o));
}

#[test]
fn command_line_errors_exit_64_and_help_exits_0() {
    let c = Case::synth();
    // An unknown option, a missing required one, an unparsable number: clap's errors.
    for args in [
        vec!["orient", "--bogus"],
        vec!["orient", "--out", "o"],
        vec!["synth", "--out", "o", "--seed", "x"],
        vec!["no-such-command"],
    ] {
        let o = coif(&args);
        fails(&o, 64, &["error:"]);
    }
    for args in [vec!["--help"], vec!["orient", "--help"], vec!["--version"]] {
        let o = coif(&args);
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
        assert!(!o.stdout.is_empty(), "{args:?} printed nothing");
    }
    // A light that is not numbers is refused with a message, before the model is read.
    let o = coif(&[
        "render",
        "--model",
        &c.s("no-model"),
        "--out",
        &c.s("r.png"),
        "--light",
        "abc",
    ]);
    fails(&o, 64, &["--light", "abc"]);
}

/// Writes a `w` x `h` PNG of one colour.
fn solid_png(path: &std::path::Path, w: u32, h: u32, rgb: [u8; 3]) {
    image::RgbImage::from_pixel(w, h, image::Rgb(rgb))
        .save(path)
        .unwrap();
}

#[test]
fn a_segmentation_of_everything_as_hair_is_refused_by_every_command() {
    let c = Case::synth();
    // The synthetic case's strokes over a photo of one hair colour: no edge to find.
    solid_png(&c.p("solid.png"), 160, 160, [90, 60, 40]);
    let strokes = c.s("case/strokes.json");
    let image = c.s("solid.png");
    let runs: [Vec<&str>; 3] = [
        vec!["analyze", "--image", &image, "--strokes", &strokes],
        vec!["model", "--image", &image, "--strokes", &strokes],
        vec!["sketch", "--image", &image, "--strokes", &strokes],
    ];
    for args in runs {
        let out = c.s(&format!("out-{}", args[0]));
        let mut a = args.clone();
        a.extend(["--out", &out, "--backend", "cpu"]);
        let o = coif(&a);
        fails(&o, 64, &["100.0%", "as hair", "solid.png"]);
        assert!(!std::path::Path::new(&out).exists(), "{out} written");
    }
    // The same strokes on the real photo still segment.
    let o = coif(&[
        "analyze",
        "--image",
        &c.s("case/image.png"),
        "--strokes",
        &strokes,
        "--out",
        &c.s("an"),
        "--backend",
        "cpu",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_segmentation_of_nothing_beyond_the_strokes_is_refused() {
    let c = Case::synth();
    // Background strokes over the whole of a white image, one direction stroke on top: the
    // hair can be only the direction stroke's own pixels.
    solid_png(&c.p("white.png"), 64, 64, [255; 3]);
    let mut strokes: Vec<serde_json::Value> = (0..=64)
        .step_by(6)
        .map(|y| {
            let y = (y as f32 + 0.5).min(63.5);
            serde_json::json!({"kind": "background", "points": [[0, y], [64, y]]})
        })
        .collect();
    strokes.push(serde_json::json!({"kind": "direction", "points": [[10, 32], [50, 32]]}));
    let doc = serde_json::json!({"version": 1, "strokes": strokes});
    std::fs::write(c.p("s.json"), doc.to_string()).unwrap();
    let o = coif(&[
        "analyze",
        "--image",
        &c.s("white.png"),
        "--strokes",
        &c.s("s.json"),
        "--out",
        &c.s("an"),
        "--backend",
        "cpu",
    ]);
    fails(&o, 64, &["no hair", "beyond", "white.png"]);
    assert!(!c.p("an").exists());
}

/// The file's first bytes name its encoding: PNG or JPEG (SOI marker).
fn encoding(path: &std::path::Path) -> &'static str {
    let b = std::fs::read(path).unwrap();
    if b.starts_with(b"\x89PNG") {
        "png"
    } else if b.starts_with(&[0xFF, 0xD8, 0xFF]) {
        "jpeg"
    } else {
        "other"
    }
}

#[test]
fn render_refuses_outputs_over_the_model_and_writes_jpeg_as_asked() {
    let c = Case::synth();
    let o = coif(&[
        "model",
        "--image",
        &c.s("case/image.png"),
        "--strokes",
        &c.s("case/strokes.json"),
        "--landmarks",
        &c.s("case/landmarks.json"),
        "--out",
        &c.s("m"),
        "--backend",
        "cpu",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let render = |out: &str, extra: &[&str]| {
        let mut a = vec!["render", "--model", "m", "--out", out, "--backend", "cpu"];
        a.extend(extra);
        Command::new(env!("CARGO_BIN_EXE_coif"))
            .args(&a)
            .current_dir(c.dir.path())
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap()
    };
    let model_files = ["strands.hair", "model.json", "photo.png", "mask.png"];
    let before: Vec<Vec<u8>> = model_files
        .iter()
        .map(|f| std::fs::read(c.p("m").join(f)).unwrap())
        .collect();
    // Every file the model is read from, also by another spelling of the path.
    for f in model_files {
        fails(&render(&format!("m/{f}"), &[]), 64, &[f, "overwrite", "m"]);
    }
    fails(&render("./m/../m/photo.png", &[]), 64, &["overwrite"]);
    fails(
        &render("r.tiff", &[]),
        64,
        &["r.tiff", "\".tiff\"", ".png or .jpg"],
    );
    fails(&render("r.jpg", &["--16bit"]), 64, &["r.jpg", "16-bit"]);
    fails(
        &render("nowhere/r.png", &[]),
        74,
        &["nowhere", "does not exist"],
    );
    for (f, b) in model_files.iter().zip(&before) {
        assert_eq!(&std::fs::read(c.p("m").join(f)).unwrap(), b, "{f} changed");
    }
    // .jpg is JPEG, .png PNG, a picture beside the model's files is fine.
    for (out, enc) in [
        ("r.jpg", "jpeg"),
        ("R.JPEG", "jpeg"),
        ("m/render.png", "png"),
    ] {
        let o = render(out, &[]);
        assert!(o.status.success(), "{out}: {}", stderr(&o));
        assert_eq!(encoding(&c.p(out)), enc, "{out}");
        let img = image::open(c.p(out)).unwrap();
        assert_eq!((img.width(), img.height()), (160, 160));
    }
    let side: serde_json::Value =
        serde_json::from_slice(&std::fs::read(c.p("r.jpg.json")).unwrap()).unwrap();
    assert_eq!(side["encoding"], "8-bit sRGB JPEG");
}

#[test]
fn pictures_of_a_sketch_refuse_to_overwrite_their_inputs() {
    let c = Case::synth();
    let o = coif(&[
        "sketch",
        "--image",
        &c.s("case/image.png"),
        "--mask",
        &c.s("case/mask.png"),
        "--out",
        &c.s("sk"),
        "--backend",
        "cpu",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let photo = std::fs::read(c.p("case/image.png")).unwrap();
    let sketch = c.s("sk/hair.czs");
    let over = c.s("case/image.png");
    for cmd in ["synth-hair", "cartoon"] {
        let run = |out: &str| {
            coif(&[
                cmd,
                "--sketch",
                &sketch,
                "--over",
                &over,
                "--out",
                out,
                "--backend",
                "cpu",
            ])
        };
        fails(&run(&over), 64, &["overwrite", "image.png"]);
        assert_eq!(
            std::fs::read(c.p("case/image.png")).unwrap(),
            photo,
            "{cmd}"
        );
        let types = if cmd == "cartoon" {
            ".png, .jpg or .svg"
        } else {
            ".png or .jpg"
        };
        fails(&run(&c.s("x.tiff")), 64, &["x.tiff", types]);
        let out = c.s(&format!("{cmd}.jpg"));
        let o = run(&out);
        assert!(o.status.success(), "{cmd}: {}", stderr(&o));
        assert_eq!(encoding(std::path::Path::new(&out)), "jpeg", "{cmd}");
    }
}
