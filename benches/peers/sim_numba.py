#!/usr/bin/env python3
"""Peer for benches/sim.rs: the same mass-spring step as coif's sim_step pass, in numba
(parallel over strands): edge, bending and twist springs with frozen directions, one banded
Cholesky solve per strand (linearly implicit Euler), constant-wind drag, strain limiting
root to tip with follow-the-leader velocities, and collision with a sphere standing in for
the head (coif evaluates its analytic head and Perlin noise per vertex, which this peer
leaves out, so it does less work per step).

Reads raw little-endian f32 files written by the bench in DIR: x.f32 (S*N*3), rest.f32
(S*N*3), roots.f32 (S*3); N from argv. Prints one JSON line: ms per step (median of REPS
batches of STEPS), strands, vertices.

usage: sim_numba.py DIR N STEPS REPS
"""
import json
import sys
import time

import numpy as np
from numba import njit, prange

BAND = 11
B1 = BAND + 1


@njit(cache=True, fastmath=False)
def step_strand(x, v, rest, root, n, dt, ks, kb, kt, damp, drag, wind, limit, centre, radius):
    nu = 3 * (n - 1)
    l = np.zeros(nu * B1, dtype=np.float32)
    rhs = np.zeros(nu, dtype=np.float32)
    diag = np.float32(1.0) + dt * drag
    for i in range(1, n):
        for c in range(3):
            r = 3 * (i - 1) + c
            rhs[r] = v[3 * i + c] + dt * drag * wind[c]
            l[r * B1] = diag
    kk = (ks, kb, kt)
    for a in range(n - 1):
        for fam in range(3):
            b = a + fam + 1
            if b >= n:
                continue
            l0 = rest[3 * a + fam]
            k = kk[fam]
            d0 = x[3 * b:3 * b + 3] - x[3 * a:3 * a + 3]
            ln = np.sqrt(d0[0] * d0[0] + d0[1] * d0[1] + d0[2] * d0[2])
            if ln < 1e-12 or l0 <= 0.0:
                continue
            d = d0 / ln
            fe = d * (dt * (k / l0) * (ln - l0))
            cc = dt * (k * dt + damp * k) / l0
            bu = 3 * (b - 1)
            for p in range(3):
                rhs[bu + p] -= fe[p]
                for q in range(p + 1):
                    l[(bu + p) * B1 + (p - q)] += cc * d[p] * d[q]
            if a > 0:
                au = 3 * (a - 1)
                for p in range(3):
                    rhs[au + p] += fe[p]
                    for q in range(p + 1):
                        l[(au + p) * B1 + (p - q)] += cc * d[p] * d[q]
                    for q in range(3):
                        l[(bu + p) * B1 + (bu + p - (au + q))] -= cc * d[p] * d[q]
    for i in range(nu):
        j0 = max(0, i - BAND)
        for j in range(j0, i + 1):
            s = l[i * B1 + (i - j)]
            for m in range(j0, j):
                s -= l[i * B1 + (i - m)] * l[j * B1 + (j - m)]
            if i == j:
                l[i * B1] = np.sqrt(max(s, 1e-20))
            else:
                l[i * B1 + (i - j)] = s / l[j * B1]
    for i in range(nu):
        s = rhs[i]
        for m in range(max(0, i - BAND), i):
            s -= l[i * B1 + (i - m)] * rhs[m]
        rhs[i] = s / l[i * B1]
    for i in range(nu - 1, -1, -1):
        s = rhs[i]
        for m in range(i + 1, min(i + BAND + 1, nu)):
            s -= l[m * B1 + (m - i)] * rhs[m]
        rhs[i] = s / l[i * B1]
    x[0:3] = root
    v[0:3] = 0.0
    parent = root.copy()
    prev_v = np.zeros(3, dtype=np.float32)
    for i in range(1, n):
        vi = rhs[3 * (i - 1):3 * i].copy()
        xi = x[3 * i:3 * i + 3] + vi * dt
        # Sphere collision.
        e = xi - centre
        dist = np.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
        if dist < radius and dist > 1e-12:
            nrm = e / dist
            xi = centre + nrm * np.float32(radius)
            vn = vi[0] * nrm[0] + vi[1] * nrm[1] + vi[2] * nrm[2]
            if vn < 0.0:
                vi = vi - nrm * vn
        before = xi.copy()
        l0 = rest[3 * (i - 1)]
        e = xi - parent
        ln = np.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
        hi = l0 * (1.0 + limit)
        lo = l0 * (1.0 - limit)
        if ln > 1e-12 and (ln > hi or ln < lo):
            want = hi if ln > hi else lo
            xi = parent + e * np.float32(want / ln)
        dd = xi - before
        if i > 1:
            v[3 * (i - 1):3 * i] = prev_v - dd / dt
        prev_v = vi + dd / dt
        x[3 * i:3 * i + 3] = xi
        parent = xi
    v[3 * (n - 1):3 * n] = prev_v


@njit(parallel=True, cache=True)
def step_all(x, v, rest, roots, n, dt, wind, centre, radius):
    s = roots.shape[0]
    for k in prange(s):
        a, b = 3 * n * k, 3 * n * (k + 1)
        step_strand(x[a:b], v[a:b], rest[a:b], roots[k], n, dt, np.float32(4e4),
                    np.float32(400.0), np.float32(100.0), np.float32(0.005), np.float32(4.0),
                    wind, np.float32(0.002), centre, radius)


def main():
    d, n, steps, reps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
    x = np.fromfile(f"{d}/x.f32", dtype="<f4")
    rest = np.fromfile(f"{d}/rest.f32", dtype="<f4")
    roots = np.fromfile(f"{d}/roots.f32", dtype="<f4").reshape(-1, 3)
    v = np.zeros_like(x)
    dt = np.float32(1.0 / 300.0)
    wind = np.array([1.0, 0.0, 0.35], dtype=np.float32)
    centre = np.array([0.0, 0.02, 0.0], dtype=np.float32)
    radius = np.float32(0.08)
    step_all(x, v, rest, roots, n, dt, wind, centre, radius)  # compile + warm up
    times = []
    for _ in range(reps):
        t = time.perf_counter()
        for _ in range(steps):
            step_all(x, v, rest, roots, n, dt, wind, centre, radius)
        times.append((time.perf_counter() - t) / steps)
    times.sort()
    print(json.dumps({"ms_per_step": 1e3 * times[len(times) // 2], "strands": len(roots),
                      "vertices": n, "finite": bool(np.isfinite(x).all())}))


if __name__ == "__main__":
    main()
