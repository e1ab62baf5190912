//! The encoder's choice of side refinements by rate and distortion (as video encoders choose
//! their quantised coefficients): a side's refinement code is what most of a sketch's bytes
//! pay for, and the pursuit picks each one alone, nearest its window's best orientation, so
//! consecutive primitives' codes wander by a step or two where the fit barely prefers one.
//! Along each curve, the codes are chosen again to minimise
//!
//! ```text
//! Σ_sides E1(code) + μ · bits(code | the coder's prediction)
//! ```
//!
//! by dynamic programming (Viterbi over the 16 codes of the side the coder chains from
//! primitive to primitive). E1 is the pursuit's data term over the pixels the side paints,
//! linear in the double-angle vector (`Σ data·z`, so the sums per side are all it needs);
//! the bits are −log2 of the step's frequency in the sketch's own codes, re-estimated over a
//! few rounds as the codes settle (the range coder adapts to them the same way). The
//! prediction is the coder's ([`super::czs_rc`]): a side follows itself on the previous
//! primitive, its code moved by 4 steps per axis turn; a two-sided kind's second side
//! mirrors its first. Dictionary indices, axes and positions are kept. [`rate_rho`] does the
//! same for the contrasts' levels. Sequential and light (16 × 16 per primitive): CPU.

use super::*;

/// Rounds of re-estimating the step frequencies.
const ROUNDS: usize = 3;
/// Zigzag step codes the frequency tables hold (the coder's 5-bit tree).
const STEPS: usize = 32;

/// The two predictions the coder makes: from the previous primitive, from the mirror.
#[derive(Clone, Copy)]
enum Pred {
    Chain = 0,
    Mirror = 1,
}

/// Bits of a zigzag step, per prediction kind.
struct Rate {
    bits: [[f32; STEPS]; 2],
}

impl Rate {
    fn of(counts: &[[u32; STEPS]; 2]) -> Rate {
        Rate {
            bits: counts.map(|c| bits_of(&c)),
        }
    }

    fn step(&self, pred: Pred, code: u8, predicted: i32) -> f32 {
        let z = czs::zigzag(code as i64 - predicted.clamp(0, 15) as i64) as usize;
        self.bits[pred as usize][z.min(STEPS - 1)]
    }
}

/// Code lengths from counts by the add-half estimate: a symbol never seen costs a few bits
/// more than one seen once.
fn bits_of<const N: usize>(counts: &[u32; N]) -> [f32; N] {
    let n: f32 = counts.iter().map(|&v| v as f32 + 0.5).sum();
    counts.map(|v| -((v as f32 + 0.5) / n).log2())
}

/// The N-state path minimising Σ_k unary(k, r_k) + Σ_{k>0} pair(k, r_{k−1}, r_k) over `n`
/// steps, and that minimum (Viterbi; ties to the lower state).
fn viterbi<const N: usize>(
    n: usize,
    unary: impl Fn(usize, usize) -> f32,
    pair: impl Fn(usize, usize, usize) -> f32,
) -> (Vec<u8>, f32) {
    if n == 0 {
        return (Vec::new(), 0.0);
    }
    let mut cost: [f32; N] = std::array::from_fn(|r| unary(0, r));
    let mut back = vec![[0u8; N]; n];
    for (k, back) in back.iter_mut().enumerate().skip(1) {
        let mut next = [0.0f32; N];
        for r in 0..N {
            let (mut bq, mut bv) = (0u8, f32::INFINITY);
            for (q, &c) in cost.iter().enumerate() {
                let v = c + pair(k, q, r);
                if v < bv {
                    (bq, bv) = (q as u8, v);
                }
            }
            next[r] = bv + unary(k, r);
            back[r] = bq;
        }
        cost = next;
    }
    let mut r = (0..N as u8)
        .min_by(|&a, &b| cost[a as usize].total_cmp(&cost[b as usize]))
        .expect("N > 0 states");
    let least = cost[r as usize];
    let mut path = vec![0u8; n];
    for k in (0..n).rev() {
        path[k] = r;
        r = back[k][r as usize];
    }
    (path, least)
}

