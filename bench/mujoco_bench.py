#!/usr/bin/env python3
"""MuJoCo reference for simbench (issue 2, deliverable 8): robot-steps/s of the same robots.

Loads `robots/<robot>/robot.urdf` into MuJoCo (PyPI `mujoco`) with the settings of
`robots/<robot>/preset.toml` and steps N robots with random actions, printing one JSON object
per line in simbench's schema:

    {"robot", "terrain", "setting": "mujoco", "solver_iterations", "threads", "robot_steps_per_s", ...}

What is the same as simbench / the rapier environment:
  * the URDF (masses, inertias, joint frames and axes) with a free base added to `base`;
  * physics dt = preset sim_dt, `decimation` physics steps per policy step;
  * the explicit PD law each physics step, tau = clip(Kp (q_default + scale*a - q) - Kd qd,
    +-tau_max): a MuJoCo "general" actuator per joint with gain Kp and affine bias
    (0, -Kp, -Kd), forcerange +-tau_max, ctrl = q_default + scale*a. MuJoCo evaluates it
    from the current q, qd inside every mj_step (explicit: the Euler integrator only treats
    joint damping implicitly, and the joints have none);
  * random actions uniform in [-1, 1], resampled every `decimation` physics steps;
  * spawn like the environment: x, y uniform in +-0.5 m, random yaw, base at terrain height +
    spawn_height, joints at the default pose, at rest; robots that fall (base z-axis
    tilted so that gravity's base-z component > -0.3, or base lower than
    0.35 * nominal_base_height above the terrain) are respawned, checked every `chunk`
    policy steps (the rapier environment checks every policy step and also on base contact);
  * the base box, the foot spheres and (setting "mujoco", as the rapier preset) the
    URDF's thigh and shank cylinders as capsules of the same radius and length touch the
    ground; setting "mujoco, no leg colliders" removes the leg shapes, as the rapier
    setting of that name does; no self-contacts; friction 1;
  * terrains at difficulty level 3 (simbench's): flat = a plane; rough = uniform random
    heights in +-(0.02 + 0.1*0.3) m on a 0.2 m grid, bilinearly upsampled to a 0.1 m
    heightfield over a 24 m tile and quantised to 5 mm, as sim/src/terrain.rs (a different
    random field: numpy's generator, not ChaCha8); stairs = the same pyramid-stairs
    heightfield as terrain.rs (step 0.104 m, width 0.31 m, 8 m sub-tiles, 3 m platform), up
    for even robots and down for odd ones. Both as a MuJoCo `hfield` of 241 x 241 samples.

What differs (MuJoCo's own choices, left at its defaults): the constraint solver (Newton,
up to 100 iterations, soft contacts), the pyramidal friction cone, joint range limits
(+-3.14 rad from the URDF), the foot body's mass (0, fused into the shank as in the rapier
model). MuJoCo only steps physics: no observations, rewards or height scans, which the
rapier environment computes every policy step.

Parallelism: `mujoco.rollout` (C++ thread pool; one MjData per thread; the GIL is released)
with nthread = threads; `--mode procs` instead runs `threads` processes each stepping its
share of robots with mj_step in a Python loop (a cross-check).
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import os
import sys
import time
import tomllib

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SUB_TILE = 8.0
TILE = 3 * SUB_TILE
HSCALE = 0.1
PLATFORM = 3.0
LEVELS = 10


def level_params(level: int) -> dict:
    d = min(level, LEVELS - 1) / LEVELS
    return {"step_height": 0.05 + 0.18 * d, "step_width": 0.31, "roughness": 0.02 + 0.1 * d}


def terrain_grid(kind: str, level: int, variant: int) -> np.ndarray | None:
    """Heights h[ix, iy] at x = (ix - (n-1)/2) * 0.1 (as terrain.rs), None for flat."""
    if kind == "flat":
        return None
    p = level_params(level)
    n = int(round(TILE / HSCALE)) + 1
    coords = (np.arange(n) - (n - 1) / 2) * HSCALE
    if kind == "rough":
        rng = np.random.default_rng(0x7E11A1 ^ (level << 8) ^ variant)
        nc = int(TILE / 0.2) + 1
        coarse = rng.uniform(-p["roughness"], p["roughness"], size=(nc, nc))
        # Bilinear upsampling 0.2 m -> 0.1 m (even samples exact, odd ones the mean).
        f = coords / 0.2 + (nc - 1) / 2
        i0 = np.clip(np.floor(f).astype(int), 0, nc - 2)
        t = f - i0
        rows = coarse[i0, :] * (1 - t)[:, None] + coarse[i0 + 1, :] * t[:, None]
        h = rows[:, i0] * (1 - t)[None, :] + rows[:, i0 + 1] * t[None, :]
        return np.round(h / 0.005) * 0.005
    if kind == "stairs":
        sign = 1.0 if variant % 2 == 0 else -1.0

        def sub(v):
            return np.mod(v + SUB_TILE / 2, SUB_TILE) - SUB_TILE / 2

        x, y = np.meshgrid(coords, coords, indexing="ij")
        d = np.minimum(SUB_TILE / 2 - np.abs(sub(x)), SUB_TILE / 2 - np.abs(sub(y)))
        max_steps = math.floor((SUB_TILE - PLATFORM) / 2 / p["step_width"])
        steps = np.minimum(np.floor(d / p["step_width"]), max_steps)
        return sign * steps * p["step_height"]
    raise SystemExit(f"unknown terrain {kind!r}; expected flat, rough or stairs")


def grid_height(h: np.ndarray | None, x: float, y: float) -> float:
    if h is None:
        return 0.0
    n = h.shape[0]
    half = (n - 1) / 2
    fx = min(max(x / HSCALE + half, 0.0), n - 1.0)
    fy = min(max(y / HSCALE + half, 0.0), n - 1.0)
    ix, iy = min(int(fx), n - 2), min(int(fy), n - 2)
    tx, ty = fx - ix, fy - iy
    h0 = h[ix, iy] * (1 - ty) + h[ix, iy + 1] * ty
    h1 = h[ix + 1, iy] * (1 - ty) + h[ix + 1, iy + 1] * ty
    return float(h0 * (1 - tx) + h1 * tx)


def load_preset(robot: str) -> tuple[dict, str]:
    d = os.path.join(ROOT, "robots", robot)
    with open(os.path.join(d, "preset.toml"), "rb") as f:
        p = tomllib.load(f)
    return p, os.path.join(d, p.get("urdf", "robot.urdf"))


def build_model(preset: dict, urdf: str, grid: np.ndarray | None, legs: bool = True) -> mujoco.MjModel:
    c = preset["control"]
    spec = mujoco.MjSpec.from_file(urdf)
    # Links without <inertial> (the feet) get no mass, as in the rapier model (not 1000 kg/m^3
    # of their collision sphere); fixed joints are fused into their parent.
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.compiler.fusestatic = True
    spec.option.timestep = c["sim_dt"]
    spec.option.gravity = [0.0, 0.0, -9.81]
    base = spec.body(preset.get("base_link", "base"))
    base.add_freejoint()
    feet = set(preset["feet"])
    friction = c.get("friction", 1.0)
    for g in list(spec.geoms):
        owner = g.parent.name
        if owner == base.name or owner in feet:
            # Robot contact shapes: collide with the terrain (contype 1) but not each other.
            g.contype, g.conaffinity = 0, 1
            g.friction = [friction, 0.005, 0.0001]
        elif legs and g.type in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
            # Leg shapes as the rapier preset builds them: capsules of the cylinder's radius
            # and half length (MuJoCo's size = [radius, half length] for both).
            g.type = mujoco.mjtGeom.mjGEOM_CAPSULE
            g.contype, g.conaffinity = 0, 1
            g.friction = [friction, 0.005, 0.0001]
        else:
            spec.delete(g)
    # PD as actuators: force = Kp*ctrl - Kp*q - Kd*qd, clipped to +-tau_max.
    kp, kd, tmax = c["stiffness"], c["damping"], c["torque_limit"]
    for j in preset["joints"]:
        a = spec.add_actuator()
        a.name = j
        a.trntype = mujoco.mjtTrn.mjTRN_JOINT
        a.target = j
        a.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        a.gainprm[0] = kp
        a.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        a.biasprm[0:3] = [0.0, -kp, -kd]
        a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        a.forcerange = [-tmax, tmax]
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    # Number of contacts of the base (the rapier environment's base-contact fall check).
    sens = spec.add_sensor()
    sens.name = "base_contact"
    sens.type = mujoco.mjtSensor.mjSENS_CONTACT
    sens.objtype = mujoco.mjtObj.mjOBJ_BODY
    sens.objname = base.name
    sens.intprm[0:3] = [1 << int(mujoco.mjtConDataField.mjCONDATA_FOUND), 0, 1]
    wb = spec.worldbody
    if grid is None:
        ground = wb.add_geom()
        ground.type = mujoco.mjtGeom.mjGEOM_PLANE
        ground.size = [0.0, 0.0, 1.0]  # infinite plane
    else:
        n = grid.shape[0]
        lo, hi = float(grid.min()), float(grid.max())
        span = max(hi - lo, 1e-6)
        # MuJoCo's hfield: row r is y, column c is x; data scaled by size[2] above the geom.
        data = ((grid.T - lo) / span).astype(np.float32).ravel().tolist()
        half = (n - 1) * HSCALE / 2
        spec.add_hfield(name="terrain", size=[half, half, span, 0.2], nrow=n, ncol=n, userdata=data)
        ground = wb.add_geom()
        ground.type = mujoco.mjtGeom.mjGEOM_HFIELD
        ground.hfieldname = "terrain"
        ground.pos = [0.0, 0.0, lo]
    ground.contype, ground.conaffinity = 1, 0
    ground.friction = [friction, 0.005, 0.0001]
    return spec.compile()


class Bench:
    """N robots of one preset on one terrain; models alternate over the terrain variants."""

    def __init__(self, robot: str, terrain: str, n: int, level: int, seed: int, legs: bool = True):
        self.preset, urdf = load_preset(robot)
        p, c = self.preset, self.preset["control"]
        variants = 1 if terrain == "flat" else 2
        self.grids = [terrain_grid(terrain, level, v) for v in range(variants)]
        self.models_v = [build_model(p, urdf, g, legs) for g in self.grids]
        self.models = [self.models_v[i % variants] for i in range(n)]
        self.n = n
        m = self.models_v[0]
        self.nu = m.nu
        self.decimation = int(c["decimation"])
        self.default = np.array(p["default_pose"], dtype=np.float64)
        self.scale = float(c["action_scale"])
        self.spawn_height = float(p["spawn_height"])
        self.fall_height = 0.35 * float(p["nominal_base_height"])
        # qpos addresses of the preset's joints (actuators are in the same order).
        self.qadr = np.array([m.jnt_qposadr[m.joint(j).id] for j in p["joints"]])
        self.spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.nstate = mujoco.mj_stateSize(m, self.spec)
        self.rng = np.random.default_rng(seed)
        self.scratch = mujoco.MjData(m)
        self.state = np.zeros((n, self.nstate))
        self.nsens = m.nsensordata
        # Terrain heights per robot for the vectorised fall check.
        gs = [g if g is not None else np.zeros((2, 2)) for g in self.grids]
        self.hgrid = np.stack([gs[i % len(gs)] for i in range(n)]) if terrain != "flat" else None
        for i in range(n):
            self.respawn(i)

    def respawn(self, i: int) -> None:
        m, d = self.models[i], self.scratch
        mujoco.mj_resetData(m, d)
        x, y = self.rng.uniform(-0.5, 0.5, size=2)
        yaw = self.rng.uniform(-math.pi, math.pi)
        z = grid_height(self.grids[i % len(self.grids)], x, y) + self.spawn_height
        d.qpos[0:7] = [x, y, z, math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
        d.qpos[self.qadr] = self.default
        mujoco.mj_getState(m, d, self.state[i], self.spec)

    def controls(self, policy_steps: int) -> np.ndarray:
        a = self.rng.uniform(-1.0, 1.0, size=(self.n, policy_steps, 1, self.nu))
        u = self.default + self.scale * a
        return np.broadcast_to(u, (self.n, policy_steps, self.decimation, self.nu)).reshape(
            self.n, policy_steps * self.decimation, self.nu)

    def heights(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Terrain height under each robot (bilinear, as grid_height)."""
        if self.hgrid is None:
            return np.zeros_like(x)
        n = self.hgrid.shape[1]
        half = (n - 1) / 2
        fx = np.clip(x / HSCALE + half, 0, n - 1)
        fy = np.clip(y / HSCALE + half, 0, n - 1)
        ix = np.minimum(fx.astype(int), n - 2)
        iy = np.minimum(fy.astype(int), n - 2)
        tx, ty, r, g = fx - ix, fy - iy, np.arange(self.n), self.hgrid
        h0 = g[r, ix, iy] * (1 - ty) + g[r, ix, iy + 1] * ty
        h1 = g[r, ix + 1, iy] * (1 - ty) + g[r, ix + 1, iy + 1] * ty
        return h0 * (1 - tx) + h1 * tx

    def check_falls(self, base_contacts: np.ndarray) -> int:
        """The rapier environment's fall rule: base contact, gravity's base-z component
        > -0.3, or base lower than 0.35 * nominal height above the terrain. Respawns."""
        # FULLPHYSICS state: time, qpos (base xyz, quat wxyz, joints), qvel, ...
        pos = self.state[:, 1:4]
        x, y = self.state[:, 5], self.state[:, 6]
        zz = 1 - 2 * (x * x + y * y)  # world z of the base z-axis = -(gravity in base).z
        fallen = (base_contacts > 0) | (zz < 0.3) | (pos[:, 2] - self.heights(pos[:, 0], pos[:, 1]) < self.fall_height)
        for i in np.flatnonzero(fallen):
            self.respawn(i)
        return int(fallen.sum())


