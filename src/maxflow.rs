//! Boykov-Kolmogorov max-flow / min-cut on a graph with an explicit edge list, as used for
//! the edge-aware hair segmentation. Sequential by nature (augmenting paths), so CPU only.

use std::collections::VecDeque;

const NONE: u32 = u32::MAX;
/// Parent marker of a tree root (attached to the terminal).
const TERMINAL: u32 = u32::MAX - 1;

/// A graph with per-node terminal capacities and symmetric-pair arcs.
pub struct Graph {
    /// Per node: residual capacity from the source (>0) or to the sink (<0).
    tr_cap: Vec<f32>,
    /// Arcs: head node, next arc out of the same tail, residual capacity, sister arc = a ^ 1.
    head: Vec<u32>,
    next: Vec<u32>,
    cap: Vec<f32>,
    first: Vec<u32>,
}

impl Graph {
    pub fn new(nodes: usize) -> Self {
        Graph {
            tr_cap: vec![0.0; nodes],
            head: Vec::new(),
            next: Vec::new(),
            cap: Vec::new(),
            first: vec![NONE; nodes],
        }
    }

    /// Adds source→i capacity `source` and i→sink capacity `sink`.
    pub fn add_terminal(&mut self, i: usize, source: f32, sink: f32) {
        self.tr_cap[i] += source - sink;
    }

    /// Adds the arc pair i→j (capacity `cap_ij`) and j→i (`cap_ji`).
    pub fn add_edge(&mut self, i: usize, j: usize, cap_ij: f32, cap_ji: f32) {
        for (t, h, c) in [(i, j, cap_ij), (j, i, cap_ji)] {
            self.head.push(h as u32);
            self.next.push(self.first[t]);
            self.cap.push(c);
            self.first[t] = self.head.len() as u32 - 1;
        }
    }

    /// Runs the max-flow and returns, per node, whether it ends on the source side.
    pub fn min_cut(mut self) -> Vec<bool> {
        let n = self.tr_cap.len();
        // tree: 0 free, 1 source tree (S), 2 sink tree (T).
        let mut tree = vec![0u8; n];
        let mut parent = vec![NONE; n]; // arc from parent to node (S) or node to parent (T)
        let mut active: VecDeque<u32> = VecDeque::new();
        for i in 0..n {
            if self.tr_cap[i] > 0.0 {
                tree[i] = 1;
                parent[i] = TERMINAL;
                active.push_back(i as u32);
            } else if self.tr_cap[i] < 0.0 {
                tree[i] = 2;
                parent[i] = TERMINAL;
                active.push_back(i as u32);
            }
        }
        let mut orphans: Vec<u32> = Vec::new();
        loop {
            // Growth: find an arc joining the two trees.
            let mut meet: Option<u32> = None;
            while let Some(&p) = active.front() {
                let p = p as usize;
                if tree[p] == 0 {
                    active.pop_front();
                    continue;
                }
                let mut a = self.first[p];
                while a != NONE {
                    let ai = a as usize;
                    let q = self.head[ai] as usize;
                    // Residual capacity in the tree's direction: S grows along p→q, T along q→p.
                    let c = if tree[p] == 1 {
                        self.cap[ai]
                    } else {
                        self.cap[ai ^ 1]
                    };
                    if c > 0.0 {
                        if tree[q] == 0 {
                            tree[q] = tree[p];
                            parent[q] = if tree[p] == 1 { a } else { a ^ 1 };
                            active.push_back(q as u32);
                        } else if tree[q] != tree[p] {
                            meet = Some(if tree[p] == 1 { a } else { a ^ 1 });
                            break;
                        }
                    }
                    a = self.next[ai];
                }
                if meet.is_some() {
                    break;
                }
                active.pop_front();
            }
            let Some(mid) = meet else { break };
            // Augment along source → ... → tail(mid) → head(mid) → ... → sink.
            let mid = mid as usize;
            let tail = self.head[mid ^ 1] as usize;
            let headn = self.head[mid] as usize;
            let mut bottleneck = self.cap[mid];
            let mut v = tail;
            while parent[v] != TERMINAL {
                let a = parent[v] as usize;
                bottleneck = bottleneck.min(self.cap[a]);
                v = self.head[a ^ 1] as usize;
            }
            bottleneck = bottleneck.min(self.tr_cap[v]);
            let mut v = headn;
            while parent[v] != TERMINAL {
                let a = parent[v] as usize;
                bottleneck = bottleneck.min(self.cap[a]);
                v = self.head[a] as usize;
            }
            bottleneck = bottleneck.min(-self.tr_cap[v]);
            self.cap[mid] -= bottleneck;
            self.cap[mid ^ 1] += bottleneck;
            let mut v = tail;
            while parent[v] != TERMINAL {
                let a = parent[v] as usize;
                self.cap[a] -= bottleneck;
                self.cap[a ^ 1] += bottleneck;
                if self.cap[a] <= 0.0 {
                    parent[v] = NONE;
                    orphans.push(v as u32);
                }
                v = self.head[a ^ 1] as usize;
            }
            self.tr_cap[v] -= bottleneck;
            if self.tr_cap[v] <= 0.0 {
                parent[v] = NONE;
                orphans.push(v as u32);
            }
            let mut v = headn;
            while parent[v] != TERMINAL {
                let a = parent[v] as usize;
                self.cap[a] -= bottleneck;
                self.cap[a ^ 1] += bottleneck;
                if self.cap[a] <= 0.0 {
                    parent[v] = NONE;
                    orphans.push(v as u32);
                }
                v = self.head[a] as usize;
            }
            self.tr_cap[v] += bottleneck;
            if self.tr_cap[v] >= 0.0 {
                parent[v] = NONE;
                orphans.push(v as u32);
            }
            // Adoption: orphans find a new valid parent in their tree or become free.
            while let Some(o) = orphans.pop() {
                let o = o as usize;
                let t = tree[o];
                let mut found = NONE;
                let mut a = self.first[o];
                while a != NONE {
                    let ai = a as usize;
                    let q = self.head[ai] as usize;
                    // Arc from q to o in the tree direction must have residual capacity.
                    let c = if t == 1 {
                        self.cap[ai ^ 1]
                    } else {
                        self.cap[ai]
                    };
                    if tree[q] == t && c > 0.0 && self.rooted(q, &parent, t) {
                        found = if t == 1 { a ^ 1 } else { a };
                        break;
                    }
                    a = self.next[ai];
                }
                if found != NONE {
                    parent[o] = found;
                    continue;
                }
                // No parent: neighbours become active, children become orphans.
                let mut a = self.first[o];
                while a != NONE {
                    let ai = a as usize;
                    let q = self.head[ai] as usize;
                    if tree[q] == t {
                        let c = if t == 1 {
                            self.cap[ai ^ 1]
                        } else {
                            self.cap[ai]
                        };
                        if c > 0.0 {
                            active.push_back(q as u32);
                        }
                        let pq = parent[q];
                        if pq != NONE && pq != TERMINAL {
                            let from = if t == 1 {
                                self.head[pq as usize ^ 1]
                            } else {
                                self.head[pq as usize]
                            } as usize;
                            if from == o {
                                parent[q] = NONE;
                                orphans.push(q as u32);
                            }
                        }
                    }
                    a = self.next[ai];
                }
                tree[o] = 0;
                parent[o] = NONE;
            }
        }
        tree.iter().map(|&t| t == 1).collect()
    }

