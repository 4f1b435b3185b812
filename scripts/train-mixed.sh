#!/usr/bin/env bash
# Issue 39 item 6: one policy on legged_gym's mixed terrain, trained with the weights a
# recording of the paper's study promoted across its terrains (its `promotions` row with
# terrain '*', written when the sweep ends), then evaluated on each terrain at levels 0-5
# (scripts/eval-terrains.sh: walks where falls <= 10% and |v_cmd - v| <= 0.25 m/s).
#
#   scripts/train-mixed.sh DATA_DIR OUT_DIR SEED [SEED ...]
#
# DATA_DIR: the recording's data dir or its committed snapshot (read only). Each seed trains
# into OUT_DIR/seed-N with sessions 39-40's settings (the robot's preset, 1,024 robots x
# 1,200 epochs, Table 1's commands, evaluations every 300 epochs at levels 0/3/5/7), and a
# seed stopped part-way resumes from its latest checkpoint when the script runs again (a
# resumed run is not bit for bit the uninterrupted one). Environment: W1 and W2 (train
# these weights instead of the promoted ones), AGENTS (1024), EPOCHS (1200), EVAL_ROBOTS
# (256) and EVAL_SECONDS (20) for every evaluation, JOBS (seeds trained at once, default 1:
# one core each), CHECKPOINT_EVERY (50 epochs: what a stop loses at most).
#
# Training that moves between machines, as the recordings do (README "Recording over
# several sittings"): GAITSWEEP_MIXED_SNAPSHOT=DIR (e.g. studies/recordings/mixed-anymal,
# committed between sittings) restores each seed from DIR where DIR's checkpoint is later
# than OUT_DIR's, and writes DIR back every GAITSWEEP_MIXED_SNAPSHOT_MINUTES (default 15)
# and when the script stops or ends: each seed's logs, metrics and latest checkpoint, and
# the evaluations. Stop it at any time (Ctrl-C or SIGTERM).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -lt 3 ]; then
  echo "usage: scripts/train-mixed.sh DATA_DIR OUT_DIR SEED [SEED ...]" >&2
  exit 2
