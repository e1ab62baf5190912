//! Hair simulation (C13 §4, after Selle et al. 2008): every strand a mass-spring chain
//! (edge, bending and twist springs), wind from improved Perlin noise acting as drag,
//! collisions with the head's signed distance field, roots carried rigidly by the head.
//! C13 has no gravity: the modelled shape is the rest state, so the hair settles back into
//! it once the wind stops. Gravity is offered ([`SimParams::gravity`]); with it the rest
//! shape sags under its own weight until the springs balance it.
//!
//! The step is one pass per strand ([`crate::stages::sim_step`], CPU mirror beside it),
//! `substeps` steps per frame recorded into one submission.

pub mod head_sdf;
pub mod noise;
pub mod run;
pub mod skin;
pub mod track;

use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::hair::head::Head;
use crate::hair::strands::StrandSet;
use crate::stages::sim_step::{self, Config, MAX_VERTS};
use serde::Serialize;
pub use track::{HeadKey, HeadTrack};

/// Edge strain beyond which a run is reported as diverged.
pub const UNSTABLE_STRAIN: f32 = 0.5;

/// Every setting of a simulation (written to `sim.json`). Units: metres, seconds, unit
/// vertex mass (stiffnesses are accelerations per unit strain).
#[derive(Clone, Debug, Serialize)]
pub struct SimParams {
    /// Frames to write after the rest frame.
    pub frames: u32,
    pub fps: f32,
    /// Steps per frame (Δt = 1 / (fps · substeps)).
    pub substeps: u32,
    /// Vertices per simulated strand (strands are resampled by arc length).
    pub n_verts: u32,
    pub k_stretch: f32,
    pub k_bend: f32,
    pub k_twist: f32,
    /// Spring damping as a multiple of stiffness (s).
    pub damping: f32,
    /// Drag towards the wind velocity (1/s); also damps motion in still air.
    pub drag: f32,
    /// Mean wind speed (m/s); 0 is still air.
    pub wind: f32,
    /// Direction of the mean wind in model space (normalised; +x is image right).
    pub wind_dir: [f32; 3],
    /// Noise amplitude relative to the mean wind speed.
    pub gust: f32,
    /// Length over which the noise changes (m).
    pub noise_scale: f32,
    /// Speed at which the noise pattern moves (noise cells per second).
    pub noise_speed: f32,
    /// Frame from which the wind is off (None: it blows throughout).
    pub wind_until: Option<u32>,
    /// Downward acceleration (m/s²); 0 as in C13.
    pub gravity: f32,
    /// Distance kept from the head surface (m).
    pub margin: f32,
    /// Largest edge strain kept after each step (0: the springs alone).
    pub strain_limit: f32,
    /// The head's rigid motion per frame.
    pub track: HeadTrack,
}

impl Default for SimParams {
    fn default() -> Self {
        SimParams {
            frames: 120,
            fps: 30.0,
            substeps: 10,
            n_verts: 32,
            k_stretch: 4.0e4,
            k_bend: 400.0,
            k_twist: 100.0,
            damping: 0.005,
            drag: 4.0,
            wind: 0.0,
            wind_dir: [1.0, 0.0, 0.35],
            gust: 0.8,
            noise_scale: 0.12,
            noise_speed: 1.5,
            wind_until: None,
            gravity: 0.0,
            margin: 1.0e-3,
            strain_limit: 0.002,
            track: HeadTrack::default(),
        }
    }
}

impl SimParams {
    pub fn dt(&self) -> f32 {
        1.0 / (self.fps * self.substeps as f32)
    }

