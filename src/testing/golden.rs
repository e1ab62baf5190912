//! Golden images: a rendering against a reviewed PNG under `golden/`, failure images, blessing.

use crate::error::Error;
use crate::io::{ensure_dir, write_atomic, write_png};
use image::{Rgba, RgbaImage};
use std::fmt;
use std::path::{Path, PathBuf};

/// A channel may differ by this many levels (of 255) before its pixel counts as differing:
/// lavapipe and other drivers round by +-1 here and there, so bytes are never compared.
pub const GOLDEN_CHANNEL_TOL: u8 = 3;
/// At most this share of pixels may differ (0.1%).
pub const GOLDEN_MAX_DIFFERING_SHARE: f64 = 0.001;
/// Rounding slack forgiven per channel before the mean is taken (levels of 255).
pub const GOLDEN_ROUNDING_SLACK: u8 = 1;
/// Upper bound for the mean, over all channels, of `max(|a-b| - 1, 0)`, in levels of 255.
pub const GOLDEN_MAX_MEAN_EXCESS: f64 = 0.5;
/// Goldens are committed, so they must stay small: width and height at most this.
pub const GOLDEN_MAX_DIM: u32 = 512;
/// ... and the encoded PNG at most this many bytes (256 KiB).
pub const GOLDEN_MAX_PNG_BYTES: usize = 256 * 1024;
/// Gain applied to `|a-b|` in the diff image so rounding-sized differences are visible.
const DIFF_GAIN: u16 = 8;

/// Figures from a golden comparison. Differences are in levels of 255.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GoldenStats {
    pub width: u32,
    pub height: u32,
    /// Pixels with some channel differing by more than [`GOLDEN_CHANNEL_TOL`].
    pub differing_pixels: u64,
    /// `differing_pixels / (width * height)`, in `[0, 1]`.
    pub differing_share: f64,
    /// Mean of `|a-b|` over all channels (for information).
    pub mean_abs_diff: f64,
    /// Mean of `max(|a-b| - GOLDEN_ROUNDING_SLACK, 0)` over all channels (the tested figure).
    pub mean_excess_diff: f64,
    /// Largest channel difference anywhere.
    pub max_diff: u8,
    /// True when this call (re)wrote the golden because `COIF_BLESS=1`.
    pub blessed: bool,
}

impl GoldenStats {
    /// Whether these figures meet the metric.
    pub fn passes(&self) -> bool {
        self.differing_share <= GOLDEN_MAX_DIFFERING_SHARE
            && self.mean_excess_diff <= GOLDEN_MAX_MEAN_EXCESS
    }
}

impl fmt::Display for GoldenStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}x{}: {} pixels differ by > {}/255 = {:.4}% (limit {}%), \
             mean diff beyond rounding {:.3}/255 (limit {}/255), mean abs diff {:.3}/255, \
             max diff {}/255",
            self.width,
            self.height,
            self.differing_pixels,
            GOLDEN_CHANNEL_TOL,
            100.0 * self.differing_share,
            100.0 * GOLDEN_MAX_DIFFERING_SHARE,
            self.mean_excess_diff,
            GOLDEN_MAX_MEAN_EXCESS,
            self.mean_abs_diff,
            self.max_diff
        )
    }
}

/// Images written to the failure folder for inspection.
#[derive(Clone, Debug, PartialEq)]
pub struct FailureImages {
    pub actual: PathBuf,
    /// `None` when the golden is missing.
    pub expected: Option<PathBuf>,
    /// `None` when there is no golden or the sizes differ.
    pub diff: Option<PathBuf>,
}

impl fmt::Display for FailureImages {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "actual {}", self.actual.display())?;
        if let Some(p) = &self.expected {
            write!(f, ", expected {}", p.display())?;
        }
        if let Some(p) = &self.diff {
            write!(f, ", diff {}", p.display())?;
        }
        Ok(())
    }
}

/// Why a golden check failed. `images` holds the inspection images or why they could not be
/// written.
pub enum GoldenFailure {
    /// Names are restricted to `[A-Za-z0-9_-]` so they map to one file in the golden folder.
    BadName { name: String },
    Missing {
        path: PathBuf,
        images: Result<FailureImages, String>,
    },
    SizeMismatch {
        path: PathBuf,
        expected: (u32, u32),
        actual: (u32, u32),
        images: Result<FailureImages, String>,
    },
    Differs {
        path: PathBuf,
        stats: GoldenStats,
        images: Result<FailureImages, String>,
    },
    /// Blessing refused because the golden would be too large (or empty).
    BlessRefused { path: PathBuf, reason: String },
    /// Reading the golden or writing it failed.
    Io(Error),
}

