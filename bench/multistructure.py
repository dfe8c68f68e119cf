#!/usr/bin/env python3
"""A 256³ label volume with the structures real segmentations are hard on, side by side.

Eight labels (0 background): three nested shells, a tube that runs through them, a
cluster of small touching spheres, a one-voxel sheet, a block with salt noise (each
voxel, with probability P, takes a random label) and a voxel checkerboard of two
labels. Each is a failure mode seen on real data: thin shells (cortex), a thin tube
(vessels), islands touching each other (lesions), a one-voxel wall, noise on every
interface (automatic segmentations), and the worst case of critical edges.

    python3 bench/multistructure.py OUT.nii.gz [--size 256] [--salt 0.2] [--seed 1]

Needs numpy and nibabel (bench/requirements.txt).
"""
import argparse

import nibabel as nib
import numpy as np


def multistructure(n, salt, seed):
    rng = np.random.default_rng(seed)
    s = n / 256
    z, y, x = np.meshgrid(*[np.arange(n, dtype=np.float32) for _ in range(3)], indexing="ij")
    labels = np.zeros((n, n, n), np.uint8)

    # nested shells: 1 outside 2 outside 3
    r = np.sqrt((z - 96 * s) ** 2 + (y - 128 * s) ** 2 + (x - 96 * s) ** 2)
    labels[r < 60 * s] = 1
    labels[r < 52 * s] = 2
    labels[r < 40 * s] = 3

    # a tube (label 4) on a bent path through the shells and out of them
    t = np.linspace(0, 1, 400)
    path = np.stack([96 + 90 * (t - 0.5), 128 + 40 * np.sin(3 * t), 40 + 170 * t], -1) * s
    for p in path:
        lo = np.maximum(np.floor(p - 7 * s).astype(int), 0)
        hi = np.minimum(np.ceil(p + 7 * s).astype(int) + 1, n)
        sl = tuple(slice(a, b) for a, b in zip(lo, hi))
        d2 = (z[sl] - p[0]) ** 2 + (y[sl] - p[1]) ** 2 + (x[sl] - p[2]) ** 2
        labels[sl][d2 < (5 * s) ** 2] = 4

    # a cluster of small spheres (label 5), radius 1.5-3.5 voxels, many touching
    centres = rng.normal([190 * s, 190 * s, 70 * s], 12 * s, size=(60, 3))
    radii = rng.uniform(1.5, 3.5, 60) * max(s, 0.5)
    for c, rad in zip(centres, radii):
        lo = np.maximum(np.floor(c - rad - 1).astype(int), 0)
        hi = np.minimum(np.ceil(c + rad + 1).astype(int) + 1, n)
        sl = tuple(slice(a, b) for a, b in zip(lo, hi))
        d2 = (z[sl] - c[0]) ** 2 + (y[sl] - c[1]) ** 2 + (x[sl] - c[2]) ** 2
        labels[sl][d2 < rad**2] = 5

    # a one-voxel sheet (label 6), bent, crossing the tube's path
    plane = (np.abs(x - (200 * s + 10 * s * np.sin(y / (20 * s)))) < 0.5) & (y > 60 * s) & (y < 200 * s)
    plane &= (z > 40 * s) & (z < 180 * s)
    labels[plane] = 6

    # a block of label 7 with salt noise: any of the eight labels at random
    b = slice(int(180 * s), int(220 * s))
    block = np.full((b.stop - b.start,) * 3, 7, np.uint8)
    flip = rng.random(block.shape) < salt
    block[flip] = rng.integers(0, 8, flip.sum())
    labels[b, int(20 * s) : int(20 * s) + block.shape[1], b] = block

    # a voxel checkerboard of labels 2 and 5
    c = slice(int(20 * s), int(44 * s))
    zz, yy, xx = np.meshgrid(*[np.arange(c.stop - c.start)] * 3, indexing="ij")
    labels[c, int(200 * s) : int(200 * s) + (c.stop - c.start), c] = np.where((zz + yy + xx) % 2 == 0, 2, 5)
    return labels


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--salt", type=float, default=0.2)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    labels = multistructure(a.size, a.salt, a.seed)
    # (z, y, x) in numpy; NIfTI wants x first
    img = nib.Nifti1Image(np.ascontiguousarray(labels.transpose(2, 1, 0)), np.eye(4))
    nib.save(img, a.out)
    counts = np.bincount(labels.ravel(), minlength=8)
    print(f"{a.out}: {a.size}³, voxels per label {counts.tolist()}")


if __name__ == "__main__":
    main()