    /// Refuses values no run can use, and time steps the scheme cannot keep stable.
    pub fn validate(&self, rest_edge: f32) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(m));
        let finite = [
            ("fps", self.fps),
            ("k-stretch", self.k_stretch),
            ("k-bend", self.k_bend),
            ("k-twist", self.k_twist),
            ("damping", self.damping),
            ("drag", self.drag),
            ("wind", self.wind),
            ("gust", self.gust),
            ("noise-scale", self.noise_scale),
            ("noise-speed", self.noise_speed),
            ("gravity", self.gravity),
            ("margin", self.margin),
            ("strain-limit", self.strain_limit),
        ];
        for (name, v) in finite {
            if !v.is_finite() {
                return bad(format!("--{name} must be finite, got {v}"));
            }
        }
        if self.wind_dir.iter().any(|v| !v.is_finite())
            || self.wind_dir.iter().map(|v| v * v).sum::<f32>() < 1e-12
        {
            return bad(format!(
                "the wind direction must be a finite non-zero vector, got {:?}",
                self.wind_dir
            ));
        }
        for (name, v) in [
            ("fps", self.fps),
            ("k-stretch", self.k_stretch),
            ("noise-scale", self.noise_scale),
        ] {
            if v <= 0.0 {
                return bad(format!("--{name} must be positive, got {v}"));
            }
        }
        for (name, v) in [
            ("k-bend", self.k_bend),
            ("k-twist", self.k_twist),
            ("damping", self.damping),
            ("drag", self.drag),
            ("wind", self.wind),
            ("gust", self.gust),
            ("margin", self.margin),
            ("strain-limit", self.strain_limit),
        ] {
            if v < 0.0 {
                return bad(format!("--{name} must not be negative, got {v}"));
            }
        }
        if self.substeps == 0 {
            return bad("--substeps must be at least 1".into());
        }
        if !(2..=MAX_VERTS).contains(&self.n_verts) {
            return bad(format!(
                "--verts must be in 2..={MAX_VERTS}, got {}",
                self.n_verts
            ));
        }
        // The springs are implicit, but their directions are frozen over a step, and the
        // roots are moved, not simulated: a root that crosses a sizeable part of a segment
        // in one step yanks its springs further than the linearisation holds. Instability
        // from anything else is caught while running (see `Sim::advance`).
        let dt = self.dt();
        let speed = self.track.max_speed(self.fps);
        if speed * dt > 0.5 * rest_edge {
            return bad(format!(
                "the time step {dt:.2e} s is too large to stay stable: the head moves strand \
                 roots at up to {speed:.2} m/s, {:.0}% of a {:.1} mm segment per step (limit \
                 50%); raise --substeps to at least {}",
                100.0 * speed * dt / rest_edge,
                rest_edge * 1e3,
                (speed / (0.5 * rest_edge * self.fps)).ceil() as u32
            ));
        }
        self.track.validate()
    }
}

/// Strands resampled to `n` vertices at equal arc length (root and tip kept), with their
/// per-vertex colour and transparency interpolated. Strands with fewer than two vertices or
/// zero length are dropped (they cannot be simulated); their indices are returned.
pub fn resample(s: &StrandSet, n: usize) -> (StrandSet, Vec<usize>) {
    let mut out = StrandSet::default();
    let mut colors = s.colors.as_ref().map(|_| Vec::new());
    let mut transparency = s.transparency.as_ref().map(|_| Vec::new());
    let mut dropped = Vec::new();
    let off = s.offsets();
    for i in 0..s.len() {
        let pts = &s.points[off[i]..off[i + 1]];
        let acc = crate::base::polyline::arc_lengths(pts);
        let total = acc[acc.len() - 1];
        if pts.len() < 2 || total <= 0.0 {
            dropped.push(i);
            continue;
        }
        let mut seg = 0;
        let mut new_pts = Vec::with_capacity(n);
        let mut samples = Vec::with_capacity(n);
        for k in 0..n {
            let target = total * k as f64 / (n - 1) as f64;
            while seg + 2 < acc.len() && acc[seg + 1] < target {
                seg += 1;
            }
            let len = acc[seg + 1] - acc[seg];
            let t = if len > 0.0 {
                ((target - acc[seg]) / len).clamp(0.0, 1.0) as f32
            } else {
                0.0
            };
            let (a, b) = (pts[seg], pts[seg + 1]);
            new_pts.push(std::array::from_fn(|c| a[c] + (b[c] - a[c]) * t));
            samples.push((off[i] + seg, t));
        }
        // The root stays bit-identical: it is what the head carries.
        new_pts[0] = pts[0];
        out.push(&new_pts);
        if let (Some(dst), Some(src)) = (&mut colors, &s.colors) {
            for &(g, t) in &samples {
                let (a, b) = (src[g], src[g + 1]);
                dst.push(std::array::from_fn(|c| a[c] + (b[c] - a[c]) * t));
            }
        }
        if let (Some(dst), Some(src)) = (&mut transparency, &s.transparency) {
            for &(g, t) in &samples {
                dst.push(src[g] + (src[g + 1] - src[g]) * t);
            }
        }
    }
    out.colors = colors;
    out.transparency = transparency;
    (out, dropped)
}

