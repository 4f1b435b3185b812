#!/usr/bin/env bash
# The README's test command: installs what it needs (libtorch into ~/.cache/gaitsweep),
# builds every binary (the end-to-end tests run the real coordinator and worker
# processes) and runs every test of the workspace in release mode.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
cargo build --release --workspace --bins
cargo test --release --workspace --no-fail-fast "$@"
