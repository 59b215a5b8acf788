"""The noise floor of the loop's held-out score on a lab recording: the
error a perfect forecast (the generator's own noise-free motion, its
offset added) scores against the angle as the loop imports it, over the
held-out angle's variance. No forecast scores below it.

Usage, from the repository root after `koopman generate --lab SEED ...
--out runs/labSEED` and `cargo build --release -p trainer`:

    python3 docs/close-loop-rig/floor.py SEED CASE [END_S]

CASE as in the file's name (`1-viscous`); END_S ends the part the loop
used where it is not the whole recording (the report's "measurements
used"). The motion is integrated as `trainer_core::data::lab` does (RK4
at 0.5 ms, Coulomb friction sticking at rest); the import is `koopman
import --dt 0.04`; its last third is held out, as the loop's is. The
floor is the mean over the held-out part, the score a median over its
windows.
"""
import csv
import json
import math
import statistics
import subprocess
import sys
import tempfile

G = 9.81
H = 5e-4


def motion(m):
    w2 = G / m['length'] if m['rig'] == 'simple' else 1.5 * G / m['length']
    effects = m['effects']

    def acc(x):
        a = -w2 * math.sin(x[0])
        for name, c in effects:
            if name == 'viscous':
                a -= c * x[1]
            elif name == 'drag':
                a -= c * x[1] * abs(x[1])
            elif name == 'coulomb' and x[1] != 0.0:
                a -= c * math.copysign(1.0, x[1])
        return a

    coulomb = sum(c for name, c in effects if name == 'coulomb')
    f = lambda x: [x[1], acc(x)]
    x, out = [m['theta0'], 0.0], []
    for _ in range(int(math.ceil(m['duration'] / H)) + 1):
        out.append(x[0])
        drive = acc([x[0], 0.0])
        if coulomb > 0 and abs(x[1]) < 1e-3 and abs(drive) <= coulomb:
            x[1] = 0.0
            continue
        k1 = f(x)
        k2 = f([x[0] + H / 2 * k1[0], x[1] + H / 2 * k1[1]])
        k3 = f([x[0] + H / 2 * k2[0], x[1] + H / 2 * k2[1]])
        k4 = f([x[0] + H * k3[0], x[1] + H * k3[1]])
        nx = [x[i] + H / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]) for i in (0, 1)]
        stuck = coulomb > 0 and nx[1] * x[1] < 0 and abs(drive) <= coulomb
        x = [nx[0], 0.0] if stuck else nx
    def at(t):
        k = min(int(t / H), len(out) - 2)
        a = min(max(t / H - k, 0.0), 1.0)
        return out[k] * (1 - a) + out[k + 1] * a

    return at


def main():
    seed, case = sys.argv[1], sys.argv[2]
    end = float(sys.argv[3]) if len(sys.argv) > 3 else None
    truth = json.load(open(f'runs/lab{seed}/lab.json'))
    m = next(x for x in truth if x['file'] == f'lab-{seed}-{case}.csv')
    at = motion(m)
    with tempfile.TemporaryDirectory() as tmp:
        out = f'{tmp}/imported.csv'
        subprocess.run(['./target/release/koopman', 'import', f'runs/lab{seed}/{m["file"]}',
                        '--dt', '0.04', '--out', out], check=True, capture_output=True)
        rows = [r[1:] for r in csv.reader(open(out)) if r and r[0][0].isdigit()]
    ts = [float(r[0]) for r in rows]
    th = [float(r[1]) for r in rows]
    n = len(ts) if end is None else sum(1 for t in ts if t <= end)
    cut = n - n // 3
    err = [(a - at(t) - m['offset']) ** 2 for a, t in zip(th[cut:n], ts[cut:n])]
    var = statistics.pvariance(th[cut:n])
    print(f"lab-{seed}-{case}: {n} measurements used, {n - cut} held out; the imported angle "
          f"{math.sqrt(sum(err) / len(err)):.4f} rad (rms) from the true motion; floor "
          f"{sum(err) / len(err) / var:.4f} of the held-out variance {var:.5f}")


if __name__ == '__main__':
    main()
