//! `septa hyper` end to end: the generated fireball (a blob splitting in two)
//! as a 4-D NIfTI and as 3-D frames, the files written, and bad input.

use std::path::Path;
use std::process::{Command, Output};

use septa::hyper::check_closed_manifold;
use septa::hyper::fireball::{FIREBALL_ISO, fireball};
use septa::hyper::ply::read_hypersurface_ply;
use septa::io::mesh_ply::read_ply;
use septa::io::{Image, Samples};
use septa::mesh::validate::{Options, validate};
use septa::volume::Geometry;

fn septa<I, S>(args: I) -> Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    Command::new(env!("CARGO_BIN_EXE_septa"))
        .args(args)
        .output()
        .expect("septa runs")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("summary.json")).unwrap()).unwrap()
}

/// Frame `k` of a 4-D image as a 3-D image.
fn frame_of(img: &Image, k: usize) -> Image {
    let n = img.dims[0] * img.dims[1] * img.dims[2];
    let Samples::F32(v) = &img.samples else {
        panic!("float samples")
    };
    Image {
        dims: img.dims[..3].to_vec(),
        samples: Samples::F32(v[k * n..(k + 1) * n].to_vec()),
        geometry: img.geometry,
        time_step: None,
        path: format!("frame{k}").into(),
        sources: Vec::new(),
    }
}

