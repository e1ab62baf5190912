// One mass-spring step per strand (C13 §4 after Selle et al. 2008); see
// `src/stages/sim_step.rs` for the equations. Linearly implicit Euler with frozen spring
// directions: one banded Cholesky solve per strand, in private memory.

struct Config {
    n_strands: u32,
    n_verts: u32,
    step: u32,
    dt: f32,
    time: f32,
    k_stretch: f32,
    k_bend: f32,
    k_twist: f32,
    damping: f32,
    drag: f32,
    wind_x: f32,
    wind_y: f32,
    wind_z: f32,
    gust: f32,
    noise_scale: f32,
    noise_speed: f32,
    gravity: f32,
    margin: f32,
    strain_limit: f32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
// Doubled Perlin permutation (512).
@group(0) @binding(1) var<storage, read> perm: array<u32>;
// Packed head distance primitives (Head::sdf_packed).
@group(0) @binding(2) var<storage, read> head: array<f32>;
// Head rotation (row-major) and translation per step frame, 12 floats each.
@group(0) @binding(3) var<storage, read> motion: array<f32>;
// Rest root per strand (model space).
@group(0) @binding(4) var<storage, read> roots: array<f32>;
// Rest lengths of the springs i-i+1, i-i+2, i-i+3 per vertex.
@group(0) @binding(5) var<storage, read> rest: array<f32>;
@group(0) @binding(6) var<storage, read_write> xs: array<f32>;
@group(0) @binding(7) var<storage, read_write> vs: array<f32>;

#include "shared/noise.wgsl"
#include "shared/head_sdf.wgsl"

const BAND: u32 = 11u;
const PROJECTIONS: u32 = 3u;
const B1: u32 = 12u;
// 3 * (MAX_VERTS - 1) with MAX_VERTS = 64.
const MAX_UNKNOWNS: u32 = 189u;

struct Rigid {
    r0: vec3<f32>,
    r1: vec3<f32>,
    r2: vec3<f32>,
    t: vec3<f32>,
}

fn motion_at(k: u32) -> Rigid {
    let o = k * 12u;
    return Rigid(
        vec3<f32>(motion[o], motion[o + 1u], motion[o + 2u]),
        vec3<f32>(motion[o + 3u], motion[o + 4u], motion[o + 5u]),
        vec3<f32>(motion[o + 6u], motion[o + 7u], motion[o + 8u]),
        vec3<f32>(motion[o + 9u], motion[o + 10u], motion[o + 11u])
    );
}

fn apply(m: Rigid, p: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(m.r0, p), dot(m.r1, p), dot(m.r2, p)) + m.t;
}

fn apply_inv(m: Rigid, p: vec3<f32>) -> vec3<f32> {
    let q = p - m.t;
    return m.r0 * q.x + m.r1 * q.y + m.r2 * q.z;
}

fn rot(m: Rigid, p: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(m.r0, p), dot(m.r1, p), dot(m.r2, p));
}

fn wind(p: vec3<f32>, t: f32) -> vec3<f32> {
    let inv = 1.0 / cfg.noise_scale;
    let s = cfg.noise_speed * t;
    let q = vec3<f32>(p.x * inv - s, p.y * inv, p.z * inv + 0.5 * s);
    let n = vec3<f32>(
        perlin(q.x, q.y, q.z),
        perlin(q.x + 31.416, q.y + 47.853, q.z + 12.793),
        perlin(q.x + 73.156, q.y + 19.284, q.z + 91.527)
    );
    return vec3<f32>(cfg.wind_x, cfg.wind_y, cfg.wind_z) + cfg.gust * n;
}

fn vert(a: ptr<function, array<f32, 192>>, i: u32) -> vec3<f32> {
    return vec3<f32>((*a)[3u * i], (*a)[3u * i + 1u], (*a)[3u * i + 2u]);
}

struct Moved {
    x: vec3<f32>,
    v: vec3<f32>,
}

