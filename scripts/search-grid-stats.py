#!/usr/bin/env python3
"""How much a recorded grid (search-bench export) says: rank agreement of replicates, noise
against the spread of point means, and how well each evaluated epoch ranks the final means.
Usage: scripts/search-grid-stats.py tests/data/search-grid-anymal-flat-4x7.json"""
import bisect
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


# What a search in continuous (w1, w2) is judged against: search-bench scores a candidate
# between grid points by bilinear interpolation of the point means, whose maxima lie on
# grid points, so only part of the rectangle is within 5% of the best mean. A uniformly
# random answer lands there this often.
W1, W2 = d["w1_values"], d["w2_values"]
mean = {(p["w1_index"], p["w2_index"]): f for p, f in zip(pts, final)}


def bracket(v, t):
    k = min(max(bisect.bisect_right(v, t) - 1, 0), len(v) - 2)
    return k, (t - v[k]) / (v[k + 1] - v[k])


def interpolate(x, y):
    i, a = bracket(W1, x)
    j, b = bracket(W2, y)
    return ((1 - a) * (1 - b) * mean[(i, j)] + a * (1 - b) * mean[(i + 1, j)]
            + (1 - a) * b * mean[(i, j + 1)] + a * b * mean[(i + 1, j + 1)])


n = 200
cut = max(final) - 0.05 * abs(max(final))
inside = sum(interpolate(W1[0] + (W1[-1] - W1[0]) * (u + 0.5) / n,
                         W2[0] + (W2[-1] - W2[0]) * (v + 0.5) / n) >= cut
             for u in range(n) for v in range(n))
print(f"share of the (w1, w2) rectangle whose interpolated mean is within 5% of the best: {inside / n / n:.1%}")
