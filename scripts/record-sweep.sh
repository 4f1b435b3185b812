#!/usr/bin/env bash
# Records a sweep too long for one sitting (issue 10's search-bench recordings): the first
# run creates the sweep from SPEC in DATA_DIR; every later run with the same DATA_DIR
# restarts the coordinator on that database and the workers pick up where the last run
# stopped (each cell resumes from its latest checkpoint). Stop it at any time (Ctrl-C or
# SIGTERM); nothing scored is lost. When the sweep is done it prints the export command.
#
#   scripts/record-sweep.sh DATA_DIR SPEC     # first run
#   scripts/record-sweep.sh DATA_DIR          # resume
#
# GAITSWEEP_RECORD_WORKERS=N (default 2) one-core workers with one slot each, at nice
# GAITSWEEP_RECORD_NICE (default 5), so that other work on the machine goes first.
set -euo pipefail
cd "$(dirname "$0")/.."
DATA="${1:?usage: scripts/record-sweep.sh DATA_DIR [SPEC]}"
SPEC="${2:-}"
source scripts/setup.sh
cargo build --release --workspace --bins
BIN="${CARGO_TARGET_DIR:-$PWD/target}/release"
mkdir -p "$DATA"
DATA="$(cd "$DATA" && pwd)"
fresh=0
[ -e "$DATA/gaitsweep.sqlite" ] || fresh=1
if [ "$fresh" = 1 ] && [ -z "$SPEC" ]; then
  echo "no sweep in $DATA yet: pass the spec to record as the second argument" >&2
  exit 2
fi
source scripts/procs.sh
stop_on_exit "stopping: resume with scripts/record-sweep.sh $DATA"

rm -f "$DATA/coordinator.addr"
# Every restart expires the leases it interrupted, which counts as an attempt: a recording
# spread over many sittings must not fail its cells for that.
"$BIN/coordinator" serve --listen 127.0.0.1:0 --data-dir "$DATA" --max-attempts 1000 >> "$DATA/coordinator.log" 2>&1 &
pids+=($!)
wait_for_file "$DATA/coordinator.addr" || { echo "coordinator did not start; see $DATA/coordinator.log" >&2; exit 1; }
export GAITSWEEP_URL="http://$(cat "$DATA/coordinator.addr")"
WORKERS="${GAITSWEEP_RECORD_WORKERS:-2}"
for i in $(seq 1 "$WORKERS"); do
  nice -n "${GAITSWEEP_RECORD_NICE:-5}" "$BIN/worker" --connect "$GAITSWEEP_URL" --slots 1 --threads 1 --work-dir "$DATA/work-$i" >> "$DATA/worker-$i.log" 2>&1 &
  pids+=($!)
done
if [ "$fresh" = 1 ]; then
  "$BIN/coordinator" create "$SPEC" | tee /dev/stderr | sed -n 's/^created sweep \([0-9]*\).*/\1/p' > "$DATA/sweep.id"
fi
SWEEP=$(cat "$DATA/sweep.id")
echo "recording sweep $SWEEP in $DATA with $WORKERS workers ($(date -u +%FT%TZ))"
"$BIN/coordinator" watch "$SWEEP" &
pids+=($!)
wait $!
"$BIN/coordinator" show "$SWEEP"
echo "done: $BIN/search-bench export --data-dir $DATA --sweep $SWEEP > RECORDING.json"
