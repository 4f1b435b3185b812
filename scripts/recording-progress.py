#!/usr/bin/env python3
"""Where a recording made with scripts/record-sweep.sh stands: the runs in progress, and for
every grid point whose replicates are done their final scores (falls, |v_cmd - v|), the mean
and the evaluations at a few epochs. Reads the data dir's SQLite file read-only, so it can run
beside the recording.

    python3 scripts/recording-progress.py DATA_DIR [EPOCH ...]   # default epochs 50 100 150 300
"""
import sqlite3
import sys

if len(sys.argv) < 2:
    sys.exit("usage: recording-progress.py DATA_DIR [EPOCH ...]")
epochs = [int(e) for e in sys.argv[2:]] or [50, 100, 150, 300]
db = sqlite3.connect(f"file:{sys.argv[1]}/gaitsweep.sqlite?mode=ro", uri=True)
points = {}
cells = db.execute("SELECT id, w1, w2, replicate, state, epochs_done FROM cells ORDER BY id")
for cid, w1, w2, rep, state, done in cells.fetchall():
    if state != "done":
        if done > 0:
            print(f"cell {cid} (w1 {w1:.2f}, w2 {w2:.2f}, replicate {rep}) {state} at epoch {done}")
        continue
    final = db.execute(
        "SELECT score, fall_rate, mean_vel_error FROM scores WHERE cell_id = ?", (cid,)
    ).fetchone()
    evals = dict(db.execute("SELECT epoch, score FROM evaluations WHERE cell_id = ?", (cid,)))
    points.setdefault((w1, w2), []).append((rep, final, evals))
head = " / ".join(str(e) for e in epochs)
print(f"| w1 | w2 | final score (falls, |v_cmd - v|) per replicate | mean | evaluation at {head} per replicate |")
print("|---:|---:|---|---:|---|")
for (w1, w2), reps in points.items():
    reps.sort()
    fin = " / ".join(f"{f[0]:.3f} ({100 * f[1]:.0f}%, {f[2]:.3f})" for _, f, _ in reps)
    mean = sum(f[0] for _, f, _ in reps) / len(reps)
    ev = "; ".join(
        " / ".join(f"{e.get(k, float('nan')):.2f}" for k in epochs) for _, _, e in reps
    )
    print(f"| {w1:.2f} | {w2:.2f} | {fin} | {mean:.3f} | {ev} |")
