//! Shared test fixtures.

pub mod procs;

use coif::analyze::orient::GrayImage;
use coif::gpu::engine::{BackendChoice, Engine};

/// The lavapipe (or any) GPU engine. Parity and golden tests need it: without an adapter they
/// fail and say how to get one, rather than pass without checking anything.
pub fn gpu() -> Engine {
    Engine::new(BackendChoice::Gpu).unwrap_or_else(|e| {
        panic!("{e}\nthe GPU tests need a Vulkan adapter: apt-get install mesa-vulkan-drivers")
    })
}

/// Deterministic hash noise in [0, 1).
pub fn hash01(i: u64, seed: u64) -> f32 {
    let mut z = i.wrapping_add(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 40) as f32 / (1u64 << 24) as f32
}

/// A hair-like test texture: stripes with a slowly turning orientation plus noise.
pub fn texture(w: u32, h: u32, seed: u64) -> GrayImage {
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let a = 0.7 + 0.9 * (x / 97.0).sin() + 0.6 * (y / 71.0).cos() + seed as f32;
            let u = -x * a.sin() + y * a.cos();
            0.5 + 0.3 * (u * std::f32::consts::TAU / 4.3).sin()
                + 0.2 * (hash01(i as u64, seed) - 0.5)
        })
        .collect();
    GrayImage {
        width: w,
        height: h,
        data,
    }
}

/// A mask with a hole, so masked and unmasked pixels both occur.
pub fn mask(w: u32, h: u32) -> Vec<u8> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let (cx, cy) = (w as f32 * 0.3, h as f32 * 0.6);
            let r = 0.2 * w.min(h) as f32;
            ((x - cx).powi(2) + (y - cy).powi(2) > r * r) as u8
        })
        .collect()
}

/// A process's stderr as text.
pub fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Asserts a process failed with `code` whose message contains every needle.
pub fn fails(o: &std::process::Output, code: i32, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(code), "exit code; stderr:\n{e}");
    for n in needles {
        assert!(e.contains(n), "stderr lacks {n:?}:\n{e}");
    }
}

/// Asserts that `written` (a `mask_agreement.json`'s `agreement`, read back) holds the
/// figures of `want`: counts exactly, ratios to 1e-12 (the JSON reader may round the last
/// bit of a float).
pub fn assert_same_agreement(written: &serde_json::Value, want: &coif::eval::mask::MaskAgreement) {
    let want = serde_json::to_value(want).unwrap();
    let close = |a: &serde_json::Value, b: &serde_json::Value| match (a.as_f64(), b.as_f64()) {
        (Some(x), Some(y)) => (x - y).abs() <= 1e-12 * y.abs().max(1.0),
        _ => a == b,
    };
    let fields = want.as_object().unwrap();
    assert_eq!(
        written.as_object().map(|o| o.len()),
        Some(fields.len()),
        "{written}"
    );
    for (k, v) in fields {
        let w = &written[k];
        let same = match (v.as_array(), w.as_array()) {
            (Some(a), Some(b)) => a.len() == b.len() && a.iter().zip(b).all(|(p, q)| close(q, p)),
            _ => close(w, v),
        };
        assert!(same, "{k}: written {w}, computed {v}");
    }
}

/// The helper above passes written figures that are the computed ones up to the last bit,
/// and fails on any other figure.
#[test]
fn assert_same_agreement_tells_other_figures_apart() {
    let a = image::GrayImage::from_fn(20, 20, |x, _| image::Luma([255 * (x < 10) as u8]));
    let b = image::GrayImage::from_fn(20, 20, |x, _| image::Luma([255 * (x < 11) as u8]));
    let want = coif::eval::mask::agreement(&b, &a);
    let mut written = serde_json::to_value(&want).unwrap();
    let iou = written["iou"].as_f64().unwrap();
    written["iou"] = serde_json::json!(iou * (1.0 + 1e-15));
    assert_same_agreement(&written, &want);
    let other = serde_json::to_value(coif::eval::mask::agreement(&a, &a)).unwrap();
    let refused = std::panic::catch_unwind(|| assert_same_agreement(&other, &want));
    assert!(refused.is_err(), "the helper passed another mask's figures");
    written["taken"] = serde_json::json!(want.taken + 1);
    let refused = std::panic::catch_unwind(|| assert_same_agreement(&written, &want));
    assert!(refused.is_err(), "the helper passed a count off by one");
}
