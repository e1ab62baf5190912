#!/usr/bin/env python3
"""Peer for benches/orient.rs: the same Gabor bank and orientation pipeline in OpenCV.

Reads the image and the kernel bank that the Rust bench wrote (so both filter with exactly
the same kernels), times OpenCV's filter2D bank and a full OpenCV/numpy orientation
pipeline (DoG, bank + argmax + confidence, refinement passes, double-angle smoothing), and
prints one JSON line with median milliseconds.

usage: gabor_opencv.py IMAGE.npy KERNELS.npy REFINE DOG_FINE DOG_COARSE SMOOTH REPS
"""
import json
import sys
import time

import cv2
import numpy as np


def bank(img, kernels):
    # Clamp-to-edge borders, as coif's passes use.
    return np.stack(
        [cv2.filter2D(img, cv2.CV_32F, k, borderType=cv2.BORDER_REPLICATE) for k in kernels]
    )


def orient_from(resp):
    n = resp.shape[0]
    r = np.maximum(resp, 0.0)
    best = np.argmax(r, axis=0)
    rmax = np.take_along_axis(r, best[None], 0)[0]
    theta = best * (np.pi / n)
    ang = np.arange(n)[:, None, None] * (np.pi / n)
    d = np.abs(ang - theta[None]) % np.pi
    d = np.minimum(d, np.pi - d)
    conf = np.sqrt((d * d * (r - rmax[None]) ** 2).sum(0) / (d * d).sum(0))
    return theta, conf


def pipeline(img, kernels, refine, fine, coarse, smooth):
    cur = img
    if coarse > 0:
        cur = cv2.GaussianBlur(img, (0, 0), fine, borderType=cv2.BORDER_REPLICATE) - cv2.GaussianBlur(
            img, (0, 0), coarse, borderType=cv2.BORDER_REPLICATE
        )
    for _ in range(refine + 1):
        theta, conf = orient_from(bank(cur, kernels))
        cur = conf.astype(np.float32)
    dx = (conf * np.cos(2 * theta)).astype(np.float32)
    dy = (conf * np.sin(2 * theta)).astype(np.float32)
    if smooth > 0:
        dx = cv2.GaussianBlur(dx, (0, 0), smooth, borderType=cv2.BORDER_REPLICATE)
        dy = cv2.GaussianBlur(dy, (0, 0), smooth, borderType=cv2.BORDER_REPLICATE)
    return (0.5 * np.arctan2(dy, dx)) % np.pi, conf


def median_ms(f, reps):
    f()  # warm-up
    ts = []
    for _ in range(reps):
        t = time.perf_counter()
        f()
        ts.append((time.perf_counter() - t) * 1e3)
    return float(np.median(ts))


def main():
    img = np.load(sys.argv[1]).astype(np.float32)
    kernels = [k.astype(np.float32) for k in np.load(sys.argv[2])]
    refine, fine, coarse, smooth, reps = (
        int(sys.argv[3]),
        float(sys.argv[4]),
        float(sys.argv[5]),
        float(sys.argv[6]),
        int(sys.argv[7]),
    )
    out = {
        "opencv": cv2.__version__,
        "threads": cv2.getNumThreads(),
        "bank_ms": median_ms(lambda: bank(img, kernels), reps),
        "pipeline_ms": median_ms(lambda: pipeline(img, kernels, refine, fine, coarse, smooth), reps),
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
