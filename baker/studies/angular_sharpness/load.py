"""Reader of `angular_dump`'s output (baker/examples/angular_dump.rs) and the metric.

The file: u32 pairs, nx, ny; f32 heights (nx·ny, voxels), normals and tangents (nx·ny·3
each); per pair f32 wi[3], wo[3], half A and half B (nx·ny·3 each, texel order, x
fastest). `M` is the mean of the halves.
"""
import numpy as np


def load(path):
    raw = np.fromfile(path, dtype='<f4')
    P, nx, ny = (int(v) for v in raw[:3].view('<u4'))
    T = nx * ny
    o = 3
    h = raw[o:o + T]; o += T
    nrm = raw[o:o + 3 * T].reshape(T, 3); o += 3 * T
    tan = raw[o:o + 3 * T].reshape(T, 3); o += 3 * T
    wi, wo = np.zeros((P, 3)), np.zeros((P, 3))
    A, B = np.zeros((P, T, 3), np.float32), np.zeros((P, T, 3), np.float32)
    for p in range(P):
        wi[p], wo[p] = raw[o:o + 3], raw[o + 3:o + 6]; o += 6
        A[p] = raw[o:o + 3 * T].reshape(T, 3); o += 3 * T
        B[p] = raw[o:o + 3 * T].reshape(T, 3); o += 3 * T
    return dict(P=P, nx=nx, ny=ny, h=h, n=nrm, t=tan, wi=wi, wo=wo, A=A, B=B, M=0.5 * (A + B))


def blocks(img, nx, ny, b=4):
    """Means over b×b blocks of texel-ordered images (..., T, 3)."""
    s = img.shape[:-2]
    return img.reshape(*s, ny // b, b, nx // b, b, 3).mean(axis=(-4, -2))


def rel(a, b):
    """Relative RMSE ‖a − b‖₂ / ‖b‖₂ over linear RGB (the held-out figure)."""
    return np.sqrt(((a - b) ** 2).sum() / (b ** 2).sum())


def ang(a, b):
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1, 1)))
