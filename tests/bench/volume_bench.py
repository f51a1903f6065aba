"""scipy's 3D exact Euclidean distance transform on the inputs of gvd_volume_bench, voxelized:
the reference a Python user would pick for a distance volume. Prints one line a case:
scene, voxels a side, seconds (best of 3), with the feature transform (nearest site's voxel)
as gvd's volume has its ids. Usage: /usr/bin/python3 tests/bench/volume_bench.py"""
import math
import time

import numpy as np
from scipy import ndimage


def points(n, seed=1):
    return np.random.default_rng(seed).random((n, 3))


def torus(big=0.3, small=0.1, n=400, m=200):
    # The bench's torus (R 0.3, r 0.1 at the box's centre), sampled 4x denser than its
    # 100 x 50 vertices so that every voxel it passes through is marked.
    u = np.linspace(0, 2 * math.pi, n, endpoint=False)[:, None]
    v = np.linspace(0, 2 * math.pi, m, endpoint=False)[None, :]
    x = (big + small * np.cos(v)) * np.cos(u) + 0.5
    y = (big + small * np.cos(v)) * np.sin(u) + 0.5
    z = small * np.sin(v) + 0.5 + 0 * u
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


def edt(samples, side):
    grid = np.ones((side, side, side), dtype=bool)
    idx = np.clip((samples * side).astype(int), 0, side - 1)
    grid[idx[:, 0], idx[:, 1], idx[:, 2]] = False
    best = math.inf
    for _ in range(3):
        t = time.perf_counter()
        ndimage.distance_transform_edt(grid, sampling=1.0 / side, return_indices=True)
        best = min(best, time.perf_counter() - t)
    return best


for side in (128, 256):
    print(f"scipy_edt points100k {side} {edt(points(100000), side):.3f} s")
    print(f"scipy_edt torus10k {side} {edt(torus(), side):.3f} s")
