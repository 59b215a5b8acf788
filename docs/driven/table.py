#!/usr/bin/env python3
"""The driven Table 1: each blob's length after 64 steps and its 127-step
simulation MSE on driven rollouts, per length and drive family, beside the
physics peer (an augmented EKF with the torque as its input) and, where
given, pykoopman's EDMDc (`edmdc_peer.py --json`).

    python3 docs/driven/table.py --data DIR/test.csv \
        --blob weights/pendulum.kkf:0.2 --blob weights/pendulum-bilinear.kkf:0.05 \
        [--edmdc edmdc.json] [--undeclared] [--json OUT.json]

`--blob PATH:ACC`: the blob and the relative accuracy its trusted lengths
are held to (a length further off and trusted is "wrong and trusted").
`--undeclared`: the same rollouts read without their torques (the `u`
column dropped): how each blob does on a drive it is not told of.

Every figure comes from the project's own commands on the same CSV:
`koopman evaluate --klm-only --data` (each rollout's length after x_63, its
verdict and the simulation MSE from x_0 with the estimate and the recorded
torques) and `koopman estimate --json --steps 64 --peer` (the learned
model's own length and the physics peer's). The peer's MSE simulates the
protocol's ODE (RK4, dt/10) at its length with the same torques, in the
blob's normalised units.
"""

import argparse
import csv
import json
import math
import os
import struct
import subprocess
import sys
import tempfile
from collections import defaultdict

G, MASS = 10.0, 1.0


def varint(b, i):
    v, s = 0, 0
    while True:
        x = b[i]
        i += 1
        v |= (x & 0x7F) << s
        s += 7
        if not x & 0x80:
            return v, i


def norm_of(blob_path):
    """The blob's normalisation (mu, s), read from its body (docs/blob-format.md)."""
    b = open(blob_path, "rb").read()
    i = 4
    for _ in range(6):  # version, state, latent, param, hidden, input
        _, i = varint(b, i)
    i += 8  # dt, g
    for _ in range(3):  # rig, family, activation
        _, i = varint(b, i)
    mu = struct.unpack_from("<2f", b, i)
    s = struct.unpack_from("<2f", b, i + 8)
    return mu, s


def read_csv(path):
    rows = defaultdict(list)
    with open(path) as f:
        r = csv.DictReader(f)
        for row in r:
            rows[int(row["rollout"])].append(
                (float(row["theta"]), float(row["theta_dot"]), float(row.get("u") or 0.0))
            )
    return rows


def rod_sim(length, x0, us, dt=0.05, sub=10):
    """The protocol's rod under the torques `us`, RK4 with dt/10 substeps."""
    w2 = 3.0 * G / (2.0 * length)
    k = 3.0 / (MASS * length * length)

    def f(x, u):
        return (x[1], -w2 * math.sin(x[0]) + k * u)

    x, out, h = x0, [], dt / sub
    for u in us:
        for _ in range(sub):
            k1 = f(x, u)
            k2 = f((x[0] + h / 2 * k1[0], x[1] + h / 2 * k1[1]), u)
            k3 = f((x[0] + h / 2 * k2[0], x[1] + h / 2 * k2[1]), u)
            k4 = f((x[0] + h * k3[0], x[1] + h * k3[1]), u)
            x = (
                x[0] + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]),
                x[1] + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]),
            )
        out.append(x)
    return out


def mse(truth, sim, s):
    n = min(len(truth), len(sim))
    if n == 0 or not all(math.isfinite(v) for x in sim[:n] for v in x):
        return float("inf")
    return sum(((a[0] - b[0]) / s[0]) ** 2 + ((a[1] - b[1]) / s[1]) ** 2 for a, b in zip(truth, sim)) / (2 * n)


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr}")
    return p.stdout


def without_u(path, tmp):
    """A copy of the CSV (and sidecar) without its `u` column."""
    base = os.path.join(tmp, "undeclared")
    with open(path) as f, open(base + ".csv", "w") as g:
        r = csv.reader(f)
        w = csv.writer(g, lineterminator="\n")
        for row in r:
            w.writerow(row[:4])
    side = os.path.splitext(path)[0] + ".json"
    if os.path.exists(side):
        with open(side) as f, open(base + ".json", "w") as g:
            g.write(f.read())
    return base + ".csv"


