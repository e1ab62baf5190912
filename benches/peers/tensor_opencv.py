#!/usr/bin/env python3
"""Peer for benches/sketch.rs: a dense orientation field by the structure tensor in OpenCV
(Sobel gradients, Gaussian-smoothed tensor, orientation across the dominant gradient) — what
a user would otherwise compute to get a hair flow field from a photo.

Reads a gray image (.npy, float32, H x W), writes the orientation (radians in [0, pi), x
right, y down) next to OUT.npy, and prints one JSON line with the median milliseconds.

usage: tensor_opencv.py IMAGE.npy OUT.npy SIGMA REPS
"""
import json
import sys
import time

import cv2
import numpy as np


def field(img, sigma):
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE)
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE)
    k = (0, 0)
    jxx = cv2.GaussianBlur(gx * gx, k, sigma, borderType=cv2.BORDER_REPLICATE)
    jxy = cv2.GaussianBlur(gx * gy, k, sigma, borderType=cv2.BORDER_REPLICATE)
    jyy = cv2.GaussianBlur(gy * gy, k, sigma, borderType=cv2.BORDER_REPLICATE)
    # Dominant gradient angle; the strands run across it.
    grad = 0.5 * np.arctan2(2.0 * jxy, jxx - jyy)
    return np.mod(grad + 0.5 * np.pi, np.pi).astype(np.float32)


def main():
    img = np.load(sys.argv[1]).astype(np.float32)
    out, sigma, reps = sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
    cv2.setNumThreads(2)
    times = []
    theta = None
    for _ in range(reps):
        t = time.perf_counter()
        theta = field(img, sigma)
        times.append((time.perf_counter() - t) * 1e3)
    np.save(out, theta)
    print(json.dumps({"peer": "opencv structure tensor", "median_ms": float(np.median(times))}))


if __name__ == "__main__":
    main()