/// Quarter-pixel steps an occluding primitive may lie off its chain, each way.
pub const SHIFT_STEPS: i32 = 8;
/// One shift step across the axis, px.
pub const SHIFT_QUANTUM: f32 = 0.25;
/// Shift codes: code r lies (r − [`SHIFT_STEPS`])·[`SHIFT_QUANTUM`] px to the left of the chain.
pub const SHIFT_CODES: usize = 2 * SHIFT_STEPS as usize + 1;
/// Zigzag steps between consecutive shift codes.
const SHIFT_DELTAS: usize = 2 * SHIFT_CODES - 1;

/// The shift code on the chain.
pub const SHIFT_ZERO: u8 = SHIFT_STEPS as u8;

/// Per curve, the shift codes of its primitives chosen by rate and distortion: `costs[c]`
/// holds per primitive of an occluding curve the energy at each code (None: the curve is not
/// placed). Along each curve, Viterbi over the codes minimising Σ cost/μ + bits(step from
/// the previous code; the first from [`SHIFT_ZERO`]) + a flag's bits; a curve stays on its
/// chain (None out) unless that beats the flag that says so. The bits are −log2 of the
/// sketch's own frequencies over a few rounds, seeded by each primitive's own best code.
pub fn rate_shifts(costs: &[Option<Vec<[f32; SHIFT_CODES]>>], mu: f32) -> Vec<Option<Vec<u8>>> {
    if mu <= 0.0 {
        return vec![None; costs.len()];
    }
    let argmin = |c: &[f32; SHIFT_CODES]| {
        (0..SHIFT_CODES)
            .min_by(|&a, &b| c[a].total_cmp(&c[b]).then(a.cmp(&b)))
            .expect("codes") as u8
    };
    let mut out: Vec<Option<Vec<u8>>> = costs
        .iter()
        .map(|c| c.as_ref().map(|c| c.iter().map(argmin).collect()))
        .collect();
    for _ in 0..ROUNDS {
        let (flags, deltas) = shift_counts(&out, costs);
        let (fb, db) = (bits_of(&flags), bits_of(&deltas));
        for (o, c) in out.iter_mut().zip(costs) {
            let Some(c) = c else { continue };
            let unary = |k: usize, r: usize| {
                let e = (c[k][r] - c[k][SHIFT_ZERO as usize]) / mu;
                if k == 0 {
                    e + db[shift_delta(SHIFT_ZERO, r as u8)]
                } else {
                    e
                }
            };
            let (path, cost) =
                viterbi::<SHIFT_CODES>(c.len(), unary, |_, q, r| db[shift_delta(q as u8, r as u8)]);
            let pays = fb[1] + cost < fb[0];
            *o = (pays && path.iter().any(|&r| r != SHIFT_ZERO)).then_some(path);
        }
    }
    out
}

/// The zigzag index of the step from shift code `q` to `r`.
pub(crate) fn shift_delta(q: u8, r: u8) -> usize {
    czs::zigzag(r as i64 - q as i64) as usize
}

/// Counts of the shift flags (off, on) over the curves with costs, and of the steps along the
/// curves that are on.
fn shift_counts(
    out: &[Option<Vec<u8>>],
    costs: &[Option<Vec<[f32; SHIFT_CODES]>>],
) -> ([u32; 2], [u32; SHIFT_DELTAS]) {
    let (mut flags, mut deltas) = ([0u32; 2], [0u32; SHIFT_DELTAS]);
    for (o, c) in out.iter().zip(costs) {
        match o {
            None if c.is_some() => flags[0] += 1,
            None => {}
            Some(path) => {
                flags[1] += 1;
                let mut q = SHIFT_ZERO;
                for &r in path {
                    deltas[shift_delta(q, r)] += 1;
                    q = r;
                }
            }
        }
    }
    (flags, deltas)
}

/// The double-angle vector of the flow a side paints: the axis turned by −angle on the
/// left, +angle on the right (as [`Primitive::side_angle`]).
fn z_of(axis_idx: i64, s: usize, dict: u8, code: u8) -> [f32; 2] {
    let axis = axis_idx as f64 * 15.0;
    let side = side_deg(dict, code);
    let deg = if s == 0 { axis - side } else { axis + side };
    let t = 2.0 * deg.to_radians();
    [t.cos() as f32, t.sin() as f32]
}

