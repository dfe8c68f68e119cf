#!/usr/bin/env python3
"""septa versus VTK on the same label volumes: time and the validator's counts.

Run from anywhere (Python >= 3.10; it was written for 3.11):

    python3 bench/compare.py                      # 256^3 and 512^3, clean and --noise 0.01
    python3 bench/compare.py --sizes 256 --repeats 1
    python3 bench/compare.py --sizes '' --volumes ../shared/data/mni152_2009a_tissue3.nii.gz
    python3 bench/compare.py --iso                # septa iso (cold and warm) vs scikit-image and VTK flying edges
    python3 bench/compare.py --remesh             # septa extract (remeshed) vs VTK surface nets + pymeshlab

On its first run it creates bench/.venv and pip-installs bench/requirements.txt
(vtk, numpy, nibabel) into it, then re-runs itself with that interpreter. It
builds septa (`cargo build --release`, honouring CARGO_TARGET_DIR), generates
the heart phantom with `septa phantom`, and for every volume, in the same run:

* septa: `septa extract VOL -o OUT --force -q`, best of N; the figure compared
  is preprocess + extract from OUT/manifest.json (`timings_s`), the whole
  command's wall time (read, preprocess, extract, validate, write) is shown too;
  and once `septa extract VOL --no-remesh --merge-flat` (the same surface with
  its flat stretches merged: fewer triangles);
* vtkSurfaceNets3D (smoothing off, triangle output, every label value present
  except the background) and vtkDiscreteFlyingEdges3D (every label value present
  except the background), on the same voxels, 2 threads (vtkSMPTools STDThread),
  timing `Update()` only, best of N, a fresh filter each time; the repeats of
  all tools are interleaved so that other load on the machine hits them alike;
* every result is written as a PLY with face properties label_a / label_b and
  checked with `septa check FILE --json`; the failure count of every check is
  reported.

Conventions used for the PLYs of the VTK results (checked on a one-voxel volume
at start-up, see `check_vtk_conventions`):

* surface nets: its `BoundaryLabels` cell array is (Label0, Label1) and the
  triangle's normal points from Label0 into Label1 (VTK's documentation; the
  background, when involved, is Label1). We write label_a = min, label_b = max
  and reverse the triangle when we swap, so the normal points from label_a
  into label_b as septa expects.
* discrete flying edges: each label value gets its own closed surface with its
  own points (points are not shared between labels). The triangles face
  outward from the label. We write label_a = the label, label_b = 9999 (a value
  that is not in the volume: "the rest"), orientation unchanged. The validator
  therefore sees label 9999 as the union of all label surfaces.

Output: a table on stdout, and the same as markdown, with machine, load average
and versions, in bench/RESULTS.md (or --out): only the part between the
`compare.py: begin/end` marker lines is replaced, the rest of the file is kept.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
VENV = HERE / ".venv"
REQUIREMENTS = HERE / "requirements.txt"

# The checks of `septa check`, with short column names.
CHECKS = [
    ("vertex indices in range", "idx"),
    ("no unused vertices", "unused"),
    ("no duplicate positions", "dup pos"),
    ("no degenerate triangles", "degen"),
    ("label surfaces closed", "open edges"),
    ("label surfaces oriented", "orient"),
    ("label surfaces manifold at vertices", "nm verts"),
    ("surfaces face away from their label", "facing"),
]
REST = 9999  # label_b of the flying-edges surfaces
# compare.py rewrites only the part of RESULTS.md between these lines.
BEGIN = "<!-- compare.py: begin (generated) -->"
END = "<!-- compare.py: end -->"


# ───────────────────────────── environment ─────────────────────────────


def in_venv() -> bool:
    return Path(sys.prefix).resolve() == VENV.resolve()


def bootstrap() -> None:
    """Creates bench/.venv with the requirements and re-runs this script in it."""
    py = VENV / "bin" / "python"
    if not py.exists():
        print(f"creating {VENV} ...", flush=True)
        subprocess.run([sys.executable, "-m", "venv", str(VENV)], check=True)
    stamp = VENV / ".requirements"
    want = REQUIREMENTS.read_text()
    if not stamp.exists() or stamp.read_text() != want:
        print(f"pip install -r {REQUIREMENTS} ...", flush=True)
        subprocess.run(
            [str(py), "-m", "pip", "install", "-q", "-r", str(REQUIREMENTS)], check=True
        )
        stamp.write_text(want)
    os.execv(str(py), [str(py), str(Path(__file__).resolve()), *sys.argv[1:]])


def run(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, text=True, capture_output=True, **kw)


def build_septa() -> Path:
    """`cargo build --release`; the path of the septa binary."""
    print("cargo build --release ...", flush=True)
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=REPO, check=True)
    meta = run(["cargo", "metadata", "--format-version", "1", "--no-deps"], cwd=REPO)
    target = Path(json.loads(meta.stdout)["target_directory"])
    exe = target / "release" / "septa"
    if not exe.exists():
        sys.exit(f"no septa binary at {exe}")
    return exe


def loadavg() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def git_rev() -> str:
    r = run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO)
    dirty = run(["git", "status", "--porcelain", "--", "src", "Cargo.toml"], cwd=REPO).stdout
    return r.stdout.strip() + ("+dirty(src)" if dirty.strip() else "")


# ───────────────────────────── VTK ─────────────────────────────


def setup_vtk(threads: int):
    import vtk

    smp = vtk.vtkSMPTools
    smp.SetBackend("STDThread")
    smp.Initialize(threads)
    return vtk, f"{smp.GetBackend()} ({smp.GetEstimatedNumberOfThreads()} threads)"


def vtk_image(labels, vtk):
    """vtkImageData (index space: origin 0, spacing 1) with the labels as point scalars."""
    from vtk.util import numpy_support as ns

    img = vtk.vtkImageData()
    img.SetDimensions(*labels.shape)
    arr = ns.numpy_to_vtk(labels.ravel(order="F"), deep=True)
    arr.SetName("labels")
    img.GetPointData().SetScalars(arr)
    return img


def triangles_of(pd):
    """The triangles of a vtkPolyData as an (n, 3) array (all cells must be triangles)."""
    import numpy as np
    from vtk.util import numpy_support as ns

    polys = pd.GetPolys()
    conn = ns.vtk_to_numpy(polys.GetConnectivityArray())
    off = ns.vtk_to_numpy(polys.GetOffsetsArray())
    if len(off) > 1 and not np.all(np.diff(off) == 3):
        raise SystemExit("expected triangles only")
    return conn.reshape(-1, 3).astype(np.int32)


def points_of(pd):
    from vtk.util import numpy_support as ns

    return ns.vtk_to_numpy(pd.GetPoints().GetData())


def surface_nets(vtk, img, labels, background, triangles=True):
    f = vtk.vtkSurfaceNets3D()
    f.SetInputData(img)
    f.SmoothingOff()
    f.DataCachingOff()
    f.SetBackgroundLabel(background)
    if triangles:
        f.SetOutputMeshTypeToTriangles()
    f.SetNumberOfLabels(len(labels))
    for i, v in enumerate(labels):
        f.SetLabel(i, float(v))
    return f


def flying_edges(vtk, img, labels):
    f = vtk.vtkDiscreteFlyingEdges3D()
    f.SetInputData(img)
    f.ComputeScalarsOn()
    f.ComputeNormalsOff()
    f.ComputeGradientsOff()
    f.SetNumberOfContours(len(labels))
    for i, v in enumerate(labels):
        f.SetValue(i, float(v))
    return f


def surface_nets_faces(pd):
    """Triangles and (label_a, label_b) with label_a < label_b, normal a -> b."""
    import numpy as np
    from vtk.util import numpy_support as ns

    t = triangles_of(pd)
    bl = ns.vtk_to_numpy(pd.GetCellData().GetArray("BoundaryLabels")).astype(np.int64)
    swap = bl[:, 0] > bl[:, 1]
    t[swap] = t[swap][:, ::-1]
    return t, np.sort(bl, axis=1)


def flying_edges_faces(pd):
    """Triangles and (label, REST); orientation kept (outward from the label)."""
    import numpy as np
    from vtk.util import numpy_support as ns

    t = triangles_of(pd)
    s = ns.vtk_to_numpy(pd.GetPointData().GetScalars()).astype(np.int64)
    lab = s[t[:, 0]]
    if not (np.all(s[t[:, 1]] == lab) and np.all(s[t[:, 2]] == lab)):
        raise SystemExit("flying edges: a triangle with points of different labels")
    return t, np.stack([lab, np.full_like(lab, REST)], axis=1)


def signed_volume(p, t):
    import numpy as np

    p = p.astype(np.float64)
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def check_vtk_conventions(vtk) -> list[str]:
    """One voxel of label 1 beside one of label 2 in background 0: the orientation
    conventions documented above, checked (exits if VTK disagrees)."""
    import numpy as np

    a = np.zeros((5, 5, 6), np.uint8)
    a[2, 2, 2] = 1
    a[2, 2, 3] = 2
    img = vtk_image(a, vtk)
    notes = []
    f = surface_nets(vtk, img, [1, 2], 0)
    f.Update()
    pd = f.GetOutput()
    p = points_of(pd)
    t, lab = surface_nets_faces(pd)
    for l in (1, 2):
        # label l's surface, outward: its faces, flipped where l is label_b
        m = (lab == l).any(axis=1)
        tl = t[m].copy()
        flip = lab[m][:, 1] == l
        tl[flip] = tl[flip][:, ::-1]
        v = signed_volume(p, tl)
        if not v > 0:
            raise SystemExit(f"surface nets: label {l}'s surface is not outward ({v})")
    notes.append("surface nets: BoundaryLabels (L0, L1), normal from L0 into L1 (checked)")
    f = flying_edges(vtk, img, [1, 2])
    f.Update()
    pd = f.GetOutput()
    p = points_of(pd)
    t, lab = flying_edges_faces(pd)
    for l in (1, 2):
        v = signed_volume(p, t[lab[:, 0] == l])
        if not v > 0:
            raise SystemExit(f"flying edges: label {l}'s surface is not outward ({v})")
    notes.append("discrete flying edges: per-label surfaces face outward (checked)")
    return notes


def to_lps(p, affine):
    """Index-space points -> LPS mm through the NIfTI affine (RAS)."""
    import numpy as np

    q = p.astype(np.float64) @ affine[:3, :3].T + affine[:3, 3]
    q[:, :2] *= -1.0
    return q.astype(np.float32)


def write_ply(path: Path, p, t, lab) -> None:
    """Binary little-endian PLY: float x, y, z; uchar-int vertex_indices, int label_a, label_b."""
    import numpy as np

    header = (
        "ply\nformat binary_little_endian 1.0\ncomment written by bench/compare.py\n"
        f"element vertex {len(p)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(t)}\nproperty list uchar int vertex_indices\n"
        "property int label_a\nproperty int label_b\nend_header\n"
    )
    face = np.zeros(
        len(t), dtype=[("n", "u1"), ("v", "<i4", (3,)), ("a", "<i4"), ("b", "<i4")]
    )
    face["n"] = 3
    face["v"] = t
    face["a"] = lab[:, 0]
    face["b"] = lab[:, 1]
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(np.ascontiguousarray(p, dtype="<f4").tobytes())
        f.write(face.tobytes())


# ───────────────────────────── septa ─────────────────────────────


def septa_check(exe: Path, ply: Path) -> dict:
    """Failure count per check name, plus 'passed' and the check's wall time."""
    t = time.perf_counter()
    r = run([str(exe), "check", str(ply), "--json", "-q"])
    dt = time.perf_counter() - t
    if r.returncode not in (0, 1):
        raise SystemExit(f"septa check {ply} failed ({r.returncode}): {r.stderr}")
    j = json.loads(r.stdout)
    out = {c["name"]: c["failures"] for c in j["report"]["checks"]}
    out["passed"] = j["passed"]
    out["check_s"] = dt
    return out


