//! Mesh files: PLY (whole, per patch, junctions) round trips and the reader's
//! handling of foreign and broken files; OBJ, STL and VTP checked with small
//! parsers written here.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;
use septa::io::mesh_formats::{
    VtpEncoding, write_obj, write_stl, write_stl_label_surface, write_vtp,
};
use septa::io::mesh_ply::{
    parse_ply, read_ply, write_junctions_ply, write_patch_ply, write_patch_plys, write_ply,
};
use septa::mesh::{InterfaceMesh, JunctionCurve, LabelInfo, Patch};

// ───────────────────────────── test meshes ─────────────────────────────

fn labels(list: &[(i64, &str)]) -> Vec<LabelInfo> {
    list.iter()
        .map(|&(value, name)| LabelInfo {
            value,
            name: name.to_string(),
        })
        .collect()
}

/// An octahedron around label "left hippocampus" (value 5): its upper half
/// faces background (value 0, dense 0), its lower half "right thing" (value 9,
/// dense 2). Patch 0 = {0, 1} has normals from background into the octahedron
/// (inward), patch 1 = {1, 2} from the octahedron into "right thing" (outward).
/// The equator is a closed junction curve of all three labels.
fn octahedron() -> InterfaceMesh {
    let positions = vec![
        DVec3::new(1.5, 0.0, 0.0),
        DVec3::new(0.0, 1.5, 0.0),
        DVec3::new(-1.5, 0.0, 0.0),
        DVec3::new(0.0, -1.5, 0.0),
        DVec3::new(0.0, 0.0, 2.25),
        DVec3::new(0.0, 0.0, -2.25),
    ];
    let mut triangles = Vec::new();
    let mut triangle_patch = Vec::new();
    for i in 0..4u32 {
        let j = (i + 1) % 4;
        triangles.push([i, 4, j]); // upper, outward would be [i, j, 4]: reversed
        triangle_patch.push(0);
        triangles.push([j, i, 5]); // lower, outward
        triangle_patch.push(1);
    }
    InterfaceMesh {
        positions,
        triangles,
        triangle_patch,
        patches: vec![Patch { labels: [0, 1] }, Patch { labels: [1, 2] }],
        junctions: vec![JunctionCurve {
            vertices: vec![0, 1, 2, 3],
            closed: true,
            labels: vec![0, 1, 2],
        }],
        labels: labels(&[
            (0, "background"),
            (5, "left hippocampus"),
            (9, "right thing"),
        ]),
        ..Default::default()
    }
}

