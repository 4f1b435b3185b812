#!/usr/bin/env python3
"""Breaks down the falls of a `worker eval` run by cause and commanded speed, from the
simulator's fall log (one "robot fell" line per fall at RUST_LOG=gaitsweep_sim::falls=debug):

    RUST_LOG=gaitsweep_sim::falls=debug target/release/worker eval --checkpoint CKPT \
        --terrain stairs --levels 5 > run.json 2> run.log
    python3 scripts/falls-breakdown.py run.log [more.log ...]

Each LOG needs its evaluation's JSON beside it (same name, .json) for the robot count.
Causes (sim/src/agent.rs, README "When a robot falls"): the base touched the ground; the
base tipped past 72.5 degrees without touching; the base sank below 0.35 x its nominal
height and neither of the others holds.
"""
import json
import re
import sys

if len(sys.argv) < 2:
    sys.exit("usage: falls-breakdown.py LOG [LOG ...]")
print("| log | fell | base contact | tipped, no contact | low base only | commanded > 1 m/s | commanded <= 1 m/s | tipped: median height above ground (m) |")
print("|---|---:|---:|---:|---:|---:|---:|---:|")
for path in sys.argv[1:]:
    falls = [dict(re.findall(r"(\w+)=(\S+)", line)) for line in open(path) if "robot fell" in line]
    robots = json.load(open(re.sub(r"\.log$", ".json", path)))["robots"]
    contact = [f for f in falls if f["base_contact"] == "true"]
    tipped = [f for f in falls if f["base_contact"] == "false" and float(f["gravity_z"]) > -0.3]
    low = len(falls) - len(contact) - len(tipped)
    fast = sum(float(f["cmd_speed"]) > 1.0 for f in falls)
    heights = sorted(float(f["height"]) for f in tipped)
    median = f"{heights[len(heights) // 2]:.2f}" if heights else "-"
    print(
        f"| {path} | {len(falls)} of {robots} ({100 * len(falls) / robots:.1f}%) | {len(contact)} | "
        f"{len(tipped)} | {low} | {fast} | {len(falls) - fast} | {median} |"
    )
