#!/usr/bin/env bash
# The README's test command: installs what it needs (libtorch into ~/.cache/gaitsweep),
# builds every binary (the end-to-end tests run the real coordinator and worker
# processes) and runs every test of the workspace in release mode.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
# The live page's end-to-end test renders it in headless Chromium (Debian's package).
if ! command -v chromium > /dev/null 2>&1; then
  echo "installing Debian's chromium for the live-page browser test (apt-get install chromium)"
  if [ "$(id -u)" = 0 ]; then
    apt-get update -qq && apt-get install -y -qq chromium > /dev/null
  else
    sudo apt-get update -qq && sudo apt-get install -y -qq chromium > /dev/null
  fi
fi
# The store's conformance suite and the end-to-end test on PostgreSQL run against a
# throwaway cluster (Debian's postgresql package), stopped and removed at the end.
# Under /tmp: the server runs as the `postgres` user, who must reach the directory.
PG_DIR="$(mktemp -d /tmp/gaitsweep-pg.XXXXXX)"
stop_pg() { scripts/pg-cluster.sh stop "$PG_DIR" || true; rm -rf "$PG_DIR"; }
trap stop_pg EXIT
GAITSWEEP_TEST_PG="$(scripts/pg-cluster.sh start "$PG_DIR")"
export GAITSWEEP_TEST_PG
echo "PostgreSQL for the tests: $GAITSWEEP_TEST_PG"
cargo build --release --workspace --bins
cargo test --release --workspace --no-fail-fast "$@"
