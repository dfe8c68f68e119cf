//! `septa iso` and `septa contour` end to end: the built binary is run on
//! files written here (MetaImage volumes, PGM and PNG images), and what it
//! writes is read back and compared with the library's results on the same
//! values.

use std::path::Path;
use std::process::{Command, Output};

use glam::DVec3;
use septa::contour::diconex::{ContourOptions, LabelContourOptions, iso_contours, label_contours};
use septa::io::image2d::encode_png_gray;
use septa::io::mesh_ply::read_ply;
use septa::iso::{Decompose, IsoOptions, Mode, iso_surface};
use septa::volume::Dims;
use serde_json::Value;

fn septa<S: AsRef<std::ffi::OsStr>>(args: &[S], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_septa"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run septa")
}

#[track_caller]
fn ok(o: Output) -> String {
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    );
    assert!(
        o.status.success(),
        "septa failed\nstdout:\n{out}\nstderr:\n{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    out
}

/// Asserts a failure with a message containing every needle, and no panic.
#[track_caller]
fn fails(o: Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "septa succeeded unexpectedly:\n{err}");
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(n), "stderr lacks `{n}`:\n{err}");
    }
}

fn json(s: &str) -> Value {
    serde_json::from_str(s).unwrap_or_else(|e| panic!("bad JSON ({e}):\n{s}"))
}

fn read_json(p: &Path) -> Value {
    json(&std::fs::read_to_string(p).unwrap())
}

/// A float32 MetaImage volume with spacing (2, 1, 3) and origin (10, 20, 30).
fn write_mha(path: &Path, d: [usize; 3], v: &[f32]) {
    let mut b = format!(
        "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\nOffset = 10 20 30\nElementSpacing = 2 1 3\nDimSize = {} {} {}\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n",
        d[0], d[1], d[2]
    )
    .into_bytes();
    for x in v {
        b.extend_from_slice(&x.to_le_bytes());
    }
    std::fs::write(path, b).unwrap();
}

