"""`compare.py --remesh`: septa's whole pipeline next to the one a user would
assemble today from VTK and pymeshlab, on the noisy heart phantom.

* septa: `septa extract VOL -o OUT --force -q --target-edge L` (read,
  preprocess, extract, smooth + remesh, validate with self-intersections,
  write); the command's wall time and the stages of OUT/manifest.json.
* the user's pipeline: `vtkSurfaceNets3D` with its own smoothing on (VTK's
  defaults: 16 iterations, relaxation factor 0.5, automatic constraints with
  constraint scale 2; triangle output; 2 threads), then pymeshlab's
  `meshing_isotropic_explicit_remeshing(targetlen=PureValue(L))` with its
  defaults otherwise (10 iterations, feature angle 30°, surface-distance check
  at 1 % of the bounding box diagonal, reprojection on), in two variants:
  - "whole": the multi-label surface-nets mesh as one mesh (it is not
    manifold: three or more labels meet along edges). pymeshlab accepts it; the
    label pair of every face rides along as face quality (`f_scalar_array`,
    code a·K + b), which the remesher copies to the faces it makes, so the
    result keeps label_a / label_b.
  - "per label": each label's closed outward surface (its faces of the
    surface-nets mesh, oriented away from it) remeshed on its own, as one would
    for per-label STL files; neighbouring labels no longer share an interface
    (label_a = the label, label_b = 9999 "the rest", as compare.py writes
    flying edges). pymeshlab runs one label after the other (it is
    single-threaded; a user could run two labels at once on 2 cores).

Every result goes through `septa check FILE --json --intersections --reference
EXACT --target-edge L`, EXACT being `septa extract --no-remesh`'s
interfaces.ply: the validator's counts and septa's own quality report
(src/mesh/quality.rs: edge lengths, angles, one-sided Hausdorff distance from
the result to EXACT, enclosed volume per label), so both pipelines are
measured by the same code. Volumes are compared with the voxel count × voxel
volume of each label.
"""

from __future__ import annotations

import datetime
import importlib.metadata
import json
import os
import platform
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import compare as C

BEGIN = "<!-- compare.py --remesh: begin (generated) -->"
END = "<!-- compare.py --remesh: end -->"
SELF = "no self-intersections"
CHECKS = C.CHECKS + [(SELF, "self-int pairs")]
STAGES = ["read", "preprocess", "extract", "remesh", "validate", "write"]
CODE = 1 << 16  # face code = label_a * CODE + label_b


def septa_run(exe: Path, vol: Path, out: Path, L: float) -> dict:
    t = time.perf_counter()
    r = C.run([str(exe), "extract", str(vol), "-o", str(out), "--force", "-q", "--target-edge", str(L)])
    wall = time.perf_counter() - t
    if r.returncode not in (0, 1):  # 1: validation failed, files written anyway
        raise SystemExit(f"septa extract {vol} failed ({r.returncode}): {r.stderr}")
    m = json.loads((out / "manifest.json").read_text())
    return {"wall": wall, "timings": m["timings_s"], "extraction": m["extraction"]["triangles"]}


def septa_measure(exe: Path, ply: Path, ref: Path, L: float) -> dict:
    r = C.run([str(exe), "check", str(ply), "--json", "-q", "--intersections",
               "--reference", str(ref), "--target-edge", str(L)])
    if r.returncode not in (0, 1):
        raise SystemExit(f"septa check {ply} failed ({r.returncode}): {r.stderr}")
    j = json.loads(r.stdout)
    chk = {c["name"]: c["failures"] for c in j["report"]["checks"]}
    return {"check": chk, "passed": j["passed"], "quality": j["quality"]}


def surface_nets_smoothed(vtk, img, fg, background):
    f = vtk.vtkSurfaceNets3D()
    f.SetInputData(img)
    f.SmoothingOn()  # VTK's defaults: 16 iterations, relaxation 0.5, automatic constraints
    f.DataCachingOff()
    f.SetBackgroundLabel(background)
    f.SetOutputMeshTypeToTriangles()
    f.SetNumberOfLabels(len(fg))
    for i, v in enumerate(fg):
        f.SetLabel(i, float(v))
    return f


def pml_remesh(ml, np, p, t, L, quality=None):
    """pymeshlab isotropic remeshing to absolute edge length L; (points, triangles, face quality)."""
    ms = ml.MeshSet()
    if quality is None:
        ms.add_mesh(ml.Mesh(vertex_matrix=p, face_matrix=t))
    else:
        ms.add_mesh(ml.Mesh(vertex_matrix=p, face_matrix=t, f_scalar_array=quality))
    ms.meshing_isotropic_explicit_remeshing(targetlen=ml.PureValue(L))
    m = ms.current_mesh()
    q = m.face_scalar_array() if quality is not None else None
    return m.vertex_matrix(), m.face_matrix().astype(np.int32), q


