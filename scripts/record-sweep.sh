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
#
# A recording that moves between machines (README "Recording over several sittings"):
# GAITSWEEP_RECORD_SNAPSHOT=DIR (e.g. studies/recordings/anymal, committed between sittings)
# restores DATA_DIR from DIR when DATA_DIR has no database yet (and refuses a DATA_DIR that
# is behind DIR), and writes DIR back with
# `coordinator snapshot` every GAITSWEEP_RECORD_SNAPSHOT_MINUTES (default 15) and when the
# recording stops: the database and the checkpoints the next sitting resumes from.
set -euo pipefail
cd "$(dirname "$0")/.."
DATA="${1:?usage: scripts/record-sweep.sh DATA_DIR [SPEC]}"
SPEC="${2:-}"
source scripts/setup.sh
# The binaries find the robot presets here, not in the source tree they were built from: a
# shared CARGO_TARGET_DIR can hold binaries built from another clone, since deleted (session
# 35 lost a recording's queue that way).
export GAITSWEEP_ROBOTS="${GAITSWEEP_ROBOTS:-$PWD/robots}"
cargo build --release --workspace --bins
BIN="${CARGO_TARGET_DIR:-$PWD/target}/release"
mkdir -p "$DATA"
DATA="$(cd "$DATA" && pwd)"
SNAP="${GAITSWEEP_RECORD_SNAPSHOT:-}"
# Epochs trained over all cells of a database: how far a recording has come.
trained() {
  python3 -c 'import sqlite3, sys
db = sqlite3.connect(f"file:{sys.argv[1]}?mode=ro", uri=True)
print(db.execute("SELECT COALESCE(SUM(epochs_done), 0) FROM cells").fetchone()[0])' "$1"
}
if [ -n "$SNAP" ] && [ -e "$SNAP/gaitsweep.sqlite" ]; then
  if [ ! -e "$DATA/gaitsweep.sqlite" ]; then
    echo "restoring $DATA from the snapshot $SNAP"
    cp -r "$SNAP/." "$DATA/"
  elif [ "$(trained "$SNAP/gaitsweep.sqlite")" -gt "$(trained "$DATA/gaitsweep.sqlite")" ]; then
    # A data dir left on a machine that an earlier sitting used, behind what later
    # sittings elsewhere recorded: going on from it would overwrite their work.
    echo "the snapshot $SNAP is ahead of $DATA ($(trained "$SNAP/gaitsweep.sqlite") epochs trained against $(trained "$DATA/gaitsweep.sqlite")): move $DATA away and run again to restore from the snapshot" >&2
    exit 2
  fi
fi
fresh=0
[ -e "$DATA/gaitsweep.sqlite" ] || fresh=1
if [ "$fresh" = 1 ] && [ -z "$SPEC" ]; then
  echo "no sweep in $DATA yet: pass the spec to record as the second argument" >&2
  exit 2
fi
source scripts/procs.sh
if [ -n "$SNAP" ]; then
  stop_on_exit "stopping: commit $SNAP (written when the workers have stopped), then resume with GAITSWEEP_RECORD_SNAPSHOT=$SNAP scripts/record-sweep.sh $DATA"
else
  stop_on_exit "stopping: resume with scripts/record-sweep.sh $DATA"
fi
take_snapshot() {
  [ -n "$SNAP" ] && [ -s "$DATA/sweep.id" ] || return 0
  "$BIN/coordinator" snapshot --data-dir "$DATA" --out "$SNAP" && cp "$DATA/sweep.id" "$SNAP/sweep.id"
}
if [ -n "$SNAP" ]; then
  # After the workers have given their cells back with a checkpoint (cleanup stops them).
  trap 'cleanup; take_snapshot || echo "the final snapshot failed: run $BIN/coordinator snapshot --data-dir $DATA --out $SNAP" >&2' EXIT
fi

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
if [ -n "$SNAP" ]; then
  # A stop waits for a snapshot under way (the trap runs after it) but not for the sleep.
  # The TERM trap stops the sleep too, which would otherwise outlive the script.
  ( trap 'kill $! 2>/dev/null; exit 0' TERM
    while true; do
      sleep "$(( ${GAITSWEEP_RECORD_SNAPSHOT_MINUTES:-15} * 60 ))" & wait $!
      take_snapshot || true
    done ) &
  pids+=($!)
fi
"$BIN/coordinator" watch "$SWEEP" &
pids+=($!)
wait $!
"$BIN/coordinator" show "$SWEEP"
echo "done: $BIN/search-bench export --data-dir $DATA --sweep $SWEEP > RECORDING.json"
