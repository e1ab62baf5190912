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
        &self,
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
    /// current terms, and each side's tensor direction. Reads the state only (the taken
    /// pixels are marked per window pixel, not in the image), so positions are scored in
    /// parallel.
    pub(super) fn delta_prep(&self, win: &Win, kind: Kind) -> DeltaPrep {
        let f = self.f;
        let hair_sides = kind.hair_sides();
        let (w, h) = (f.width as usize, f.height as usize);
        let n = win.px.len();
        debug_assert!(win.px.windows(2).all(|p| p[0].0 < p[1].0), "raster order");
        // Which window pixels the primitive takes.
        let mut small = [false; 256];
        let mut large = Vec::new();
        let tk: &mut [bool] = if n <= small.len() {
            &mut small[..n]
        } else {
            large.resize(n, false);
            &mut large
        };
        for (t, &(i, s)) in tk.iter_mut().zip(&win.px) {
            let i = i as usize;
            *t = s
                .index()
                .is_some_and(|k| hair_sides[k] && f.hair[i] && !self.on[i]);
        }
        let mut px = Vec::with_capacity(n);
        let mut g = [[0.0f32; 2]; 2];
        // The window is in raster order, so the pixel below a taken one is found by a
        // cursor that only moves forward.
        let mut below = 0;
        for (k, &(i, s)) in win.px.iter().enumerate() {
            if !tk[k] {
                continue;
            }
            let i = i as usize;
            let side = s.index().expect("taken pixels lie on a side");
            g[side][0] += f.data[i][0];
            g[side][1] += f.data[i][1];
            let zo = self.z[i];
            // Edges with both ends taken stop costing; each is counted from its lower end
            // (right and down neighbours), as the score adds them.
            let (x, y) = (i % w, i / w);
            let mut edges = [0.0f32; 2];
            let mut n_edges = 0;
            if x + 1 < w && k + 1 < n && win.px[k + 1].0 as usize == i + 1 && tk[k + 1] {
                edges[n_edges] = f.edge(self.z[i + 1], zo);
                n_edges += 1;
            }
            if y + 1 < h {
                while below < n && (win.px[below].0 as usize) < i + w {
                    below += 1;
                }
                if below < n && win.px[below].0 as usize == i + w && tk[below] {
                    edges[n_edges] = f.edge(self.z[i + w], zo);
                    n_edges += 1;
                }
            }
            px.push(PrepPx {
                i: i as u32,
                side: side as u8,
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

    /// The exact δ (before λ_NC or the turn cost) of painting `win` with `zb` and relaxing
    /// the free pixels within [`RELAX_MARGIN`] px of it by [`RELAX_SWEEPS`] Gauss-Seidel
    /// sweeps; returns δ and the relaxed values. Works on a copy of the box and the ring
    /// of pixels around it, so candidates are scored in parallel.
    pub(super) fn relax(
        &self,
        win: &Win,
        kind: Kind,
        zb: [[f32; 2]; 2],
    ) -> (f32, Vec<(u32, [f32; 2])>) {
        let f = self.f;
        let (w, h) = (f.width as usize, f.height as usize);
        if win.px.is_empty() {
            return (0.0, Vec::new());
        }
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for &(i, _) in &win.px {
            let (x, y) = (i as usize % w, i as usize / w);
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
        }
        let bx = Boxed {
            x0: x0.saturating_sub(RELAX_MARGIN),
            y0: y0.saturating_sub(RELAX_MARGIN),
            x1: (x1 + RELAX_MARGIN).min(w),
            y1: (y1 + RELAX_MARGIN).min(h),
        };
        let mut patch = Patch::copy(self, &bx);
        let before = patch.energy(self, &bx);
        let hair_sides = kind.hair_sides();
        let skr = self.sk_kind(kind);
        for &(i, s) in &win.px {
            let i = i as usize;
            if let Some(k) = s.index() {
                if hair_sides[k] && f.hair[i] && !self.on[i] {
                    let c = patch.at(i % w, i / w);
                    patch.z[c] = zb[k];
                    patch.fixed[c] = true;
                    patch.skrho[c] = skr;
                }
            }
        }
        // The free pixels of each colour, in raster order: image and patch index.
        let mut by_parity: [Vec<(u32, u32)>; 2] = [Vec::new(), Vec::new()];
        for y in bx.y0..bx.y1 {
            let c0 = patch.at(bx.x0, y);
            for (k, x) in (bx.x0..bx.x1).enumerate() {
                let c = c0 + k;
                if patch.hair[c] && !patch.fixed[c] {
                    by_parity[(x + y) % 2].push(((y * w + x) as u32, c as u32));
                }
            }
        }
        let half = 0.5 * f.smooth;
        let pw = patch.w;
        for _ in 0..RELAX_SWEEPS {
            for colour in &by_parity {
                for &(i, c) in colour {
                    let (i, c) = (i as usize, c as usize);
                    let mut s = f.data[i];
                    // Left, right, up, down, as `nbrs4` orders them; the ring off the
                    // image is no hair.
                    for cj in [c - 1, c + 1, c - pw, c + pw] {
                        if patch.hair[cj] {
                            s[0] += half * patch.z[cj][0];
                            s[1] += half * patch.z[cj][1];
                        }
                    }
                    let n2 = s[0] * s[0] + s[1] * s[1];
                    if n2 > 1e-24 {
                        let n = n2.sqrt();
                        patch.z[c] = [s[0] / n, s[1] / n];
                    }
                }
            }
        }
        let after = patch.energy(self, &bx);
        let mut relaxed: Vec<(u32, [f32; 2])> =
            Vec::with_capacity(by_parity[0].len() + by_parity[1].len());
        for y in bx.y0..bx.y1 {
            let c0 = patch.at(bx.x0, y);
            for (k, x) in (bx.x0..bx.x1).enumerate() {
                let c = c0 + k;
                if patch.hair[c] && !patch.fixed[c] {
                    relaxed.push(((y * w + x) as u32, patch.z[c]));
                }
            }
        }
        ((before - after) as f32, relaxed)
    }
}

/// A box of pixels [x0, x1) × [y0, y1).
struct Boxed {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
}

/// A copy of the state over a box and a ring of one pixel around it: what
/// [`Search::relax`] changes and reads. The ring is there even where it falls off the
/// image, as pixels without hair, so no neighbour needs a bounds check.
struct Patch {
    /// The image coordinates of the patch's (0, 0) are (x0 − 1, y0 − 1) of the box.
    ox: isize,
    oy: isize,
    w: usize,
    hair: Vec<bool>,
    z: Vec<[f32; 2]>,
    fixed: Vec<bool>,
    skrho: Vec<bool>,
}

impl Patch {
    fn copy(s: &Search, b: &Boxed) -> Patch {
        let (w, h) = (s.f.width as usize, s.f.height as usize);
        let (ox, oy) = (b.x0 as isize - 1, b.y0 as isize - 1);
        let pw = b.x1 - b.x0 + 2;
        let ph = b.y1 - b.y0 + 2;
        let n = pw * ph;
        let mut p = Patch {
            ox,
            oy,
            w: pw,
            hair: vec![false; n],
            z: vec![[0.0; 2]; n],
            fixed: vec![false; n],
            skrho: vec![false; n],
        };
        // The part of the patch inside the image.
        let (x0, y0) = (b.x0.saturating_sub(1), b.y0.saturating_sub(1));
        let (x1, y1) = ((b.x1 + 1).min(w), (b.y1 + 1).min(h));
        for y in y0..y1 {
            let r = y * w + x0..y * w + x1;
            let c = p.at(x0, y);
            let c = c..c + (x1 - x0);
            p.hair[c.clone()].copy_from_slice(&s.f.hair[r.clone()]);
            p.z[c.clone()].copy_from_slice(&s.z[r.clone()]);
            p.fixed[c.clone()].copy_from_slice(&s.fixed[r.clone()]);
            p.skrho[c].copy_from_slice(&s.skrho[r]);
        }
        p
    }

    #[inline]
    fn at(&self, x: usize, y: usize) -> usize {
        (y as isize - self.oy) as usize * self.w + (x as isize - self.ox) as usize
    }

    /// E over the hair pixels of the box and the edges with an end in it.
    fn energy(&self, s: &Search, b: &Boxed) -> f64 {
        let f = s.f;
        let w = f.width as usize;
        let pw = self.w;
        let mut e = 0.0f64;
        for y in b.y0..b.y1 {
            let c0 = self.at(b.x0, y);
            for (k, x) in (b.x0..b.x1).enumerate() {
                let c = c0 + k;
                if !self.hair[c] {
                    continue;
                }
                let i = y * w + x;
                let zi = self.z[c];
                let r = f.rho(i, zi);
                let lp = if self.fixed[c] && self.skrho[c] {
                    s.sk.at(r)
                } else {
                    s.nsk.at(r)
                };
                e += (f.e1(i, zi) - lp) as f64;
                // Each edge once: one with both ends in the box is counted from its lower
                // index (right and down), one leaving the box always; the ring off the
                // image is no hair.
                let mut edge = |cj: usize| {
                    if self.hair[cj] && !(self.fixed[c] && self.fixed[cj]) {
                        e += f.edge(zi, self.z[cj]) as f64;
                    }
                };
                if x == b.x0 {
                    edge(c - 1);
                }
                edge(c + 1);
                if y == b.y0 {
                    edge(c - pw);
                }
                edge(c + pw);
            }
        }
        e
    }
}
