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
