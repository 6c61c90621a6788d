import json,sys
tasks=['sidestep','turn','pallet_push','diagonal_balance','squat_jump','rearing','gallop']
for f in sys.argv[1:]:
    d=json.load(open(f if f.endswith('.json') else f+'/summary.json'))
    rows={r['task']:r for r in d['tasks']}
    def miss(n): return [f"{x['what']}: {x['value']}" for x in n['target'] if isinstance(x,dict) and not x['met']]
    plain=[t for t in tasks if rows[t]['nominal']['met']]; pushed=[t for t in tasks if rows[t]['pushed'] and rows[t]['pushed']['met']]
    g=rows['gallop']; tr=rows['trot']
    def val(n,what): 
        for x in n['target']:
            if isinstance(x,dict) and x['what'].startswith(what): return x['value']
    lat=[rows[t]['nominal'].get('latency_p50_s',0)*1e3 for t in tasks]
    tick=[rows[t]['nominal']['tick_time_p50_s']*1e3 for t in tasks]
    print(f"{f}: plain {len(plain)}/7 pushed {len(pushed)}/7 | misses: " + '; '.join(f"{t} {k}: {', '.join(miss(rows[t][k]))}" for t in tasks for k in ('nominal','pushed') if rows[t][k] and not rows[t][k]['met']))
    print(f"   gallop x {val(g['nominal'],'base x')} / pushed {val(g['pushed'],'base x')}, low {val(g['nominal'],'lowest')} / {val(g['pushed'],'lowest')} | trot x {val(tr['nominal'],'base x')} low {val(tr['nominal'],'lowest')}; pushed x {val(tr['pushed'],'base x')} low {val(tr['pushed'],'lowest')} | latency p50 {min(lat):.2f}-{max(lat):.2f} ms, tick p50 {min(tick):.2f}-{max(tick):.2f} ms")
