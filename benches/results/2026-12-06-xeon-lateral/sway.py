import json,sys
for d in sys.argv[1:]:
    t=json.load(open(d+'/trajectory.json'))
    k=t['knots']
    k0=k[0]; 
    def y(kn): 
        q=kn.get('q') or kn.get('base_position')
        return q[1] if 'q' in kn else kn['base_position'][1]
    ys=[y(kn) for kn in k]; zs=[(kn['q'][2] if 'q' in kn else kn['base_position'][2]) for kn in k]
    # sway amplitude in 2 s windows
    n=len(ys); w=n//4
    amps=[max(ys[i:i+w])-min(ys[i:i+w]) for i in range(0,n-w+1,w)]
    print(d, 'y range per 2 s', ' '.join('%.3f'%a for a in amps), 'min z %.3f'%min(zs), 'y end %.3f'%ys[-1])
