#!/usr/bin/env bash
# The README's main command: a small sweep end to end on localhost. Starts a coordinator
# (embedded SQLite in a fresh data dir), a worker, runs scripts/demo-sweep.toml,
# prints the score grid and the promoted cell, writes the report, and shuts everything
# down, on success and on Ctrl-C.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
# The binaries find the robot presets here, not in the source tree they were built from: a
# shared CARGO_TARGET_DIR can hold binaries built from another clone, since deleted (session
# 35 lost a recording's queue that way).
export GAITSWEEP_ROBOTS="${GAITSWEEP_ROBOTS:-$PWD/robots}"
cargo build --release --workspace --bins

SPEC="${1:-scripts/demo-sweep.toml}"
OUT="${GAITSWEEP_DEMO_OUT:-$PWD/demo-output}"
rm -rf "$OUT"
mkdir -p "$OUT/data"
BIN="${CARGO_TARGET_DIR:-$PWD/target}/release"
source scripts/procs.sh
stop_on_exit "interrupted: stopping coordinator and workers"

"$BIN/coordinator" serve --listen 127.0.0.1:0 --http 127.0.0.1:0 --data-dir "$OUT/data" > "$OUT/coordinator.log" 2>&1 &
pids+=($!)
wait_for_file "$OUT/data/coordinator.addr" || { echo "coordinator did not start; see $OUT/coordinator.log" >&2; exit 1; }
URL="http://$(cat "$OUT/data/coordinator.addr")"
export GAITSWEEP_URL="$URL"
echo "coordinator on $URL, data in $OUT/data"
wait_for_file "$OUT/data/http.addr" || true
echo "live page: http://$(cat "$OUT/data/http.addr")/ (open it in a browser to watch the sweep)"

# One worker with every core by default: successive halving leaves one cell training at
# the end, which a worker of one core would train on half the machine. With
# GAITSWEEP_DEMO_WORKERS=N each of the N workers gets nproc / N simulation threads.
WORKERS="${GAITSWEEP_DEMO_WORKERS:-1}"
threads=()
if [ "$WORKERS" -gt 1 ]; then
  per=$(( $(nproc) / WORKERS ))
  threads=(--threads "$(( per > 0 ? per : 1 ))")
fi
for i in $(seq 1 "$WORKERS"); do
  "$BIN/worker" --connect "$URL" --slots 1 "${threads[@]}" --work-dir "$OUT/work-$i" > "$OUT/worker-$i.log" 2>&1 &
  pids+=($!)
done
echo "started $WORKERS workers (logs in $OUT)"

created=$("$BIN/coordinator" create "$SPEC")
echo "$created"
SWEEP=$(echo "$created" | sed -n 's/^created sweep \([0-9]*\).*/\1/p')
start=$(date +%s)
# In the background and waited for, so that Ctrl-C or SIGTERM runs the trap at once.
"$BIN/coordinator" watch "$SWEEP" &
pids+=($!)
wait $!
echo "sweep finished in $(( $(date +%s) - start )) s"
"$BIN/coordinator" show "$SWEEP" | tee "$OUT/grid.txt"
"$BIN/coordinator" fetch-best "$SWEEP" --out "$OUT/best.safetensors"
if "$BIN/coordinator" report --help > /dev/null 2>&1; then
  "$BIN/coordinator" report "$SWEEP" --data-dir "$OUT/data" --out "$OUT/report"
  echo "report: $OUT/report/index.html"
fi
echo "best model: $OUT/best.safetensors"
