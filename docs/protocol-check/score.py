"""The protocol blob's reading of draw.py's rollouts: each untrusted one
with its error and reasons, then how many are trusted, within 5%, and
flagged while within 5% and within the blob's accuracy, 20%, and how many more than 20% off are trusted (`estimate --json`, g = 9.81 declared)."""
import json, subprocess, sys
csv, truthf = sys.argv[1], sys.argv[2]
extra = sys.argv[3:]
truth = list(map(float, open(truthf).read().split()))
out = subprocess.run(['target/release/koopman', 'estimate', '--weights', 'weights/pendulum.kkf', csv, '--g', '9.81', '--json'] + extra, capture_output=True, text=True).stdout
flag = 0; n = 0; rows = []
for line, L in zip(out.strip().split('\n'), truth):
    j = json.loads(line); n += 1
    e = j['params'][0] / L - 1
    rows.append((j['rollout'], L, e, j['trust'], j['trust_reasons'], j['offset']))
for r in rows:
    if r[3] != 'trusted':
        print(f"{r[0]:3d} L={r[1]:.3f} err={100*r[2]:+.2f}% {r[3]} {r[4]} offset={r[5]}")
print('trusted', sum(r[3]=='trusted' for r in rows), 'of', n, '; within 5%', sum(abs(r[2])<0.05 for r in rows), '; flagged with |err|<5%', sum(r[3]!='trusted' and abs(r[2])<0.05 for r in rows), '; flagged within 20% (the blob\'s accuracy)', sum(r[3]!='trusted' and abs(r[2])<0.2 for r in rows), '; more than 20% off and trusted', sum(r[3]=='trusted' and abs(r[2])>=0.2 for r in rows), '; largest error', f"{100*max(abs(r[2]) for r in rows):.1f}%")