fn fmt_images(f: &mut fmt::Formatter<'_>, images: &Result<FailureImages, String>) -> fmt::Result {
    match images {
        Ok(imgs) => write!(f, "; wrote {imgs}"),
        Err(e) => write!(f, "; could not write inspection images: {e}"),
    }
}

impl fmt::Display for GoldenFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GoldenFailure::BadName { name } => write!(
                f,
                "golden name {name:?} must be non-empty and use only A-Z a-z 0-9 _ -"
            ),
            GoldenFailure::Missing { path, images } => {
                write!(
                    f,
                    "golden image {} is missing; run `COIF_BLESS=1 cargo test ...` (the failing \
                     test) to write it, then review and commit it",
                    path.display()
                )?;
                fmt_images(f, images)
            }
            GoldenFailure::SizeMismatch {
                path,
                expected,
                actual,
                images,
            } => {
                write!(
                    f,
                    "golden {}: size mismatch, actual {}x{}, expected {}x{}",
                    path.display(),
                    actual.0,
                    actual.1,
                    expected.0,
                    expected.1
                )?;
                fmt_images(f, images)
            }
            GoldenFailure::Differs {
                path,
                stats,
                images,
            } => {
                write!(
                    f,
                    "golden {} differs: {stats}{}",
                    path.display(),
                    if stats.differing_share > GOLDEN_MAX_DIFFERING_SHARE {
                        " [too many differing pixels]"
                    } else {
                        " [mean difference too large]"
                    }
                )?;
                fmt_images(f, images)?;
                write!(
                    f,
                    "; if the change is intended, rerun with COIF_BLESS=1 and commit the golden"
                )
            }
            GoldenFailure::BlessRefused { path, reason } => {
                write!(f, "refusing to bless {}: {reason}", path.display())
            }
            GoldenFailure::Io(e) => write!(f, "golden check: {e}"),
        }
    }
}

impl fmt::Debug for GoldenFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

impl std::error::Error for GoldenFailure {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            GoldenFailure::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<Error> for GoldenFailure {
    fn from(e: Error) -> Self {
        GoldenFailure::Io(e)
    }
}

/// `<crate root>/golden`, where committed goldens live.
pub fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("golden")
}

/// `<CARGO_TARGET_DIR or <crate root>/target>/golden-failures`, where failing checks put their
/// inspection images (a relative `CARGO_TARGET_DIR` is taken from the crate root, where cargo
/// runs tests).
pub fn golden_failure_dir() -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let target = match std::env::var_os("CARGO_TARGET_DIR") {
        Some(t) if !t.is_empty() => root.join(t), // join keeps an absolute path as is
        _ => root.join("target"),
    };
    target.join("golden-failures")
}

/// True when `COIF_BLESS=1`: golden checks then write goldens instead of failing.
pub fn bless_requested() -> bool {
    std::env::var_os("COIF_BLESS").is_some_and(|v| v == "1")
}

/// [`check_golden_in`] with the committed golden folder, the target failure folder and
/// blessing from `COIF_BLESS`.
pub fn check_golden(name: &str, actual: &RgbaImage) -> Result<GoldenStats, GoldenFailure> {
    check_golden_in(
        &golden_dir(),
        &golden_failure_dir(),
        name,
        actual,
        bless_requested(),
    )
}

/// [`check_golden`] for an RGB image (compared as RGBA with opaque alpha).
pub fn check_golden_rgb(
    name: &str,
    actual: &image::RgbImage,
) -> Result<GoldenStats, GoldenFailure> {
    check_golden(name, &rgb_to_rgba(actual))
}

/// Converts to RGBA with alpha 255.
pub fn rgb_to_rgba(img: &image::RgbImage) -> RgbaImage {
    RgbaImage::from_fn(img.width(), img.height(), |x, y| {
        let [r, g, b] = img.get_pixel(x, y).0;
        Rgba([r, g, b, 255])
    })
}

