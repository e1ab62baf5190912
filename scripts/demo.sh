#!/usr/bin/env bash
# Builds coif and runs the main job on the embedded inputs (no GPU needed: `auto` picks the
# CPU backend when there is no hardware GPU). Outputs land in out/demo.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v cargo >/dev/null; then
  echo "demo: cargo not found; install Rust (https://rustup.rs) and run again" >&2
  exit 1
fi
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
cargo run --release --quiet -- demo "$@"
