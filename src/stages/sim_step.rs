//! One simulation step of every strand (C13 §4 after Selle et al. 2008), one invocation per
//! strand, the strand held in private memory. Pairs with `wgsl/sim_step.wgsl`; the mirror
//! below does the same f32 arithmetic in the same order.
//!
//! Each strand is a mass-spring chain of `n_verts` unit masses: edge springs i–i+1
//! (`k_stretch`), bending springs i–i+2 (`k_bend`) and twist springs i–i+3 (`k_twist`), each
//! F = (k/l0)(|x2−x1|−l0)·d + (kd/l0)((v2−v1)·d)·d with kd = `damping`·k. The step is
//! linearly implicit Euler with the spring directions d frozen at the start of the step
//! (Selle 2008), so each strand needs one banded solve and no Newton loop:
//!
//! ```text
//! (I(1 + Δt·c) + Δt Σ_springs ((kΔt + kd)/l0) d dᵀ ⊗ [[1,−1],[−1,1]]) v' =
//!     v + Δt (Σ (k/l0)(|x2−x1|−l0) d  +  c·u(x, t)  +  g)
//! x' = x + Δt v'
//! ```
//!
//! with wind u from improved Perlin noise acting as drag c·(u − v) (the −c v is the implicit
//! diagonal). The root is not an unknown: it follows the head's rigid motion exactly
//! (`motion` holds the head transform at every step), and springs to it move its known
//! velocity to the right-hand side. Then edges are strain-limited root to tip
//! (`strain_limit`, after Provot 1995): frozen directions stretch an edge that turns through
//! φ in one step by 1/cos φ, 5% for a 1 cm segment whose tip moves 3 mm in a step. Last,
//! vertices closer to the head than
//! `margin` are projected out along the signed distance gradient and lose the velocity
//! component into the head (relative to the head's own motion).

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use crate::sim::head_sdf::{head_sdf, head_sdf_grad, head_sdf_of, Lanes, Num};
use crate::sim::noise::perlin32;
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "sim_step",
    wgsl: include_str!("../../wgsl/sim_step.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::ReadWrite,
    ],
    cpu: sim_step_cpu,
};

/// Workgroup width of the WGSL entry point.
pub const WORKGROUP: u32 = 64;
/// Most vertices a simulated strand may have (the private arrays of the shader).
pub const MAX_VERTS: u32 = 64;
/// Half bandwidth of the system: the twist spring couples vertex i with i + 3.
const BAND: usize = 11;
const B1: usize = BAND + 1;
const MAX_UNKNOWNS: usize = 3 * (MAX_VERTS as usize - 1);

/// Alternations of collision and strain limit after the first of each (see the step).
const PROJECTIONS: u32 = 3;

/// Floats per step in the `motion` buffer: the head rotation (row-major) and translation.
pub const MOTION_STRIDE: usize = 12;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub n_strands: u32,
    pub n_verts: u32,
    /// The step being taken: from `motion[step]` to `motion[step + 1]`.
    pub step: u32,
    pub dt: f32,
    /// Simulated time at the start of the step (s).
    pub time: f32,
    pub k_stretch: f32,
    pub k_bend: f32,
    pub k_twist: f32,
    /// Spring damping as a multiple of stiffness (s).
    pub damping: f32,
    /// Drag towards the wind velocity (1/s).
    pub drag: f32,
    /// Mean wind velocity (m/s).
    pub wind_x: f32,
    pub wind_y: f32,
    pub wind_z: f32,
    /// Amplitude of the noise part of the wind (m/s).
    pub gust: f32,
    /// Length over which the noise changes (m).
    pub noise_scale: f32,
    /// Speed at which the noise pattern moves (noise cells per second).
    pub noise_speed: f32,
    /// Downward acceleration (m/s², 0 in C13).
    pub gravity: f32,
    /// Distance kept from the head surface (m).
    pub margin: f32,
    /// Largest edge strain kept after the step (0: no limit).
    pub strain_limit: f32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [crate::gpu::engine::groups(cfg.n_strands, WORKGROUP), 1, 1]
}

