#!/usr/bin/env python3
"""Times a forward and backward pass of two checkpoints' actor and critic, with subnormal
floats kept and flushed (torch.set_flush_denormal), and shows where subnormals appear
(BENCHMARKS session 42: a never-rewarded cell's networks run 2.2x slower on an Intel Xeon).

    ~/.cache/gaitsweep/venv/bin/python scripts/denormal-probe.py CKPT_A CKPT_B

Reads the gaitsweep checkpoint format (safetensors: actor.<i>.weight/bias, critic.<i>...)
without the safetensors package; one thread, 24,576 random normalised observations
(a 1,024-robot x 24-step batch)."""
import json, struct, sys, time
import torch

torch.set_num_threads(1)


def load(path):
    b = open(path, "rb").read()
    n = struct.unpack("<Q", b[:8])[0]
    header = json.loads(b[8 : 8 + n])
    out = {}
    for k, m in header.items():
        if k == "__metadata__" or m["dtype"] not in ("F32", "F64"):
            continue
        s, e = m["data_offsets"]
        dt = torch.float32 if m["dtype"] == "F32" else torch.float64
        out[k] = torch.frombuffer(bytearray(b[8 + n + s : 8 + n + e]), dtype=dt).reshape(m["shape"])
    return out


def net(t, pre):
    return [
        (t[f"{pre}.{i}.weight"].clone().requires_grad_(), t[f"{pre}.{i}.bias"].clone().requires_grad_())
        for i in range(4)
    ]


def fwd(layers, x):
    for i, (w, b) in enumerate(layers):
        x = x @ w.T + b
        if i < 3:
            x = torch.nn.functional.elu(x)
    return x


for path in sys.argv[1:]:
    t = load(path)
    torch.manual_seed(0)
    x = torch.randn(24576, 235).clamp(-5, 5)
    times = {}
    for ftz in (False, True):
        torch.set_flush_denormal(ftz)
        a, c = net(t, "actor"), net(t, "critic")
        t0 = time.time()
        for _ in range(3):
            (fwd(a, x).pow(2).mean() + fwd(c, x).pow(2).mean()).backward()
        times[ftz] = (time.time() - t0) / 3
    torch.set_flush_denormal(False)
    wmax = [f"{w.abs().max().item():.2g}" for w, _ in net(t, "actor")]
    print(f"{path}: forward+backward {times[False]:.3f} s kept, {times[True]:.3f} s flushed; actor |W| max by layer {wmax}")