/// Where an occluding line's flows are read: a band this far from the axis, px. The row
/// nearer the axis is left out: its derivative's stencil straddles both flows, and the axis
/// lies within about a pixel of the edge, so those pixels mix the two.
const OCCLUDING_BAND: [f32; 2] = [1.0, 2.5];
/// The Cauchy scale of the band's weights about its own estimate, degrees: a pixel whose
/// gradient says a flow this far off counts half.
const OCCLUDING_SCALE_DEG: f32 = 10.0;
/// Reweighting rounds of that estimate.
const OCCLUDING_ROUNDS: usize = 5;

/// Σ data over the hair pixels each side of each primitive of `curves` paints on a w×h
/// image, with the painting's ownership (a pixel belongs to the first primitive that reaches
/// it, curve order then primitive order, as [`crate::sketch::prim::paint`]). An occluding
/// primitive's sides are read beside its axis instead ([`occluding_sums`]).
pub fn side_sums(
    curves: &[Curve],
    w: u32,
    h: u32,
    data: &[[f32; 2]],
    hair: &[bool],
) -> Vec<Vec<[[f32; 2]; 2]>> {
    let mut on = vec![false; w as usize * h as usize];
    curves
        .iter()
        .map(|c| {
            let hs = c.kind.hair_sides();
            c.prims
                .iter()
                .map(|p| {
                    let mut g = [[0.0f32; 2]; 2];
                    crate::sketch::prim::window(c.kind, p, w, h, |k, side| {
                        if std::mem::replace(&mut on[k], true) {
                            return;
                        }
                        if let Some(si) = side.index() {
                            if hs[si] && hair[k] {
                                g[si][0] += data[k][0];
                                g[si][1] += data[k][1];
                            }
                        }
                    });
                    if c.kind == Kind::Occluding {
                        g = occluding_sums(p, w, h, data, hair);
                    }
                    g
                })
                .collect()
        })
        .collect()
}

/// Each side's Σ data over the band [`OCCLUDING_BAND`] beside an occluding primitive's axis,
/// each pixel weighted by 1/(1 + (r/[`OCCLUDING_SCALE_DEG`])²), r how far its gradient's
/// orientation lies from the side's estimate, reweighted [`OCCLUDING_ROUNDS`] times from the
/// plain sum (iteratively reweighted least squares): the other flow's stray pixels, on the
/// wrong side of an axis a pixel off the edge, count little. Still linear in the side's
/// double-angle vector, as the rate step needs.
fn occluding_sums(
    p: &Primitive,
    w: u32,
    h: u32,
    data: &[[f32; 2]],
    hair: &[bool],
) -> [[f32; 2]; 2] {
    let mut px: [Vec<usize>; 2] = [Vec::new(), Vec::new()];
    let [near, far] = OCCLUDING_BAND;
    crate::sketch::prim::beside(p, w, h, near, far, |k, s| {
        if hair[k] {
            px[s].push(k);
        }
    });
    let c2 = (2.0 * OCCLUDING_SCALE_DEG.to_radians()).powi(2);
    px.map(|px| {
        let sum = |wt: &dyn Fn([f32; 2]) -> f32| {
            px.iter().fold([0.0f32; 2], |acc, &k| {
                let v = wt(data[k]);
                [acc[0] + v * data[k][0], acc[1] + v * data[k][1]]
            })
        };
        let mut g = sum(&|_| 1.0);
        for _ in 0..OCCLUDING_ROUNDS {
            let n = g[0].hypot(g[1]);
            if n <= 0.0 {
                break;
            }
            let e = [g[0] / n, g[1] / n];
            g = sum(&|d| {
                // 2r, the double-angle distance between the pixel's orientation and e.
                let m = d[0].hypot(d[1]);
                if m <= 0.0 {
                    return 0.0;
                }
                let r2 = ((d[0] * e[1] - d[1] * e[0]) / m).atan2((d[0] * e[0] + d[1] * e[1]) / m);
                1.0 / (1.0 + r2 * r2 / c2)
            });
        }
        g
    })
}

