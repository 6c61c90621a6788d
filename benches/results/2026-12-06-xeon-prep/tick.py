import json,sys
# Timing rows of `legwork bench mpc` summaries: ticks, solve p50 / full-window p99, latency p50 / p99 (ms).
for f in sys.argv[1:]:
    d=json.load(open(f if f.endswith('.json') else f+'/summary.json'));t=d['timing'][0]
    print(f.split('/')[-1], 'ticks %d over %d | solve p50 %.2f p99fw %.2f | latency p50 %.2f p99 %.2f'%(t['ticks'],t['ticks_over_period'],t['tick_time_p50_s']*1e3,t['tick_time_p99_full_window_s']*1e3,t['latency_p50_s']*1e3,t['latency_p99_s']*1e3))