type V3 = [f32; 3];

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn scale(a: V3, s: f32) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The head transform at motion frame `k`: rotation rows and translation.
fn motion_at(motion: &[f32], k: u32) -> ([V3; 3], V3) {
    let m = &motion[k as usize * MOTION_STRIDE..];
    (
        [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]],
        [m[9], m[10], m[11]],
    )
}

/// R·p + t.
fn apply(r: &[V3; 3], t: V3, p: V3) -> V3 {
    add([dot(r[0], p), dot(r[1], p), dot(r[2], p)], t)
}

/// Rᵀ·(p − t).
fn apply_inv(r: &[V3; 3], t: V3, p: V3) -> V3 {
    let q = sub(p, t);
    [
        r[0][0] * q[0] + r[1][0] * q[1] + r[2][0] * q[2],
        r[0][1] * q[0] + r[1][1] * q[1] + r[2][1] * q[2],
        r[0][2] * q[0] + r[1][2] * q[1] + r[2][2] * q[2],
    ]
}

/// Wind velocity at `p` and time `t`: the mean wind plus three decorrelated noise channels
/// sampled in a pattern that moves with the mean wind's direction.
pub fn wind(cfg: &Config, perm: &[u32], p: V3, t: f32) -> V3 {
    let inv = 1.0 / cfg.noise_scale;
    let s = cfg.noise_speed * t;
    let q = [p[0] * inv - s, p[1] * inv, p[2] * inv + 0.5 * s];
    let n = [
        perlin32(perm, q[0], q[1], q[2]),
        perlin32(perm, q[0] + 31.416, q[1] + 47.853, q[2] + 12.793),
        perlin32(perm, q[0] + 73.156, q[1] + 19.284, q[2] + 91.527),
    ];
    [
        cfg.wind_x + cfg.gust * n[0],
        cfg.wind_y + cfg.gust * n[1],
        cfg.wind_z + cfg.gust * n[2],
    ]
}

/// Strands stepped together by the mirror. Every strand's band system has the same shape, so
/// the assembly and the solve run lane by lane over `LANES` strands in one loop, which the
/// compiler turns into SIMD (the solve's long chains of dependent divides and square roots
/// then overlap); each lane does one shader invocation's arithmetic in the same order, so a
/// batch gives the one-strand step's values to the bit (tested below).
const LANES: usize = 8;

/// Per batch of `L` strands: the band of the lower triangle, l[i * B1 + (i − j)] = A[i][j],
/// and the right-hand side, one value per lane.
struct Scratch<const L: usize> {
    l: Vec<Lanes<L>>,
    rhs: Vec<Lanes<L>>,
}

impl<const L: usize> Scratch<L> {
    fn new() -> Self {
        Scratch {
            l: vec![Lanes([0.0; L]); MAX_UNKNOWNS * B1],
            rhs: vec![Lanes([0.0; L]); MAX_UNKNOWNS],
        }
    }
}

/// What every strand of a step reads: the settings, the noise's permutation, the packed
/// head and the head's motion.
#[derive(Clone, Copy)]
pub struct Shared<'a> {
    pub cfg: &'a Config,
    pub perm: &'a [u32],
    pub head: &'a [f32],
    pub motion: &'a [f32],
}

