//! The pursuit's parameters, counts and result.

use super::*;

/// Parameters of the pursuit. The paper publishes none (they were learned from hand sketches
/// it does not release); the defaults are ours, see each field.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PursuitParams {
    /// λ_NC, the cost of a curve (Eq. 22), in units of the per-pixel energies. Default 40:
    /// on `coif synth` at 512² (seed 1) it gives 73 / 26 / 31 / 27 curves on long / whorl /
    /// sidepart / short (42 on fringe), inside the 20-80 the reading notes aim for; with the
    /// contrast term on every kind, 20 gave 117 / 42 / 44 / 31 and 80 gave 53 / 13 / 21 / 12
    /// (`pursuit_512_timing` with COIF_LAMBDA_NC). With the literal birth rule
    /// (`birth_lookahead` false) the scale differs: there 20 gives ~25-60.
    pub lambda_nc: f32,
    /// λ_B, the cost of each primitive, in the same units: a primitive is kept (a birth
    /// started, a curve extended) only where it gains more than its own description.
    pub lambda_b: f32,
    /// Θ is diffused again, and births screened again, after this many new curves. Default 4.
    pub rebuild_every: u32,
    /// Sweeps of a re-diffusion (warm from the current field; the convergence test of
    /// `theta` applies). Default 60.
    pub rebuild_sweeps: u32,
    /// Curves with fewer primitives are dropped. Default 3.
    pub min_prims: usize,
    /// Longest curve, in primitives. Default 120.
    pub max_prims: usize,
    /// Most curves. Default 400.
    pub max_curves: usize,
    /// Births are screened every `birth_stride` px in x and y. Default 2.
    pub birth_stride: u32,
    /// a, b: the share of their non-hair side's pixels that may be hair. Default 0.25.
    pub spill: f32,
    /// a, b: the least share of their hair side's pixels that must be hair. Default 0.5.
    pub hair_min: f32,
    /// Before any sketch, p_sk is fitted to the ρ of the hair pixels whose local contrast is
    /// above this quantile, p_nsk to the rest (see `rho::fit_split`). Default 0.8.
    pub split_quantile: f32,
    /// Refit p_sk and p_nsk from the first pursuit's sketch and pursue again. Default true.
    pub refit: bool,
    /// Refine side angles by up to ±30° (3.75° steps) around the dictionary. Default true.
    pub refine_sides: bool,
    /// Place occluding primitives up to ±2 px off their chain, ¼ px steps, where the two
    /// flows split best (`pursuit::place`; with a rate, `bit_cost` > 0). Default true.
    pub place_occluding: bool,
    /// Births are ranked by the first primitive's δ without λ_NC, and λ_NC is charged when
    /// the traced curve is scored whole (kept only if its δ, λ_NC included, is positive);
    /// false: the paper's literal rule, the first primitive alone must beat λ_NC. Default
    /// true: a seam is cheap per window (on `coif synth` fringe at 256² no primitive on the
    /// seam gains more than ~12 before λ_NC, searched over every axis, variant and
    /// refinement) but long, so the literal rule never starts a curve there.
    pub birth_lookahead: bool,
    /// The contrast term of Eq. 21 (−log p_sk on the sketch, −log p_nsk off it) on the
    /// pixels of every kind, as printed; false: on stream lines' pixels only, the others
    /// keep p_nsk. Default false: the paper gives those terms the stream lines ("the
    /// streamline primitives are distinguished from the nonsketchable part not by their
    /// orientations but by their relatively high gradients"), and an occluding line on a
    /// seam of ordinary contrast costs ~20 per window under p_sk, more than its orientation
    /// terms gain. On the fringe at 512² (seeds 1-3) the error within 4 px of the seam falls
    /// by 21% / 23% / 28% against S = ∅ with both defaults; with the term on every kind by
    /// 3% / 1% / 0%.
    pub contrast_all: bool,
    /// μ, the energy one bit of `.czs` is worth when the finished sketch's side refinements
    /// (and with `rate_contrast` its contrasts) are chosen again by rate and distortion
    /// (`format::rate_sides`, `format::rate_rho`: each code may follow the coder's
    /// prediction where the image barely prefers another); 0 keeps the pursuit's own.
    /// Default ln 2: the distortions are negative log-likelihoods in nats and a bit is ln 2
    /// of them (minimum description length). See the README for what it measured.
    pub bit_cost: f32,
    /// Choose the contrasts' codes by rate too. Default false: 3-5% smaller files (the long
    /// case 1074 → 1022 B), but chelsea's round trip through synthesis fell from 93.5% to
    /// 90.0% (README, "Bit cost").
    pub rate_contrast: bool,
    /// The diffusion of Θ∅ and of the final Θ.
    pub theta: ThetaParams,
}

impl Default for PursuitParams {
    fn default() -> Self {
        PursuitParams {
            lambda_nc: 40.0,
            lambda_b: 0.0,
            rebuild_every: 4,
            rebuild_sweeps: 60,
            min_prims: 3,
            max_prims: 120,
            max_curves: 400,
            birth_stride: 2,
            spill: 0.25,
            hair_min: 0.5,
            split_quantile: 0.8,
            refit: true,
            refine_sides: true,
            place_occluding: true,
            birth_lookahead: true,
            contrast_all: false,
            bit_cost: std::f32::consts::LN_2,
            rate_contrast: false,
            theta: ThetaParams::default(),
        }
    }
}