/// A tetrahedron of label 7 (dense 1) with two faces towards label -3 (dense 0)
/// and two towards label 20 (dense 2), positions far from the origin.
fn tetrahedron() -> InterfaceMesh {
    let o = DVec3::new(-480.125, 312.5, 499.75);
    let positions = vec![o, o + DVec3::X, o + DVec3::Y, o + DVec3::Z * 0.003];
    // outward faces of the tetrahedron (0,1,2,3)
    let outward = [[0u32, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let triangles = vec![
        [outward[0][0], outward[0][2], outward[0][1]], // {-3, 7}: normal from -3 into 7 = inward
        [outward[1][0], outward[1][2], outward[1][1]],
        outward[2], // {7, 20}: from 7 into 20 = outward
        outward[3],
    ];
    InterfaceMesh {
        positions,
        triangles,
        triangle_patch: vec![0, 0, 1, 1],
        patches: vec![Patch { labels: [0, 1] }, Patch { labels: [1, 2] }],
        junctions: vec![JunctionCurve {
            vertices: vec![0, 3],
            closed: false,
            labels: vec![0, 1, 2],
        }],
        labels: labels(&[(-3, "minus three"), (7, "seven"), (20, "twenty")]),
        ..Default::default()
    }
}

fn f32_round(p: DVec3) -> DVec3 {
    DVec3::new(p.x as f32 as f64, p.y as f32 as f64, p.z as f32 as f64)
}

fn assert_same_mesh(read: &InterfaceMesh, mesh: &InterfaceMesh) {
    let expected: Vec<DVec3> = mesh.positions.iter().map(|&p| f32_round(p)).collect();
    assert_eq!(read.positions, expected);
    assert_eq!(read.triangles, mesh.triangles);
    assert_eq!(read.triangle_patch, mesh.triangle_patch);
    assert_eq!(read.patches, mesh.patches);
    assert_eq!(read.labels, mesh.labels);
}

// ───────────────────────────── PLY ─────────────────────────────

#[test]
fn ply_header_is_as_documented() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("octa.ply");
    write_ply(&path, &octahedron()).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    let expected = format!(
        "ply\nformat binary_little_endian 1.0\ncomment septa {}\ncomment space LPS mm SPACE=LPS\n\
         comment label 0 background\ncomment label 5 left hippocampus\ncomment label 9 right thing\n\
         element vertex 6\nproperty float x\nproperty float y\nproperty float z\n\
         element face 8\nproperty list uchar int vertex_indices\nproperty int label_a\n\
         property int label_b\nproperty uint patch\nend_header\n",
        env!("CARGO_PKG_VERSION")
    );
    assert_eq!(header, expected);
    assert_eq!(bytes.len() - end, 6 * 12 + 8 * (1 + 12 + 12));
    // first face: 3, [0, 4, 1], label values 0 and 5, patch 0
    let f = &bytes[end + 72..end + 72 + 25];
    assert_eq!(f[0], 3);
    let ints: Vec<i32> = f[1..]
        .chunks(4)
        .map(|c| i32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(ints, [0, 4, 1, 0, 5, 0]);
}

#[test]
fn ply_whole_mesh_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    for (name, mesh) in [("octa.ply", octahedron()), ("tet.ply", tetrahedron())] {
        let path = dir.path().join(name);
        write_ply(&path, &mesh).unwrap();
        let read = read_ply(&path).unwrap();
        assert!(read.notes.is_empty(), "{:?}", read.notes);
        assert!(read.vertex_ids.is_none());
        assert_same_mesh(&read.mesh, &mesh);
    }
}

#[test]
fn ply_float_precision_is_enough_far_from_the_origin() {
    let mesh = tetrahedron();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tet.ply");
    write_ply(&path, &mesh).unwrap();
    let read = read_ply(&path).unwrap().mesh;
    for (a, b) in read.positions.iter().zip(&mesh.positions) {
        assert!(
            (*a - *b).abs().max_element() <= 2f64.powi(-16),
            "{a} vs {b}"
        );
    }
    // the 0.003 mm edge keeps its length to 1%
    let edge = (read.positions[3] - read.positions[0]).length();
    assert!((edge - 0.003).abs() < 0.00003, "{edge}");
}

#[test]
fn per_patch_plys_round_trip_with_global_vertex_ids() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = octahedron();
    let paths = write_patch_plys(dir.path(), "patch_", &mesh).unwrap();
    let names: Vec<_> = paths
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["patch_0_5.ply", "patch_5_9.ply"]);
    let by_patch = mesh.patch_triangles();
    for (p, path) in paths.iter().enumerate() {
        let read = read_ply(path).unwrap();
        let vids = read.vertex_ids.clone().expect("per-patch files carry vid");
        let m = &read.mesh;
        assert_eq!(m.patches.len(), 1);
        let values = m.patches[0].labels.map(|l| m.label_value(l));
        assert_eq!(values, mesh.patches[p].labels.map(|l| mesh.label_value(l)));
        // vertices: exactly the patch's vertices, ascending global id, same positions
        let mut used: Vec<u32> = by_patch[p]
            .iter()
            .flat_map(|&t| mesh.triangles[t as usize])
            .collect();
        used.sort_unstable();
        used.dedup();
        assert_eq!(vids, used);
        for (local, &g) in vids.iter().enumerate() {
            assert_eq!(m.positions[local], f32_round(mesh.positions[g as usize]));
        }
        let global: Vec<[u32; 3]> = m
            .triangles
            .iter()
            .map(|t| t.map(|v| vids[v as usize]))
            .collect();
        let expected: Vec<[u32; 3]> = by_patch[p]
            .iter()
            .map(|&t| mesh.triangles[t as usize])
            .collect();
        assert_eq!(global, expected);
    }
    // the two files share exactly the equator
    let a = read_ply(&paths[0]).unwrap().vertex_ids.unwrap();
    let b = read_ply(&paths[1]).unwrap().vertex_ids.unwrap();
    let shared: Vec<u32> = a.iter().copied().filter(|v| b.contains(v)).collect();
    assert_eq!(shared, [0, 1, 2, 3]);
    assert!(write_patch_ply(&dir.path().join("x.ply"), &mesh, 2).is_err());
}

