import json,sys
tasks=['sidestep','turn','pallet_push','diagonal_balance','squat_jump','rearing','gallop','trot']
for f in sys.argv[1:]:
    d=json.load(open(f+'/summary.json'))
    rows={r['task']:r for r in d['tasks']}
    plain=[t for t in tasks[:7] if rows[t]['nominal']['met']]
    pushed=[t for t in tasks[:7] if rows[t]['pushed'] and rows[t]['pushed']['met']]
    p50=[rows[t]['nominal']['tick_time_p50_s']*1e3 for t in tasks]
    print(f"{f}: plain {len(plain)}/7, pushed {len(pushed)}/7; missed plain {[t for t in tasks[:7] if t not in plain]}, pushed {[t for t in tasks[:7] if t not in pushed]}; tick p50 {min(p50):.2f}-{max(p50):.2f} ms")
