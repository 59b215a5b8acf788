"""Checks on the shared real recordings (`../shared/data/measured`: the six
video files and the three encoder swings): each as it is, with an
offset of +-0.05 rad added, resampled to 5 Hz, and with 1% of its samples
replaced by spikes (seed 36). Prints the length at the end, the verdict,
the offset, the outliers and Q; under each, the physics peer's reading
(`estimate --peer`) of the same import."""
import csv, json, math, os, random, subprocess, sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
K = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, 'target/release/koopman')
S = os.path.join(ROOT, '..', 'shared/data/measured')
OUT = os.path.join(ROOT, 'runs/real-rigs')
os.makedirs(OUT, exist_ok=True)
VIDEO = ['q2_data', 'q4b_data1', 'q4b_data2', 'q4b_data3', 'q4b_data4', 'q4b_data5']
ENCODER = ['pendulum_free_swing_data_01', 'pendulum_free_swing_data_02', 'pendulum_free_swing_data_03']

def read_video(name):
    rows = list(csv.reader(open(f'{S}/video-tracked/{name}.csv')))
    return [(float(r[0]), float(r[1])) for r in rows[1:] if r and r[0] and r[1]]

def read_encoder(name):
    """Degrees, one a line after a header and its values (the rate, Hz)."""
    lines = open(f'{S}/rotary-encoder/{name}.txt').read().split('\n')
    rate = float(lines[1].split(',')[1])
    degrees = [float(l) for l in lines[2:] if l.strip()]
    return [(k / rate, math.radians(d)) for k, d in enumerate(degrees)]

def write(path, rows):
    with open(path, 'w') as f:
        f.write('t,theta\n')
        for t, a in rows:
            f.write(f'{t:.6f},{a:.9f}\n')

def variants(rows, rng):
    yield 'as-is', rows
    yield '+0.05', [(t, a + 0.05) for t, a in rows]
    yield '-0.05', [(t, a - 0.05) for t, a in rows]
    yield '5Hz', coarse(rows, 0.2)
    spiked = list(rows)
    n = max(1, round(0.01 * len(rows)))
    for k in rng.sample(range(5, len(rows) - 5), n):
        t, a = spiked[k]
        spiked[k] = (t, a + rng.choice([-1, 1]) * rng.uniform(0.1, 0.5))
    yield 'spikes1%', spiked

def coarse(rows, dt):
    out, next_t = [], rows[0][0]
    for t, a in rows:
        if t >= next_t - 1e-9:
            out.append((t, a)); next_t = t + dt
    return out

def run(path, label):
    csv_out = f'{OUT}/{label}.csv'
    imp = subprocess.run([K, 'import', path, '--time-column', 't', '--angle-column', 'theta',
                          '--dt', '0.04', '--out', csv_out], capture_output=True, text=True)
    if imp.returncode != 0:
        return {'error': imp.stderr.strip()[-200:]}
    est = subprocess.run([K, 'estimate', '--weights', os.path.join(ROOT, 'weights/rig.kkf'), csv_out,
                          '--g', '9.81', '--json', '--peer'], capture_output=True, text=True)
    if est.returncode != 0:
        return {'error': est.stderr.strip()[-200:]}
    lines = [json.loads(l) for l in est.stdout.splitlines() if l.strip().startswith('{')]
    return lines[-1] if lines else {'error': 'no output'}

rng = random.Random(36)
for name, rows in [(n, read_video(n)) for n in VIDEO] + [('encoder' + n[-2:], read_encoder(n)) for n in ENCODER]:
    for label, v in variants(rows, rng):
        p = f'{OUT}/{name}-{label}.src.csv'
        write(p, v)
        r = run(p, f'{name}-{label}')
        if 'error' in r:
            print(f'{name:10s} {label:9s} ERROR {r["error"]}')
            continue
        L = r.get('params', [None])[0] if 'params' in r else r.get('length')
        print(f'{name:10s} {label:9s} L={L} trust={r.get("trust")} reasons={r.get("trust_reasons")} offset={r.get("offset")} outliers={r.get("outliers")} glitches={r.get("glitches", r.get("dropped"))} Q={r.get("q_factor")}')
        p = r.get('peer', {})
        print(f'{"":10s} {"peer":9s} L={p.get("length")} trusted={p.get("trusted")} doubts={p.get("doubts")} offset={p.get("offset")} Q={p.get("q_factor")}')
