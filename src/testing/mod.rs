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
//! * **Fuzzing**: [`fuzz::run`] runs one parser under fuzzing on one input (`fuzz/`).
//!
//! The error types print readable messages from both `Display` and `Debug`, so
//! `.unwrap()` / `.expect()` in a test shows the diagnosis rather than a struct dump.

// The error types carry the whole diagnosis (values, figures, paths) so tests can match on
// them; they only travel on the failure path of a test, where their size costs nothing.
#![allow(clippy::result_large_err)]

pub mod fuzz;
mod golden;
mod parity;

pub use golden::*;
pub use parity::*;
