"""The quality factor of the shared real recordings: the blob's at the end
(`koopman estimate --weights weights/rig.kkf --g 9.81 --json`: `q_factor`,
`q_factor_std`, `q_swing`) beside the swing envelope's over the last third,
and the physics peer's `w0 / c` (`--peer`, its viscous `c`).

The envelope's method: the recording imported at 0.04 s; its turning points
(where the rate changes sign, each moved to the vertex of the parabola
through it and its neighbours); each half swing's amplitude, half the range
between two turning points, at the time between them; over the last third
of the recording, the least-squares line through ln(amplitude) against
time, whose slope is -gamma; omega = pi / (the mean half swing's duration);
Q = omega / (2 gamma), at the geometric mean of the amplitudes. Run from the
repository root after a release build:
    python3 docs/real-rigs/q_check.py > docs/real-rigs/q-check.txt
"""
import csv, json, math, os, subprocess, tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
K = os.path.join(ROOT, 'target/release/koopman')
S = os.path.join(ROOT, '..', 'shared/data/measured')
FILES = [(f'video-tracked/{n}.csv', ['--time-column', 'X', '--angle-column', 'Y'])
         for n in ['q2_data', 'q4b_data1', 'q4b_data2', 'q4b_data3', 'q4b_data4', 'q4b_data5']]
FILES += [(f'rotary-encoder/pendulum_free_swing_data_0{k}.txt', []) for k in (1, 2, 3)]


def envelope_q(path):
    rows = [list(map(float, r)) for r in list(csv.reader(open(path)))[1:]]
    t, th, w = [r[1] for r in rows], [r[2] for r in rows], [r[3] for r in rows]
    turns = []
    for i in range(1, len(t) - 1):
        if w[i] * w[i + 1] < 0 or (w[i] == 0 and w[i - 1] * w[i + 1] < 0):
            a, b, c = th[i - 1], th[i], th[i + 1]
            curv = a - 2 * b + c
            v = b - (a - c) ** 2 / (8 * curv) if curv != 0 and abs(a - c) <= abs(2 * curv) else b
            turns.append((t[i], v))
    halves = [((t1 + t2) / 2, abs(v2 - v1) / 2, t2 - t1) for (t1, v1), (t2, v2) in zip(turns, turns[1:])]
    start = t[0] + 2 * (t[-1] - t[0]) / 3
    last = [h for h in halves if h[0] >= start and h[1] > 0.005]
    if len(last) < 4:
        return None
    xs, ys = [h[0] for h in last], [math.log(h[1]) for h in last]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    omega = math.pi / (sum(h[2] for h in last) / len(last))
    return (omega / (-2 * slope) if slope < 0 else float('inf')), math.exp(my), len(last)


with tempfile.TemporaryDirectory() as d:
    print('| recording | blob Q at the end | 2 std | at swing (rad) | envelope Q, last third | at swing (rad) | half swings | blob / envelope | peer Q (w0 / c) | length verdict |')
    print('| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |')
    for rel, opts in FILES:
        out = os.path.join(d, 'x.csv')
        subprocess.run([K, 'import', os.path.join(S, rel), '--dt', '0.04', '--out', out] + opts,
                       capture_output=True, check=True)
        est = subprocess.run([K, 'estimate', '--weights', os.path.join(ROOT, 'weights/rig.kkf'), out,
                              '--g', '9.81', '--json', '--peer'], capture_output=True, text=True, check=True)
        v = [json.loads(l) for l in est.stdout.splitlines()][-1]
        env = envelope_q(out)
        q, qs, sw = v.get('q_factor'), v.get('q_factor_std'), v.get('q_swing')
        name = os.path.basename(rel).rsplit('.', 1)[0]
        fmt = lambda x, p=1: '-' if x is None else f'{x:.{p}f}'
        peer = fmt(v.get('peer', {}).get('q_factor'))
        if env:
            eq, esw, n = env
            ratio = f'{q / eq:.2f}' if q and math.isfinite(eq) else '-'
            print(f'| {name} | {fmt(q)} | {fmt(qs and 2 * qs)} | {fmt(sw, 3)} | {eq:.1f} | {esw:.3f} | {n} | {ratio} | {peer} | {v["trust"]} |')
        else:
            print(f'| {name} | {fmt(q)} | {fmt(qs and 2 * qs)} | {fmt(sw, 3)} | - | - | - | - | {peer} | {v["trust"]} |')
