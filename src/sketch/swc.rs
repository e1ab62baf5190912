//! Step 2 of CZ06 (§4.2, Eq. 28-30): the growth directions of the sketch's curves, by
//! Swendsen-Wang cuts on the graph of adjacent curve sides.
//!
//! The graph. Its nodes are the curves' free direction variables ([`Kind::free_dirs`]: a and
//! b one on their hair side, c one per side, e one shared by both sides, d none: a dividing
//! line is fixed outward and enters as a known label). Each curve side with hair grows a
//! *cell*: the geodesic Voronoi cell of its sketch pixels inside the mask (8-neighbour
//! chamfer distance, 5/7), so a pixel belongs to the side it can reach first without
//! leaving the hair or crossing another curve. Two sides are adjacent when their cells share
//! at least [`SwcParams::min_border`] 4-neighbour pixel pairs. This replaces the paper's
//! "a straight segment joins the two curves without crossing a third": the cells say the
//! same thing (nothing lies between the two curves) but through the hair rather than across
//! gaps of background, and they give the border pixels that the energy needs.
//!
//! The energy. Inside each cell the sign of the direction field is propagated along Θ from
//! the curve side outwards (each pixel takes its Dijkstra parent's sign, turned by the sign
//! of cos(Θ_v − Θ_parent)), so a cell's pixels all follow its side's label: the growth
//! direction at pixel v is s_v·d_cell·(cos Θ_v, sin Θ_v). Then the smoothness term of
//! Eq. 30, Σ (1 − cos Δτ) over 4-neighbour pairs, is constant inside a cell and
//! 1 − s_u s_v d_A d_B cos(Θ_u − Θ_v) across a border, and −log p_dir on the sketch pixels is
//! linear in each label: E(d) = C − Σ J_ij d_i d_j − Σ h_i d_i exactly, a [`PairModel`], with
//! J_ij = Σ_border s_u s_v cos(Θ_u − Θ_v) and h_i = κ Σ_sketch cos(φ_v − μ_v) (φ the side's
//! flow vector, μ the prior's mean direction, [`DirPrior`]). Contacts thinner than
//! `min_border` are left out of the graph and of E. The cells stand in for the diffused d_V
//! of the paper, which the fill computes afterwards from the chosen labels.
//!
//! Labels are relative to each curve's traversal (see `sketch`'s module docs), so two
//! compatible curves may carry opposite labels: J is then negative. The sampler works in
//! that gauge: an edge "agrees" when d_i = sgn(J_ij)·d_j, and only agreeing edges can bond
//! (CZ06 writes d_i = d_j, true when both curves run the same way).
//!
//! The sampler (§4.2.2): bonds on agreeing edges with probability q_ij, the connected
//! component V0 of a uniformly chosen node, flipped as a whole, accepted with the
//! Metropolis-Hastings ratio of the paper, min(1, Π_{C'}(1 − q)/Π_{C}(1 − q) · p'/p) where C
//! are the edges from V0 to the rest that agree now and C' those that will agree after the
//! flip. No annealing, as in the paper; the best state seen is kept. One departure: q_ij is
//! drawn per proposal from a ladder of bond strengths ([`Bonds`], which says why: with the
//! paper's single strength the chain freezes at the couplings' pixel-sum scale);
//! `Bonds::single` is the paper's sampler unchanged.
//!
//! Light, branchy, sequential work (a Dijkstra over the hair, then a graph of a few hundred
//! nodes): CPU.

use super::prim::window;
use super::{Curve, Kind};
use crate::base::rng::Rng;
use crate::error::{Error, Result};
use crate::io::annot::{StrokeKind, Strokes};
use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap};
use std::str::FromStr;

/// How the labels are chosen (the ablation of the issue).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// Swendsen-Wang cuts from a random start, keeping the best state seen.
    Swc,
    /// Iterated conditional modes: greedy single-node flips from the prior-only labels.
    Icm,
    /// Each free node by its own p_dir term alone (CZ06 Fig. 14b).
    Prior,
}

impl Method {
    pub const ALL: [Method; 3] = [Method::Swc, Method::Icm, Method::Prior];

    pub fn name(self) -> &'static str {
        match self {
            Method::Swc => "swc",
            Method::Icm => "icm",
            Method::Prior => "prior",
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Method> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                Error::Invalid(format!(
                    "unknown direction method \"{s}\" (expected one of swc, icm, prior)"
                ))
            })
    }
}

/// The bond probability q_ij of an agreeing edge with coupling J.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bond {
    /// q = 1 − e^{−2|J|}, Swendsen-Wang's: with it the acceptance ratio is exactly 1 when the
    /// model has no unary terms, so only the unaries reject.
    Sw,
    /// q = 1 / (1 + e^{−2|J|}), CZ06's q_ij = p(d_i = d_j) for the pair alone. Any q gives a
    /// correct sampler through the acceptance ratio; this one rejects more.
    Paper,
}

impl Bond {
    /// (q, ln(1 − q)) for coupling `j` at bond strength `scale` (the coupling scaled by it),
    /// the logarithm computed without cancellation.
    fn q(self, j: f64, scale: f64) -> (f64, f64) {
        let a = 2.0 * j.abs() * scale;
        match self {
            Bond::Sw => (-(-a).exp_m1(), -a),
            // 1 − q = 1 / (1 + e^{a}); ln = −softplus(a).
            Bond::Paper => (1.0 / (1.0 + (-a).exp()), -(a + (-a).exp().ln_1p())),
        }
    }
}

