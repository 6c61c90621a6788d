import json,sys
d=json.load(open(sys.argv[1]))
t=d['timing'][0] if d.get('timing') else None
if t: print('timing', d.get('timing_task'), 'p50 %.2f p99fw %.2f failed %d'%(t['tick_time_p50_s']*1e3,t['tick_time_p99_full_window_s']*1e3,t['failed_ticks']))
for r in d['tasks']:
    for k in ('nominal','pushed'):
        n=r.get(k)
        if not n: continue
        miss=[f"{x['what']}: {x['value']} (req {x['required']})" for x in n["target"] if isinstance(x,dict) and not x["met"]] + [x for x in n["target"] if isinstance(x,str)]
        print(f"{r['task']:17s} {k:8s} met={n['met']!s:5s} stopped={n['stopped']} failed={n['failed_ticks']} held={n['held_ticks']} p50={n['tick_time_p50_s']*1e3:.2f} p99={n['tick_time_p99_s']*1e3:.2f} | {'; '.join(miss)}")
