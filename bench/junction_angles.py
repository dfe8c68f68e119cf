#!/usr/bin/env python3
"""Where the bad triangles of a septa output are: near junction curves or not.

    bench/.venv/bin/python bench/junction_angles.py OUT_DIR [--min-angle 20]

Reads OUT_DIR/interfaces.ply and OUT_DIR/junctions.ply (needs numpy and
trimesh) and prints the share of triangles whose smallest angle is under
the bound, split by whether they touch a junction vertex, how many junction
vertices they have, where their smallest angle sits, and for those with two
junction vertices (a curve edge, usually) the ratio of that edge to the
other two. On the head volume (2026-12-03) 92 % of the bad triangles touched
a junction curve: the place to work on for the angle bound.
"""
import argparse
import collections

import numpy as np
import trimesh


def angles(p, q, r):
    u, w = q - p, r - p
    cos = (u * w).sum(1) / (np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1) + 1e-300)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out_dir")
    ap.add_argument("--min-angle", type=float, default=20.0)
    args = ap.parse_args()
    mesh = trimesh.load(f"{args.out_dir}/interfaces.ply", process=False)
    curves = trimesh.load(f"{args.out_dir}/junctions.ply", process=False)
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    key = lambda p: [tuple(r) for r in np.round(p, 5)]
    cv = np.asarray(curves.vertices)
    curve_keys = set(key(cv))
    on_curve = np.array([k in curve_keys for k in key(v)])
    degree = collections.Counter()
    for entity in curves.entities:
        for a, b in zip(entity.points[:-1], entity.points[1:]):
            degree[a] += 1
            degree[b] += 1
    corners = set(key(cv[[i for i, d in degree.items() if d != 2]]))
    is_corner = np.array([k in corners for k in key(v)])

    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    all_angles = np.stack([angles(a, b, c), angles(b, c, a), angles(c, a, b)], 1)
    bad = all_angles.min(1) < args.min_angle
    at = f[np.arange(len(f)), all_angles.argmin(1)]
    touch = on_curve[f].any(1)
    n_on = on_curve[f].sum(1)
    print(f"triangles {len(f)}, under {args.min_angle:g}°: {bad.sum()} ({bad.mean():.2%})")
    print(f"touching a junction vertex: {touch.mean():.1%} of all, {touch[bad].mean():.1%} of the bad")
    print(f"bad among those touching junctions {bad[touch].mean():.2%}, elsewhere {bad[~touch].mean():.2%}")
    print(f"bad touching a curve corner {is_corner[f].any(1)[bad].mean():.1%}; "
          f"smallest angle at a junction vertex {on_curve[at][bad].mean():.1%}, at a corner {is_corner[at][bad].mean():.1%}")
    for k in (1, 2):
        s = bad & (n_on == k)
        print(f"bad with {k} junction vertices: {s.sum()} ({s.sum() / max(bad.sum(), 1):.1%})")
    s = bad & (n_on == 2)
    if s.any():
        lengths = np.stack([np.linalg.norm(b - c, axis=1), np.linalg.norm(c - a, axis=1),
                            np.linalg.norm(a - b, axis=1)], 1)
        free = np.argmin(on_curve[f], 1)
        edge = lengths[np.arange(len(f)), free]
        ratio = (edge / ((lengths.sum(1) - edge) / 2))[s]
        print("  their junction edge / mean other edge, 10/25/50/75/90 %:",
              np.percentile(ratio, [10, 25, 50, 75, 90]).round(2))


if __name__ == "__main__":
    main()
