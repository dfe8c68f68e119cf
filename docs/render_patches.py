"""Render septa interface patches (interfaces.ply) to a PNG, one colour per
patch, the front half cut away so that inner walls and junctions show.

    pip install matplotlib numpy plyfile
    python3 docs/render_patches.py OUT.png DIR1:TITLE1 [DIR2:TITLE2 ...]

Each DIR is a `septa extract` output directory. Used for the README picture
(docs/heart.png); not part of septa itself.
"""
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from plyfile import PlyData


def load(path):
    ply = PlyData.read(path)
    v = ply["vertex"]
    pos = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(float)
    f = ply["face"]
    tris = np.stack(f["vertex_indices"]).astype(int)
    pair = np.stack([f["label_a"], f["label_b"]], axis=1)
    return pos, tris, pair


def draw(ax, pos, tris, pair, title, colours, centre):
    p = pos[tris]
    cent = p.mean(axis=1)
    keep = cent[:, 1] > centre[1]  # cut away the anterior half (LPS: y posterior)
    p, pair = p[keep], pair[keep]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-12
    light = np.array([0.3, -0.6, 0.75])
    light /= np.linalg.norm(light)
    shade = 0.35 + 0.65 * np.abs(n @ light)
    base = np.array([colours[tuple(k)] for k in pair])
    face = np.clip(base * shade[:, None], 0, 1)
    coll = Poly3DCollection(p, facecolors=face, edgecolors=(0, 0, 0, 0.25) if len(p) < 60000 else "none", linewidths=0.15)
    ax.add_collection3d(coll)
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    mid, r = (lo + hi) / 2, (hi - lo).max() * 0.36
    ax.set_xlim(mid[0] - r, mid[0] + r)
    ax.set_ylim(mid[1] - r, mid[1] + r)
    ax.set_zlim(mid[2] - r, mid[2] + r)
    ax.view_init(elev=20, azim=-60)
    ax.set_axis_off()
    ax.set_title(f"{title}\n{len(tris):,} triangles", fontsize=10)


def main():
    out, runs = sys.argv[1], sys.argv[2:]
    meshes = [(load(f"{d}/interfaces.ply"), t) for d, t in (r.split(":", 1) for r in runs)]
    pairs = sorted({tuple(k) for (m, _) in meshes for k in m[2]})
    cmap = plt.get_cmap("tab20")
    colours = {k: np.array(cmap(i % 20)[:3]) for i, k in enumerate(pairs)}
    fig = plt.figure(figsize=(5 * len(meshes), 5), dpi=100)
    for i, ((pos, tris, pair), title) in enumerate(meshes):
        ax = fig.add_subplot(1, len(meshes), i + 1, projection="3d")
        draw(ax, pos, tris, pair, title, colours, (pos.min(axis=0) + pos.max(axis=0)) / 2)
    fig.tight_layout()
    fig.savefig(out, bbox_inches="tight", pad_inches=0.05)


if __name__ == "__main__":
    main()
