#!/usr/bin/env python3
"""The estimator's step against a numpy peer, in the same run.

The peer is the textbook extended Kalman filter a researcher would write
in numpy for the rig blob's model, at the blob's sizes (its hidden width
read from its sidecar; the weights drawn at a trained blob's scale, as a
dense numpy step's time does not depend on their values): the encoder
(2 -> H -> H -> 16, ReLU), the bilinear prediction `F(q) y` with
`F(q) = F_0 + q_1 F_1 + q_2 F_2 + q_1^2 F_11`, its Jacobian, `P = J P J^T +
Q`, `S = P_yy + R`, the gain by `np.linalg.solve`, the update of the mean
and `P`. It leaves out what the estimator adds around the filter (the
swing's readers, the fusion, the verdict: about 3,000 of the rig step's
69,000 Cortex-M4F instructions), so it is the cheaper of the two.

The estimator's own step is timed by `koopman bench --json` (the same
blob, 64 steps of a lab recording, many batches) in the same run, and the
ratio printed:

    python3 docs/bench/numpy_peer.py [--weights weights/rig.kkf] [--seconds 3]

Needs numpy (any 1.x or 2.x) and `target/release/koopman`.
"""

import argparse
import json
import subprocess
import sys
import time

import numpy as np

S, L, P_DIM = 2, 16, 2
AUG = L + P_DIM


def hidden_width(path):
    """The blob's hidden width, from the sidecar `koopman export` writes
    beside it (`weights/NAME.json`: its training config)."""
    sidecar = path.rsplit(".", 1)[0] + ".json"
    return int(json.load(open(sidecar))["config"]["hidden"])


def peer_weights(hidden, seed=0):
    """Weights of the blob's shapes, drawn at the trained blob's scale
    (the timing of a dense numpy step does not depend on the values)."""
    rng = np.random.default_rng(seed)
    w = {
        "W0": rng.normal(0, 0.5, (S, hidden)).astype(np.float32),
        "b0": np.zeros(hidden, np.float32),
        "W1": rng.normal(0, 1 / np.sqrt(hidden), (hidden, hidden)).astype(np.float32),
        "b1": np.zeros(hidden, np.float32),
        "W2": rng.normal(0, 1 / np.sqrt(hidden), (hidden, L)).astype(np.float32),
        "b2": np.zeros(L, np.float32),
    }
    rot = np.linalg.qr(rng.normal(size=(L, L)))[0].astype(np.float32)
    w["F0"] = 0.99 * rot
    for k in ("F1", "F2", "F11"):
        w[k] = rng.normal(0, 0.01, (L, L)).astype(np.float32)
    w["Q"] = np.diag(np.full(AUG, 1e-4, np.float32))
    w["R"] = np.diag(np.full(L, 1e-2, np.float32))
    return w


def make_step(w):
    W0, b0, W1, b1, W2, b2 = (w[k] for k in ("W0", "b0", "W1", "b1", "W2", "b2"))
    F0, F1, F2, F11, Q, R = (w[k] for k in ("F0", "F1", "F2", "F11", "Q", "R"))
    eye_p = np.eye(P_DIM, dtype=np.float32)

    def step(x, m, P):
        # Encode the measurement.
        h = np.maximum(x @ W0 + b0, 0.0)
        h = np.maximum(h @ W1 + b1, 0.0)
        z = h @ W2 + b2
        # Predict: y' = F(q) y, q' = q; J its Jacobian.
        y, q = m[:L], m[L:]
        q1, q2 = q
        Fq = F0 + q1 * F1 + q2 * F2 + q1 * q1 * F11
        J = np.zeros((AUG, AUG), np.float32)
        J[:L, :L] = Fq
        J[:L, L] = (F1 + 2 * q1 * F11) @ y
        J[:L, L + 1] = F2 @ y
        J[L:, L:] = eye_p
        mp = np.concatenate([Fq @ y, q])
        P = J @ P @ J.T + Q
        # Update with the encoded measurement (H = [I 0]).
        Syy = P[:L, :L] + R
        K = np.linalg.solve(Syy, P[:L, :]).T
        nu = z - mp[:L]
        m = mp + K @ nu
        P = P - K @ P[:L, :]
        return m, 0.5 * (P + P.T)

    return step


def time_peer(step, seconds):
    rng = np.random.default_rng(1)
    xs = rng.normal(0, 0.3, (64, S)).astype(np.float32)
    m0 = np.concatenate([np.zeros(L), [0.5, 0.0]]).astype(np.float32)
    P0 = np.eye(AUG, dtype=np.float32) * 0.1
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        m, P = m0, P0
        for x in xs:
            m, P = step(x, m, P)
        n += len(xs)
    return (time.perf_counter() - t0) / n * 1e9


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--weights", default="weights/rig.kkf")
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--koopman", default="target/release/koopman")
    a = ap.parse_args()
    hidden = hidden_width(a.weights)
    step = make_step(peer_weights(hidden))
    bench = [a.koopman, "bench", "--weights", a.weights, "--seconds", str(a.seconds), "--json"]
    ours_ns = lambda: json.loads(subprocess.run(bench, check=True, capture_output=True, text=True).stdout)["step_ns"]
    before = ours_ns()
    peer = time_peer(step, a.seconds)
    after = ours_ns()
    step_ns = 0.5 * (before + after)
    print(f"blob {a.weights} (hidden {hidden}); numpy {np.__version__}, Python {sys.version.split()[0]}")
    print(f"estimator step (koopman bench, before and after the peer): {before:.0f} / {after:.0f} ns")
    print(f"numpy peer step (the filter alone): {peer:.0f} ns")
    print(f"ratio: {peer / step_ns:.1f}x")


if __name__ == "__main__":
    main()
