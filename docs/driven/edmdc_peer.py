"""pykoopman's EDMDc as a peer for driven forecasts (the protocol's Table 1 metric).

Fits `pykoopman.Koopman(observables=..., regressor=pykoopman.regression.EDMDc())`
on the one-step pairs of a training CSV (protocol format, with the `u` column)
and, for every test rollout, simulates 127 steps from x_0 alone under the
recorded torques u_0..u_126, scoring the MSE against x_1..x_127 in normalised
units, averaged over theta and theta_dot:
    mse = mean_k mean_d ((sim_k,d - x_k,d) / s_d)^2
(the project's `metrics::scaled_mse` with the model's normalisation scale).

The state the model sees, x_n = ((theta, theta_dot) - mu) / s, and with
--with-length a third, constant state z = (1/L - a) / b from the sidecar's
length (a, b the mean and standard deviation of 1/L over the training
rollouts): the rod enters the gravity term as 1/L. Without it EDMDc cannot
know which rod it simulates.

Observables (pykoopman.observables), fixed by --observables:
  poly3 (default)  Polynomial(degree=3): every monomial of the state up to
                   degree 3 with a bias (10 features on 2 states, 20 on 3)
  poly:D           Polynomial(degree=D)
  rbf:N            RadialBasisFunction("thinplate", N centres drawn from the
                   training states, include_state=True)

EDMDc learns y' = A y + B u in the lifted space with B constant, so the torque
enters the same way for every state and rod, while the physics has 3 u / (m L^2).
--u-by-length (with --with-length) gives EDMDc a second control column
u / L^2 (the rod's length is known per rollout), so B can carry it.

Simulation: `model.simulate(x0, u=U, n_steps=127)` (pykoopman: lift x0 once,
iterate y' = A y + B u, read x = C y; the length state is simulated too).
--relift instead lifts the estimate at every step (`model.predict(x, u)`,
the length state reset to its known value).

pykoopman 1.2.1 API used (checked against its source): `Koopman.fit(x, y, u)`
with x, y the stacked (x_k, x_{k+1}) pairs of every rollout and u of shape
(n_pairs, n_controls); a 1-D u is read by EDMDc.fit as ONE sample of n_pairs
controls, so u is always passed 2-D. With y given, Koopman wraps EDMDc in
EnsembleBaseRegressor, which lifts y with the same observables.

    python edmdc_peer.py --train TRAIN.csv --test TEST.csv
        [--norm-mu a,b --norm-s c,d] [--with-length [--u-by-length]]
        [--observables poly3|poly:D|rbf:N] [--relift] [--json OUT.json]
    python edmdc_peer.py --make-demo DIR [--seed S]

Without --norm-mu/--norm-s the normalisation is the training rows' mean and
standard deviation (printed). --json writes [{"rollout", "length", "drive",
"mse"}, ...]; a non-finite MSE (a diverged simulation) is written as null.
--make-demo writes DIR/train.csv (seed S, lengths 2,3,4,5, 10 rollouts per
drive) and DIR/test.csv (seed S + 1, 5 per drive) of the protocol physics (RK4
at dt / 10) under gym_rollouts.py's drives, with their sidecars.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import time
import warnings

import numpy as np

STEPS = 127


def read_set(path: str):
    """Rollouts [{id, xs (n, 2), us (n,), length, drive}] and the sidecar."""
    by = {}
    order = []
    with open(path) as f:
        r = csv.reader(f)
        header = [h.strip() for h in next(r)]
        if header != ["rollout", "t", "theta", "theta_dot", "u"]:
            raise SystemExit(f"{path}: header {header}, expected rollout,t,theta,theta_dot,u")
        for row in r:
            if not row:
                continue
            rid = int(float(row[0]))
            if rid not in by:
                by[rid] = []
                order.append(rid)
            by[rid].append([float(row[2]), float(row[3]), float(row[4])])
    side_path = os.path.splitext(path)[0] + ".json"
    side = None
    metas = {}
    if os.path.exists(side_path):
        with open(side_path) as f:
            side = json.load(f)
        metas = {m["rollout"]: m for m in side.get("rollouts", [])}
    out = []
    for rid in order:
        a = np.array(by[rid], dtype=np.float64)
        m = metas.get(rid, {})
        out.append({"id": rid, "xs": a[:, :2], "us": a[:, 2],
                    "length": m.get("length"), "drive": m.get("drive", "?")})
    return out, side


def parse_pair(s: str, what: str):
    v = [float(x) for x in s.split(",")]
    if len(v) != 2:
        raise SystemExit(f"{what} needs two numbers, got {s!r}")
    return np.array(v)


class Setup:
    """How rollouts become the model's states and controls."""

    def __init__(self, mu, s, with_length, u_by_length, inv_len_stats):
        self.mu, self.s = mu, s
        self.with_length = with_length
        self.u_by_length = u_by_length
        self.a, self.b = inv_len_stats

    def z(self, r):
        return (1.0 / r["length"] - self.a) / self.b

    def states(self, r):
        xn = (r["xs"] - self.mu) / self.s
        if self.with_length:
            xn = np.hstack([xn, np.full((len(xn), 1), self.z(r))])
        return xn

    def controls(self, r):
        u = r["us"][:, None]
        if self.u_by_length:
            u = np.hstack([u, u / r["length"] ** 2])
        return u


