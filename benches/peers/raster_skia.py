#!/usr/bin/env python3
"""Peer for benches/raster.rs: the same strands drawn by Skia (skia-python) as anti-aliased
path strokes, one path per strand with ONE colour per strand (the mean of its vertex
colours, sRGB-encoded; per-segment colours would need a Python call per segment, which
would time Python rather than Skia). Square caps and miter joins, like our quads extended by
half a width. Raster N32 premultiplied 8-bit surface, Skia's usual (non-linear) blending.

Inputs in DIR, raw little-endian: points.f32 (n x 3: x px, y px, depth), counts.u32,
colors.f32 (n x 4, linear straight RGBA). Prints one JSON line: path build time, draw
time (median of REPS), and the share of pixels drawn. With "serve" for REPS: prints a
"ready" JSON line once the paths are built, then draws once per "draw" line on stdin and
prints its seconds, until another line or the end of stdin; then the JSON line.

usage: raster_skia.py DIR WIDTH HEIGHT STROKE_WIDTH [REPS | serve]
"""
import json
import sys
import time

import numpy as np
import skia


def srgb(lin):
    lin = np.clip(lin, 0.0, 1.0)
    return np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)


def main():
    d, w, h, width = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
    reps = int(sys.argv[5]) if len(sys.argv) > 5 and sys.argv[5] != "serve" else 3
    serve = len(sys.argv) > 5 and sys.argv[5] == "serve"
    pts = np.fromfile(f"{d}/points.f32", dtype="<f4").reshape(-1, 3)
    counts = np.fromfile(f"{d}/counts.u32", dtype="<u4").astype(np.int64)
    cols = np.fromfile(f"{d}/colors.f32", dtype="<f4").reshape(-1, 4)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])

    t0 = time.perf_counter()
    items = []
    for s, n in zip(starts, counts):
        if n < 2:
            continue
        xy = pts[s:s + n, :2].tolist()
        path = skia.Path()
        path.addPoly([skia.Point(x, y) for x, y in xy], False)
        c = cols[s:s + n].mean(axis=0)
        rgb = srgb(c[:3])
        paint = skia.Paint(
            AntiAlias=True,
            Style=skia.Paint.kStroke_Style,
            StrokeWidth=width,
            StrokeCap=skia.Paint.kSquare_Cap,
            Color4f=skia.Color4f(float(rgb[0]), float(rgb[1]), float(rgb[2]),
                                 float(np.clip(c[3], 0.0, 1.0))),
        )
        items.append((path, paint))
    t1 = time.perf_counter()

    surface = skia.Surface(w, h)

    def draw():
        canvas = surface.getCanvas()
        t2 = time.perf_counter()
        canvas.clear(skia.ColorTRANSPARENT)
        for path, paint in items:
            canvas.drawPath(path, paint)
        surface.flushAndSubmit()
        return time.perf_counter() - t2

    if serve:
        # Driven by the bench: one draw per "draw" line, its seconds printed back, so that
        # its rounds interleave with ours (the machine's speed drifts over a run).
        print(json.dumps({"ready": True, "paths": len(items), "build_s": t1 - t0}), flush=True)
        for line in sys.stdin:
            if line.strip() != "draw":
                break
            print(draw(), flush=True)
        reps = 0
    times = sorted(draw() for _ in range(reps))
    arr = surface.toarray()
    drawn = float((arr[..., 3] > 0).mean())
    out = {
        "paths": len(items),
        "build_s": t1 - t0,
        "drawn_share": drawn,
        "skia_python": getattr(skia, "__version__", "?"),
    }
    if times:
        out.update(draw_s=times[len(times) // 2], draw_reps=reps)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