def run_rollout(b: Bench, threads: int, steps: int, warmup: int, chunk: int) -> tuple[float, int]:
    m0 = b.models_v[0]
    if threads <= 1:
        pool, datas = mj_rollout.Rollout(nthread=0), [mujoco.MjData(m0)]
    else:
        pool, datas = mj_rollout.Rollout(nthread=threads), [mujoco.MjData(m0) for _ in range(threads)]
    nphys = chunk * b.decimation
    out = np.zeros((b.n, nphys, b.nstate))
    sens = np.zeros((b.n, nphys, b.nsens))
    falls = 0

    def do(policy_steps: int) -> int:
        ctrl = b.controls(policy_steps)
        st = out if policy_steps == chunk else np.zeros((b.n, policy_steps * b.decimation, b.nstate))
        se = sens if policy_steps == chunk else np.zeros((b.n, policy_steps * b.decimation, b.nsens))
        pool.rollout(b.models, datas, b.state, ctrl, state=st, sensordata=se)
        b.state[:] = st[:, -1, :]
        return b.check_falls(se[:, -1, 0])

    with pool:
        done = 0
        while done < warmup:
            k = min(chunk, warmup - done)
            do(k)
            done += k
        t = time.perf_counter()
        done = 0
        while done < steps:
            k = min(chunk, steps - done)
            falls += do(k)
            done += k
        dt = time.perf_counter() - t
    return steps * b.decimation * b.n / dt, falls


