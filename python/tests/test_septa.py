"""Tests of the Python package: numpy volumes in, meshes out."""

import json
import os
import shutil
import subprocess
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import septa

ROOT = Path(__file__).resolve().parents[2]
PHANTOM = ROOT / "data" / "heart_phantom_48.nii.gz"
HEART = ROOT / "configs" / "heart.toml"


def nested_cubes(n=12):
    """0 outside, a cube of 1, a cube of 2 inside it, a cube of 3 touching both."""
    v = np.zeros((n, n, n), dtype=np.int16)
    v[2:10, 2:10, 2:10] = 1
    v[4:7, 4:7, 4:7] = 2
    v[7:10, 2:5, 2:6] = 3
    return v


def edge_uses(triangles):
    """How many triangles use each undirected edge."""
    t = np.asarray(triangles)
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    return Counter(map(tuple, edges))


def signed_volume(s):
    v = s.vertices[s.triangles]
    return np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0


def test_numpy_volume_gives_labelled_arrays():
    m = septa.extract(nested_cubes(), spacing=(1.0, 1.0, 1.0), remesh=False)
    assert m.vertices.dtype == np.float64 and m.vertices.shape[1] == 3
    assert m.triangles.shape == (len(m.labels), 3) and m.triangles.dtype == np.int64
    assert m.labels.shape == (len(m.triangles), 2)
    assert m.patch.shape == (len(m.triangles),)
    assert np.all(m.labels[:, 0] < m.labels[:, 1])
    pairs = {tuple(p) for p in m.labels.tolist()}
    assert pairs == {(0, 1), (0, 3), (1, 2), (1, 3), (2, 3)}
    assert m.manifest["triangles"] == len(m.triangles)
    assert m.manifest["vertices"] == len(m.vertices)
    assert m.manifest["quality"] is None and m.quality == {}
    assert len(m.junctions) > 0
    for j in m.junctions:
        assert len(j.labels) >= 3
        assert np.allclose(j.points, m.vertices[j.vertex_ids])
    assert "Interfaces" in repr(m)


def test_label_surfaces_are_closed_and_outward():
    m = septa.extract(nested_cubes(), remesh=False, space="lps")
    for label in (1, 2, 3):
        s = m.label_surface(label)
        assert set(edge_uses(s.triangles).values()) == {2}, label
        assert signed_volume(s) > 0, label
    # the inner cube: 27 voxels; the VESTA surface cuts the corners, so less
    assert 10 < signed_volume(m.label_surface(2)) < 27
    with pytest.raises(septa.ParameterError):
        m.label_surface(99)


def test_patch_by_label_pair_in_either_order():
    m = septa.extract(nested_cubes(), remesh=False)
    forward = m.patch(1, 2)
    backward = m.patch(2, 1)
    assert len(forward.triangles) == np.count_nonzero((m.labels == [1, 2]).all(axis=1))
    assert np.array_equal(forward.triangles[:, ::-1], backward.triangles)
    with pytest.raises(septa.ParameterError):
        m.patch(0, 2)


def test_ras_is_lps_with_x_and_y_negated():
    v = nested_cubes()
    ras = septa.extract(v, remesh=False, space="ras")
    lps = septa.extract(v, remesh=False, space="lps")
    assert np.array_equal(ras.triangles, lps.triangles)
    assert np.allclose(ras.vertices, lps.vertices * [-1, -1, 1])


def test_affine_and_spacing_agree():
    v = nested_cubes()
    by_spacing = septa.extract(v, spacing=(2.0, 1.0, 0.5), remesh=False, space="lps")
    # nibabel's RAS affine of an LPS-aligned grid: x and y flipped
    affine = np.diag([-2.0, -1.0, 0.5, 1.0])
    by_affine = septa.extract(v, affine=affine, remesh=False, space="lps")
    assert np.allclose(by_spacing.vertices, by_affine.vertices)
    assert np.allclose(by_spacing.manifest["input"]["spacing_mm"], [2.0, 1.0, 0.5])


def test_remeshing_reports_quality_and_keeps_surfaces_closed():
    m = septa.extract(nested_cubes(16), target_edge=1.5)
    assert m.manifest["parameters"]["remesh"]["target_edge"] == 1.5
    assert m.quality and "distance" in m.quality
    for label in (1, 2, 3):
        assert set(edge_uses(m.label_surface(label).triangles).values()) == {2}