#[test]
fn junctions_ply_reads_back_with_ply_rs_bw() {
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Property};
    let dir = tempfile::tempdir().unwrap();
    for (mesh, n_vertices, edges) in [
        (octahedron(), 4, vec![[0, 1], [1, 2], [2, 3], [3, 0]]),
        (tetrahedron(), 2, vec![[0, 1]]),
    ] {
        let path = dir.path().join("junctions.ply");
        write_junctions_ply(&path, &mesh).unwrap();
        let mut f = std::fs::File::open(&path).unwrap();
        let ply = Parser::<DefaultElement>::new().read_ply(&mut f).unwrap();
        let vertices = &ply.payload["vertex"];
        assert_eq!(vertices.len(), n_vertices);
        let curve_vertices = &mesh.junctions[0].vertices;
        for v in vertices {
            let Property::UInt(vid) = v["vid"] else {
                panic!("vid is uint")
            };
            let Property::Float(x) = v["x"] else {
                panic!("x is float")
            };
            assert!(curve_vertices.contains(&vid));
            assert_eq!(x, mesh.positions[vid as usize].x as f32);
        }
        let read_edges: Vec<[i32; 2]> = ply.payload["edge"]
            .iter()
            .map(
                |e| match (&e["vertex1"], &e["vertex2"], &e["curve"], &e["labels"]) {
                    (
                        Property::Int(a),
                        Property::Int(b),
                        Property::UInt(0),
                        Property::ListInt(l),
                    ) => {
                        let expected: Vec<i32> =
                            mesh.labels.iter().map(|l| l.value as i32).collect();
                        assert_eq!(*l, expected);
                        [*a, *b]
                    }
                    other => panic!("unexpected edge {other:?}"),
                },
            )
            .collect();
        assert_eq!(read_edges, edges);
    }
}

fn ascii_ply(vertex_props: &str, face_props: &str, vertices: &[&str], faces: &[&str]) -> Vec<u8> {
    let mut s = format!(
        "ply\nformat ascii 1.0\ncomment label 4 four\nelement vertex {}\n{vertex_props}element face {}\n{face_props}end_header\n",
        vertices.len(),
        faces.len()
    );
    for l in vertices.iter().chain(faces) {
        s.push_str(l);
        s.push('\n');
    }
    s.into_bytes()
}

const XYZ: &str = "property float x\nproperty float y\nproperty float z\n";
const SQUARE: [&str; 5] = ["0 0 0", "1 0 0", "1 1 0", "0 1 0", "0.5 0.5 1"];

#[test]
fn reading_label_a_greater_than_label_b_reverses_the_face() {
    let props =
        "property list uchar int vertex_indices\nproperty int label_a\nproperty int label_b\n";
    let bytes = ascii_ply(XYZ, props, &SQUARE, &["3 0 1 4 4 2", "3 1 2 4 2 4"]);
    let read = parse_ply(Path::new("mirror.ply"), &bytes).unwrap();
    let m = &read.mesh;
    // labels 2 and 4 (named by the comment): dense 0 and 1
    assert_eq!(m.labels, labels(&[(2, "label2"), (4, "four")]));
    assert_eq!(m.patches, [Patch { labels: [0, 1] }]);
    // first face was 4 → 2: swapped and reversed; second kept
    assert_eq!(m.triangles, [[0, 4, 1], [1, 2, 4]]);
    assert_eq!(m.triangle_patch, [0, 0]);
    assert!(
        read.notes
            .iter()
            .any(|n| n.contains("1 faces had label_a > label_b")),
        "{:?}",
        read.notes
    );
}