/// Compares `actual` with `<golden_dir>/<name>.png`.
///
/// Metric (differences in levels of 255, all four channels):
/// * sizes must match exactly;
/// * a pixel *differs* when any channel differs by more than 3 ([`GOLDEN_CHANNEL_TOL`]), since
///   drivers (lavapipe included) round by +-1 here and there; bytes are never compared;
/// * the image passes when at most 0.1% of the pixels differ ([`GOLDEN_MAX_DIFFERING_SHARE`])
///   AND the mean over all channels of `max(|a-b| - 1, 0)` is at most 0.5
///   ([`GOLDEN_MAX_MEAN_EXCESS`]). One level of rounding is forgiven in the mean so +-1 jitter
///   costs nothing even where it covers the whole image, while a global shift of 2 or more
///   levels (wrong gamma, bias) fails although no single pixel reaches the per-pixel threshold.
///
/// With `bless` the golden is written (created, or replaced unless pixel-identical) atomically
/// and the check passes with `blessed = true`; blessing refuses images over 512x512 or PNGs
/// over 256 KiB. Without `bless` a missing golden fails. On failure `<name>.actual.png`,
/// `<name>.expected.png` and `<name>.diff.png` go to `failure_dir`; the diff shows `|a-b|*8`
/// per channel (alpha difference folded into all three), with differing pixels' red set to 255.
/// A pass deletes stale inspection images of the same name.
pub fn check_golden_in(
    golden_dir: &Path,
    failure_dir: &Path,
    name: &str,
    actual: &RgbaImage,
    bless: bool,
) -> Result<GoldenStats, GoldenFailure> {
    let valid = !name.is_empty()
        && name
            .bytes()
            .all(|c| c.is_ascii_alphanumeric() || c == b'_' || c == b'-');
    if !valid {
        return Err(GoldenFailure::BadName {
            name: name.to_string(),
        });
    }
    let path = golden_dir.join(format!("{name}.png"));
    let expected = read_golden(&path)?;

    if bless {
        return bless_golden(golden_dir, &path, actual, expected.as_ref());
    }

    let Some(expected) = expected else {
        let images = write_failure_images(failure_dir, name, actual, None);
        return Err(GoldenFailure::Missing { path, images });
    };
    if expected.dimensions() != actual.dimensions() {
        let images = write_failure_images(failure_dir, name, actual, Some(&expected));
        return Err(GoldenFailure::SizeMismatch {
            path,
            expected: expected.dimensions(),
            actual: actual.dimensions(),
            images,
        });
    }
    let stats = golden_stats(actual, &expected);
    if stats.passes() {
        remove_failure_images(failure_dir, name);
        Ok(stats)
    } else {
        let images = write_failure_images(failure_dir, name, actual, Some(&expected));
        Err(GoldenFailure::Differs {
            path,
            stats,
            images,
        })
    }
}

/// `Ok(None)` when the file does not exist; other read or decode problems are errors.
fn read_golden(path: &Path) -> Result<Option<RgbaImage>, GoldenFailure> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(path, e).into()),
    };
    let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
        .map_err(|e| Error::bad_file(path, format!("cannot decode golden PNG: {e}")))?;
    Ok(Some(img.to_rgba8()))
}

fn bless_golden(
    golden_dir: &Path,
    path: &Path,
    actual: &RgbaImage,
    old: Option<&RgbaImage>,
) -> Result<GoldenStats, GoldenFailure> {
    let (w, h) = actual.dimensions();
    let refuse = |reason: String| {
        Err(GoldenFailure::BlessRefused {
            path: path.to_path_buf(),
            reason,
        })
    };
    if w == 0 || h == 0 {
        return refuse(format!("the image is empty ({w}x{h})"));
    }
    if w > GOLDEN_MAX_DIM || h > GOLDEN_MAX_DIM {
        return refuse(format!(
            "{w}x{h} exceeds the {GOLDEN_MAX_DIM}x{GOLDEN_MAX_DIM} limit for committed goldens; \
             render the test at a smaller size"
        ));
    }
    let same_size_old = old.filter(|o| o.dimensions() == actual.dimensions());
    let mut stats = match same_size_old {
        Some(o) => golden_stats(actual, o),
        None => golden_stats(actual, actual),
    };
    stats.blessed = true;
    // Rewriting a pixel-identical golden would only churn the file's bytes in git.
    if same_size_old.is_some_and(|o| o.as_raw() == actual.as_raw()) {
        eprintln!("COIF_BLESS: golden {} unchanged", path.display());
        return Ok(stats);
    }
    let png = encode_png_small(actual).map_err(|e| Error::bad_file(path, e))?;
    if png.len() > GOLDEN_MAX_PNG_BYTES {
        return refuse(format!(
            "the PNG is {} bytes, over the {GOLDEN_MAX_PNG_BYTES}-byte limit for committed goldens; \
             use a smaller or simpler image",
            png.len()
        ));
    }
    ensure_dir(golden_dir)?;
    write_atomic(path, &png)?;
    let verb = if old.is_some() { "replaced" } else { "created" };
    eprintln!(
        "COIF_BLESS: {verb} golden {} ({w}x{h}, {} bytes)",
        path.display(),
        png.len()
    );
    Ok(stats)
}