def septa_extract(exe: Path, vol: Path, out: Path, extra: tuple[str, ...] = ()) -> dict:
    """One `septa extract` run: its wall time and manifest figures."""
    t = time.perf_counter()
    r = run([str(exe), "extract", str(vol), "-o", str(out), "--force", "-q", *extra])
    wall = time.perf_counter() - t
    if r.returncode != 0:
        raise SystemExit(f"septa extract {vol} failed: {r.stderr}")
    m = json.loads((out / "manifest.json").read_text())
    ts = m["timings_s"]
    return {
        "time": ts["preprocess"] + ts["extract"],
        "wall": wall,
        "timings": ts,
        "vertices": m["vertices"],
        "triangles": m["triangles"],
        "manifest_passed": m["validation"]["passed"],
    }


# ───────────────────────────── main ─────────────────────────────


def fmt_int(n) -> str:
    return f"{n:,}" if isinstance(n, int) else str(n)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="256,512", help="phantom sizes (default 256,512)")
    ap.add_argument("--noise", default="0,0.01", help="phantom noise levels (default 0,0.01)")
    ap.add_argument("--volumes", default="",
                    help="also these label volumes (NIfTI, comma-separated), e.g. "
                    "../shared/data/mni152_2009a_tissue3.nii.gz; --sizes '' compares only them")
    ap.add_argument("--repeats", type=int, default=3, help="best of N (default 3)")
    ap.add_argument("--threads", type=int, default=2, help="VTK threads (default 2)")
    ap.add_argument("--out", type=Path, default=HERE / "RESULTS.md", help="markdown output")
    ap.add_argument("--workdir", type=Path, help="keep volumes and meshes here (default: a temp dir, removed)")
    ap.add_argument("--no-venv", action="store_true", help="use this interpreter as is")
    ap.add_argument("--septa-bin", type=Path,
                    help="use this septa binary instead of building the work tree "
                    "(e.g. one built from a clean `git archive HEAD`)")
    ap.add_argument("--septa-rev", help="what to report as the binary's git revision (with --septa-bin)")
    ap.add_argument("--iso", action="store_true",
                    help="instead: VESTA iso-surfaces, `septa iso` vs scikit-image marching_cubes and "
                    "vtkFlyingEdges3D on the CT-like volume of benches/iso.rs (see compare_iso.py)")
    ap.add_argument("--iso-size", type=int, default=256, help="--iso: voxels per axis (default 256)")
    ap.add_argument("--iso-out", type=Path, help="--iso: also write the markdown tables here")
    ap.add_argument("--remesh", action="store_true",
                    help="instead: the whole pipeline with smoothing and remeshing, `septa extract "
                    "--target-edge L` vs vtkSurfaceNets3D (smoothing on) + pymeshlab isotropic remeshing, "
                    "time, quality and validator figures (see compare_remesh.py)")
    ap.add_argument("--remesh-size", type=int, default=256, help="--remesh: phantom size (default 256)")
    ap.add_argument("--remesh-noise", default="0.01", help="--remesh: phantom noise (default 0.01)")
    ap.add_argument("--remesh-volume", type=Path,
                    help="--remesh: this label volume (NIfTI) instead of the phantom, e.g. "
                    "../shared/data/mni152_2009a_tissue3.nii.gz; its tables go in a block of their own")
    ap.add_argument("--target-edge", type=float,
                    help="--remesh: target edge length L in mm (default: twice the mean voxel spacing, "
                    "septa's default)")
    ap.add_argument("--pml-variants", default="whole,per-label",
                    help="--remesh: pymeshlab on the whole multi-label mesh and/or on each label's "
                    "surface (default whole,per-label)")
    ap.add_argument("--remesh-out", type=Path, default=REPO / "BENCHMARKS.md",
                    help="--remesh: markdown goes between its marker lines in this file "
                    "(default BENCHMARKS.md)")
    args = ap.parse_args()
    if not args.no_venv and not in_venv():
        bootstrap()

    import nibabel as nib
    import numpy as np

    if args.iso:
        sys.path.insert(0, str(HERE))
        import compare_iso

        compare_iso.main(args, np, setup_vtk)
        return

    if args.remesh:
        sys.path.insert(0, str(HERE))
        import compare_remesh

        compare_remesh.main(args, np)
        return

    exe = args.septa_bin.resolve() if args.septa_bin else build_septa()
    vtk, smp = setup_vtk(args.threads)
    notes = check_vtk_conventions(vtk)
    sizes = [int(s) for s in args.sizes.split(",") if s.strip()]
    volumes = [Path(v).resolve() for v in args.volumes.split(",") if v.strip()]
    noises = [n.strip() for n in args.noise.split(",")]
    work = args.workdir or Path(tempfile.mkdtemp(prefix="septa-compare-"))
    work.mkdir(parents=True, exist_ok=True)
    septa_version = run([str(exe), "--version"]).stdout.strip()
    header = {
        "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, "
        f"{os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES') / 2**30:.0f} GiB",
        "python": platform.python_version(),
        "vtk": vtk.vtkVersion.GetVTKVersion(),
        "numpy": np.__version__,
        "septa": f"{septa_version} (git {args.septa_rev or git_rev()})"
        + (f", binary {exe}" if args.septa_bin else ""),
        "nice": os.nice(0),
        "vtk_smp": smp,
        "repeats": args.repeats,
        "load_start": loadavg(),
    }
    print(json.dumps(header, indent=1))
    rows = []
    try:
        for n in sizes:
            for noise in noises:
                name = f"heart{n}" + ("" if float(noise) == 0 else f"_noise{noise}")
                vol = work / f"{name}.nii.gz"
                if not vol.exists():
                    r = run([str(exe), "phantom", "-o", str(vol), "--size", str(n), "--noise", noise, "-q"])
                    if r.returncode != 0:
                        raise SystemExit(r.stderr)
                rows += compare_one(exe, vtk, nib, np, vol, name, work, args.repeats)
                (work / f"{name}.nii.gz").unlink()  # 512^3 meshes and volumes add up
        for vol in volumes:
            name = vol.name.removesuffix(".gz").removesuffix(".nii")
            rows += compare_one(exe, vtk, nib, np, vol, name, work, args.repeats)
    finally:
        if args.workdir is None:
            shutil.rmtree(work, ignore_errors=True)
    header["load_end"] = loadavg()
    print_table(rows)
    write_markdown(args.out, header, notes, rows)
    print(f"\nwrote {args.out}")