#[test]
fn reading_unlabelled_polygons_fan_triangulates_into_one_patch() {
    let props = "property list uchar uint vertex_index\n";
    let bytes = ascii_ply(XYZ, props, &SQUARE, &["4 0 1 2 3", "3 0 1 4", "2 0 1"]);
    let read = parse_ply(Path::new("plain.ply"), &bytes).unwrap();
    let m = &read.mesh;
    assert_eq!(m.triangles, [[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
    assert_eq!(m.labels, labels(&[(0, "inside"), (1, "outside")]));
    assert_eq!(m.patches, [Patch { labels: [0, 1] }]);
    assert_eq!(read.notes.len(), 2, "{:?}", read.notes);
    assert!(read.notes[0].contains("inside"));
    assert!(read.notes[1].contains("skipped 1 faces"));
}

#[test]
fn reading_double_big_endian_short_indices() {
    let mut bytes = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\n\
        property double y\nproperty double z\nproperty uchar red\nelement face 1\n\
        property list ushort short vertex_indices\nproperty short label_a\nproperty char label_b\n\
        element extra 2\nproperty list uchar float stuff\nend_header\n"
        .to_vec();
    for (i, p) in [[0.1f64, 0.2, 0.3], [1.0, 0.0, 0.0], [0.0, 1.0, 1e-9]]
        .iter()
        .enumerate()
    {
        for c in p {
            bytes.extend(c.to_be_bytes());
        }
        bytes.push(i as u8);
    }
    bytes.extend(3u16.to_be_bytes());
    for v in [0i16, 1, 2] {
        bytes.extend(v.to_be_bytes());
    }
    bytes.extend(300i16.to_be_bytes());
    bytes.push((-7i8) as u8);
    bytes.extend([1u8, 0, 0, 0, 0, 0]);
    let read = parse_ply(Path::new("be.ply"), &bytes).unwrap();
    let m = &read.mesh;
    assert_eq!(m.positions[0], DVec3::new(0.1, 0.2, 0.3));
    assert_eq!(m.positions[2].z, 1e-9);
    assert_eq!(m.triangles, [[0, 2, 1]]);
    assert_eq!(
        m.labels.iter().map(|l| l.value).collect::<Vec<_>>(),
        [-7, 300]
    );
}

fn expect_error(name: &str, bytes: &[u8], needle: &str) {
    match parse_ply(Path::new(name), bytes) {
        Ok(_) => panic!("{name}: read a bad file"),
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains(name) && msg.contains(needle), "{name}: {msg}");
        }
    }
}

#[test]
fn bad_plys_give_clear_errors() {
    let props = "property list uchar int vertex_indices\n";
    expect_error(
        "notply.ply",
        b"solid cube\nfacet normal 0 0 1\n",
        "not a PLY file",
    );
    expect_error("empty.ply", b"", "not a PLY file");
    expect_error(
        "noend.ply",
        b"ply\nformat ascii 1.0\nelement vertex 3\n",
        "header",
    );
    let no_face = format!("ply\nformat ascii 1.0\nelement vertex 1\n{XYZ}end_header\n0 0 0\n");
    expect_error("noface.ply", no_face.as_bytes(), "no 'face' element");
    expect_error("novertex.ply", b"ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n", "no 'vertex'");
    expect_error(
        "noy.ply",
        &ascii_ply("property float x\nproperty float z\n", props, &["0 0"], &[]),
        "'y'",
    );
    expect_error(
        "range.ply",
        &ascii_ply(XYZ, props, &SQUARE, &["3 0 1 5"]),
        "refers to vertex 5",
    );
    expect_error(
        "negative.ply",
        &ascii_ply(XYZ, props, &SQUARE, &["3 0 -1 2"]),
        "refers to vertex -1",
    );
    let full = ascii_ply(XYZ, props, &SQUARE[..3], &["3 0 1 2"]);
    expect_error("short.ply", &full[..full.len() - 8], "truncated");
    expect_error(
        "text.ply",
        &ascii_ply(XYZ, props, &["0 0 zero"], &[]),
        "bad data",
    );
    expect_error(
        "onelabel.ply",
        &ascii_ply(
            XYZ,
            "property list uchar int vertex_indices\nproperty int label_a\n",
            &SQUARE,
            &["3 0 1 2 5"],
        ),
        "only one of",
    );
    expect_error(
        "same.ply",
        &ascii_ply(
            XYZ,
            "property list uchar int vertex_indices\nproperty int label_a\nproperty int label_b\n",
            &SQUARE,
            &["3 0 1 2 5 5"],
        ),
        "and itself",
    );
    expect_error(
        "fraction.ply",
        &ascii_ply(
            XYZ,
            "property list uchar int vertex_indices\nproperty float label_a\nproperty float label_b\n",
            &SQUARE,
            &["3 0 1 2 0.5 1"],
        ),
        "whole numbers",
    );
    expect_error(
        "twice.ply",
        &ascii_ply(
            "property float x\nproperty float y\nproperty float z\nproperty float x\n",
            props,
            &["0 0 0 0"],
            &[],
        ),
        "twice",
    );
    // binary: NaN coordinate, huge count
    let mut nan = octa_bytes();
    let end = nan.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    nan[end..end + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    expect_error("nan.ply", &nan, "non-finite");
    let huge = String::from_utf8_lossy(&octa_bytes()).replacen(
        "element face 8",
        "element face 4000000000",
        1,
    );
    expect_error("huge.ply", huge.as_bytes(), "truncated");
}

fn octa_bytes() -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("octa.ply");
    write_ply(&path, &octahedron()).unwrap();
    std::fs::read(&path).unwrap()
}

/// xorshift64*: deterministic pseudo-random numbers without a dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[test]
fn corrupt_binary_plys_never_panic() {
    let good = octa_bytes();
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (mut ok, mut err) = (0, 0);
    for case in 0..600 {
        let mut bytes = good.clone();
        match case % 3 {
            0 => bytes.truncate(rng.below(good.len())),
            1 => {
                for _ in 0..1 + rng.below(4) {
                    let i = rng.below(bytes.len());
                    bytes[i] ^= 1 << rng.below(8);
                }
            }
            _ => {
                let i = rng.below(bytes.len());
                bytes[i] = rng.next() as u8;
                bytes.truncate(good.len() - rng.below(20));
            }
        }
        match parse_ply(Path::new("fuzz.ply"), &bytes) {
            Ok(read) => {
                ok += 1;
                let m = &read.mesh;
                assert_eq!(m.triangles.len(), m.triangle_patch.len());
                assert!(
                    m.triangles
                        .iter()
                        .flatten()
                        .all(|&v| (v as usize) < m.positions.len())
                );
                assert!(m.patches.iter().all(|p| p.labels[0] < p.labels[1]));
            }
            Err(e) => {
                err += 1;
                assert!(e.to_string().contains("fuzz.ply"), "{e}");
            }
        }
    }
    assert!(ok > 0 && err > 0, "ok {ok}, err {err}");
}

// ───────────────────────────── OBJ ─────────────────────────────

#[test]
fn obj_has_shared_vertices_and_one_group_per_patch() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = tetrahedron();
    let path = dir.path().join("tet.obj");
    write_obj(&path, &mesh).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let mut vertices = Vec::new();
    let mut groups: Vec<(String, Vec<[u32; 3]>)> = Vec::new();
    for line in text.lines() {
        let tokens: Vec<&str> = line.split_whitespace().collect();
        match tokens.as_slice() {
            ["v", x, y, z] => vertices.push(DVec3::new(
                x.parse().unwrap(),
                y.parse().unwrap(),
                z.parse().unwrap(),
            )),
            ["g", name] => groups.push((name.to_string(), Vec::new())),
            ["f", i, j, k] => {
                let t = [i, j, k].map(|s| s.parse::<u32>().unwrap() - 1);
                groups.last_mut().unwrap().1.push(t);
            }
            _ => {}
        }
    }
    assert_eq!(vertices, mesh.positions, "OBJ keeps full double precision");
    let names: Vec<&str> = groups.iter().map(|g| g.0.as_str()).collect();
    assert_eq!(names, ["minus_three__seven", "seven__twenty"]);
    assert_eq!(groups[0].1, mesh.triangles[..2]);
    assert_eq!(groups[1].1, mesh.triangles[2..]);
    assert!(text.contains("# label -3 minus three\n"));
    assert_eq!(text.lines().filter(|l| l.starts_with("o ")).count(), 2);
}

