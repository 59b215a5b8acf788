"""Weak SINDy (PySINDy) against our swing diagnosis on the 108 lab-like recordings.

What it does
------------
For every recording lab/<seed>/lab-<seed>-<k>-<case>.csv (columns t,theta; angle only):

* ours: runs `koopman diagnose FILE --g 9.81 --json` and reads the "swings" verdict
  (none / explained / unexplained) and the named effects;
* PySINDy: weak SINDy (Messenger & Bortz 2021) via ps.WeakPDELibrary, as follows.
  1. Resampling: sort by t, drop repeated stamps, then linear interpolation of theta onto
     an even grid with step dt = max(median step, 0.01 s) (jittered and one-row-per-count
     files have uneven stamps; the cap keeps per-count files at 100 Hz).
  2. Period T from the FFT peak of theta (0.2..5 Hz). omega = ps.SmoothedFiniteDifference
     (Savitzky-Golay, polyorder 3, window = odd, max(5, T/10 / dt) samples) of theta.
  3. State x = [theta, omega]. Library (ps.CustomLibrary, functions of (theta, omega)):
     sin(theta), cos(theta), omega, tanh(omega/0.1), omega*|omega|, wrapped in
     ps.WeakPDELibrary(spatiotemporal_grid=t, K=clip(4*duration/T, 100, 600), H_xt=T/2, p=4),
     subdomain centres drawn after np.random.seed(0). The weak target of the omega
     equation (-int phi' omega) comes from WeakPDELibrary.convert_u_dot_integral, so no
     second derivative is taken from data. theta' = omega is not fitted.
  4. FIXED RULE (chosen before looking at any result; same for all 108 files):
     the target is divided by its norm; ps.STLSQ(threshold=0.01, normalize_columns=True,
     other arguments default: alpha=0.05, max_iter=20, unbias=True) is fitted to it. A term
     is named when its coefficient is non-zero, i.e. it carries >= 1% of the weak target's
     norm on a unit-norm column. Mapping: omega -> viscous, tanh(omega/0.1) -> coulomb,
     omega|omega| -> drag, cos(theta) -> offset (a constant torque would also land on
     cos(theta); there is no torque case, so cos(theta) is scored as "offset").
     sin(theta) is the pendulum itself and is never scored.
     "unexplained" := weak-form R^2 of the omega equation (after STLSQ) < 0.99.
  Named right = exactly the expected set (clean: none; forcing: unexplained), for both.
  A sweep over other thresholds (tuned on seed 1 only, reported on seeds 2..12) is printed
  as a sensitivity check; the headline is the fixed rule above.

pysindy 2.1.0 (numpy 2.4.6, scipy 1.17.1, scikit-learn 1.9.1); see requirements.txt.

Run (from the repository root, one core):
  for s in $(seq 1 12); do
    cargo run --release -p trainer --bin koopman -- generate --lab $s --out /tmp/lab/$s
  done
  python3 -m venv /tmp/venv && /tmp/venv/bin/pip install -r docs/pysindy/requirements.txt
  OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 nice -n 10 \
    /tmp/venv/bin/python docs/pysindy/weak_sindy.py [LAB_DIR=/tmp/lab] \
    [KOOPMAN=target/release/koopman] [OUT_DIR=docs/pysindy] [OURS_CACHE_DIR]
OURS_CACHE_DIR (optional) holds <stem>.json outputs of `koopman diagnose --json`: reused when
present, written when missing. KOOPMAN_WEIGHTS (env) overrides the blob passed to --weights
(default weights/pendulum.kkf; the swing diagnosis reads only the data, but the binary must be
able to load the blob, so use one whose format the binary reads).
"""
import csv
import json
import os
import subprocess
import sys
import time
import warnings

import numpy as np
import pysindy as ps

warnings.filterwarnings("ignore")

HERE = os.path.dirname(os.path.abspath(__file__))
LAB = sys.argv[1] if len(sys.argv) > 1 else "/tmp/lab"
KOOPMAN = sys.argv[2] if len(sys.argv) > 2 else os.path.join(HERE, "..", "..", "target", "release", "koopman")
OUT = sys.argv[3] if len(sys.argv) > 3 else HERE
CACHE = sys.argv[4] if len(sys.argv) > 4 else None
WEIGHTS = os.environ.get("KOOPMAN_WEIGHTS", os.path.join(HERE, "..", "..", "weights", "pendulum.kkf"))

THRESHOLD = 0.01  # STLSQ threshold on unit-norm columns, target scaled to unit norm
R2_MIN = 0.99     # below: "unexplained"
EPS = 0.1         # rad/s, tanh smoothing of sign(omega)
NAMES = ["sin", "offset", "viscous", "coulomb", "drag"]
SCORED = NAMES[1:]