def compare_one(exe, vtk, nib, np, vol: Path, name: str, work: Path, repeats: int) -> list[dict]:
    print(f"\n== {name} (load {loadavg()})", flush=True)
    img_nii = nib.load(str(vol))
    labels = np.asanyarray(img_nii.dataobj)
    if labels.ndim != 3:
        raise SystemExit(f"{vol}: not 3-D")
    values = [int(v) for v in np.unique(labels)]
    border = np.concatenate(
        [labels[[0, -1]].ravel(), labels[:, [0, -1]].ravel(), labels[:, :, [0, -1]].ravel()]
    )
    bv, bc = np.unique(border, return_counts=True)
    background = int(bv[np.argmax(bc)])
    fg = [v for v in values if v != background]
    dims = "×".join(map(str, labels.shape))

    # VTK does not close surfaces at the volume's border, septa does (the outside
    # is the background): VTK's validated runs get the volume padded with one
    # background voxel on each side (points are shifted back); the time on the
    # unpadded volume is shown too.
    img0 = vtk_image(labels, vtk)
    img = vtk_image(np.pad(labels, 1, constant_values=background), vtk)
    makers = {
        "sn": lambda: surface_nets(vtk, img, fg, background),
        "snq": lambda: surface_nets(vtk, img, fg, background, triangles=False),
        "fe": lambda: flying_edges(vtk, img, fg),
        "sn0": lambda: surface_nets(vtk, img0, fg, background),
        "fe0": lambda: flying_edges(vtk, img0, fg),
    }
    # Repeats are interleaved (septa, then each VTK filter, then again) so that
    # other processes on the machine slow all tools alike; best of each.
    out = work / f"{name}.septa"
    best = {k: float("inf") for k in ["septa", "wall", *makers]}
    outputs = {}
    s = None
    for _ in range(repeats):
        one = septa_extract(exe, vol, out)
        if one["time"] < best["septa"]:
            best["septa"], s = one["time"], one
        best["wall"] = min(best["wall"], one["wall"])
        for k, make in makers.items():
            f = make()
            t = time.perf_counter()
            f.Update()
            best[k] = min(best[k], time.perf_counter() - t)
            if k in ("sn", "fe", "snq"):
                outputs[k] = f.GetOutput()
            del f
    load = loadavg()
    print(f"timed (load {load}): " + ", ".join(f"{k} {v:.3f}" for k, v in best.items()), flush=True)
    del img0, img

    chk = septa_check(exe, out / "interfaces.ply")
    shutil.rmtree(out, ignore_errors=True)
    rows = [dict(tool="septa (preprocess+extract)", volume=name, dims=dims, load=load,
                 time=best["septa"], wall=best["wall"], vertices=s["vertices"],
                 triangles=s["triangles"], check=chk, extra=s["timings"])]
    print(f"septa: {best['septa']:.3f} s (preprocess+extract), command {best['wall']:.3f} s; "
          f"{s['vertices']:,} vertices, {s['triangles']:,} triangles", flush=True)
    # the extraction as written with --no-remesh --merge-flat: the same surface,
    # flat stretches merged (once: its size is the figure, the time is shown too)
    merged = septa_extract(exe, vol, out, ("--no-remesh", "--merge-flat"))
    chk = septa_check(exe, out / "interfaces.ply")
    shutil.rmtree(out, ignore_errors=True)
    rows.append(dict(tool="septa --no-remesh --merge-flat", volume=name, dims=dims, load=load,
                     time=merged["time"], wall=merged["wall"], vertices=merged["vertices"],
                     triangles=merged["triangles"], check=chk, extra=merged["timings"]))
    print(f"septa --merge-flat: {merged['time']:.3f} s, {merged['triangles']:,} triangles", flush=True)

    for key, tool, faces in [
        ("sn", "vtkSurfaceNets3D (triangles)", surface_nets_faces),
        ("fe", "vtkDiscreteFlyingEdges3D", flying_edges_faces),
    ]:
        pd = outputs.pop(key)
        tri, lab = faces(pd)
        p = to_lps(points_of(pd) - 1.0, img_nii.affine)
        del pd
        ply = work / f"{name}.{key}.ply"
        write_ply(ply, p, tri, lab)
        chk = septa_check(exe, ply)
        ply.unlink()
        rows.append(dict(tool=tool, volume=name, dims=dims, load=load, time=best[key],
                         time0=best[key + "0"], vertices=len(p), triangles=len(tri), check=chk))
        print(f"{tool}: {best[key]:.3f} s, {len(p):,} points, {len(tri):,} triangles", flush=True)
        if key == "sn":
            pd = outputs.pop("snq")
            rows.append(dict(tool="vtkSurfaceNets3D (quads, default)", volume=name, dims=dims,
                             load=load, time=best["snq"], vertices=pd.GetNumberOfPoints(),
                             triangles=None, quads=pd.GetNumberOfCells(), check=None))
            del pd
    ref = rows[0]["time"]
    for r in rows:
        r["ratio"] = r["time"] / ref
    return rows