/// Steps every strand: `x` and `v` hold `n_strands` strands of `n_verts` vertices (xyz each),
/// `roots` one point per strand, `rest` three spring rest lengths per vertex.
pub fn step_all(sh: Shared, roots: &[f32], rest: &[f32], x: &mut [f32], v: &mut [f32]) {
    let n = sh.cfg.n_verts as usize;
    let ns = sh.cfg.n_strands as usize;
    let sn = 3 * n;
    let full = ns / LANES * LANES;
    let (xa, xb) = x[..sn * ns].split_at_mut(sn * full);
    let (va, vb) = v[..sn * ns].split_at_mut(sn * full);
    xa.par_chunks_mut(sn * LANES)
        .zip(va.par_chunks_mut(sn * LANES))
        .enumerate()
        .for_each_init(Scratch::<LANES>::new, |sc, (c, (xs, vs))| {
            let s = c * LANES;
            let (r, l) = (
                &roots[3 * s..3 * (s + LANES)],
                &rest[sn * s..sn * (s + LANES)],
            );
            step_strands(sh, r, l, xs, vs, sc);
        });
    // The last strands, fewer than a batch, one at a time.
    let mut sc = Scratch::<1>::new();
    for (j, (xs, vs)) in xb.chunks_mut(sn).zip(vb.chunks_mut(sn)).enumerate() {
        let s = full + j;
        let (r, l) = (&roots[3 * s..3 * (s + 1)], &rest[sn * s..sn * (s + 1)]);
        step_strands(sh, r, l, xs, vs, &mut sc);
    }
}

