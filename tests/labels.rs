//! Per-label surfaces in every format, label names from files, meshing a
//! subset of labels (`--per-label`, `--label-names`, `--labels`/`--others`),
//! and `septa check` on one patch file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use septa::config::{Config, LabelRef, RemeshOptions};
use septa::io::Space;
use septa::io::label_files::LabelFormats;
use septa::io::mesh_ply::{mesh_from_arrays, read_ply};
use septa::labels::LabelSelection;
use septa::mesh::InterfaceMesh;
use septa::mesh::validate::{Options, validate, validate_label_surface};
use septa::output::{Formats, OutDir, write_outdir};
use septa::pipeline::{PipelineOptions, PipelineResult, run};
use septa::volume::{Dims, Geometry, LabelVolume};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn phantom() -> (LabelVolume, Config) {
    let image = septa::io::read_image(
        &root().join("data/heart_phantom_48.nii.gz"),
        &Default::default(),
    )
    .unwrap();
    let config = Config::from_file(&root().join("configs/heart.toml")).unwrap();
    (image.into_label_volume().unwrap(), config)
}

fn no_remesh() -> PipelineOptions {
    PipelineOptions {
        remesh: RemeshOptions {
            enabled: Some(false),
            ..Default::default()
        },
        ..Default::default()
    }
}

fn extract(volume: LabelVolume, config: &Config, options: &PipelineOptions) -> PipelineResult {
    let r = run(volume, config, options, &mut |_| {}).unwrap();
    assert!(r.report.passed(), "{}", r.report.summary());
    r
}

/// The triangles of `mesh` that touch the label of value `value`, oriented
/// outward from it (whatever the file's label order), as one closed surface
/// from `inside` to `outside`: septa's validator then checks that it is
/// closed, manifold at every edge and vertex, oriented, and faces outward.
fn as_one_surface(mesh: &InterfaceMesh, value: i64) -> InterfaceMesh {
    let mut triangles = Vec::new();
    for (t, &p) in mesh.triangle_patch.iter().enumerate() {
        let [a, b] = mesh.patches[p as usize].labels.map(|l| mesh.label_value(l));
        let [i, j, k] = mesh.triangles[t].map(i64::from);
        if a == value {
            triangles.push([i, j, k]);
        } else if b == value {
            triangles.push([i, k, j]);
        }
    }
    // drop the vertices no triangle uses
    let mut used: Vec<i64> = triangles.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    let local = |v: i64| used.binary_search(&v).unwrap() as i64;
    let triangles: Vec<[i64; 3]> = triangles.iter().map(|t| t.map(local)).collect();
    let positions = used.iter().map(|&v| mesh.positions[v as usize]).collect();
    mesh_from_arrays(positions, &triangles, None, &BTreeMap::new()).unwrap()
}

fn assert_closed(mesh: &InterfaceMesh, what: &str) {
    let report = validate(
        mesh,
        &Options {
            intersections: true,
            fidelity: None,
        },
    );
    assert!(report.passed(), "{what}: {}", report.summary());
    assert!(mesh.triangle_count() > 0, "{what}: empty");
}

#[test]
fn every_label_surface_of_the_phantom_is_closed_manifold_and_outward() {
    let (volume, config) = phantom();
    let r = extract(volume, &config, &no_remesh());
    let labels = r.mesh.labels_with_patches();
    assert_eq!(labels.len(), 8);
    for l in labels {
        let surface = r.mesh.label_surface_mesh(l);
        let name = r.mesh.label_name(l);
        assert_eq!(surface.labels[0].name, name);
        assert_eq!(surface.label_surface(0).len(), surface.triangle_count());
        assert_closed(&as_one_surface(&surface, r.mesh.label_value(l)), &name);
        // outward: positive volume, but for the outside (it encloses the rest)
        let v = surface.signed_volume(&surface.triangles);
        assert_eq!(v > 0.0, name != "background", "{name}: volume {v}");
    }
}