def test_config_as_dict_and_as_file(tmp_path):
    v = nested_cubes()
    config = {"labels": {1: "wall", 2: "core", 3: "side"}, "remesh": {"enabled": False}}
    m = septa.extract(v, config=config)
    assert m.label_names[2] == "core"
    assert {p["name_a"] for p in m.manifest["patches"]} >= {"wall"}
    path = tmp_path / "c.toml"
    path.write_text('[labels]\n1 = "wall"\n[remesh]\nenabled = false\n')
    m2 = septa.extract(v, config=path)
    assert m2.label_names[1] == "wall"
    assert m2.manifest["input"]["config"] == str(path)


def test_errors_are_python_exceptions_with_septas_messages(tmp_path):
    v = nested_cubes()
    with pytest.raises(septa.ConfigError, match="lables"):
        septa.extract(v, config={"lables": {1: "x"}})
    with pytest.raises(septa.ParameterError, match="target_edge"):
        septa.extract(v, target_edge=-1.0)
    with pytest.raises(septa.InputError, match="integral"):
        septa.extract(v + 0.5)
    with pytest.raises(septa.InputError, match="3-D"):
        septa.extract(v[0])
    with pytest.raises(FileNotFoundError):
        septa.read_volume(tmp_path / "missing.nii.gz")
    bad = tmp_path / "bad.nii"
    bad.write_bytes(b"not a nifti file at all" * 20)
    with pytest.raises(septa.SeptaError):
        septa.read_volume(bad)
    assert issubclass(septa.InputError, ValueError)


def test_progress_reports_every_stage():
    events = []
    septa.extract(nested_cubes(), remesh=False, progress=lambda e, s, m: events.append((e, s)))
    finished = [s for e, s in events if e == "finished"]
    assert finished == ["preprocess", "extract", "validate"]


def test_save_writes_the_output_directory(tmp_path):
    m = septa.extract(nested_cubes(), remesh=False)
    out = tmp_path / "out"
    files = m.save(out, formats=["vtp"])
    assert "interfaces.ply" in files and "interfaces.vtp" in files and files[-1] == "manifest.json"
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["triangles"] == len(m.triangles)
    assert sorted(manifest["files"]) == sorted(files)
    with pytest.raises(septa.InputError, match="exists"):
        m.save(out)
    m.save(out, force=True)
    assert septa.check(out / "interfaces.ply")
    back = septa._septa.read_mesh(str(out / "interfaces.ply"))
    assert np.array_equal(back["triangles"], m.triangles)


def test_read_volume_of_the_phantom():
    vol = septa.read_volume(PHANTOM)
    assert vol.labels.shape == (48, 48, 48)
    assert vol.labels.dtype == np.int64
    assert np.allclose(vol.affine_ras, np.diag([-1, -1, 1, 1]) @ vol.affine_lps)
    assert set(np.unique(vol.labels)) >= {0, 1}


def test_nibabel_round_trip(tmp_path):
    nib = pytest.importorskip("nibabel")
    v = nested_cubes().astype(np.int16)
    affine = np.array(
        [[0.0, -1.5, 0.0, 30.0], [2.0, 0.0, 0.0, -12.0], [0.0, 0.0, 1.25, 7.0], [0, 0, 0, 1]]
    )
    path = tmp_path / "v.nii.gz"
    nib.save(nib.Nifti1Image(v, affine), path)
    vol = septa.read_volume(path)
    assert np.array_equal(vol.labels, v)
    assert np.allclose(vol.affine_ras, affine)
    # and back: what septa read, nibabel writes
    img = nib.load(path)
    assert np.array_equal(np.asarray(img.dataobj), vol.labels)
    # the RAS vertices of label 2's surface, taken back to voxel indices by
    # nibabel's affine, lie within half a voxel of one of its voxels
    m = septa.extract(np.asarray(img.dataobj), affine=img.affine, remesh=False)
    s = m.label_surface(2)
    index = nib.affines.apply_affine(np.linalg.inv(img.affine), s.vertices)
    voxels = np.argwhere(v == 2)
    offset = np.abs(index[:, None, :] - voxels[None, :, :]).max(axis=2).min(axis=1)
    assert offset.max() <= 0.5 + 1e-9


def test_to_pyvista_has_label_arrays():
    pv = pytest.importorskip("pyvista")
    m = septa.extract(nested_cubes(), remesh=False)
    mesh = m.to_pyvista()
    assert isinstance(mesh, pv.PolyData)
    assert mesh.n_cells == len(m.triangles) and mesh.n_points == len(m.vertices)
    assert np.array_equal(mesh.cell_data["label_a"], m.labels[:, 0])
    assert np.array_equal(mesh.cell_data["label_b"], m.labels[:, 1])
    assert np.array_equal(mesh.cell_data["patch"], m.patch)
    assert m.label_surface(1).to_pyvista().n_cells > 0


