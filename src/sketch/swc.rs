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

use super::pairwise::sgn;
pub use super::pairwise::{
    enumerate_marginals, ground_state, Bond, Bonds, Coupling, PairModel, Proposal, Run, Sampler,
};
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
        by_name(&Method::ALL, Method::name, "direction method", s)
    }
}

/// The one of `all` that `name` calls `s`, or an error naming `what` and the choices.
fn by_name<T: Copy>(all: &[T], name: fn(T) -> &'static str, what: &str, s: &str) -> Result<T> {
    all.iter().copied().find(|&v| name(v) == s).ok_or_else(|| {
        let names: Vec<&str> = all.iter().map(|&v| name(v)).collect();
        Error::Invalid(format!(
            "unknown {what} \"{s}\" (expected one of {})",
            names.join(", ")
        ))
    })
}

/// Where across the hair [`DirPrior`]'s crown sits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Crown {
    /// Over the parting Step 1's Θ shows at the top of the hair, or the mask's centroid
    /// where it shows none ([`DirPrior::parting_x`]).
    Parting,
    /// Over the mask's centroid (the default): CZ06's generic prior, which leaves a side
    /// parting to the sketch (a dividing line) and to the curves' compatibility.
    Centroid,
}

impl Crown {
    pub const ALL: [Crown; 2] = [Crown::Parting, Crown::Centroid];

    pub fn name(self) -> &'static str {
        match self {
            Crown::Parting => "parting",
            Crown::Centroid => "centroid",
        }
    }
}

impl FromStr for Crown {
    type Err = Error;
    fn from_str(s: &str) -> Result<Crown> {
        by_name(&Crown::ALL, Crown::name, "crown", s)
    }
}

/// The direction prior's default κ. Weak next to the compatibility (J sums one unit per
/// border pixel pair, h κ per sketch pixel): the prior breaks each connected cluster's
/// global sign, the curves' compatibility decides the rest. Chosen by a scan on the
/// synthetic styles (README, `coif sketch`, Step 2): at κ 1 the prior overrules the
/// compatibility where a whorl or a side parting sends hair against it.
pub const DEFAULT_PRIOR_WEIGHT: f32 = 0.2;

/// p_dir of Eq. 5-6 without hand sketches to learn it from: a von Mises density of the
/// growth direction around μ(p) = norm((p − c)/|p − c| + gravity·ŷ), outward from a crown c
/// = (the parting's x, or the mask centroid's: [`Crown`]; mask top + crown_depth · mask
/// height) and bent down.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirPrior {
    /// Concentration κ; −log p_dir = κ(1 − cos(τ − μ)) per sketch pixel, up to a constant.
    /// The prior-only baseline takes each curve's sign from it, whatever κ; Swendsen-Wang
    /// weighs it against the compatibility.
    pub kappa: f32,
    /// Weight of the downward pull added to the outward unit vector.
    pub gravity: f32,
    /// The crown's depth below the top of the mask, as a fraction of the mask's height.
    pub crown_depth: f32,
    /// Where across the hair the crown sits.
    pub crown: Crown,
}

impl Default for DirPrior {
    fn default() -> Self {
        DirPrior {
            kappa: DEFAULT_PRIOR_WEIGHT,
            gravity: 0.5,
            crown_depth: 0.15,
            crown: Crown::Centroid,
        }
    }
}