/// PNG with the strongest compression: goldens are committed, so bytes count more than time.
fn encode_png_small(img: &RgbaImage) -> Result<Vec<u8>, String> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::ImageEncoder;
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, CompressionType::Best, FilterType::Adaptive)
        .write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            image::ExtendedColorType::Rgba8,
        )
        .map_err(|e| format!("cannot encode PNG: {e}"))?;
    Ok(out)
}

/// The metric's figures; the images must have equal sizes.
fn golden_stats(actual: &RgbaImage, expected: &RgbaImage) -> GoldenStats {
    debug_assert_eq!(actual.dimensions(), expected.dimensions());
    let (w, h) = actual.dimensions();
    let mut differing = 0u64;
    let mut sum_abs = 0u64;
    let mut sum_excess = 0u64;
    let mut max_diff = 0u8;
    for (a, e) in actual.pixels().zip(expected.pixels()) {
        let mut pixel_max = 0u8;
        for (ca, ce) in a.0.iter().zip(e.0.iter()) {
            let d = ca.abs_diff(*ce);
            pixel_max = pixel_max.max(d);
            sum_abs += d as u64;
            sum_excess += d.saturating_sub(GOLDEN_ROUNDING_SLACK) as u64;
        }
        max_diff = max_diff.max(pixel_max);
        if pixel_max > GOLDEN_CHANNEL_TOL {
            differing += 1;
        }
    }
    let pixels = w as u64 * h as u64;
    let channels = (pixels * 4).max(1) as f64;
    GoldenStats {
        width: w,
        height: h,
        differing_pixels: differing,
        differing_share: differing as f64 / pixels.max(1) as f64,
        mean_abs_diff: sum_abs as f64 / channels,
        mean_excess_diff: sum_excess as f64 / channels,
        max_diff,
        blessed: false,
    }
}

/// Amplified difference: `|a-b| * 8` per colour channel, the alpha difference folded into all
/// three; pixels over the per-pixel threshold get red = 255 so they stand out.
fn diff_image(actual: &RgbaImage, expected: &RgbaImage) -> RgbaImage {
    RgbaImage::from_fn(actual.width(), actual.height(), |x, y| {
        let (a, e) = (actual.get_pixel(x, y).0, expected.get_pixel(x, y).0);
        let d: [u8; 4] = std::array::from_fn(|c| a[c].abs_diff(e[c]));
        let amp = |v: u8| (v as u16 * DIFF_GAIN).min(255) as u8;
        let mut px = [
            amp(d[0].max(d[3])),
            amp(d[1].max(d[3])),
            amp(d[2].max(d[3])),
            255,
        ];
        if d.iter().any(|&v| v > GOLDEN_CHANNEL_TOL) {
            px[0] = 255;
        }
        Rgba(px)
    })
}

fn failure_paths(dir: &Path, name: &str) -> [PathBuf; 3] {
    ["actual", "expected", "diff"].map(|kind| dir.join(format!("{name}.{kind}.png")))
}

