# Per tracking weight and latency: squat_jump's base x / y at the end (`python3 weights_table.py`)
# or the gallop's x at the end / lowest base (`python3 weights_table.py gallop`), plain | pushed
# (docs/experiments/mpc-21.md).
import json, glob, os, sys, collections
here = os.path.dirname(os.path.abspath(__file__))
folder = sys.argv[1] if len(sys.argv) > 1 else 'squat_jump'
rows = collections.defaultdict(dict)
for f in sorted(glob.glob(os.path.join(here, folder, '*.json'))):
    weights, latency = os.path.basename(f)[:-5].split('-')
    cells = []
    task = json.load(open(f))['tasks'][0]
    for kind in ('nominal', 'pushed'):
        n = task[kind]
        figures = [x['value'].split()[0] for x in n['target'] if isinstance(x, dict) and ('at the end' in x['what'] or 'lowest' in x['what'])]
        shown = figures[:2] if folder == 'squat_jump' else [figures[0], figures[-1]]
        cells.append(('ok ' if n['met'] else 'MISSED ') + ' / '.join(shown))
    rows[weights][latency] = ' | '.join(cells)
for weights in rows:
    print(weights, '(plain | pushed)')
    for latency in sorted(rows[weights], key=float):
        print('  ', latency, rows[weights][latency])
