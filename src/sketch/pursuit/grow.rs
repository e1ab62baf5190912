//! The pursuit's search, CPU: births from the screened heap, extension at both ends,
//! tracing and placing a curve on the lattice, and the window pass's maps and screening.

use super::*;
use rayon::prelude::*;

impl Search<'_> {
    /// The exact best birth at integer corner (x, y): δ − λ_NC over every kind, axis and
    /// side variant the mask allows there. Reads the state only.
    pub(super) fn best_birth(&self, x: i32, y: i32) -> Birth {
        let (hair_min, spill, lambda) = (self.p.hair_min, self.p.spill, birth_cost(self.p));
        let mut ranked: Vec<(f32, Cand)> = Vec::with_capacity(256);
        for a in 0..AXIS_STEPS as i32 {
            let mk = |kind, dict, code| Cand {
                kind,
                x: x as f32,
                y: y as f32,
                axis: a,
                dict,
                code,
            };
            let mut kinds: Vec<Kind> = Vec::with_capacity(4);
            let w5 = self.win_at(Kind::Stream, a, x, y);
            if w5.at_edge(hair_min, spill) {
                kinds.push(Kind::Boundary);
                kinds.push(Kind::Source);
            }
            // c, d, e look the same from either end: half the axes suffice.
            let half = a < AXIS_STEPS as i32 / 2;
            if half && w5.inside() {
                kinds.push(Kind::Stream);
                kinds.push(Kind::Occluding);
            }
            for kind in kinds {
                let prep = self.delta_prep(&w5, kind);
                for dict in variants(kind, None) {
                    let (d, code, _) = self.delta_with(&prep, kind, a, dict);
                    ranked.push((d, mk(kind, dict, code)));
                }
            }
            if half {
                let w6 = self.win_at(Kind::Dividing, a, x, y);
                if w6.inside() {
                    let prep = self.delta_prep(&w6, Kind::Dividing);
                    for dict in variants(Kind::Dividing, None) {
                        let (d, code, _) = self.delta_with(&prep, Kind::Dividing, a, dict);
                        ranked.push((d, mk(Kind::Dividing, dict, code)));
                    }
                }
            }
        }
        ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut best: Option<(f32, Cand)> = None;
        for &(_, c) in ranked.iter().take(RELAX_BIRTHS) {
            let d = self.exact(&c).0 - lambda;
            if best.is_none_or(|(b, _)| d > b) {
                best = Some((d, c));
            }
        }
        best
    }

    /// The exact δ of candidate `c` (its refinement as it is), with its relaxed field.
    pub(super) fn exact(&self, c: &Cand) -> (f32, Vec<(u32, [f32; 2])>) {
        let win = self.win(c.kind, &c.prim());
        let zb = self.zb_of(c);
        self.relax(&win, c.kind, zb)
    }

    /// Whether the mask allows `kind` with this window.
    pub(super) fn allowed(&self, kind: Kind, w: &Win) -> bool {
        match kind {
            Kind::Boundary | Kind::Source => w.at_edge(self.p.hair_min, self.p.spill),
            _ => w.inside(),
        }
    }

    pub(super) fn corner(&self, pos: u32) -> (i32, i32) {
        let s = self.p.birth_stride;
        (
            ((pos % self.nx) * s + s / 2) as i32,
            ((pos / self.nx) * s + s / 2) as i32,
        )
    }

    pub(super) fn fresh(&self, e: &Entry) -> bool {
        e.stamp != PROXY && self.fresh_at(e.pos, e.stamp)
    }

    /// Whether a score made at `stamp` for birth position `pos` is still valid.
    fn fresh_at(&self, pos: u32, stamp: u32) -> bool {
        let (x, y) = self.corner(pos);
        let (w, h) = (self.f.width as usize, self.f.height as usize);
        let (cx, cy) = (
            (x as usize).min(w - 1) / CELL,
            (y as usize).min(h - 1) / CELL,
        );
        self.dirty[cy * self.cells_x + cx] <= stamp
    }

    /// The best birth by exact δ (lazily: stale scores are refreshed until the top is
    /// fresh); None when no position has a positive score.
    ///
    /// Refreshing is where the pursuit spends its time, one position after another. So
    /// when the top needs a score, the next stale positions in heap order are scored with
    /// it, in parallel, and kept until their turn comes or a change near them makes them
    /// stale. The heap itself moves exactly as if they were scored one by one: the same
    /// births come out, whatever the number of threads.
    pub(super) fn pop_best(&mut self) -> Option<(f32, Cand, u32)> {
        while let Some(e) = self.heap.pop() {
            if e.delta <= 0.0 {
                return None;
            }
            if self.blacklist[e.pos as usize] {
                continue;
            }
            if self.fresh(&e) {
                let c = self.best_at[e.pos as usize].expect("fresh entries were scored");
                return Some((e.delta, c, e.pos));
            }
            let scored = match self.memo[e.pos as usize] {
                Some((stamp, r)) if self.fresh_at(e.pos, stamp) => {
                    self.stats.memo_hits += 1;
                    r
                }
                _ => self.score_ahead(e.pos),
            };
            if let Some((d, c)) = scored {
                self.best_at[e.pos as usize] = Some(c);
                self.heap.push(Entry {
                    delta: d,
                    pos: e.pos,
                    stamp: self.epoch,
                });
            }
        }
        None
    }

    /// Scores birth position `pos` and, in parallel with it, the stale positions that come
    /// next in the heap (the heap is left as it was); the others' scores go to the memo.
    fn score_ahead(&mut self, pos: u32) -> Birth {
        let want = match rayon::current_num_threads() {
            0 | 1 => 1,
            t => SCORE_AHEAD * t,
        };
        let mut batch = vec![pos];
        let mut popped = Vec::new();
        while batch.len() < want && popped.len() < 4 * want {
            let Some(f) = self.heap.pop() else {
                break;
            };
            popped.push(f);
            if f.delta <= 0.0 {
                break;
            }
            let p = f.pos as usize;
            let known = matches!(self.memo[p], Some((stamp, _)) if self.fresh_at(f.pos, stamp));
            if !self.blacklist[p] && !self.fresh(&f) && !known {
                batch.push(f.pos);
            }
        }
        self.heap.extend(popped);
        let score = |&q: &u32| {
            let (x, y) = self.corner(q);
            self.best_birth(x, y)
        };
        // One position is scored here: handing it to the pool costs a wake-up.
        let scores: Vec<Birth> = if batch.len() == 1 {
            batch.iter().map(score).collect()
        } else {
            batch.par_iter().map(score).collect()
        };
        self.stats.exact_births += batch.len() as u64;
        for (&q, &r) in batch.iter().zip(&scores).skip(1) {
            self.memo[q as usize] = Some((self.epoch, r));
        }
        scores[0]
    }

    /// The best extension of a curve at either end: (δ − turn cost, candidate, at the end).
    /// Ahead of the last primitive the new one turns by −1, 0 or +1 step and sits STEP px
    /// along its own axis; behind the first it sits STEP px back along the first's axis
    /// (the chain rule of [`chain`]) and its axis turns into the first's.
    pub(super) fn best_extension(&self, curve: &VecDeque<Cand>) -> Option<(f32, Cand, bool)> {
        let (w, h) = (self.f.width as f32, self.f.height as f32);
        let first = curve[0];
        let along_left = (first.kind == Kind::Occluding).then_some(first.dict[0] == 0);
        let vars = variants(first.kind, along_left);
        let smooth = self.f.smooth;
        let mut ranked: Vec<(f32, Cand, bool, i32)> = Vec::new();
        for at_end in [true, false] {
            let end = if at_end {
                *curve.back().expect("a curve has a primitive")
            } else {
                first
            };
            for turn in -1..=1 {
                let (axis, step_axis, sign) = if at_end {
                    (end.axis + turn, end.axis + turn, 1.0)
                } else {
                    (end.axis - turn, end.axis, -1.0)
                };
                let (x, y) = (
                    end.x + sign * STEP * cos15(step_axis as i64) as f32,
                    end.y + sign * STEP * sin15(step_axis as i64) as f32,
                );
                if !(0.0..=w).contains(&x) || !(0.0..=h).contains(&y) {
                    continue;
                }
                let c0 = Cand {
                    kind: first.kind,
                    x,
                    y,
                    axis,
                    dict: vars[0],
                    code: [NO_REFINE; 2],
                };
                let win = self.win(first.kind, &c0.prim());
                if !self.allowed(first.kind, &win) {
                    continue;
                }
                let prep = self.delta_prep(&win, first.kind);
                for &dict in &vars {
                    let (d, code, _) = self.delta_with(&prep, first.kind, axis, dict);
                    ranked.push((
                        d - smooth * turn_cost(turn),
                        Cand { dict, code, ..c0 },
                        at_end,
                        turn,
                    ));
                }
            }
        }
        ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut best: Option<(f32, Cand, bool)> = None;
        for &(_, c, at_end, turn) in ranked.iter().take(RELAX_EXTENSIONS) {
            let d = self.exact(&c).0 - smooth * turn_cost(turn);
            if best.as_ref().is_none_or(|b| d > b.0) {
                best = Some((d, c, at_end));
            }
        }
        best
    }

    /// Paints candidate `c` with its refinement as it is; returns its exact δ (before λ_NC
    /// and turns) and ρ.
    pub(super) fn place(&mut self, c: &Cand) -> (f32, f32) {
        self.stats.placements += 1;
        let win = self.win(c.kind, &c.prim());
        let zb = self.zb_of(c);
        let (d, relaxed) = self.relax(&win, c.kind, zb);
        (d, self.apply(&win, c.kind, zb, &relaxed))
    }

    /// Paints candidate `c` with its refinement scored again where it sits.
    pub(super) fn place_refined(&mut self, c: &Cand) -> (f32, Cand, f32) {
        let win = self.win(c.kind, &c.prim());
        let (_, code, _) = self.delta(&win, c.kind, c.axis, c.dict);
        let c = Cand { code, ..*c };
        let (d, rho) = self.place(&c);
        (d, c, rho)
    }

    /// Paints a traced curve from an integer `start` on the lattice; returns its exact δ
    /// (λ_NC and turns included) and its primitives.
    pub(super) fn lay(
        &mut self,
        curve: &VecDeque<Cand>,
        axes: &[i32],
        start: [f32; 2],
    ) -> (f32, Vec<Primitive>) {
        let centres = chain(start, axes);
        let mut prims = Vec::with_capacity(curve.len());
        let mut delta = -self.p.lambda_nc;
        for (k, (c, xy)) in curve.iter().zip(&centres).enumerate() {
            let c = Cand {
                x: xy[0],
                y: xy[1],
                ..*c
            };
            let (d, placed, rho) = self.place_refined(&c);
            delta += d - self.p.lambda_b;
            if k > 0 {
                delta -= self.f.smooth * turn_cost(c.axis - axes[k - 1]);
            }
            prims.push(Primitive {
                rho,
                ..placed.prim()
            });
        }
        (delta, prims)
    }

    /// Traces a curve from a birth, then places it on the lattice and scores it as placed.
    /// Returns the kept curve and its δ, or None (the state is then as before).
    pub(super) fn trace(&mut self, birth: Cand) -> Option<(Curve, f32)> {
        let mark = self.log.len();
        // A dropped curve leaves the state as it found it, so the scores it made stale are
        // valid again: its staleness marks are taken back with it.
        let dirty = self.dirty.clone();
        let mut curve = VecDeque::from([birth]);
        self.place(&birth);
        while curve.len() < self.p.max_prims {
            self.stats.extensions += 1;
            let Some((d, c, at_end)) = self.best_extension(&curve) else {
                break;
            };
            if d <= self.p.lambda_b {
                break;
            }
            self.place(&c);
            if at_end {
                curve.push_back(c);
            } else {
                curve.push_front(c);
            }
        }
        self.undo_to(mark);
        if curve.len() < self.p.min_prims {
            self.stats.dropped_short += 1;
            self.dirty = dirty;
            return None;
        }
        // On the lattice: an integer start, centres chained from it, each primitive placed
        // in curve order (a pixel keeps the first primitive that reaches it, as in Eq. 8's
        // painting) with its refinement scored again where it now sits. The start is
        // rounded down or up in x and y, whichever of the four scores best: the whole curve
        // moves with it, and a seam is missed by a pixel row as easily as by a metre.
        let axes: Vec<i32> = curve.iter().map(|c| c.axis).collect();
        let (fx, fy) = (curve[0].x.floor(), curve[0].y.floor());
        let (w, h) = (self.f.width as f32, self.f.height as f32);
        let mut best: Option<(f32, [f32; 2])> = None;
        for start in [
            [fx, fy],
            [fx + 1.0, fy],
            [fx, fy + 1.0],
            [fx + 1.0, fy + 1.0],
        ] {
            if start[0] > w || start[1] > h || start[0] < 0.0 || start[1] < 0.0 {
                continue;
            }
            let (d, _) = self.lay(&curve, &axes, start);
            self.undo_to(mark);
            if best.is_none_or(|(b, _)| d > b) {
                best = Some((d, start));
            }
        }
        let Some((_, start)) = best else {
            self.stats.dropped_snapped += 1;
            self.dirty = dirty;
            return None;
        };
        let (delta, prims) = self.lay(&curve, &axes, start);
        if delta <= 0.0 {
            self.undo_to(mark);
            self.stats.dropped_snapped += 1;
            self.dirty = dirty;
            return None;
        }
        // Accepted: nothing of it will be undone.
        self.log.clear();
        Some((
            Curve {
                kind: birth.kind,
                prims,
                dirs: [0, 0],
            },
            delta,
        ))
    }

    /// The per-pixel maps of the window pass for the current state.
    pub(super) fn maps(&self) -> Vec<f32> {
        let f = self.f;
        let n = f.len();
        let (w, h) = (f.width as usize, f.height as usize);
        let mut m = vec![0.0f32; ws::N_MAPS * n];
        let k = 1.0 / (2.0 * f.sigma2);
        for i in 0..n {
            if !f.hair[i] {
                continue;
            }
            m[ws::MAP_HAIR * n + i] = 1.0;
            if self.on[i] {
                continue;
            }
            let (x, y) = (i % w, i / w);
            let zi = self.z[i];
            let mut sm = 0.0f32;
            for j in nbrs4(i, x, y, w, h).into_iter().flatten() {
                if f.hair[j] && !self.fixed[j] {
                    sm += f.edge(zi, self.z[j]);
                }
            }
            let (gx, gy) = (f.gx[i], f.gy[i]);
            m[ws::MAP_TXX * n + i] = gx * gx * k;
            m[ws::MAP_TXY * n + i] = gx * gy * k;
            m[ws::MAP_TYY * n + i] = gy * gy * k;
            let r = f.rho(i, zi);
            m[ws::MAP_BASE * n + i] = f.e1(i, zi) + 0.5 * sm;
            m[ws::MAP_LLR * n + i] = self.sk.at(r) - self.nsk.at(r);
        }
        m
    }

    /// Screens every birth position with the window pass and refills the heap.
    pub(super) fn screen(&mut self, engine: &Engine) -> Result<()> {
        let t = Instant::now();
        let (best, _code) = window_pass(engine, self.f, &self.maps(), self.p)?;
        self.stats.window_runs += 1;
        // Θ was diffused again: every score ahead is stale.
        self.memo.fill(None);
        self.stats.seconds_windows += t.elapsed().as_secs_f64();
        self.heap.clear();
        for (pos, &d) in best.iter().enumerate() {
            if d > 0.0 && !self.blacklist[pos] {
                self.heap.push(Entry {
                    delta: d,
                    pos: pos as u32,
                    stamp: PROXY,
                });
            }
        }
        Ok(())
    }

    /// Diffuses Θ again with the sketch clamped, warm from the current field.
    pub(super) fn rediffuse(&mut self, engine: &Engine) -> Result<()> {
        let t = Instant::now();
        let fl = self.flags();
        let solved = theta::solve(
            engine,
            self.f,
            &fl,
            self.z.clone(),
            self.p.rebuild_sweeps,
            &self.p.theta,
        )?;
        for (i, &f) in fl.iter().enumerate() {
            if f == FREE {
                self.z[i] = solved.z[i];
            }
        }
        self.stats.rebuilds += 1;
        self.stats.seconds_theta += t.elapsed().as_secs_f64();
        Ok(())
    }

    pub(super) fn flags(&self) -> Vec<u32> {
        (0..self.f.len())
            .map(|i| {
                if !self.f.hair[i] {
                    OFF
                } else if self.fixed[i] {
                    FIXED
                } else {
                    FREE
                }
            })
            .collect()
    }

    /// E of Eq. 19 for the current state and `curves`.
    pub(super) fn energy(&self, curves: &[Curve]) -> f64 {
        let f = self.f;
        let (w, h) = (f.width as usize, f.height as usize);
        let mut e = 0.0f64;
        for i in 0..f.len() {
            if !f.hair[i] {
                continue;
            }
            let zi = self.z[i];
            let r = f.rho(i, zi);
            e += f.e1(i, zi) as f64;
            e -= if self.fixed[i] && self.skrho[i] {
                self.sk.at(r)
            } else {
                self.nsk.at(r)
            } as f64;
            let (x, y) = (i % w, i / w);
            for j in [(x + 1 < w).then(|| i + 1), (y + 1 < h).then(|| i + w)]
                .into_iter()
                .flatten()
            {
                if f.hair[j] && !(self.fixed[i] && self.fixed[j]) {
                    e += f.edge(zi, self.z[j]) as f64;
                }
            }
        }
        e + curve_energy(curves, self.p, f.smooth)
    }
}
