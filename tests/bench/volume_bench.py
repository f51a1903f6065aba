"""The references for gvd_volume_bench's volumes, on its inputs: scipy's 3D exact Euclidean
distance transform of the inputs voxelized (with the feature transform, the nearest site's
voxel, as gvd's volume has its ids), and OpenVDB's meshToVolume of the torus itself (Debian's
python3-openvdb, multithreaded through TBB) with a band wide enough to cover the whole box:
what a user would pick for a distance volume. Prints one line a case: tool, scene, voxels a
side, seconds (best of 3; OpenVDB's at 256, best of 2).
Usage: /usr/bin/python3 tests/bench/volume_bench.py"""
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


def torus_mesh(big=0.3, small=0.1, n=100, m=50):
    # The bench's torus itself: its 5,000 vertices and 10,000 triangles, as gvd's Torus()
    # makes them.
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    u, v = 2 * math.pi * i / n, 2 * math.pi * j / m
    xyz = np.stack([(big + small * np.cos(v)) * np.cos(u) + 0.5,
                    (big + small * np.cos(v)) * np.sin(u) + 0.5,
                    small * np.sin(v) + 0.5], axis=-1).reshape(-1, 3).astype(np.float32)
    at = lambda a, b: (a % n) * m + b % m
    tris = np.concatenate([np.stack([at(i, j), at(i + 1, j), at(i + 1, j + 1)], axis=-1),
                           np.stack([at(i, j), at(i + 1, j + 1), at(i, j + 1)], axis=-1)])
    return xyz, tris.reshape(-1, 3).astype(np.int32)


def mesh_to_volume(side):
    import pyopenvdb as vdb
    xyz, tris = torus_mesh()
    # Index (i, j, k) at the voxel centre ((i + 0.5) / side, ...), as gvd's grid.
    h = 1.0 / side
    transform = vdb.createLinearTransform(
        matrix=[[h, 0, 0, 0], [0, h, 0, 0], [0, 0, h, 0], [h / 2, h / 2, h / 2, 1]])
    # The farthest voxel of the box from the torus is a corner, 0.545 away: a band of
    # 0.55 side voxels covers the box.
    band = math.ceil(0.55 * side)
    best = math.inf
    for _ in range(3 if side <= 128 else 2):
        t = time.perf_counter()
        vdb.FloatGrid.createLevelSetFromPolygons(xyz, triangles=tris, transform=transform,
                                                 halfWidth=float(band))
        best = min(best, time.perf_counter() - t)
    return best


for side in (128, 256):
    print(f"scipy_edt points100k {side} {edt(points(100000), side):.3f} s")
    print(f"scipy_edt torus10k {side} {edt(torus(), side):.3f} s")
    print(f"openvdb_mesh_to_volume torus10k {side} {mesh_to_volume(side):.3f} s")