EXPECTED = {
    "clean": set(), "viscous": {"viscous"}, "coulomb": {"coulomb"}, "drag": {"drag"},
    "viscous+drag": {"viscous", "drag"}, "viscous+coulomb": {"viscous", "coulomb"},
    "viscous+offset": {"viscous", "offset"}, "coulomb+offset": {"coulomb", "offset"},
    "forcing": "unexplained",
}
CASES = list(EXPECTED)


def named_right(case, verdict, effects):
    exp = EXPECTED[case]
    if exp == "unexplained":
        return verdict == "unexplained"
    return verdict != "unexplained" and set(effects) == exp


def ours(path):
    stem = os.path.basename(path)[:-4]
    t0 = time.time()
    if CACHE and os.path.exists(os.path.join(CACHE, stem + ".json")):
        text = open(os.path.join(CACHE, stem + ".json")).read()
    else:
        text = subprocess.run([KOOPMAN, "diagnose", path, "--g", "9.81", "--json",
                               "--weights", WEIGHTS], capture_output=True, text=True).stdout
        if CACHE:
            os.makedirs(CACHE, exist_ok=True)
            open(os.path.join(CACHE, stem + ".json"), "w").write(text)
    secs = time.time() - t0
    try:
        sw = json.loads(text)["swings"][0]
        d = sw["diagnosis"]
        if d is None:
            return "error: " + str(sw.get("error")), [], secs
        return d["verdict"], sorted(e["name"] for e in d["effects"]), secs
    except Exception as e:  # noqa: BLE001
        return f"error: {e}", [], secs


def load(path):
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    t, th = data[:, 0], data[:, 1]
    o = np.argsort(t, kind="stable")
    t, th = t[o], th[o]
    keep = np.concatenate([[True], np.diff(t) > 0])
    t, th = t[keep], th[keep]
    dt = max(float(np.median(np.diff(t))), 0.01)
    tg = np.arange(t[0], t[-1], dt)
    return tg, np.interp(tg, t, th), dt


def period(tg, th, dt):
    y = th - th.mean()
    f = np.fft.rfftfreq(len(y), dt)
    p = np.abs(np.fft.rfft(y * np.hanning(len(y))))
    band = (f > 0.2) & (f < 5.0)
    return 1.0 / f[band][np.argmax(p[band])]


def weak_system(path):
    """Weak-form matrix Theta (K x 5) and target b (K) of the omega equation."""
    tg, th, dt = load(path)
    T = period(tg, th, dt)
    w = max(5, int(round(T / 10 / dt)))
    w += 1 - w % 2
    fd = ps.SmoothedFiniteDifference(smoother_kws={"window_length": w, "polyorder": 3})
    om = fd._differentiate(th.reshape(-1, 1), dt)[:, 0]
    x = np.column_stack([th, om])
    funcs = [lambda a, b: np.sin(a), lambda a, b: np.cos(a), lambda a, b: b,
             lambda a, b: np.tanh(b / EPS), lambda a, b: b * np.abs(b)]
    fnames = [lambda a, b: f"sin({a})", lambda a, b: f"cos({a})", lambda a, b: f"{b}",
              lambda a, b: f"tanh({b}/eps)", lambda a, b: f"{b}|{b}|"]
    dur = tg[-1] - tg[0]
    K = int(np.clip(4 * dur / T, 100, 600))
    lib = ps.WeakPDELibrary(function_library=ps.CustomLibrary(funcs, fnames),
                            spatiotemporal_grid=tg, K=K, H_xt=min(T / 2, dur / 2.1), p=4)
    np.random.seed(0)
    lib.fit(x)
    Theta = np.asarray(lib.transform(x))
    b = np.asarray(lib.convert_u_dot_integral(x))[:, 1]
    return Theta, b, dict(dt=dt, T=T, window=w, K=K)


def sindy_rule(Theta, b, threshold=THRESHOLD, r2_min=R2_MIN):
    bn = b / np.linalg.norm(b)
    opt = ps.STLSQ(threshold=threshold, normalize_columns=True)
    opt.fit(Theta, bn)
    c = opt.coef_[0]
    r2 = 1 - np.sum((bn - Theta @ c) ** 2) / np.sum(bn ** 2)
    eff = sorted(n for n, ci in zip(NAMES, c) if n in SCORED and ci != 0)
    verdict = "unexplained" if r2 < r2_min else ("explained" if eff else "none")
    return verdict, eff, c * np.linalg.norm(Theta, axis=0), r2