def septa_binary():
    found = os.environ.get("SEPTA_BIN") or shutil.which("septa")
    for candidate in [found, ROOT / "target" / "release" / "septa", ROOT / "target" / "debug" / "septa"]:
        if candidate and Path(candidate).is_file():
            return str(candidate)
    return None


def test_vtk_and_trimesh_read_the_outputs_with_labels_and_lines(tmp_path):
    """What users open: interfaces.vtp with its label arrays and junctions.vtp
    with lines in VTK (pyvista), junctions.ply as a path in trimesh."""
    pv = pytest.importorskip("pyvista")
    trimesh = pytest.importorskip("trimesh")
    pytest.importorskip("scipy")  # trimesh reads edge lists as paths with it
    binary = septa_binary()
    if binary is None:
        pytest.skip("no septa binary (set SEPTA_BIN or build with cargo build)")
    out = tmp_path / "out"
    subprocess.run([binary, "-q", "extract", str(PHANTOM), "-c", str(HEART), "-o", str(out), "--no-remesh"], check=True)
    manifest = json.loads((out / "manifest.json").read_text())
    mesh = pv.read(out / "interfaces.vtp")
    assert mesh.n_cells == manifest["triangles"]
    values = {entry["value"] for entry in manifest["labels"]}
    for name in ("label_a", "label_b"):
        assert set(np.unique(mesh.cell_data[name])) <= values
    assert (mesh.cell_data["label_a"] < mesh.cell_data["label_b"]).all()
    junctions = pv.read(out / "junctions.vtp")
    curves = len(manifest["junction_curves"])
    assert junctions.n_lines == curves > 0
    path = trimesh.load(out / "junctions.ply")
    assert len(path.entities) >= curves


def test_phantom_gives_the_same_triangles_as_the_cli(tmp_path):
    binary = septa_binary()
    if binary is None:
        pytest.skip("no septa binary (set SEPTA_BIN or build with cargo build)")
    out = tmp_path / "cli"
    subprocess.run(
        [binary, "-q", "extract", str(PHANTOM), "-c", str(HEART), "-o", str(out)], check=True
    )
    cli = json.loads((out / "manifest.json").read_text())
    vol = septa.read_volume(PHANTOM)
    m = septa.extract(vol.labels, affine=vol.affine, config=HEART, space="lps")
    assert len(m.triangles) == cli["triangles"]
    assert len(m.vertices) == cli["vertices"]
    ply = septa._septa.read_mesh(str(out / "interfaces.ply"))
    assert np.array_equal(ply["triangles"], m.triangles)
    assert np.array_equal(ply["labels"], m.labels)
    assert np.allclose(ply["vertices"], m.vertices, atol=1e-4)


def readme_block(heading, language):
    """The first ```language block after `heading` in the README."""
    text = (ROOT / "README.md").read_text()
    after = text[text.index(heading) :]
    start = after.index(f"```{language}\n") + len(f"```{language}\n")
    return after[start : after.index("```", start)]