/// `L` strands' step, lane k holding strand k of `x`, `v` (`n_verts` vertices, xyz each),
/// `roots` and `rest`.
fn step_strands<const L: usize>(
    sh: Shared,
    roots: &[f32],
    rest: &[f32],
    x: &mut [f32],
    v: &mut [f32],
    sc: &mut Scratch<L>,
) {
    let Shared {
        cfg,
        perm,
        head,
        motion,
    } = sh;
    let n = cfg.n_verts as usize;
    let sn = 3 * n;
    let nu = 3 * (n - 1);
    let dt = cfg.dt;
    let (r0, t0) = motion_at(motion, cfg.step);
    let (r1, t1) = motion_at(motion, cfg.step + 1);
    let mut root_new = [[0.0f32; 3]; L];
    let mut v_root = [[0.0f32; 3]; L];
    for k in 0..L {
        let root = [roots[3 * k], roots[3 * k + 1], roots[3 * k + 2]];
        root_new[k] = apply(&r1, t1, root);
        v_root[k] = scale(sub(root_new[k], apply(&r0, t0, root)), 1.0 / dt);
    }
    let get = |a: &[f32], k: usize, i: usize| -> V3 {
        let o = k * sn + 3 * i;
        [a[o], a[o + 1], a[o + 2]]
    };
    let l = &mut sc.l[..nu * B1];
    let rhs = &mut sc.rhs[..nu];
    let zero = Lanes([0.0; L]);
    l.fill(zero);
    let diag = 1.0 + dt * cfg.drag;
    for i in 1..n {
        for k in 0..L {
            let xi = get(x, k, i);
            let u = wind(cfg, perm, xi, cfg.time);
            let vi = get(v, k, i);
            let f = [
                vi[0] + dt * cfg.drag * u[0],
                vi[1] + dt * (cfg.drag * u[1] - cfg.gravity),
                vi[2] + dt * cfg.drag * u[2],
            ];
            for (c, fc) in f.iter().enumerate() {
                let r = 3 * (i - 1) + c;
                rhs[r].0[k] = *fc;
                l[r * B1].0[k] = diag;
            }
        }
    }
    // The root's velocity, component by component over the lanes.
    let vr: [Lanes<L>; 3] = std::array::from_fn(|c| Lanes(std::array::from_fn(|k| v_root[k][c])));
    for a in 0..n - 1 {
        for fam in 0..3 {
            let b = a + fam + 1;
            if b >= n {
                continue;
            }
            let kf = [cfg.k_stretch, cfg.k_bend, cfg.k_twist][fam];
            // A lane whose spring is skipped keeps d, fe and c at zero: it adds exact zeros.
            let (mut d, mut fe, mut c) = ([zero; 3], [zero; 3], zero);
            for k in 0..L {
                let l0 = rest[k * sn + 3 * a + fam];
                let xa = get(x, k, a);
                let d0 = sub(get(x, k, b), xa);
                let len = dot(d0, d0).sqrt();
                if len < 1e-12 || l0 <= 0.0 {
                    continue;
                }
                let dk = scale(d0, 1.0 / len);
                // Elastic force on a (and its opposite on b), explicit at x.
                let fk = scale(dk, dt * (kf / l0) * (len - l0));
                c.0[k] = dt * (kf * dt + cfg.damping * kf) / l0;
                for p in 0..3 {
                    d[p].0[k] = dk[p];
                    fe[p].0[k] = fk[p];
                }
            }
            let bu = 3 * (b - 1);
            for p in 0..3 {
                rhs[bu + p] = rhs[bu + p] - fe[p];
                for q in 0..=p {
                    let e = &mut l[(bu + p) * B1 + (p - q)];
                    *e = *e + c * d[p] * d[q];
                }
            }
            if a == 0 {
                // The root's velocity is known: its spring term moves to the right.
                let dv = d[0] * vr[0] + d[1] * vr[1] + d[2] * vr[2];
                for p in 0..3 {
                    rhs[bu + p] = rhs[bu + p] + c * d[p] * dv;
                }
            } else {
                let au = 3 * (a - 1);
                for p in 0..3 {
                    rhs[au + p] = rhs[au + p] + fe[p];
                    for q in 0..=p {
                        let e = &mut l[(au + p) * B1 + (p - q)];
                        *e = *e + c * d[p] * d[q];
                    }
                    // Off-diagonal block: row of b, column of a (always below the diagonal).
                    for q in 0..3 {
                        let e = &mut l[(bu + p) * B1 + (bu + p - (au + q))];
                        *e = *e - c * d[p] * d[q];
                    }
                }
            }
        }
    }
    // Banded Cholesky in place, then the two triangular solves.
    for i in 0..nu {
        let j0 = i.saturating_sub(BAND);
        for j in j0..=i {
            let mut s = l[i * B1 + (i - j)];
            for kk in j0.max(j.saturating_sub(BAND))..j {
                s = s - l[i * B1 + (i - kk)] * l[j * B1 + (j - kk)];
            }
            l[i * B1 + (i - j)] = if i == j {
                s.max(Lanes([1e-20; L])).sqrt()
            } else {
                s / l[j * B1]
            };
        }
    }
    for i in 0..nu {
        let mut s = rhs[i];
        for kk in i.saturating_sub(BAND)..i {
            s = s - l[i * B1 + (i - kk)] * rhs[kk];
        }
        rhs[i] = s / l[i * B1];
    }
    for i in (0..nu).rev() {
        let mut s = rhs[i];
        for kk in i + 1..(i + BAND + 1).min(nu) {
            s = s - l[kk * B1 + (kk - i)] * rhs[kk];
        }
        rhs[i] = s / l[i * B1];
    }
    let m = Rigid { r0, t0, r1, t1, dt };
    let vel = |k: usize, i: usize| -> V3 {
        let r = 3 * (i - 1);
        [rhs[r].0[k], rhs[r + 1].0[k], rhs[r + 2].0[k]]
    };
    // Every vertex's place in head space where its first collision test takes it, and the
    // head's distance there, all lanes at once (most vertices need no other test).
    let mut ph = [[[0.0f32; 3]; L]; MAX_VERTS as usize];
    let mut dist = [[0.0f32; L]; MAX_VERTS as usize];
    for i in 1..n {
        let mut q = [Lanes([0.0f32; L]); 3];
        for (k, p) in ph[i].iter_mut().enumerate() {
            *p = apply_inv(&m.r1, m.t1, add(get(x, k, i), scale(vel(k, i), dt)));
            for c in 0..3 {
                q[c].0[k] = p[c];
            }
        }
        dist[i] = head_sdf_of(head, q).0;
    }
    for k in 0..L {
        let xs = &mut x[k * sn..(k + 1) * sn];
        let vs = &mut v[k * sn..(k + 1) * sn];
        let first = |i: usize| (vel(k, i), ph[i][k], dist[i][k]);
        project(
            sh,
            &m,
            root_new[k],
            v_root[k],
            &rest[k * sn..],
            first,
            xs,
            vs,
        );
    }
}

