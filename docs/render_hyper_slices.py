#!/usr/bin/env python3
"""Render time slices written by `septa hyper` into one picture.

    cargo run --release --example make_4d -- fireball.nii.gz
    septa hyper fireball.nii.gz --iso 50 --times 0:5:1 -o fireball_out
    python3 docs/render_hyper_slices.py fireball_out docs/hyper_slices.png

Reads OUTDIR/summary.json and the slice_t*.ply files it lists (septa's binary
little-endian PLY: float x, y, z; faces `uchar int vertex_indices` plus three
4-byte properties) and draws each slice with matplotlib's plot_trisurf, one
panel per time, on shared axes. Needs numpy and matplotlib; septa itself never
runs Python.
"""
import json
import sys
from pathlib import Path

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_ply(path):
    data = Path(path).read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    counts, props, current = {}, {}, None
    for line in header:
        w = line.split()
        if w[:1] == ["element"]:
            current = w[1]
            counts[current] = int(w[2])
            props[current] = []
        elif w[:1] == ["property"]:
            props[current].append(w[1:])
    assert "binary_little_endian" in header[1], "septa writes binary little-endian PLY"
    nv, nf = counts["vertex"], counts.get("face", 0)
    vprops = props["vertex"]
    assert all(p[0] == "float" for p in vprops), vprops
    v = np.frombuffer(data, dtype="<f4", count=nv * len(vprops), offset=end)
    v = v.reshape(nv, len(vprops))[:, :3]
    # faces: uchar 3, int a, b, c, then label_a, label_b, patch (4 bytes each)
    extra = len(props["face"]) - 1
    rec = np.dtype([("n", "u1"), ("v", "<i4", 3), ("x", "<i4", extra)])
    f = np.frombuffer(data, dtype=rec, count=nf, offset=end + v.nbytes)
    assert np.all(f["n"] == 3)
    return v, f["v"]


def main():
    outdir, png = Path(sys.argv[1]), sys.argv[2]
    summary = json.loads((outdir / "summary.json").read_text())
    slices = [s for s in summary["slices"] if s["triangles"] > 0]
    meshes = [read_ply(outdir / s["file"]) for s in slices]
    allv = np.concatenate([m[0] for m in meshes])
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2
    fig = plt.figure(figsize=(2.2 * len(slices), 2.6))
    unit = "s" if summary["parameters"]["time_step"] != 1 else "frames"
    for i, (s, (v, f)) in enumerate(zip(slices, meshes)):
        ax = fig.add_subplot(1, len(slices), i + 1, projection="3d")
        ax.plot_trisurf(v[:, 0], v[:, 1], v[:, 2], triangles=f, color="#e8843c",
                        edgecolor="#7a3b12", linewidth=0.05, shade=True)
        for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
            set_lim(c - half, c + half)
        ax.set_box_aspect((1, 1, 1), zoom=1.6)
        ax.view_init(elev=20, azim=-60)
        ax.set_axis_off()
        frame = "" if s["frame"] is None else f" (frame {s['frame']})"
        ax.set_title(f"t = {s['time']:g} {unit}{frame}\n{s['components']} component"
                     + ("s" if s["components"] != 1 else ""), fontsize=9)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.88, wspace=0)
    fig.savefig(png, dpi=110)
    print(f"{png}: {len(slices)} slices")


if __name__ == "__main__":
    main()