/// Two bumps in a 12 × 10 × 8 volume.
fn bumps() -> (Vec<f32>, [usize; 3]) {
    let d = [12, 10, 8];
    let mut v = Vec::new();
    for z in 0..d[2] {
        for y in 0..d[1] {
            for x in 0..d[0] {
                let p = DVec3::new(x as f64, y as f64, z as f64);
                let f = 100.0 * (-(p - DVec3::new(3.5, 4.0, 3.0)).length_squared() / 6.0).exp()
                    + 80.0 * (-(p - DVec3::new(8.0, 5.5, 4.5)).length_squared() / 4.0).exp()
                    + ((x * 7 + y * 3 + z) % 5) as f64;
                v.push(f as f32);
            }
        }
    }
    (v, d)
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

// ───────────────────────────── septa iso ─────────────────────────────

#[test]
fn iso_writes_the_library_surface_with_its_statistics() {
    let dir = tmp();
    let (v, d) = bumps();
    let vol = dir.path().join("bumps.mha");
    write_mha(&vol, d, &v);
    let geometry = septa::io::read_image(&vol, &Default::default())
        .unwrap()
        .geometry;
    for (mode, dec) in [("mixed", "l"), ("connect", "h"), ("disconnect", "l")] {
        let out = dir.path().join(format!("s_{mode}_{dec}.ply"));
        let j = json(&ok(septa(
            &[
                "iso",
                p(&vol),
                "--iso",
                "40",
                "--mode",
                mode,
                "--decompose",
                dec,
                "-o",
                p(&out),
                "--json",
                "--check",
            ],
            dir.path(),
        )));
        let o = IsoOptions {
            iso: 40.0,
            mode: mode.parse().unwrap(),
            decompose: if dec == "l" {
                Decompose::L
            } else {
                Decompose::H
            },
            displace: true,
        };
        let s = iso_surface(&v, Dims::new(d[0], d[1], d[2]).unwrap(), geometry, &o).unwrap();
        assert_eq!(j["valid"], true);
        assert_eq!(j["points"], s.stats.points);
        assert_eq!(j["triangles"], s.stats.triangles);
        assert_eq!(j["parameters"]["mode"], mode);
        for n in 3..=12 {
            assert_eq!(
                j["cycles"][n.to_string()],
                s.stats.cycles_by_length[n],
                "{n}-cycles"
            );
        }
        let back = read_ply(&out).unwrap().mesh;
        assert_eq!(back.triangles, s.mesh.triangles);
        assert_eq!(back.vertex_count(), s.mesh.vertex_count());
        for (a, b) in back.positions.iter().zip(&s.mesh.positions) {
            assert!((*a - *b).length() < 1e-4, "{a} vs {b}");
        }
        // physical space: x spacing 2 and origin 10 put the surface in x ∈ (10, 34)
        let xs: Vec<f64> = back.positions.iter().map(|q| q.x.abs()).collect();
        assert!(xs.iter().all(|&x| (10.0..34.0).contains(&x)), "{xs:?}");
    }
    // the text summary has the N-cycle table
    let txt = ok(septa(
        &[
            "iso",
            p(&vol),
            "--iso",
            "40",
            "-o",
            "s.obj",
            "--no-displace",
        ],
        dir.path(),
    ));
    for n in 3..=12 {
        assert!(txt.contains(&format!("{n}-cycles")), "{txt}");
    }
    assert!(
        txt.contains("cycle sum") && txt.contains("triangles"),
        "{txt}"
    );
    let obj = std::fs::read_to_string(dir.path().join("s.obj")).unwrap();
    assert!(obj.lines().filter(|l| l.starts_with("f ")).count() > 100);
    for f in ["s.stl", "s.vtp"] {
        ok(septa(&["iso", p(&vol), "--iso", "40", "-o", f], dir.path()));
        assert!(std::fs::metadata(dir.path().join(f)).unwrap().len() > 100);
    }
}

#[test]
fn iso_bad_input_gets_clear_errors() {
    let dir = tmp();
    let (v, d) = bumps();
    let vol = dir.path().join("bumps.mha");
    write_mha(&vol, d, &v);
    fails(
        septa(
            &["iso", "missing.mha", "--iso", "1", "-o", "x.ply"],
            dir.path(),
        ),
        &["missing.mha"],
    );
    fails(
        septa(&["iso", p(&vol), "--iso", "1", "-o", "x.txt"], dir.path()),
        &["x.txt", ".ply"],
    );
    fails(
        septa(&["iso", p(&vol), "--iso", "1", "-o", p(&vol)], dir.path()),
        &["input"],
    );
    fails(
        septa(&["iso", p(&vol), "--iso", "NaN", "-o", "x.ply"], dir.path()),
        &["NaN"],
    );
    fails(
        septa(
            &[
                "iso",
                p(&vol),
                "--iso",
                "1",
                "--mode",
                "sideways",
                "-o",
                "x.ply",
            ],
            dir.path(),
        ),
        &["sideways"],
    );
    // an iso value above everything: an empty mesh and a warning, not an error
    let o = septa(
        &["iso", p(&vol), "--iso", "1000", "-o", "e.ply"],
        dir.path(),
    );
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success() && err.contains("empty"), "{err}");
}