/// The proposal's bond probabilities: [`Bond`] with the coupling scaled by s, s drawn per
/// proposal, uniformly from `levels` strengths 1, 1/4, 1/16, …, and (with ≥ 2 levels) 0.
///
/// CZ06 leaves q_ij free ("the exact formula for q_ij does not matter too much, though a
/// good probability will lead to fast convergence"). At the pixel-sum scale of the sketch's
/// couplings (|J| in the tens to hundreds) q = 1 − e^{−2|J|} is 1 to machine precision, so
/// every proposal's V0 is a whole connected set of agreeing nodes and a node whose unary
/// term disagrees with its neighbours is never proposed alone: the chain freezes in the
/// first state where no whole cluster may flip (seen on the toy sketch of the tests: stuck
/// 100 energy units above the ground state, one node away from it). Weaker bonds propose
/// smaller clusters; s = 0 proposes one node (a Metropolis flip). Each strength is a
/// correct SW-cut kernel with its own acceptance ratio, and the strength is drawn
/// independently of the state, so the mixture keeps p(d) invariant. `levels` = 1 is the
/// paper's sampler unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bonds {
    pub kind: Bond,
    pub levels: u32,
}

impl Default for Bonds {
    fn default() -> Self {
        Bonds {
            kind: Bond::Sw,
            levels: 8,
        }
    }
}

impl Bonds {
    /// The paper's sampler: one strength, s = 1.
    pub fn single(kind: Bond) -> Self {
        Bonds { kind, levels: 1 }
    }

    /// Strength s of level `k`.
    pub fn scale(self, k: u32) -> f64 {
        if self.levels >= 2 && k == self.levels - 1 {
            0.0
        } else {
            0.25f64.powi(k as i32)
        }
    }
}

/// p_dir of Eq. 5-6 without hand sketches to learn it from: a von Mises density of the
/// growth direction around μ(p) = norm((p − c)/|p − c| + gravity·ŷ), outward from a crown c
/// = (mask centroid x, mask top + crown_depth · mask height) and bent down.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirPrior {
    /// Concentration κ; −log p_dir = κ(1 − cos(τ − μ)) per sketch pixel, up to a constant.
    pub kappa: f32,
    /// Weight of the downward pull added to the outward unit vector.
    pub gravity: f32,
    /// The crown's depth below the top of the mask, as a fraction of the mask's height.
    pub crown_depth: f32,
}

impl Default for DirPrior {
    fn default() -> Self {
        DirPrior {
            kappa: 1.0,
            gravity: 0.5,
            crown_depth: 0.15,
        }
    }
}

impl DirPrior {
    /// The crown c of the mask, None when the mask is empty.
    pub fn crown(&self, hair: &[bool], w: u32, h: u32) -> Option<[f32; 2]> {
        let (mut sx, mut n) = (0f64, 0usize);
        let (mut top, mut bottom) = (u32::MAX, 0u32);
        for y in 0..h {
            for x in 0..w {
                if hair[(y * w + x) as usize] {
                    sx += x as f64 + 0.5;
                    n += 1;
                    top = top.min(y);
                    bottom = bottom.max(y);
                }
            }
        }
        (n > 0).then(|| {
            let height = (bottom - top + 1) as f32;
            [
                (sx / n as f64) as f32,
                top as f32 + self.crown_depth * height,
            ]
        })
    }

    /// The prior's mean growth direction μ at (x, y), a unit vector.
    pub fn mean(&self, crown: [f32; 2], x: f32, y: f32) -> [f32; 2] {
        let (dx, dy) = (x - crown[0], y - crown[1]);
        let r = dx.hypot(dy);
        let (ox, oy) = if r > 1e-6 {
            (dx / r, dy / r)
        } else {
            (0.0, 0.0)
        };
        let (vx, vy) = (ox, oy + self.gravity);
        let l = vx.hypot(vy);
        if l > 1e-6 {
            [vx / l, vy / l]
        } else {
            [0.0, 1.0]
        }
    }
}

/// Parameters of Step 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwcParams {
    /// Sweeps of the sampler; a sweep makes one proposal per free node.
    pub sweeps: usize,
    /// Seed of the random start and of the sampler.
    pub seed: u64,
    pub prior: DirPrior,
    /// Least number of 4-neighbour pixel pairs two cells must share to be adjacent; thinner
    /// contacts (corners, single pixels) are left out of the graph and of the energy.
    pub min_border: usize,
    pub bonds: Bonds,
}

impl Default for SwcParams {
    fn default() -> Self {
        SwcParams {
            sweeps: 200,
            seed: 1,
            prior: DirPrior::default(),
            min_border: 3,
            bonds: Bonds::default(),
        }
    }
}

/// A known label for one side of one curve (a user stroke, or a decision made elsewhere).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Clamp {
    pub curve: usize,
    /// 0 left, 1 right.
    pub side: usize,
    /// +1 along the side's flow vector, −1 against it.
    pub label: i8,
}

// ---------------------------------------------------------------------------------------
// The generic pairwise binary model and its samplers.

/// One coupling: the energy holds −j·d_a·d_b.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coupling {
    pub a: usize,
    pub b: usize,
    pub j: f64,
}

/// A binary pairwise model over labels d ∈ {−1, +1}^n:
/// E(d) = constant − Σ_edges j·d_a·d_b − Σ_i h_i·d_i, p(d) ∝ e^{−E(d)}.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PairModel {
    pub h: Vec<f64>,
    pub edges: Vec<Coupling>,
    pub constant: f64,
}

