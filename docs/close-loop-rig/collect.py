"""Summary of the loop ending in a rig blob (docs/close-loop-rig/run.sh):
one row per recording from runs/cl-rig-*/report.json, the lab recordings'
truth from runs/labSEED/lab.json, each run's wall time from its .time file.
The lab seed is the first argument (61 unless given); the shared real
recordings (q2, the encoder) are listed with seed 61, or after a seed
and `real`; `phone` lists
run-inputs.sh's phone export."""
import glob, json, os, re, sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
R = os.path.join(ROOT, 'runs')
truth = {}
SEED = sys.argv[1] if len(sys.argv) > 1 else '61'
# A seed's lab set, or a single run whose truth lies beside its input
# (`collect.py phone`: runs/phone-gyro.json, written by phone.py).
lab = os.path.join(R, f'lab{SEED}', 'lab.json') if SEED.isdigit() else os.path.join(R, f'{SEED}-gyro.json')
if os.path.exists(lab):
    for c in json.load(open(lab)):
        truth[c['file']] = c

def minutes(name):
    p = os.path.join(R, f'cl-rig-{name}.time')
    t = open(p).read() if os.path.exists(p) else ''
    m = re.search(r'real\s+(\d+)m([\d.]+)s', t)
    return int(m.group(1)) + float(m.group(2)) / 60 if m else float('nan')

def verdict(b):
    return b['verdict'] + (': ' + '; '.join(b['reasons']) if b['reasons'] else '')

def second(b):
    v = b['second_value']
    return f"{b['second']} {v[0]:.3g} ± {v[1]:.2g}" if v else 'none'

def fc(b):
    return f"{b['forecast']['median']:.4f}" if b['forecast'] else '-'

print('| recording | truth | period\'s length, m | diagnosed | blob | forecast error | length, m (vs period\'s) | verdict | second parameter | Q | after / before | physics with / without terms | goal | minutes |')
print('|---|---|---|---|---|---|---|---|---|---|---|---|---|---|')
REAL = SEED == '61' or 'real' in sys.argv[2:]
order = [SEED] if not SEED.isdigit() else (['q2', 'encoder'] if REAL else []) + sorted(n[len('cl-rig-'):] for n in os.listdir(R) if n.startswith(f'cl-rig-lab{SEED}-') and os.path.isdir(os.path.join(R, n)))
for name in order:
    p = os.path.join(R, f'cl-rig-{name}', 'report.json')
    if not os.path.exists(p):
        continue
    r = json.load(open(p))
    mins = minutes(name)
    for i, rec in enumerate(r['recordings']):
        src = os.path.basename(rec['source'])
        t = truth.get(src)
        tr = (f"{t['length']:.4f} m, " + ', '.join(f'{k} {v:.3g}' for k, v in t['effects'])) if t else 'real'
        d = ', '.join(f"{e['name']} {e['coefficient']:.3g}" for e in rec['diagnosis']['effects'] if e['name'] != 'offset')
        ph = rec['physics']
        ratio = prat = None
        if ph and rec['before']['forecast'] and rec['after']['forecast']:
            ratio = rec['after']['forecast']['median'] / rec['before']['forecast']['median']
            prat = ph[1]['median'] / ph[0]['median']
        if ratio is None:
            goal = 'no forecasts'
        elif prat <= 0.5:
            goal = 'met' if ratio <= 0.5 else 'missed'
        else:
            goal = 'met' if ratio <= prat + 0.1 else 'missed'
        for side in ['before', 'after']:
            b = rec[side]
            rel = 100 * (b['length'] / rec['length_period'] - 1)
            q = f"{b['q_factor'][0]:.0f} ± {b['q_factor'][1]:.0f}" if b['q_factor'] else '-'
            first = side == 'before'
            print(f"| {src if first else ''} | {tr if first else ''} | {rec['length_period']:.4f} | {d if first else ''} | {side} | {fc(b)} | {b['length']:.4f} ({rel:+.2f}%) | {verdict(b)} | {second(b)} | {q} | "
                  + (f"{ratio:.2f}" if (ratio is not None and not first) else '') + ' | '
                  + (f"{prat:.2f} (physics {ph[1]['median']:.4f})" if (prat is not None and not first) else '') + ' | '
                  + (goal if not first else '') + ' | '
                  + (f"{mins:.1f}" if (not first and i == 0) else '') + ' |')
