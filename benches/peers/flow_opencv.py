#!/usr/bin/env python3
"""Peer for coif's video flow: OpenCV's DIS (MEDIUM preset) and Farneback optical flow
between consecutive frames, on grey levels, with end-point error against ground truth.

Flow convention (as coif's V_i): the flow of pair (i-1, i) is defined on frame i-1's pixels,
I_{i-1}(q) ~ I_i(q + V(q)), in pixels, x right, y down; arrays are H x W x 2 float32
(channel 0 = x, 1 = y), NaN where unknown (off hair in the synthetic clips).

Inputs, either:
  CLIP_DIR         a folder with frames/NNNN.png (consecutive numbers) and, optionally,
                   flow/NNNN.npy: the true flow from frame NNNN-1 to frame NNNN
  A.png B.png      one pair, with --gt FLOW.npy for its true flow

Prints one JSON line per pair: for each method its mean end-point error on the pixels where
the truth is finite ("epe", null without truth), the number of those pixels and the
milliseconds of one flow computation (median of --reps runs, after one untimed warm-up
run; the flow object is made once, outside the timing). A last line {"summary": ...} has the means over pairs.

--write DIR saves each method's flow as DIR/<method>/NNNN.npy (H x W x 2 float32, C order,
named like the truth: by the number of the pair's second frame), which coif's
io::npy::read_f32 reads.

--make-shift DIR DX DY writes a test clip instead: smooth noise and the same noise moved
by (DX, DY) px (bilinear, so any fraction), frames/0000.png, 0001.png and the true flow
flow/0001.npy, NaN where the moved image reads outside the first.

usage: flow_opencv.py CLIP_DIR [--write DIR] [--reps N] [--threads N]
       flow_opencv.py A.png B.png [--gt FLOW.npy] [--write DIR] [--reps N] [--threads N]
       flow_opencv.py --make-shift DIR DX DY [--size W H] [--seed S]
"""
import argparse
import json
import os
import re
import sys
import time

import cv2
import numpy as np

# OpenCV's own Farneback sample values (samples/python/opt_flow.py).
FARNEBACK = dict(pyr_scale=0.5, levels=3, winsize=15, iterations=3, poly_n=5, poly_sigma=1.2, flags=0)


def fail(msg):
    print(f"flow_opencv: {msg}", file=sys.stderr)
    sys.exit(2)


def read_gray(path):
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        fail(f"{path}: cannot read the image")
    if img.dtype != np.uint8:
        img = (img.astype(np.float32) * (255.0 / np.iinfo(img.dtype).max)).round().astype(np.uint8)
    if img.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        img = cv2.cvtColor(img, code)
    return img


def read_flow(path, shape):
    try:
        f = np.load(path)
    except Exception as e:  # noqa: BLE001 - any load failure is reported with the file
        fail(f"{path}: cannot read the flow: {e}")
    if f.shape != (shape[0], shape[1], 2):
        fail(f"{path}: flow has shape {f.shape}, expected {(shape[0], shape[1], 2)} for the frames")
    return f.astype(np.float32)


def epe(est, gt):
    if gt is None:
        return None, 0
    ok = np.isfinite(gt).all(axis=2)
    n = int(ok.sum())
    if n == 0:
        return None, 0
    d = est[ok] - gt[ok]
    return float(np.sqrt((d * d).sum(axis=1)).mean()), n


def methods():
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    return {
        "dis_medium": lambda a, b: dis.calc(a, b, None),
        "farneback": lambda a, b: cv2.calcOpticalFlowFarneback(a, b, None, **FARNEBACK),
    }


def timed(fn, a, b, reps):
    ts, out = [], None
    for _ in range(max(1, reps)):
        t = time.perf_counter()
        out = fn(a, b)
        ts.append((time.perf_counter() - t) * 1e3)
    return out, float(np.median(ts))


def numbered(folder, ext):
    """{number: path} for the files NNNN.ext in folder (the last digit run of the stem)."""
    out = {}
    if not os.path.isdir(folder):
        return out
    for name in os.listdir(folder):
        stem, e = os.path.splitext(name)
        m = re.search(r"(\d+)(?!.*\d)", stem)
        if e.lower() in ext and m and not name.startswith("."):
            k = int(m.group(1))
            if k in out:
                fail(f"{folder}: frame number {k} appears twice ({os.path.basename(out[k])}, {name})")
            out[k] = os.path.join(folder, name)
    return out


def clip_pairs(clip):
    frames_dir = os.path.join(clip, "frames")
    frames = numbered(frames_dir, (".png", ".jpg", ".jpeg"))
    if len(frames) < 2:
        fail(f"{frames_dir}: needs at least two numbered frames (NNNN.png)")
    ks = sorted(frames)
    for a, b in zip(ks, ks[1:]):
        if b != a + 1:
            fail(f"{frames_dir}: frame {a + 1} is missing (numbering jumps from {a} to {b})")
    flows = numbered(os.path.join(clip, "flow"), (".npy",))
    return [(frames[a], frames[b], flows.get(b), b) for a, b in zip(ks, ks[1:])]