/// What a labelling run returns.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// The best labels seen.
    pub labels: Vec<i8>,
    /// Their energy.
    pub energy: f64,
    /// The current state's energy after each sweep (SW), each pass (ICM); the start first.
    pub trace: Vec<f64>,
    pub proposals: usize,
    pub accepted: usize,
}

fn sgn(x: f64) -> i8 {
    if x < 0.0 {
        -1
    } else {
        1
    }
}

/// Uniform in (0, 1), with 32 bits.
fn uniform(rng: &mut Rng) -> f64 {
    (rng.next_u32() as f64 + 0.5) / 4_294_967_296.0
}

impl PairModel {
    /// A model of `n` free nodes with no terms.
    pub fn new(n: usize) -> Self {
        PairModel {
            h: vec![0.0; n],
            edges: Vec::new(),
            constant: 0.0,
        }
    }

    pub fn len(&self) -> usize {
        self.h.len()
    }

    pub fn is_empty(&self) -> bool {
        self.h.is_empty()
    }

    /// Checks indices and finiteness.
    pub fn validate(&self) -> Result<()> {
        let n = self.len();
        if let Some(i) = self.h.iter().position(|v| !v.is_finite()) {
            return Err(Error::Invalid(format!("pair model: h[{i}] is not finite")));
        }
        for (k, e) in self.edges.iter().enumerate() {
            if e.a >= n || e.b >= n || e.a == e.b || !e.j.is_finite() {
                return Err(Error::Invalid(format!(
                    "pair model: edge {k} ({}, {}, {}) needs two distinct nodes below {n} and a finite coupling",
                    e.a, e.b, e.j
                )));
            }
        }
        Ok(())
    }

    /// E(d).
    pub fn energy(&self, d: &[i8]) -> f64 {
        let mut e = self.constant;
        for (hi, &di) in self.h.iter().zip(d) {
            e -= hi * di as f64;
        }
        for c in &self.edges {
            e -= c.j * (d[c.a] * d[c.b]) as f64;
        }
        e
    }

    /// Labels by the unary terms alone: sgn(h_i), +1 on ties.
    pub fn field_labels(&self) -> Vec<i8> {
        self.h.iter().map(|&v| sgn(v)).collect()
    }

    /// Per node: (neighbour, edge index), edges with j = 0 left out (they never bond and
    /// never change the energy).
    fn adjacency(&self) -> Vec<Vec<(usize, usize)>> {
        let mut adj = vec![Vec::new(); self.len()];
        for (k, c) in self.edges.iter().enumerate() {
            if c.j != 0.0 {
                adj[c.a].push((c.b, k));
                adj[c.b].push((c.a, k));
            }
        }
        adj
    }

    /// The model on the nodes that `fixed` leaves free, the fixed ones folded into the free
    /// nodes' fields and the constant. Returns it and, per free node, its index here.
    pub fn condition(&self, fixed: &[Option<i8>]) -> (PairModel, Vec<usize>) {
        let mut map = Vec::new();
        let mut index = vec![usize::MAX; self.len()];
        for (i, f) in fixed.iter().enumerate() {
            if f.is_none() {
                index[i] = map.len();
                map.push(i);
            }
        }
        let mut out = PairModel::new(map.len());
        out.constant = self.constant;
        for (i, &hi) in self.h.iter().enumerate() {
            match fixed[i] {
                Some(v) => out.constant -= hi * v as f64,
                None => out.h[index[i]] += hi,
            }
        }
        for c in &self.edges {
            match (fixed[c.a], fixed[c.b]) {
                (None, None) => out.edges.push(Coupling {
                    a: index[c.a],
                    b: index[c.b],
                    j: c.j,
                }),
                (Some(va), None) => out.h[index[c.b]] += c.j * va as f64,
                (None, Some(vb)) => out.h[index[c.a]] += c.j * vb as f64,
                (Some(va), Some(vb)) => out.constant -= c.j * (va * vb) as f64,
            }
        }
        (out, map)
    }

    /// Iterated conditional modes from `init`: flip any node whose flip lowers the energy,
    /// in index order, until a pass changes nothing.
    pub fn icm(&self, init: &[i8]) -> Run {
        let adj = self.adjacency();
        let mut d = init.to_vec();
        let mut trace = vec![self.energy(&d)];
        let mut proposals = 0;
        let mut accepted = 0;
        loop {
            let mut changed = false;
            for i in 0..self.len() {
                let f = self.h[i]
                    + adj[i]
                        .iter()
                        .map(|&(j, k)| self.edges[k].j * d[j] as f64)
                        .sum::<f64>();
                proposals += 1;
                // Flipping d_i changes E by 2·d_i·f; a tolerance keeps ties from cycling.
                if 2.0 * d[i] as f64 * f < -1e-9 {
                    d[i] = -d[i];
                    accepted += 1;
                    changed = true;
                }
            }
            trace.push(self.energy(&d));
            if !changed {
                break;
            }
        }
        Run {
            energy: self.energy(&d),
            labels: d,
            trace,
            proposals,
            accepted,
        }
    }

