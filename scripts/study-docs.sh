#!/usr/bin/env bash
# The pictures and data of a study recording, for the write-up (issue 39, item 5): reads the
# committed snapshot studies/recordings/ROBOT (never the live data dir, never for writing),
# writes the report's score heatmaps (peak marked), 3D surfaces, fall rates, the score's
# tracking component, torque shares and the overlap across terrains to docs/study/ROBOT/
# (replacing the pictures there) with findings.md (the paper's findings beside the sweep's),
# each terrain's grid as JSON to tests/data/study-ROBOT-TERRAIN.json once every point of it
# is scored, with the spec it was recorded with beside it (tests/data/study-ROBOT.toml), and
# docs/study/findings.md: every recording's findings in one table (`coordinator findings`).
#
#   scripts/study-docs.sh anymal
#   scripts/study-docs.sh heavy
#
# Runs on a partial recording too (the pictures mark unscored cells "queued"; the JSON of an
# unfinished terrain is skipped with a note). Look at every picture before committing it.
set -euo pipefail
cd "$(dirname "$0")/.."
ROBOT="${1:?usage: scripts/study-docs.sh ROBOT (a recording in studies/recordings/)}"
SNAP="studies/recordings/$ROBOT"
if [ ! -e "$SNAP/gaitsweep.sqlite" ] || [ ! -e "$SNAP/sweep.id" ]; then
  echo "error: $SNAP has no recording (gaitsweep.sqlite and sweep.id); record one with scripts/record-sweep.sh" >&2
  exit 1
fi
source scripts/setup.sh
# The snapshot's copy is the database: one named in the environment must not take its place.
unset GAITSWEEP_DATABASE
export GAITSWEEP_ROBOTS="${GAITSWEEP_ROBOTS:-$PWD/robots}"
# The whole workspace, as the other scripts build it: one feature set, no rebuild between them.
cargo build --release --workspace --bins
BIN="${CARGO_TARGET_DIR:-$PWD/target}/release"
SWEEP="$(cat "$SNAP/sweep.id")"
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
# The report reads a copy: opening the snapshot itself could leave SQLite files beside it.
mkdir -p "$TMP/data"
cp "$SNAP/gaitsweep.sqlite" "$TMP/data/"
"$BIN/coordinator" report --data-dir "$TMP/data" "$SWEEP" --out "$TMP/report" --no-gif
OUT="docs/study/$ROBOT"
mkdir -p "$OUT"
rm -f "$OUT"/*.png "$OUT/findings.md"
for f in "$TMP"/report/{score,surface,fall_rate,track,torque_share}_*.png "$TMP/report/overlap.png" "$TMP/report/findings.md"; do
  [ -e "$f" ] && cp "$f" "$OUT/"
done
echo "pictures: $(ls "$OUT" | tr '\n' ' ')in $OUT"
TERRAINS="$(python3 -c 'import json, sqlite3, sys
db = sqlite3.connect(f"file:{sys.argv[1]}?mode=ro", uri=True)
spec = json.loads(db.execute("SELECT spec_json FROM sweeps WHERE id = ?", (int(sys.argv[2]),)).fetchone()[0])
print(" ".join(spec["terrains"]))' "$TMP/data/gaitsweep.sqlite" "$SWEEP")"
for t in $TERRAINS; do
  json="tests/data/study-$ROBOT-$t.json"
  if "$BIN/search-bench" export --data-dir "$TMP/data" --sweep "$SWEEP" --terrain "$t" > "$TMP/$t.json" 2> "$TMP/$t.err"; then
    mv "$TMP/$t.json" "$json"
    # The spec beside the grid (a test checks they agree).
    cp "studies/$ROBOT.toml" "tests/data/study-$ROBOT.toml"
    echo "grid of $t: $json (spec: tests/data/study-$ROBOT.toml)"
  else
    echo "grid of $t not exported yet: $(tail -1 "$TMP/$t.err")"
  fi
done
# The study's one table (README "The paper's study"): every robot recorded so far, one column
# per robot and terrain, from copies laid out as the repository's so that the text names
# studies/recordings/ROBOT, with links to each robot's pictures.
mkdir -p "$TMP/all/studies/recordings"
SOURCES=()
for snap in studies/recordings/*; do
  [ -e "$snap/gaitsweep.sqlite" ] && [ -e "$snap/sweep.id" ] || continue
  mkdir -p "$TMP/all/$snap"
  cp "$snap/gaitsweep.sqlite" "$snap/sweep.id" "$TMP/all/$snap/"
  SOURCES+=("$snap")
done
STUDY="docs/study/findings.md"
(cd "$TMP/all" && "$BIN/coordinator" findings "${SOURCES[@]}" --out "$OLDPWD/$STUDY")
{
  printf '\nThe pictures (score heatmaps with the best point marked, 3D surfaces, fall rates):\n\n'
  for snap in "${SOURCES[@]}"; do
    r="$(basename "$snap")"
    links=""
    for f in docs/study/"$r"/{score,surface,fall_rate}_*.png docs/study/"$r"/overlap.png; do
      [ -e "$f" ] || continue
      name="$(basename "$f" .png)"
      links="$links${links:+, }[${name//_/ }]($r/$name.png)"
    done
    printf -- '- %s: %s\n' "$r" "${links:-none drawn yet (run scripts/study-docs.sh $r)}"
  done
} >> "$STUDY"
echo "the study's table of ${#SOURCES[@]} recording(s): $STUDY"