/// Whether vertex `g` of a set whose strands all have the same count is a root.
fn rest_is_root(counts: &[u32], g: usize) -> bool {
    counts
        .first()
        .is_some_and(|&n| g.is_multiple_of(n as usize))
}

/// Rest lengths of the three spring families at every vertex (0 past the tip).
pub fn rest_lengths(s: &StrandSet, n: usize) -> Vec<f32> {
    let mut rest = vec![0.0f32; 3 * s.points.len()];
    for (i, st) in s.strands().enumerate() {
        for a in 0..n {
            for fam in 0..3 {
                let b = a + fam + 1;
                if b < n {
                    let d: f32 = (0..3).map(|k| (st[b][k] - st[a][k]).powi(2)).sum();
                    rest[3 * (i * n + a) + fam] = d.sqrt();
                }
            }
        }
    }
    rest
}

/// A running simulation: positions and velocities of every simulated strand.
pub struct Sim {
    pub params: SimParams,
    /// The resampled rest strands (model space), with their attributes.
    pub rest: StrandSet,
    pub x: Vec<f32>,
    pub v: Vec<f32>,
    rest_len: Vec<f32>,
    roots: Vec<f32>,
    head: Vec<f32>,
    perm: Vec<u32>,
    /// How the modelled strands follow the guides.
    skin: skin::Skin,
    /// Steps taken so far.
    pub steps: u32,
}

impl Sim {
    /// Resamples `strands` and starts at rest (zero velocity) with the head at its first key.
    pub fn new(strands: &StrandSet, head: &Head, params: &SimParams) -> Result<Sim> {
        strands.validate()?;
        let n = params.n_verts as usize;
        if !(2..=MAX_VERTS as usize).contains(&n) {
            return Err(Error::Invalid(format!(
                "--verts must be in 2..={MAX_VERTS}, got {n}"
            )));
        }
        let (mut rest, dropped) = resample(strands, n);
        // Chords of a strand that hugs the scalp cut into the head: the rest shape is moved
        // out to the margin first, so that it is a state the simulation can rest in.
        for (g, q) in rest.points.iter_mut().enumerate() {
            if rest_is_root(&rest.counts, g) {
                continue;
            }
            let p = glam::Vec3::from_array(*q);
            let d = head.sdf(p);
            if d < params.margin {
                let nrm = head.sdf_grad(p).normalize_or_zero();
                *q = (p + nrm * (params.margin - d)).to_array();
            }
        }
        if rest.is_empty() {
            return Err(Error::Invalid(
                "no strand has two distinct vertices to simulate".into(),
            ));
        }
        let rest_len = rest_lengths(&rest, n);
        let mean_edge = {
            let (sum, cnt) = rest_len
                .chunks(3)
                .filter(|c| c[0] > 0.0)
                .fold((0.0f64, 0usize), |(s, c), v| (s + v[0] as f64, c + 1));
            (sum / cnt.max(1) as f64) as f32
        };
        params.validate(mean_edge)?;
        let roots: Vec<f32> = rest.strands().flat_map(|s| s[0]).collect();
        let m = params.track.transform(0.0);
        let x: Vec<f32> = rest
            .points
            .iter()
            .flat_map(|p| track::apply(&m, *p))
            .collect();
        let skin = skin::Skin::new(strands, &rest, n, &dropped);
        Ok(Sim {
            params: params.clone(),
            skin,
            v: vec![0.0; x.len()],
            x,
            rest_len,
            roots,
            head: head.sdf_packed(),
            perm: noise::perm_table(),
            rest,
            steps: 0,
        })
    }

    pub fn n_strands(&self) -> usize {
        self.rest.len()
    }

    /// Rest lengths of the springs i–i+1, i–i+2, i–i+3 at every vertex (what the pass reads).
    pub fn rest_lengths(&self) -> &[f32] {
        &self.rest_len
    }

    /// Rest root of every strand (model space).
    pub fn roots(&self) -> &[f32] {
        &self.roots
    }