#[test]
fn per_label_files_in_every_format_are_closed_surfaces() {
    let (volume, config) = phantom();
    let mut r = extract(volume, &config, &no_remesh());
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let formats = Formats {
        obj: false,
        per_label: LabelFormats {
            stl: true,
            obj: true,
            ply: true,
            vtp: true,
        },
        preview: false,
    };
    let files = write_outdir(
        &OutDir::new(&out, false),
        &r.mesh,
        formats,
        Space::Ras,
        &mut r.manifest,
    )
    .unwrap();
    for name in [
        "background",
        "lv_blood",
        "rv_blood",
        "la_blood",
        "ra_blood",
        "myocardium",
        "aorta",
        "pulmonary_artery",
    ] {
        for ext in ["stl", "obj", "ply", "vtp"] {
            let rel = PathBuf::from(format!("labels/{name}.{ext}"));
            assert!(files.contains(&rel), "{rel:?} not in {files:?}");
            assert!(out.join(&rel).is_file(), "{rel:?}");
        }
        let value = r
            .manifest
            .labels
            .iter()
            .find(|l| l.name == name)
            .unwrap()
            .value;
        let ply = read_ply(&out.join(format!("labels/{name}.ply"))).unwrap();
        assert_closed(&as_one_surface(&ply.mesh, value), name);
        // the header marks it as that label's surface, and the library checks it so
        assert_eq!(ply.surface_of, Some(value), "{name}");
        assert!(ply.notes.is_empty(), "{name}: {:?}", ply.notes);
        let id = ply
            .mesh
            .labels
            .iter()
            .position(|l| l.value == value)
            .unwrap() as septa::volume::LabelId;
        let options = Options::default();
        let report = validate_label_surface(&ply.mesh, id, &options).unwrap();
        assert!(report.passed(), "{name}: {}", report.summary());
        // ... which sees a hole: one triangle less is an open surface
        let mut holed = ply.mesh.clone();
        holed.triangles.pop();
        holed.triangle_patch.pop();
        let report = validate_label_surface(&holed, id, &options).unwrap();
        assert!(!report.passed(), "{name}: a hole passed");
        // the file names the label and its neighbours, and nothing else
        let vtp = std::fs::read_to_string(out.join(format!("labels/{name}.vtp"))).unwrap();
        assert!(
            vtp.contains(&format!("<!-- label {value} {name} -->")),
            "{name}"
        );
        assert!(vtp.contains("SPACE=RAS"));
        let obj = std::fs::read_to_string(out.join(format!("labels/{name}.obj"))).unwrap();
        assert!(obj.contains(&format!("o {name}__")), "{name}");
        // STL: 84 bytes of header and count, 50 per triangle, as many as the PLY
        let stl = std::fs::metadata(out.join(format!("labels/{name}.stl"))).unwrap();
        assert_eq!(stl.len(), 84 + 50 * ply.mesh.triangle_count() as u64);
    }
    let listed: Vec<&str> = r.manifest.files.iter().map(String::as_str).collect();
    assert!(listed.contains(&"labels/myocardium.vtp"));
}

/// 0 outside, three boxes: 1 and 2 side by side, 3 on top of both.
fn three_labels() -> LabelVolume {
    let n = 12;
    let mut v = vec![0i64; n * n * n];
    for z in 2..10 {
        for y in 2..10 {
            for x in 2..10 {
                v[x + n * (y + n * z)] = if z >= 7 {
                    3
                } else if x < 6 {
                    1
                } else {
                    2
                };
            }
        }
    }
    LabelVolume::from_values(Dims::new(n, n, n).unwrap(), &v, Geometry::identity()).unwrap()
}

fn pairs(r: &PipelineResult) -> Vec<[i64; 2]> {
    r.manifest
        .patches
        .iter()
        .map(|p| [p.label_a, p.label_b])
        .collect()
}