def table_lines(rows: list[dict]) -> list[list[str]]:
    head = ["tool", "volume", "time (s)", "÷ septa", "unpadded (s)", "vertices", "triangles"] + [c for _, c in CHECKS] + ["load"]
    lines = [head]
    for r in rows:
        chk = r["check"]
        tri = fmt_int(r["triangles"]) if r["triangles"] is not None else f"({fmt_int(r['quads'])} quads)"
        time_s = f"{r['time']:.3f}" + (f" (command {r['wall']:.2f})" if "wall" in r else "")
        t0 = f"{r['time0']:.3f}" if "time0" in r else "–"
        cells = [r["tool"], r["volume"], time_s, f"{r['ratio']:.2f}", t0, fmt_int(r["vertices"]), tri]
        cells += [fmt_int(chk[name]) if chk and name in chk else "–" for name, _ in CHECKS]
        cells.append(r["load"].split()[0])
        lines.append(cells)
    return lines


def print_table(rows: list[dict]) -> None:
    lines = table_lines(rows)
    w = [max(len(l[i]) for l in lines) for i in range(len(lines[0]))]
    print()
    for k, l in enumerate(lines):
        print("  ".join(c.ljust(w[i]) for i, c in enumerate(l)))
        if k == 0:
            print("  ".join("-" * x for x in w))


def write_markdown(path: Path, header: dict, notes: list[str], rows: list[dict]) -> None:
    lines = table_lines(rows)
    md = ["## Measured by bench/compare.py", ""]
    md += [f"- {k}: {v}" for k, v in header.items()]
    md += [f"- {n}" for n in notes]
    md += ["", "| " + " | ".join(lines[0]) + " |", "|" + "---|" * len(lines[0])]
    md += ["| " + " | ".join(l) + " |" for l in lines[1:]]
    md += ["", "septa's stage timings (best run, s):", ""]
    for r in rows:
        if r.get("extra"):
            md.append(f"- {r['volume']}: " + ", ".join(f"{k} {v:.3f}" for k, v in r["extra"].items()))
    block = BEGIN + "\n" + "\n".join(md) + "\n" + END
    text = path.read_text() if path.exists() else ""
    if BEGIN in text and END in text:
        pre, rest = text.split(BEGIN, 1)
        text = pre + block + rest.split(END, 1)[1]
    else:
        text = block + "\n" + text
    path.write_text(text)


if __name__ == "__main__":
    main()