fi
data="$1"; out="$2"; shift 2
db="$data/gaitsweep.sqlite"
[ -f "$db" ] || { echo "no gaitsweep database at $db: pass a recording's data dir or snapshot dir" >&2; exit 2; }
read -r robot w1 w2 < <(python3 - "$db" "${W1:-}" "${W2:-}" <<'PY'
import sqlite3, sys
db = sqlite3.connect(f"file:{sys.argv[1]}?mode=ro", uri=True)
robot = db.execute("SELECT json_extract(spec_json, '$.robot') FROM sweeps ORDER BY id LIMIT 1").fetchone()
if robot is None:
    sys.exit(f"{sys.argv[1]} holds no sweep")
if sys.argv[2] and sys.argv[3]:
    print(robot[0], sys.argv[2], sys.argv[3])
    sys.exit()
row = db.execute(
    "SELECT c.w1, c.w2 FROM promotions p JOIN cells c ON c.id = p.cell_id "
    "WHERE p.terrain = '*' ORDER BY p.id DESC LIMIT 1").fetchone()
if row is None:
    sys.exit(f"{sys.argv[1]} has no promotion across terrains yet (it is written when a sweep "
             "over several terrains ends): let the recording finish, or set W1 and W2")
print(robot[0], repr(row[0]), repr(row[1]))
PY
)
echo "mixed terrain: robot $robot, w1 $w1, w2 $w2, seeds $*" >&2
source scripts/setup.sh > /dev/null
# The whole workspace, as the other scripts build it: one feature set, no rebuild between them.
cargo build --release -q --workspace --bins
export GAITSWEEP_ROBOTS="$PWD/robots"
jobs="${JOBS:-1}"
epochs="${EPOCHS:-1200}"
snap="${GAITSWEEP_MIXED_SNAPSHOT:-}"
seeds=("$@")
# A dir's latest checkpoint (empty: none) and its epoch (0: none).
latest_ckpt() { ls "$1"/ckpt-*.safetensors 2> /dev/null | sort | tail -n 1 || true; }
ckpt_epoch() {
  local f
  f="$(latest_ckpt "$1")"
  [ -n "$f" ] || { echo 0; return; }
  f="${f##*/ckpt-}"
  echo $((10#${f%.safetensors}))
}
# A seed's last checkpoint, the one its evaluation reads.
final_ckpt() { echo "$out/seed-$1/ckpt-$(printf %06d "$epochs").safetensors"; }
mkdir -p "$out"
if [ -n "$snap" ]; then
  for seed in "${seeds[@]}"; do
    s="$snap/seed-$seed" d="$out/seed-$seed"
    if [ -d "$s" ] && [ "$(ckpt_epoch "$s")" -gt "$(ckpt_epoch "$d")" ]; then
      echo "seed $seed: restoring $d from the snapshot $s (epoch $(ckpt_epoch "$s"))" >&2
      rm -rf "$d"
      cp -r "$s" "$d"
    fi
  done
  if [ -d "$snap/eval" ] && [ ! -d "$out/eval" ]; then cp -r "$snap/eval" "$out/eval"; fi
fi
# Copies each seed's files and latest checkpoint (written atomically by the trainer) to the
# snapshot, never over a later one, each seed swapped in whole.
take_snapshot() {
  [ -n "$snap" ] || return 0
  local seed s d last tmp
  mkdir -p "$snap"
  for seed in "${seeds[@]}"; do
    d="$out/seed-$seed" s="$snap/seed-$seed"
    last="$(latest_ckpt "$d")"
    [ -n "$last" ] && [ "$(ckpt_epoch "$d")" -ge "$(ckpt_epoch "$s")" ] || continue
    tmp="$snap/.seed-$seed.tmp"
    rm -rf "$tmp"
    mkdir -p "$tmp"
    find "$d" -maxdepth 1 -type f ! -name 'ckpt-*' ! -name '*.tmp' -exec cp {} "$tmp/" \;
    cp "$last" "${last%.safetensors}.json" "$tmp/"
    rm -rf "$s"
    mv "$tmp" "$s"
  done
  if [ -d "$out/eval" ]; then
    rm -rf "$snap/eval"
    cp -r "$out/eval" "$snap/eval"
  fi
  echo "snapshot of $out in $snap ($(date -u +%FT%TZ))" >&2
}
running=() names=() snap_loop="" eval_pid=""
# On Ctrl-C or SIGTERM the trainers stop where they are (they resume from their latest
# checkpoint), then the snapshot is written.
stop() {
  trap - INT TERM
  echo "stopping: ${#running[@]} trainers ($(date -u +%T))${snap:+; commit $snap, then resume with GAITSWEEP_MIXED_SNAPSHOT=$snap scripts/train-mixed.sh $data $out ${seeds[*]}}" >&2
  for p in "${running[@]}" $snap_loop; do kill "$p" 2> /dev/null || true; done
  # The evaluations run in their own process group: stop their `worker eval`s too.
  [ -z "$eval_pid" ] || kill -- "-$eval_pid" 2> /dev/null || true
  wait 2> /dev/null || true
  take_snapshot
  exit 130
}
trap stop INT TERM
trap '[ -z "$snap_loop" ] || kill "$snap_loop" 2> /dev/null || true' EXIT
if [ -n "$snap" ]; then
  # The TERM trap stops the sleep too, which would otherwise outlive the script.
  ( trap 'kill $! 2>/dev/null; exit 0' TERM
    while true; do
      sleep "$(( ${GAITSWEEP_MIXED_SNAPSHOT_MINUTES:-15} * 60 ))" & wait $!
      take_snapshot || true
    done ) &
  snap_loop=$!
fi
# Starts a seed's training in the background (its pid joins `running`), resuming from its
# latest checkpoint; does nothing for a seed trained already.
start_one() {
  local seed="$1" dir="$out/seed-$1" last
  mkdir -p "$dir"
  last="$(latest_ckpt "$dir")"
  if [ -n "$last" ] && [ "$last" = "$(final_ckpt "$seed")" ]; then
    echo "seed $seed: trained already ($last)" >&2
    return 0
  fi
  echo "seed $seed: training in $dir${last:+ from $last} (log: $dir/train.log)" >&2
  RAYON_NUM_THREADS=1 target/release/worker train --robot "$robot" --terrain mixed \
    --w1 "$w1" --w2 "$w2" --agents "${AGENTS:-1024}" --epochs "$epochs" --seed "$seed" \
    --out "$dir" --checkpoint-every "${CHECKPOINT_EVERY:-50}" --eval-every 300 \
    --eval-robots "${EVAL_ROBOTS:-256}" --eval-seconds "${EVAL_SECONDS:-20}" \
    --threads 1 --quiet ${last:+--resume "$last"} >> "$dir/train.log" 2>&1 &
  running+=($!)
  names+=("$seed")
}
# Waits for the oldest trainer; a failed one stops the script (its log says why).
wait_oldest() {
  local rc=0
  wait "${running[0]}" || rc=$?
  if [ "$rc" != 0 ]; then
    echo "seed ${names[0]}: training failed (exit $rc); see $out/seed-${names[0]}/train.log" >&2
    exit "$rc"
  fi
  echo "seed ${names[0]}: trained ($out/seed-${names[0]})" >&2
  running=("${running[@]:1}") names=("${names[@]:1}")
}
for seed in "${seeds[@]}"; do
  start_one "$seed"
  if [ "${#running[@]}" -ge "$jobs" ]; then wait_oldest; fi
done
while [ "${#running[@]}" -gt 0 ]; do wait_oldest; done
take_snapshot
ckpts=()
for seed in "${seeds[@]}"; do
  ckpts+=("$(final_ckpt "$seed")")
done
# In the background, so that a stop is handled at once rather than after the evaluations.
JOBS="$jobs" ROBOTS="${EVAL_ROBOTS:-256}" setsid scripts/eval-terrains.sh "$out/eval" "${ckpts[@]}" &
eval_pid=$!
wait "$eval_pid"
eval_pid=""
take_snapshot