/// `curves` (on the `.czs` lattice of a w×h sketch) with their side refinements chosen
/// again by rate and distortion: `sums` from [`side_sums`], `mu` the energy one bit is worth
/// (0: unchanged). Only the side angles change.
pub fn rate_sides(
    curves: &[Curve],
    w: u32,
    h: u32,
    sums: &[Vec<[[f32; 2]; 2]>],
    mu: f32,
) -> Vec<Curve> {
    let mut out = curves.to_vec();
    if mu <= 0.0 {
        return out;
    }
    let mut cc: Vec<Option<CurveCodes>> = curves.iter().map(|c| curve_codes(c, w, h)).collect();
    for _ in 0..ROUNDS {
        let rate = Rate::of(&step_counts(&cc));
        for (c, g) in cc.iter_mut().zip(sums) {
            if let Some(c) = c {
                choose(c, g, &rate, mu);
            }
        }
    }
    for (curve, c) in out.iter_mut().zip(&cc) {
        if let Some(c) = c {
            for (p, q) in curve.prims.iter_mut().zip(&decode_curve(c).prims) {
                p.side = q.side;
            }
        }
    }
    out
}

/// The contrast each primitive paints: per primitive of `curves`, (pixels, mean, variance)
/// of the per-pixel ρ it fixes, as [`rate_rho`] reads them.
pub type RhoStats = Vec<Vec<[f32; 3]>>;

/// `curves` with their contrasts' codes chosen again by rate and distortion: along each
/// curve, Viterbi over the 16 ρ levels minimising Σ n(level − mean)²/2σ² (the Gaussian
/// negative log-likelihood of the primitive's pixels about the stored level, less that about
/// their own mean; σ² their variance) plus μ times the bits of the level given the previous
/// one (the coder's context), from the sketch's own frequencies over a few rounds. A
/// primitive that paints no pixel keeps its level.
pub fn rate_rho(curves: &[Curve], stats: &RhoStats, mu: f32) -> Vec<Curve> {
    let mut out = curves.to_vec();
    if mu <= 0.0 {
        return out;
    }
    let mut codes: Vec<Vec<u8>> = curves
        .iter()
        .map(|c| c.prims.iter().map(|p| snap_rho(p.rho)).collect())
        .collect();
    for _ in 0..ROUNDS {
        // Bits of code r after code q (q = 16: a curve's first primitive).
        let mut n = [[0u32; 16]; 17];
        for c in &codes {
            let mut q = 16;
            for &r in c {
                n[q][r as usize] += 1;
                q = r as usize;
            }
        }
        let bits = n.map(|c| bits_of(&c));
        for (c, st) in codes.iter_mut().zip(stats) {
            let unary = |k: usize, r: usize| {
                let [px, mean, var] = st[k];
                let d = if px == 0.0 {
                    if r == c[k] as usize {
                        0.0
                    } else {
                        f32::INFINITY
                    }
                } else {
                    let d = RHO_LEVELS[r] - mean;
                    px * d * d / (2.0 * var.max(1e-6)) / mu
                };
                if k == 0 {
                    d + bits[16][r]
                } else {
                    d
                }
            };
            *c = viterbi::<16>(c.len(), unary, |_, q, r| bits[q][r]).0;
        }
    }
    for (curve, c) in out.iter_mut().zip(&codes) {
        for (p, &r) in curve.prims.iter_mut().zip(c) {
            p.rho = RHO_LEVELS[r as usize];
        }
    }
    out
}

/// The coder's prediction for side `s` of primitive `k`: its kind and predicted code, or
/// None where the side is coded without one (first primitive, another dictionary index).
fn prediction(c: &CurveCodes, k: usize, s: usize) -> Option<(Pred, i32)> {
    let hair = c.kind.hair_sides();
    let p = &c.prims[k];
    if s == 1 && hair[0] {
        let (d, r) = p.side[0];
        return (d == p.side[1].0).then_some((Pred::Mirror, 16 - r as i32));
    }
    let q = &c.prims[k.checked_sub(1)?];
    (q.side[s].0 == p.side[s].0).then_some((Pred::Chain, q.side[s].1 as i32 + 4 * p.turn as i32))
}

fn step_counts(cc: &[Option<CurveCodes>]) -> [[u32; STEPS]; 2] {
    let mut n = [[0u32; STEPS]; 2];
    for c in cc.iter().flatten() {
        let hair = c.kind.hair_sides();
        for k in 0..c.prims.len() {
            for s in (0..2).filter(|&s| hair[s]) {
                if let Some((pk, r)) = prediction(c, k, s) {
                    let z = czs::zigzag(c.prims[k].side[s].1 as i64 - r.clamp(0, 15) as i64);
                    n[pk as usize][(z as usize).min(STEPS - 1)] += 1;
                }
            }
        }
    }
    n
}