    fn config(&self, step: u32, n_strands: u32) -> Config {
        let p = &self.params;
        let dt = p.dt();
        let frame = step / p.substeps;
        let blowing = p.wind_until.is_none_or(|f| frame < f);
        let w = if blowing { p.wind } else { 0.0 };
        let dl = p.wind_dir.iter().map(|v| v * v).sum::<f32>().sqrt();
        Config {
            n_strands,
            n_verts: p.n_verts,
            step: 0,
            dt,
            time: step as f32 * dt,
            k_stretch: p.k_stretch,
            k_bend: p.k_bend,
            k_twist: p.k_twist,
            damping: p.damping,
            drag: p.drag,
            wind_x: w * p.wind_dir[0] / dl,
            wind_y: w * p.wind_dir[1] / dl,
            wind_z: w * p.wind_dir[2] / dl,
            gust: w * p.gust,
            noise_scale: p.noise_scale,
            noise_speed: p.noise_speed,
            gravity: p.gravity,
            margin: p.margin,
            strain_limit: p.strain_limit,
        }
    }

    /// Advances `steps` steps (one submission per tile of strands that fits a binding).
    pub fn advance(&mut self, engine: &Engine, steps: u32) -> Result<()> {
        if steps == 0 {
            return Ok(());
        }
        let p = &self.params;
        let n = p.n_verts as usize;
        let dt = p.dt();
        // The head transform at every step boundary of this batch.
        let motion: Vec<f32> = (0..=steps)
            .flat_map(|k| {
                let t = (self.steps + k) as f32 * dt * p.fps;
                track::pack(&p.track.transform(t))
            })
            .collect();
        let per_strand = 12 * n as u64;
        let tile = ((engine.max_binding_bytes() / per_strand) as usize)
            .min(65535 * sim_step::WORKGROUP as usize)
            .max(1);
        let ns = self.n_strands();
        let mut start = 0;
        while start < ns {
            let count = tile.min(ns - start);
            let (a, b) = (3 * n * start, 3 * n * (start + count));
            let mut rec = Recording::default();
            let perm = rec.upload("coif.sim.perm", &self.perm);
            let head = rec.upload("coif.sim.head", &self.head);
            let mot = rec.upload("coif.sim.motion", &motion);
            let roots = rec.upload(
                "coif.sim.roots",
                &self.roots[3 * start..3 * (start + count)],
            );
            let rest = rec.upload("coif.sim.rest", &self.rest_len[a..b]);
            let xb = rec.upload("coif.sim.x", &self.x[a..b]);
            let vb = rec.upload("coif.sim.v", &self.v[a..b]);
            for k in 0..steps {
                let mut cfg = self.config(self.steps + k, count as u32);
                cfg.step = k;
                let u = rec.uniform("coif.sim.cfg", &cfg);
                rec.dispatch(
                    &sim_step::STAGE,
                    sim_step::workgroups(&cfg),
                    &[u, perm, head, mot, roots, rest, xb, vb],
                    &[],
                );
            }
            rec.download(xb);
            rec.download(vb);
            let dl = engine.run(rec)?;
            self.x[a..b].copy_from_slice(&dl.get::<f32>(xb)[..b - a]);
            self.v[a..b].copy_from_slice(&dl.get::<f32>(vb)[..b - a]);
            start += count;
        }
        self.steps += steps;
        // A step too large for the scheme shows as runaway stretch long before NaN.
        let strain = self.max_strain();
        if !strain.is_finite() || strain > UNSTABLE_STRAIN {
            return Err(Error::Invalid(format!(
                "the time step {:.2e} s is too large to stay stable: by step {} an edge is \
                 stretched by {:.0}% (more than {:.0}% means the scheme has diverged); raise \
                 --substeps (now {}) or lower the stiffnesses",
                p.dt(),
                self.steps,
                100.0 * strain,
                100.0 * UNSTABLE_STRAIN,
                p.substeps
            )));
        }
        Ok(())
    }

    /// The largest |l − l0| / l0 over the edges (NaN if a position is not finite).
    pub fn max_strain(&self) -> f32 {
        let n = self.params.n_verts as usize;
        let mut worst = 0.0f32;
        for (g, l0) in self.rest_len.chunks(3).map(|c| c[0]).enumerate() {
            if l0 <= 0.0 || g % n == n - 1 {
                continue;
            }
            let i = 3 * g;
            let d: f32 = (0..3)
                .map(|c| (self.x[i + 3 + c] - self.x[i + c]).powi(2))
                .sum();
            let e = (d.sqrt() - l0).abs() / l0;
            if !e.is_finite() {
                return f32::NAN;
            }
            worst = worst.max(e);
        }
        worst
    }

    /// The simulated guides now (model space), with the rest guides' attributes.
    pub fn guides(&self) -> StrandSet {
        let mut s = self.rest.clone();
        s.points = self.x.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
        s
    }

