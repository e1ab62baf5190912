#!/usr/bin/env bash
# Installs what coif's tests need on Debian/Ubuntu: a Vulkan driver (Mesa lavapipe, the
# software GPU the parity and golden tests run on) when none is present, numpy (the .npy
# interoperability test), usd-core (the .usda export test), ffmpeg (video decoding and the
# real clip) and opencv-python-headless (the OpenCV flow peers).
# Safe to run again; does nothing when all is there.
set -euo pipefail

as_root() {
  if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
    echo "setup: need root for: $*" >&2; return 1; fi
}

# Either folder may hold the driver manifests (ls of both fails when one is empty).
have_vulkan_icd() {
  compgen -G '/usr/share/vulkan/icd.d/*.json' >/dev/null ||
    compgen -G '/etc/vulkan/icd.d/*.json' >/dev/null
}

apt_updated=0
apt_install() {
  if [ "$apt_updated" = 0 ]; then
    as_root apt-get update -qq
    apt_updated=1
  fi
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null
}

if ! command -v cargo >/dev/null; then
  echo "setup: cargo not found; install Rust (https://rustup.rs) and run again" >&2
  exit 1
fi

# No grep -q: it stops reading early, and ldconfig's SIGPIPE fails the pipe under pipefail.
if ! have_vulkan_icd || ! ldconfig -p | grep 'libvulkan\.so\.1' >/dev/null; then
  echo "setup: installing Mesa's software Vulkan driver (lavapipe)"
  apt_install mesa-vulkan-drivers libvulkan1
fi

if ! python3 -c 'import numpy' >/dev/null 2>&1; then
  echo "setup: installing numpy"
  python3 -m pip install -q numpy 2>/dev/null || apt_install python3-numpy
fi

# The .usda export is checked by opening it with the real USD library.
if ! python3 -c 'from pxr import Usd, UsdGeom' >/dev/null 2>&1; then
  echo "setup: installing usd-core"
  python3 -m pip install -q usd-core 2>/dev/null ||
    python3 -m pip install -q --break-system-packages usd-core
fi

# Video input is decoded with the ffmpeg program (about 30 s to install, 93 packages).
if ! command -v ffmpeg >/dev/null || ! command -v ffprobe >/dev/null; then
  echo "setup: installing ffmpeg"
  apt_install ffmpeg
fi

# OpenCV's DIS and Farneback flow are the peers of coif's video flow (benches/peers). The
# pip wheel (headless: no GUI libraries) installs in seconds; Debian's python3-opencv pulls
# about 170 packages and only serves the system python.
if ! python3 -c 'import cv2; cv2.DISOpticalFlow_create' >/dev/null 2>&1; then
  echo "setup: installing opencv-python-headless"
  python3 -m pip install -q opencv-python-headless 2>/dev/null ||
    python3 -m pip install -q --break-system-packages opencv-python-headless
fi

# Real portraits with no stated licence, for tests/it/segment_real.rs (never committed).
"$(dirname "$0")/real_portraits.sh"