def make_observables(spec: str, train_states: np.ndarray, seed: int):
    import pykoopman as pk

    if spec == "poly3":
        spec = "poly:3"
    kind, _, n = spec.partition(":")
    if kind == "poly":
        return pk.observables.Polynomial(degree=int(n)), f"Polynomial(degree={int(n)})"
    if kind == "rbf":
        rng = np.random.Generator(np.random.PCG64(seed))
        idx = rng.choice(len(train_states), size=int(n), replace=False)
        centers = train_states[idx].T.copy()  # (n_features, n_centers)
        obs = pk.observables.RadialBasisFunction(
            rbf_type="thinplate", n_centers=int(n), centers=centers, include_state=True)
        return obs, f"RadialBasisFunction(thinplate, {int(n)} centres from training states)"
    raise SystemExit(f"unknown --observables {spec!r}")


def simulate(model, setup: Setup, r, relift: bool):
    x = setup.states(r)
    u = setup.controls(r)[:STEPS]
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if not relift:
            sim = np.real(model.simulate(x[0], u=u, n_steps=STEPS))
        else:
            sim = np.empty((STEPS, x.shape[1]))
            cur = x[0:1]
            for k in range(STEPS):
                nxt = np.real(model.predict(cur, u=u[k:k + 1]))
                if setup.with_length:
                    nxt[:, 2] = x[0, 2]
                sim[k] = nxt[0]
                cur = nxt
                if not np.all(np.isfinite(nxt)):
                    sim[k + 1:] = np.nan
                    break
    return sim[:, :2], x[1:STEPS + 1, :2]


def mse(sim, truth):
    with np.errstate(all="ignore"):
        return float(np.mean((sim - truth) ** 2))