#[test]
fn fireball_splits_in_two() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("fireball.nii.gz");
    // 18³ voxels of 1.5 mm, 7 frames of 0.5 s
    let img = fireball(18, 7, 1.5, 0.5);
    septa::io::nifti::write_image(&vol, &img).unwrap();
    let out = dir.path().join("out");
    let o = septa([
        "hyper".as_ref(),
        vol.as_os_str(),
        "--iso".as_ref(),
        FIREBALL_ISO.to_string().as_ref(),
        "--times".as_ref(),
        "0:3:0.5".as_ref(),
        "--at-time".as_ref(),
        "1.25".as_ref(),
        "--field".as_ref(),
        vol.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("closed oriented  yes"), "{}", text(&o));
    let s = summary(&out);
    assert_eq!(s["hypersurface"]["closed_oriented"], true);
    assert_eq!(s["parameters"]["time_step"], 0.5);
    assert_eq!(s["input"]["dims"], serde_json::json!([18, 18, 18, 7]));
    let slices = s["slices"].as_array().unwrap();
    assert_eq!(slices.len(), 8);
    let names: Vec<&str> = slices.iter().map(|x| x["file"].as_str().unwrap()).collect();
    assert_eq!(names[0], "slice_t0.00.ply");
    assert!(names.contains(&"slice_t1.25.ply"));
    assert_eq!(names[7], "slice_t3.00.ply");
    // one blob at the start, two at the end; every slice a valid closed surface
    let components: Vec<u64> = slices
        .iter()
        .map(|x| x["components"].as_u64().unwrap())
        .collect();
    assert_eq!(components[0], 1);
    assert_eq!(*components.last().unwrap(), 2);
    assert!(
        components.windows(2).all(|w| w[0] <= w[1]),
        "{components:?}"
    );
    for x in slices {
        assert_eq!(x["valid"], true);
        let m = read_ply(&out.join(x["file"].as_str().unwrap()))
            .unwrap()
            .mesh;
        assert!(m.triangle_count() > 0);
        let r = validate(&m, &Options::default());
        assert!(r.passed(), "{}", r.summary());
        // physical space: the blobs stay inside the volume's box (±13.5 mm)
        assert!(m.positions.iter().all(|p| p.abs().max_element() < 13.5));
    }
    // frame times say which frame they are
    assert_eq!(slices[2]["frame"], 2);
    assert!(slices[3]["frame"].is_null());
    // the hypersurface file: 4-D vertices, tetrahedra, closed and oriented
    let h = read_hypersurface_ply(&out.join("hypersurface.ply")).unwrap();
    assert_eq!(
        h.tets.len() as u64,
        s["hypersurface"]["tetrahedra"].as_u64().unwrap()
    );
    assert!(check_closed_manifold(h.points.len(), &h.tets).passed());
    // --field: the iso field itself is ≈ iso at the support points
    let values = h.values.as_ref().expect("value property");
    // (support points between frames 0 and 6: 0 s < t < 3 s)
    let support: Vec<f64> = (0..values.len())
        .filter(|&i| h.kinds[i] == 0 && h.points[i][3] > 0.0 && h.points[i][3] < 3.0)
        .map(|i| values[i])
        .collect();
    let near = support.iter().filter(|v| (**v - 50.0).abs() < 1e-3).count();
    assert!(
        near * 100 >= support.len() * 95,
        "{near} of {}",
        support.len()
    );
    let tmax = h.points.iter().map(|p| p[3]).fold(f64::MIN, f64::max);
    assert!(tmax > 2.5 && tmax <= 3.25, "{tmax}");

    // the same frames given one by one give the same hypersurface
    let mut args: Vec<std::ffi::OsString> = vec!["hyper".into(), "--frames".into()];
    for k in 0..7 {
        let p = dir.path().join(format!("f{k}.nii"));
        septa::io::nifti::write_image(&p, &frame_of(&img, k)).unwrap();
        args.push(p.into());
    }
    let out2 = dir.path().join("out2");
    for a in [
        "--iso",
        "50",
        "--time-step",
        "0.5",
        "--at-time",
        "1.25",
        "--json",
        "-o",
    ] {
        args.push(a.into());
    }
    args.push(out2.clone().into());
    let o = septa(&args);
    assert!(o.status.success(), "{}", text(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        j["hypersurface"]["tetrahedra"],
        s["hypersurface"]["tetrahedra"]
    );
    let a = read_ply(&out.join("slice_t1.25.ply")).unwrap().mesh;
    let b = read_ply(&out2.join("slice_t1.25.ply")).unwrap().mesh;
    assert_eq!(a.positions, b.positions);
    assert_eq!(a.triangles, b.triangles);

    // an existing output directory is kept unless --force
    let o = septa([
        "hyper".as_ref(),
        vol.as_os_str(),
        "--iso".as_ref(),
        "50".as_ref(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("--force"), "{}", text(&o));
    assert!(out.join("slice_t1.25.ply").exists());
}

#[test]
fn bad_input_gets_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let three = Image {
        dims: vec![4, 4, 4],
        samples: Samples::U8(vec![0; 64]),
        geometry: Geometry::identity(),
        time_step: None,
        path: "x".into(),
        sources: Vec::new(),
    };
    let vol3 = d.join("vol3.nii");
    septa::io::nifti::write_image(&vol3, &three).unwrap();
    let mut other = three.clone();
    other.dims = vec![4, 4, 5];
    other.samples = Samples::U8(vec![0; 80]);
    let vol3b = d.join("vol3b.nii");
    septa::io::nifti::write_image(&vol3b, &other).unwrap();
    let out = d.join("out");
    let o = out.to_str().unwrap();
    let v3 = vol3.to_str().unwrap();
    let v3b = vol3b.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["hyper", v3, "--iso", "1", "-o", o], "--frames"),
        (
            vec!["hyper", "--frames", v3, v3b, "--iso", "1", "-o", o],
            "same grid",
        ),
        (vec!["hyper", v3, "--iso", "abc", "-o", o], "invalid value"),
        (
            vec![
                "hyper",
                "--frames",
                v3,
                v3,
                "--iso",
                "1",
                "--at-time",
                "x",
                "-o",
                o,
            ],
            "invalid value",
        ),
        (
            vec![
                "hyper", "--frames", v3, v3, "--iso", "1", "--times", "0:1", "-o", o,
            ],
            "START:STOP:STEP",
        ),
        (
            vec![
                "hyper", "--frames", v3, v3, "--iso", "1", "--times", "0:1:0", "-o", o,
            ],
            "STEP must be positive",
        ),
        (
            vec![
                "hyper",
                "--frames",
                v3,
                v3,
                "--iso",
                "1",
                "--time-step",
                "-1",
                "-o",
                o,
            ],
            "positive",
        ),
        (
            vec!["hyper", "--frames", v3, "--iso", "1", "-o", o],
            "--frames",
        ),
        (vec!["hyper", "--iso", "1", "-o", o], "VOLUME"),
        (
            vec![
                "hyper", "--frames", v3, v3, "--iso", "1", "--field", v3, "-o", o,
            ],
            "same grid and frames",
        ),
        (
            vec!["hyper", "missing.nii", "--iso", "1", "-o", o],
            "missing.nii",
        ),
        (
            vec!["hyper", "--frames", v3, v3, "--iso", "nan", "-o", o],
            "NaN",
        ),
    ];
    for (args, expect) in cases {
        let r = septa(&args);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {}", text(&r));
        assert!(text(&r).contains(expect), "{args:?}: {}", text(&r));
        assert!(!text(&r).contains("panicked"), "{args:?}: {}", text(&r));
        assert!(!out.exists());
    }
    // two identical all-dark frames: empty but valid output
    let r = septa([
        "hyper",
        "--frames",
        v3,
        v3,
        "--iso",
        "1",
        "--at-time",
        "0",
        "-o",
        o,
    ]);
    assert!(r.status.success(), "{}", text(&r));
    assert!(text(&r).contains("empty hypersurface"));
    assert_eq!(summary(&out)["slices"][0]["triangles"], 0);
}
