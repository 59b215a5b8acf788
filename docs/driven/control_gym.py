#!/usr/bin/env python3
"""Swing-up and balance on gymnasium's Pendulum-v1 through `koopman control`.

For each rod and start: a fresh Pendulum-v1 (g = 10, max_torque 2, dt 0.05,
its `l` set), its state set to rest within 0.1 rad of hanging, 600 steps. Each
step sends the state (theta turned from gym's upright to the protocol's
hanging) as `theta,theta_dot` to `koopman control` and applies the `u` it
answers. Balanced: the last 100 steps within 0.2 rad of the upright at under
1 rad/s. Three controllers, the same command: controlling with the length it
reads, with the true length (`--length L`), and with 3.5 m for every rod.

    /work/venv-driven/bin/python docs/driven/control_gym.py \
        [--weights weights/pendulum-bilinear.kkf] [--lengths 2,3,4,5] \
        [--starts 5] [--seed 1] [--json OUT] [--trace DIR]
    .../control_gym.py --picture docs/control-swing-up.png   # one run, drawn
"""

import argparse
import json
import math
import os
import subprocess
import sys

import numpy as np
import gymnasium as gym


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def run(koopman, weights, length, theta0, fixed=None, steps=600, plot=None):
    env = gym.make("Pendulum-v1", g=10.0)
    env.reset(seed=0)
    env.unwrapped.l = length
    # Gym's theta is from the upright and not wrapped as it moves: theta0 + pi
    # keeps the protocol's theta = gym's - pi continuous from theta0.
    env.unwrapped.state = np.array([theta0 + math.pi, 0.0])
    cmd = [koopman, "control", "--weights", weights, "--g", "10", "--max-torque", "2"]
    if fixed is not None:
        cmd += ["--length", str(fixed)]
    if plot is not None:
        cmd += ["--plot", plot]
    p = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
    trace = []
    for _ in range(steps):
        th, thdot = env.unwrapped.state
        theta = th - math.pi  # from hanging, continuous
        p.stdin.write(f"{theta},{thdot}\n")
        p.stdin.flush()
        u, est = map(float, p.stdout.readline().split(","))
        trace.append((theta, float(thdot), u, est))
        env.step(np.array([u], dtype=np.float32))
    p.stdin.close()
    p.wait()
    env.close()
    last = trace[-100:]
    balanced = all(abs(wrap(t - math.pi)) < 0.2 and abs(r) < 1.0 for t, r, _, _ in last)
    return balanced, trace[-1][3], trace


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--koopman", default="target/release/koopman")
    ap.add_argument("--weights", default="weights/pendulum-bilinear.kkf")
    ap.add_argument("--lengths", default="2,3,4,5")
    ap.add_argument("--starts", type=int, default=5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json")
    ap.add_argument("--trace", help="write each run's trace (theta, theta_dot, u, length) here")
    ap.add_argument("--picture", help="instead, one run (a 3 m rod from 0.05 rad, the length read) drawn to this PNG")
    a = ap.parse_args()
    if a.picture:
        bal, est, _ = run(a.koopman, a.weights, 3.0, 0.05, plot=a.picture)
        print(f"balanced {bal}, final length read {est:.3f} m; wrote {a.picture}")
        return
    rng = np.random.default_rng(a.seed)
    lengths = [float(x) for x in a.lengths.split(",")]
    results = []
    print("| rod (m) | controller | balanced | final length read (within 5%) |")
    print("| --- | --- | --- | --- |")
    for L in lengths:
        starts = rng.uniform(-0.1, 0.1, a.starts)
        for name, fixed in [("read", None), ("true", L), ("3.5 m", 3.5)]:
            ok, within = 0, 0
            for k, th0 in enumerate(starts):
                bal, est, trace = run(a.koopman, a.weights, L, float(th0), fixed)
                ok += bal
                within += abs(est - L) / L <= 0.05
                results.append({"length": L, "controller": name, "start": float(th0), "balanced": bal, "final_length": est})
                if a.trace:
                    os.makedirs(a.trace, exist_ok=True)
                    with open(os.path.join(a.trace, f"{name.replace(' ', '')}-{L:g}-{k}.csv"), "w") as f:
                        f.write("theta,theta_dot,u,length\n")
                        f.writelines(f"{t},{r},{u},{e}\n" for t, r, u, e in trace)
            print(f"| {L:g} | {name} | {ok}/{len(starts)} | {within}/{len(starts)} |", flush=True)
    if a.json:
        json.dump(results, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
