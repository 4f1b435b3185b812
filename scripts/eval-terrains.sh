#!/usr/bin/env bash
# Evaluates checkpoints on each terrain of the paper's study (issue 39 item 6: one policy
# trained on the mixed terrain must walk on each): `worker eval` with 256 robots x 20 s at
# levels 0-5 on rough, stairs and slopes, then one table of score, falls and |v_cmd - v|
# per checkpoint, terrain and level, with the verdict "walks" where falls <= 10% and
# |v_cmd - v| <= 0.25 m/s at every level.
#
#   scripts/eval-terrains.sh OUT_DIR CKPT.safetensors [CKPT.safetensors ...]
#
# Environment: TERRAINS (default "rough stairs slopes"), LEVELS (default 0,1,2,3,4,5),
# ROBOTS (256), EVAL_SECONDS (20), JOBS (parallel evaluations, default: the number of cores).
# Each evaluation's JSON stays in OUT_DIR; rerunning skips those already there.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -lt 2 ]; then
  echo "usage: scripts/eval-terrains.sh OUT_DIR CKPT.safetensors [CKPT.safetensors ...]" >&2
  exit 2
fi
out="$1"; shift
source scripts/setup.sh > /dev/null
# The whole workspace, as the other scripts build it: one feature set, no rebuild between them.
cargo build --release -q --workspace --bins
mkdir -p "$out"
terrains="${TERRAINS:-rough stairs slopes}"
levels="${LEVELS:-0,1,2,3,4,5}"
jobs="${JOBS:-$(nproc)}"
for ckpt in "$@"; do
  [ -f "$ckpt" ] || { echo "no checkpoint at $ckpt" >&2; exit 2; }
done
run_one() {
  local ckpt="$1" terrain="$2" file="$3"
  [ -s "$file" ] && return 0
  RAYON_NUM_THREADS=1 target/release/worker eval --checkpoint "$ckpt" --terrain "$terrain" \
    --levels "$levels" --robots "${ROBOTS:-256}" --seconds "${EVAL_SECONDS:-20}" \
    > "$file.tmp" && mv "$file.tmp" "$file"
  echo "evaluated $ckpt on $terrain" >&2
}
pids=()
for ckpt in "$@"; do
  name="$(basename "$(dirname "$ckpt")")-$(basename "$ckpt" .safetensors)"
  for terrain in $terrains; do
    run_one "$ckpt" "$terrain" "$out/$name-$terrain.json" &
    pids+=($!)
    if [ "${#pids[@]}" -ge "$jobs" ]; then wait "${pids[0]}"; pids=("${pids[@]:1}"); fi
  done
done
for p in "${pids[@]}"; do wait "$p"; done
python3 - "$out" <<'PY'
import json, pathlib, sys
rows = []
for f in sorted(pathlib.Path(sys.argv[1]).glob("*.json")):
    d = json.loads(f.read_text())
    name, terrain = f.stem.rsplit("-", 1)
    levels = d.get("levels", [])
    walks = all(l["score"]["fall_rate"] <= 0.10 and l["score"]["mean_vel_error"] <= 0.25 for l in levels)
    cells = " / ".join(f'{l["level"]}: {l["score"]["score"]:.2f}, {100 * l["score"]["fall_rate"]:.0f}%, {l["score"]["mean_vel_error"]:.2f}' for l in levels)
    rows.append(f'| {name} | {terrain} | {"walks" if walks else "no"} | {cells} |')
print("| checkpoint | terrain | walks at every level | level: score, falls, abs(v_cmd - v) |")
print("|---|---|---|---|")
print("\n".join(rows))
PY