impl DirPrior {
    /// The crown c of the mask, None when the mask is empty: at `crown_depth` of the mask's
    /// height below its top, and across (with [`Crown::Parting`]) at the parting that Θ
    /// shows there (see [`parting_x`](Self::parting_x)), or at the mask's centroid where Θ
    /// shows none or with [`Crown::Centroid`].
    pub fn crown(&self, hair: &[bool], theta: &[f32], w: u32, h: u32) -> Option<[f32; 2]> {
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
            let depth = self.crown_depth * height;
            let band = top..(top + depth.ceil().max(1.0) as u32).min(h);
            let centroid = (sx / n as f64) as f32;
            let x = match self.crown {
                Crown::Parting => Self::parting_x(hair, theta, w, band).unwrap_or(centroid),
                Crown::Centroid => centroid,
            };
            [x, top as f32 + depth]
        })
    }

    /// Where, across the rows `band` (the top of the hair), the hair's slope changes from
    /// falling to the left to falling to the right: the split x maximising
    /// −Σ_{x′<x} sin 2Θ + Σ_{x′≥x} sin 2Θ over the band's hair (y down, so hair falling to
    /// the left has sin 2Θ < 0). A side parting puts the crown over the parting rather than
    /// over the mask's centroid, so the prior does not send the hair between them the wrong
    /// way. Searched over the middle 80% of the band's hair span; the middle of the splits
    /// within 2% of Σ|sin 2Θ| of the best; None when the band has no orientation, or the
    /// best split explains under a quarter of Σ|sin 2Θ| (no parting).
    pub fn parting_x(
        hair: &[bool],
        theta: &[f32],
        w: u32,
        band: std::ops::Range<u32>,
    ) -> Option<f32> {
        let wu = w as usize;
        let mut col = vec![0f64; wu];
        let (mut lo, mut hi, mut total) = (usize::MAX, 0usize, 0f64);
        for y in band {
            for (x, c) in col.iter_mut().enumerate() {
                let k = y as usize * wu + x;
                if hair[k] && theta[k].is_finite() {
                    let s = (2.0 * theta[k] as f64).sin();
                    *c += s;
                    total += s.abs();
                    lo = lo.min(x);
                    hi = hi.max(x);
                }
            }
        }
        if lo > hi || total <= 0.0 {
            return None;
        }
        let span = (hi - lo + 1) as f64;
        let (a, b) = (
            lo + (0.1 * span).round() as usize,
            hi + 1 - (0.1 * span).round() as usize,
        );
        // S(x) = −Σ_{x′<x} s + Σ_{x′≥x} s = Σ s − 2 Σ_{x′<x} s.
        let sum: f64 = col.iter().sum();
        let mut below: f64 = col[..a].iter().sum();
        let mut score = Vec::with_capacity(b.saturating_sub(a));
        for &c in col.iter().take(b.max(a + 1)).skip(a) {
            score.push(sum - 2.0 * below);
            below += c;
        }
        let (best, at) =
            score.iter().enumerate().fold(
                (f64::NEG_INFINITY, 0),
                |m, (i, &v)| if v > m.0 { (v, i) } else { m },
            );
        if best < 0.25 * total {
            return None;
        }
        // The parting strip (scalp, hair across it) scores nearly flat: take the middle of
        // the run of splits within 2% of the best, not its first column, so that the crown
        // does not sit at one edge of the strip and turn that edge's hair the wrong way.
        let near = |i: usize| score[i] >= best - 0.02 * total;
        let mut first = at;
        while first > 0 && near(first - 1) {
            first -= 1;
        }
        let mut last = at;
        while last + 1 < score.len() && near(last + 1) {
            last += 1;
        }
        Some(a as f32 + 0.5 * (first + last) as f32)
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
    if let Some(crown) = p.prior.crown(hair, theta, w, h) {
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

#[cfg(test)]
mod tests {
    use super::DirPrior;

    /// Θ on a 100 x 10 band: falling to the left (135°) left of `split`, to the right (45°)
    /// from it on.
    fn band(split: usize) -> (Vec<bool>, Vec<f32>) {
        let theta = (0..1000)
            .map(|k| {
                let deg: f32 = if k % 100 < split { 135.0 } else { 45.0 };
                deg.to_radians()
            })
            .collect();
        (vec![true; 1000], theta)
    }

    #[test]
    fn the_parting_is_where_the_slope_turns() {
        for split in [30, 50, 71] {
            let (hair, theta) = band(split);
            assert_eq!(
                DirPrior::parting_x(&hair, &theta, 100, 0..10),
                Some(split as f32)
            );
        }
        // Flat hair shows no parting; nor does hair with no orientation.
        let hair = vec![true; 1000];
        assert_eq!(
            DirPrior::parting_x(&hair, &vec![0.0; 1000], 100, 0..10),
            None
        );
        assert_eq!(
            DirPrior::parting_x(&hair, &vec![f32::NAN; 1000], 100, 0..10),
            None
        );
        // A crown from it with `Crown::Parting`: the parting's x, not the centroid's, which
        // the default crown takes.
        let (hair, theta) = band(30);
        let at = |crown| {
            let p = DirPrior {
                crown,
                ..DirPrior::default()
            };
            p.crown(&hair, &theta, 100, 10).unwrap()[0]
        };
        assert_eq!(at(super::Crown::Parting), 30.0);
        assert_eq!(at(super::Crown::Centroid), 50.0);
    }
}
