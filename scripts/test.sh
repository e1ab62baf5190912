#!/usr/bin/env bash
# Sets up (lavapipe, numpy) and runs every test. This is what CI runs.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
# Headless Vulkan loaders complain about this variable; a valid one keeps logs clean.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
cargo fmt --check
cargo clippy --release --all-targets -- -D warnings
cargo test --release
