#!/usr/bin/env python3
"""Seconds an epoch of each lease in a worker's log, from its `epoch` lines, over the lease's
epochs logged at or after SINCE (UTC, e.g. 2026-12-05T23:50) and before UNTIL (BENCHMARKS
session 42's recording speeds).

    python3 scripts/epoch-rate.py DATA_DIR/worker-1.log [SINCE [UNTIL]]"""
import datetime, re, sys

log = sys.argv[1]
since = datetime.datetime.fromisoformat(sys.argv[2]) if len(sys.argv) > 2 else datetime.datetime.min
until = datetime.datetime.fromisoformat(sys.argv[3]) if len(sys.argv) > 3 else datetime.datetime.max
by_lease = {}
for line in open(log, errors="replace"):
    m = re.match(r"(\S+?)Z\s+INFO gaitsweep_worker::daemon: epoch lease=(\d+) epoch=(\d+)", line)
    if m:
        t = datetime.datetime.fromisoformat(m.group(1)[:26])
        if since <= t < until:
            by_lease.setdefault(int(m.group(2)), []).append((t, int(m.group(3))))
for lease, seg in sorted(by_lease.items()):
    if len(seg) > 1 and seg[-1][1] > seg[0][1]:
        (t0, e0), (t1, e1) = seg[0], seg[-1]
        rate = (t1 - t0).total_seconds() / (e1 - e0)
        print(f"lease {lease}: epochs {e0}-{e1}, {t0:%H:%M:%S}-{t1:%H:%M:%S}, {rate:.2f} s an epoch")