def pml_whole(ml, np, p, tri, lab, L):
    code = (lab[:, 0] * CODE + lab[:, 1]).astype(np.float64)
    q, t, c = pml_remesh(ml, np, p, tri, L, code)
    c = np.rint(c).astype(np.int64)
    if not np.isin(c, code.astype(np.int64)).all():
        raise SystemExit("pymeshlab: face quality is not one of the label codes any more")
    return q, t, np.stack([c // CODE, c % CODE], axis=1)


def label_surface(np, tri, lab, l):
    """Label l's faces, oriented outward (away from l), on compact vertices."""
    m = (lab == l).any(axis=1)
    tl = tri[m].copy()
    flip = lab[m][:, 1] == l  # the normal points from label_a into label_b
    tl[flip] = tl[flip][:, ::-1]
    used, inv = np.unique(tl, return_inverse=True)
    return used, inv.reshape(-1, 3).astype(np.int32)


def pml_per_label(ml, np, p, tri, lab, fg, L):
    ps, ts, ls, n = [], [], [], 0
    for l in fg:
        used, tl = label_surface(np, tri, lab, l)
        q, t, _ = pml_remesh(ml, np, p[used], tl, L)
        ps.append(q)
        ts.append(t + n)
        ls.append(np.tile([l, C.REST], (len(t), 1)))
        n += len(q)
    return np.concatenate(ps), np.concatenate(ts), np.concatenate(ls)


def volume_changes(quality: dict, voxels: dict[int, float]) -> dict[int, float]:
    """(enclosed volume − voxel count × voxel volume) / that, per bounded label."""
    out = {}
    for l in quality["labels"]:
        v = l["value"]
        if not l["unbounded"] and v in voxels and voxels[v] > 0:
            out[v] = (l["volume_mm3"] - voxels[v]) / voxels[v]
    return out


def main(args, np) -> None:
    import nibabel as nib
    import pymeshlab as ml

    exe = args.septa_bin.resolve() if args.septa_bin else C.build_septa()
    vtk, smp = C.setup_vtk(args.threads)
    C.check_vtk_conventions(vtk)
    n = args.remesh_size
    noise = args.remesh_noise
    work = args.workdir or Path(tempfile.mkdtemp(prefix="septa-remesh-"))
    work.mkdir(parents=True, exist_ok=True)
    given = getattr(args, "remesh_volume", None)
    if given:
        name = given.name.split(".")[0]
        vol = given.resolve()
        if not vol.exists():
            raise SystemExit(f"{given}: no such file")
    else:
        name = f"heart{n}_noise{noise}"
        vol = work / f"{name}.nii.gz"
    if not vol.exists():
        r = C.run([str(exe), "phantom", "-o", str(vol), "--size", str(n), "--noise", noise, "-q"])
        if r.returncode != 0:
            raise SystemExit(r.stderr)
    nii = nib.load(str(vol))
    spacing = [float(s) for s in nii.header.get_zooms()[:3]]
    L = args.target_edge if args.target_edge else 2.0 * sum(spacing) / 3.0
    labels = np.asanyarray(nii.dataobj)
    values, counts = np.unique(labels, return_counts=True)
    voxel_mm3 = spacing[0] * spacing[1] * spacing[2]
    voxels = {int(v): float(c) * voxel_mm3 for v, c in zip(values, counts)}
    border = np.concatenate(
        [labels[[0, -1]].ravel(), labels[:, [0, -1]].ravel(), labels[:, :, [0, -1]].ravel()]
    )
    bv, bc = np.unique(border, return_counts=True)
    background = int(bv[np.argmax(bc)])
    fg = [int(v) for v in values if v != background]

    septa_version = C.run([str(exe), "--version"]).stdout.strip()
    header = {
        "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, "
        f"{os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES') / 2**30:.0f} GiB",
        "volume": (f"`{given.name}`, " if given else f"`septa phantom --size {n} --noise {noise}`, ")
        + f"{'×'.join(map(str, labels.shape))}, spacing {spacing} mm, {len(values)} labels",
        "target edge L": f"{L:g} mm = {L / max(spacing):g} voxels",
        "septa": f"{septa_version} (git {args.septa_rev or C.git_rev()})",
        "vtk": vtk.vtkVersion.GetVTKVersion() + f", {smp}",
        "pymeshlab": importlib.metadata.version("pymeshlab"),
        "python / numpy": f"{platform.python_version()} / {np.__version__}",
        "repeats": f"best of {args.repeats}, interleaved",
        "load_start": C.loadavg(),
    }
    print(json.dumps(header, indent=1), flush=True)

    # the reference: septa's exact (unsmoothed) extraction
    exact = work / f"{name}.exact"
    r = C.run([str(exe), "extract", str(vol), "-o", str(exact), "--force", "-q", "--no-remesh"])
    if r.returncode != 0:
        raise SystemExit(f"septa extract --no-remesh failed: {r.stderr}")
    ref = exact / "interfaces.ply"

    img = C.vtk_image(np.pad(labels, 1, constant_values=background), vtk)
    out = work / f"{name}.septa"
    best = {k: float("inf") for k in ["septa", "septa_remesh", "sn", "pml_whole", "pml_label"]}
    septa_best = None
    every = {k: [] for k in best}  # every repeat's time, for the record

    def note(k, v):
        every[k].append(v)
        best[k] = min(best[k], v)
    results = {}
    for rep in range(args.repeats):
        s = septa_run(exe, vol, out, L)
        if s["wall"] < best["septa"]:
            septa_best = s
        note("septa", s["wall"])
        note("septa_remesh", s["timings"]["remesh"])

        f = surface_nets_smoothed(vtk, img, fg, background)
        t = time.perf_counter()
        f.Update()
        note("sn", time.perf_counter() - t)
        pd = f.GetOutput()
        tri, lab = C.surface_nets_faces(pd)
        p = C.to_lps(C.points_of(pd) - 1.0, nii.affine).astype(np.float64)
        sn_size = (pd.GetNumberOfPoints(), len(tri))
        del f, pd

        if "whole" in args.pml_variants:
            t = time.perf_counter()
            results["whole"] = pml_whole(ml, np, p, tri, lab, L)
            note("pml_whole", time.perf_counter() - t)
        if "per-label" in args.pml_variants:
            t = time.perf_counter()
            results["per-label"] = pml_per_label(ml, np, p, tri, lab, fg, L)
            note("pml_label", time.perf_counter() - t)
        print(f"repeat {rep + 1}/{args.repeats} (load {C.loadavg()}): "
              + ", ".join(f"{k} {v[-1]:.2f} s" for k, v in every.items() if v), flush=True)
    header["load_end"] = C.loadavg()
    header["every repeat (s)"] = "; ".join(
        f"{k} " + ", ".join(f"{x:.2f}" for x in v) for k, v in every.items() if v)

    rows = []
    ts = septa_best["timings"]
    m = septa_measure(exe, out / "interfaces.ply", ref, L)
    rows.append(dict(
        pipeline="septa extract --target-edge L", time=best["septa"],
        stages=f"command wall {best['septa']:.2f}; " + ", ".join(
            f"{k} {ts[k]:.2f}" for k in sorted(ts, key=STAGES.index if set(ts) <= set(STAGES) else str))
        + f" (best remesh of the repeats {best['septa_remesh']:.2f})",
        **m))
    # surface nets' smoothed output itself, before pymeshlab: what pymeshlab got
    ply = work / f"{name}.sn.ply"
    C.write_ply(ply, p.astype(np.float32), tri, lab)
    m = septa_measure(exe, ply, ref, L)
    rows.append(dict(pipeline="vtkSurfaceNets3D (smoothing), not remeshed", time=best["sn"],
                     stages=f"surface nets {best['sn']:.2f}", **m))
    if args.workdir is None:
        ply.unlink()
    for key, variant, label in [("pml_whole", "whole", "whole mesh"), ("pml_label", "per-label", "per label")]:
        if variant not in results:
            continue
        q, t, lb = results[variant]
        ply = work / f"{name}.pml_{variant}.ply"
        C.write_ply(ply, q.astype(np.float32), t, lb)
        m = septa_measure(exe, ply, ref, L)
        rows.append(dict(
            pipeline=f"vtkSurfaceNets3D (smoothing) + pymeshlab, {label}",
            time=best["sn"] + best[key],
            stages=f"surface nets {best['sn']:.2f} ({sn_size[1]:,} triangles), "
            f"pymeshlab {best[key]:.2f}",
            **m))
        if args.workdir is None:
            ply.unlink()
    for r in rows:
        r["ratio"] = r["time"] / rows[0]["time"]
        r["volumes"] = volume_changes(r["quality"], voxels)
    # the exact extraction's own volume error, for scale (the reference volumes
    # of septa's quality report are EXACT's)
    exact_vol = {
        l["value"]: (l["reference_mm3"] - voxels[l["value"]]) / voxels[l["value"]]
        for l in rows[0]["quality"]["labels"]
        if not l["unbounded"] and l["reference_mm3"] is not None and voxels.get(l["value"], 0) > 0
    }
    if args.workdir is None:
        shutil.rmtree(work, ignore_errors=True)

    tables = tables_of(rows, fg, exact_vol, voxels)
    for t in tables:
        print()
        print_table(t)
    text = markdown(header, rows, tables)
    path = args.remesh_out
    doc = path.read_text() if path.exists() else ""
    # a given volume has its own block, the phantom the original one
    begin, end = (BEGIN, END) if not given else (
        BEGIN.replace("begin", f"{name} begin"), END.replace("end", f"{name} end"))
    block = begin + "\n" + text + "\n" + end
    if begin in doc and end in doc:
        pre, rest = doc.split(begin, 1)
        doc = pre + block + rest.split(end, 1)[1]
    else:
        doc = doc.rstrip("\n") + "\n\n" + block + "\n"
    path.write_text(doc)
    print(f"\nwrote {path}")


def pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def tables_of(rows, fg, exact_vol, voxels):
    t1 = [["pipeline", "time (s)", "÷ septa", "vertices", "triangles", "edges in [0.8 L, 1.33 L]",
           "mean / L", "std / L", "min angle", "min angle 1st pct", "min angle ≥ 20°",
           "Hausdorff to exact (mm / voxels)", "volume change vs voxels: worst / mean of abs."]]
    for r in rows:
        q = r["quality"]
        e, a, d = q["edges"], q["angles"], q["distance"]
        ch = [abs(v) for v in r["volumes"].values()]
        t1.append([r["pipeline"], f"{r['time']:.2f}", f"{r['ratio']:.1f}", f"{q['vertices']:,}",
                   f"{q['triangles']:,}", pct(e["within_range"]), f"{e['mean_rel']:.3f}",
                   f"{e['std_rel']:.3f}", f"{a['min_deg']:.1f}°", f"{a['min_p1_deg']:.1f}°",
                   pct(a["min_ge_20"]),
                   f"{d['hausdorff_mm']:.2f} / {d['hausdorff_voxels']:.2f}",
                   f"{100 * max(ch):.2f} % / {100 * sum(ch) / len(ch):.2f} %" if ch else "–"])
    t2 = [["pipeline"] + [c for _, c in CHECKS] + ["passed"]]
    for r in rows:
        t2.append([r["pipeline"]] + [f"{r['check'].get(name, '–'):,}" if name in r["check"] else "–"
                                     for name, _ in CHECKS] + ["yes" if r["passed"] else "no"])
    t3 = [["label", "voxels × voxel volume (mm³)", "exact extraction"] + [r["pipeline"] for r in rows]]
    for l in fg:
        t3.append([str(l), f"{voxels[l]:,.0f}",
                   f"{100 * exact_vol[l]:+.2f} %" if l in exact_vol else "–"]
                  + [f"{100 * r['volumes'][l]:+.2f} %" if l in r["volumes"] else "–" for r in rows])
    t4 = [["pipeline", "stages (s)"]] + [[r["pipeline"], r["stages"]] for r in rows]
    return [t1, t2, t3, t4]


def print_table(lines):
    w = [max(len(l[i]) for l in lines) for i in range(len(lines[0]))]
    for k, l in enumerate(lines):
        print("  ".join(c.ljust(w[i]) for i, c in enumerate(l)))
        if k == 0:
            print("  ".join("-" * x for x in w))


def md_table(lines):
    out = ["| " + " | ".join(lines[0]) + " |", "|" + "---|" * len(lines[0])]
    out += ["| " + " | ".join(l) + " |" for l in lines[1:]]
    return out


def markdown(header, rows, tables):
    md = ["Measured by `python3 bench/compare.py --remesh` (generated; see bench/README.md):", ""]
    md += [f"- {k}: {v}" for k, v in header.items()]
    md += ["", "Time and quality (quality by `septa check --reference EXACT --target-edge L`, "
           "the same code as septa's manifest; EXACT = `septa extract --no-remesh`):", ""]
    md += md_table(tables[0])
    md += ["", "`septa check --intersections`: failures per check:", ""]
    md += md_table(tables[1])
    md += ["", "Enclosed volume per label against voxel count × voxel volume:", ""]
    md += md_table(tables[2])
    md += ["", "Stages (best of the repeats):", ""]
    md += md_table(tables[3])
    return "\n".join(md)
