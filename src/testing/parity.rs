//! Parity of a GPU pass with its CPU mirror, and the check that a pass wrote every element.

use std::fmt;

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
}
