"""septa iso versus scikit-image and VTK on one CT-like volume (`compare.py --iso`).

The volume is the 256^3 CT-like volume of `benches/iso.rs`, written by
`cargo run --release --example ct_like` (int16 Hounsfield units: septa's heart
phantom with its labels mapped to contrast-enhanced CT values, blurred with
sigma = 1 voxel, Gaussian noise sigma = 25 HU). Iso value 200 HU.

In the same run, repeats interleaved, best of N, the input already in memory
for every tool:

* septa iso (mixed L, displaced, the default; and disconnect L): the library's
  extraction time as reported by `septa iso --json` (`timings_s.extract_internal`;
  reading and writing excluded), RAYON_NUM_THREADS = threads;
* skimage.measure.marching_cubes(volume, level, spacing) (Lewiner, the
  default; single-threaded, scikit-image has no threading here);
* vtkFlyingEdges3D (value = iso, normals, gradients and scalars off),
  `Update()` only, vtkSMPTools with `threads` threads.

For each: time, points, triangles. The N-cycle table of septa's mixed-L
surface is printed too.
"""

from __future__ import annotations

import datetime
import json
import os
import platform
import subprocess
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent


def read_mha(path: Path, np):
    """A MetaImage file with ElementDataFile = LOCAL (as `ct_like` writes it)."""
    raw = path.read_bytes()
    header = {}
    pos = 0
    while True:
        end = raw.index(b"\n", pos)
        key, _, value = raw[pos:end].decode().partition("=")
        header[key.strip()] = value.strip()
        pos = end + 1
        if key.strip() == "ElementDataFile":
            break
    dims = [int(x) for x in header["DimSize"].split()]
    spacing = [float(x) for x in header["ElementSpacing"].split()]
    dtype = {"MET_SHORT": np.int16, "MET_FLOAT": np.float32, "MET_UCHAR": np.uint8}[header["ElementType"]]
    vol = np.frombuffer(raw, dtype=dtype, count=dims[0] * dims[1] * dims[2], offset=pos)
    return vol.reshape(dims[2], dims[1], dims[0]), spacing  # (z, y, x)


def build(threads: int) -> tuple[Path, Path]:
    """The release septa binary and the ct_like example."""
    print("cargo build --release (septa, example ct_like) ...", flush=True)
    subprocess.run(["cargo", "build", "--release", "--quiet", "--bin", "septa", "--example", "ct_like"],
                   cwd=REPO, check=True)
    meta = subprocess.run(["cargo", "metadata", "--format-version", "1", "--no-deps"], cwd=REPO,
                          capture_output=True, text=True, check=True)
    target = Path(json.loads(meta.stdout)["target_directory"]) / "release"
    return target / "septa", target / "examples" / "ct_like"


