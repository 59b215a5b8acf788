import json, collections, os
import sys; R=[json.loads(l) for l in open(sys.argv[1])]
print(len(R),'files')
cnt=collections.Counter(r['category'] for r in R); print(cnt)
fmtc=collections.Counter((r['category'],r['format']) for r in R if r['category']!='malformed'); 
# anomalies
print('\n== panic/timeout/nan/odd rc')
for r in R:
    for k,v in r['steps'].items():
        if v['panic'] or v['timeout'] or v['nan_stdout'] or v.get('nan_in_files') or v['rc'] not in (0,1,2):
            print(os.path.relpath(r['path'], os.environ.get('FUZZ_DIR', '.')), k, 'rc=%s to=%s panic=%s nan=%s %s'%(v['rc'],v['timeout'],v['panic'],v['nan_hits'],v.get('nan_in_files')), v['secs'])
print('\n== good/nearmiss: read wrong or refused')
ok=collections.Counter(); tot=collections.Counter()
for r in R:
    if not r['good']: continue
    t=r['truth']; key=r['format']; tot[key]+=1
    s=r['steps']; imp=s['import_dt04']
    if imp['rc']!=0:
        print('REFUSED', os.path.relpath(r['path'], os.environ.get('FUZZ_DIR', '.')), r['note'], {k:t[k] for k in ('L','rate','duration','amp')}, '|', imp['err_line'][:250]); continue
    ls=s.get('est_imp_json',{}).get('lengths',[])
    if not ls:
        print('NO-EST', os.path.relpath(r['path'], os.environ.get('FUZZ_DIR', '.')), s.get('est_imp_json',{}).get('err_line')); continue
    l0=ls[0]
    e=(l0['L']-t['L'])/t['L'] if l0['L'] else None
    fl=s.get('follow_json',{}).get('lengths',[])
    fe=(fl[-1]['L']-t['L'])/t['L'] if fl and fl[-1]['L'] else None
    bad = e is None or abs(e)>0.03
    if not bad: ok[key]+=1
    if bad or (fe is not None and abs(fe)>0.03):
        print('WRONG' if bad else 'follow-wrong', os.path.relpath(r['path'], os.environ.get('FUZZ_DIR', '.')), r['note'], {k:t[k] for k in ('L','Q','rate','duration','amp')}, 'L=%s (%+.1f%%) trust=%s %s rollouts=%d follow=%s'%(round(l0['L'],4) if l0['L'] else None, 100*e if e is not None else float('nan'), l0['trust'], l0['reasons'], len(ls), ('%+.1f%%'%(100*fe)) if fe is not None else None))
print('\nwithin 3%:', sum(ok.values()),'of', sum(tot.values()))
for k in tot: print('  %-28s %d/%d'%(k,ok[k],tot[k]))
print('\n== malformed accepted (rc 0) with truth: length check; without truth: listed')
for r in R:
    if r['good']: continue
    s=r['steps']; imp=s['import_dt04']
    if imp['rc']==0:
        ls=s.get('est_imp_json',{}).get('lengths',[])
        L=[ (round(x['L'],3) if x['L'] else None, x['trust']) for x in ls]
        tr=r['truth']['L'] if r['truth'] else None
        flag=''
        if tr and ls and ls[0]['L'] and abs(ls[0]['L']-tr)/tr>0.03: flag='!!OFF'
        print('  ACCEPT', os.path.relpath(r['path'], os.environ.get('FUZZ_DIR', '.')), 'truth', tr, L, flag)
print('\n== malformed refused: message')
for r in R:
    if r['good']: continue
    imp=r['steps']['import_dt04']
    if imp['rc']!=0:
        print('  ', os.path.relpath(r['path'], os.environ.get('FUZZ_DIR', '.')), r['args'], '|', imp['err_line'][:220])
