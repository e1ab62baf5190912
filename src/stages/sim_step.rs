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
use crate::sim::head_sdf::{head_sdf, head_sdf_grad};
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

/// One strand's step; `x` and `v` hold its `n_verts` vertices (xyz each).
#[allow(clippy::too_many_arguments)]
pub fn step_strand(
    cfg: &Config,
    perm: &[u32],
    head: &[f32],
    motion: &[f32],
    root: V3,
    rest: &[f32],
    x: &mut [f32],
    v: &mut [f32],
) {
    let n = cfg.n_verts as usize;
    let nu = 3 * (n - 1);
    let dt = cfg.dt;
    let (r0, t0) = motion_at(motion, cfg.step);
    let (r1, t1) = motion_at(motion, cfg.step + 1);
    let root_new = apply(&r1, t1, root);
    let v_root = scale(sub(root_new, apply(&r0, t0, root)), 1.0 / dt);
    let get = |a: &[f32], i: usize| -> V3 { [a[3 * i], a[3 * i + 1], a[3 * i + 2]] };
    // Band of the lower triangle: l[i * B1 + (i − j)] = A[i][j].
    let mut l = [0.0f32; MAX_UNKNOWNS * B1];
    let mut rhs = [0.0f32; MAX_UNKNOWNS];
    let diag = 1.0 + dt * cfg.drag;
    for i in 1..n {
        let xi = get(x, i);
        let u = wind(cfg, perm, xi, cfg.time);
        let vi = get(v, i);
        let f = [
            vi[0] + dt * cfg.drag * u[0],
            vi[1] + dt * (cfg.drag * u[1] - cfg.gravity),
            vi[2] + dt * cfg.drag * u[2],
        ];
        for (c, fc) in f.iter().enumerate() {
            let r = 3 * (i - 1) + c;
            rhs[r] = *fc;
            l[r * B1] = diag;
        }
    }
    for a in 0..n - 1 {
        for fam in 0..3 {
            let b = a + fam + 1;
            if b >= n {
                continue;
            }
            let l0 = rest[3 * a + fam];
            let k = [cfg.k_stretch, cfg.k_bend, cfg.k_twist][fam];
            let xa = get(x, a);
            let d0 = sub(get(x, b), xa);
            let len = dot(d0, d0).sqrt();
            if len < 1e-12 || l0 <= 0.0 {
                continue;
            }
            let d = scale(d0, 1.0 / len);
            // Elastic force on a (and its opposite on b), explicit at x.
            let fe = scale(d, dt * (k / l0) * (len - l0));
            let c = dt * (k * dt + cfg.damping * k) / l0;
            let bu = 3 * (b - 1);
            for p in 0..3 {
                rhs[bu + p] -= fe[p];
                for q in 0..=p {
                    l[(bu + p) * B1 + (p - q)] += c * d[p] * d[q];
                }
            }
            if a == 0 {
                // The root's velocity is known: its spring term moves to the right.
                for p in 0..3 {
                    rhs[bu + p] += c * d[p] * dot(d, v_root);
                }
            } else {
                let au = 3 * (a - 1);
                for p in 0..3 {
                    rhs[au + p] += fe[p];
                    for q in 0..=p {
                        l[(au + p) * B1 + (p - q)] += c * d[p] * d[q];
                    }
                    // Off-diagonal block: row of b, column of a (always below the diagonal).
                    for q in 0..3 {
                        l[(bu + p) * B1 + (bu + p - (au + q))] -= c * d[p] * d[q];
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
            let k0 = j0.max(j.saturating_sub(BAND));
            for kk in k0..j {
                s -= l[i * B1 + (i - kk)] * l[j * B1 + (j - kk)];
            }
            if i == j {
                l[i * B1] = s.max(1e-20).sqrt();
            } else {
                l[i * B1 + (i - j)] = s / l[j * B1];
            }
        }
    }
    for i in 0..nu {
        let mut s = rhs[i];
        for kk in i.saturating_sub(BAND)..i {
            s -= l[i * B1 + (i - kk)] * rhs[kk];
        }
        rhs[i] = s / l[i * B1];
    }
    for i in (0..nu).rev() {
        let mut s = rhs[i];
        for kk in i + 1..(i + BAND + 1).min(nu) {
            s -= l[kk * B1 + (kk - i)] * rhs[kk];
        }
        rhs[i] = s / l[i * B1];
    }
    x[0..3].copy_from_slice(&root_new);
    v[0..3].copy_from_slice(&v_root);
    let m = Rigid { r0, t0, r1, t1, dt };
    let mut parent = root_new;
    // The previous vertex's velocity waits for this vertex's limit correction (DFTL).
    let mut prev_v = [0.0f32; 3];
    for i in 1..n {
        let r = 3 * (i - 1);
        let mut vi = [rhs[r], rhs[r + 1], rhs[r + 2]];
        let mut xi = add(get(x, i), scale(vi, dt));
        // Collision, then strain limiting root to tip: the limit pulls a vertex towards its
        // (final) parent, which can dip the edge into the margin or the head.
        (xi, vi) = collide(head, &m, xi, vi, cfg.margin);
        let before = xi;
        xi = limit(cfg.strain_limit, rest[3 * (i - 1)], parent, xi);
        // Where the edge wraps round the head (an ear, the nape) one push and one pull do
        // not meet: alternating projections onto "outside the head" and "within the limit
        // of the parent" converge to a point in both when there is one; the limit has the
        // last word, so no edge ever stretches past it.
        for _ in 0..PROJECTIONS {
            let pushed = collide(head, &m, xi, vi, 0.5 * cfg.margin);
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
    let dist = head_sdf(head, ph);
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
    let (perm, head, motion, roots, rest) = (&*perm, &*head, &*motion, &*roots, &*rest);
    let n = cfg.n_verts as usize;
    let ns = cfg.n_strands as usize;
    x[..3 * n * ns]
        .par_chunks_mut(3 * n)
        .zip(v[..3 * n * ns].par_chunks_mut(3 * n))
        .enumerate()
        .for_each(|(s, (xs, vs))| {
            let root = [roots[3 * s], roots[3 * s + 1], roots[3 * s + 2]];
            step_strand(
                &cfg,
                perm,
                head,
                motion,
                root,
                &rest[3 * n * s..3 * n * (s + 1)],
                xs,
                vs,
            );
        });
}

#[cfg(test)]
mod tests {
    use super::*;

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
        for _ in 0..600 {
            step_strand(&cfg, &perm, &head, &motion, root, &rest, &mut x, &mut v);
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