def table(rows, key_ok, seeds=None):
    out = {c: [0, 0, 0] for c in CASES}
    for r in rows:
        if seeds and r["seed"] not in seeds:
            continue
        out[r["case"]][0] += 1
        out[r["case"]][1] += r["ours_ok"]
        out[r["case"]][2] += key_ok(r)
    return out


def print_table(tab, title):
    print(f"\n{title}\n| case | recordings | ours named right | PySINDy named right |\n|---|---|---|---|")
    tot = [0, 0, 0]
    for c in CASES:
        n, a, s = tab[c]
        tot = [tot[0] + n, tot[1] + a, tot[2] + s]
        print(f"| {c} | {n} | {a} | {s} |")
    print(f"| total | {tot[0]} | {tot[1]} | {tot[2]} |")


def main():
    meta = {}
    for s in range(1, 13):
        for r in json.load(open(os.path.join(LAB, str(s), "lab.json"))):
            meta[(s, r["file"])] = r
    rows = []
    for (s, fname), r in sorted(meta.items(), key=lambda kv: (kv[0][0], kv[0][1])):
        path = os.path.join(LAB, str(s), fname)
        ov, oe, osecs = ours(path)
        t0 = time.time()
        Theta, b, info = weak_system(path)
        sv, se, contrib, r2 = sindy_rule(Theta, b)
        ssecs = time.time() - t0
        row = dict(file=fname, seed=s, case=r["case"], rate=r["rate"], stamps=r["stamps"],
                   noise=r["noise"], ours_verdict=ov, ours_effects=oe,
                   ours_ok=named_right(r["case"], ov, oe), sindy_verdict=sv, sindy_effects=se,
                   sindy_ok=named_right(r["case"], sv, se), sindy_r2=r2,
                   sindy_contrib=contrib, ours_s=osecs, sindy_s=ssecs, Theta=Theta, b=b, **info)
        rows.append(row)
        print(f"{fname:32s} ours {ov:11s} {'+'.join(oe) or '-':22s} {'ok' if row['ours_ok'] else 'WRONG':5s}"
              f" | sindy {sv:11s} {'+'.join(se) or '-':30s} {'ok' if row['sindy_ok'] else 'WRONG':5s}"
              f" R2 {r2:.4f}  {ssecs:.2f}s", flush=True)

    with open(os.path.join(OUT, "per_file.csv"), "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["file", "case", "rate", "stamps", "noise", "ours_verdict", "ours_effects",
                     "ours_named_right", "pysindy_verdict", "pysindy_effects",
                     "pysindy_named_right", "pysindy_weak_r2"] +
                    [f"pysindy_rel_{n}" for n in NAMES])
        for r in rows:
            wr.writerow([r["file"], r["case"], r["rate"], r["stamps"], f"{r['noise']:.4f}",
                         r["ours_verdict"], "+".join(r["ours_effects"]), int(r["ours_ok"]),
                         r["sindy_verdict"], "+".join(r["sindy_effects"]), int(r["sindy_ok"]),
                         f"{r['sindy_r2']:.5f}"] + [f"{v:.5f}" for v in r["sindy_contrib"]])

    print_table(table(rows, lambda r: r["sindy_ok"]), "All 108, fixed rule (threshold 0.01, R2 < 0.99 -> unexplained)")
    print_table(table(rows, lambda r: r["sindy_ok"], seeds=set(range(2, 13))), "Seeds 2..12, fixed rule")
    print(f"\nmedian seconds per file: ours {np.median([r['ours_s'] for r in rows]):.2f}"
          f" (0 if cached), PySINDy {np.median([r['sindy_s'] for r in rows]):.2f}")

    # Sensitivity: tune (threshold, R2_MIN) on seed 1 only, report seeds 2..12.
    grid = [(th, rm) for th in (0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05) for rm in (0.95, 0.99, 0.995, 0.999)]
    res = {}
    for th, rm in grid:
        ok = {}
        for r in rows:
            v, e, _, _ = sindy_rule(r["Theta"], r["b"], th, rm)
            ok[r["file"]] = named_right(r["case"], v, e)
        s1 = sum(ok[r["file"]] for r in rows if r["seed"] == 1)
        rest = sum(ok[r["file"]] for r in rows if r["seed"] != 1)
        res[(th, rm)] = (s1, rest, sum(ok.values()))
        print(f"threshold {th:<6} R2_min {rm:<6} seed1 {s1}/9  seeds2-12 {rest}/99  all {sum(ok.values())}/108")
    best = max(grid, key=lambda k: (res[k][0], -abs(np.log(k[0] / THRESHOLD))))
    print(f"tuned on seed 1: threshold {best[0]}, R2_min {best[1]} -> seeds 2..12 {res[best][1]}/99, all {res[best][2]}/108")


if __name__ == "__main__":
    main()