#[test]
fn a_subset_of_labels_gives_only_their_patches() {
    let config = Config::default();
    let all = extract(three_labels(), &config, &no_remesh());
    assert_eq!(
        pairs(&all),
        [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    );
    let options = PipelineOptions {
        labels: Some(LabelSelection {
            keep: vec![LabelRef::Value(1), LabelRef::Value(3)],
            others: None,
        }),
        ..no_remesh()
    };
    let some = extract(three_labels(), &config, &options);
    assert_eq!(pairs(&some), [[0, 1], [0, 3], [1, 3]]);
    let sel = some.manifest.parameters.label_selection.as_ref().unwrap();
    assert_eq!(
        (sel.kept.clone(), sel.merged.clone(), sel.into),
        (vec![0, 1, 3], vec![2], 0)
    );
    // label 1 keeps its voxels; its surface meets the outside where it touched
    // 2 (the VESTA surface moves a little only near the old junctions)
    let l1 = |r: &PipelineResult| {
        r.report
            .labels
            .iter()
            .find(|l| l.value == 1)
            .map(|l| l.volume_mm3)
            .unwrap()
    };
    let (before, after) = (l1(&all), l1(&some));
    assert!((before - after).abs() < 0.05 * before, "{before} {after}");

    // the others into a chosen label, by name
    let config = Config::from_toml_str("[labels]\n3 = \"top\"\n", "c.toml".as_ref()).unwrap();
    let options = PipelineOptions {
        labels: Some(LabelSelection {
            keep: vec![LabelRef::Value(1)],
            others: Some(LabelRef::Name("top".into())),
        }),
        ..no_remesh()
    };
    let into = extract(three_labels(), &config, &options);
    assert_eq!(pairs(&into), [[0, 1], [0, 3], [1, 3]]);
    let top = into.manifest.labels.iter().find(|l| l.value == 3).unwrap();
    assert_eq!(top.name, "top");
    // 2's voxels are 3's now: 8 × 4 × 5 + 8 × 8 × 3
    assert_eq!(top.voxels, 160 + 192);
}

#[test]
fn a_bad_selection_is_an_error_not_a_panic() {
    let config = Config::default();
    for (keep, others, needle) in [
        (vec![], None, "no label"),
        (vec![LabelRef::Value(7)], None, "does not occur"),
        (
            vec![LabelRef::Name("lv".into())],
            None,
            "unknown label name",
        ),
        (
            vec![LabelRef::Value(1)],
            Some(LabelRef::Name("x".into())),
            "others",
        ),
    ] {
        let options = PipelineOptions {
            labels: Some(LabelSelection { keep, others }),
            ..no_remesh()
        };
        let e = run(three_labels(), &config, &options, &mut |_| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains(needle), "{e} should mention {needle}");
    }
}

fn septa(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_septa"))
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

#[test]
fn cli_labels_names_and_per_label_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // an ITK-SNAP label description renaming two of the phantom's labels
    std::fs::write(
        d.join("names.txt"),
        "# ITK-SnAP Label Description File\n\
         0 0 0 0 0 0 0 \"Clear Label\"\n\
         1 255 0 0 1 1 1 \"Left ventricle\"\n\
         5 0 255 0 1 1 1 \"heart muscle\"\n",
    )
    .unwrap();
    let volume = root().join("data/heart_phantom_48.nii.gz");
    let config = root().join("configs/heart.toml");
    let o = septa(
        &[
            "-v",
            "extract",
            volume.to_str().unwrap(),
            "-c",
            config.to_str().unwrap(),
            "--label-names",
            "names.txt",
            "--labels",
            "Left ventricle,heart muscle",
            "--per-label",
            "ply,stl",
            "--no-remesh",
            "-o",
            "out",
        ],
        d,
    );
    assert!(o.status.success(), "{}", text(&o));
    let t = text(&o);
    assert!(t.contains("Left ventricle | heart muscle"), "{t}");
    assert!(t.contains("merged into Clear Label"), "{t}");
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("out/manifest.json")).unwrap())
            .unwrap();
    let names: Vec<&str> = manifest["labels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["Clear Label", "Left ventricle", "heart muscle"]);
    for f in [
        "labels/Left_ventricle.ply",
        "labels/heart_muscle.stl",
        "labels/Clear_Label.ply",
        "patches/Left_ventricle__heart_muscle.ply",
    ] {
        assert!(d.join("out").join(f).is_file(), "{f}");
    }
    let ply = std::fs::read(d.join("out/labels/heart_muscle.ply")).unwrap();
    assert!(String::from_utf8_lossy(&ply[..400]).contains("comment label 5 heart muscle"));

    // a malformed names file: the line, and nothing written
    std::fs::write(d.join("bad.ctbl"), "0 bg 0 0 0 0\n1 lv 0 0\n").unwrap();
    let o = septa(
        &[
            "extract",
            volume.to_str().unwrap(),
            "--label-names",
            "bad.ctbl",
            "-o",
            "bad",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("bad.ctbl: line 2"), "{}", text(&o));
    assert!(!d.join("bad").exists());
    // an unknown label to mesh
    let o = septa(
        &[
            "extract",
            volume.to_str().unwrap(),
            "--labels",
            "99",
            "-o",
            "bad",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("--labels 99"), "{}", text(&o));

    // one patch file: checked as an open patch, and it passes
    let o = septa(
        &["check", "out/patches/Left_ventricle__heart_muscle.ply"],
        d,
    );
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(
        t.contains("open by design") && !t.contains("VIOLATED"),
        "{t}"
    );
}
