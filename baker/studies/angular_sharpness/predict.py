"""What a per-texel function of (ω_i, ω_o) learned from the training pairs predicts at
other pairs: a dump made without SWEEP holds the 40 default training pairs, then random
pairs in the 60° cap (the last 40 are the test set, those ≥ 5° from every training pair
kept). Per texel: ridge regression on 10 global angular features; and kernel
interpolation of the training images (Gaussian in angle, 15°). Relative RMSE over 4×4
blocks, mean over the test pairs, for growing training sets (the extra training pairs are
random ones).

python3 predict.py DUMP.bin
"""
import sys
import numpy as np
from load import load, blocks, rel, ang

d = load(sys.argv[1])
nx, ny, M, wi, wo, P = d['nx'], d['ny'], d['M'], d['wi'], d['wo'], d['P']
Mb = blocks(M, nx, ny)
hv = wi + wo
hv /= np.linalg.norm(hv, axis=1, keepdims=True)
F = np.stack([np.ones(P), wi[:, 0], wi[:, 1], wo[:, 0], wo[:, 1], wi[:, 2], wo[:, 2], hv[:, 0] ** 2, hv[:, 1] ** 2, hv[:, 0] * hv[:, 1]], 1)
te = np.arange(P - 40, P)
for ntr in [24, 40, 60, P - 40]:
    tr = np.arange(ntr)
    D = np.array([[max(ang(wi[p], wi[q]), ang(wo[p], wo[q])) for q in tr] for p in te])
    tt = te[D.min(1) >= 5]
    C = np.linalg.solve(F[tr].T @ F[tr] + 0.1 * np.eye(F.shape[1]), F[tr].T @ M[tr].reshape(ntr, -1))
    pr, ptr = (F[tt] @ C).reshape(len(tt), -1, 3), (F[tr] @ C).reshape(ntr, -1, 3)
    e = np.mean([rel(blocks(pr[i], nx, ny), Mb[p]) for i, p in enumerate(tt)])
    etr = np.mean([rel(blocks(ptr[i], nx, ny), Mb[p]) for i, p in enumerate(tr)])
    W = np.exp(-np.array([[ang(wi[p], wi[q]) ** 2 + ang(wo[p], wo[q]) ** 2 for q in tr] for p in tt]) / (2 * 15 ** 2))
    W /= W.sum(1, keepdims=True)
    ek = np.mean([rel(blocks(x, nx, ny), Mb[p]) for x, p in zip(np.einsum('pq,qtc->ptc', W, M[tr]), tt)])
    print(f'{ntr:3d} training pairs, {len(tt)} test: ridge train {100 * etr:4.1f}% test {100 * e:4.1f}% | kernel test {100 * ek:4.1f}% | nearest training pair, median {np.median(D.min(1)):.1f}°')
