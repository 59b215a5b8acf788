"""Driven-pendulum rollouts from gymnasium's Pendulum-v1, in the protocol CSV.

The environment is used as a client: `gymnasium.make("Pendulum-v1", g=10.0)`,
the rod length set through `env.unwrapped.l`, the initial state written to
`env.unwrapped.state` after `reset`, and one `env.step([u])` per observation
interval. What is recorded is what the environment did: the torque it applied
(`env.unwrapped.last_u`, after its clip to [-2, 2] N m) and the state it holds
afterwards (`env.unwrapped.state`, float64; the float32 observation
[cos, sin, theta_dot] is checked against it).

Gymnasium's Pendulum-v1 (checked in gymnasium 1.4.0, classic_control/pendulum.py):
  theta measured from UPRIGHT, m = 1, dt = 0.05, one semi-implicit Euler step:
    w'  = clip(w + (3 g / (2 l) sin(th) + 3 u / (m l^2)) dt, -8, 8)
    th' = th + w' dt
  u clipped to [-2, 2] first. With th = theta + pi this is the protocol's rod,
  theta_ddot = -(3 g / (2 L)) sin(theta) + 3 u / (m L^2), integrated differently
  (first order, no substeps) and with the speed clipped at 8 rad/s.

Angle convention: theta (protocol, from hanging) = theta_gym - pi. The initial
angle is wrapped into (-pi, pi] and written to the env as theta_0 + pi. Gym's
state angle is not wrapped by the environment, so the recorded angle is
continuous (a swing over the top keeps counting past pi), like the project's
own simulator; `--wrap` wraps every row into (-pi, pi] instead.

Output (the protocol CSV and sidecar):
  DIR/gym.csv   rollout,t,theta,theta_dot,u   (t "%.6f" s from the rollout's
                start; u the torque held from this row to the next; the last
                row of a rollout has u = 0)
  DIR/gym.json  {"set", "seed", "dt": 0.05, "rig": "rod", "rollouts": [
                  {"rollout", "length", "theta0", "drive", "effects": {}}]}

Drives (u_k is the commanded torque at observation k, held for one step):
  steps   a torque uniform in [-2, 2] held for a random 5..20 steps, redrawn
  sine    A sin(phase(t)), A uniform in [0.5, 2] N m, angular frequency
          w0 * U(0.5, 1.5) with w0 = sqrt(3 g / (2 L)), random phase; with
          probability --chirp (default 0.5) a linear chirp between two such
          frequencies over the rollout
  energy  swing-up: u = clip(k w (E_target - E), -2, 2), E = 0.5 (m L^2 / 3) w^2
          + m g (L / 2)(1 - cos theta) from hanging, E_target = m g L (upright),
          k uniform in [0.05, 0.5]; half the rollouts start near hanging
          (|theta_0| uniform in [0.05, 0.3], random sign), half as the others
  free    u = 0
Initial state: theta_0 uniform in [pi/2, 0.9 pi], theta_dot_0 = 0.

    python gym_rollouts.py --out DIR --seed S [--lengths 2,3,4,5] [--per-drive 10]
        [--drives steps,sine,energy,free] [--set gym] [--wrap] [--chirp 0.5]
    python gym_rollouts.py --check [--seed S] [--lengths 2]

Deterministic for a seed (numpy Generator(PCG64(seed))). `--check` records one
rollout per drive and compares it with the protocol ODE integrated by RK4 at
dt / 10 from the same state under the same (applied) torques, printing the
largest angle difference over the first 10 and all 127 steps (and against the
protocol's angle half a step later, which gym's angle tracks more closely:
th' = th + w' dt uses the new speed), and confirms a numpy replica of the
semi-implicit Euler step reproduces gym's states.

`record(..., backend="rk4")` gives the same drives on the protocol physics
(RK4, dt / 10, no clipping) without gymnasium; edmdc_peer.py --make-demo uses it.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

G = 10.0
M = 1.0
DT = 0.05
SUBSTEPS = 10
ROLLOUT_LEN = 128
MAX_TORQUE = 2.0  # gym's clip; every drive here stays within it
DRIVES = ("steps", "sine", "energy", "free")


def wrap(x: float) -> float:
    """x wrapped into (-pi, pi]."""
    return math.pi - ((math.pi - x) % (2.0 * math.pi))


def w0(length: float) -> float:
    """The rod's small-swing angular frequency, rad/s."""
    return math.sqrt(3.0 * G / (2.0 * length))