// ───────────────────────────── STL ─────────────────────────────

/// (normal, vertices, attribute) of every facet of a binary STL.
fn parse_stl(bytes: &[u8]) -> Vec<([f32; 3], [[f32; 3]; 3], u16)> {
    let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize;
    assert_eq!(bytes.len(), 84 + 50 * n);
    let f = |b: &[u8]| f32::from_le_bytes(b.try_into().unwrap());
    let v3 = |b: &[u8]| [f(&b[0..4]), f(&b[4..8]), f(&b[8..12])];
    bytes[84..]
        .chunks(50)
        .map(|c| {
            (
                v3(&c[0..12]),
                [v3(&c[12..24]), v3(&c[24..36]), v3(&c[36..48])],
                u16::from_le_bytes([c[48], c[49]]),
            )
        })
        .collect()
}

#[test]
fn stl_of_all_patches_carries_patch_ids() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = octahedron();
    let path = dir.path().join("all.stl");
    write_stl(&path, &mesh).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert!(bytes.starts_with(b"septa"));
    let facets = parse_stl(&bytes);
    assert_eq!(facets.len(), 8);
    for (t, (normal, verts, attr)) in facets.iter().enumerate() {
        assert_eq!(*attr as u32, mesh.triangle_patch[t]);
        let tri = mesh.triangles[t].map(|v| mesh.positions[v as usize].as_vec3().to_array());
        assert_eq!(*verts, tri);
        let [a, b, c] = mesh.triangles[t].map(|v| mesh.positions[v as usize]);
        let expected = (b - a).cross(c - a).normalize();
        assert!((DVec3::from(normal.map(f64::from)) - expected).length() < 1e-6);
    }
}