/// After the solve: the root follows the head, and each vertex moves with its new velocity,
/// is collided and strain-limited root to tip (DFTL velocity correction). `first(i)` is
/// vertex i's new velocity, the place in head space where that takes it and the head's
/// distance there.
#[allow(clippy::too_many_arguments)]
fn project(
    sh: Shared,
    m: &Rigid,
    root_new: V3,
    v_root: V3,
    rest: &[f32],
    first: impl Fn(usize) -> (V3, V3, f32),
    x: &mut [f32],
    v: &mut [f32],
) {
    let (cfg, head) = (sh.cfg, sh.head);
    let n = cfg.n_verts as usize;
    let dt = cfg.dt;
    let get = |a: &[f32], i: usize| -> V3 { [a[3 * i], a[3 * i + 1], a[3 * i + 2]] };
    x[0..3].copy_from_slice(&root_new);
    v[0..3].copy_from_slice(&v_root);
    let mut parent = root_new;
    // The previous vertex's velocity waits for this vertex's limit correction (DFTL).
    let mut prev_v = [0.0f32; 3];
    for i in 1..n {
        let (mut vi, ph, dist) = first(i);
        let mut xi = add(get(x, i), scale(vi, dt));
        // Collision, then strain limiting root to tip: the limit pulls a vertex towards its
        // (final) parent, which can dip the edge into the margin or the head.
        let free = xi;
        (xi, vi) = push(head, m, ph, dist, xi, vi, cfg.margin);
        let before = xi;
        xi = limit(cfg.strain_limit, rest[3 * (i - 1)], parent, xi);
        // Where the edge wraps round the head (an ear, the nape) one push and one pull do
        // not meet: alternating projections onto "outside the head" and "within the limit
        // of the parent" converge to a point in both when there is one; the limit has the
        // last word, so no edge ever stretches past it. A vertex neither pushed nor limited
        // is at least `margin` from the head, where the first test would end the loop.
        let untouched = before == free && xi == before;
        let rounds = if untouched { 0 } else { PROJECTIONS };
        for _ in 0..rounds {
            let pushed = collide(head, m, xi, vi, 0.5 * cfg.margin);
            if pushed.0 == xi {
                break;
            }
            vi = pushed.1;
            xi = limit(cfg.strain_limit, rest[3 * (i - 1)], parent, pushed.0);
        }
        let d = sub(xi, before);
        if i > 1 {
            let pv = sub(prev_v, scale(d, 1.0 / dt));
            v[3 * (i - 1)..3 * i].copy_from_slice(&pv);
        }
        prev_v = add(vi, scale(d, 1.0 / dt));
        x[3 * i..3 * i + 3].copy_from_slice(&xi);
        parent = xi;
    }
    v[3 * (n - 1)..3 * n].copy_from_slice(&prev_v);
}

/// The head's transforms at the start and end of the step.
struct Rigid {
    r0: [V3; 3],
    t0: V3,
    r1: [V3; 3],
    t1: V3,
    dt: f32,
}

/// A vertex closer to the head than `margin` (head space at the end of the step) is moved
/// out along the distance gradient and loses its velocity into the head, relative to the
/// head's own motion at that point.
fn collide(head: &[f32], m: &Rigid, xi: V3, vi: V3, margin: f32) -> (V3, V3) {
    let ph = apply_inv(&m.r1, m.t1, xi);
    push(head, m, ph, head_sdf(head, ph), xi, vi, margin)
}

/// [`collide`] of `xi` given its place `ph` in head space and the distance `dist` there.
#[allow(clippy::too_many_arguments)]
fn push(head: &[f32], m: &Rigid, ph: V3, dist: f32, xi: V3, vi: V3, margin: f32) -> (V3, V3) {
    if dist >= margin {
        return (xi, vi);
    }
    let g = head_sdf_grad(head, ph);
    let gl = dot(g, g).sqrt();
    if gl <= 1e-12 {
        return (xi, vi);
    }
    let nh = scale(g, 1.0 / gl);
    let ph2 = add(ph, scale(nh, margin - dist));
    let x2 = apply(&m.r1, m.t1, ph2);
    let vs = scale(sub(x2, apply(&m.r0, m.t0, ph2)), 1.0 / m.dt);
    let nw = apply(&m.r1, [0.0; 3], nh);
    let vn = dot(sub(vi, vs), nw);
    let v2 = if vn < 0.0 { sub(vi, scale(nw, vn)) } else { vi };
    (x2, v2)
}