// A vertex closer to the head than `margin` moves out along the distance gradient and loses
// its velocity into the head, relative to the head's own motion there.
fn collide(m0: Rigid, m1: Rigid, xi: vec3<f32>, vi: vec3<f32>, margin: f32) -> Moved {
    let ph = apply_inv(m1, xi);
    let dist = head_sdf(ph);
    if dist >= margin {
        return Moved(xi, vi);
    }
    let g = head_sdf_grad(ph);
    let gl = sqrt(dot(g, g));
    if gl <= 1e-12 {
        return Moved(xi, vi);
    }
    let nh = g * (1.0 / gl);
    let ph2 = ph + nh * (margin - dist);
    let x2 = apply(m1, ph2);
    let vsurf = (x2 - apply(m0, ph2)) * (1.0 / cfg.dt);
    let nw = rot(m1, nh);
    let vn = dot(vi - vsurf, nw);
    if vn < 0.0 {
        return Moved(x2, vi - nw * vn);
    }
    return Moved(x2, vi);
}

// Strain limiting: the vertex moves along its edge to within `lim` of the rest length.
fn limit(lim: f32, l0: f32, parent: vec3<f32>, xi: vec3<f32>) -> vec3<f32> {
    if lim <= 0.0 || l0 <= 0.0 {
        return xi;
    }
    let e = xi - parent;
    let len = sqrt(dot(e, e));
    let hi = l0 * (1.0 + lim);
    let lo = l0 * (1.0 - lim);
    if len <= 1e-12 || (len <= hi && len >= lo) {
        return xi;
    }
    let want = select(lo, hi, len > hi);
    return parent + e * (want / len);
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x;
    if s >= cfg.n_strands {
        return;
    }
    let n = cfg.n_verts;
    let nu = 3u * (n - 1u);
    let dt = cfg.dt;
    let base = 3u * n * s;
    var x: array<f32, 192>;
    var v: array<f32, 192>;
    for (var k = 0u; k < 3u * n; k++) {
        x[k] = xs[base + k];
        v[k] = vs[base + k];
    }
    let m0 = motion_at(cfg.step);
    let m1 = motion_at(cfg.step + 1u);
    let root = vec3<f32>(roots[3u * s], roots[3u * s + 1u], roots[3u * s + 2u]);
    let root_new = apply(m1, root);
    let v_root = (root_new - apply(m0, root)) * (1.0 / dt);
    var l: array<f32, 2268>;
    var rhs: array<f32, 189>;
    let diag = 1.0 + dt * cfg.drag;
    for (var i = 1u; i < n; i++) {
        let xi = vert(&x, i);
        let u = wind(xi, cfg.time);
        let vi = vert(&v, i);
        let f = vec3<f32>(
            vi.x + dt * cfg.drag * u.x,
            vi.y + dt * (cfg.drag * u.y - cfg.gravity),
            vi.z + dt * cfg.drag * u.z
        );
        for (var c = 0u; c < 3u; c++) {
            let r = 3u * (i - 1u) + c;
            rhs[r] = f[c];
            l[r * B1] = diag;
        }
    }
    for (var a = 0u; a + 1u < n; a++) {
        for (var fam = 0u; fam < 3u; fam++) {
            let b = a + fam + 1u;
            if b >= n {
                continue;
            }
            let l0 = rest[base + 3u * a + fam];
            var k = cfg.k_stretch;
            if fam == 1u {
                k = cfg.k_bend;
            } else if fam == 2u {
                k = cfg.k_twist;
            }
            let xa = vert(&x, a);
            let d0 = vert(&x, b) - xa;
            let len = sqrt(dot(d0, d0));
            if len < 1e-12 || l0 <= 0.0 {
                continue;
            }
            let d = d0 * (1.0 / len);
            let fe = d * (dt * (k / l0) * (len - l0));
            let c = dt * (k * dt + cfg.damping * k) / l0;
            let bu = 3u * (b - 1u);
            for (var p = 0u; p < 3u; p++) {
                rhs[bu + p] -= fe[p];
                for (var q = 0u; q <= p; q++) {
                    l[(bu + p) * B1 + (p - q)] += c * d[p] * d[q];
                }
            }
            if a == 0u {
                for (var p = 0u; p < 3u; p++) {
                    rhs[bu + p] += c * d[p] * dot(d, v_root);
                }
            } else {
                let au = 3u * (a - 1u);
                for (var p = 0u; p < 3u; p++) {
                    rhs[au + p] += fe[p];
                    for (var q = 0u; q <= p; q++) {
                        l[(au + p) * B1 + (p - q)] += c * d[p] * d[q];
                    }
                    for (var q = 0u; q < 3u; q++) {
                        l[(bu + p) * B1 + (bu + p - (au + q))] -= c * d[p] * d[q];
                    }
                }
            }
        }
    }
    // Banded Cholesky in place, then the two triangular solves.
    for (var i = 0u; i < nu; i++) {
        let j0 = select(0u, i - BAND, i > BAND);
        for (var j = j0; j <= i; j++) {
            var sum = l[i * B1 + (i - j)];
            for (var kk = j0; kk < j; kk++) {
                sum -= l[i * B1 + (i - kk)] * l[j * B1 + (j - kk)];
            }
            if i == j {
                l[i * B1] = sqrt(max(sum, 1e-20));
            } else {
                l[i * B1 + (i - j)] = sum / l[j * B1];
            }
        }
    }
    for (var i = 0u; i < nu; i++) {
        var sum = rhs[i];
        let k0 = select(0u, i - BAND, i > BAND);
        for (var kk = k0; kk < i; kk++) {
            sum -= l[i * B1 + (i - kk)] * rhs[kk];
        }
        rhs[i] = sum / l[i * B1];
    }
    for (var ii = 0u; ii < nu; ii++) {
        let i = nu - 1u - ii;
        var sum = rhs[i];
        let k1 = min(i + BAND + 1u, nu);
        for (var kk = i + 1u; kk < k1; kk++) {
            sum -= l[kk * B1 + (kk - i)] * rhs[kk];
        }
        rhs[i] = sum / l[i * B1];
    }
    xs[base] = root_new.x;
    xs[base + 1u] = root_new.y;
    xs[base + 2u] = root_new.z;
    vs[base] = v_root.x;
    vs[base + 1u] = v_root.y;
    vs[base + 2u] = v_root.z;
    var parent = root_new;
    var prev_v = vec3<f32>(0.0);
    for (var i = 1u; i < n; i++) {
        let r = 3u * (i - 1u);
        var vi = vec3<f32>(rhs[r], rhs[r + 1u], rhs[r + 2u]);
        var xi = vert(&x, i) + vi * dt;
        var c = collide(m0, m1, xi, vi, cfg.margin);
        let before = c.x;
        let untouched = all(c.x == xi);
        xi = limit(cfg.strain_limit, rest[base + 3u * (i - 1u)], parent, c.x);
        vi = c.v;
        // Alternating projections: outside the head, within the limit of the parent. A
        // vertex neither pushed nor limited is at least `margin` from the head, where the
        // first test would end the loop.
        let rounds = select(PROJECTIONS, 0u, untouched && all(xi == before));
        for (var k = 0u; k < rounds; k++) {
            c = collide(m0, m1, xi, vi, 0.5 * cfg.margin);
            if all(c.x == xi) {
                break;
            }
            xi = limit(cfg.strain_limit, rest[base + 3u * (i - 1u)], parent, c.x);
            vi = c.v;
        }
        let d = xi - before;
        if i > 1u {
            let pv = prev_v - d * (1.0 / dt);
            vs[base + 3u * (i - 1u)] = pv.x;
            vs[base + 3u * (i - 1u) + 1u] = pv.y;
            vs[base + 3u * (i - 1u) + 2u] = pv.z;
        }
        prev_v = vi + d * (1.0 / dt);
        xs[base + 3u * i] = xi.x;
        xs[base + 3u * i + 1u] = xi.y;
        xs[base + 3u * i + 2u] = xi.z;
        parent = xi;
    }
    vs[base + 3u * (n - 1u)] = prev_v.x;
    vs[base + 3u * (n - 1u) + 1u] = prev_v.y;
    vs[base + 3u * (n - 1u) + 2u] = prev_v.z;
}