#[test]
fn stl_label_surface_is_closed_and_outward() {
    let dir = tempfile::tempdir().unwrap();
    for mesh in [octahedron(), tetrahedron()] {
        let path = dir.path().join("label.stl");
        write_stl_label_surface(&path, &mesh, 1).unwrap();
        let facets = parse_stl(&std::fs::read(&path).unwrap());
        assert_eq!(facets.len(), mesh.triangle_count());
        // closed: every directed edge appears once, its reverse once
        let key = |p: [f32; 3]| p.map(f32::to_bits);
        let mut edges: HashMap<([u32; 3], [u32; 3]), i32> = HashMap::new();
        let mut volume = 0.0;
        for (_, [a, b, c], _) in &facets {
            for (p, q) in [(a, b), (b, c), (c, a)] {
                *edges.entry((key(*p), key(*q))).or_default() += 1;
            }
            let [a, b, c] = [a, b, c].map(|p| DVec3::from(p.map(f64::from)));
            volume += a.dot(b.cross(c)) / 6.0;
        }
        for ((p, q), n) in &edges {
            assert_eq!(*n, 1);
            assert_eq!(edges.get(&(*q, *p)), Some(&1));
        }
        assert!(
            volume > 0.0,
            "outward surface encloses a positive volume: {volume}"
        );
        // dense id 3 does not exist
        assert!(write_stl_label_surface(&path, &mesh, 3).is_err());
    }
}

// ───────────────────────────── VTP ─────────────────────────────

fn b64_decode(s: &[u8]) -> Vec<u8> {
    let val = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("bad base64 {c}"),
    } as u32;
    let mut out = Vec::new();
    for q in s.chunks(4) {
        let pad = q.iter().filter(|&&c| c == b'=').count();
        let n = q
            .iter()
            .fold(0u32, |n, &c| (n << 6) | if c == b'=' { 0 } else { val(c) });
        out.extend(&n.to_be_bytes()[1..4 - pad]);
    }
    out
}

/// Attribute `name="…"` of an XML tag.
fn attr<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let start = tag.find(&format!(" {name}=\""))? + name.len() + 3;
    Some(&tag[start..start + tag[start..].find('"')?])
}

/// Every DataArray of a `.vtp` file as f64 values, by name.
fn parse_vtp(text: &str) -> (HashMap<String, Vec<f64>>, HashMap<String, String>) {
    let appended = match text.find("<AppendedData") {
        Some(i) => text[i..]
            .split_once('_')
            .unwrap()
            .1
            .split_whitespace()
            .next()
            .unwrap(),
        None => "",
    };
    let mut arrays = HashMap::new();
    let mut types = HashMap::new();
    for piece in text.split("<DataArray").skip(1) {
        let tag = &piece[..piece.find('>').unwrap()];
        let name = attr(tag, "Name").unwrap().to_string();
        let ty = attr(tag, "type").unwrap().to_string();
        let values: Vec<f64> = match attr(tag, "format").unwrap() {
            "ascii" => {
                let body =
                    &piece[piece.find('>').unwrap() + 1..piece.find("</DataArray>").unwrap()];
                let f32_text = ty == "Float32";
                let parse = |s: &str| {
                    if f32_text {
                        s.parse::<f32>().unwrap() as f64
                    } else {
                        s.parse().unwrap()
                    }
                };
                body.split_whitespace().map(parse).collect()
            }
            "appended" => {
                let offset: usize = attr(tag, "offset").unwrap().parse().unwrap();
                let rest = &appended.as_bytes()[offset..];
                let n = u64::from_le_bytes(b64_decode(&rest[..12]).try_into().unwrap()) as usize;
                let data = b64_decode(&rest[12..12 + n.div_ceil(3) * 4]);
                assert_eq!(data.len(), n);
                match ty.as_str() {
                    "Float32" => data
                        .chunks(4)
                        .map(|c| f32::from_le_bytes(c.try_into().unwrap()) as f64)
                        .collect(),
                    "Int32" => data
                        .chunks(4)
                        .map(|c| i32::from_le_bytes(c.try_into().unwrap()) as f64)
                        .collect(),
                    "Int64" => data
                        .chunks(8)
                        .map(|c| i64::from_le_bytes(c.try_into().unwrap()) as f64)
                        .collect(),
                    other => panic!("type {other}"),
                }
            }
            other => panic!("format {other}"),
        };
        types.insert(name.clone(), ty);
        arrays.insert(name, values);
    }
    (arrays, types)
}

