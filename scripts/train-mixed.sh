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
# one core each).
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
cargo build --release -q -p gaitsweep-worker
export GAITSWEEP_ROBOTS="$PWD/robots"
jobs="${JOBS:-1}"
epochs="${EPOCHS:-1200}"
# A seed's last checkpoint, the one its evaluation reads.
final_ckpt() { echo "$out/seed-$1/ckpt-$(printf %06d "$epochs").safetensors"; }
train_one() {
  local seed="$1" dir="$out/seed-$1" last
  mkdir -p "$dir"
  last="$(ls "$dir"/ckpt-*.safetensors 2> /dev/null | sort | tail -n 1 || true)"
  if [ -n "$last" ] && [ "$last" = "$(final_ckpt "$seed")" ]; then
    echo "seed $seed: trained already ($last)" >&2
    return 0
  fi
  RAYON_NUM_THREADS=1 target/release/worker train --robot "$robot" --terrain mixed \
    --w1 "$w1" --w2 "$w2" --agents "${AGENTS:-1024}" --epochs "$epochs" --seed "$seed" \
    --out "$dir" --checkpoint-every 100 --eval-every 300 --eval-robots "${EVAL_ROBOTS:-256}" \
    --eval-seconds "${EVAL_SECONDS:-20}" \
    --threads 1 --quiet ${last:+--resume "$last"} >> "$dir/train.log" 2>&1
  echo "seed $seed: trained ($dir)" >&2
}
pids=()
for seed in "$@"; do
  train_one "$seed" &
  pids+=($!)
  if [ "${#pids[@]}" -ge "$jobs" ]; then wait "${pids[0]}"; pids=("${pids[@]:1}"); fi
done
for p in "${pids[@]}"; do wait "$p"; done
ckpts=()
for seed in "$@"; do
  ckpts+=("$(final_ckpt "$seed")")
done
JOBS="$jobs" ROBOTS="${EVAL_ROBOTS:-256}" scripts/eval-terrains.sh "$out/eval" "${ckpts[@]}"