/// Writes what exists of actual / expected / diff; a stale file of a kind not written this
/// time is removed so the folder never mixes runs.
fn write_failure_images(
    dir: &Path,
    name: &str,
    actual: &RgbaImage,
    expected: Option<&RgbaImage>,
) -> Result<FailureImages, String> {
    let [actual_path, expected_path, diff_path] = failure_paths(dir, name);
    ensure_dir(dir).map_err(|e| e.to_string())?;
    write_png(&actual_path, actual).map_err(|e| e.to_string())?;
    let mut images = FailureImages {
        actual: actual_path,
        expected: None,
        diff: None,
    };
    match expected {
        Some(exp) => {
            write_png(&expected_path, exp).map_err(|e| e.to_string())?;
            images.expected = Some(expected_path);
        }
        None => {
            let _ = std::fs::remove_file(&expected_path);
        }
    }
    match expected.filter(|e| e.dimensions() == actual.dimensions()) {
        Some(exp) => {
            write_png(&diff_path, &diff_image(actual, exp)).map_err(|e| e.to_string())?;
            images.diff = Some(diff_path);
        }
        None => {
            let _ = std::fs::remove_file(&diff_path);
        }
    }
    Ok(images)
}

fn remove_failure_images(dir: &Path, name: &str) {
    for p in failure_paths(dir, name) {
        // Absent files are the common case; nothing else here is worth failing a passing test.
        let _ = std::fs::remove_file(p);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn picture(w: u32, h: u32) -> RgbaImage {
        RgbaImage::from_fn(w, h, |x, y| {
            Rgba([
                (x * 255 / w.max(1)) as u8,
                (y * 255 / h.max(1)) as u8,
                ((x ^ y) & 0xff) as u8 / 2 + 64,
                255,
            ])
        })
    }

    struct Dirs {
        _tmp: tempfile::TempDir,
        golden: PathBuf,
        failures: PathBuf,
    }

    fn dirs() -> Dirs {
        let tmp = tempfile::tempdir().unwrap();
        Dirs {
            golden: tmp.path().join("golden"),
            failures: tmp.path().join("failures"),
            _tmp: tmp,
        }
    }

    #[test]
    fn golden_missing_fails_then_bless_writes_then_passes() {
        let d = dirs();
        let img = picture(96, 64);
        let err = check_golden_in(&d.golden, &d.failures, "scene", &img, false).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, GoldenFailure::Missing { .. }), "{msg}");
        assert!(
            msg.contains("scene.png") && msg.contains("COIF_BLESS=1"),
            "{msg}"
        );
        assert!(!d.golden.join("scene.png").exists());
        assert!(d.failures.join("scene.actual.png").exists());

        let s = check_golden_in(&d.golden, &d.failures, "scene", &img, true).unwrap();
        assert!(s.blessed);
        let written = image::open(d.golden.join("scene.png")).unwrap().to_rgba8();
        assert_eq!(written, img);

        let s = check_golden_in(&d.golden, &d.failures, "scene", &img, false).unwrap();
        assert_eq!((s.differing_pixels, s.max_diff, s.blessed), (0, 0, false));
        // A pass clears the stale inspection image from the failed run.
        assert!(!d.failures.join("scene.actual.png").exists());
    }

    #[test]
    fn golden_tolerates_rounding_noise_everywhere() {
        let d = dirs();
        let img = picture(128, 80);
        check_golden_in(&d.golden, &d.failures, "noise", &img, true).unwrap();
        // +-1 on every colour channel of every pixel, as a driver's rounding might do.
        let mut noisy = img.clone();
        for (i, p) in noisy.pixels_mut().enumerate() {
            for c in 0..3 {
                p.0[c] = if (i + c) % 2 == 0 {
                    p.0[c].saturating_add(1)
                } else {
                    p.0[c].saturating_sub(1)
                };
            }
        }
        let s = check_golden_in(&d.golden, &d.failures, "noise", &noisy, false).unwrap();
        assert_eq!((s.differing_pixels, s.max_diff), (0, 1));
        assert!(s.mean_abs_diff > 0.5 && s.mean_excess_diff == 0.0, "{s}");
        // A global shift of 2 levels passes per pixel but fails the mean.
        let mut shifted = img.clone();
        for p in shifted.pixels_mut() {
            for c in 0..3 {
                p.0[c] = p.0[c].saturating_add(2);
            }
        }
        let err = check_golden_in(&d.golden, &d.failures, "noise", &shifted, false).unwrap_err();
        assert!(err.to_string().contains("mean difference"), "{err}");
    }

    #[test]
    fn golden_changed_block_fails_and_writes_images() {
        let d = dirs();
        let img = picture(200, 120);
        check_golden_in(&d.golden, &d.failures, "block", &img, true).unwrap();
        let mut changed = img.clone();
        for y in 30..70 {
            for x in 100..140 {
                changed.put_pixel(x, y, Rgba([255, 0, 0, 255]));
            }
        }
        let err = check_golden_in(&d.golden, &d.failures, "block", &changed, false).unwrap_err();
        let msg = err.to_string();
        let GoldenFailure::Differs { stats, images, .. } = &err else {
            panic!("expected Differs: {msg}");
        };
        assert_eq!(stats.differing_pixels, 1600, "{msg}");
        let images = images.as_ref().unwrap();
        let paths = [
            images.actual.clone(),
            images.expected.clone().unwrap(),
            images.diff.clone().unwrap(),
        ];
        for (p, suffix) in paths.iter().zip(["actual", "expected", "diff"]) {
            assert_eq!(*p, d.failures.join(format!("block.{suffix}.png")));
            assert!(p.exists(), "{} not written", p.display());
            assert!(msg.contains(&p.display().to_string()), "{msg}");
        }
        assert!(msg.contains("6.6667%") && msg.contains("max diff"), "{msg}");
        // The diff marks the block and stays dark outside it.
        let diff = image::open(&paths[2]).unwrap().to_rgba8();
        assert_eq!(diff.get_pixel(120, 50).0[0], 255);
        assert_eq!(diff.get_pixel(10, 10).0, [0, 0, 0, 255]);
        assert_eq!(image::open(&paths[0]).unwrap().to_rgba8(), changed);
        // The golden itself is untouched by a failing check.
        let golden = image::open(d.golden.join("block.png")).unwrap().to_rgba8();
        assert_eq!(golden, img);
    }

    #[test]
    fn golden_size_mismatch_fails() {
        let d = dirs();
        check_golden_in(&d.golden, &d.failures, "size", &picture(64, 64), true).unwrap();
        let err =
            check_golden_in(&d.golden, &d.failures, "size", &picture(64, 65), false).unwrap_err();
        assert!(matches!(err, GoldenFailure::SizeMismatch { .. }), "{err}");
        assert!(err.to_string().contains("64x65"), "{err}");
        assert!(d.failures.join("size.actual.png").exists());
        assert!(d.failures.join("size.expected.png").exists());
    }

    #[test]
    fn bless_replaces_and_refuses_oversized() {
        let d = dirs();
        check_golden_in(&d.golden, &d.failures, "re", &picture(32, 32), true).unwrap();
        let other = RgbaImage::from_pixel(40, 30, Rgba([9, 9, 9, 255]));
        check_golden_in(&d.golden, &d.failures, "re", &other, true).unwrap();
        check_golden_in(&d.golden, &d.failures, "re", &other, false).unwrap();

        let big = picture(513, 8);
        let err = check_golden_in(&d.golden, &d.failures, "big", &big, true).unwrap_err();
        assert!(matches!(err, GoldenFailure::BlessRefused { .. }), "{err}");
        assert!(err.to_string().contains("512x512"), "{err}");
        assert!(!d.golden.join("big.png").exists());

        // Incompressible noise at 512x512 is ~1 MiB of PNG: refused on bytes.
        let mut state = 0x1234_5678u32;
        let noise = RgbaImage::from_fn(512, 512, |_, _| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let [r, g, b, _] = state.to_le_bytes();
            Rgba([r, g, b, 255])
        });
        let err = check_golden_in(&d.golden, &d.failures, "noisy", &noise, true).unwrap_err();
        assert!(err.to_string().contains("bytes"), "{err}");
        assert!(!d.golden.join("noisy.png").exists());
    }

    #[test]
    fn golden_rejects_bad_names() {
        let d = dirs();
        for name in ["", "../escape", "a/b", "x.png"] {
            let err =
                check_golden_in(&d.golden, &d.failures, name, &picture(4, 4), true).unwrap_err();
            assert!(
                matches!(err, GoldenFailure::BadName { .. }),
                "{name}: {err}"
            );
        }
    }

    #[test]
    fn rgb_converts_with_opaque_alpha() {
        let rgb = image::RgbImage::from_pixel(3, 2, image::Rgb([1, 2, 3]));
        let rgba = rgb_to_rgba(&rgb);
        assert_eq!(rgba.get_pixel(2, 1).0, [1, 2, 3, 255]);
    }
}
