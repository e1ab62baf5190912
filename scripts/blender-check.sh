#!/usr/bin/env bash
# Opens coif's .usda exports in Blender (headless) and checks the curve and point counts:
# a still model and a simulated (time-sampled) one, from a 128² synthetic portrait.
#
#   scripts/blender-check.sh            # prints Blender's counts beside coif's; exit 1 on a mismatch
#
# Debian's `blender` package (3.4) is built without USD (bpy.app.build_options.usd is False),
# so the check uses Blender's own Python module `bpy` from PyPI (4.5, with USD), in a venv
# under target/ (about 400 MB, installed once). BLENDER_PY names another Python that has bpy.
set -euo pipefail
cd "$(dirname "$0")/.."
tgt="${CARGO_TARGET_DIR:-target}"
py="${BLENDER_PY:-$tgt/venv-bpy/bin/python}"
if ! "$py" -c 'import bpy' 2>/dev/null; then
    python3 -m venv "$tgt/venv-bpy"
    "$tgt/venv-bpy/bin/pip" install -q "bpy==4.5.*"
    py="$tgt/venv-bpy/bin/python"
fi
cargo build --release --bin coif
coif="$tgt/release/coif"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$coif" synth --out "$work/case" --style long --size 128 --seed 1 >/dev/null
"$coif" model --image "$work/case/image.png" --strokes "$work/case/strokes.json" \
    --mask "$work/case/mask.png" --landmarks "$work/case/landmarks.json" \
    --out "$work/model" --backend cpu >/dev/null
"$coif" export --model "$work/model" --to "$work/hair.usda" >/dev/null
"$coif" simulate --model "$work/model" --out "$work/wind" --frames 6 --backend cpu >/dev/null
"$coif" export --model "$work/wind" --to "$work/wind.usda" >/dev/null

# coif's own counts, from the file's curveVertexCounts (first time sample for the animation).
counts() {
    python3 - "$1" <<'PY'
import re, sys
text = open(sys.argv[1]).read()
m = re.search(r"int\[\] curveVertexCounts(?:\.timeSamples)? = (?:\{\s*[-\d.]+: )?\[([^\]]*)\]", text)
v = [int(x) for x in m.group(1).split(",")]
print(len(v), sum(v))
PY
}
read -r c p < <(counts "$work/hair.usda")
"$py" scripts/blender_usda_check.py "$work/hair.usda" "$c" "$p"
read -r c p < <(counts "$work/wind.usda")
"$py" scripts/blender_usda_check.py "$work/wind.usda" "$c" "$p"
