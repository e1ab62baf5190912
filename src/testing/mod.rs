//! Test harnesses shared by the integration tests in `tests/*.rs`:
//!
//! * **Parity**: every GPU compute pass has a CPU mirror; [`compare_f32`] and friends compare the
//!   GPU output (`actual`) with the CPU mirror (`expected`) element by element and, on failure,
//!   say which buffer, how many elements, and the first and worst offenders with both values.
//!   [`SENTINEL_F32`] / [`assert_no_sentinel`] prove a pass wrote every output element, and
//!   [`PARITY_SIZES`] lists dispatch sizes that straddle workgroup boundaries.
//! * **Golden images**: [`check_golden`] compares a rendered image with a reviewed PNG under
//!   `golden/` using a tolerant metric (see [`check_golden_in`]), writes actual/expected/diff
//!   images on failure, and (re)writes goldens only when `COIF_BLESS=1`.
//!
//! The error types print readable messages from both `Display` and `Debug`, so
//! `.unwrap()` / `.expect()` in a test shows the diagnosis rather than a struct dump.

// The error types carry the whole diagnosis (values, figures, paths) so tests can match on
// them; they only travel on the failure path of a test, where their size costs nothing.
#![allow(clippy::result_large_err)]

use crate::error::Error;
use crate::io::{ensure_dir, write_atomic, write_png};
use image::{Rgba, RgbaImage};
use std::fmt;
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------------
// Parity comparison
// ---------------------------------------------------------------------------------------------

/// Dispatch sizes for parity tests: a 1x1 (degenerate dispatch), odd sizes either side of 64
/// (partial workgroups in both directions), a non-square (catches swapped width/height) and a
/// large square (many workgroups, exercises bounds checks at scale).
pub const PARITY_SIZES: &[(u32, u32)] = &[(1, 1), (63, 65), (200, 120), (512, 512)];

/// Bit pattern of [`SENTINEL_F32`]; see [`crate::base::sentinel`].
pub use crate::base::sentinel::SENTINEL as SENTINEL_BITS;
/// Fill value for GPU output buffers before a pass runs; see [`assert_no_sentinel`].
pub use crate::base::sentinel::SENTINEL_F32;

/// A buffer of `len` sentinels, to upload as the initial content of an output buffer.
pub fn sentinel_vec(len: usize) -> Vec<f32> {
    vec![SENTINEL_F32; len]
}

/// Element `i` passes when `|actual - expected| <= atol + rtol * |expected|`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    pub atol: f32,
    pub rtol: f32,
}

impl Tolerance {
    /// Bit-for-bit equality (apart from `-0.0 == 0.0`).
    pub const EXACT: Tolerance = Tolerance {
        atol: 0.0,
        rtol: 0.0,
    };

    pub const fn new(atol: f32, rtol: f32) -> Self {
        Tolerance { atol, rtol }
    }

    /// Absolute tolerance only.
    pub const fn abs(atol: f32) -> Self {
        Tolerance { atol, rtol: 0.0 }
    }
}

/// Figures from a comparison that passed (a fraction comparison may still have `failing > 0`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompareStats {
    /// Elements compared.
    pub count: usize,
    /// Elements outside tolerance (only non-zero for the `*_fraction` / angle comparators).
    pub failing: usize,
    /// Largest `|actual - expected|` (for angles: the circular difference in radians).
    pub max_abs: f64,
    /// Largest `|actual - expected| / |expected|` over elements whose expected value is
    /// non-zero (the ratio is undefined at zero; `max_abs` covers those). 0 for angles.
    pub max_rel: f64,
}

impl fmt::Display for CompareStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} elements, {} outside tolerance, max abs error {:.3e}, max rel error {:.3e}",
            self.count, self.failing, self.max_abs, self.max_rel
        )
    }
}

/// One element value, kept in its own type so messages print it exactly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scalar {
    F32(f32),
    U32(u32),
}

