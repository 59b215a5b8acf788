"""Q at the end against the swing envelope's over the last third (how the
hidden real recordings are held), on lab-like recordings of real strings'
sizes, with the truth at each swing beside it.

Each seed's lab set: `koopman generate --lab SEED --offset 0.06 --drag
0.004,0.046 --coulomb 0,0.01 --swings 0.1,1.2 --rates 12,60 --seconds
60,600`. Each recording is imported at 0.04 s and read by `koopman
estimate --weights weights/rig.kkf --g 9.81 --json` (its last line's
`q_factor`, `q_factor_std`, `q_swing`). The envelope is
`docs/real-rigs/q_check.py`'s. A recording counts where the envelope's Q
lies in 30..1000 (real rigs'). The truth is `trainer_core::physics::
quality::q_of` of its effects. The row "not forced" leaves out the lab
set's forcing case (a drive at another frequency, which real rigs do not
have; the truth ignores it and its envelope is no exponential). With
`short`, the sets are shaped like the shared q4b recordings instead: 15
to 30 s of a 0.3 to 0.9 rad swing at 25 to 60 Hz, drag 0.004 to 0.03
1/rad, Coulomb up to 0.005 rad/s^2. Run from the repository root after a
release build:
    python3 docs/damping-labcheck/envelope_check.py 401 420 [short]
"""
import json, math, os, subprocess, sys, tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
K = os.path.join(ROOT, 'target/release/koopman')
GEN = ['--offset', '0.06', '--drag', '0.004,0.046', '--coulomb', '0,0.01', '--swings', '0.1,1.2',
       '--rates', '12,60', '--seconds', '60,600']
SHORT = ['--offset', '0.06', '--drag', '0.004,0.03', '--coulomb', '0,0.005', '--swings', '0.3,0.9',
         '--rates', '25,60', '--seconds', '15,30']


def _q_check():
    """q_check.py's definitions (its table is run below them)."""
    path = os.path.join(ROOT, 'docs/real-rigs/q_check.py')
    ns = {'__file__': path}
    exec(open(path).read().split('\nwith tempfile')[0], ns)
    return ns


envelope_q = _q_check()['envelope_q']


def equivalent_length(c):
    """A lab recording's equivalent simple length, m (a uniform rod's: 2/3 of it)."""
    return c['length'] * (2 / 3 if c['rig'] == 'rod' else 1)


def q_of(effects, omega, a):
    rate = 0.0
    for kind, c in effects:
        c = abs(c)
        rate += {'viscous': c * a / 2, 'drag': 4 / (3 * math.pi) * c * omega * a * a,
                 'coulomb': 2 / math.pi * c / omega}.get(kind, 0.0)
    return omega * a / (2 * rate) if rate > 0 else math.inf


def main(lo, hi, gen):
    rows, refused = [], []
    with tempfile.TemporaryDirectory() as d:
        for seed in range(lo, hi + 1):
            lab = os.path.join(d, f'lab{seed}')
            subprocess.run([K, 'generate', '--lab', str(seed), '--out', lab] + gen, capture_output=True, check=True)
            for c in json.load(open(os.path.join(lab, 'lab.json'))):
                out = os.path.join(d, 'x.csv')
                imp = subprocess.run([K, 'import', os.path.join(lab, c['file']), '--dt', '0.04', '--out', out],
                                     capture_output=True, text=True)
                if imp.returncode:
                    refused.append(imp.stderr.strip().replace(d + '/', ''))
                    continue
                est = subprocess.run([K, 'estimate', '--weights', os.path.join(ROOT, 'weights/rig.kkf'), out,
                                      '--g', '9.81', '--json'], capture_output=True, text=True, check=True)
                v = [json.loads(l) for l in est.stdout.splitlines()][-1]
                env = envelope_q(out)
                if not env or not 30 <= env[0] <= 1000:
                    continue
                omega = math.sqrt(9.81 / equivalent_length(c))
                rows.append((v.get('q_factor'), v.get('q_factor_std'), v.get('q_swing'), env,
                             lambda a, c=c, omega=omega: q_of(c['effects'], omega, a), c['case']))
    near = lambda x, y: x is not None and abs(x / y - 1) <= 0.25
    print(f'seeds {lo}..{hi}: {len(rows)} recordings with an envelope Q of 30..1000 over the last third; '
          f'{len(refused)} refused by the import: {refused}\n')
    print('| last third (its swing from, or its envelope) | n | Q within 25% of the envelope | envelope within 2 std | '
          'Q within 25% of the truth at its own swing | of the truth at the envelope\'s swing | '
          'envelope within 25% of the truth at its swing |')
    print('| --- | --- | --- | --- | --- | --- | --- |')
    groups = [(f'{low:.2f} rad', lambda r, low=low: r[3][1] >= low) for low in (0.0, 0.03, 0.05)]
    groups += [('the envelope within 25% of the truth', lambda r: near(r[3][0], r[4](r[3][1]))),
               ('not forced', lambda r: r[5] != 'forcing')]
    for name, keep in groups:
        h = [r[:5] for r in rows if keep(r)]
        n = max(1, len(h))
        pct = lambda k: f'{k} ({100 * k / n:.0f}%)'
        print(f'| {name} | {len(h)} | '
              f'{pct(sum(near(q, e[0]) for q, s, sw, e, t in h))} | '
              f'{pct(sum(q is not None and abs(q - e[0]) <= 2 * s for q, s, sw, e, t in h))} | '
              f'{pct(sum(near(q, t(sw)) for q, s, sw, e, t in h if sw))} | '
              f'{pct(sum(near(q, t(e[1])) for q, s, sw, e, t in h))} | '
              f'{pct(sum(near(e[0], t(e[1])) for q, s, sw, e, t in h))} |')


if __name__ == '__main__':
    main(int(sys.argv[1]), int(sys.argv[2]), SHORT if sys.argv[3:] == ['short'] else GEN)
