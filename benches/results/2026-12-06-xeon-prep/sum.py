import json,sys
for f in sys.argv[1:]:
    d=json.load(open(f if f.endswith('.json') else f+'/summary.json'))
    tasks=['sidestep','turn','pallet_push','diagonal_balance','squat_jump','rearing','gallop','trot']
    rows={r['task']:r for r in d['tasks']}
    plain=[t for t in tasks[:7] if rows[t]['nominal']['met']]
    pushed=[t for t in tasks[:7] if rows[t]['pushed'] and rows[t]['pushed']['met']]
    print(f"{f}: plain {len(plain)}/7, pushed {len(pushed)}/7")
    for r in d['tasks']:
        for k in ('nominal','pushed'):
            n=r.get(k)
            if not n: continue
            miss=[f"{x['what']}: {x['value']}" for x in n["target"] if isinstance(x,dict) and not x["met"]] + [x for x in n["target"] if isinstance(x,str)]
            lat = f"lat p50 {n['latency_p50_s']*1e3:.2f} p99 {n['latency_p99_s']*1e3:.2f}" if 'latency_p50_s' in n else ''
            print(f"  {r['task']:17s} {k:8s} met={n['met']!s:5s} ticks={n['ticks']} failed={n['failed_ticks']} held={n['held_ticks']} p50={n['tick_time_p50_s']*1e3:.2f} {lat} | {'; '.join(miss)}")