    /// Swendsen-Wang cuts from `init` for `sweeps` sweeps of `len()` proposals each, keeping
    /// the best state seen.
    pub fn swc(&self, init: &[i8], sweeps: usize, bonds: Bonds, seed: u64) -> Run {
        let mut s = Sampler::new(self, init, bonds, seed);
        let mut best = init.to_vec();
        let mut best_e = s.energy();
        let mut trace = vec![best_e];
        let (mut proposals, mut accepted) = (0, 0);
        for _ in 0..sweeps {
            for _ in 0..self.len() {
                proposals += 1;
                if s.step() {
                    accepted += 1;
                    if s.energy() < best_e - 1e-9 {
                        best_e = s.energy();
                        best.copy_from_slice(s.labels());
                    }
                }
            }
            // Recomputed rather than accumulated, so rounding cannot drift.
            s.energy = self.energy(&s.d);
            trace.push(s.energy);
        }
        Run {
            energy: self.energy(&best),
            labels: best,
            trace,
            proposals,
            accepted,
        }
    }
}

/// One proposed cluster flip.
#[derive(Clone, Debug, PartialEq)]
pub struct Proposal {
    /// V0: the nodes to flip.
    pub component: Vec<usize>,
    /// E(d') − E(d).
    pub delta_e: f64,
    /// ln [Π_{C'}(1 − q) / Π_{C}(1 − q)]: the proposal's asymmetry.
    pub log_q_ratio: f64,
}

impl Proposal {
    /// The log of the paper's acceptance ratio before min(1, ·).
    pub fn log_ratio(&self) -> f64 {
        self.log_q_ratio - self.delta_e
    }
}

/// The Swendsen-Wang cut sampler of CZ06 §4.2.2 on a [`PairModel`].
pub struct Sampler<'m> {
    model: &'m PairModel,
    adj: Vec<Vec<(usize, usize)>>,
    /// Per strength level, per edge: q and ln(1 − q).
    q: Vec<Vec<f64>>,
    log1mq: Vec<Vec<f64>>,
    levels: u32,
    d: Vec<i8>,
    energy: f64,
    rng: Rng,
    in_v0: Vec<bool>,
}

impl<'m> Sampler<'m> {
    pub fn new(model: &'m PairModel, init: &[i8], bonds: Bonds, seed: u64) -> Self {
        assert_eq!(init.len(), model.len(), "one initial label per node");
        assert!(bonds.levels >= 1, "at least one bond strength");
        let (q, log1mq) = (0..bonds.levels)
            .map(|k| {
                let s = bonds.scale(k);
                model.edges.iter().map(|c| bonds.kind.q(c.j, s)).unzip()
            })
            .unzip();
        Sampler {
            model,
            adj: model.adjacency(),
            q,
            log1mq,
            levels: bonds.levels,
            d: init.to_vec(),
            energy: model.energy(init),
            rng: Rng::new(seed),
            in_v0: vec![false; model.len()],
        }
    }

    pub fn labels(&self) -> &[i8] {
        &self.d
    }

    pub fn energy(&self) -> f64 {
        self.energy
    }

    /// Whether edge `k` between nodes `i` and `j` agrees now: d_i = sgn(J)·d_j.
    fn agrees(&self, k: usize, i: usize, j: usize) -> bool {
        (self.d[i] * self.d[j]) as f64 * self.model.edges[k].j > 0.0
    }

    /// Draws a bond strength ([`Bonds`]), bonds agreeing edges with probability q, takes
    /// the component of a uniformly chosen node (only its component is needed, so bonds are
    /// drawn as the search meets them: each edge at most once, the same law as drawing them
    /// all first), and measures the flip. Choosing a node uniformly picks V0 with
    /// probability |V0|/n in both directions of the move, so the choice cancels from the
    /// ratio.
    pub fn propose(&mut self) -> Proposal {
        let n = self.model.len();
        if n == 0 {
            return Proposal {
                component: Vec::new(),
                delta_e: 0.0,
                log_q_ratio: 0.0,
            };
        }
        let level = if self.levels > 1 {
            self.rng.below(self.levels) as usize
        } else {
            0
        };
        let (q, log1mq) = (&self.q[level], &self.log1mq[level]);
        let start = self.rng.below(n as u32) as usize;
        let mut comp = vec![start];
        self.in_v0[start] = true;
        let mut head = 0;
        while head < comp.len() {
            let i = comp[head];
            head += 1;
            for a in 0..self.adj[i].len() {
                let (j, k) = self.adj[i][a];
                if self.in_v0[j] || !self.agrees(k, i, j) {
                    continue;
                }
                if uniform(&mut self.rng) < q[k] {
                    self.in_v0[j] = true;
                    comp.push(j);
                }
            }
        }
        // The cuts and the energy change: only unaries of V0 and edges leaving it change.
        let mut delta_e = 0.0;
        let mut log_q_ratio = 0.0;
        for &i in &comp {
            delta_e += 2.0 * self.model.h[i] * self.d[i] as f64;
            for &(j, k) in &self.adj[i] {
                if self.in_v0[j] {
                    continue;
                }
                delta_e += 2.0 * self.model.edges[k].j * (self.d[i] * self.d[j]) as f64;
                if self.agrees(k, i, j) {
                    // In C(V0, V_ℓ \ V0): this bond was off.
                    log_q_ratio -= log1mq[k];
                } else {
                    // In C(V0, V_ℓ' \ V0): the reverse move needs it off.
                    log_q_ratio += log1mq[k];
                }
            }
        }
        for &i in &comp {
            self.in_v0[i] = false;
        }
        Proposal {
            component: comp,
            delta_e,
            log_q_ratio,
        }
    }

    /// Applies a proposal made from the current state.
    pub fn apply(&mut self, p: &Proposal) {
        for &i in &p.component {
            self.d[i] = -self.d[i];
        }
        self.energy += p.delta_e;
    }