def score(koopman, blob, acc, data, truth_rows, truth, tmp):
    out = os.path.join(tmp, os.path.basename(blob) + ".eval")
    run([koopman, "evaluate", "--klm-only", "--quiet", "--weights", blob, "--data", data, "--out", out])
    rep = json.load(open(os.path.join(out, "report.json")))
    ev = {r["rollout"]: r for r in rep["seeds"][0]["rollouts"]}
    est = {}
    for line in run([koopman, "estimate", "--weights", blob, data, "--json", "--steps", "64", "--peer", "--g", str(G)]).splitlines():
        o = json.loads(line)
        est[o["rollout"]] = o
    _, s = norm_of(blob)
    rows = []
    for rid, m in sorted(truth.items()):
        e, o = ev[rid], est[rid]
        L = m["length"]
        xs = truth_rows[rid]
        us = [u for (_, _, u) in xs[:-1]]
        peer_len = o["peer"]["length"]
        peer_sim = rod_sim(peer_len, xs[0][:2], us) if peer_len > 0 and math.isfinite(peer_len) else []
        rel = abs(e["length_est"] - L) / L
        rows.append(
            {
                "rollout": rid,
                "length": L,
                "drive": m.get("drive") or "free",
                "fused": e["length_est"],
                "model": (o.get("model_params") or [None])[0],
                "trusted": e["trusted"],
                "within": rel <= acc,
                "wrong_trusted": e["trusted"] and rel > acc,
                "mse": e["mse_klm"],
                "mse_true": e["mse_true"],
                "peer": peer_len,
                "peer_within": abs(peer_len - L) / L <= 0.05,
                "peer_mse": mse([x[:2] for x in xs[1:]], peer_sim, s),
                "reasons": o.get("trust_reasons", []),
            }
        )
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--blob", action="append", required=True, help="PATH:ACCURACY")
    ap.add_argument("--koopman", default="target/release/koopman")
    ap.add_argument("--edmdc", help="edmdc_peer.py --json output for the same CSV")
    ap.add_argument("--undeclared", action="store_true")
    ap.add_argument("--json")
    a = ap.parse_args()
    side = json.load(open(os.path.splitext(a.data)[0] + ".json"))
    truth = {m["rollout"]: m for m in side["rollouts"]}
    truth_rows = read_csv(a.data)
    edmdc = {}
    if a.edmdc:
        for r in json.load(open(a.edmdc)):
            edmdc[r["rollout"]] = r["mse"]
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        data = without_u(a.data, tmp) if a.undeclared else a.data
        for spec in a.blob:
            path, acc = spec.rsplit(":", 1)
            results[path] = score(a.koopman, path, float(acc), data, truth_rows, truth, tmp)
    title = "undeclared (read without u)" if a.undeclared else "driven, u declared"
    print(f"## {title}: {a.data}\n")
    for path, rows in results.items():
        acc = float([s for s in a.blob if s.startswith(path + ":")][0].rsplit(":", 1)[1])
        print(f"### {path} (accuracy {acc:.0%})\n")
        print("| L | drive | n | within 5% (fused) | model alone within 5% | trusted | wrong & trusted | MSE | MSE true L | peer within 5% | peer MSE | EDMDc MSE |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        groups = defaultdict(list)
        for r in rows:
            groups[(r["length"], r["drive"])].append(r)
        for (L, d), g in sorted(groups.items()):
            n = len(g)
            w5 = sum(abs(r["fused"] - L) / L <= 0.05 for r in g)
            m5 = sum(r["model"] is not None and abs(r["model"] - L) / L <= 0.05 for r in g)
            tr = sum(r["trusted"] for r in g)
            wt = sum(r["wrong_trusted"] for r in g)
            def mean(v):
                v = [float("inf") if x is None else x for x in v]
                return sum(v) / len(v) if v else float("nan")

            ed = [edmdc[r["rollout"]] for r in g if r["rollout"] in edmdc]
            print(
                f"| {L:g} | {d} | {n} | {w5} | {m5} | {tr} | {wt} | {mean([r['mse'] for r in g]):.3f} | "
                f"{mean([r['mse_true'] for r in g]):.3f} | {sum(r['peer_within'] for r in g)} | "
                f"{mean([r['peer_mse'] for r in g]):.3f} | {mean(ed):.3f} |"
            )
        inr = [r for r in rows if 2.0 <= r["length"] <= 5.0]
        print(
            f"\nIn range (2-5 m): {sum(abs(r['fused'] - r['length']) / r['length'] <= 0.05 for r in inr)}/{len(inr)} within 5%, "
            f"{sum(r['within'] for r in inr)}/{len(inr)} within {acc:.0%}; "
            f"wrong and trusted {sum(r['wrong_trusted'] for r in rows)}/{len(rows)} (all lengths), "
            f"{sum(r['wrong_trusted'] for r in inr)}/{len(inr)} in range; "
            f"peer within 5% {sum(r['peer_within'] for r in inr)}/{len(inr)}.\n"
        )
    if a.json:
        json.dump(results, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