impl fmt::Display for Scalar {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            // NaN payloads matter here (sentinel vs canonical NaN), so print the bits.
            Scalar::F32(v) if v.is_nan() => write!(f, "NaN(0x{:08x})", v.to_bits()),
            Scalar::F32(v) => write!(f, "{v:?}"),
            Scalar::U32(v) => write!(f, "{v}"),
        }
    }
}

/// An element named in a [`Mismatch`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Element {
    pub index: usize,
    pub actual: Scalar,
    pub expected: Scalar,
    /// The error measure the comparator used (abs diff, circular diff; infinite for NaN).
    pub error: f64,
}

impl fmt::Display for Element {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "index {}: actual {}, expected {} (error {:.3e})",
            self.index, self.actual, self.expected, self.error
        )
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum MismatchKind {
    /// The buffers differ in length; nothing else was compared.
    Length { actual: usize, expected: usize },
    /// Too many elements outside tolerance, or a NaN against a number.
    Values {
        total: usize,
        failing: usize,
        /// Of `failing`, how many are NaN against a number (these fail whatever the fraction).
        nan_failing: usize,
        /// The pass criterion in words, e.g. `|a-b| <= 1e-5 + 1e-4*|expected|, all elements`.
        criterion: String,
        first: Element,
        /// Largest error among the failing elements (first one on ties).
        worst: Element,
    },
    /// Elements still hold [`SENTINEL_F32`]: the pass never wrote them.
    Sentinel {
        total: usize,
        count: usize,
        first: usize,
    },
}

/// Why a parity comparison failed. Prints the buffer name and the figures.
#[derive(Clone, PartialEq)]
pub struct Mismatch {
    pub buffer: String,
    pub kind: MismatchKind,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "buffer `{}`: ", self.buffer)?;
        match &self.kind {
            MismatchKind::Length { actual, expected } => write!(
                f,
                "length mismatch: actual has {actual} elements, expected {expected}"
            ),
            MismatchKind::Values {
                total,
                failing,
                nan_failing,
                criterion,
                first,
                worst,
            } => {
                let pct = 100.0 * *failing as f64 / (*total).max(1) as f64;
                write!(
                    f,
                    "{failing} of {total} elements ({pct:.3}%) fail [{criterion}]"
                )?;
                if *nan_failing > 0 {
                    write!(
                        f,
                        "; {nan_failing} of them are NaN against a number (always fatal)"
                    )?;
                }
                write!(f, "; first failing {first}; worst {worst}")
            }
            MismatchKind::Sentinel {
                total,
                count,
                first,
            } => write!(
                f,
                "{count} of {total} elements still hold the sentinel NaN(0x{SENTINEL_BITS:08x}), \
                 first at index {first}: the pass did not write them"
            ),
        }
    }
}

// Debug = Display so `.unwrap()` in a test prints the diagnosis.
impl fmt::Debug for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

impl std::error::Error for Mismatch {}

/// The verdict on one element pair.
struct Judged {
    ok: bool,
    /// NaN against a number (or an infinite angle): fails regardless of the allowed fraction.
    fatal: bool,
    /// Error measure; `INFINITY` when not measurable.
    abs: f64,
    /// Relative error, `None` where undefined (expected zero, angles, NaN pairs).
    rel: Option<f64>,
}

