"""The two shared exports of one pendulum (../shared/data/measured/imu-and-video/):
imported without options, read by weights/rig.kkf (g = 9.81), and held to the
length the period gives.

The period's length: each recording imported again on a fine grid (the IMU's
4 ms, the video's 1/60 s), the time between upward crossings of the swing's
centre (interpolated) for swings of 0.1 to 0.5 rad, each corrected to small
swings by T0 = T / (1 + A^2/16 + 11 A^4/3072), the median T0 per release,
g / (2 pi / T0)^2. Run from the repository root after a release build:
    python3 docs/real-rigs/imu_and_video.py > docs/real-rigs/imu-and-video.txt
"""
import csv, json, math, os, subprocess, sys, tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
K = os.path.join(ROOT, 'target/release/koopman')
SHARED = os.path.join(ROOT, '../shared/data/measured/imu-and-video')
FILES = {'tracker_swing_one.txt': 1 / 59.94, 'phidget_imu_usb_facing_down.txt': 0.004}


def small_swing_periods(path):
    rows = [list(map(float, r)) for r in list(csv.reader(open(path)))[1:]]
    out = {}
    for rid in sorted({r[0] for r in rows}):
        r = [x for x in rows if x[0] == rid]
        t, th = [x[1] for x in r], [x[2] for x in r]
        c = sorted(th)[len(th) // 2]
        ups = []
        for i in range(1, len(t)):
            if t[i] - t[i - 1] < 0.05 and th[i - 1] - c < 0 <= th[i] - c:
                f = (c - th[i - 1]) / (th[i] - th[i - 1])
                ups.append((t[i - 1] + f * (t[i] - t[i - 1]), i))
        t0 = []
        for (a, i), (b, j) in zip(ups, ups[1:]):
            amp = (max(th[i:j]) - min(th[i:j])) / 2
            if 0.1 < amp < 0.5 and 0.6 < b - a < 1.3:
                t0.append((b - a) / (1 + amp ** 2 / 16 + 11 * amp ** 4 / 3072))
        if t0:
            out[int(rid)] = sorted(t0)[len(t0) // 2]
    return out


with tempfile.TemporaryDirectory() as d:
    for name, fine in FILES.items():
        src = os.path.join(SHARED, name)
        out = os.path.join(d, name + '.csv')
        imp = subprocess.run([K, 'import', src, '--dt', '0.04', '--out', out], capture_output=True, text=True)
        if imp.returncode != 0:
            print(name, 'import failed:', imp.stderr.strip()); continue
        est = subprocess.run([K, 'estimate', '--weights', os.path.join(ROOT, 'weights/rig.kkf'), out,
                              '--g', '9.81', '--json'], capture_output=True, text=True, check=True)
        fine_out = os.path.join(d, name + '.fine.csv')
        subprocess.run([K, 'import', src, '--dt', str(fine), '--out', fine_out], capture_output=True, check=True)
        periods = small_swing_periods(fine_out)
        print(f'# {name}')
        for line in imp.stderr.splitlines():
            if 'layout' in line:
                print('#  ', line.split(': ', 1)[1][:160])
                break
        for v in map(json.loads, est.stdout.splitlines()):
            rid = v['rollout']
            t0 = periods.get(rid)
            lp = 9.81 * (t0 / (2 * math.pi)) ** 2 if t0 else float('nan')
            print(f"{name[:8]} release {rid}: L = {v['params'][0]:.4f} m +- {v['param_std'][0]:.4f}, "
                  f"period's {lp:.4f} m ({100 * (v['params'][0] / lp - 1):+.2f}%), {v['trust']} "
                  f"{v['trust_reasons'] or ''}")
