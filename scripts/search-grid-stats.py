#!/usr/bin/env python3
"""How much a recorded grid (search-bench export) says: rank agreement of replicates, noise
against the spread of point means, and how well each evaluated epoch ranks the final means.
Usage: scripts/search-grid-stats.py tests/data/search-grid-anymal-flat-4x7.json"""
import json
import statistics as st
import sys


def ranks(x):
    r = [0] * len(x)
    for k, i in enumerate(sorted(range(len(x)), key=lambda i: x[i])):
        r[i] = k
    return r


def spearman(a, b):
    ra, rb = ranks(a), ranks(b)
    ma, mb = st.mean(ra), st.mean(rb)
    cov = sum((x - ma) * (y - mb) for x, y in zip(ra, rb))
    return cov / (sum((x - ma) ** 2 for x in ra) * sum((y - mb) ** 2 for y in rb)) ** 0.5


d = json.load(open(sys.argv[1]))
pts = d["points"]
final = [st.mean(r["score"] for r in p["runs"]) for p in pts]
for e in sorted(pts[0]["runs"][0]["evals"], key=int):
    ev = [st.mean(r["evals"][e] for r in p["runs"]) for p in pts]
    print(f"epoch {e:>4}: spearman(eval mean, final mean) {spearman(ev, final):+.2f}, mean eval {st.mean(ev):+.3f}")
a = [p["runs"][0]["score"] for p in pts]
b = [p["runs"][1]["score"] for p in pts]
print(f"spearman(replicate 0, replicate 1) final: {spearman(a, b):+.2f}")
sd = st.mean([(x - y) ** 2 / 2 for x, y in zip(a, b)]) ** 0.5
print(f"pooled replicate sd {sd:.3f}; sd of point means {st.pstdev(final):.3f}; best mean {max(final):.3f}")
print(f"points within 5% of the best: {sum(f >= 0.95 * max(final) for f in final)}")