#[test]
fn vtp_ascii_and_base64_hold_points_polys_and_cell_data() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = tetrahedron();
    for enc in [VtpEncoding::Ascii, VtpEncoding::Base64] {
        let path = dir.path().join("tet.vtp");
        write_vtp(&path, &mesh, enc).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.contains("NumberOfPoints=\"4\"") && text.contains("NumberOfPolys=\"4\""),
            "{text}"
        );
        assert!(text.contains("<!-- label 20 twenty -->"));
        let (arrays, types) = parse_vtp(&text);
        let points: Vec<f64> = mesh
            .positions
            .iter()
            .flat_map(|p| p.as_vec3().to_array().map(f64::from))
            .collect();
        assert_eq!(arrays["Points"], points, "{enc:?}");
        let conn: Vec<f64> = mesh.triangles.iter().flatten().map(|&v| v as f64).collect();
        assert_eq!(arrays["connectivity"], conn);
        assert_eq!(arrays["offsets"], [3.0, 6.0, 9.0, 12.0]);
        assert_eq!(arrays["label_a"], [-3.0, -3.0, 7.0, 7.0]);
        assert_eq!(arrays["label_b"], [7.0, 7.0, 20.0, 20.0]);
        assert_eq!(arrays["patch"], [0.0, 0.0, 1.0, 1.0]);
        // (connectivity and offsets too: Int64 only past 2³¹ indices)
        for name in ["label_a", "label_b", "patch", "connectivity", "offsets"] {
            assert_eq!(types[name], "Int32", "{name}");
        }
    }
}

// ───────────────────────────── manifest ─────────────────────────────

#[test]
fn manifest_of_the_pipeline_lists_patches_and_files() {
    let dir = tempfile::tempdir().unwrap();
    let volume = septa::phantom::heart(&septa::phantom::PhantomParams {
        size: 16,
        ..Default::default()
    })
    .unwrap();
    let options = septa::pipeline::PipelineOptions {
        remesh: septa::config::RemeshOptions {
            enabled: Some(false),
            ..Default::default()
        },
        ..Default::default()
    };
    let config = septa::config::Config::default();
    let mut result = septa::pipeline::run(volume, &config, &options, &mut |_| {}).unwrap();
    let out = septa::output::OutDir::new(dir.path().join("out"), false);
    let formats = septa::output::Formats::default();
    let space = septa::io::Space::Lps;
    let files =
        septa::output::write_outdir(&out, &result.mesh, formats, space, &mut result.manifest)
            .unwrap();
    let path = dir.path().join("out/manifest.json");
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    // the same keys as the typed manifest (values to JSON's float rounding)
    let typed = result.manifest.to_value().unwrap();
    let keys = |v: &serde_json::Value| v.as_object().unwrap().keys().cloned().collect::<Vec<_>>();
    assert_eq!(keys(&json), keys(&typed));
    for (a, b) in json["patches"]
        .as_array()
        .unwrap()
        .iter()
        .zip(typed["patches"].as_array().unwrap())
    {
        assert_eq!(
            (&a["file"], &a["label_a"], &a["label_b"]),
            (&b["file"], &b["label_a"], &b["label_b"])
        );
    }
    assert_eq!(json["triangles"], result.mesh.triangle_count());
    assert_eq!(json["files"].as_array().unwrap().len(), files.len());
    assert_eq!(
        json["files"].as_array().unwrap().last().unwrap(),
        "manifest.json"
    );
    for (i, p) in result.mesh.patches.iter().enumerate() {
        let m = &json["patches"][i];
        assert_eq!(m["label_a"], result.mesh.label_value(p.labels[0]));
        assert!(
            dir.path()
                .join("out")
                .join(m["file"].as_str().unwrap())
                .is_file()
        );
    }
    assert!(json["quality"].is_null());
    assert_eq!(json["validation"]["passed"], true);
    // the preview is written by default, listed, and a PNG of 2 × 2 views
    assert!(
        files
            .iter()
            .any(|f| f == std::path::Path::new("preview.png"))
    );
    assert!(
        json["files"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| f == "preview.png")
    );
    let png = std::fs::read(dir.path().join("out/preview.png")).unwrap();
    let reader = png::Decoder::new(std::io::Cursor::new(&png[..]))
        .read_info()
        .unwrap();
    assert_eq!((reader.info().width, reader.info().height), (800, 800));
    // and not without `preview`, in a directory that --force may replace
    let no_preview = septa::output::Formats {
        preview: false,
        ..Default::default()
    };
    let out = septa::output::OutDir::new(dir.path().join("out"), true);
    let files =
        septa::output::write_outdir(&out, &result.mesh, no_preview, space, &mut result.manifest)
            .unwrap();
    assert!(
        !files
            .iter()
            .any(|f| f == std::path::Path::new("preview.png"))
    );
    assert!(!dir.path().join("out/preview.png").exists());
}