/// Strain limiting (Provot 1995): with frozen directions an edge that turns through φ in one
/// step grows by 1/cos φ; the vertex is moved along the edge to within `limit` of the rest
/// length `l0` of its parent.
fn limit(limit: f32, l0: f32, parent: V3, xi: V3) -> V3 {
    if limit <= 0.0 || l0 <= 0.0 {
        return xi;
    }
    let e = sub(xi, parent);
    let len = dot(e, e).sqrt();
    let hi = l0 * (1.0 + limit);
    let lo = l0 * (1.0 - limit);
    if len <= 1e-12 || (len <= hi && len >= lo) {
        return xi;
    }
    let target = if len > hi { hi } else { lo };
    add(parent, scale(e, target / len))
}

/// Bindings: cfg, perm (512 u32), head (packed f32), motion (12 f32 per step frame), roots
/// (3 f32 per strand, model space), rest (3 spring rest lengths per vertex), x, v.
pub fn sim_step_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let perm = b[1].get::<u32>();
    let head = b[2].get::<f32>();
    let motion = b[3].get::<f32>();
    let roots = b[4].get::<f32>();
    let rest = b[5].get::<f32>();
    let mut x = b[6].get_mut::<f32>();
    let mut v = b[7].get_mut::<f32>();
    // Plain slices: the binding guards are not shared across threads.
    let sh = Shared {
        cfg: &cfg,
        perm: &perm,
        head: &head,
        motion: &motion,
    };
    step_all(sh, &roots, &rest, &mut x, &mut v);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Batches of strands give the one-strand step's values to the bit: strands on the
    /// head's surface (collisions), in gusty wind, with the head turning, and a strand count
    /// that leaves a part batch.
    #[test]
    fn batched_strands_step_like_single_strands() {
        let (n, ns) = (12usize, 2 * LANES + 5);
        let head = crate::hair::head::Head::default().sdf_packed();
        let perm = crate::sim::noise::perm_table();
        let cfg = |step| Config {
            n_strands: ns as u32,
            n_verts: n as u32,
            step,
            dt: 1.0 / 300.0,
            time: step as f32 / 300.0,
            k_stretch: 4e4,
            k_bend: 400.0,
            k_twist: 100.0,
            damping: 0.005,
            drag: 4.0,
            wind_x: 3.0,
            wind_z: 1.0,
            gust: 0.8,
            noise_scale: 0.12,
            noise_speed: 1.5,
            margin: 1e-3,
            strain_limit: 0.002,
            ..Default::default()
        };
        let steps = 30u32;
        let mut motion = Vec::new();
        for k in 0..=steps {
            let (s, c) = (0.004 * k as f32).sin_cos();
            motion.extend_from_slice(&[c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c, 0.0, 0.0, 0.0]);
        }
        // Roots on the surface along directions over the top of the head; each strand runs
        // down and outwards by 1 cm edges, its first vertices inside the margin.
        let (mut roots, mut x) = (Vec::new(), Vec::new());
        for s in 0..ns {
            let a = s as f32 * 0.7;
            let dir = [a.cos() * 0.8, 0.6, a.sin() * 0.8];
            let (mut lo, mut hi) = (0.0f32, 0.3f32);
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if head_sdf(&head, scale(dir, mid)) < 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let root = scale(dir, hi);
            roots.extend_from_slice(&root);
            let step = [dir[0] * 0.5, -0.8, dir[2] * 0.5];
            for i in 0..n {
                x.extend_from_slice(&add(root, scale(step, 0.01 * i as f32)));
            }
        }
        let mut rest = vec![0.0f32; 3 * n * ns];
        for s in 0..ns {
            for a in 0..n {
                for f in 0..3 {
                    if a + f + 1 < n {
                        let o = 3 * (s * n + a);
                        let b = 3 * (s * n + a + f + 1);
                        let d = sub([x[b], x[b + 1], x[b + 2]], [x[o], x[o + 1], x[o + 2]]);
                        rest[3 * (s * n + a) + f] = dot(d, d).sqrt();
                    }
                }
            }
        }
        let x0 = x.clone();
        let (mut xb, mut vb) = (x.clone(), vec![0.0f32; x.len()]);
        let (mut xs, mut vs) = (x, vec![0.0f32; xb.len()]);
        let mut sc = Scratch::<1>::new();
        let sn = 3 * n;
        for k in 0..steps {
            let c = cfg(k);
            let sh = Shared {
                cfg: &c,
                perm: &perm,
                head: &head,
                motion: &motion,
            };
            step_all(sh, &roots, &rest, &mut xb, &mut vb);
            for s in 0..ns {
                step_strands(
                    sh,
                    &roots[3 * s..3 * s + 3],
                    &rest[sn * s..sn * (s + 1)],
                    &mut xs[sn * s..sn * (s + 1)],
                    &mut vs[sn * s..sn * (s + 1)],
                    &mut sc,
                );
            }
        }
        let bits = |a: &[f32]| a.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&xb), bits(&xs));
        assert_eq!(bits(&vb), bits(&vs));
        // The strands moved, and the collision had vertices to push out.
        let moved = xb
            .iter()
            .zip(&x0)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(moved > 1e-3, "{moved} m");
        let inside = (0..ns * n)
            .filter(|&g| {
                g % n != 0 && head_sdf(&head, [x0[3 * g], x0[3 * g + 1], x0[3 * g + 2]]) < 1e-3
            })
            .count();
        assert!(inside > 0);
    }

    /// A horizontal 8-vertex strand far from the head falls under gravity and keeps its
    /// edge lengths; hanging straight down it stays put.
    #[test]
    fn a_chain_swings_down_without_stretching() {
        let n = 8usize;
        let cfg = Config {
            n_strands: 1,
            n_verts: n as u32,
            step: 0,
            dt: 1.0 / 300.0,
            time: 0.0,
            k_stretch: 4e4,
            k_bend: 400.0,
            k_twist: 100.0,
            damping: 0.005,
            drag: 4.0,
            noise_scale: 0.1,
            gravity: 9.8,
            margin: 1e-3,
            strain_limit: 0.002,
            ..Default::default()
        };
        let perm = crate::sim::noise::perm_table();
        let head = crate::hair::head::Head::default().sdf_packed();
        let id = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
        let motion: Vec<f32> = id.iter().chain(id.iter()).copied().collect();
        let l = 0.01f32;
        let mut rest = vec![0.0f32; 3 * n];
        for a in 0..n {
            for f in 0..3 {
                if a + f + 1 < n {
                    rest[3 * a + f] = l * (f + 1) as f32;
                }
            }
        }
        let root = [1.0, 0.0, 0.0];
        let mut x: Vec<f32> = (0..n)
            .flat_map(|i| [1.0 + l * i as f32, 0.0, 0.0])
            .collect();
        let mut v = vec![0.0f32; 3 * n];
        let mut worst = 0.0f32;
        let sh = Shared {
            cfg: &cfg,
            perm: &perm,
            head: &head,
            motion: &motion,
        };
        let mut sc = Scratch::<1>::new();
        for _ in 0..600 {
            step_strands(sh, &root, &rest, &mut x, &mut v, &mut sc);
            for i in 0..n - 1 {
                let d: f32 = (0..3)
                    .map(|c| (x[3 * i + 3 + c] - x[3 * i + c]).powi(2))
                    .sum();
                worst = worst.max((d.sqrt() - l).abs() / l);
            }
        }
        let tip_y = x[3 * (n - 1) + 1];
        assert!(tip_y < -0.05, "the tip should have fallen: {tip_y}");
        assert!(worst < 0.01, "stretch {worst}");
    }
}
