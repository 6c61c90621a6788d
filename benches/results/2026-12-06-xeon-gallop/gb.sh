#!/bin/bash
# usage: gb.sh NAME TASKS LATENCY [extra]
name=$1; tasks=$2; L=$3; shift 3
out=/tmp/s54/gb/$name-L$L
./target/release/legwork bench mpc --sim mujoco --tasks $tasks --knot-dt 0.001 --horizon 0.2 --substeps 4 --latency $L --feedback physical --tracking 10 --horizons 0.2 --thread-counts 2 "$@" --json --out $out > $out.log 2>&1
/work/main/.venv-mujoco/bin/python - $out/summary.json $name $L <<'PY'
import json,sys
d=json.load(open(sys.argv[1]))
for r in d['tasks']:
    for k in ('nominal','pushed'):
        n=r.get(k)
        if not n: continue
        miss=[f"{x['what']}: {x['value']}" for x in n["target"] if isinstance(x,dict) and not x["met"]] + [x for x in n["target"] if isinstance(x,str)]
        lat = f"lat p50 {n['latency_p50_s']*1e3:.2f}" if 'latency_p50_s' in n else ''
        print(f"{sys.argv[2]} L={sys.argv[3]} {r['task']:12s} {k:8s} met={n['met']!s:5s} p50={n['tick_time_p50_s']*1e3:.2f} {lat} | {'; '.join(miss)}")
PY
