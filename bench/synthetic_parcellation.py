#!/usr/bin/env python3
"""A parcellation-like label volume for trying septa where no real one is at hand.

An ellipsoid split into N regions (Voronoi cells of random seeds, their borders
warped by smooth noise), with salt noise inside (each voxel, with probability P,
takes a random region's label): thin, irregular, many-junction geometry like an
atlas parcellation, plus isolated voxels on every interface, which is what
showed septa's junction loops collapsing under smoothing (BENCHMARKS.md, issue 13).

    python3 bench/synthetic_parcellation.py OUT.nii.gz [--shape 181 217 181] [--regions 116]
        [--salt 0.005] [--seed 1]

Needs numpy, scipy and nibabel (pip install numpy scipy nibabel).
"""
import argparse

import nibabel as nib
import numpy as np
from scipy import ndimage as ndi
from scipy.spatial import cKDTree


def parcellation(shape, regions, salt, seed):
    rng = np.random.default_rng(seed)
    z, y, x = np.meshgrid(*[np.arange(n, dtype=np.float32) for n in shape], indexing="ij")
    c = np.array(shape) / 2
    r = np.array(shape) * np.array([80 / 181, 100 / 217, 80 / 181])
    inside = ((z - c[0]) / r[0]) ** 2 + ((y - c[1]) / r[1]) ** 2 + ((x - c[2]) / r[2]) ** 2 < 1
    seeds = rng.uniform([10, 10, 10], np.array(shape) - 11, size=(regions, 3))
    scale = shape[0] / 181
    warp = [ndi.gaussian_filter(rng.standard_normal(shape).astype(np.float32), 6 * scale) * 60 * scale
            for _ in range(3)]
    coords = np.stack([z + warp[0], y + warp[1], x + warp[2]], -1).reshape(-1, 3)
    _, nearest = cKDTree(seeds).query(coords)
    labels = (nearest + 1).reshape(shape)
    labels[~inside] = 0
    flip = (rng.random(shape) < salt) & inside
    labels[flip] = rng.integers(1, regions + 1, flip.sum())
    return labels.astype(np.int16)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("output")
    ap.add_argument("--shape", type=int, nargs=3, default=[181, 217, 181])
    ap.add_argument("--regions", type=int, default=116)
    ap.add_argument("--salt", type=float, default=0.005)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    labels = parcellation(tuple(a.shape), a.regions, a.salt, a.seed)
    nib.save(nib.Nifti1Image(labels, np.eye(4)), a.output)
    print(f"{a.output}: {labels.shape}, {len(np.unique(labels))} labels")


if __name__ == "__main__":
    main()