#[test]
fn iso_repeat_writes_the_same_file_and_reports_both_times() {
    let dir = tmp();
    let (v, d) = bumps();
    let vol = dir.path().join("bumps.mha");
    write_mha(&vol, d, &v);
    let run = |n: &str, out: &str| {
        json(&ok(septa(
            &[
                "iso",
                p(&vol),
                "--iso",
                "40",
                "-o",
                out,
                "--repeat",
                n,
                "--json",
                "-q",
            ],
            dir.path(),
        )))
    };
    let j1 = run("1", "r1.ply");
    let j3 = run("3", "r3.ply");
    let b1 = std::fs::read(dir.path().join("r1.ply")).unwrap();
    let b3 = std::fs::read(dir.path().join("r3.ply")).unwrap();
    assert!(b1.len() > 100);
    assert!(b1 == b3, "--repeat 3 wrote other bytes than --repeat 1");
    assert_eq!(j1["repeat"], 1);
    assert_eq!(j3["repeat"], 3);
    for k in [
        "points",
        "triangles",
        "cycles",
        "cycle_types",
        "active_voxels",
    ] {
        assert_eq!(j1[k], j3[k], "{k}");
    }
    for j in [&j1, &j3] {
        let t = &j["timings_s"];
        let f = |k: &str| {
            t[k].as_f64()
                .unwrap_or_else(|| panic!("timings_s.{k} missing: {t}"))
        };
        // the best is never slower than the first
        assert!(f("extract") <= f("extract_first"), "{t}");
        assert!(f("extract_internal") <= f("extract_internal_first"), "{t}");
        assert!(f("extract_internal") > 0.0, "{t}");
    }
    // one run: the best is the first
    let t = &j1["timings_s"];
    assert_eq!(t["extract"], t["extract_first"]);
    assert_eq!(t["extract_internal"], t["extract_internal_first"]);
    // the text summary says so
    let txt = ok(septa(
        &[
            "iso",
            p(&vol),
            "--iso",
            "40",
            "-o",
            "r.ply",
            "--repeat",
            "2",
        ],
        dir.path(),
    ));
    assert!(txt.contains("fastest of 2"), "{txt}");
    // at least one run
    for bad in ["0", "-1", "x"] {
        fails(
            septa(
                &[
                    "iso",
                    p(&vol),
                    "--iso",
                    "40",
                    "-o",
                    "r0.ply",
                    &format!("--repeat={bad}"),
                ],
                dir.path(),
            ),
            &["--repeat"],
        );
    }
    assert!(!dir.path().join("r0.ply").exists());
}

// ───────────────────────────── septa contour ─────────────────────────────

/// A 9 × 7 gray image: a ring, a lone pixel, and two pixels touching at a corner.
fn gray_image() -> (Vec<u16>, usize, usize) {
    let (w, h) = (9, 7);
    let mut v = vec![10u16; w * h];
    for j in 1..5 {
        for i in 1..5 {
            if !(j == 2 && i == 2) {
                v[i + w * j] = 200;
            }
        }
    }
    v[7 + w] = 250;
    v[6 + w * 4] = 180;
    v[7 + w * 5] = 180;
    v[2 + w * 2] = 60;
    (v, w, h)
}

fn write_pgm(path: &Path, v: &[u16], w: usize, h: usize) {
    let mut b = format!("P5\n# test image\n{w} {h}\n255\n").into_bytes();
    b.extend(v.iter().map(|&x| x as u8));
    std::fs::write(path, b).unwrap();
}

