#!/bin/bash
# usage: plansweep.sh NAME SET-ARGS...
name=$1; shift
out=/tmp/s54/ps/$name
./target/release/legwork solve gallop "$@" --out $out > $out.log 2>&1
/work/main/.venv-mujoco/bin/python - $out $name <<'PY'
import json, sys, numpy as np
out, name = sys.argv[1], sys.argv[2]
d = json.load(open(out + '/trajectory.json')); s = d['summary']
Q = np.array([k['q'] for k in d['knots']]); V = np.array([k['v'] for k in d['knots']])
knee = np.abs(np.degrees(Q[:, 7 + np.array([2, 5, 8, 11])]))
t = np.array([k['t'] for k in d['knots']])
mid = (t > 0.8) & (t < 2.6)
p = {r['what']: r['value'] + ('' if r['met'] else '!') for r in s['target']['plan']}
print(f"{name:28s} x {p['base x at the end']:10s} y {p['base y at the end']:9s} lo {p['lift-offs per foot']:12s} knee min {knee.min():4.0f} p5 {np.percentile(knee,5):4.0f} | z mid {Q[mid,2].mean():.3f} end {Q[-1,2]:.3f} vz end {V[-1,2]:+.2f} | viol {s['constraint_violation']['friction']:.2f} {s['constraint_violation']['joint_limit']:.3f} | {s['solve_time_s']:.1f} s")
PY
