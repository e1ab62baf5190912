#!/usr/bin/env bash
# Peak memory of `coif orient --backend cpu` on a large image (issue 18: an 8000² PNG took
# 22.9 GB before the cpu backend tiled it). Generates the image (never committed), runs
# orient under /usr/bin/time -v and prints the peak RSS beside coif's own estimate.
#   scripts/memory-peak.sh [SIDE]      # default 8000; needs python3 with numpy and Pillow
set -euo pipefail
side=${1:-8000}
root=$(cd "$(dirname "$0")/.." && pwd)
cargo build --release --bin coif --manifest-path "$root/Cargo.toml" >&2
coif="${CARGO_TARGET_DIR:-$root/target}/release/coif"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 - "$side" "$work/big.png" <<'PY'
import sys
import numpy as np
from PIL import Image
n = int(sys.argv[1])
y, x = np.mgrid[0:n, 0:n].astype(np.float32)
# Strand-like stripes whose direction turns across the image, plus noise.
a = 0.6 * np.sin(x / 900.0) + 0.4 * np.cos(y / 700.0)
v = 0.5 + 0.35 * np.sin((x * np.cos(a) + y * np.sin(a)) * 1.3)
v += np.random.default_rng(1).normal(0, 0.05, (n, n)).astype(np.float32)
g = (np.clip(v, 0, 1) * 255).astype(np.uint8)
Image.fromarray(np.dstack([g, g, g])).save(sys.argv[2])
PY
# A budget of 1 byte: the refusal states the estimate without running.
"$coif" --max-memory 1 orient --image "$work/big.png" --out "$work/refused" --backend cpu 2>&1 |
    sed 's/^/estimate: /' || true
/usr/bin/time -v "$coif" -v orient --image "$work/big.png" --out "$work/out" --backend cpu \
    2>"$work/time.txt"
grep -E "tiles|Maximum resident|Elapsed" "$work/time.txt"
