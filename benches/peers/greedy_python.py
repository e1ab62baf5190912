#!/usr/bin/env python3
"""Peer for benches/resolve.rs: C13's greedy direction resolution (Eq. 1-2) in plain Python
(max-heap with lazy updates, curve neighbours from a grid of bounding boxes), on the same
curves and strokes. Prints one JSON line.

usage: greedy_python.py CASE.json REPS
CASE.json: {"curves": [[[x,y],...],...], "strokes": [[[x,y],...],...], "radius": r, "stroke_weight": w}
"""
import heapq
import json
import math
import sys
import time

import numpy as np


def tangents(pts):
    n = len(pts)
    out = []
    for j in range(n):
        a = pts[max(j - 1, 0)]
        b = pts[min(j + 1, n - 1)]
        dx, dy = b[0] - a[0], b[1] - a[1]
        m = math.hypot(dx, dy) or 1.0
        out.append((dx / m, dy / m))
    return out


def pair_sum(pa, ta, pb, tb, r2):
    """Sum of t_a . t_b over vertex pairs within the radius (numpy, all pairs at once)."""
    d2 = ((pa[:, None, :] - pb[None, :, :]) ** 2).sum(-1)
    return float((ta @ tb.T)[d2 <= r2].sum())


def bbox(pts, pad):
    xs = [p[0] for p in pts]
    ys = [p[1] for p in pts]
    return (min(xs) - pad, min(ys) - pad, max(xs) + pad, max(ys) + pad)


def overlap(a, b):
    return a[0] <= b[2] and b[0] <= a[2] and a[1] <= b[3] and b[1] <= a[3]


def resolve(curves, strokes, radius, weight):
    r2 = radius * radius
    tans = [np.array(tangents(c)) for c in curves]
    boxes = [bbox(c, radius) for c in curves]
    curves = [np.array(c, dtype=np.float64) for c in curves]
    # Curve neighbours through a grid of boxes, as a spatial index.
    cell = 2 * radius
    grid = {}
    for i, b in enumerate(boxes):
        for gx in range(int(b[0] // cell), int(b[2] // cell) + 1):
            for gy in range(int(b[1] // cell), int(b[3] // cell) + 1):
                grid.setdefault((gx, gy), []).append(i)
    neighbours = [set() for _ in curves]
    for ids in grid.values():
        for a in ids:
            for b in ids:
                if a != b and overlap(boxes[a], boxes[b]):
                    neighbours[a].add(b)
    score = [0.0] * len(curves)
    for s in strokes:
        ts = np.array(tangents(s))
        sb = bbox(s, radius)
        s = np.array(s, dtype=np.float64)
        for i, c in enumerate(curves):
            if overlap(sb, boxes[i]):
                score[i] += weight * pair_sum(c, tans[i], s, ts, r2)
    resolved = [False] * len(curves)
    version = [0] * len(curves)
    heap = [(-abs(p), 0, i) for i, p in enumerate(score) if p != 0.0]
    heapq.heapify(heap)
    order = []
    while heap:
        _, ver, i = heapq.heappop(heap)
        if resolved[i] or ver != version[i]:
            continue
        resolved[i] = True
        sign = 1.0 if score[i] >= 0 else -1.0
        order.append(i)
        for j in neighbours[i]:
            if resolved[j]:
                continue
            d = sign * pair_sum(curves[j], tans[j], curves[i], tans[i], r2)
            if d != 0.0:
                score[j] += d
                version[j] += 1
                heapq.heappush(heap, (-abs(score[j]), version[j], j))
    return order


def main():
    case = json.load(open(sys.argv[1]))
    reps = int(sys.argv[2])
    ts = []
    for _ in range(reps):
        t = time.perf_counter()
        resolve(case["curves"], case["strokes"], case["radius"], case["stroke_weight"])
        ts.append((time.perf_counter() - t) * 1e3)
    ts.sort()
    print(json.dumps({"python": sys.version.split()[0], "ms": ts[len(ts) // 2]}))


if __name__ == "__main__":
    main()
