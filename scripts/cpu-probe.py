#!/usr/bin/env python3
"""CPU seconds for a fixed amount of one-thread work (a Python loop and small torch matmuls),
5 tries: a probe of the machine's speed that a neighbouring load does not change, since it
counts this process's CPU time, not the wall clock (BENCHMARKS "Session 43").

    ~/.cache/gaitsweep/venv/bin/python scripts/cpu-probe.py
"""
import time

import torch

torch.set_num_threads(1)
a = torch.randn(512, 256)
b = torch.randn(256, 256)


def work():
    s = 0
    for i in range(300000):
        s += i * i
    for _ in range(400):
        torch.tanh(a @ b)
    return s


work()
res = []
for _ in range(5):
    t = time.process_time()
    work()
    res.append(time.process_time() - t)
print("cpu seconds per work unit:", " ".join(f"{r:.3f}" for r in res), "min", f"{min(res):.3f}")
