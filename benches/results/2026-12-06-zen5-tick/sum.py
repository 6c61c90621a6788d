import json,sys,glob,re
rows={}
for f in sorted(glob.glob(sys.argv[1]+'*/summary.json')):
    d=json.load(open(f)); t=d['timing'][0]; n=d['tasks'][0]['nominal']
    name=f.split('/')[-2]; kind=re.sub(r'-\d+$','',name)
    rows.setdefault(kind,[]).append((name,t['tick_time_p50_s']*1e3,t['tick_time_p99_full_window_s']*1e3,t.get('tick_time_max_s',0)*1e3,t['failed_ticks'],n['met']))
for kind,rs in rows.items():
    ok=sum(1 for r in rs if r[2]<=5.0)
    print(f"{kind}: {ok} of {len(rs)} runs fw-p99 <= 5 ms; p50 {min(r[1] for r in rs):.2f}-{max(r[1] for r in rs):.2f}; fw-p99 {min(r[2] for r in rs):.2f}-{max(r[2] for r in rs):.2f}; max {min(r[3] for r in rs):.1f}-{max(r[3] for r in rs):.1f}; failed {sum(r[4] for r in rs)}; met {sum(r[5] for r in rs)}/{len(rs)}")
    for r in rs: print('   ',r[0],'p50 %.2f fwp99 %.2f max %.2f failed %d met %s'%r[1:])
