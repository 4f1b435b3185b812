#!/usr/bin/env python3
"""Where a recording made with scripts/record-sweep.sh stands: how much is left and when it
ends at the speed measured so far, the runs in progress, and for every grid point of every
terrain whose replicates are done their final scores (falls, |v_cmd - v|, "never rewarded" as
the report says it), the mean and, when
the sweep evaluates during training, the evaluations at a few epochs. Reads the data dir's
(or a snapshot dir's) SQLite file read-only, so it can run beside the recording.

    python3 scripts/recording-progress.py DATA_DIR [EPOCH ...]   # default epochs 50 100 150 300
"""
import json
import math
import sqlite3
import sys

if len(sys.argv) < 2:
    sys.exit("usage: recording-progress.py DATA_DIR [EPOCH ...]")
epochs = [int(e) for e in sys.argv[2:]] or [50, 100, 150, 300]
path = f"{sys.argv[1]}/gaitsweep.sqlite"
try:
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    db.execute("SELECT 1 FROM sweeps LIMIT 1")
except sqlite3.Error as e:
    sys.exit(f"cannot read a gaitsweep database at {path} ({e}): pass a recording's data dir or snapshot dir")

for sweep, name, spec_json, sweep_state in db.execute(
    "SELECT id, name, spec_json, state FROM sweeps ORDER BY id"
).fetchall():
    spec = json.loads(spec_json)
    counts = dict(db.execute(
        "SELECT state, COUNT(*) FROM cells WHERE sweep_id = ? GROUP BY state", (sweep,)))
    total = sum(counts.values())
    left = db.execute(
        "SELECT COALESCE(SUM(target_epochs - epochs_done), 0) FROM cells "
        "WHERE sweep_id = ? AND state IN ('queued', 'running', 'paused')", (sweep,)).fetchone()[0]
    # Finalist replicates are queued once the grid is done: count them ahead.
    fin = spec.get("finalists")
    pending = 0
    if fin and not db.execute(
            "SELECT 1 FROM cells WHERE sweep_id = ? AND replicate > 0", (sweep,)).fetchone():
        pending = fin["top"] * (fin["seeds"] - 1) * len(spec["terrains"])
        left += pending * spec["epochs"]
    # One worker's wall seconds per epoch, evaluations included: attempts that ended in the
    # last 24 hours of the recording, from their start to their end.
    last = db.execute(
        "SELECT MAX(ended_unix_ms) FROM attempts a JOIN cells c ON c.id = a.cell_id "
        "WHERE c.sweep_id = ?", (sweep,)).fetchone()[0] or 0
    wall, trained = db.execute(
        "SELECT COALESCE(SUM(a.ended_unix_ms - a.started_unix_ms) / 1000.0, 0), "
        "COALESCE(SUM(m.top - a.resumed_from_epoch), 0) FROM attempts a "
        "JOIN cells c ON c.id = a.cell_id "
        "JOIN (SELECT attempt_id, MAX(epoch) AS top FROM epoch_metrics GROUP BY attempt_id) m "
        "ON m.attempt_id = a.id "
        "WHERE c.sweep_id = ? AND a.ended_unix_ms > ? AND m.top > a.resumed_from_epoch",
        (sweep, last - 86_400_000)).fetchone()
    running = counts.get("running", 0)
    print(f"sweep {sweep} {name} ({sweep_state}): {counts.get('done', 0)} of {total} cells done, "
          f"{counts.get('failed', 0)} failed, {running} running"
          + (f", {pending} finalist replicates to come" if pending else "")
          + f"; {left:,} epochs left")
    if spec.get("stop_unrewarded"):
        stop = max(1, math.ceil(spec["stop_unrewarded"] * spec["epochs"] - 1e-9))
        print(f"  at most: a cell never rewarded stops at epoch {stop} (stop_unrewarded = "
              f"{spec['stop_unrewarded']}), so its remaining epochs are counted in full here")
    if trained:
        per = wall / trained
        hours = left * per / 3600
        if not left:
            pace = "nothing left"
        elif running:
            pace = f"about {hours / running:.1f} hours left with {running} worker(s)"
        else:
            # No cell running means no worker is connected: give one worker's time, not a guess.
            pace = f"about {hours:.1f} hours of one worker's time left (none running now)"
        print(f"  {per:.2f} s an epoch per worker (evaluations included, {trained:,} epochs of the "
              f"last day's attempts): {pace}")
    if fin and len(spec["terrains"]) > 1 and sweep_state != "done":
        # The confirmation is queued only once the finalists are scored; from then on its
        # cells are queued cells and counted above.
        print("  not counted above until queued: after the finalists, the seeds of the point best "
              "across terrains on each terrain where it is no finalist (the live page forecasts them)")
    for cid, terrain, w1, w2, rep, state, done in db.execute(
            "SELECT id, terrain, w1, w2, replicate, state, epochs_done FROM cells "
            "WHERE sweep_id = ? AND state != 'done' AND epochs_done > 0 ORDER BY id", (sweep,)):
        print(f"  cell {cid} {terrain} (w1 {w1:.2f}, w2 {w2:.2f}, replicate {rep}) {state} at epoch {done}")

    points = {}
    for cid, terrain, w1, w2, rep in db.execute(
            "SELECT id, terrain, w1, w2, replicate FROM cells WHERE sweep_id = ? AND state = 'done' "
            "ORDER BY terrain_index, w1, w2, replicate", (sweep,)).fetchall():
        final = db.execute(
            "SELECT score, fall_rate, mean_vel_error FROM scores WHERE cell_id = ?", (cid,)
        ).fetchone()
        evals = dict(db.execute("SELECT epoch, score FROM evaluations WHERE cell_id = ? "
                                "AND kind = 'periodic'", (cid,)))
        # The report's "never rewarded": mean reward per step 0 at every epoch logged.
        top = db.execute("SELECT MAX(ABS(value)) FROM epoch_metrics WHERE cell_id = ? "
                         "AND name = 'mean_step_reward'", (cid,)).fetchone()[0]
        final = (*final, top == 0)
        points.setdefault((terrain, w1, w2), []).append((rep, final, evals))
    if not points:
        continue
    periodic = spec.get("eval_every", 0) > 0
    head = " / ".join(str(e) for e in epochs)
    print()
    print("| terrain | w1 | w2 | final score (falls, abs(v_cmd - v)) per replicate | mean |"
          + (f" evaluation at {head} per replicate |" if periodic else ""))
    print("|---|---:|---:|---|---:|" + ("---|" if periodic else ""))
    for (terrain, w1, w2), reps in points.items():
        fin_txt = " / ".join(f"{f[0]:.3f} ({100 * f[1]:.0f}%, {f[2]:.3f}"
                             + ("; never rewarded)" if f[3] else ")") for _, f, _ in reps)
        mean = sum(f[0] for _, f, _ in reps) / len(reps)
        row = f"| {terrain} | {w1:.2f} | {w2:.2f} | {fin_txt} | {mean:.3f} |"
        if periodic:
            row += " " + "; ".join(
                " / ".join(f"{e.get(k, float('nan')):.2f}" for k in epochs) for _, _, e in reps
            ) + " |"
        print(row)
    print()
