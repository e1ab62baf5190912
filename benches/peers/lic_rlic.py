#!/usr/bin/env python3
"""Peer for benches/lic.rs: line-integral convolution by PyPI `rlic` (Rust, single thread)
on the same noise and orientation field as coif's `cz_lic` pass.

Reads the noise and the field's (u, v) = (cos t, sin t) (.npy, float32, H x W; NaN off the
hair, where rlic ends its streamlines), convolves with a box kernel of KLEN taps in
'polarization' mode (an orientation has no sign, as in coif), ITERS iterations, writes the
result to OUT.npy and prints one JSON line with the median milliseconds over REPS runs.

usage: lic_rlic.py NOISE.npy U.npy V.npy OUT.npy KLEN ITERS REPS
"""
import importlib.metadata
import json
import sys
import time

import numpy as np
import rlic


def main():
    noise = np.load(sys.argv[1]).astype(np.float32)
    u = np.load(sys.argv[2]).astype(np.float32)
    v = np.load(sys.argv[3]).astype(np.float32)
    out, klen, iters, reps = sys.argv[4], int(sys.argv[5]), int(sys.argv[6]), int(sys.argv[7])
    kernel = np.full(klen, 1.0 / klen, dtype=np.float32)
    times = []
    res = None
    for _ in range(reps):
        t = time.perf_counter()
        res = rlic.convolve(noise, u, v, kernel=kernel, uv_mode="polarization", iterations=iters)
        times.append((time.perf_counter() - t) * 1e3)
    np.save(out, np.nan_to_num(res).astype(np.float32))
    version = importlib.metadata.version("rlic")
    print(json.dumps({"peer": f"rlic {version}", "median_ms": float(np.median(times))}))


if __name__ == "__main__":
    main()