    /// One proposal, accepted with probability min(1, ratio). Returns whether it was.
    pub fn step(&mut self) -> bool {
        let p = self.propose();
        if p.component.is_empty() {
            return false;
        }
        let r = p.log_ratio();
        if r >= 0.0 || uniform(&mut self.rng).ln() < r {
            self.apply(&p);
            true
        } else {
            false
        }
    }
}

/// Largest model [`enumerate_marginals`] and [`ground_state`] accept.
pub const ENUMERATE_MAX: usize = 24;

fn check_enumerable(m: &PairModel) -> Result<()> {
    m.validate()?;
    if m.len() > ENUMERATE_MAX {
        return Err(Error::Invalid(format!(
            "enumeration of {} nodes: at most {ENUMERATE_MAX}",
            m.len()
        )));
    }
    Ok(())
}

fn labels_of(bits: u32, n: usize) -> Vec<i8> {
    (0..n)
        .map(|i| if bits >> i & 1 == 1 { 1 } else { -1 })
        .collect()
}

/// P(d_i = +1) for every node, by brute force over all 2^n labellings.
pub fn enumerate_marginals(m: &PairModel) -> Result<Vec<f64>> {
    check_enumerable(m)?;
    let n = m.len();
    let energies: Vec<f64> = (0..1u32 << n).map(|b| m.energy(&labels_of(b, n))).collect();
    let e0 = energies.iter().copied().fold(f64::INFINITY, f64::min);
    let mut z = 0.0;
    let mut up = vec![0.0; n];
    for (b, &e) in energies.iter().enumerate() {
        let p = (e0 - e).exp();
        z += p;
        for (i, u) in up.iter_mut().enumerate() {
            if b >> i & 1 == 1 {
                *u += p;
            }
        }
    }
    Ok(up.into_iter().map(|u| u / z).collect())
}

/// The lowest-energy labelling and its energy, by brute force.
pub fn ground_state(m: &PairModel) -> Result<(Vec<i8>, f64)> {
    check_enumerable(m)?;
    let n = m.len();
    let mut best = (labels_of(0, n), m.energy(&labels_of(0, n)));
    for b in 1..1u32 << n {
        let d = labels_of(b, n);
        let e = m.energy(&d);
        if e < best.1 {
            best = (d, e);
        }
    }
    Ok(best)
}

// ---------------------------------------------------------------------------------------
// The graph of a sketch.

/// One free direction variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Node {
    pub curve: usize,
    /// The sides whose label it is (both for a stream line).
    pub sides: [bool; 2],
}

/// What decides a curve side's label.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SideVar {
    /// A free variable, by node index.
    Node(usize),
    /// A known label (a dividing line's sides: +1, outward).
    Fixed(i8),
    /// No hair on that side.
    None,
}

/// The labels' variables, their energy, and the cells it came from.
#[derive(Clone, Debug)]
pub struct Graph {
    pub width: u32,
    pub height: u32,
    pub nodes: Vec<Node>,
    /// Per curve, per side.
    pub side_var: Vec<[SideVar; 2]>,
    /// The energy over all nodes, the fixed sides folded in.
    pub model: PairModel,
    /// The p_dir part of `model.h`.
    pub prior: Vec<f64>,
    /// Per pixel: the cell's side as 2·curve + side, u32::MAX outside every cell.
    pub cell: Vec<u32>,
    /// Per pixel: the growth direction there is sign · label · (cos Θ, sin Θ); 0 outside.
    pub sign: Vec<i8>,
    pub sketch_pixels: usize,
    pub cell_pixels: usize,
    /// Hair pixels (finite Θ) that no cell reaches (hair with no curve in it).
    pub unreached: usize,
    /// Pairs of adjacent sides, and those left out for sharing fewer than `min_border`
    /// pixel pairs.
    pub borders: usize,
    pub thin_contacts: usize,
}

/// Sketch pixels and whose they are: paint()'s rules (a pixel keeps the first primitive
/// that reaches it, in curve then primitive order).
struct Owners {
    /// 2·curve + side of a hair side's pixel, u32::MAX elsewhere.
    unit: Vec<u32>,
    /// That side's flow vector angle at the pixel.
    phi: Vec<f32>,
    /// Any window covers it (strips and non-hair sides too): walls for the cells.
    on: Vec<bool>,
}

fn owners(curves: &[Curve], w: u32, h: u32, hair: &[bool], theta: Option<&[f32]>) -> Owners {
    let n = w as usize * h as usize;
    let mut o = Owners {
        unit: vec![u32::MAX; n],
        phi: vec![f32::NAN; n],
        on: vec![false; n],
    };
    for (ci, c) in curves.iter().enumerate() {
        let hair_sides = c.kind.hair_sides();
        for p in &c.prims {
            window(c.kind, p, w, h, |k, side| {
                if o.on[k] {
                    return;
                }
                o.on[k] = true;
                let Some(s) = side.index() else { return };
                if !hair_sides[s] || !hair[k] || theta.is_some_and(|t| !t[k].is_finite()) {
                    return;
                }
                o.unit[k] = (2 * ci + s) as u32;
                o.phi[k] = p.side_angle(s);
            });
        }
    }
    o
}

/// Which variable each side of a curve of `kind` uses: `base` is the curve's first node.
fn side_vars(kind: Kind, base: usize) -> [SideVar; 2] {
    match kind {
        Kind::Boundary | Kind::Source => [SideVar::Node(base), SideVar::None],
        Kind::Occluding => [SideVar::Node(base), SideVar::Node(base + 1)],
        Kind::Dividing => [SideVar::Fixed(1), SideVar::Fixed(1)],
        Kind::Stream => [SideVar::Node(base), SideVar::Node(base)],
    }
}