def _proc_worker(args):
    robot, terrain, n, level, seed, steps, warmup, chunk, barrier, q = args
    b = Bench(robot, terrain, n, level, seed)
    datas = [mujoco.MjData(m) for m in b.models]
    falls = 0

    def load():
        for i, d in enumerate(datas):
            mujoco.mj_setState(b.models[i], d, b.state[i], b.spec)

    def do(k):
        ctrl = b.controls(k)
        for s in range(k):
            for i, d in enumerate(datas):
                d.ctrl[:] = ctrl[i, s * b.decimation]
                mujoco.mj_step(b.models[i], d, b.decimation)
        for i, d in enumerate(datas):
            mujoco.mj_getState(b.models[i], d, b.state[i], b.spec)
        f = b.check_falls(np.array([d.sensordata[0] for d in datas]))
        load()
        return f

    load()
    for done in range(0, warmup, chunk):
        do(min(chunk, warmup - done))
    barrier.wait()
    t = time.perf_counter()
    for done in range(0, steps, chunk):
        falls += do(min(chunk, steps - done))
    q.put((time.perf_counter() - t, steps * b.decimation * n, falls))


def run_procs(robot, terrain, n, level, seed, threads, steps, warmup, chunk) -> tuple[float, int]:
    ctx = mp.get_context("fork")
    barrier, q = ctx.Barrier(threads), ctx.Queue()
    shares = [n // threads + (1 if k < n % threads else 0) for k in range(threads)]
    procs = [ctx.Process(target=_proc_worker, args=((robot, terrain, shares[k], level, seed + k, steps, warmup, chunk, barrier, q),))
             for k in range(threads)]
    for p in procs:
        p.start()
    res = [q.get() for _ in procs]
    for p in procs:
        p.join()
    # Robot-steps/s per process, summed over processes.
    return sum(r[1] / r[0] for r in res), sum(r[2] for r in res)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", default="anymal,heavy")
    ap.add_argument("--terrains", default="flat,rough,stairs")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--robots-per-env", type=int, default=64, help="robots stepped per run (simbench: 64)")
    ap.add_argument("--steps", type=int, default=200, help="policy steps timed after --warmup (simbench: 200)")
    ap.add_argument("--warmup", type=int, default=25)
    ap.add_argument("--chunk", type=int, default=1,
                    help="policy steps per rollout call; falls are checked and respawned between calls")
    ap.add_argument("--level", type=int, default=3, help="terrain difficulty level (simbench: 3)")
    ap.add_argument("--mode", choices=["rollout", "procs"], default="rollout")
    ap.add_argument("--seed", type=int, default=9)
    ap.add_argument("--json", action="store_true", help="JSON lines (default: a markdown table)")
    ap.add_argument("--legs", default="on", help="leg colliders: on, off or on,off (rollout mode)")
    a = ap.parse_args()
    if not a.json:
        print("| robot | terrain | setting | threads | robot-steps/s | respawns |")
        print("|---|---|---|---|---|---|")
    for robot in a.robots.split(","):
        for terrain in a.terrains.split(","):
            for th, legs in ((int(t), l == "on") for t in a.threads.split(",") for l in a.legs.split(",")):
                if a.mode == "rollout":
                    b = Bench(robot, terrain, a.robots_per_env, a.level, a.seed, legs)
                    rate, falls = run_rollout(b, th, a.steps, a.warmup, a.chunk)
                    m = b.models_v[0]
                else:
                    rate, falls = run_procs(robot, terrain, a.robots_per_env, a.level, a.seed, th, a.steps, a.warmup, a.chunk)
                    p, urdf = load_preset(robot)
                    m = build_model(p, urdf, None)
                setting = "mujoco" if a.mode == "rollout" else "mujoco procs"
                if not legs:
                    setting += ", no leg colliders"
                if a.json:
                    print(json.dumps({
                        "robot": robot, "terrain": terrain, "setting": setting,
                        "solver_iterations": int(m.opt.iterations), "threads": th,
                        "robot_steps_per_s": rate, "mujoco_version": mujoco.__version__,
                        "solver": mujoco.mjtSolver(m.opt.solver).name, "respawns": falls,
                    }), flush=True)
                else:
                    print(f"| {robot} | {terrain} | {setting} | {th} | {rate:.0f} | {falls} |", flush=True)


if __name__ == "__main__":
    sys.exit(main())
