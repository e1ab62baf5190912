//! A pairwise binary model, E(d) = C − Σ J_ab d_a d_b − Σ h_a d_a over labels ±1, and its
//! samplers: Swendsen-Wang cuts with the Metropolis-Hastings ratio of CZ06 Eq. 28-30, ICM,
//! and brute-force enumeration for small graphs (the sampler's test). `swc` builds the model
//! from a sketch. Sequential, branchy work over a few hundred nodes: CPU.

use crate::base::rng::Rng;
use crate::error::{Error, Result};

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

/// The sign of x as a label (0 counts as +1).
pub(crate) fn sgn(x: f64) -> i8 {
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