/// The shared loop: judge every element, gather stats, remember first and worst failures.
/// `min_fraction = None` means every element must pass.
fn compare_core(
    buffer: &str,
    len: usize,
    min_fraction: Option<f64>,
    criterion: impl FnOnce() -> String,
    judge: impl Fn(usize) -> Judged,
    values: impl Fn(usize) -> (Scalar, Scalar),
) -> Result<CompareStats, Mismatch> {
    let mut stats = CompareStats {
        count: len,
        ..CompareStats::default()
    };
    let mut fatal = 0usize;
    let mut first: Option<(usize, f64)> = None;
    let mut worst: Option<(usize, f64)> = None;
    for i in 0..len {
        let j = judge(i);
        if j.abs.is_finite() {
            stats.max_abs = stats.max_abs.max(j.abs);
        }
        if let Some(r) = j.rel.filter(|r| r.is_finite()) {
            stats.max_rel = stats.max_rel.max(r);
        }
        if j.ok {
            continue;
        }
        stats.failing += 1;
        if j.fatal {
            fatal += 1;
        }
        // NaN errors never compare greater, so map them to infinity to rank them worst.
        let err = if j.abs.is_nan() { f64::INFINITY } else { j.abs };
        first.get_or_insert((i, err));
        if worst.is_none_or(|(_, w)| err > w) {
            worst = Some((i, err));
        }
    }
    let passed = match min_fraction {
        None => stats.failing == 0,
        Some(frac) => {
            let ok = (len - stats.failing) as f64;
            // The small slack keeps e.g. 0.999 * 1000 from demanding 999.0000000001 elements.
            fatal == 0 && ok >= frac * len as f64 - 1e-9 * len as f64
        }
    };
    if passed {
        return Ok(stats);
    }
    let element = |(index, error): (usize, f64)| {
        let (actual, expected) = values(index);
        Element {
            index,
            actual,
            expected,
            error,
        }
    };
    // `passed` is false only when something failed, so both are set.
    let (first, worst) = (first.expect("a failure"), worst.expect("a failure"));
    let fraction_words = match min_fraction {
        None => "all elements".to_string(),
        Some(frac) => format!(">= {}% of elements", 100.0 * frac),
    };
    Err(Mismatch {
        buffer: buffer.to_string(),
        kind: MismatchKind::Values {
            total: len,
            failing: stats.failing,
            nan_failing: fatal,
            criterion: format!("{}, {fraction_words}", criterion()),
            first: element(first),
            worst: element(worst),
        },
    })
}

fn check_len(buffer: &str, actual: usize, expected: usize) -> Result<(), Mismatch> {
    if actual == expected {
        Ok(())
    } else {
        Err(Mismatch {
            buffer: buffer.to_string(),
            kind: MismatchKind::Length { actual, expected },
        })
    }
}

fn judge_f32(a: f32, b: f32, tol: Tolerance, nan_eq: bool) -> Judged {
    if a.is_nan() || b.is_nan() {
        let both = a.is_nan() && b.is_nan();
        let ok = both && nan_eq;
        return Judged {
            ok,
            fatal: !ok,
            abs: if ok { 0.0 } else { f64::INFINITY },
            rel: None,
        };
    }
    if a == b {
        // Also covers equal infinities, whose difference would be NaN.
        return Judged {
            ok: true,
            fatal: false,
            abs: 0.0,
            rel: Some(0.0),
        };
    }
    // f64 so the test itself adds no rounding at the tolerance boundary.
    let (a, b) = (a as f64, b as f64);
    let d = (a - b).abs();
    let allowed = tol.atol as f64 + tol.rtol as f64 * b.abs();
    Judged {
        ok: d <= allowed,
        fatal: false,
        abs: d,
        rel: (b != 0.0).then(|| d / b.abs()),
    }
}

fn tol_words(tol: Tolerance, nan_eq: bool) -> String {
    format!(
        "|a-b| <= {:e} + {:e}*|expected|{}",
        tol.atol,
        tol.rtol,
        if nan_eq { ", NaN==NaN allowed" } else { "" }
    )
}

