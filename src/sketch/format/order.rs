//! The order of a sketch's curves, and how `.czs` version 5 stores it cheaply.
//!
//! Order matters in one place: a pixel two curves' windows cover is painted by the first
//! curve ([`prim::paint`]). Only the relative order of curves whose windows overlap
//! changes the painting, so version 5 stores the curves sorted by start (row, then column:
//! the starts then cost their row gaps and columns) and, for each overlapping pair, one bit
//! saying which paints first. The reader rebuilds the paint order as the topological order
//! of those pairs that takes the earliest stored curve available ([`from_precedence`]); a
//! sketch whose curves already come in that order (the pursuit's do: [`paint_order`]) is
//! stored so, any other by its full permutation.
//!
//! A graph over a few hundred curves: sequential, CPU.

use super::super::prim;
use super::super::Curve;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Pairs [a, b], a < b, of `curves` whose windows share a pixel of the w×h image, sorted.
pub(super) fn overlap_pairs(curves: &[Curve], w: u32, h: u32) -> Vec<[u32; 2]> {
    // (pixel, curve) for every window pixel, grouped by pixel: memory in proportion to the
    // windows, not to the image (a damaged file may claim any size).
    let mut on: Vec<(usize, u32)> = Vec::new();
    for (ci, c) in curves.iter().enumerate() {
        for p in &c.prims {
            prim::window(c.kind, p, w, h, |k, _| on.push((k, ci as u32)));
        }
    }
    on.sort_unstable();
    on.dedup();
    let mut pairs = Vec::new();
    for group in on.chunk_by(|a, b| a.0 == b.0) {
        for (i, &(_, a)) in group.iter().enumerate() {
            pairs.extend(group[i + 1..].iter().map(|&(_, b)| [a, b]));
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// The paint order of `n` stored curves from the overlapping `pairs` ([a, b], a < b) and
/// whether each one's b paints first: the topological order that takes the earliest
/// stored curve available. None when the bits contradict each other (a damaged file).
pub(super) fn from_precedence(n: usize, pairs: &[[u32; 2]], b_first: &[bool]) -> Option<Vec<u32>> {
    let mut after: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut blocked = vec![0u32; n];
    for (&[a, b], &bf) in pairs.iter().zip(b_first) {
        let (x, y) = if bf { (b, a) } else { (a, b) };
        after[x as usize].push(y);
        blocked[y as usize] += 1;
    }
    let mut ready: BinaryHeap<Reverse<u32>> = (0..n as u32)
        .filter(|&i| blocked[i as usize] == 0)
        .map(Reverse)
        .collect();
    let mut order = Vec::with_capacity(n);
    while let Some(Reverse(i)) = ready.pop() {
        order.push(i);
        for &y in &after[i as usize] {
            blocked[y as usize] -= 1;
            if blocked[y as usize] == 0 {
                ready.push(Reverse(y));
            }
        }
    }
    (order.len() == n).then_some(order)
}

/// The stored order of curves with starts `starts` (x, y): by row, then column, ties in
/// their given order. `stored[k]` is the given index of the k-th stored curve.
pub(super) fn stored_order(starts: &[[u32; 2]]) -> Vec<u32> {
    let mut stored: Vec<u32> = (0..starts.len() as u32).collect();
    stored.sort_by_key(|&i| (starts[i as usize][1], starts[i as usize][0]));
    stored
}

/// For curves given in paint order, stored in `stored` order with overlapping `pairs` (in
/// stored indices): whether each pair's later stored curve paints first.
pub(super) fn precedence(stored: &[u32], pairs: &[[u32; 2]]) -> Vec<bool> {
    pairs
        .iter()
        .map(|&[a, b]| stored[b as usize] < stored[a as usize])
        .collect()
}

/// `curves` (in paint order, on the `.czs` lattice) reordered as `.czs` version 5 reads
/// them back from their stored order and overlaps ([`from_precedence`]): the painting is
/// the same (every overlapping pair keeps its order), and the file stores the order in a
/// bit per overlapping pair instead of a permutation.
pub fn paint_order(curves: Vec<Curve>, w: u32, h: u32) -> Vec<Curve> {
    let starts: Vec<[u32; 2]> = curves
        .iter()
        .map(|c| super::curve_start(c, w, h).unwrap_or([0, 0]))
        .collect();
    let stored = stored_order(&starts);
    // The overlaps of the curves as the file stores them (on the lattice), as the writer
    // and the reader find them.
    let lattice: Vec<Curve> = stored
        .iter()
        .map(|&i| {
            let c = &curves[i as usize];
            super::curve_codes(c, w, h).map_or_else(
                || Curve {
                    prims: Vec::new(),
                    ..c.clone()
                },
                |cc| super::decode_curve(&cc),
            )
        })
        .collect();
    let pairs = overlap_pairs(&lattice, w, h);
    let order = from_precedence(curves.len(), &pairs, &precedence(&stored, &pairs))
        .expect("a paint order's precedences have no cycle");
    let mut slots: Vec<Option<Curve>> = curves.into_iter().map(Some).collect();
    order
        .into_iter()
        .map(|k| {
            slots[stored[k as usize] as usize]
                .take()
                .expect("each curve once")
        })
        .collect()
}

/// The curves not yet placed in a permutation, 0..n, with rank and select in O(log n) (a
/// Fenwick tree of counts): a damaged file may claim tens of thousands of curves.
pub(super) struct Ranks {
    tree: Vec<u32>,
    left: u32,
}

impl Ranks {
    pub(super) fn new(n: usize) -> Self {
        let mut tree = vec![0u32; n + 1];
        for i in 1..=n {
            tree[i] += 1;
            let j = i + (i & i.wrapping_neg());
            if j <= n {
                tree[j] += tree[i];
            }
        }
        Ranks {
            tree,
            left: n as u32,
        }
    }

    pub(super) fn len(&self) -> u32 {
        self.left
    }

    fn remove(&mut self, v: u32) {
        let mut i = v as usize + 1;
        while i < self.tree.len() {
            self.tree[i] -= 1;
            i += i & i.wrapping_neg();
        }
        self.left -= 1;
    }

    /// The rank of `v` (still there) among those left; removes it.
    pub(super) fn take(&mut self, v: u32) -> u32 {
        let (mut i, mut below) = (v as usize, 0u32);
        while i > 0 {
            below += self.tree[i];
            i -= i & i.wrapping_neg();
        }
        self.remove(v);
        below
    }

    /// The value of rank `r` (< len) among those left; removes it.
    pub(super) fn nth(&mut self, mut r: u32) -> u32 {
        let n = self.tree.len() - 1;
        let (mut pos, mut step) = (0usize, n.checked_ilog2().map_or(0, |b| 1usize << b));
        while step > 0 {
            let next = pos + step;
            if next <= n && self.tree[next] <= r {
                pos = next;
                r -= self.tree[next];
            }
            step >>= 1;
        }
        self.remove(pos as u32);
        pos as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(x: f32, y: f32, axis: f32, n: usize) -> Curve {
        Curve::straight(x, y, axis, n, 6.0, 8.0, 1)
    }

    /// Crossing curves keep their relative order, separate ones move to start order, and
    /// the painting is the same.
    #[test]
    fn paint_order_keeps_the_painting_and_sorts_the_rest() {
        let (w, h) = (120, 100);
        // 0 and 1 cross (1 starts above 0); 2 and 3 are apart from everything.
        let curves = vec![
            curve(10.0, 50.0, 0.0, 12),
            curve(40.0, 20.0, std::f32::consts::FRAC_PI_2, 10),
            curve(100.0, 90.0, 0.0, 2),
            curve(100.0, 5.0, 0.0, 2),
        ];
        let pairs = overlap_pairs(&curves, w, h);
        assert_eq!(pairs, vec![[0, 1]]);
        let ordered = paint_order(curves.clone(), w, h);
        let starts: Vec<f32> = ordered.iter().map(|c| c.prims[0].y).collect();
        assert_eq!(starts, vec![5.0, 50.0, 20.0, 90.0]);
        let (a, b) = (
            prim::paint(&curves, w, h, None),
            prim::paint(&ordered, w, h, None),
        );
        assert_eq!(a.theta.len(), b.theta.len());
        for i in 0..a.theta.len() {
            assert_eq!(a.on[i], b.on[i]);
            assert!(a.theta[i].to_bits() == b.theta[i].to_bits(), "pixel {i}");
        }
        // The other way round, the crossing pair's order is kept too.
        let swapped = vec![curves[1].clone(), curves[0].clone()];
        let ordered = paint_order(swapped, w, h);
        assert_eq!(ordered[0].prims[0].y, 20.0);
        // Contradicting bits are refused.
        assert!(from_precedence(2, &[[0, 1]], &[true]) == Some(vec![1, 0]));
        assert!(from_precedence(3, &[[0, 1], [1, 2], [0, 2]], &[false, false, true]).is_none());
    }

    /// Rank and select agree with a plain list, and a permutation round trips.
    #[test]
    fn ranks_match_a_list() {
        let n = 37;
        let perm: Vec<u32> = (0..n).map(|k| (k * 17 + 5) % n).collect();
        let (mut r, mut list) = (Ranks::new(n as usize), (0..n).collect::<Vec<u32>>());
        let mut ranks = Vec::new();
        for &v in &perm {
            let at = list.iter().position(|&x| x == v).unwrap();
            list.remove(at);
            let k = r.take(v);
            assert_eq!(k as usize, at);
            ranks.push(k);
            assert_eq!(r.len() as usize, list.len());
        }
        let mut r = Ranks::new(n as usize);
        let back: Vec<u32> = ranks.iter().map(|&k| r.nth(k)).collect();
        assert_eq!(back, perm);
        assert_eq!(Ranks::new(0).len(), 0);
    }
}
