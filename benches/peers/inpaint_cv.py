#!/usr/bin/env python3
"""Peer for benches/inpaint.rs: OpenCV's cv2.inpaint on the same 8-bit photo and hole.

cv2.inpaint is a different, diffusion-type family (Telea 2004: fast marching, each hole
pixel a gradient-weighted average of known neighbours within `radius`; NS: Navier-Stokes
transport of the image Laplacian). It fills smoothly and copies no texture, so it is a speed
reference, not a quality one. Reads DIR/photo.png (RGB) and DIR/hole.png (nonzero = hole);
writes DIR/telea.png; prints one JSON line with the median seconds of REPS runs.

usage: inpaint_cv.py DIR REPS
"""
import json
import statistics
import sys
import time

import cv2
import numpy as np


def main():
    d, reps = sys.argv[1], int(sys.argv[2])
    img = cv2.imread(f"{d}/photo.png", cv2.IMREAD_COLOR)
    hole = (cv2.imread(f"{d}/hole.png", cv2.IMREAD_GRAYSCALE) > 0).astype(np.uint8)
    out = {"opencv": cv2.__version__, "hole_px": int(hole.sum()), "radius": 3}
    for name, flag in (("telea", cv2.INPAINT_TELEA), ("ns", cv2.INPAINT_NS)):
        cv2.inpaint(img, hole, 3, flag)  # warm-up
        times = []
        for _ in range(reps):
            t = time.perf_counter()
            res = cv2.inpaint(img, hole, 3, flag)
            times.append(time.perf_counter() - t)
        out[f"{name}_s"] = statistics.median(times)
        if name == "telea":
            cv2.imwrite(f"{d}/telea.png", res)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