fn compare_f32_impl(
    buffer: &str,
    actual: &[f32],
    expected: &[f32],
    tol: Tolerance,
    min_fraction: Option<f64>,
    nan_eq: bool,
) -> Result<CompareStats, Mismatch> {
    check_len(buffer, actual.len(), expected.len())?;
    if let Some(frac) = min_fraction {
        assert!(
            (0.0..=1.0).contains(&frac),
            "min_fraction_ok must lie in [0, 1], got {frac}"
        );
    }
    compare_core(
        buffer,
        actual.len(),
        min_fraction,
        || tol_words(tol, nan_eq),
        |i| judge_f32(actual[i], expected[i], tol, nan_eq),
        |i| (Scalar::F32(actual[i]), Scalar::F32(expected[i])),
    )
}

/// Every element must satisfy `|a-b| <= atol + rtol*|expected|`. A NaN on either side fails
/// (including NaN against NaN; see [`compare_f32_nan_eq`]); equal infinities pass; different
/// lengths fail. `actual` is the GPU output, `expected` the CPU mirror.
pub fn compare_f32(
    buffer: &str,
    actual: &[f32],
    expected: &[f32],
    tol: Tolerance,
) -> Result<CompareStats, Mismatch> {
    compare_f32_impl(buffer, actual, expected, tol, None, false)
}

/// As [`compare_f32`], but NaN against NaN passes: for masked outputs where both sides write
/// NaN outside the mask. NaN against a number still fails.
pub fn compare_f32_nan_eq(
    buffer: &str,
    actual: &[f32],
    expected: &[f32],
    tol: Tolerance,
) -> Result<CompareStats, Mismatch> {
    compare_f32_impl(buffer, actual, expected, tol, None, true)
}

/// Passes when at least `min_fraction_ok` (in `[0, 1]`, e.g. `0.999`) of the elements are within
/// tolerance; for outputs where a few elements may legitimately flip (ties, thresholds). A NaN
/// against anything still fails outright. Panics if `min_fraction_ok` is outside `[0, 1]`.
pub fn compare_f32_fraction(
    buffer: &str,
    actual: &[f32],
    expected: &[f32],
    tol: Tolerance,
    min_fraction_ok: f64,
) -> Result<CompareStats, Mismatch> {
    compare_f32_impl(buffer, actual, expected, tol, Some(min_fraction_ok), false)
}

/// As [`compare_f32_fraction`], but NaN against NaN passes (masked outputs).
pub fn compare_f32_fraction_nan_eq(
    buffer: &str,
    actual: &[f32],
    expected: &[f32],
    tol: Tolerance,
    min_fraction_ok: f64,
) -> Result<CompareStats, Mismatch> {
    compare_f32_impl(buffer, actual, expected, tol, Some(min_fraction_ok), true)
}

/// Undirected angles (orientations): the difference is taken modulo pi and circularly, so `0`
/// and `pi - 1e-6` are 1e-6 apart. NaN against NaN passes (masked pixels); NaN against a
/// number, or an infinite angle, fails outright. Passes when at least `min_fraction_ok` of the
/// elements are within `tol_rad`. Stats report the circular difference as `max_abs`.
/// Panics if `min_fraction_ok` is outside `[0, 1]`.
pub fn compare_angles_mod_pi(
    buffer: &str,
    actual: &[f32],
    expected: &[f32],
    tol_rad: f32,
    min_fraction_ok: f64,
) -> Result<CompareStats, Mismatch> {
    use std::f64::consts::PI;
    check_len(buffer, actual.len(), expected.len())?;
    assert!(
        (0.0..=1.0).contains(&min_fraction_ok),
        "min_fraction_ok must lie in [0, 1], got {min_fraction_ok}"
    );
    let judge = |i: usize| {
        let (a, b) = (actual[i], expected[i]);
        if a.is_nan() && b.is_nan() {
            return Judged {
                ok: true,
                fatal: false,
                abs: 0.0,
                rel: None,
            };
        }
        // NaN against a number, or infinities (which have no angle), cannot be measured.
        if !a.is_finite() || !b.is_finite() {
            return Judged {
                ok: false,
                fatal: true,
                abs: f64::INFINITY,
                rel: None,
            };
        }
        let d = (a as f64 - b as f64).rem_euclid(PI);
        let d = d.min(PI - d);
        Judged {
            ok: d <= tol_rad as f64,
            fatal: false,
            abs: d,
            rel: None,
        }
    };
    compare_core(
        buffer,
        actual.len(),
        Some(min_fraction_ok),
        || {
            format!(
                "circular |a-b| mod pi <= {tol_rad:e} rad ({:.3} deg), NaN==NaN allowed",
                (tol_rad as f64).to_degrees()
            )
        },
        judge,
        |i| (Scalar::F32(actual[i]), Scalar::F32(expected[i])),
    )
}