def energy(length: float, th: float, w: float) -> float:
    """The rod's energy, J, from hanging at rest."""
    return 0.5 * (M * length**2 / 3.0) * w**2 + M * G * (length / 2.0) * (1.0 - math.cos(th))


# ---------------------------------------------------------------- drives


class Drive:
    """A torque law: u(k, theta, theta_dot), theta from hanging."""

    name = "free"

    def u(self, k: int, th: float, w: float) -> float:
        return 0.0


class Steps(Drive):
    name = "steps"

    def __init__(self, rng: np.random.Generator, n: int):
        self.seq = np.empty(n)
        k = 0
        while k < n:
            hold = int(rng.integers(5, 21))  # 5..20 steps
            self.seq[k : k + hold] = rng.uniform(-MAX_TORQUE, MAX_TORQUE)
            k += hold

    def u(self, k, th, w):
        return float(self.seq[k])


class Sine(Drive):
    name = "sine"

    def __init__(self, rng: np.random.Generator, length: float, n: int, chirp: float):
        self.amp = rng.uniform(0.5, 2.0)
        self.wa = w0(length) * rng.uniform(0.5, 1.5)
        self.phase = rng.uniform(0.0, 2.0 * math.pi)
        self.chirped = bool(rng.uniform() < chirp)
        self.wb = w0(length) * rng.uniform(0.5, 1.5) if self.chirped else self.wa
        self.span = (n - 1) * DT

    def u(self, k, th, w):
        t = k * DT
        ph = self.phase + self.wa * t + 0.5 * (self.wb - self.wa) / self.span * t * t
        return float(self.amp * math.sin(ph))


class Energy(Drive):
    name = "energy"

    def __init__(self, rng: np.random.Generator, length: float):
        self.length = length
        self.k = rng.uniform(0.05, 0.5)
        self.target = M * G * length

    def u(self, k, th, w):
        e = energy(self.length, th, w)
        return float(np.clip(self.k * w * (self.target - e), -MAX_TORQUE, MAX_TORQUE))


def draw_rollout(rng: np.random.Generator, drive: str, length: float, chirp: float):
    """(theta_0, Drive) for one rollout; the draws in a fixed order."""
    if drive == "energy" and rng.uniform() < 0.5:
        th0 = rng.uniform(0.05, 0.3) * (1.0 if rng.uniform() < 0.5 else -1.0)
    else:
        th0 = rng.uniform(math.pi / 2.0, 0.9 * math.pi)
    if drive == "steps":
        d = Steps(rng, ROLLOUT_LEN - 1)
    elif drive == "sine":
        d = Sine(rng, length, ROLLOUT_LEN - 1, chirp)
    elif drive == "energy":
        d = Energy(rng, length)
    elif drive == "free":
        d = Drive()
    else:
        raise ValueError(f"unknown drive {drive!r} (one of {', '.join(DRIVES)})")
    return th0, d


# ---------------------------------------------------------------- backends


def protocol_f(length: float, th: float, w: float, u: float):
    return w, -(3.0 * G / (2.0 * length)) * math.sin(th) + 3.0 * u / (M * length**2)


def rk4_step(length: float, th: float, w: float, u: float, dt: float = DT, sub: int = SUBSTEPS):
    """The protocol ODE over dt by RK4 at dt / sub, u held."""
    h = dt / sub
    for _ in range(sub):
        a1, b1 = protocol_f(length, th, w, u)
        a2, b2 = protocol_f(length, th + h / 2 * a1, w + h / 2 * b1, u)
        a3, b3 = protocol_f(length, th + h / 2 * a2, w + h / 2 * b2, u)
        a4, b4 = protocol_f(length, th + h * a3, w + h * b3, u)
        th += h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
        w += h / 6 * (b1 + 2 * b2 + 2 * b3 + b4)
    return th, w


class Rk4Rig:
    """The protocol physics, no clipping."""

    def __init__(self, length: float):
        self.length = length

    def reset(self, th0: float, w0_: float):
        self.th, self.w = th0, w0_
        return self.th, self.w

    def step(self, u: float):
        self.th, self.w = rk4_step(self.length, self.th, self.w, u)
        return self.th, self.w, u, False