fn check_inputs(theta: &[f32], hair: &[bool], w: u32, h: u32) -> Result<()> {
    let n = w as usize * h as usize;
    if theta.len() != n || hair.len() != n {
        return Err(Error::Invalid(format!(
            "directions: Θ has {} values and the mask {}, the image {w}x{h} has {n} pixels",
            theta.len(),
            hair.len()
        )));
    }
    Ok(())
}

/// Builds the adjacency graph and its pairwise energy (see the module docs). Pixels of
/// `hair` with a non-finite Θ are left out of the cells.
pub fn build_graph(
    curves: &[Curve],
    theta: &[f32],
    hair: &[bool],
    w: u32,
    h: u32,
    p: &SwcParams,
) -> Result<Graph> {
    check_inputs(theta, hair, w, h)?;
    let (wu, n) = (w as usize, w as usize * h as usize);

    let mut nodes = Vec::new();
    let mut side_var = Vec::with_capacity(curves.len());
    for (ci, c) in curves.iter().enumerate() {
        let before = nodes.len();
        let sv = side_vars(c.kind, before);
        match c.kind {
            Kind::Stream => nodes.push(Node {
                curve: ci,
                sides: [true, true],
            }),
            Kind::Occluding => {
                nodes.push(Node {
                    curve: ci,
                    sides: [true, false],
                });
                nodes.push(Node {
                    curve: ci,
                    sides: [false, true],
                });
            }
            Kind::Boundary | Kind::Source => nodes.push(Node {
                curve: ci,
                sides: [true, false],
            }),
            Kind::Dividing => {}
        }
        debug_assert_eq!(nodes.len() - before, c.kind.free_dirs());
        side_var.push(sv);
    }
    let var_of = |unit: u32| side_var[unit as usize / 2][unit as usize % 2];

    let own = owners(curves, w, h, hair, Some(theta));
    let open = |k: usize| hair[k] && theta[k].is_finite() && !own.on[k];

    // Geodesic Voronoi cells of the sides' sketch pixels, signs carried along Θ.
    let mut cell = vec![u32::MAX; n];
    let mut sign = vec![0i8; n];
    let mut dist = vec![u32::MAX; n];
    let mut parent = vec![u32::MAX; n];
    let mut heap = BinaryHeap::new();
    let mut sketch_pixels = 0;
    for k in 0..n {
        if own.unit[k] != u32::MAX {
            sketch_pixels += 1;
            cell[k] = own.unit[k];
            sign[k] = sgn(((theta[k] - own.phi[k]) as f64).cos());
            dist[k] = 0;
            heap.push(Reverse((0u32, k as u32)));
        }
    }
    const STEPS: [(i32, i32, u32); 8] = [
        (1, 0, 5),
        (-1, 0, 5),
        (0, 1, 5),
        (0, -1, 5),
        (1, 1, 7),
        (-1, 1, 7),
        (1, -1, 7),
        (-1, -1, 7),
    ];
    while let Some(Reverse((dk, k))) = heap.pop() {
        let k = k as usize;
        if dk > dist[k] {
            continue;
        }
        if cell[k] == u32::MAX {
            // Settled now; its parent, nearer, settled earlier.
            let q = parent[k] as usize;
            cell[k] = cell[q];
            sign[k] = sign[q] * sgn(((theta[k] - theta[q]) as f64).cos());
        }
        let (x, y) = ((k % wu) as i32, (k / wu) as i32);
        for (dx, dy, c) in STEPS {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
                continue;
            }
            let m = ny as usize * wu + nx as usize;
            if !open(m) || dist[m] <= dk + c {
                continue;
            }
            dist[m] = dk + c;
            parent[m] = k as u32;
            heap.push(Reverse((dk + c, m as u32)));
        }
    }

    // Pixel pairs: inside a cell a constant, across a border a coupling of two sides.
    let mut constant = 0f64;
    let mut cross: BTreeMap<(u32, u32), (usize, f64)> = BTreeMap::new();
    let mut cell_pixels = 0;
    let mut unreached = 0;
    for k in 0..n {
        if cell[k] == u32::MAX {
            unreached += (hair[k] && theta[k].is_finite() && !own.on[k]) as usize;
            continue;
        }
        cell_pixels += 1;
        let (x, y) = (k % wu, k / wu);
        let right = (x + 1 < wu).then_some(k + 1);
        let down = (y + 1 < h as usize).then_some(k + wu);
        for m in [right, down].into_iter().flatten() {
            if cell[m] == u32::MAX {
                continue;
            }
            let c = (sign[k] * sign[m]) as f64 * ((theta[k] - theta[m]) as f64).cos();
            if cell[k] == cell[m] {
                constant += 1.0 - c;
            } else {
                let key = (cell[k].min(cell[m]), cell[k].max(cell[m]));
                let e = cross.entry(key).or_insert((0, 0.0));
                e.0 += 1;
                e.1 += c;
            }
        }
    }

    let mut model = PairModel::new(nodes.len());
    let mut edge_j: BTreeMap<(usize, usize), f64> = BTreeMap::new();
    let (mut borders, mut thin_contacts) = (0, 0);
    for (&(a, b), &(count, j)) in &cross {
        if count < p.min_border {
            thin_contacts += 1;
            continue;
        }
        borders += 1;
        constant += count as f64;
        match (var_of(a), var_of(b)) {
            (SideVar::Node(i), SideVar::Node(k)) if i == k => constant -= j,
            (SideVar::Node(i), SideVar::Node(k)) => {
                *edge_j.entry((i.min(k), i.max(k))).or_insert(0.0) += j
            }
            (SideVar::Node(i), SideVar::Fixed(f)) | (SideVar::Fixed(f), SideVar::Node(i)) => {
                model.h[i] += j * f as f64
            }
            (SideVar::Fixed(fa), SideVar::Fixed(fb)) => constant -= j * (fa * fb) as f64,
            // Units exist only on hair sides, which always have a variable or a label.
            (SideVar::None, _) | (_, SideVar::None) => unreachable!("a cell on a non-hair side"),
        }
    }
    model.edges = edge_j
        .into_iter()
        .map(|((a, b), j)| Coupling { a, b, j })
        .collect();

    // −log p_dir on the sketch pixels: κ(1 − d·cos(φ − μ)).
    let mut prior = vec![0f64; nodes.len()];
    if let Some(crown) = p.prior.crown(hair, w, h) {
        let kappa = p.prior.kappa as f64;
        for k in 0..n {
            if own.unit[k] == u32::MAX {
                continue;
            }
            let mu = p
                .prior
                .mean(crown, (k % wu) as f32 + 0.5, (k / wu) as f32 + 0.5);
            let phi = own.phi[k];
            let c = kappa * (phi.cos() * mu[0] + phi.sin() * mu[1]) as f64;
            constant += kappa;
            match var_of(own.unit[k]) {
                SideVar::Node(i) => prior[i] += c,
                SideVar::Fixed(f) => constant -= c * f as f64,
                SideVar::None => unreachable!("a sketch pixel on a non-hair side"),
            }
        }
    }
    for (hi, pi) in model.h.iter_mut().zip(&prior) {
        *hi += pi;
    }
    model.constant = constant;

    Ok(Graph {
        width: w,
        height: h,
        nodes,
        side_var,
        model,
        prior,
        cell,
        sign,
        sketch_pixels,
        cell_pixels,
        unreached,
        borders,
        thin_contacts,
    })
}