    /// Whether `v` still reaches its terminal through parents.
    fn rooted(&self, mut v: usize, parent: &[u32], t: u8) -> bool {
        let mut steps = 0usize;
        loop {
            let p = parent[v];
            if p == TERMINAL {
                return true;
            }
            if p == NONE || steps > parent.len() {
                return false;
            }
            v = if t == 1 {
                self.head[p as usize ^ 1]
            } else {
                self.head[p as usize]
            } as usize;
            steps += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Max-flow value by brute force over all cuts of a small graph.
    fn brute(n: usize, t: &[(usize, f32, f32)], e: &[(usize, usize, f32, f32)]) -> f32 {
        let mut best = f32::MAX;
        for mask in 0..(1u32 << n) {
            let s = |i: usize| mask & (1 << i) != 0;
            let mut c = 0.0;
            for &(i, src, snk) in t {
                c += if s(i) { snk } else { src };
            }
            for &(i, j, a, b) in e {
                if s(i) && !s(j) {
                    c += a;
                }
                if s(j) && !s(i) {
                    c += b;
                }
            }
            best = best.min(c);
        }
        best
    }

    #[test]
    fn min_cut_matches_brute_force_on_random_graphs() {
        let mut rng = crate::rng::Rng::new(7);
        for _ in 0..200 {
            let n = 2 + rng.below(7) as usize;
            let t: Vec<(usize, f32, f32)> = (0..n)
                .map(|i| {
                    (
                        i,
                        rng.range_f32(0.0, 3.0).floor(),
                        rng.range_f32(0.0, 3.0).floor(),
                    )
                })
                .collect();
            let mut e = Vec::new();
            for _ in 0..rng.below(12) {
                let (i, j) = (rng.below(n as u32) as usize, rng.below(n as u32) as usize);
                if i != j {
                    e.push((
                        i,
                        j,
                        rng.range_f32(0.0, 4.0).floor(),
                        rng.range_f32(0.0, 4.0).floor(),
                    ));
                }
            }
            let mut g = Graph::new(n);
            for &(i, a, b) in &t {
                g.add_terminal(i, a, b);
            }
            for &(i, j, a, b) in &e {
                g.add_edge(i, j, a, b);
            }
            let side = g.min_cut();
            // The cut the solver returns must be a minimum cut.
            let mut c = 0.0;
            for &(i, src, snk) in &t {
                c += if side[i] { snk } else { src };
            }
            for &(i, j, a, b) in &e {
                if side[i] && !side[j] {
                    c += a;
                }
                if side[j] && !side[i] {
                    c += b;
                }
            }
            assert_eq!(c, brute(n, &t, &e), "graph {t:?} {e:?}");
        }
    }
}