class GymRig:
    """gymnasium Pendulum-v1 as a client; states converted to/from hanging."""

    def __init__(self, env, length: float, seed: int):
        self.env = env
        self.length = length
        self.seed = seed

    def reset(self, th0: float, w0_: float):
        env = self.env
        env.reset(seed=self.seed)
        un = env.unwrapped
        un.l = float(self.length)
        assert un.g == G and un.m == M and un.dt == DT, (un.g, un.m, un.dt)
        un.state = np.array([wrap(th0) + math.pi, float(w0_)], dtype=np.float64)
        return self._read(None)

    def _read(self, obs):
        th_g, w = (float(v) for v in self.env.unwrapped.state)
        if obs is not None:  # the float32 observation agrees with the state
            assert abs(math.atan2(obs[1], obs[0]) - wrap(th_g)) < 1e-5 or abs(
                abs(wrap(th_g)) - math.pi
            ) < 1e-5, (obs, th_g)
            assert abs(obs[2] - w) < 1e-4 * max(1.0, abs(w)), (obs, w)
        return th_g - math.pi, w

    def step(self, u: float):
        obs, _r, term, trunc, _i = self.env.step(np.array([u], dtype=np.float64))
        assert not term and not trunc
        applied = float(self.env.unwrapped.last_u)
        th, w = self._read(obs)
        return th, w, applied, abs(w) >= self.env.unwrapped.max_speed


def make_env():
    import gymnasium

    return gymnasium.make("Pendulum-v1", g=G)


# ---------------------------------------------------------------- recording


def record_one(rig, th0: float, drive: Drive, wrap_rows: bool):
    """128 rows (t, theta, theta_dot, u) and the count of speed-clipped steps."""
    th, w = rig.reset(wrap(th0), 0.0)
    rows, clipped = [], 0
    for k in range(ROLLOUT_LEN):
        if k == ROLLOUT_LEN - 1:
            rows.append([k * DT, th, w, 0.0])
            break
        u_cmd = drive.u(k, th, w)
        th1, w1, applied, hit = rig.step(u_cmd)
        rows.append([k * DT, th, w, applied])
        clipped += int(hit)
        th, w = th1, w1
    if wrap_rows:
        for r in rows:
            r[1] = wrap(r[1])
    return rows, clipped


def record(seed: int, lengths, per_drive: int, drives, backend: str = "gym",
           chirp: float = 0.5, wrap_rows: bool = False, set_name: str = "gym"):
    """(rows, sidecar, clipped per rollout). Rollouts ordered length, drive, index."""
    rng = np.random.Generator(np.random.PCG64(seed))
    env = make_env() if backend == "gym" else None
    rows, metas, clips = [], [], []
    rid = 0
    for length in lengths:
        for drive in drives:
            for _ in range(per_drive):
                th0, d = draw_rollout(rng, drive, length, chirp)
                rig = GymRig(env, length, seed) if backend == "gym" else Rk4Rig(length)
                rr, clipped = record_one(rig, th0, d, wrap_rows)
                rows += [[rid] + r for r in rr]
                metas.append({"rollout": rid, "length": float(length), "theta0": rr[0][1],
                              "drive": drive, "effects": {}})
                clips.append(clipped)
                rid += 1
    if env is not None:
        env.close()
    sidecar = {"set": set_name, "seed": seed, "dt": DT, "rig": "rod", "rollouts": metas}
    return rows, sidecar, clips


def write(out_dir: str, stem: str, rows, sidecar):
    os.makedirs(out_dir, exist_ok=True)
    csv_path = os.path.join(out_dir, f"{stem}.csv")
    with open(csv_path, "w") as f:
        f.write("rollout,t,theta,theta_dot,u\n")
        for rid, t, th, w, u in rows:
            f.write(f"{rid},{t:.6f},{float(th)!r},{float(w)!r},{float(u)!r}\n")
    with open(os.path.join(out_dir, f"{stem}.json"), "w") as f:
        json.dump(sidecar, f, indent=2)
        f.write("\n")
    return csv_path


# ---------------------------------------------------------------- check