impl Graph {
    /// The label of curve `c`'s side `s` under node labels `labels` (0 without hair).
    pub fn side_label(&self, c: usize, s: usize, labels: &[i8]) -> i8 {
        match self.side_var[c][s] {
            SideVar::Node(i) => labels[i],
            SideVar::Fixed(f) => f,
            SideVar::None => 0,
        }
    }

    /// The growth direction the labels give each cell pixel, NaN elsewhere: the field the
    /// energy was measured on (the fill computes the final one).
    pub fn field(&self, theta: &[f32], labels: &[i8]) -> Vec<[f32; 2]> {
        (0..self.cell.len())
            .map(|k| {
                let u = self.cell[k];
                if u == u32::MAX {
                    return [f32::NAN; 2];
                }
                let d = self.side_label(u as usize / 2, u as usize % 2, labels) * self.sign[k];
                let t = theta[k];
                [d as f32 * t.cos(), d as f32 * t.sin()]
            })
            .collect()
    }
}

/// Counts of the graph and of the result.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GraphStats {
    /// Free direction variables before clamping.
    pub nodes: usize,
    pub clamped: usize,
    /// Curve sides with a fixed label (dividing lines).
    pub fixed_sides: usize,
    /// Couplings between nodes.
    pub edges: usize,
    /// Couplings the chosen labels violate (J·d_i·d_j < 0): frustration left over.
    pub violated: usize,
    pub sketch_pixels: usize,
    pub cell_pixels: usize,
    pub unreached: usize,
}

/// Step 2's result.
#[derive(Clone, Debug)]
pub struct Directed {
    /// The input curves with `dirs` filled in.
    pub curves: Vec<Curve>,
    /// E of the chosen labels (Eq. 30 on the cells, the von Mises constant left out).
    pub energy: f64,
    /// Energy per sweep (SW), per pass (ICM), or the one value (prior).
    pub trace: Vec<f64>,
    pub proposals: usize,
    pub accepted: usize,
    pub stats: GraphStats,
    /// Per pixel, the growth direction of the cells under the chosen labels (NaN outside
    /// every cell); see [`Graph::field`].
    pub dir: Vec<[f32; 2]>,
}