def make_shift(out, dx, dy, w, h, seed):
    rng = np.random.default_rng(seed)
    # Smooth noise: texture at several scales, as a flow method needs.
    base = rng.random((h, w)).astype(np.float32)
    img = sum(cv2.GaussianBlur(base, (0, 0), s, borderType=cv2.BORDER_REFLECT) * wgt
              for s, wgt in ((1.0, 0.5), (2.5, 1.0), (6.0, 1.5)))
    img = (img - img.min()) / (img.max() - img.min())
    a = (img * 255).round().astype(np.uint8)
    # b(p) = a(p - d), so a(q) = b(q + d): the flow from a to b is d everywhere.
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    b = cv2.remap(img, xs - dx, ys - dy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    b = (b * 255).round().astype(np.uint8)
    flow = np.empty((h, w, 2), np.float32)
    flow[..., 0], flow[..., 1] = dx, dy
    # Where q + d falls outside b the motion cannot be seen: truth unknown.
    tx, ty = xs + dx, ys + dy
    inside = (tx >= 0) & (tx <= w - 1) & (ty >= 0) & (ty <= h - 1)
    flow[~inside] = np.nan
    os.makedirs(os.path.join(out, "frames"), exist_ok=True)
    os.makedirs(os.path.join(out, "flow"), exist_ok=True)
    cv2.imwrite(os.path.join(out, "frames", "0000.png"), a)
    cv2.imwrite(os.path.join(out, "frames", "0001.png"), b)
    np.save(os.path.join(out, "flow", "0001.npy"), flow)
    print(json.dumps({"made": out, "size": [w, h], "shift": [dx, dy], "known_pixels": int(inside.sum())}))


def save_flow(path, f):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = path + ".part.npy"
    np.save(tmp, np.ascontiguousarray(f, dtype=np.float32))
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("inputs", nargs="*")
    ap.add_argument("--gt")
    ap.add_argument("--write")
    ap.add_argument("--reps", type=int, default=1)
    ap.add_argument("--threads", type=int)
    ap.add_argument("--make-shift", nargs=3, metavar=("DIR", "DX", "DY"))
    ap.add_argument("--size", nargs=2, type=int, default=(64, 48), metavar=("W", "H"))
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()

    if args.make_shift:
        d, dx, dy = args.make_shift
        make_shift(d, float(dx), float(dy), args.size[0], args.size[1], args.seed)
        return
    if args.threads is not None:
        cv2.setNumThreads(args.threads)
    if len(args.inputs) == 1 and os.path.isdir(args.inputs[0]):
        if args.gt:
            fail("--gt is for a pair; a clip folder has its truth in flow/")
        pairs = clip_pairs(args.inputs[0])
    elif len(args.inputs) == 2:
        m = re.search(r"(\d+)(?!.*\d)", os.path.basename(os.path.splitext(args.inputs[1])[0]))
        pairs = [(args.inputs[0], args.inputs[1], args.gt, int(m.group(1)) if m else 1)]
    else:
        ap.print_usage(sys.stderr)
        fail("give a clip folder or two frames")

    ms = methods()
    # One untimed run each first: the first call pays for allocations and thread start-up.
    a0 = read_gray(pairs[0][0])
    for fn in ms.values():
        fn(a0, a0)
    totals = {name: {"epe": [], "ms": []} for name in ms}
    prev_path, prev = None, None
    for pa, pb, gt_path, k in pairs:
        a = prev if pa == prev_path else read_gray(pa)
        b = read_gray(pb)
        if a.shape != b.shape:
            fail(f"{pb}: frame is {b.shape[1]}x{b.shape[0]} px but {pa} is {a.shape[1]}x{a.shape[0]} px")
        gt = read_flow(gt_path, a.shape) if gt_path else None
        row = {"pair": [os.path.basename(pa), os.path.basename(pb)]}
        for name, fn in ms.items():
            f, t = timed(fn, a, b, args.reps)
            e, n = epe(f, gt)
            row[name] = {"epe": e, "pixels": n, "ms": round(t, 3)}
            totals[name]["ms"].append(t)
            if e is not None:
                totals[name]["epe"].append(e)
            if args.write:
                save_flow(os.path.join(args.write, name, f"{k:04d}.npy"), f)
        print(json.dumps(row))
        prev_path, prev = pb, b
    summary = {
        name: {
            "mean_epe": float(np.mean(t["epe"])) if t["epe"] else None,
            "pairs_with_truth": len(t["epe"]),
            "mean_ms": float(np.mean(t["ms"])),
        }
        for name, t in totals.items()
    }
    summary["pairs"] = len(pairs)
    summary["size"] = [int(prev.shape[1]), int(prev.shape[0])]
    summary["opencv"] = cv2.__version__
    summary["threads"] = cv2.getNumThreads()
    summary["farneback_params"] = FARNEBACK
    print(json.dumps({"summary": summary}))


if __name__ == "__main__":
    main()
