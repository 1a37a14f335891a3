"""How fast the truth changes with direction: a dump made with SWEEP=1 holds, for each
random base pair, the pair again (another noise sample) and both directions turned by
2.5°, 5°, 10°, 20°. Prints the relative RMSE of each turned image against the base
image per block size, net of both images' own noise (from their halves).

python3 sweep.py DUMP.bin [DUMP.bin ...]
"""
import sys
import numpy as np
from load import load, blocks, rel

DEGS = [0, 2.5, 5, 10, 20]
for path in sys.argv[1:]:
    d = load(path)
    nx, ny, P, G = d['nx'], d['ny'], d['P'], 1 + len(DEGS)
    print(f'{path}: {P // G} base pairs; median over them')
    for bs in [1, 4, 8, 16, 32]:
        bl = lambda x: blocks(x, nx, ny, bs)
        noise = lambda k: rel(bl(d['A'][k]), bl(d['B'][k])) / 2
        row = []
        for i in range(len(DEGS)):
            v = []
            for base in range(0, P - G + 1, G):
                k = base + 1 + i
                e = rel(bl(d['M'][k]), bl(d['M'][base]))
                v.append(np.sqrt(max(e * e - noise(base) ** 2 - noise(k) ** 2, 0.0)))
            row.append(np.median(v))
        print(f'  {bs:2d}x{bs:<2d} blocks: ' + '  '.join(f'{g:4.1f}°: {100 * r:5.1f}%' for g, r in zip(DEGS, row)))

# A plot of the 4×4-block curves where matplotlib is installed: `PLOT=sweep.png`.
import os
if os.environ.get('PLOT'):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for path in sys.argv[1:]:
        d = load(path)
        nx, ny, P, G = d['nx'], d['ny'], d['P'], 1 + len(DEGS)
        bl = lambda x: blocks(x, nx, ny, 4)
        noise = lambda k: rel(bl(d['A'][k]), bl(d['B'][k])) / 2
        med = []
        for i in range(len(DEGS)):
            v = [np.sqrt(max(rel(bl(d['M'][b + 1 + i]), bl(d['M'][b])) ** 2 - noise(b) ** 2 - noise(b + 1 + i) ** 2, 0.0)) for b in range(0, P - G + 1, G)]
            med.append(100 * np.median(v))
        ax.plot(DEGS, med, marker='o', label=os.path.basename(path).split('_')[0])
    ax.axhline(10, color='k', ls='--', lw=1, label='the bar (10%)')
    ax.set_xlabel('both directions turned (degrees)')
    ax.set_ylabel('reference vs itself, 4×4 blocks (%)')
    ax.set_title('How fast the truth changes with angle (128×128×32)')
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.environ['PLOT'], dpi=110)
    print('wrote', os.environ['PLOT'])