// ───────────────────────────── speed ─────────────────────────────

/// A grid of `n × n` vertices, two triangles per cell, four patches.
fn big_grid(n: u32) -> InterfaceMesh {
    let positions = (0..n * n)
        .map(|i| DVec3::new((i % n) as f64 * 0.3 - 400.0, (i / n) as f64 * 0.3, 12.5))
        .collect();
    let mut triangles = Vec::new();
    let mut triangle_patch = Vec::new();
    for y in 0..n - 1 {
        for x in 0..n - 1 {
            let v = y * n + x;
            triangles.push([v, v + 1, v + n + 1]);
            triangles.push([v, v + n + 1, v + n]);
            let p = u32::from(x >= n / 2) + 2 * u32::from(y >= n / 2);
            triangle_patch.extend([p, p]);
        }
    }
    InterfaceMesh {
        positions,
        triangles,
        triangle_patch,
        patches: vec![
            Patch { labels: [0, 1] },
            Patch { labels: [0, 2] },
            Patch { labels: [1, 2] },
            Patch { labels: [1, 3] },
        ],
        labels: labels(&[(0, "a"), (1, "b"), (2, "c"), (3, "d")]),
        ..Default::default()
    }
}

#[test]
#[ignore = "timing; run with --ignored --nocapture"]
fn ply_write_speed_1m_vertices_2m_triangles() {
    let mesh = big_grid(1001);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.ply");
    let t = std::time::Instant::now();
    write_ply(&path, &mesh).unwrap();
    let write = t.elapsed();
    let shm = Path::new("/dev/shm/septa-mesh-io-speed.ply");
    let t = std::time::Instant::now();
    write_ply(shm, &mesh).unwrap();
    println!("PLY write to /dev/shm {:?}", t.elapsed());
    std::fs::remove_file(shm).unwrap();
    let t = std::time::Instant::now();
    let read = read_ply(&path).unwrap();
    let read_time = t.elapsed();
    let t = std::time::Instant::now();
    write_vtp(&dir.path().join("big.vtp"), &mesh, VtpEncoding::Base64).unwrap();
    let vtp = t.elapsed();
    let t = std::time::Instant::now();
    let patches = write_patch_plys(dir.path(), "p", &mesh).unwrap();
    println!("{} per-patch PLYs {:?}", patches.len(), t.elapsed());
    let t = std::time::Instant::now();
    write_stl(&dir.path().join("big.stl"), &mesh).unwrap();
    let stl = t.elapsed();
    let t = std::time::Instant::now();
    write_obj(&dir.path().join("big.obj"), &mesh).unwrap();
    let obj = t.elapsed();
    println!(
        "{} vertices, {} triangles: PLY write {write:?}, PLY read {read_time:?}, VTP {vtp:?}, STL {stl:?}, OBJ {obj:?}",
        mesh.vertex_count(),
        mesh.triangle_count()
    );
    assert_eq!(read.mesh.triangles.len(), mesh.triangles.len());
    assert_eq!(read.mesh.triangle_patch, mesh.triangle_patch);
}
