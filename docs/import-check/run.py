#!/usr/bin/env python3
"""Runs koopman import / estimate / estimate --follow over $FUZZ_MANIFEST.
Writes $FUZZ_RESULTS (one line per file, each command's outcome) and logs
under $FUZZ_DIR/logs (docs/import-check/run.sh sets them). Usage: run.py
[substring filter]"""
import json, os, re, resource, subprocess, sys, time

ROOTDIR = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
K = os.path.join(ROOTDIR, 'target/release/koopman')
W = 'weights/rig.kkf'
OUT = os.path.join(os.environ['FUZZ_DIR'], 'out')
LOG = os.path.join(os.environ['FUZZ_DIR'], 'logs')
TIMEOUT = 60
NANRE = re.compile(r'(?<![A-Za-z_])(NaN|nan|-?inf|-?Infinity|-?infinity)(?![A-Za-z_])')


def limit():
    resource.setrlimit(resource.RLIMIT_AS, (6 << 30, 6 << 30))


def run(cmd, tag, stdin=None):
    t0 = time.time()
    try:
        p = subprocess.run(cmd, cwd=ROOTDIR, capture_output=True, timeout=TIMEOUT,
                           preexec_fn=limit, stdin=stdin or subprocess.DEVNULL)
        rc, so, se, to = p.returncode, p.stdout, p.stderr, False
    except subprocess.TimeoutExpired as e:
        rc, so, se, to = None, e.stdout or b'', e.stderr or b'', True
    dt = time.time() - t0
    with open(os.path.join(LOG, tag + '.out'), 'wb') as f:
        f.write(so[:2_000_000])
    with open(os.path.join(LOG, tag + '.err'), 'wb') as f:
        f.write(se[:2_000_000])
    so_t = so.decode('utf-8', 'replace')
    se_t = se.decode('utf-8', 'replace')
    return dict(rc=rc, timeout=to, secs=round(dt, 2),
                panic=('panicked' in se_t or 'RUST_BACKTRACE' in se_t),
                nan_stdout=bool(NANRE.search(so_t)),
                nan_hits=sorted(set(m.group(0) for m in NANRE.finditer(so_t)))[:5],
                err_line=next((l for l in se_t.splitlines() if l.lower().startswith('error')), se_t.strip().splitlines()[-1] if se_t.strip() else '')[:400],
                stderr_tail=se_t.strip()[-600:],
                stdout=so_t if len(so_t) < 200_000 else so_t[-200_000:])


def lengths_from_json(stdout):
    res = []
    for l in stdout.splitlines():
        l = l.strip()
        if not l.startswith('{'):
            continue
        try:
            j = json.loads(l.replace('NaN', 'null').replace('-inf', 'null').replace('inf', 'null'))
        except Exception:
            continue
        res.append(dict(rollout=j.get('rollout'), steps=j.get('steps'), L=(j.get('params') or [None])[0],
                        period_L=j.get('period_length'), trust=j.get('trust'), reasons=j.get('trust_reasons'),
                        angle_from=j.get('angle_from')))
    return res


def main():
    flt = sys.argv[1] if len(sys.argv) > 1 else ''
    os.makedirs(OUT, exist_ok=True)
    os.makedirs(LOG, exist_ok=True)
    man = json.load(open(os.environ['FUZZ_MANIFEST']))
    rf = open(os.environ['FUZZ_RESULTS'], 'w')
    for m in man:
        if flt and flt not in m['path']:
            continue
        path, args = m['path'], m['args']
        fid = m['category'] + '__' + os.path.basename(path)
        o1 = os.path.join(OUT, fid + '.dt05.csv')
        o2 = os.path.join(OUT, fid + '.csv')
        steps = {}
        steps['import'] = run([K, 'import', path, '--out', o1] + args, fid + '.import')
        steps['import_dt04'] = run([K, 'import', path, '--dt', '0.04', '--out', o2] + args, fid + '.import04')
        steps['est_raw'] = run([K, 'estimate', '--weights', W, path] + args, fid + '.estraw')
        steps['est_raw_json'] = run([K, 'estimate', '--weights', W, '--json', path] + args, fid + '.estrawjson')
        if steps['import_dt04']['rc'] == 0 and os.path.exists(o2):
            steps['est_imp'] = run([K, 'estimate', '--weights', W, '--g', '9.81', o2], fid + '.estimp')
            steps['est_imp_json'] = run([K, 'estimate', '--weights', W, '--g', '9.81', '--json', o2], fid + '.estimpjson')
            # NaN / inf in the imported CSV or its sidecar
            for o in (o2, o2[:-4] + '.json'):
                if os.path.exists(o):
                    txt = open(o, encoding='utf-8', errors='replace').read()
                    hits = NANRE.findall(txt)
                    if hits:
                        steps['import_dt04'].setdefault('nan_in_files', []).append((o, sorted(set(hits))[:5]))
        if not m['format'].startswith(('xlsx', 'zip')) and not path.endswith(('.xlsx', '.zip')):
            steps['follow_json'] = run([K, 'estimate', '--weights', W, '--g', '9.81', '--json', '--follow', path,
                                        '--idle', '0.3'] + args, fid + '.follow')
        rec = dict(m)
        rec['steps'] = {}
        for k, v in steps.items():
            v = dict(v)
            so = v.pop('stdout')
            if k in ('est_imp_json', 'follow_json', 'est_raw_json'):
                ls = lengths_from_json(so)
                if k == 'follow_json' and ls:
                    ls = ls[-1:]
                v['lengths'] = ls
            rec['steps'][k] = v
        rf.write(json.dumps(rec) + '\n')
        rf.flush()
        bad = [k for k, v in steps.items() if v['panic'] or v['timeout'] or v['nan_stdout'] or v.get('nan_in_files') or (v['rc'] not in (0, 1, 2))]
        Ls = [x['L'] for x in rec['steps'].get('est_imp_json', {}).get('lengths', [])]
        print('%-60s imp=%s est=%s %s %s' % (fid, steps['import_dt04']['rc'], steps.get('est_imp_json', {}).get('rc'),
                                           ('L=%s' % [round(x, 3) if x else x for x in Ls]) if Ls else '',
                                           ('!!' + ','.join(bad)) if bad else ''), flush=True)


if __name__ == '__main__':
    main()
