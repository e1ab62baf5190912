#!/usr/bin/env bash
# Sets up (lavapipe, numpy) and runs every test. This is what CI runs.
set -euo pipefail
cd "$(dirname "$0")/.."
# Each phase's wall time goes to stderr, so a slow CI run shows where its minutes went.
phase() { echo "test.sh: $1 took $((SECONDS - t0)) s" >&2; t0=$SECONDS; }
t0=$SECONDS
./scripts/setup.sh
phase setup
# Headless Vulkan loaders complain about this variable; a valid one keeps logs clean.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
cargo fmt --check
cargo clippy --release --all-targets -- -D warnings
phase "fmt and clippy"
cargo test --release
phase "cargo test (build and run)"