/// Viterbi along one curve over the codes of its chained side (the left where it is hair,
/// else the right); a two-sided kind's other side is chosen given it.
fn choose(c: &mut CurveCodes, g: &[[[f32; 2]; 2]], rate: &Rate, mu: f32) {
    let hair = c.kind.hair_sides();
    let chained = if hair[0] {
        0
    } else if hair[1] {
        1
    } else {
        return;
    };
    let other = (chained == 0 && hair[1]).then_some(1);
    let n = c.prims.len();
    let mut axis = c.axis as i64;
    // Per primitive: for each chained code, its unary cost and the other side's best code.
    let mut unary = vec![[0.0f32; 16]; n];
    let mut best_other = vec![[0u8; 16]; n];
    for k in 0..n {
        if k > 0 {
            axis += c.prims[k].turn as i64;
        }
        let e1 = |s: usize, d: u8, r: u8| {
            let z = z_of(axis, s, d, r);
            -mu.recip() * (g[k][s][0] * z[0] + g[k][s][1] * z[1])
        };
        let dc = c.prims[k].side[chained].0;
        for r in 0..16u8 {
            let mut u = e1(chained, dc, r);
            if let Some(o) = other {
                let d_o = c.prims[k].side[o].0;
                let mirror = (d_o == dc).then_some(16 - r as i32);
                let (mut bc, mut bv) = (0u8, f32::INFINITY);
                for r1 in 0..16u8 {
                    let v = e1(o, d_o, r1) + mirror.map_or(0.0, |m| rate.step(Pred::Mirror, r1, m));
                    if v < bv {
                        (bc, bv) = (r1, v);
                    }
                }
                u += bv;
                best_other[k][r as usize] = bc;
            }
            unary[k][r as usize] = u;
        }
    }
    // Costs in bits (E1 divided by μ).
    let path = viterbi::<16>(
        n,
        |k, r| unary[k][r],
        |k, q, r| {
            let linked = c.prims[k - 1].side[chained].0 == c.prims[k].side[chained].0;
            if linked {
                rate.step(Pred::Chain, r as u8, q as i32 + 4 * c.prims[k].turn as i32)
            } else {
                0.0
            }
        },
    )
    .0;
    for (k, &r) in path.iter().enumerate() {
        c.prims[k].side[chained].1 = r;
        if let Some(o) = other {
            c.prims[k].side[o].1 = best_other[k][r as usize];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sketch::{Kind, Primitive};

    /// Costs over the shift codes: 0, and −`gain` at code `at`.
    fn dip(at: usize, gain: f32) -> [f32; SHIFT_CODES] {
        std::array::from_fn(|r| if r == at { -gain } else { 0.0 })
    }

    #[test]
    fn shifts_are_kept_where_the_fit_pays_for_their_bits() {
        // Ten occluding curves of 8 primitives: three fit far better 3 steps to the left,
        // the others gain a fraction of a bit there; one curve is of another kind.
        let mut costs: Vec<Option<Vec<[f32; SHIFT_CODES]>>> = (0..10)
            .map(|c| Some(vec![dip(11, if c < 3 { 40.0 } else { 0.2 }); 8]))
            .collect();
        costs.push(None);
        let out = rate_shifts(&costs, 1.0);
        for (c, o) in out.iter().enumerate() {
            if c < 3 {
                assert_eq!(o.as_deref(), Some(&[11u8; 8][..]), "curve {c}");
            } else {
                assert_eq!(*o, None, "curve {c}");
            }
        }
        // The energy of a bit: at μ = 100 the same gains pay for nothing.
        assert!(rate_shifts(&costs, 100.0).iter().all(Option::is_none));
        assert!(rate_shifts(&costs, 0.0).iter().all(Option::is_none));
    }

    #[test]
    fn viterbi_finds_the_cheapest_path() {
        // Brute force over 5^4 paths with random costs.
        let mut r = crate::base::rng::Rng::new(3);
        let u: Vec<[f32; 5]> = (0..4)
            .map(|_| [(); 5].map(|_| r.range_f32(0.0, 3.0)))
            .collect();
        let pair: Vec<[[f32; 5]; 5]> = (0..4)
            .map(|_| [(); 5].map(|_| [(); 5].map(|_| r.range_f32(0.0, 3.0))))
            .collect();
        let cost = |p: &[u8]| -> f32 {
            (0..4).map(|k| u[k][p[k] as usize]).sum::<f32>()
                + (1..4)
                    .map(|k| pair[k][p[k - 1] as usize][p[k] as usize])
                    .sum::<f32>()
        };
        let path = viterbi::<5>(4, |k, r| u[k][r], |k, q, r| pair[k][q][r]).0;
        let mut best = f32::INFINITY;
        for i in 0..625u32 {
            let p: Vec<u8> = (0..4).map(|k| (i / 5u32.pow(k) % 5) as u8).collect();
            best = best.min(cost(&p));
        }
        assert!(
            (cost(&path) - best).abs() < 1e-5,
            "{} vs {best}",
            cost(&path)
        );
    }

    fn stream(codes: &[u8]) -> Sketch {
        let prims = codes
            .iter()
            .enumerate()
            .map(|(k, &r)| Primitive {
                shift: 0.0,
                x: 20.0 + STEP * k as f32,
                y: 20.0,
                axis: 0.0,
                rho: 1.0,
                side: [side_radians(0, r), side_radians(0, 16 - r)],
            })
            .collect();
        Sketch {
            width: 64,
            height: 64,
            curves: vec![Curve {
                kind: Kind::Stream,
                prims,
                dirs: [1, 1],
            }],
            seed: 1,
            rho_off: crate::sketch::RhoPrior {
                weight: [0.7, 0.3],
                mean: [1.0, 5.0],
                sigma: [0.5, 2.0],
            },
            shading: crate::sketch::Shading {
                mean: 40.0,
                bases: Vec::new(),
            },
            colour: crate::sketch::ColourMap {
                uv: vec![[0.0; 2]; 8],
            },
            region: Vec::new(),
            along_across: None,
        }
    }

    fn codes_of(s: &Sketch) -> Vec<u8> {
        let c = curve_codes(&s.curves[0], s.width, s.height).unwrap();
        c.prims.iter().map(|p| p.side[0].1).collect()
    }

    /// A weak window's code follows its neighbours; a strong one keeps its own; μ 0 keeps
    /// every code; fewer bytes after.
    #[test]
    fn weak_windows_follow_their_neighbours() {
        let codes = [8u8, 8, 10, 8, 8, 12, 8, 8];
        let s = stream(&codes);
        // The data each side's chosen code fits best, with a weight per primitive.
        let weight = [20.0f32, 20.0, 0.05, 20.0, 20.0, 200.0, 20.0, 20.0];
        let sums: Vec<Vec<[[f32; 2]; 2]>> = vec![codes
            .iter()
            .zip(weight)
            .map(|(&r, wgt)| {
                let z0 = z_of(0, 0, 0, r);
                let z1 = z_of(0, 1, 0, 16 - r);
                [z0.map(|v| v * wgt), z1.map(|v| v * wgt)]
            })
            .collect()];
        let rated = |mu| Sketch {
            curves: rate_sides(&s.curves, 64, 64, &sums, mu),
            ..s.clone()
        };
        assert_eq!(codes_of(&rated(0.0)), codes);
        let r = rated(1.0);
        assert_eq!(codes_of(&r), [8, 8, 8, 8, 8, 12, 8, 8]);
        // The mirrored side follows.
        let c = curve_codes(&r.curves[0], 64, 64).unwrap();
        assert!(c.prims.iter().all(|p| p.side[1].1 == 16 - p.side[0].1));
        assert!(czs_sizes(&r).curves < czs_sizes(&s).curves);
    }

    /// A pixel counts for the first primitive that paints it only; the non-hair side and
    /// non-hair pixels count for none.
    #[test]
    fn sums_follow_the_paintings_ownership() {
        let s = stream(&[8, 8]);
        let mut curves = s.curves.clone();
        curves.push(curves[0].clone());
        let data = vec![[1.0f32, 0.5]; 64 * 64];
        let mut hair = vec![true; 64 * 64];
        let g = side_sums(&curves, 64, 64, &data, &hair);
        let painted = crate::sketch::prim::paint(&curves, 64, 64, Some(&hair));
        let n_first: f32 = g[0].iter().map(|p| p[0][0] + p[1][0]).sum();
        let n_painted = painted.theta.iter().filter(|t| t.is_finite()).count();
        assert_eq!(n_first as usize, n_painted);
        assert!(g[1].iter().all(|p| p == &[[0.0; 2]; 2]), "{:?}", g[1]);
        // Off the hair, nothing.
        hair.iter_mut().for_each(|h| *h = false);
        let g = side_sums(&curves, 64, 64, &data, &hair);
        assert!(g.iter().flatten().all(|p| p == &[[0.0; 2]; 2]));
    }

    /// An occluding line on the edge between two flows: the pixels next to its axis carry
    /// the edge's own strong gradient (the derivative's stencil straddles it), so the sums of
    /// the pixels it paints say neither flow; the band beside the axis reads each one, and
    /// its weights keep a few stray pixels of the other flow from pulling it.
    #[test]
    fn occluding_sides_are_read_beside_the_axis() {
        let [ta, tb, edge] = [80f32, 20.0, 90.0].map(f32::to_radians);
        let z = |t: f32, a: f32| [a * (2.0 * t).cos(), a * (2.0 * t).sin()];
        let mut data = vec![[0.0f32; 2]; 64 * 64];
        for y in 0..64 {
            for x in 0..64 {
                data[y * 64 + x] = match x {
                    31 | 32 => z(edge, 3.0),
                    _ if x < 32 => z(ta, 1.0),
                    _ => z(tb, 1.0),
                };
            }
        }
        let hair = vec![true; 64 * 64];
        // Down the edge at x = 32: its left (+x) is the flow tb, its right ta.
        let p = Primitive {
            shift: 0.0,
            x: 32.0,
            y: 32.5,
            axis: std::f32::consts::FRAC_PI_2,
            rho: 1.0,
            side: [0.0; 2],
        };
        let curve = Curve {
            kind: Kind::Occluding,
            dirs: [0, 0],
            prims: vec![p],
        };
        let deg = |g: [f32; 2]| (0.5 * g[1].atan2(g[0])).to_degrees().rem_euclid(180.0);
        let band = side_sums(std::slice::from_ref(&curve), 64, 64, &data, &hair)[0][0];
        assert!((deg(band[0]) - 20.0).abs() < 0.5, "{}", deg(band[0]));
        assert!((deg(band[1]) - 80.0).abs() < 0.5, "{}", deg(band[1]));
        // What the pixels it paints say (a stream line paints the same window).
        let painted = side_sums(
            &[Curve {
                kind: Kind::Stream,
                ..curve.clone()
            }],
            64,
            64,
            &data,
            &hair,
        )[0][0];
        assert!((deg(painted[0]) - 20.0).abs() > 20.0, "{}", deg(painted[0]));
        assert!((deg(painted[1]) - 80.0).abs() > 5.0, "{}", deg(painted[1]));
        // Two of the seven rows of the left band stray into the other flow.
        for y in 29..31 {
            data[y * 64 + 33] = z(ta, 1.0);
        }
        let band = side_sums(std::slice::from_ref(&curve), 64, 64, &data, &hair)[0][0];
        assert!((deg(band[0]) - 20.0).abs() < 1.0, "{}", deg(band[0]));
    }

    /// A contrast measured from scattered pixels follows its neighbours' level; one from
    /// many consistent pixels keeps its own; a primitive that paints nothing keeps its level.
    #[test]
    fn uncertain_contrasts_follow_their_neighbours() {
        let mut s = stream(&[8; 20]);
        let mut levels = [8usize; 20];
        // The fifth scattered, the twelfth tight, the sixteenth paints nothing.
        (levels[5], levels[12], levels[16]) = (9, 10, 11);
        for (p, &l) in s.curves[0].prims.iter_mut().zip(&levels) {
            p.rho = RHO_LEVELS[l];
        }
        let stats = vec![(0..20)
            .map(|k| match k {
                5 => [20.0, RHO_LEVELS[9], 400.0],
                12 => [20.0, RHO_LEVELS[10], 0.01],
                16 => [0.0; 3],
                _ => [20.0, RHO_LEVELS[8], 4.0],
            })
            .collect()];
        let codes = |c: &[Curve]| -> Vec<usize> {
            c[0].prims
                .iter()
                .map(|p| snap_rho(p.rho) as usize)
                .collect()
        };
        assert_eq!(codes(&rate_rho(&s.curves, &stats, 0.0)), levels);
        let mut want = levels;
        want[5] = 8;
        assert_eq!(codes(&rate_rho(&s.curves, &stats, 1.0)), want);
    }
}