def make_demo(out_dir: str, seed: int):
    here = os.path.dirname(os.path.abspath(__file__))
    sys.path.insert(0, here)
    import gym_rollouts as gr

    for name, sd, per in (("train", seed, 10), ("test", seed + 1, 5)):
        rows, side, _ = gr.record(sd, [2.0, 3.0, 4.0, 5.0], per, list(gr.DRIVES),
                                  backend="rk4", set_name=name)
        path = gr.write(out_dir, name, rows, side)
        print(f"{path}: {len(side['rollouts'])} rollouts (protocol RK4, seed {sd})")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--train")
    ap.add_argument("--test")
    ap.add_argument("--norm-mu", help="mu of theta, theta_dot: a,b")
    ap.add_argument("--norm-s", help="s of theta, theta_dot: c,d")
    ap.add_argument("--with-length", action="store_true",
                    help="append the normalised 1/L of the sidecar as a constant third state")
    ap.add_argument("--u-by-length", action="store_true",
                    help="a second control column u / L^2 (needs --with-length)")
    ap.add_argument("--observables", default="poly3", help="poly3 (default), poly:D or rbf:N")
    ap.add_argument("--relift", action="store_true",
                    help="lift the estimate again at every step instead of model.simulate")
    ap.add_argument("--seed", type=int, default=0, help="RBF centres; --make-demo's seed")
    ap.add_argument("--json", help="write the per-rollout MSEs here")
    ap.add_argument("--make-demo", metavar="DIR", help="write a small demo train/test set and exit")
    a = ap.parse_args(argv)

    if a.make_demo:
        make_demo(a.make_demo, a.seed)
        return 0
    if not a.train or not a.test:
        ap.error("--train and --test are required (or --make-demo DIR)")
    if a.u_by_length and not a.with_length:
        ap.error("--u-by-length needs --with-length")

    import pykoopman as pk

    train, _ = read_set(a.train)
    test, _ = read_set(a.test)
    for r in train + test:
        if len(r["xs"]) < STEPS + 1:
            raise SystemExit(f"rollout {r['id']} has {len(r['xs'])} rows, {STEPS + 1} needed")
        if (a.with_length or a.u_by_length) and r["length"] is None:
            raise SystemExit(f"rollout {r['id']}: no length in the sidecar (--with-length)")

    if (a.norm_mu is None) != (a.norm_s is None):
        ap.error("give both --norm-mu and --norm-s, or neither")
    if a.norm_mu is not None:
        mu, s = parse_pair(a.norm_mu, "--norm-mu"), parse_pair(a.norm_s, "--norm-s")
        norm_from = "given"
    else:
        allx = np.vstack([r["xs"] for r in train])
        mu, s = allx.mean(axis=0), allx.std(axis=0)
        norm_from = "training rows"
    inv = np.array([1.0 / r["length"] for r in train if r["length"] is not None])
    stats = (float(inv.mean()), float(inv.std()) or 1.0) if len(inv) else (0.0, 1.0)
    setup = Setup(mu, s, a.with_length, a.u_by_length, stats)

    X = np.vstack([setup.states(r)[:-1] for r in train])
    Y = np.vstack([setup.states(r)[1:] for r in train])
    U = np.vstack([setup.controls(r)[:-1] for r in train])
    obs, obs_name = make_observables(a.observables, X, a.seed)

    t0 = time.perf_counter()
    model = pk.Koopman(observables=obs, regressor=pk.regression.EDMDc(), quiet=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.fit(X, y=Y, u=U)
    fit_s = time.perf_counter() - t0

    print(f"pykoopman {pk.__version__}, numpy {np.__version__}")
    print(f"train {a.train}: {len(train)} rollouts, {len(X)} pairs; test {a.test}: {len(test)} rollouts")
    print(f"normalisation ({norm_from}): mu = {mu[0]:.6g},{mu[1]:.6g}  s = {s[0]:.6g},{s[1]:.6g}")
    state = "theta_n, theta_dot_n" + (f", z = (1/L - {stats[0]:.5g}) / {stats[1]:.5g}"
                                      if a.with_length else "")
    ctrl = "u" + (", u / L^2" if a.u_by_length else "")
    print(f"state [{state}]; controls [{ctrl}]; observables {obs_name}: "
          f"{model.n_output_features_} lifted features; A {model.A.shape}, B {model.B.shape}")
    print(f"simulation: {'relifted every step (model.predict)' if a.relift else 'model.simulate'}")
    print(f"fit: {fit_s:.3f} s")

    results = []
    answer_mu = {}  # the MSE of answering mu at every step: a reference
    t1 = time.perf_counter()
    for r in test:
        sim, truth = simulate(model, setup, r, a.relift)
        results.append({"rollout": r["id"], "length": r["length"], "drive": r["drive"],
                        "mse": mse(sim, truth)})
        answer_mu[r["id"]] = mse(np.zeros_like(truth), truth)
    sim_s = time.perf_counter() - t1
    print(f"simulation of {len(test)} rollouts: {sim_s:.3f} s")

    def fmt(v):
        return f"{v:10.4g}" if math.isfinite(v) else f"{'diverged':>10s}"

    drives = sorted({r["drive"] for r in results})
    lengths = sorted({r["length"] for r in results}, key=lambda v: (v is None, v))
    print()
    print("length  rollouts  mean MSE  median MSE  diverged  answer mu  "
          + "  ".join(f"{d:>10s}" for d in drives))
    for L in lengths + ["all"]:
        rs = [r for r in results if L == "all" or r["length"] == L]
        m = np.array([r["mse"] for r in rs])
        fin = np.isfinite(m)
        per = []
        for d in drives:
            md = [r["mse"] for r in rs if r["drive"] == d]
            per.append(fmt(float(np.mean(md))) if md else f"{'-':>10s}")
        lab = f"{L:6.2f}" if isinstance(L, float) else f"{str(L):>6s}"
        print(f"{lab}  {len(rs):8d}  {fmt(float(np.mean(m)))}  {fmt(float(np.median(m)))}  "
              f"{int((~fin).sum()):8d}  {fmt(float(np.mean([answer_mu[r['rollout']] for r in rs])))} "
              + "  ".join(per))
    print("(mean over the test rollouts of each row; 'answer mu': the MSE of answering mu at every "
          "step; on the right the mean MSE per drive)")

    if a.json:
        with open(a.json, "w") as f:
            json.dump([{**r, "mse": r["mse"] if math.isfinite(r["mse"]) else None}
                       for r in results], f, indent=1)
            f.write("\n")
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
