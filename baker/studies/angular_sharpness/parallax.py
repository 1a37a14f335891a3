"""Is the change with ω_o parallax? For pairs of images with ω_i within 5° and ω_o 8–30°
apart (each normalized by its mean), the 4×4-block difference as is, after the best
global shift of one image (±2 texels, half-texel steps, periodic), and after the best
depth per 8×8 region (the shift along the parallax direction, −6…6 texels of depth: an
oracle that picks with the answer).

python3 parallax.py DUMP.bin
"""
import sys
import numpy as np
from load import load, rel, ang

d = load(sys.argv[1])
nx, ny, P, wi, wo = d['nx'], d['ny'], d['P'], d['wi'], d['wo']
img = d['M'].reshape(P, ny, nx, 3)


def shift(im, dx, dy):
    ix, fx, iy, fy = int(np.floor(dx)), dx - np.floor(dx), int(np.floor(dy)), dy - np.floor(dy)
    r = lambda a, sx, sy: np.roll(np.roll(a, -sy, 0), -sx, 1)
    return (1 - fx) * (1 - fy) * r(im, ix, iy) + fx * (1 - fy) * r(im, ix + 1, iy) + (1 - fx) * fy * r(im, ix, iy + 1) + fx * fy * r(im, ix + 1, iy + 1)


b4 = lambda im: im.reshape(ny // 4, 4, nx // 4, 4, 3).mean((1, 3))
rows = []
for p in range(P):
    for q in range(p + 1, P):
        if ang(wi[p], wi[q]) >= 5 or not 8 < ang(wo[p], wo[q]) < 30:
            continue
        a, b = img[p] / img[p].mean(), img[q] / img[q].mean()
        B = b4(b)
        glob = min(rel(b4(shift(a, dx, dy)), B) for dx in np.arange(-2, 2.01, 0.5) for dy in np.arange(-2, 2.01, 0.5))
        dxy = wo[q][:2] / wo[q][2] - wo[p][:2] / wo[p][2]
        cands = [b4(shift(a, s * dxy[0], s * dxy[1])) for s in np.arange(-6, 6.01, 0.5)]
        out = np.zeros_like(B)
        for by in range(0, ny // 4, 2):
            for bx in range(0, nx // 4, 2):
                k = int(np.argmin([((c[by:by + 2, bx:bx + 2] - B[by:by + 2, bx:bx + 2]) ** 2).sum() for c in cands]))
                out[by:by + 2, bx:bx + 2] = cands[k][by:by + 2, bx:bx + 2]
        rows.append((rel(b4(a), B), glob, rel(out, B)))
r = np.array(rows)
print(f'{len(r)} image pairs, median: as is {100 * np.median(r[:, 0]):.1f}%, best global shift {100 * np.median(r[:, 1]):.1f}%, best depth per 8x8 region {100 * np.median(r[:, 2]):.1f}%')