def septa_iso(exe: Path, vol: Path, out: Path, iso: float, mode: str, threads: int) -> dict:
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    t0 = time.perf_counter()
    r = subprocess.run([str(exe), "iso", str(vol), "--iso", str(iso), "--mode", mode, "-o", str(out),
                        "--json", "-q"], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(r.stderr)
    j = json.loads(r.stdout)
    j["wall"] = wall
    return j


def main(args, np, vtk_setup) -> None:
    import skimage
    from skimage.measure import marching_cubes

    vtk, smp = vtk_setup(args.threads)
    if args.septa_bin:
        exe = args.septa_bin.resolve()
        gen = exe.parent / "examples" / "ct_like"
    else:
        exe, gen = build(args.threads)
    work = args.workdir or Path("/tmp")
    work.mkdir(parents=True, exist_ok=True)
    vol_path = work / f"ct_like_{args.iso_size}.mha"
    subprocess.run([str(gen), str(vol_path), "--size", str(args.iso_size)], check=True)
    vol, spacing = read_mha(vol_path, np)
    iso = 200.0

    img = vtk.vtkImageData()
    img.SetDimensions(vol.shape[2], vol.shape[1], vol.shape[0])
    img.SetSpacing(*spacing)
    from vtk.util import numpy_support

    arr = numpy_support.numpy_to_vtk(vol.ravel(), deep=True, array_type=vtk.VTK_SHORT)
    arr.SetName("hu")
    img.GetPointData().SetScalars(arr)

    def run_vtk():
        fe = vtk.vtkFlyingEdges3D()
        fe.SetInputData(img)
        fe.SetValue(0, iso)
        fe.ComputeNormalsOff()
        fe.ComputeGradientsOff()
        fe.ComputeScalarsOff()
        t0 = time.perf_counter()
        fe.Update()
        dt = time.perf_counter() - t0
        pd = fe.GetOutput()
        return dt, pd.GetNumberOfPoints(), pd.GetNumberOfPolys()

    def run_skimage():
        t0 = time.perf_counter()
        verts, faces, _, _ = marching_cubes(vol, level=iso, spacing=tuple(spacing[::-1]))
        dt = time.perf_counter() - t0
        return dt, len(verts), len(faces)

    load_start = " ".join(f"{x:.2f}" for x in os.getloadavg())
    best = {}
    info = {}
    for rep in range(args.repeats):
        for name in ["septa mixed L", "septa disconnect L", "skimage", "vtk"]:
            if name.startswith("septa"):
                mode = name.split()[1]
                j = septa_iso(exe, vol_path, work / "septa_iso.ply", iso, mode, args.threads)
                res = (j["timings_s"]["extract_internal"], j["points"], j["triangles"])
                info[name] = j
                info[name + " wall"] = min(info.get(name + " wall", 1e9), j["wall"])
            elif name == "skimage":
                res = run_skimage()
            else:
                res = run_vtk()
            if name not in best or res[0] < best[name][0]:
                best[name] = res
        print(f"repeat {rep + 1}/{args.repeats}: " + ", ".join(f"{k} {v[0]:.3f} s" for k, v in best.items()),
              flush=True)
    load_end = " ".join(f"{x:.2f}" for x in os.getloadavg())

    mc_points = best["skimage"][1]
    lines = [
        f"Volume: `ct_like` {vol.shape[2]}×{vol.shape[1]}×{vol.shape[0]} int16, spacing {spacing} mm, "
        f"iso {iso:g} HU, {int((vol >= iso).sum()):,} voxels inside.",
        f"Date {datetime.datetime.now():%Y-%m-%d %H:%M}; {platform.machine()}, {os.cpu_count()} cores; "
        f"load average {load_start} at start, {load_end} at end; best of {args.repeats}, repeats interleaved; "
        f"{args.threads} threads for septa (rayon) and VTK ({smp}); scikit-image {skimage.__version__}, "
        f"VTK {vtk.vtkVersion.GetVTKVersion()}, numpy {np.__version__}.",
        "",
        "| tool | time (s) | points | triangles | points vs marching cubes |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, label in [
        ("septa mixed L", "`septa iso` mixed, L, displaced"),
        ("septa disconnect L", "`septa iso` disconnect, L, displaced"),
        ("skimage", "scikit-image `marching_cubes` (Lewiner)"),
        ("vtk", "VTK `vtkFlyingEdges3D`"),
    ]:
        t, p, tr = best[name]
        lines.append(f"| {label} | {t:.3f} | {p:,} | {tr:,} | {p / mc_points:.2f} |")
    j = info["septa mixed L"]
    lines += [
        "",
        f"`septa iso` whole command (read {vol_path.stat().st_size / 2**20:.0f} MiB, extract, write PLY), "
        f"best wall time: mixed {info['septa mixed L wall']:.3f} s, disconnect {info['septa disconnect L wall']:.3f} s.",
        "",
        "N-cycles of the mixed-L surface (the paper's Tables II–IV):",
        "",
        "| N | " + " | ".join(str(n) for n in range(3, 13)) + " | sum | points | triangles |",
        "|---" * 14 + "|",
        "| cycles | " + " | ".join(f"{j['cycles'][str(n)]:,}" for n in range(3, 13))
        + f" | {j['cycle_sum']:,} | {j['points']:,} | {j['triangles']:,} |",
    ]
    jd = info["septa disconnect L"]
    lines += [
        "| disconnect | " + " | ".join(f"{jd['cycles'][str(n)]:,}" for n in range(3, 13))
        + f" | {jd['cycle_sum']:,} | {jd['points']:,} | {jd['triangles']:,} |",
    ]
    text = "\n".join(lines)
    print()
    print(text)
    if args.iso_out:
        args.iso_out.write_text(text + "\n")
        print(f"\nwrote {args.iso_out}")