/// Every element must be equal (labels, counts, indices).
pub fn compare_u32_exact(
    buffer: &str,
    actual: &[u32],
    expected: &[u32],
) -> Result<CompareStats, Mismatch> {
    check_len(buffer, actual.len(), expected.len())?;
    compare_core(
        buffer,
        actual.len(),
        None,
        || "exact equality".to_string(),
        |i| {
            let (a, b) = (actual[i], expected[i]);
            Judged {
                ok: a == b,
                fatal: false,
                abs: a.abs_diff(b) as f64,
                rel: (b != 0).then(|| a.abs_diff(b) as f64 / b as f64),
            }
        },
        |i| (Scalar::U32(actual[i]), Scalar::U32(expected[i])),
    )
}

/// Fails if any element still has the [`SENTINEL_BITS`] pattern, naming the first such index.
/// Compares bits because NaN != NaN. Fill the output buffer with [`sentinel_vec`] (or the bits)
/// before the dispatch, read it back, and call this before the value comparison.
pub fn assert_no_sentinel(buffer: &str, data: &[f32]) -> Result<(), Mismatch> {
    let mut hits = data
        .iter()
        .enumerate()
        .filter(|(_, v)| v.to_bits() == SENTINEL_BITS)
        .map(|(i, _)| i);
    let Some(first) = hits.next() else {
        return Ok(());
    };
    Err(Mismatch {
        buffer: buffer.to_string(),
        kind: MismatchKind::Sentinel {
            total: data.len(),
            count: 1 + hits.count(),
            first,
        },
    })
}

// ---------------------------------------------------------------------------------------------
// Golden images
// ---------------------------------------------------------------------------------------------

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