def test_readme_python_example_runs_verbatim():
    pytest.importorskip("nibabel")
    pytest.importorskip("pyvista")
    code = readme_block("### Python", "python")
    done = subprocess.run(
        [os.sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr
    assert "septa.Interfaces" in done.stdout


def test_readme_install_command_is_the_one_ci_runs():
    install = readme_block("### Python", "sh")
    assert "pip install ./python" in install
    assert "python -m pip install ./python" in (ROOT / ".ci" / "run").read_text()


def ras_voxel_offsets(vertices, affine, labels, pair_labels, outside=0):
    """For each vertex (RAS mm), the distance in voxels (per axis, largest) to the
    nearest voxel centre of each label of its triangle's patch, by nibabel's affine."""
    nib = pytest.importorskip("nibabel")
    # outside the volume is the outside label: pad by a voxel
    index = nib.affines.apply_affine(np.linalg.inv(affine), vertices) + 1
    labels = np.pad(labels, 1, constant_values=outside)
    worst = np.zeros(len(vertices))
    shape = np.array(labels.shape)
    for tri_vertices, (a, b) in pair_labels:
        for v in tri_vertices:
            p = index[v]
            lo = np.clip(np.floor(p - 0.5 - 1e-6).astype(int), 0, shape - 1)
            hi = np.clip(np.ceil(p + 0.5 + 1e-6).astype(int), 0, shape - 1)
            block = labels[lo[0] : hi[0] + 1, lo[1] : hi[1] + 1, lo[2] : hi[2] + 1]
            for label in (a, b):
                ids = np.argwhere(block == label) + lo
                d = np.abs(ids - p).max(axis=1) if len(ids) else np.array([np.inf])
                worst[v] = max(worst[v], d.min())
    return worst


def test_cli_space_ras_overlays_nibabels_voxel_centres(tmp_path):
    nib = pytest.importorskip("nibabel")
    binary = septa_binary()
    if binary is None:
        pytest.skip("no septa binary (set SEPTA_BIN or build with cargo build)")
    out = tmp_path / "ras"
    subprocess.run(
        [binary, "-q", "extract", str(PHANTOM), "-c", str(HEART), "-o", str(out), "--space", "ras", "--no-remesh"],
        check=True,
    )
    assert "SPACE=RAS" in (out / "interfaces.vtp").read_text()[:200]
    assert json.loads((out / "manifest.json").read_text())["space"].startswith("RAS")
    ply = septa._septa.read_mesh(str(out / "interfaces.ply"))
    img = nib.load(PHANTOM)
    labels = np.asarray(img.dataobj).astype(np.int64)
    # every vertex of the exact extraction within half a voxel of a voxel of each of its
    # labels (label 0 is also outside the volume: the phantom's border is background)
    rng = np.random.default_rng(1)
    sample = rng.choice(len(ply["triangles"]), size=2000, replace=False)
    pairs = [(ply["triangles"][t], ply["labels"][t]) for t in sample]
    worst = ras_voxel_offsets(ply["vertices"], img.affine, labels, pairs)
    used = np.unique(ply["triangles"][sample])
    # vertices on the voxel grid (face centres: whole or half voxel indices) lie
    # within half a voxel (and the float32 of the file) of both labels' voxels;
    # where critical voxels were fattened (7³ subvoxels) the labels moved, by
    # less than a voxel
    index = nib.affines.apply_affine(np.linalg.inv(img.affine), ply["vertices"][used])
    on_grid = (np.abs(index * 2 - np.round(index * 2)) < 1e-3).all(axis=1)
    assert on_grid.sum() > 500
    assert worst[used][on_grid].max() <= 0.5 + 1e-3
    assert worst[used].max() < 1.0
    # the same from Python, space="ras"
    m = septa.extract(labels, affine=img.affine, config=HEART, remesh=False)
    assert np.allclose(m.vertices, ply["vertices"], atol=1e-4)


def test_cli_space_ras_overlays_nibabels_voxel_centres_on_a_real_head(tmp_path):
    """The shipped ITK k-means head (LSA orientation, 2 x 2 x 3 mm, air is label 1):
    a permuted, flipped, anisotropic grid, the case where a wrong axis shows."""
    nib = pytest.importorskip("nibabel")
    binary = septa_binary()
    if binary is None:
        pytest.skip("no septa binary (set SEPTA_BIN or build with cargo build)")
    head = ROOT / "data" / "itk_kmeans_head.nii.gz"
    out = tmp_path / "head"
    subprocess.run(
        [binary, "-q", "extract", str(head), "-o", str(out), "--space", "ras", "--no-remesh", "--no-preview"],
        check=True,
    )
    manifest = json.loads((out / "manifest.json").read_text())
    ply = septa._septa.read_mesh(str(out / "interfaces.ply"))
    img = nib.load(head)
    assert nib.aff2axcodes(img.affine) != ("R", "A", "S")
    labels = np.asarray(img.dataobj).astype(np.int64)
    values = [entry["value"] for entry in manifest["labels"]]
    assert values == list(range(len(values)))  # label ids are the values here
    rng = np.random.default_rng(2)
    sample = rng.choice(len(ply["triangles"]), size=1500, replace=False)
    pairs = [(ply["triangles"][t], ply["labels"][t]) for t in sample]
    worst = ras_voxel_offsets(ply["vertices"], img.affine, labels, pairs, outside=manifest["parameters"]["outside"])
    used = np.unique(ply["triangles"][sample])
    index = nib.affines.apply_affine(np.linalg.inv(img.affine), ply["vertices"][used])
    on_grid = (np.abs(index * 2 - np.round(index * 2)) < 1e-3).all(axis=1)
    assert on_grid.sum() > 100
    assert worst[used][on_grid].max() <= 0.5 + 1e-3
    assert worst[used].max() < 1.0


# ---- labels, per-label files, iso, hyper, check in memory ----


def three_boxes(n=12):
    """0 outside; 1 and 2 side by side, 3 on top of both."""
    v = np.zeros((n, n, n), dtype=np.int16)
    v[2:6, 2:10, 2:7] = 1
    v[6:10, 2:10, 2:7] = 2
    v[2:10, 2:10, 7:10] = 3
    return v


def test_labels_subset_and_others():
    v = three_boxes()
    m = septa.extract(v, select=[1, 3], remesh=False)
    assert {tuple(p) for p in m.labels.tolist()} == {(0, 1), (0, 3), (1, 3)}
    assert m.manifest["parameters"]["label_selection"] == {"kept": [0, 1, 3], "merged": [2], "into": 0}
    assert septa.check(m).passed
    into = septa.extract(v, select=["core"], others="top", label_names={1: "core", 3: "top"}, remesh=False)
    assert {tuple(p) for p in into.labels.tolist()} == {(0, 1), (0, 3), (1, 3)}
    assert into.label_names == {0: "label0", 1: "core", 3: "top"}
    with pytest.raises(septa.SeptaError, match="labels 9: label label9 does not occur"):
        septa.extract(v, select=[9], remesh=False)
    with pytest.raises(septa.ParameterError, match="others"):
        septa.extract(v, others=3)


def test_label_names_from_files(tmp_path):
    v = three_boxes()
    ctbl = tmp_path / "colors.ctbl"
    ctbl.write_text("# Slicer colour table\n0 Background 0 0 0 0\n1 left part 255 0 0 255\n")
    m = septa.extract(v, label_names=ctbl, remesh=False)
    assert m.label_names[1] == "left part" and m.label_names[2] == "label2"
    snap = tmp_path / "snap.txt"
    snap.write_text('# ITK-SnAP\n    0 0 0 0 0 0 0 "Clear Label"\n    3 0 0 255 1 1 1 "top box"\n')
    m = septa.extract(v, label_names=snap, remesh=False)
    assert m.label_names[3] == "top box"
    assert {p["name_a"] for p in m.manifest["patches"]} >= {"Clear Label"}
    bad = tmp_path / "bad.json"
    bad.write_text('{"1": "a", "x": "b"}')
    with pytest.raises(septa.ConfigError, match='bad.json: "x"'):
        septa.extract(v, label_names=bad, remesh=False)
    with pytest.raises(septa.ConfigError, match="also given to label 1"):
        septa.extract(v, label_names={1: "same", 2: "same"}, remesh=False)


def test_per_label_files_are_watertight_in_trimesh(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    vol = septa.read_volume(PHANTOM)
    m = septa.extract(vol.labels, affine=vol.affine_ras, config=HEART, remesh=False)
    files = m.save(tmp_path / "out", per_label=["stl", "obj", "ply", "vtp"])
    names = [n for _, n in sorted(m.label_names.items())]
    assert len(names) == 8
    for name in names:
        for ext in ("stl", "obj", "ply", "vtp"):
            assert f"labels/{name}.{ext}" in files
        for ext in ("stl", "obj", "ply"):
            mesh = trimesh.load(tmp_path / "out" / "labels" / f"{name}.{ext}", force="mesh")
            assert mesh.is_watertight, (name, ext)
            assert mesh.is_winding_consistent, (name, ext)
            # outward: positive volume, but for the outside label around everything
            assert (mesh.volume > 0) == (name != "background"), (name, ext, mesh.volume)
    with pytest.raises(septa.ParameterError, match="per-label format"):
        m.save(tmp_path / "x", per_label=["gltf"])


def test_check_in_memory_reports_failures():
    m = septa.extract(nested_cubes(), remesh=False)
    r = septa.check(m)
    assert isinstance(r, septa.CheckReport) and r and r.failures == 0 and r.failed == []
    assert {l["value"] for l in r.labels} == {0, 1, 2, 3}
    assert septa.check(m.vertices, m.triangles, m.labels).passed
    s = m.label_surface(2)
    assert septa.check(s).passed
    # a hole: drop a triangle of the closed surface
    broken = septa.check(s.vertices, s.triangles[1:])
    assert not broken and broken.failures > 0
    assert "label surfaces closed" in broken.failed
    assert "INVARIANTS VIOLATED" in broken.summary
    # a flipped triangle
    t = s.triangles.copy()
    t[0] = t[0][::-1]
    assert "label surfaces oriented" in septa.check(s.vertices, t).failed
    with pytest.raises(septa.SeptaError, match="refers to vertex"):
        septa.check(s.vertices, s.triangles + 10_000)
    with pytest.raises(septa.ParameterError, match="shape"):
        septa.check(s.vertices[:, :2], s.triangles)


def ball(n=16, r=5.0):
    x, y, z = np.mgrid[:n, :n, :n] - (n - 1) / 2
    return 100.0 * np.exp(-(x**2 + y**2 + z**2) / (2 * r * r))


def test_iso_surface_is_closed_and_matches_the_cli(tmp_path):
    v = ball()
    s = septa.iso(v, 50.0, spacing=(1.0, 1.0, 1.0), space="lps")
    assert isinstance(s, septa.Surface)
    assert set(edge_uses(s.triangles).values()) == {2}
    assert signed_volume(s) > 0
    assert septa.check(s).passed
    assert s.stats["cycles_by_length"][3] > 0
    # the same volume, other dtypes and modes
    assert len(septa.iso(v.astype(np.uint8), 50, mode="connect").triangles) > 0
    assert len(septa.iso(v.astype(np.int64), 50, mode="disconnect", decompose="h").triangles) > 0
    with pytest.raises(septa.ParameterError, match="mode"):
        septa.iso(v, 50, mode="sideways")
    with pytest.raises(septa.InputError, match="3-D"):
        septa.iso(v[0], 50)
    nib = pytest.importorskip("nibabel")
    binary = septa_binary()
    if binary is None:
        pytest.skip("no septa binary")
    path = tmp_path / "ball.nii.gz"
    nib.save(nib.Nifti1Image(v.astype(np.float32), np.diag([-1.0, -1.0, 1.0, 1.0])), path)
    subprocess.run([binary, "-q", "iso", str(path), "--iso", "50", "-o", str(tmp_path / "b.ply")], check=True)
    cli = septa._septa.read_mesh(str(tmp_path / "b.ply"))
    mine = septa.iso(v.astype(np.float32), 50, affine=np.diag([-1.0, -1.0, 1.0, 1.0]), space="lps")
    assert np.array_equal(cli["triangles"], mine.triangles)
    assert np.allclose(cli["vertices"], mine.vertices, atol=1e-4)


def test_hyper_slices_are_closed_and_frames_are_vesta():
    frames = np.stack([ball(12, 3.0), ball(12, 4.0), ball(12, 3.5)], axis=-1)
    h = septa.hyper(frames, 50.0, time_step=0.5, space="lps")
    assert "Hypersurface" in repr(h)
    assert h.points.shape[1] == 4 and h.tets.shape[1] == 4 and len(h.kinds) == len(h.points)
    assert h.check()["passed"]
    lo, hi = h.time_range
    assert lo < 0.0 and hi > 1.0
    mid = h.slice(0.25)
    assert set(edge_uses(mid.triangles).values()) == {2}
    # at a frame's time, the slice is that frame's VESTA surface (H decomposition)
    at = h.slice(0.5)
    vesta = septa.iso(frames[..., 1], 50.0, decompose="h", space="lps")
    assert len(at.triangles) == len(vesta.triangles)
    assert np.allclose(np.sort(at.vertices, axis=0), np.sort(vesta.vertices, axis=0))
    with pytest.raises(septa.InputError, match="4-D"):
        septa.hyper(frames[..., 0], 50.0)
    with pytest.raises(septa.SeptaError, match="time step"):
        septa.hyper(frames, 50.0, time_step=0.0)


def test_merge_flat_is_the_same_surface_in_fewer_triangles():
    dense = septa.extract(nested_cubes(), remesh=False)
    merged = septa.extract(nested_cubes(), remesh=False, merge_flat=True)
    assert len(merged.triangles) < 0.8 * len(dense.triangles)
    assert merged.manifest["parameters"]["merge_flat"] is True
    for label in (1, 2, 3):
        s = merged.label_surface(label)
        assert set(edge_uses(s.triangles).values()) == {2}, label
        assert signed_volume(s) == pytest.approx(signed_volume(dense.label_surface(label)), rel=1e-9)
    # remeshing smooths the extraction, which needs every point of it
    with pytest.raises(septa.ParameterError, match="--no-remesh"):
        septa.extract(nested_cubes(), merge_flat=True)