    /// The modelled strands now, following their guides ([`skin::Skin`]).
    pub fn strands(&self) -> StrandSet {
        let p = &self.params;
        let m = p.track.transform(self.steps as f32 / p.substeps as f32);
        self.skin.apply(&self.x, &m)
    }

    /// Kinetic plus spring energy (unit masses).
    pub fn energy(&self) -> f64 {
        let p = &self.params;
        let n = p.n_verts as usize;
        let ke: f64 = self.v.iter().map(|v| 0.5 * (*v as f64).powi(2)).sum();
        let mut pe = 0.0f64;
        let k = [p.k_stretch, p.k_bend, p.k_twist];
        for s in 0..self.n_strands() {
            for a in 0..n {
                for (fam, kf) in k.iter().enumerate() {
                    let b = a + fam + 1;
                    let l0 = self.rest_len[3 * (s * n + a) + fam];
                    if b >= n || l0 <= 0.0 {
                        continue;
                    }
                    let (ia, ib) = (3 * (s * n + a), 3 * (s * n + b));
                    let d: f64 = (0..3)
                        .map(|c| (self.x[ib + c] as f64 - self.x[ia + c] as f64).powi(2))
                        .sum();
                    pe += 0.5 * (*kf as f64 / l0 as f64) * (d.sqrt() - l0 as f64).powi(2);
                }
            }
        }
        ke + pe
    }

    /// Figures of the current state: stretch of every edge, root error against the head's
    /// rigid transform, deepest vertex inside the head.
    pub fn figures(&self) -> SimFigures {
        let p = &self.params;
        let n = p.n_verts as usize;
        let m = p.track.transform(self.steps as f32 / p.substeps as f32);
        let mut stretch = Vec::with_capacity(self.x.len() / 3);
        let mut length_err = 0.0f64;
        let mut root_err = 0.0f64;
        let mut min_sdf = f32::INFINITY;
        for s in 0..self.n_strands() {
            let (mut len, mut len0) = (0.0f64, 0.0f64);
            let root = [
                self.roots[3 * s],
                self.roots[3 * s + 1],
                self.roots[3 * s + 2],
            ];
            let want = track::apply(&m, root);
            let got = &self.x[3 * s * n..3 * s * n + 3];
            let e: f64 = (0..3)
                .map(|c| (want[c] as f64 - got[c] as f64).powi(2))
                .sum();
            root_err = root_err.max(e.sqrt());
            for a in 0..n {
                let i = 3 * (s * n + a);
                let ph = track::apply_inv(&m, [self.x[i], self.x[i + 1], self.x[i + 2]]);
                if a > 0 {
                    min_sdf = min_sdf.min(head_sdf::head_sdf(&self.head, ph));
                }
                if a + 1 < n {
                    let l0 = self.rest_len[i] as f64;
                    let d: f64 = (0..3)
                        .map(|c| (self.x[i + 3 + c] as f64 - self.x[i + c] as f64).powi(2))
                        .sum();
                    stretch.push(((d.sqrt() - l0) / l0).abs());
                    len += d.sqrt();
                    len0 += l0;
                }
            }
            length_err = length_err.max(((len - len0) / len0).abs());
        }
        stretch.sort_by(f64::total_cmp);
        let q = |f: f64| stretch[((stretch.len() - 1) as f64 * f).round() as usize];
        SimFigures {
            stretch_p99: q(0.99),
            stretch_max: q(1.0),
            length_max: length_err,
            root_error_max: root_err,
            min_head_distance: min_sdf,
        }
    }
}

/// What [`Sim::figures`] measures.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct SimFigures {
    /// 99th percentile and maximum of |l − l0| / l0 over the edges.
    pub stretch_p99: f64,
    pub stretch_max: f64,
    /// Largest relative change of a strand's length.
    pub length_max: f64,
    /// Largest distance of a root from the head's rigid transform of its rest position (m).
    pub root_error_max: f64,
    /// Smallest signed distance of a free vertex to the head (m; negative inside).
    pub min_head_distance: f32,
}

/// The largest distance a vertex moved between two states (m).
pub fn max_displacement(a: &[f32], b: &[f32]) -> f64 {
    a.chunks(3)
        .zip(b.chunks(3))
        .map(|(p, q)| {
            (0..3)
                .map(|c| (p[c] as f64 - q[c] as f64).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
}
