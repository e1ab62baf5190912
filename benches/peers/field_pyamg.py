#!/usr/bin/env python3
"""Peer for benches/field.rs: pyamg smoothed-aggregation AMG as a CG preconditioner on the
normal equations (L^2 + w_c P) v = w_c P c of C13 Eq. (3), written by the bench as raw
little-endian files in DIR: indptr.i64, indices.i32, data.f64 (CSR, n x n), b.f64 (n x 3).
Each of the three components is solved to relative residual TOL. Prints one JSON line with
setup / solve seconds, iterations and the final relative residuals.

usage: field_pyamg.py DIR TOL
"""
import json
import sys
import time

import numpy as np
import pyamg
import scipy.sparse as sp


def main():
    d, tol = sys.argv[1], float(sys.argv[2])
    indptr = np.fromfile(f"{d}/indptr.i64", dtype="<i8")
    indices = np.fromfile(f"{d}/indices.i32", dtype="<i4")
    data = np.fromfile(f"{d}/data.f64", dtype="<f8")
    n = len(indptr) - 1
    b = np.fromfile(f"{d}/b.f64", dtype="<f8").reshape(n, 3)
    a = sp.csr_matrix((data, indices, indptr), shape=(n, n))
    t0 = time.perf_counter()
    ml = pyamg.smoothed_aggregation_solver(a, symmetry="hermitian")
    t1 = time.perf_counter()
    iters, rels = [], []
    for c in range(3):
        res = []
        x = ml.solve(b[:, c], tol=tol, accel="cg", maxiter=2000, residuals=res)
        iters.append(len(res) - 1)
        rels.append(float(np.linalg.norm(b[:, c] - a @ x) / np.linalg.norm(b[:, c])))
    t2 = time.perf_counter()
    print(json.dumps({
        "n": n, "nnz": int(a.nnz), "levels": len(ml.levels),
        "setup_s": t1 - t0, "solve_s": t2 - t1, "total_s": t2 - t0,
        "iterations": iters, "rel_residuals": rels,
        "pyamg": pyamg.__version__,
    }))


if __name__ == "__main__":
    main()
