//! The pursuit's scores, CPU: a candidate primitive's ranking δ over a window (prepared
//! once per window and kind, then per dictionary variant), and its exact δ with the field
//! around relaxed.

use super::*;

/// A window's pixels as [`Search::delta_prep`] leaves them for scoring variants.
pub(super) struct DeltaPrep {
    px: Vec<PrepPx>,
    /// Per side, the along-flow direction of the structure tensor over its pixels (3.75°
    /// units of the doubled angle, unwrapped).
    jstar: [f32; 2],
}

pub(super) struct PrepPx {
    i: u32,
    side: u8,
    e1_old: f32,
    lp_old: f32,
    edges: [f32; 2],
    n_edges: u8,
}

impl Search<'_> {
    /// The ranking score (the paper's approximation, before λ_NC or the turn cost) of
    /// painting `win` as a `kind` primitive with axis `a` (15° steps) and side angles from
    /// the dictionary indices `dict`: the E1 and contrast terms of the pixels it takes and
    /// the edges among them, Θ elsewhere and the window's border edges unchanged. Each side's
    /// refinement (when `refine_sides`) turns it toward the structure tensor's along-flow
    /// direction over the side's pixels (E1 is linear in z = e^{2iθ}, so the best is ½ arg
    /// of its coefficient and the nearest allowed refinement is the best allowed; the field
    /// around is left out, or a seam's side would follow the blur it is meant to replace).
    /// Returns the score, the refinement codes and the sides' double-angle vectors.
    pub(super) fn delta(
        &mut self,
        win: &Win,
        kind: Kind,
        a: i32,
        dict: [u8; 2],
    ) -> (f32, [u8; 2], [[f32; 2]; 2]) {
        let prep = self.delta_prep(win, kind);
        self.delta_with(&prep, kind, a, dict)
    }

    /// What [`Self::delta`] computes once per window and kind, shared by every dictionary
    /// variant scored on it: the pixels a primitive would take, in window order, with their
    /// current terms, and each side's tensor direction.
    pub(super) fn delta_prep(&mut self, win: &Win, kind: Kind) -> DeltaPrep {
        let f = self.f;
        let hair_sides = kind.hair_sides();
        self.gen = self.gen.wrapping_add(1);
        let gen = self.gen;
        for &(i, s) in &win.px {
            let i = i as usize;
            if let Some(k) = s.index() {
                if hair_sides[k] && f.hair[i] && !self.on[i] {
                    self.mark[i] = gen;
                }
            }
        }
        let (w, h) = (f.width as usize, f.height as usize);
        let mut px = Vec::with_capacity(win.px.len());
        let mut g = [[0.0f32; 2]; 2];
        for &(i, s) in &win.px {
            let i = i as usize;
            if self.mark[i] != gen {
                continue;
            }
            let k = s.index().expect("marked pixels lie on a side");
            g[k][0] += f.data[i][0];
            g[k][1] += f.data[i][1];
            let zo = self.z[i];
            // Edges with both ends taken stop costing; each is counted from its lower end
            // (right and down neighbours), as the score adds them.
            let (x, y) = (i % w, i / w);
            let mut edges = [0.0f32; 2];
            let mut n_edges = 0;
            for j in [(x + 1 < w).then(|| i + 1), (y + 1 < h).then(|| i + w)]
                .into_iter()
                .flatten()
            {
                if f.hair[j] && self.mark[j] == gen {
                    edges[n_edges] = f.edge(self.z[j], zo);
                    n_edges += 1;
                }
            }
            px.push(PrepPx {
                i: i as u32,
                side: k as u8,
                e1_old: f.e1(i, zo),
                lp_old: self.nsk.at(f.rho(i, zo)),
                edges,
                n_edges: n_edges as u8,
            });
        }
        let jstar = [0, 1].map(|k| g[k][1].atan2(g[k][0]) * (24.0 / std::f32::consts::PI));
        DeltaPrep { px, jstar }
    }

    /// [`Self::delta`] for one dictionary variant on a prepared window (the same sums in the
    /// same order, so the same score to the bit).
    pub(super) fn delta_with(
        &self,
        prep: &DeltaPrep,
        kind: Kind,
        a: i32,
        dict: [u8; 2],
    ) -> (f32, [u8; 2], [[f32; 2]; 2]) {
        let f = self.f;
        let hair_sides = kind.hair_sides();
        // Dictionary orientation of each side in 3.75° units, and the sign a refinement
        // turns it by (θ = axis − angle on the left, axis + angle on the right).
        let base = [
            4 * a - DICT_FINE[dict[0] as usize],
            4 * a + DICT_FINE[dict[1] as usize],
        ];
        let sign = [-1, 1];
        let mut code = [NO_REFINE; 2];
        if self.p.refine_sides {
            for k in 0..2 {
                if !hair_sides[k] {
                    continue;
                }
                let mut o = prep.jstar[k] - base[k] as f32;
                o -= 48.0 * ((o + 24.0) / 48.0).floor();
                let r = ((sign[k] as f32 * o + 0.5).floor() as i32).clamp(-8, 7);
                code[k] = (r + NO_REFINE as i32) as u8;
            }
        }
        let zb = [0, 1].map(|k| self.z_of(base[k] + sign[k] * (code[k] as i32 - NO_REFINE as i32)));
        let new = if self.sk_kind(kind) {
            &self.sk
        } else {
            &self.nsk
        };
        let mut d = 0.0f32;
        for q in &prep.px {
            let i = q.i as usize;
            let zn = zb[q.side as usize];
            d += q.e1_old - f.e1(i, zn);
            d += new.at(f.rho(i, zn)) - q.lp_old;
            for &e in &q.edges[..q.n_edges as usize] {
                d += e;
            }
        }
        (d, code, zb)
    }

    /// The sides' double-angle vectors of candidate `c` (its refinement codes as they are).
    pub(super) fn zb_of(&self, c: &Cand) -> [[f32; 2]; 2] {
        let base = [
            4 * c.axis - DICT_FINE[c.dict[0] as usize],
            4 * c.axis + DICT_FINE[c.dict[1] as usize],
        ];
        [0, 1].map(|k| {
            let r = c.code[k] as i32 - NO_REFINE as i32;
            self.z_of(base[k] + if k == 0 { -r } else { r })
        })
    }

    /// E over the hair pixels of the box [x0, x1) × [y0, y1) and the edges with an end in it.
    pub(super) fn local_energy(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> f64 {
        let f = self.f;
        let (w, h) = (f.width as usize, f.height as usize);
        let mut e = 0.0f64;
        for y in y0..y1 {
            for x in x0..x1 {
                let i = y * w + x;
                if !f.hair[i] {
                    continue;
                }
                let zi = self.z[i];
                let r = f.rho(i, zi);
                let lp = if self.fixed[i] && self.skrho[i] {
                    self.sk.at(r)
                } else {
                    self.nsk.at(r)
                };
                e += (f.e1(i, zi) - lp) as f64;
                // Each edge once: one with both ends in the box is counted from its lower
                // index (right and down), one leaving the box always.
                let nb = [
                    (x > 0 && x == x0).then(|| i - 1),
                    (x + 1 < w).then(|| i + 1),
                    (y > 0 && y == y0).then(|| i - w),
                    (y + 1 < h).then(|| i + w),
                ];
                for j in nb.into_iter().flatten() {
                    if f.hair[j] && !(self.fixed[i] && self.fixed[j]) {
                        e += f.edge(zi, self.z[j]) as f64;
                    }
                }
            }
        }
        e
    }

    /// The exact δ (before λ_NC or the turn cost) of painting `win` with `zb` and relaxing
    /// the free pixels within [`RELAX_MARGIN`] px of it by [`RELAX_SWEEPS`] Gauss-Seidel
    /// sweeps; returns δ and the relaxed values (the state is left as it was).
    pub(super) fn relax(
        &mut self,
        win: &Win,
        kind: Kind,
        zb: [[f32; 2]; 2],
    ) -> (f32, Vec<(u32, [f32; 2])>) {
        let f = self.f;
        let (w, h) = (f.width as usize, f.height as usize);
        let hair_sides = kind.hair_sides();
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        let mut taken: Vec<(usize, [f32; 2])> = Vec::with_capacity(win.px.len());
        for &(i, s) in &win.px {
            let i = i as usize;
            let (x, y) = (i % w, i / w);
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
            if let Some(k) = s.index() {
                if hair_sides[k] && f.hair[i] && !self.on[i] {
                    taken.push((i, zb[k]));
                }
            }
        }
        if win.px.is_empty() {
            return (0.0, Vec::new());
        }
        let (x0, y0) = (
            x0.saturating_sub(RELAX_MARGIN),
            y0.saturating_sub(RELAX_MARGIN),
        );
        let (x1, y1) = ((x1 + RELAX_MARGIN).min(w), (y1 + RELAX_MARGIN).min(h));
        let before = self.local_energy(x0, y0, x1, y1);
        let saved: Vec<[f32; 2]> = taken.iter().map(|&(i, _)| self.z[i]).collect();
        let skr = self.sk_kind(kind);
        for &(i, z) in &taken {
            self.z[i] = z;
            self.fixed[i] = true;
            self.skrho[i] = skr;
        }
        let mut free = Vec::new();
        // The free pixels of each colour, in raster order, with their coordinates.
        let mut by_parity: [Vec<(usize, usize, usize)>; 2] = [Vec::new(), Vec::new()];
        for y in y0..y1 {
            for x in x0..x1 {
                let i = y * w + x;
                if f.hair[i] && !self.fixed[i] {
                    free.push(i);
                    by_parity[(x + y) % 2].push((i, x, y));
                }
            }
        }
        let old: Vec<[f32; 2]> = free.iter().map(|&i| self.z[i]).collect();
        let half = 0.5 * f.smooth;
        for _ in 0..RELAX_SWEEPS {
            for colour in &by_parity {
                for &(i, x, y) in colour {
                    let mut s = f.data[i];
                    for j in nbrs4(i, x, y, w, h).into_iter().flatten() {
                        if f.hair[j] {
                            s[0] += half * self.z[j][0];
                            s[1] += half * self.z[j][1];
                        }
                    }
                    let n2 = s[0] * s[0] + s[1] * s[1];
                    if n2 > 1e-24 {
                        let n = n2.sqrt();
                        self.z[i] = [s[0] / n, s[1] / n];
                    }
                }
            }
        }
        let after = self.local_energy(x0, y0, x1, y1);
        let relaxed: Vec<(u32, [f32; 2])> = free.iter().map(|&i| (i as u32, self.z[i])).collect();
        for (k, &i) in free.iter().enumerate() {
            self.z[i] = old[k];
        }
        for (k, &(i, _)) in taken.iter().enumerate() {
            self.z[i] = saved[k];
            self.fixed[i] = false;
            self.skrho[i] = false;
        }
        ((before - after) as f32, relaxed)
    }
}