impl PursuitParams {
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("pursuit: {m}")));
        if !(self.lambda_nc.is_finite() && self.lambda_nc >= 0.0) {
            return bad(format!(
                "the curve penalty λ_NC {} must be a number ≥ 0",
                self.lambda_nc
            ));
        }
        if !(self.lambda_b.is_finite() && self.lambda_b >= 0.0) {
            return bad(format!(
                "the primitive penalty λ_B {} must be a number ≥ 0",
                self.lambda_b
            ));
        }
        if !(self.bit_cost.is_finite() && self.bit_cost >= 0.0) {
            return bad(format!(
                "the bit cost μ {} must be a number ≥ 0",
                self.bit_cost
            ));
        }
        if self.rebuild_every == 0 {
            return bad("rebuild_every must be at least 1".into());
        }
        if self.rebuild_sweeps == 0 || self.rebuild_sweeps > 100_000 {
            return bad(format!(
                "rebuild_sweeps {} must be in 1..=100000",
                self.rebuild_sweeps
            ));
        }
        if self.min_prims == 0 || self.max_prims < self.min_prims || self.max_prims > 10_000 {
            return bad(format!(
                "need 1 ≤ min_prims ({}) ≤ max_prims ({}) ≤ 10000",
                self.min_prims, self.max_prims
            ));
        }
        if self.max_curves > 100_000 {
            return bad(format!("max_curves {} is over 100000", self.max_curves));
        }
        if !(1..=16).contains(&self.birth_stride) {
            return bad(format!(
                "birth_stride {} must be in 1..=16",
                self.birth_stride
            ));
        }
        for (name, v) in [("spill", self.spill), ("hair_min", self.hair_min)] {
            if !(0.0..=1.0).contains(&v) {
                return bad(format!("{name} {v} must be in [0, 1]"));
            }
        }
        if !(self.split_quantile > 0.0 && self.split_quantile < 1.0) {
            return bad(format!(
                "split_quantile {} must be in (0, 1)",
                self.split_quantile
            ));
        }
        self.theta.validate()
    }
}

/// Counts and times of a pursuit.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PursuitStats {
    /// Pursuits run (2 with the refit).
    pub passes: u32,
    /// Births traced (kept or dropped), over all passes.
    pub births: u32,
    /// Curves dropped for having fewer than `min_prims` primitives.
    pub dropped_short: u32,
    /// Curves dropped because, moved onto the integer start, they no longer lowered E.
    pub dropped_snapped: u32,
    /// Re-diffusions of Θ with the sketch clamped.
    pub rebuilds: u32,
    /// Runs of the `cz_window_sums` pass.
    pub window_runs: u32,
    /// Birth positions scored exactly (all kinds, axes and variants at once).
    pub exact_births: u64,
    /// Of them, scored ahead of their turn (in parallel with another) and then used.
    pub memo_hits: u64,
    /// Extension steps scored (both ends of a curve at once), and primitives painted with
    /// the field around them relaxed (while tracing and when placing on the lattice).
    pub extensions: u64,
    pub placements: u64,
    /// Sweeps of Θ∅, and of the final Θ.
    pub sweeps_empty: u32,
    pub sweeps_final: u32,
    /// Wall time in the diffusions, the window pass, and the CPU search, seconds.
    pub seconds_theta: f64,
    pub seconds_windows: f64,
    pub seconds_search: f64,
    /// Of the search: choosing births (the heap and the exact scores), and tracing curves.
    pub seconds_births: f64,
    pub seconds_traces: f64,
    /// Primitives whose side codes, and whose contrast code, the rate choice changed
    /// (`bit_cost`; the last pass).
    pub sides_rated: usize,
    pub rho_rated: usize,
    /// Occluding primitives placed off their chain (the last pass).
    pub shifted: usize,
}

impl PursuitStats {
    /// Adds the counts and times of another pass (the final sweeps are the last pass's).
    pub(super) fn add(&mut self, o: &PursuitStats) {
        self.passes += o.passes;
        self.births += o.births;
        self.sides_rated = o.sides_rated;
        self.rho_rated = o.rho_rated;
        self.shifted = o.shifted;
        self.dropped_short += o.dropped_short;
        self.dropped_snapped += o.dropped_snapped;
        self.rebuilds += o.rebuilds;
        self.window_runs += o.window_runs;
        self.exact_births += o.exact_births;
        self.memo_hits += o.memo_hits;
        self.extensions += o.extensions;
        self.placements += o.placements;
        self.seconds_theta += o.seconds_theta;
        self.seconds_windows += o.seconds_windows;
        self.seconds_search += o.seconds_search;
        self.seconds_births += o.seconds_births;
        self.seconds_traces += o.seconds_traces;
    }
}

/// The result of a pursuit.
#[derive(Clone, Debug)]
pub struct Pursuit {
    /// Undirected curves (dirs all 0: directions are Step 2), on the lattice.
    pub curves: Vec<Curve>,
    /// Θ in [0, π) diffused with the sketch clamped; NaN off the hair.
    pub theta: Vec<f32>,
    /// ρ = |∇⊥Θ I_H| under `theta`; NaN off the hair.
    pub rho: Vec<f32>,
    /// p_sk and p_nsk the final pursuit used.
    pub rho_on: RhoPrior,
    pub rho_off: RhoPrior,
    /// σθ² (Eq. 20).
    pub sigma2: f32,
    /// E(Θ∅, ∅) of the final pursuit, then E after each accepted curve (Fig. 13).
    pub energy_empty: f64,
    pub energy: Vec<f64>,
    /// E with the final Θ.
    pub energy_final: f64,
    pub stats: PursuitStats,
}