#[test]
fn contour_of_pgm_and_png_matches_the_library() {
    let dir = tmp();
    let (v, w, h) = gray_image();
    write_pgm(&dir.path().join("g.pgm"), &v, w, h);
    std::fs::write(dir.path().join("g.png"), encode_png_gray(w, h, &v, false)).unwrap();
    let vf: Vec<f64> = v.iter().map(|&x| x as f64).collect();
    for mode in ["disconnect", "connect", "mixed"] {
        let o = ContourOptions {
            iso: 100.0,
            mode: mode.parse::<Mode>().unwrap(),
            displace: true,
        };
        let lib = iso_contours(&vf, w, h, &o).unwrap();
        for input in ["g.pgm", "g.png"] {
            let j = json(&ok(septa(
                &[
                    "contour", input, "--iso", "100", "--mode", mode, "-o", "c.json", "--json",
                ],
                dir.path(),
            )));
            assert_eq!(j["contour_count"], lib.contours.len());
            assert_eq!(j["holes"], lib.hole_count());
            assert_eq!(j["point_count"], lib.point_count());
            let file = read_json(&dir.path().join("c.json"));
            let cs = file["contours"].as_array().unwrap();
            assert_eq!(cs.len(), lib.contours.len());
            for (c, l) in cs.iter().zip(&lib.contours) {
                assert_eq!(c["hole"], l.is_hole());
                let pts = c["points"].as_array().unwrap();
                assert_eq!(pts.len(), l.points.len());
                for (a, b) in pts.iter().zip(&l.points) {
                    assert_eq!(a[0].as_f64().unwrap(), b.x);
                    assert_eq!(a[1].as_f64().unwrap(), b.y);
                }
            }
        }
    }
    // the ring's hole, the corner pair joined or not
    let count = |mode: &str| {
        let j = json(&ok(septa(
            &[
                "contour", "g.pgm", "--iso", "100", "--mode", mode, "-o", "c.svg", "--json",
            ],
            dir.path(),
        )));
        (
            j["contour_count"].as_u64().unwrap(),
            j["holes"].as_u64().unwrap(),
        )
    };
    assert_eq!(count("disconnect"), (5, 1));
    assert_eq!(count("connect"), (4, 1));
    // the mean of (180, 10, 10, 180) is below 100: mixed keeps them apart
    assert_eq!(count("mixed"), (5, 1));
    // SVG: one path per contour, holes marked
    let svg = std::fs::read_to_string(dir.path().join("c.svg")).unwrap();
    assert_eq!(svg.matches("<path").count(), 5);
    assert_eq!(svg.matches("class=\"hole\"").count(), 1);
    assert!(svg.trim_end().ends_with("</svg>"));
    // CSV: a header and one row per point, undisplaced at edge midpoints
    ok(septa(
        &[
            "contour",
            "g.pgm",
            "--iso",
            "100",
            "--no-displace",
            "-o",
            "c.csv",
        ],
        dir.path(),
    ));
    let csv = std::fs::read_to_string(dir.path().join("c.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("contour,hole,point,x,y"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    let lib = iso_contours(
        &vf,
        w,
        h,
        &ContourOptions {
            iso: 100.0,
            mode: Mode::Mixed,
            displace: false,
        },
    )
    .unwrap();
    assert_eq!(rows.len(), lib.point_count());
    for r in &rows {
        // one coordinate an integer, the other half-way
        assert!((r[3].fract() == 0.0) != (r[4].fract() == 0.0), "{r:?}");
    }
}

#[test]
fn contour_of_a_volume_slice_has_physical_coordinates() {
    let dir = tmp();
    let (v, d) = bumps();
    let vol = dir.path().join("bumps.mha");
    write_mha(&vol, d, &v);
    ok(septa(
        &[
            "contour",
            p(&vol),
            "--iso",
            "40",
            "--slice",
            "y=5",
            "-o",
            "s.json",
        ],
        dir.path(),
    ));
    let j = read_json(&dir.path().join("s.json"));
    assert_eq!(
        j["input"]["slice"]["pixel_axes"],
        serde_json::json!(["x", "z"])
    );
    assert_eq!(
        (j["input"]["width"].as_u64(), j["input"]["height"].as_u64()),
        (Some(12), Some(8))
    );
    let cs = j["contours"].as_array().unwrap();
    assert!(!cs.is_empty());
    for c in cs {
        let (px, mm) = (
            c["points"].as_array().unwrap(),
            c["points_mm"].as_array().unwrap(),
        );
        assert_eq!(px.len(), mm.len());
        for (a, b) in px.iter().zip(mm) {
            let (u, w) = (a[0].as_f64().unwrap(), a[1].as_f64().unwrap());
            let q: Vec<f64> = b
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            // MetaImage is LPS: x = 10 + 2 u, y = 20 + 5, z = 30 + 3 w
            assert!((q[0] - (10.0 + 2.0 * u)).abs() < 1e-9, "{q:?}");
            assert!((q[1] - 25.0).abs() < 1e-9);
            assert!((q[2] - (30.0 + 3.0 * w)).abs() < 1e-9);
        }
    }
    // the same slice through the library
    let sl: Vec<f64> = (0..d[2])
        .flat_map(|z| (0..d[0]).map(move |x| (x, z)))
        .map(|(x, z)| v[x + d[0] * (5 + d[1] * z)] as f64)
        .collect();
    let lib = iso_contours(&sl, d[0], d[2], &ContourOptions::new(40.0)).unwrap();
    assert_eq!(cs.len(), lib.contours.len());
    // CSV of a slice has millimetres too
    ok(septa(
        &[
            "contour",
            p(&vol),
            "--iso",
            "40",
            "--slice",
            "z=3",
            "-o",
            "s.csv",
        ],
        dir.path(),
    ));
    let csv = std::fs::read_to_string(dir.path().join("s.csv")).unwrap();
    assert!(csv.starts_with("contour,hole,point,x,y,x_mm,y_mm,z_mm\n"));
}

#[test]
fn label_contours_share_junction_points() {
    let dir = tmp();
    // three labels in a frame of 0: 1 | 2 side by side, 3 below both
    let (w, h) = (8, 6);
    let mut v = vec![0u16; w * h];
    for j in 1..5 {
        for i in 1..7 {
            v[i + w * j] = if j >= 3 {
                3
            } else if i < 4 {
                1
            } else {
                2
            };
        }
    }
    write_pgm(&dir.path().join("l.pgm"), &v, w, h);
    let j = json(&ok(septa(
        &["contour", "l.pgm", "--labels", "-o", "l.json", "--json"],
        dir.path(),
    )));
    let file = read_json(&dir.path().join("l.json"));
    let labels: Vec<i64> = v.iter().map(|&x| x as i64).collect();
    let lib = label_contours(&labels, w, h, &LabelContourOptions { outside: None }).unwrap();
    assert_eq!(j["polyline_count"], lib.polylines.len());
    assert_eq!(j["junctions"], lib.junction_count());
    assert_eq!(
        j["label_pairs"],
        serde_json::json!([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    );
    let first_junction = file["first_junction"].as_u64().unwrap() as usize;
    let pls = file["polylines"].as_array().unwrap();
    assert_eq!(pls.len(), lib.polylines.len());
    // junctions where three labels meet: 0|1|2 at the top, 1|2|3 in the
    // middle, 0|1|3 and 0|2|3 on the sides; each ends exactly three polylines
    let n_points = file["points"].as_array().unwrap().len();
    assert_eq!(n_points - first_junction, 4);
    for jn in first_junction..n_points {
        let ends = pls
            .iter()
            .flat_map(|pl| {
                let pts = pl["points"].as_array().unwrap();
                [
                    pts[0].as_u64().unwrap(),
                    pts[pts.len() - 1].as_u64().unwrap(),
                ]
            })
            .filter(|&i| i as usize == jn)
            .count();
        assert_eq!(ends, 3, "junction {jn}");
    }
    // CSV flags junction rows, SVG draws them
    ok(septa(
        &["contour", "l.pgm", "--labels", "-o", "l.csv"],
        dir.path(),
    ));
    let csv = std::fs::read_to_string(dir.path().join("l.csv")).unwrap();
    assert!(csv.starts_with("polyline,label_a,label_b,closed,point,point_id,junction,x,y\n"));
    let junction_rows = csv
        .lines()
        .skip(1)
        .filter(|l| l.split(',').nth(6) == Some("1"))
        .count();
    assert_eq!(junction_rows, 2 * pls.len());
    ok(septa(
        &["contour", "l.pgm", "--labels", "-o", "l.svg"],
        dir.path(),
    ));
    let svg = std::fs::read_to_string(dir.path().join("l.svg")).unwrap();
    assert_eq!(svg.matches("class=\"junction\"").count(), 4);
    // each label's pixels filled in its palette colour (by rank), and a
    // legend entry per label with the same colour
    let mut values: Vec<i64> = j["label_pairs"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|p| p.as_array().unwrap().iter().map(|v| v.as_i64().unwrap()))
        .collect();
    values.sort_unstable();
    values.dedup();
    assert!(values.len() >= 3);
    assert_eq!(svg.matches("class=\"label\"").count(), values.len());
    let legend = &svg[svg.find("class=\"legend\"").expect("a legend")..];
    for (k, v) in values.iter().enumerate() {
        let colour = septa::render::palette::hex(k);
        assert!(
            svg.contains(&format!("data-label=\"{v}\" d=\"M")) && svg.contains(&colour),
            "label {v}"
        );
        assert!(legend.contains(&format!(">{v}")), "legend lacks {v}");
        assert_eq!(legend.matches(&colour).count(), 1, "legend colour of {v}");
    }
    assert!(legend.contains("(outside)"));
    // --outside changes the frame's label
    let j = json(&ok(septa(
        &[
            "contour",
            "l.pgm",
            "--labels",
            "--outside",
            "3",
            "-o",
            "l.json",
            "--json",
        ],
        dir.path(),
    )));
    assert_eq!(j["parameters"]["outside"], 3);
}

#[test]
fn contour_bad_input_gets_clear_errors() {
    let dir = tmp();
    let d = dir.path();
    let (v, w, h) = gray_image();
    write_pgm(&d.join("g.pgm"), &v, w, h);
    let (vv, dd) = bumps();
    write_mha(&d.join("b.mha"), dd, &vv);
    fails(septa(&["contour", "g.pgm", "-o", "c.svg"], d), &["--iso"]);
    fails(
        septa(
            &["contour", "g.pgm", "--iso", "1", "--labels", "-o", "c.svg"],
            d,
        ),
        &["--labels"],
    );
    fails(
        septa(&["contour", "g.pgm", "--iso", "1", "-o", "c.txt"], d),
        &["c.txt", ".svg"],
    );
    fails(
        septa(&["contour", "nope.pgm", "--iso", "1", "-o", "c.svg"], d),
        &["nope.pgm"],
    );
    fails(
        septa(
            &[
                "contour", "g.pgm", "--iso", "1", "--slice", "z=0", "-o", "c.svg",
            ],
            d,
        ),
        &["--slice"],
    );
    fails(
        septa(&["contour", "b.mha", "--iso", "1", "-o", "c.svg"], d),
        &["--slice", "z=4"],
    );
    fails(
        septa(
            &[
                "contour", "b.mha", "--iso", "1", "--slice", "z=8", "-o", "c.svg",
            ],
            d,
        ),
        &["0 to 7"],
    );
    fails(
        septa(
            &[
                "contour", "b.mha", "--iso", "1", "--slice", "w=1", "-o", "c.svg",
            ],
            d,
        ),
        &["axis"],
    );
    fails(
        septa(
            &[
                "contour", "b.mha", "--labels", "--slice", "z=1", "-o", "c.svg",
            ],
            d,
        ),
        &["non-integral"],
    );
    fails(
        septa(&["contour", "g.pgm", "--iso", "NaN", "-o", "c.svg"], d),
        &["NaN"],
    );
    fails(
        septa(&["contour", "g.pgm", "--iso", "1", "-o", "g.pgm"], d),
        &["input"],
    );
    // corrupted and unsupported files
    let png = encode_png_gray(w, h, &v, false);
    // a byte of the image data, and one of a chunk type: the png crate finds
    // a bad deflate stream, a bad CRC or an unknown critical chunk
    for k in [40, 45] {
        let mut bad = png.clone();
        bad[k] ^= 1;
        std::fs::write(d.join("bad.png"), &bad).unwrap();
        fails(
            septa(&["contour", "bad.png", "--iso", "1", "-o", "c.svg"], d),
            &["bad.png", "corrupt"],
        );
    }
    std::fs::write(d.join("cut.png"), &png[..png.len() / 2]).unwrap();
    fails(
        septa(&["contour", "cut.png", "--iso", "1", "-o", "c.svg"], d),
        &["cut.png"],
    );
    std::fs::write(d.join("t.pgm"), b"P5 3 3 255\n\x01\x02").unwrap();
    fails(
        septa(&["contour", "t.pgm", "--iso", "1", "-o", "c.svg"], d),
        &["t.pgm", "truncated"],
    );
    std::fs::write(d.join("c.ppm.pgm"), b"P6 1 1 255\n\0\0\0").unwrap();
    fails(
        septa(&["contour", "c.ppm.pgm", "--iso", "1", "-o", "c.svg"], d),
        &["P6"],
    );
    // nothing was left behind by the failures
    assert!(!d.join("c.svg").exists());
}

#[test]
fn contour_help_describes_the_2d_modes() {
    let dir = tempfile::tempdir().unwrap();
    let help = ok(septa(&["contour", "--help"], dir.path()));
    let mode = &help[help.find("--mode").unwrap()..help.find("--no-displace").unwrap()];
    assert!(mode.contains("pixels") && mode.contains("corner"), "{mode}");
    assert!(!mode.contains("voxel") && !mode.contains("edge"), "{mode}");
}