/// The growth directions of `curves` (CZ06 Step 2). `theta` is the dense orientation field
/// on the w×h image (NaN allowed off the hair), `hair` the mask, `clamps` known labels
/// (see [`stroke_clamps`]). Input labels are ignored; dividing lines get [1, 1].
#[allow(clippy::too_many_arguments)] // The interface the plan fixes for the pipeline.
pub fn directions(
    curves: &[Curve],
    theta: &[f32],
    hair: &[bool],
    w: u32,
    h: u32,
    clamps: &[Clamp],
    p: &SwcParams,
    method: Method,
) -> Result<Directed> {
    let g = build_graph(curves, theta, hair, w, h, p)?;
    let mut fixed: Vec<Option<i8>> = vec![None; g.nodes.len()];
    for cl in clamps {
        let bad = |m: &str| {
            Err(Error::Invalid(format!(
                "clamp (curve {}, side {}, label {}): {m}",
                cl.curve, cl.side, cl.label
            )))
        };
        if cl.curve >= curves.len() || cl.side > 1 {
            return bad(&format!(
                "no such curve side ({} curves, sides 0 and 1)",
                curves.len()
            ));
        }
        if cl.label != 1 && cl.label != -1 {
            return bad("a label is +1 or −1");
        }
        match g.side_var[cl.curve][cl.side] {
            SideVar::Node(i) => {
                if fixed[i].is_some_and(|f| f != cl.label) {
                    return bad("contradicts another clamp on the same variable");
                }
                fixed[i] = Some(cl.label);
            }
            SideVar::Fixed(_) => return bad("a dividing line's directions are fixed outward"),
            SideVar::None => return bad("that side has no hair"),
        }
    }
    let (red, map) = g.model.condition(&fixed);
    let prior_labels: Vec<i8> = map.iter().map(|&i| sgn(g.prior[i])).collect();
    let run = match method {
        Method::Prior => Run {
            energy: red.energy(&prior_labels),
            trace: vec![red.energy(&prior_labels)],
            labels: prior_labels,
            proposals: 0,
            accepted: 0,
        },
        Method::Icm => red.icm(&prior_labels),
        Method::Swc => {
            let mut rng = Rng::new(p.seed ^ 0x5357_435f_696e_6974);
            let init: Vec<i8> = (0..red.len())
                .map(|_| if rng.next_u32() & 1 == 1 { 1 } else { -1 })
                .collect();
            red.swc(&init, p.sweeps, p.bonds, p.seed)
        }
    };
    let mut labels: Vec<i8> = fixed.iter().map(|f| f.unwrap_or(0)).collect();
    for (k, &i) in map.iter().enumerate() {
        labels[i] = run.labels[k];
    }
    let out_curves = curves
        .iter()
        .enumerate()
        .map(|(ci, c)| {
            let mut c = c.clone();
            c.dirs = [g.side_label(ci, 0, &labels), g.side_label(ci, 1, &labels)];
            c
        })
        .collect();
    let violated = g
        .model
        .edges
        .iter()
        .filter(|c| c.j * ((labels[c.a] * labels[c.b]) as f64) < 0.0)
        .count();
    let stats = GraphStats {
        nodes: g.nodes.len(),
        clamped: fixed.iter().filter(|f| f.is_some()).count(),
        fixed_sides: g
            .side_var
            .iter()
            .flatten()
            .filter(|v| matches!(v, SideVar::Fixed(_)))
            .count(),
        edges: g.model.edges.len(),
        violated,
        sketch_pixels: g.sketch_pixels,
        cell_pixels: g.cell_pixels,
        unreached: g.unreached,
    };
    Ok(Directed {
        curves: out_curves,
        energy: g.model.energy(&labels),
        trace: run.trace,
        proposals: run.proposals,
        accepted: run.accepted,
        stats,
        dir: g.field(theta, &labels),
    })
}

/// Stroke samples (1 px apart) a curve side must collect to be clamped by a stroke.
pub const STROKE_MIN_SAMPLES: usize = 5;
/// Least |mean cos| between stroke and flow over those samples: the stroke runs along the
/// side (either way) rather than across it, and the strokes on it agree.
pub const STROKE_MIN_ALIGN: f64 = 0.7;

/// Clamps from the user's direction strokes (points root to tip) for the curves they run
/// along: every stroke sample on a curve side's sketch pixels votes cos(stroke − flow) for
/// that side's variable; a variable with at least [`STROKE_MIN_SAMPLES`] votes whose mean
/// is at least [`STROKE_MIN_ALIGN`] in magnitude gets the sign of the sum. Sides without a free
/// variable (dividing lines) are skipped.
pub fn stroke_clamps(
    curves: &[Curve],
    strokes: &Strokes,
    hair: &[bool],
    w: u32,
    h: u32,
) -> Vec<Clamp> {
    let own = owners(curves, w, h, hair, None);
    // Per (curve, variable side): the first side it was seen on, Σcos, count.
    let mut votes: BTreeMap<(usize, usize), (usize, f64, usize)> = BTreeMap::new();
    for s in strokes
        .strokes
        .iter()
        .filter(|s| s.kind == StrokeKind::Direction)
    {
        for seg in s.points.windows(2) {
            let (dx, dy) = (seg[1][0] - seg[0][0], seg[1][1] - seg[0][1]);
            let len = dx.hypot(dy);
            if len < 1e-6 {
                continue;
            }
            let (tx, ty) = (dx / len, dy / len);
            let samples = len.ceil() as usize;
            for i in 0..samples {
                let t = (i as f32 + 0.5) / samples as f32;
                let (x, y) = (seg[0][0] + t * dx, seg[0][1] + t * dy);
                if x < 0.0 || y < 0.0 || x >= w as f32 || y >= h as f32 {
                    continue;
                }
                let k = y as usize * w as usize + x as usize;
                let u = own.unit[k];
                if u == u32::MAX {
                    continue;
                }
                let (c, side) = (u as usize / 2, u as usize % 2);
                let var_side = match curves[c].kind {
                    Kind::Dividing => continue,
                    Kind::Stream => 0,
                    _ => side,
                };
                let phi = own.phi[k];
                let cos = (tx * phi.cos() + ty * phi.sin()) as f64;
                let e = votes.entry((c, var_side)).or_insert((side, 0.0, 0));
                e.1 += cos;
                e.2 += 1;
            }
        }
    }
    votes
        .into_iter()
        .filter(|(_, v)| v.2 >= STROKE_MIN_SAMPLES && v.1.abs() / v.2 as f64 >= STROKE_MIN_ALIGN)
        .map(|((curve, _), (side, sum, _))| Clamp {
            curve,
            side,
            label: sgn(sum),
        })
        .collect()
}
