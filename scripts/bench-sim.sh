#!/usr/bin/env bash
# Simulation benchmark (issue 2, deliverable 8): rapier (simbench) and MuJoCo side by side in
# one run, same robots (URDF + preset), dt, PD law, random actions and terrains.
#
#   scripts/bench-sim.sh            # prints one markdown table (about 3-4 minutes on 2 cores)
#   scripts/bench-sim.sh --quick    # fewer steps, for checking the script
#
# Installs the PyPI `mujoco` package into the project venv (the cache, outside the clone)
# if it is missing. Robot-steps/s = physics steps x robots per second, summed over threads.
set -euo pipefail
cd "$(dirname "$0")/.."
MUJOCO_VERSION="${MUJOCO_VERSION:-4.0.0}"
STEPS=200
if [[ "${1:-}" == "--quick" ]]; then STEPS=40; fi

source scripts/setup.sh
PY="$VIRTUAL_ENV/bin/python"
if ! "$PY" -c "import mujoco, sys; sys.exit(0 if mujoco.__version__ == '$MUJOCO_VERSION' else 1)" 2>/dev/null; then
  echo "bench-sim: installing mujoco==$MUJOCO_VERSION into $VIRTUAL_ENV" >&2
  "$VIRTUAL_ENV/bin/pip" install --quiet "mujoco==$MUJOCO_VERSION"
fi
cargo build --release -p gaitsweep-sim --features bench --bin simbench >&2

TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
SIMBENCH=(target/release/simbench --json --robots anymal,heavy --terrains flat,rough,stairs
          --threads 1,2 --steps "$STEPS" --no-legs --parry-contacts --extra multibody:1:1)
MUJOCO=("$PY" bench/mujoco_bench.py --json --robots anymal,heavy --terrains flat,rough,stairs
        --threads 1,2 --steps "$STEPS" --legs on,off)

load_before="$(cut -d' ' -f1-3 /proc/loadavg)"
start=$(date +%s)
echo "bench-sim: ${SIMBENCH[*]}" >&2
"${SIMBENCH[@]}" | tee "$TMP/rapier.jsonl" >&2
echo "bench-sim: ${MUJOCO[*]}" >&2
"${MUJOCO[@]}" | tee "$TMP/mujoco.jsonl" >&2
load_after="$(cut -d' ' -f1-3 /proc/loadavg)"
elapsed=$(( $(date +%s) - start ))

cpu="$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//')"
rev="$(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
mjv="$("$PY" -c 'import mujoco; print(mujoco.__version__)')"

echo "Machine: $(nproc) cores, $cpu; $(date -u '+%Y-%m-%d %H:%M UTC'); commit $rev; MuJoCo $mjv."
echo "Load average (1/5/15 min) before: $load_before; after: $load_after; benchmark took ${elapsed} s."
echo "Command: scripts/bench-sim.sh $*  (runs: ${SIMBENCH[*]}; python ${MUJOCO[*]:1})"
echo
"$PY" - "$TMP/rapier.jsonl" "$TMP/mujoco.jsonl" <<'EOF'
import json, sys, tomllib
def control(robot):
    with open(f"robots/{robot}/preset.toml", "rb") as f:
        return tomllib.load(f)["control"]
rapier = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
mujoco = [json.loads(l) for l in open(sys.argv[2]) if l.strip()]
legs = lambda r: "no leg colliders" not in r["setting"]
mj = {(r["robot"], r["terrain"], r["threads"], legs(r)): r for r in mujoco}
order = {"preset": 0, "preset, no leg colliders": 1, "preset, parry's capsule contacts": 1.5, "multibody:1:1": 2, "rapier default": 3,
         "multibody:4:1": 4, "mujoco": 9, "mujoco, no leg colliders": 10}
rows = rapier + mujoco
rows.sort(key=lambda r: (r["robot"], ["flat", "rough", "stairs"].index(r["terrain"]), order.get(r["setting"], 1), r["threads"]))
print("| robot | terrain | setting | solver iterations | threads | robot-steps/s | MuJoCo (same robot, terrain, threads, leg colliders) | ratio to MuJoCo |")
print("|---|---|---|---:|---:|---:|---:|---:|")
for r in rows:
    m = mj.get((r["robot"], r["terrain"], r["threads"], legs(r)))
    ref = m["robot_steps_per_s"] if m else float("nan")
    if r["setting"].startswith("mujoco"):
        setting = f'MuJoCo {r.get("mujoco_version", "")} ({r.get("solver", "").replace("mjSOL_", "").title()}, defaults)'
        if not legs(r):
            setting += ", no leg colliders"
    elif r["setting"].startswith("preset"):
        c = control(r["robot"])
        setting = f'preset: {c["joints"]}, {c["pgs_iterations"]} PGS' + ("" if legs(r) else ", no leg colliders")
        if "parry" in r["setting"]:
            setting += ", parry's per-triangle capsule contacts"
    elif r["setting"] == "rapier default":
        setting = "rapier's defaults: multibody, 1 PGS"
    else:
        backend, _, pgs = r["setting"].split(":")
        setting = f"{backend}, {pgs} PGS ({r['setting']})"
    print(f'| {r["robot"]} | {r["terrain"]} | {setting} | {r["solver_iterations"]} | {r["threads"]} '
          f'| {r["robot_steps_per_s"]:,.0f} | {ref:,.0f} | {r["robot_steps_per_s"] / ref:.2f} |')
print()
print("Leg-collider cost: 1 - (robot-steps/s with thigh and shank colliders) / (without), same run:")
print("the preset's closed-form capsule contacts, parry's per-triangle ones, MuJoCo's.")
print()
print("| robot | terrain | threads | rapier preset | rapier, parry's capsule contacts | MuJoCo |")
print("|---|---|---:|---:|---:|---:|")
by = {(r["robot"], r["terrain"], r["threads"], r["setting"]): r["robot_steps_per_s"] for r in rows}
for (robot, terrain, th, setting), v in sorted(by.items()):
    if setting != "preset":
        continue
    cost = lambda on, off: f"{1 - on / off:.1%}" if on and off else "n/a"
    off = by.get((robot, terrain, th, 'preset, no leg colliders'))
    parry = by.get((robot, terrain, th, "preset, parry's capsule contacts"))
    print(f"| {robot} | {terrain} | {th} | {cost(v, off)} | {cost(parry, off)} "
          f"| {cost(by.get((robot, terrain, th, 'mujoco')), by.get((robot, terrain, th, 'mujoco, no leg colliders')))} |")
EOF
