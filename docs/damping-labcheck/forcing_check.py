"""The lab sets' driven case (a drive at another frequency, which the
envelope check leaves out as "not forced"): the length `koopman estimate
--weights weights/rig.kkf --g 9.81 --json` reads at the end, against the
string's (a rod's equivalent, 2/3 of it), and its verdict. The sets are
envelope_check.py's. Run from the repository root after a release build:
    python3 docs/damping-labcheck/forcing_check.py 521 560
"""
import importlib.util, json, os, subprocess, sys, tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
spec = importlib.util.spec_from_file_location('envelope_check', os.path.join(HERE, 'envelope_check.py'))
ENV = importlib.util.module_from_spec(spec)
spec.loader.exec_module(ENV)


def main(lo, hi):
    n = trusted = wrong_trusted = 0
    print('| seed | rig | true length (m) | read (m) | error | verdict | drive (rad/s^2 at rad/s) |')
    print('| --- | --- | --- | --- | --- | --- | --- |')
    with tempfile.TemporaryDirectory() as d:
        for seed in range(lo, hi + 1):
            lab = os.path.join(d, f'lab{seed}')
            subprocess.run([ENV.K, 'generate', '--lab', str(seed), '--out', lab] + ENV.GEN,
                           capture_output=True, check=True)
            for c in json.load(open(os.path.join(lab, 'lab.json'))):
                if c['case'] != 'forcing':
                    continue
                out = os.path.join(d, 'x.csv')
                if subprocess.run([ENV.K, 'import', os.path.join(lab, c['file']), '--dt', '0.04', '--out', out],
                                  capture_output=True).returncode:
                    print(f'| {seed} | {c["rig"]} | refused by the import | | | | |')
                    continue
                est = subprocess.run([ENV.K, 'estimate', '--weights', os.path.join(ENV.ROOT, 'weights/rig.kkf'),
                                      out, '--g', '9.81', '--json'], capture_output=True, text=True, check=True)
                v = [json.loads(l) for l in est.stdout.splitlines()][-1]
                true = ENV.equivalent_length(c)
                err = v['params'][0] / true - 1
                n += 1
                trusted += v['trust'] == 'trusted'
                wrong_trusted += v['trust'] == 'trusted' and abs(err) > 0.05
                amp, w = c['forcing']
                print(f'| {seed} | {c["rig"]} | {true:.3f} | {v["params"][0]:.3f} | {100 * err:+.1f}% | {v["trust"]} | '
                      f'{amp:.2f} at {w:.2f} |')
    print(f'\nseeds {lo}..{hi}: {n} driven recordings, {trusted} trusted, {wrong_trusted} of them more than 5% off')


if __name__ == '__main__':
    main(int(sys.argv[1]), int(sys.argv[2]))
