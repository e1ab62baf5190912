//! The segmentation graph on the 8-connected pixel grid and its Boykov-Kolmogorov max-flow.

use rayon::prelude::*;
use std::collections::VecDeque;

/// Neighbour offsets (dx, dy); direction `7 - d` is the opposite of `d`.
pub(super) use crate::base::mask::NEIGHBOURS_8 as DIRS;

/// GrabCut smoothness gamma * exp(-beta |dI|^2) / dist for every pixel and direction
/// (`n * 8`, zero towards outside the image), with beta = 1 / (2 <|dI|^2>) over all
/// neighbour pairs.
///
/// |dI|^2 splits the RGB step into its part along grey, l = mean of the channel steps
/// (3 l^2 of the squared distance), and the chroma left over; the grey part is weighted by
/// `lum^2`. Hair in a photo is lit on one side and shadowed on the other, and with `lum` 1
/// (GrabCut) the cheapest cut often runs along that shading edge inside the hair rather than
/// along the hair's outline, where the colour changes as well as the brightness.
pub(super) fn smoothness_weights(
    rgb: &[[f32; 3]],
    w: usize,
    h: usize,
    gamma: f32,
    lum: f32,
) -> Vec<f32> {
    let damp = 3.0 * (lum * lum - 1.0);
    let diff2 = |a: [f32; 3], b: [f32; 3]| {
        let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let l = (d[0] + d[1] + d[2]) / 3.0;
        // |d|^2 = chroma^2 + 3 l^2, so this is chroma^2 + 3 (lum l)^2 (never below 0).
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + damp * l * l).max(0.0)
    };
    let inside = |x: usize, y: usize, d: usize| {
        let (nx, ny) = (x as i64 + DIRS[d].0 as i64, y as i64 + DIRS[d].1 as i64);
        nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h
    };
    // Each unordered pair once (directions 4..8 point forward in raster order).
    let (sum, cnt) = (0..h)
        .into_par_iter()
        .map(|y| {
            let (mut s, mut c) = (0.0f64, 0u64);
            for x in 0..w {
                for (d, &(dx, dy)) in DIRS.iter().enumerate().skip(4) {
                    if inside(x, y, d) {
                        let j =
                            (y as i64 + dy as i64) as usize * w + (x as i64 + dx as i64) as usize;
                        s += diff2(rgb[y * w + x], rgb[j]) as f64;
                        c += 1;
                    }
                }
            }
            (s, c)
        })
        .collect::<Vec<_>>()
        .into_iter()
        .fold((0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    let mean = if cnt > 0 { sum / cnt as f64 } else { 0.0 };
    let beta = if mean > 0.0 { 0.5 / mean } else { 0.0 } as f32;
    let mut out = vec![0.0f32; w * h * 8];
    out.par_chunks_mut(w * 8).enumerate().for_each(|(y, row)| {
        for x in 0..w {
            for (d, &(dx, dy)) in DIRS.iter().enumerate() {
                if inside(x, y, d) {
                    let j = (y as i64 + dy as i64) as usize * w + (x as i64 + dx as i64) as usize;
                    let dist = if dx != 0 && dy != 0 {
                        std::f32::consts::SQRT_2
                    } else {
                        1.0
                    };
                    row[x * 8 + d] = gamma * (-beta * diff2(rgb[y * w + x], rgb[j])).exp() / dist;
                }
            }
        }
    });
    out
}

// ----------------------------------------------------------------------------------------
// Max-flow: Boykov-Kolmogorov (PAMI 2004) on the 8-connected grid.
//
// The grid is padded with a one-pixel frame of nodes that never join a tree, so arc heads
// need no bounds checks. Arc `a = node * 8 + d` goes from `node` towards `DIRS[d]`; its
// reverse is `head(a) * 8 + 7 - d`. Terminal links are folded into one signed residual per
// node (`tr > 0`: from the source, `tr < 0`: to the sink), as in Boykov's implementation.

pub(super) const NO_PARENT: u32 = u32::MAX;
pub(super) const TERMINAL: u32 = u32::MAX - 1;
pub(super) const ORPHAN: u32 = u32::MAX - 2;
pub(super) const T_FREE: u8 = 0;
pub(super) const T_SRC: u8 = 1;
pub(super) const T_SNK: u8 = 2;

pub(super) struct GridFlow {
    w: usize,
    h: usize,
    /// Padded width.
    pw: usize,
    off: [isize; 8],
    cap: Vec<f32>,
    tr: Vec<f32>,
    tree: Vec<u8>,
    parent: Vec<u32>,
    /// Timestamp and distance-to-terminal of the last validated path (BK's origin-search
    /// shortcut).
    ts: Vec<u32>,
    dist: Vec<u32>,
    time: u32,
    active: VecDeque<u32>,
    in_active: Vec<bool>,
    orphans: VecDeque<u32>,
}

impl GridFlow {
    pub(super) fn new(w: usize, h: usize) -> GridFlow {
        let pw = w + 2;
        let n = pw * (h + 2);
        let mut off = [0isize; 8];
        for (o, &(dx, dy)) in off.iter_mut().zip(DIRS.iter()) {
            *o = dy as isize * pw as isize + dx as isize;
        }
        GridFlow {
            w,
            h,
            pw,
            off,
            cap: vec![0.0; n * 8],
            tr: vec![0.0; n],
            tree: vec![T_FREE; n],
            parent: vec![NO_PARENT; n],
            ts: vec![0; n],
            dist: vec![0; n],
            time: 0,
            active: VecDeque::new(),
            in_active: vec![false; n],
            orphans: VecDeque::new(),
        }
    }

    pub(super) fn node(&self, i: usize) -> usize {
        (i / self.w + 1) * self.pw + i % self.w + 1
    }

    /// Sets the arc capacities (`smooth`, per image pixel and direction) and terminal
    /// residuals (`term(i)`: source minus sink capacity; +-inf for hard constraints) and
    /// clears any previous flow.
    pub(super) fn reset(&mut self, smooth: &[f32], term: impl Fn(usize) -> f32) {
        // Hard constraints: larger than any cut through the pixel's neighbourhood.
        let hard = smooth.iter().fold(0.0f32, |a, &b| a.max(b)) * 16.0 + 1e4;
        self.cap.iter_mut().for_each(|c| *c = 0.0);
        self.tr.iter_mut().for_each(|c| *c = 0.0);
        for i in 0..self.w * self.h {
            let v = self.node(i);
            self.cap[v * 8..v * 8 + 8].copy_from_slice(&smooth[i * 8..i * 8 + 8]);
            let t = term(i);
            self.tr[v] = if t.is_infinite() { hard.copysign(t) } else { t };
        }
        self.tree.iter_mut().for_each(|t| *t = T_FREE);
        self.parent.iter_mut().for_each(|p| *p = NO_PARENT);
        self.ts.iter_mut().for_each(|t| *t = 0);
        self.dist.iter_mut().for_each(|d| *d = 0);
        self.in_active.iter_mut().for_each(|a| *a = false);
        self.active.clear();
        self.orphans.clear();
        self.time = 0;
    }

    pub(super) fn head(&self, a: u32) -> usize {
        (a as usize / 8).wrapping_add_signed(self.off[a as usize % 8])
    }

    pub(super) fn sister(&self, a: u32) -> u32 {
        (self.head(a) * 8 + 7 - a as usize % 8) as u32
    }

    pub(super) fn activate(&mut self, v: usize) {
        if !self.in_active[v] {
            self.in_active[v] = true;
            self.active.push_back(v as u32);
        }
    }

    /// Whether image pixel `i` is on the source (hair) side of the minimum cut. Nodes in
    /// neither tree go to the sink, as in Boykov's implementation.
    pub(super) fn is_source(&self, i: usize) -> bool {
        self.tree[self.node(i)] == T_SRC
    }

    pub(super) fn max_flow(&mut self) {
        for v in 0..self.tr.len() {
            if self.tr[v] != 0.0 {
                self.tree[v] = if self.tr[v] > 0.0 { T_SRC } else { T_SNK };
                self.parent[v] = TERMINAL;
                self.dist[v] = 1;
                self.activate(v);
            }
        }
        let mut current: Option<usize> = None;
        loop {
            // Next active node still in a tree.
            let v = match current.take() {
                Some(v) if self.tree[v] != T_FREE => v,
                _ => loop {
                    match self.active.pop_front() {
                        None => return,
                        Some(v) => {
                            let v = v as usize;
                            self.in_active[v] = false;
                            if self.tree[v] != T_FREE {
                                break v;
                            }
                        }
                    }
                },
            };
            // Grow: find an arc joining the two trees (oriented source side -> sink side).
            let mut bridge = None;
            let src = self.tree[v] == T_SRC;
            for d in 0..8 {
                let a = (v * 8 + d) as u32;
                let out = if src {
                    self.cap[a as usize]
                } else {
                    self.cap[self.sister(a) as usize]
                };
                if out <= 0.0 {
                    continue;
                }
                let j = self.head(a);
                if self.tree[j] == T_FREE {
                    self.tree[j] = self.tree[v];
                    self.parent[j] = self.sister(a);
                    self.ts[j] = self.ts[v];
                    self.dist[j] = self.dist[v] + 1;
                    self.activate(j);
                } else if self.tree[j] != self.tree[v] {
                    bridge = Some(if src { a } else { self.sister(a) });
                    break;
                } else if self.ts[j] <= self.ts[v] && self.dist[j] > self.dist[v] {
                    // Shorter path to the terminal through v.
                    self.parent[j] = self.sister(a);
                    self.ts[j] = self.ts[v];
                    self.dist[j] = self.dist[v] + 1;
                }
            }
            let Some(bridge) = bridge else { continue };
            // v may have more bridges: come back to it.
            current = Some(v);
            self.time += 1;
            self.augment(bridge);
            self.adopt();
        }
    }

    pub(super) fn augment(&mut self, bridge: u32) {
        let s0 = bridge as usize / 8;
        let t0 = self.head(bridge);
        // Bottleneck.
        let mut f = self.cap[bridge as usize];
        let mut v = s0;
        loop {
            let p = self.parent[v];
            if p == TERMINAL {
                f = f.min(self.tr[v]);
                break;
            }
            f = f.min(self.cap[self.sister(p) as usize]);
            v = self.head(p);
        }
        let mut v = t0;
        loop {
            let p = self.parent[v];
            if p == TERMINAL {
                f = f.min(-self.tr[v]);
                break;
            }
            f = f.min(self.cap[p as usize]);
            v = self.head(p);
        }
        // Push.
        self.cap[bridge as usize] -= f;
        let sb = self.sister(bridge) as usize;
        self.cap[sb] += f;
        let mut v = s0;
        loop {
            let p = self.parent[v];
            if p == TERMINAL {
                self.tr[v] -= f;
                if self.tr[v] <= 0.0 {
                    self.make_orphan(v);
                }
                break;
            }
            let sp = self.sister(p) as usize;
            self.cap[sp] -= f;
            self.cap[p as usize] += f;
            let next = self.head(p);
            if self.cap[sp] <= 0.0 {
                self.make_orphan(v);
            }
            v = next;
        }
        let mut v = t0;
        loop {
            let p = self.parent[v];
            if p == TERMINAL {
                self.tr[v] += f;
                if self.tr[v] >= 0.0 {
                    self.make_orphan(v);
                }
                break;
            }
            let sp = self.sister(p) as usize;
            self.cap[p as usize] -= f;
            self.cap[sp] += f;
            let next = self.head(p);
            if self.cap[p as usize] <= 0.0 {
                self.make_orphan(v);
            }
            v = next;
        }
    }

    pub(super) fn make_orphan(&mut self, v: usize) {
        self.parent[v] = ORPHAN;
        self.orphans.push_back(v as u32);
    }

    /// Residual capacity along arc `a` in the direction the flow of `v`'s tree runs:
    /// into `v` for the source tree, out of `v` for the sink tree.
    pub(super) fn tree_cap(&self, src: bool, a: u32) -> f32 {
        if src {
            self.cap[self.sister(a) as usize]
        } else {
            self.cap[a as usize]
        }
    }

    pub(super) fn adopt(&mut self) {
        while let Some(v) = self.orphans.pop_front() {
            let v = v as usize;
            let t = self.tree[v];
            let src = t == T_SRC;
            // Find the neighbour with a valid origin and the shortest path to the terminal.
            let mut best: Option<(u32, u32)> = None;
            for d in 0..8 {
                let a = (v * 8 + d) as u32;
                if self.tree_cap(src, a) <= 0.0 {
                    continue;
                }
                let j0 = self.head(a);
                if self.tree[j0] != t {
                    continue;
                }
                let mut j = j0;
                let mut len = 0u32;
                let valid = loop {
                    if self.ts[j] == self.time {
                        len += self.dist[j];
                        break true;
                    }
                    let p = self.parent[j];
                    len += 1;
                    if p == TERMINAL {
                        self.ts[j] = self.time;
                        self.dist[j] = 1;
                        break true;
                    }
                    if p == ORPHAN || p == NO_PARENT {
                        break false;
                    }
                    j = self.head(p);
                };
                if !valid {
                    continue;
                }
                if best.is_none_or(|(_, bl)| len < bl) {
                    best = Some((a, len));
                }
                // Stamp the checked path so later searches stop early.
                let mut j = j0;
                let mut dl = len;
                while self.ts[j] != self.time {
                    self.ts[j] = self.time;
                    self.dist[j] = dl;
                    dl -= 1;
                    j = self.head(self.parent[j]);
                }
            }
            if let Some((a, len)) = best {
                self.parent[v] = a;
                self.ts[v] = self.time;
                self.dist[v] = len + 1;
                continue;
            }
            // No parent: v leaves the tree; its children become orphans and neighbours that
            // could reach it become active so the tree can regrow.
            for d in 0..8 {
                let a = (v * 8 + d) as u32;
                let j = self.head(a);
                if self.tree[j] != t {
                    continue;
                }
                if self.tree_cap(src, a) > 0.0 {
                    self.activate(j);
                }
                let pj = self.parent[j];
                if pj != TERMINAL && pj != ORPHAN && pj != NO_PARENT && self.head(pj) == v {
                    self.make_orphan(j);
                }
            }
            self.tree[v] = T_FREE;
            self.parent[v] = NO_PARENT;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::Rng;

    /// A random flow network solved by BK must give the same max-flow value as a plain
    /// Edmonds-Karp on the same graph, and the cut must cost exactly that.
    #[test]
    pub(super) fn max_flow_matches_reference() {
        let mut rng = Rng::new(7);
        for trial in 0..30 {
            let (w, h) = (2 + rng.below(7) as usize, 2 + rng.below(7) as usize);
            let n = w * h;
            let mut smooth = vec![0.0f32; n * 8];
            // Symmetric-free capacities: each direction independent, integers for exactness.
            for y in 0..h {
                for x in 0..w {
                    for (d, &(dx, dy)) in DIRS.iter().enumerate() {
                        let (nx, ny) = (x as i64 + dx as i64, y as i64 + dy as i64);
                        if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                            smooth[(y * w + x) * 8 + d] = rng.below(6) as f32;
                        }
                    }
                }
            }
            let term: Vec<f32> = (0..n).map(|_| rng.below(21) as f32 - 10.0).collect();
            let mut g = GridFlow::new(w, h);
            g.reset(&smooth, |i| term[i]);
            g.max_flow();
            // Cut cost of BK's labelling.
            let mut cut = 0.0f64;
            for i in 0..n {
                let s = g.is_source(i);
                if s && term[i] < 0.0 {
                    cut += -term[i] as f64;
                }
                if !s && term[i] > 0.0 {
                    cut += term[i] as f64;
                }
                for (d, &(dx, dy)) in DIRS.iter().enumerate() {
                    let c = smooth[i * 8 + d];
                    if c > 0.0 && s {
                        let j = ((i / w) as i64 + dy as i64) as usize * w
                            + ((i % w) as i64 + dx as i64) as usize;
                        if !g.is_source(j) {
                            cut += c as f64;
                        }
                    }
                }
            }
            let reference = edmonds_karp(w, h, &smooth, &term);
            assert_eq!(cut, reference, "trial {trial} ({w}x{h})");
        }
    }

    /// Three vertical bands: a shading step (the same colour, darker) and then a chroma step of
    /// the same RGB length. GrabCut's contrast (`lum` 1) prices both edges alike; with the
    /// luminance damped, cutting along the shading costs more than cutting along the chroma.
    #[test]
    fn damped_luminance_makes_shading_edges_dearer_than_colour_edges() {
        let (w, h) = (9, 4);
        // Lit hair, shadowed hair (-30 on every channel: all grey, |d| = 52), then a step
        // towards red of the same length (grey part 17, chroma 42).
        let (lit, shade, other) = (
            [150.0, 100.0, 60.0],
            [120.0, 70.0, 30.0],
            [150.0f32, 70.0, 30.0],
        );
        let mut third = other;
        let d: Vec<f32> = (0..3).map(|c| third[c] - shade[c]).collect();
        let norm = d.iter().map(|v| v * v).sum::<f32>().sqrt();
        for c in 0..3 {
            third[c] = shade[c] + d[c] * (30.0 * 3f32.sqrt()) / norm;
        }
        let rgb: Vec<[f32; 3]> = (0..w * h)
            .map(|i| match i % w {
                0..=2 => lit,
                3..=5 => shade,
                _ => third,
            })
            .collect();
        // Direction 4.. points forward; find the one pointing +x.
        let east = DIRS.iter().position(|&d| d == (1, 0)).unwrap();
        let at = |wts: &[f32], x: usize| wts[(w + x) * 8 + east];
        let grabcut = smoothness_weights(&rgb, w, h, 50.0, 1.0);
        assert!((at(&grabcut, 2) - at(&grabcut, 5)).abs() < 1e-3 * at(&grabcut, 2));
        let damped = smoothness_weights(&rgb, w, h, 50.0, 0.5);
        assert!(
            at(&damped, 2) > 2.0 * at(&damped, 5),
            "shading edge {} against colour edge {}",
            at(&damped, 2),
            at(&damped, 5)
        );
        // Flat regions keep the full weight either way.
        assert_eq!(at(&damped, 0), 50.0);
    }

    /// Max-flow value by BFS augmenting paths on a dense matrix (small graphs only).
    pub(super) fn edmonds_karp(w: usize, h: usize, smooth: &[f32], term: &[f32]) -> f64 {
        let n = w * h;
        let (s, t) = (n, n + 1);
        let mut c = vec![vec![0.0f64; n + 2]; n + 2];
        for i in 0..n {
            if term[i] > 0.0 {
                c[s][i] += term[i] as f64;
            } else {
                c[i][t] += -term[i] as f64;
            }
            for (d, &(dx, dy)) in DIRS.iter().enumerate() {
                let v = smooth[i * 8 + d] as f64;
                if v > 0.0 {
                    let j = ((i / w) as i64 + dy as i64) as usize * w
                        + ((i % w) as i64 + dx as i64) as usize;
                    c[i][j] += v;
                }
            }
        }
        let mut total = 0.0;
        loop {
            let mut prev = vec![usize::MAX; n + 2];
            prev[s] = s;
            let mut q = VecDeque::from([s]);
            while let Some(u) = q.pop_front() {
                for v in 0..n + 2 {
                    if prev[v] == usize::MAX && c[u][v] > 0.0 {
                        prev[v] = u;
                        q.push_back(v);
                    }
                }
            }
            if prev[t] == usize::MAX {
                return total;
            }
            let mut f = f64::INFINITY;
            let mut v = t;
            while v != s {
                f = f.min(c[prev[v]][v]);
                v = prev[v];
            }
            let mut v = t;
            while v != s {
                c[prev[v]][v] -= f;
                c[v][prev[v]] += f;
                v = prev[v];
            }
            total += f;
        }
    }
}