def check(seed: int, length: float, chirp: float):
    env = make_env()
    rng = np.random.Generator(np.random.PCG64(seed))
    un = env.unwrapped
    print(f"gymnasium Pendulum-v1: g={un.g} m={un.m} dt={un.dt} max_speed={un.max_speed} "
          f"max_torque={un.max_torque}; rod L={length} (w0={w0(length):.3f} rad/s), seed {seed}")
    print("drive   theta0   clipped  max|dtheta| 1..10  max|dtheta| 1..127  "
          "max|dw| 1..127  max|dtheta| vs t+dt/2  euler-replica max diff")
    for drive in DRIVES:
        th0, d = draw_rollout(rng, drive, length, chirp)
        rows, clipped = record_one(GymRig(env, length, seed), th0, d, False)
        gym_th = np.array([r[1] for r in rows])
        gym_w = np.array([r[2] for r in rows])
        us = [r[3] for r in rows[:-1]]
        # the protocol's physics from the same state under the applied torques
        th, w = rows[0][1], rows[0][2]
        ref = [(th, w)]
        for u in us:
            th, w = rk4_step(length, th, w, u)
            ref.append((th, w))
        ref = np.array(ref)
        # gym's angle at step k against the protocol's half a step later
        half = np.array([rk4_step(length, ref[k, 0], ref[k, 1], us[k], DT / 2, SUBSTEPS // 2)[0]
                         for k in range(len(us))])
        dhalf = np.abs(gym_th[1:-1] - half[1:]).max()
        dth = np.abs(gym_th - ref[:, 0])
        dw = np.abs(gym_w - ref[:, 1])
        # a numpy replica of gym's step (upright angle), fed the same torques
        thg, wg = rows[0][1] + math.pi, rows[0][2]
        rep = [(thg - math.pi, wg)]
        for u in us:
            wg = float(np.clip(wg + (3 * G / (2 * length) * math.sin(thg)
                                     + 3.0 / (M * length**2) * u) * DT, -8, 8))
            thg = thg + wg * DT
            rep.append((thg - math.pi, wg))
        rep = np.array(rep)
        rdiff = max(np.abs(rep[:, 0] - gym_th).max(), np.abs(rep[:, 1] - gym_w).max())
        print(f"{drive:7s} {th0:7.3f}  {clipped:7d}  {dth[1:11].max():18.3e}  "
              f"{dth[1:].max():18.3e}  {dw[1:].max():14.3e}  {dhalf:20.3e}  {rdiff:.1e}")
    env.close()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", help="directory for gym.csv and gym.json")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lengths", default="2,3,4,5", help="rod lengths, m, comma-separated")
    ap.add_argument("--per-drive", type=int, default=10, help="rollouts per drive per length")
    ap.add_argument("--drives", default=",".join(DRIVES))
    ap.add_argument("--set", default="gym", help='the sidecar\'s "set" (default gym)')
    ap.add_argument("--chirp", type=float, default=0.5,
                    help="probability that a sine rollout is a chirp (default 0.5)")
    ap.add_argument("--wrap", action="store_true", help="wrap every theta into (-pi, pi]")
    ap.add_argument("--backend", choices=["gym", "rk4"], default="gym",
                    help="gym (default) or the protocol's RK4 (no gymnasium needed)")
    ap.add_argument("--check", action="store_true",
                    help="compare gym with the protocol's RK4 and print the differences")
    a = ap.parse_args(argv)
    lengths = [float(v) for v in a.lengths.split(",") if v]
    drives = [v for v in a.drives.split(",") if v]
    for d in drives:
        if d not in DRIVES:
            ap.error(f"unknown drive {d!r} (one of {', '.join(DRIVES)})")
    if a.check:
        check(a.seed, lengths[0], a.chirp)
        return
    if not a.out:
        ap.error("--out is required (or --check)")
    rows, sidecar, clips = record(a.seed, lengths, a.per_drive, drives, a.backend,
                                  a.chirp, a.wrap, a.set)
    stem = "gym" if a.backend == "gym" else "rk4"
    path = write(a.out, stem, rows, sidecar)
    n = len(sidecar["rollouts"])
    print(f"{path}: {n} rollouts x {ROLLOUT_LEN} rows ({a.backend}, seed {a.seed})")
    print("length  drive    rollouts  speed-clipped rollouts  |theta| max  |theta_dot| max  |u| max")
    by = {}
    for m, c in zip(sidecar["rollouts"], clips):
        by.setdefault((m["length"], m["drive"]), []).append((m["rollout"], c))
    ths = {}
    for rid, _t, th, w, u in rows:
        a_, w_, b_ = ths.get(rid, (0.0, 0.0, 0.0))
        ths[rid] = (max(a_, abs(th)), max(w_, abs(w)), max(b_, abs(u)))
    for (length, drive), v in by.items():
        print(f"{length:6.2f}  {drive:7s}  {len(v):8d}  {sum(1 for _, c in v if c):22d}  "
              f"{max(ths[r][0] for r, _ in v):11.3f}  {max(ths[r][1] for r, _ in v):15.3f}  "
              f"{max(ths[r][2] for r, _ in v):7.3f}")


if __name__ == "__main__":
    sys.exit(main())