// ---------------------------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::{FRAC_PI_2, PI};

    const TOL: Tolerance = Tolerance::new(1e-5, 1e-4);

    fn ramp(n: usize) -> Vec<f32> {
        (0..n).map(|i| i as f32 * 0.37 - 5.0).collect()
    }

    fn values_kind(m: &Mismatch) -> (usize, usize, Element, Element) {
        match &m.kind {
            MismatchKind::Values {
                failing,
                nan_failing,
                first,
                worst,
                ..
            } => (*failing, *nan_failing, *first, *worst),
            k => panic!("expected a Values mismatch, got {k:?}"),
        }
    }

    #[test]
    fn f32_equal_passes() {
        let a = ramp(100);
        let s = compare_f32("ramp", &a, &a, Tolerance::EXACT).unwrap();
        assert_eq!(
            (s.count, s.failing, s.max_abs, s.max_rel),
            (100, 0, 0.0, 0.0)
        );
        // Equal infinities pass; within-tolerance noise passes and shows in the stats.
        let inf = [f32::INFINITY, f32::NEG_INFINITY];
        compare_f32("inf", &inf, &inf, TOL).unwrap();
        let noisy: Vec<f32> = a.iter().map(|v| v + 5e-6).collect();
        let s = compare_f32("noisy", &noisy, &a, TOL).unwrap();
        assert!(s.max_abs > 4e-6 && s.max_abs < 6e-6, "{s}");
    }

    #[test]
    fn f32_one_element_off_fails_and_names_it() {
        let e = ramp(1000);
        let mut a = e.clone();
        a[417] += 0.1;
        a[900] += 0.5;
        let m = compare_f32("orient", &a, &e, TOL).unwrap_err();
        let (failing, nan, first, worst) = values_kind(&m);
        assert_eq!((failing, nan, first.index, worst.index), (2, 0, 417, 900));
        assert_eq!(first.actual, Scalar::F32(a[417]));
        assert_eq!(first.expected, Scalar::F32(e[417]));
        let msg = m.to_string();
        for needle in ["`orient`", "2 of 1000", "index 417", "index 900"] {
            assert!(msg.contains(needle), "{needle:?} missing from: {msg}");
        }
        // Debug prints the same, so `.unwrap()` is readable.
        assert_eq!(format!("{m:?}"), msg);
    }

    #[test]
    fn f32_tolerance_boundary_uses_rtol_of_expected() {
        // |a-b| = 0.1 <= 0 + 0.01*|10|: passes; against expected 1 it would not.
        compare_f32("rel", &[10.1], &[10.0], Tolerance::new(0.0, 0.0101)).unwrap();
        compare_f32("rel", &[1.1], &[1.0], Tolerance::new(0.0, 0.0101)).unwrap_err();
    }

    #[test]
    fn f32_nan_handling() {
        let e = ramp(10);
        let mut a = e.clone();
        a[3] = f32::NAN;
        let m = compare_f32("nan", &a, &e, TOL).unwrap_err();
        let (failing, nan, first, _) = values_kind(&m);
        assert_eq!((failing, nan, first.index), (1, 1, 3));
        assert!(m.to_string().contains("NaN(0x7fc00000)"), "{m}");
        // NaN vs NaN: fails by default, passes in the nan_eq variant.
        let mut b = e.clone();
        b[3] = f32::NAN;
        compare_f32("nan", &a, &b, TOL).unwrap_err();
        compare_f32_nan_eq("nan", &a, &b, TOL).unwrap();
        // NaN vs number still fails in the nan_eq variant.
        compare_f32_nan_eq("nan", &a, &e, TOL).unwrap_err();
    }

    #[test]
    fn length_mismatch_fails() {
        let m = compare_f32("len", &[1.0, 2.0], &[1.0], TOL).unwrap_err();
        assert_eq!(
            m.kind,
            MismatchKind::Length {
                actual: 2,
                expected: 1
            }
        );
        assert!(m.to_string().contains("length mismatch"), "{m}");
        compare_f32_fraction("len", &[1.0], &[], TOL, 0.0).unwrap_err();
        compare_angles_mod_pi("len", &[], &[0.0], 0.1, 0.0).unwrap_err();
        compare_u32_exact("len", &[1, 2, 3], &[1, 2]).unwrap_err();
    }

    #[test]
    fn fraction_allows_few_outliers_but_never_nan() {
        let e = ramp(1000);
        let mut a = e.clone();
        a[10] += 1.0;
        // 999/1000 within: exactly the 99.9% asked for.
        let s = compare_f32_fraction("frac", &a, &e, TOL, 0.999).unwrap();
        assert_eq!(s.failing, 1);
        a[20] += 1.0;
        let m = compare_f32_fraction("frac", &a, &e, TOL, 0.999).unwrap_err();
        assert_eq!(values_kind(&m).0, 2);
        // A single NaN fails even with a lenient fraction.
        let mut n = e.clone();
        n[5] = f32::NAN;
        compare_f32_fraction("frac", &n, &e, TOL, 0.5).unwrap_err();
        // ... but NaN == NaN passes in the nan_eq variant.
        let mut m2 = e.clone();
        m2[5] = f32::NAN;
        compare_f32_fraction_nan_eq("frac", &n, &m2, TOL, 1.0).unwrap();
        compare_f32_fraction("frac", &n, &m2, TOL, 0.5).unwrap_err();
    }

    #[test]
    fn angles_mod_pi() {
        // 0 and pi-1e-4 are 1e-4 apart circularly.
        let s = compare_angles_mod_pi("ang", &[0.0], &[PI - 1e-4], 1e-3, 1.0).unwrap();
        assert!(s.max_abs < 2e-4, "{s}");
        compare_angles_mod_pi("ang", &[PI - 1e-6], &[0.0], 1e-5, 1.0).unwrap();
        // Angles outside [0, pi) wrap too.
        compare_angles_mod_pi("ang", &[0.3 + PI], &[0.3], 1e-5, 1.0).unwrap();
        compare_angles_mod_pi("ang", &[-0.1], &[PI - 0.1], 1e-5, 1.0).unwrap();
        // 0 vs pi/2 is the largest possible difference.
        let m = compare_angles_mod_pi("ang", &[0.0], &[FRAC_PI_2], 0.5f32.to_radians(), 1.0)
            .unwrap_err();
        let (_, _, first, _) = values_kind(&m);
        assert!((first.error - std::f64::consts::FRAC_PI_2).abs() < 1e-6);
        assert!(m.to_string().contains("`ang`"), "{m}");
        // Masked pixels: NaN == NaN passes; NaN vs number fails even at fraction 0.
        compare_angles_mod_pi("ang", &[f32::NAN, 1.0], &[f32::NAN, 1.0], 1e-6, 1.0).unwrap();
        compare_angles_mod_pi("ang", &[f32::NAN, 1.0], &[0.5, 1.0], 1e-6, 0.0).unwrap_err();
        compare_angles_mod_pi("ang", &[0.5], &[f32::NAN], 1e-6, 0.0).unwrap_err();
        // 99.9%: one bad pixel of 1000 is tolerated, two are not.
        let e: Vec<f32> = (0..1000).map(|i| (i as f32 * 0.01) % PI).collect();
        let mut a = e.clone();
        a[0] += 0.1;
        compare_angles_mod_pi("ang", &a, &e, 0.5f32.to_radians(), 0.999).unwrap();
        a[1] += 0.1;
        compare_angles_mod_pi("ang", &a, &e, 0.5f32.to_radians(), 0.999).unwrap_err();
    }

    #[test]
    fn u32_exact() {
        let e: Vec<u32> = (0..64).collect();
        compare_u32_exact("labels", &e, &e).unwrap();
        let mut a = e.clone();
        a[7] = 70;
        let m = compare_u32_exact("labels", &a, &e).unwrap_err();
        let (failing, _, first, _) = values_kind(&m);
        assert_eq!((failing, first.index), (1, 7));
        assert!(m.to_string().contains("actual 70, expected 7"), "{m}");
    }

    #[test]
    fn sentinel() {
        assert!(SENTINEL_F32.is_nan());
        assert_ne!(SENTINEL_BITS, f32::NAN.to_bits());
        assert_no_sentinel("out", &ramp(16)).unwrap();
        // A canonical NaN is a written value, not the sentinel.
        assert_no_sentinel("out", &[f32::NAN]).unwrap();
        let mut d = sentinel_vec(8);
        for v in &mut d[..5] {
            *v = 1.0;
        }
        let m = assert_no_sentinel("out", &d).unwrap_err();
        assert_eq!(
            m.kind,
            MismatchKind::Sentinel {
                total: 8,
                count: 3,
                first: 5
            }
        );
        assert!(m.to_string().contains("first at index 5"), "{m}");
        // The value comparison also rejects a sentinel left in place (NaN vs number).
        compare_f32("out", &d, &[1.0; 8], TOL).unwrap_err();
    }

    #[test]
    fn parity_sizes_straddle_workgroups() {
        assert!(PARITY_SIZES.contains(&(1, 1)));
        assert!(PARITY_SIZES.iter().any(|&(w, h)| w < 64 && h > 64));
        assert!(PARITY_SIZES.iter().any(|&(w, h)| w != h && w > 64));
    }

    // --- golden ---

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
