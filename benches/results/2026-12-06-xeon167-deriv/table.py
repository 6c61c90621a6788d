import json,re,sys
ops=["computeMinverse","computeABADerivatives","computeRNEADerivatives"]
def pin(f):
    return {json.loads(l)['robot']:json.loads(l) for l in open(f)}
def crit(f):
    t=open(f).read(); out={}
    for m in re.finditer(r"^(\w+)_urdf/(\w+)\s+time:\s+\[\S+ \S+ (\S+) (\S+)",t,re.M):
        val=float(m.group(3)); unit=m.group(4)
        out[(m.group(1),m.group(2))]=val*1000 if unit=='µs' else val
    return out
P=[pin(f'pinocchio-{i}.jsonl') for i in range(1,5)]
def pm(i,robot,op):
    x=P[i][robot]['timings_ns'][op]; return x['median']
N=[crit(f'native-{i}.txt') for i in range(1,4)]
Q=[crit(f'portable-{i}.txt') for i in range(1,4)]
for robot in ['hyq','a1']:
  for op in ops:
    pins=[pm(i,robot,op) for i in range(4)]
    nat=[N[i][(robot,op)] for i in range(3)]; por=[Q[i][(robot,op)] for i in range(3)]
    rn=[nat[i]/((pins[i]+pins[i+1])/2) for i in range(3)]; rp=[por[i]/((pins[i]+pins[i+1])/2) for i in range(3)]
    print(f"| {robot} | {op} | {', '.join(str(round(p)) for p in pins)} | {', '.join(str(round(x)) for x in nat)} | {min(rn):.2f}-{max(rn):.2f} | {', '.join(str(round(x)) for x in por)} | {min(rp):.2f}-{max(rp):.2f} |")
for i in range(4):
    print('pin',i+1,P[i]['hyq']['date_utc'],P[i]['hyq']['loadavg_before'])
