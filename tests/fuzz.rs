//! A seeded fuzz loop over what users hand septa besides voxels: configs,
//! PLY meshes for `septa check`, and gzip-compressed volumes. Each input is a
//! valid one damaged at random (a few thousand times, seconds in all; the
//! seed makes every failure reproducible). Errors are fine; a panic fails,
//! and so does anything corrupt that is accepted:
//! - a config error must name the file;
//! - a damaged gzip volume must either fail or read back exactly the voxels
//!   it held (the CRC-32 catches any change of the data);
//! - a PLY that reads must give a mesh the validator can check.
//!
//! Volume headers are fuzzed in `io_mutation.rs`.

mod common;

use std::path::Path;

use common::Rng;
use septa::config::Config;
use septa::io::{ReadOptions, read_label_volume, write_label_volume};
use septa::mesh::validate::{Options, validate};
use septa::volume::{Dims, Geometry, LabelVolume};

const SEED: u64 = 0x5e97_a014;

const CONFIG: &str = r#"outside = "bg"
priority = ["myo", 2]
[labels]
0 = "bg"
1 = "lv"
2 = "rv"
3 = "myo"
[[separate]]
labels = ["lv", "rv"]
by = "myo"
[remesh]
enabled = true
target_edge = 2.0
smooth_iterations = 10
max_displacement = 0.5
iterations = 8
"#;

/// Values that break things: huge, negative, not numbers, other types.
const NASTY: &[&str] = &[
    "1e9",
    "-1",
    "0",
    "nan",
    "inf",
    "-inf",
    "1e308",
    "4294967296",
    "-9223372036854775808",
    "\"x\"",
    "[]",
    "{}",
    "true",
    "\"\"",
    "1.5",
    "99",
    "\"bg\"",
];

fn small_volume() -> LabelVolume {
    let v: Vec<i64> = (0..64).map(|i| [0, 1, 2, 3][(i * 7 / 5) % 4]).collect();
    LabelVolume::from_values(Dims::new(4, 4, 4).unwrap(), &v, Geometry::identity()).unwrap()
}

fn mutate_text(text: &str, rng: &mut Rng) -> String {
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    for _ in 0..1 + rng.below(3) {
        let i = rng.below(lines.len() as u64) as usize;
        match rng.below(6) {
            // a value replaced by a nasty one
            0 | 1 => {
                if let Some((k, _)) = lines[i].split_once('=') {
                    let v = NASTY[rng.below(NASTY.len() as u64) as usize];
                    lines[i] = format!("{k}= {v}");
                }
            }
            2 => {
                lines.remove(i);
            }
            3 => {
                let l = lines[i].clone();
                lines.insert(i, l);
            }
            4 => {
                let j = rng.below(lines.len() as u64) as usize;
                lines.swap(i, j);
            }
            _ => {
                let mut b = lines[i].clone().into_bytes();
                if !b.is_empty() {
                    let at = rng.below(b.len() as u64) as usize;
                    const BYTES: &[u8] = b"[]=\"#.,\\\n\x00\xff-9e";
                    b[at] = BYTES[rng.below(BYTES.len() as u64) as usize];
                }
                lines[i] = String::from_utf8_lossy(&b).into_owned();
            }
        }
        if lines.is_empty() {
            break;
        }
    }
    lines.join("\n")
}

#[test]
fn fuzz_configs() {
    let mut rng = Rng(SEED);
    let path = Path::new("fuzzed.toml");
    let (mut ok, mut errors) = (0, 0);
    for i in 0..4000 {
        let text = mutate_text(CONFIG, &mut rng);
        let result = Config::from_toml_str(&text, path).and_then(|c| c.resolve(small_volume()));
        match result {
            Ok(_) => ok += 1,
            Err(e) => {
                errors += 1;
                let msg = e.to_string();
                assert!(msg.contains("fuzzed.toml"), "case {i}: {msg}\n{text}");
            }
        }
    }
    assert!(ok > 100 && errors > 100, "{ok} read, {errors} refused");
}

fn gzip(bytes: &[u8], level: u32) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::new(level));
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

/// Damages `bytes` in one of the ways a disk, a transfer or a tool does.
fn damage(bytes: &mut Vec<u8>, rng: &mut Rng) {
    let n = bytes.len() as u64;
    match rng.below(5) {
        0 | 1 => {
            let at = rng.below(n) as usize;
            bytes[at] ^= 1 << rng.below(8);
        }
        2 => {
            let at = rng.below(n) as usize;
            bytes[at] = rng.below(256) as u8;
        }
        3 => bytes.truncate(rng.below(n) as usize),
        _ => {
            let extra: Vec<u8> = (0..1 + rng.below(16))
                .map(|_| rng.below(256) as u8)
                .collect();
            bytes.extend(extra);
        }
    }
}

#[test]
fn fuzz_gzip_volumes_never_read_wrong_voxels() {
    let dir = tempfile::tempdir().unwrap();
    let vol = small_volume();
    let nii = dir.path().join("v.nii");
    write_label_volume(&nii, &vol).unwrap();
    let plain = std::fs::read(&nii).unwrap();
    let nrrd_header = b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: gzip\n\n";
    let voxels: Vec<u8> = vol.ids().iter().map(|&i| vol.value(i) as u8).collect();
    let mut rng = Rng(SEED ^ 1);
    let (mut same, mut refused) = (0, 0);
    for i in 0..3000 {
        let level = [0, 1, 6, 9][rng.below(4) as usize];
        let (name, mut bytes, header_len) = if rng.below(2) == 0 {
            ("f.nii.gz", gzip(&plain, level), 0)
        } else {
            let z = gzip(&voxels, level);
            ("f.nrrd", [&nrrd_header[..], &z].concat(), nrrd_header.len())
        };
        // damage the compressed part: the text header is fuzzed elsewhere
        let mut tail = bytes.split_off(header_len);
        damage(&mut tail, &mut rng);
        bytes.extend(tail);
        let path = dir.path().join(name);
        std::fs::write(&path, &bytes).unwrap();
        match read_label_volume(&path, &ReadOptions::default()) {
            Ok(read) => {
                let values: Vec<i64> = read.ids().iter().map(|&i| read.value(i)).collect();
                let want: Vec<i64> = vol.ids().iter().map(|&i| vol.value(i)).collect();
                assert_eq!(
                    values, want,
                    "case {i}: damaged {name} read with other voxels"
                );
                same += 1;
            }
            Err(e) => {
                assert!(e.to_string().contains(name), "case {i}: {e}");
                refused += 1;
            }
        }
    }
    // damage to the gzip header's time stamp or OS byte changes no voxel
    assert!(
        refused > 2000 && same > 10,
        "{same} read, {refused} refused"
    );
}

fn sample_ply(dir: &Path) -> (Vec<u8>, Vec<u8>) {
    // the mesh of two touching blocks, written by septa (binary), and as ascii
    let v: Vec<i64> = (0..125)
        .map(|i| {
            let (x, y, z) = (i % 5, i / 5 % 5, i / 25);
            let inside = (1..4).contains(&y) && (1..4).contains(&z);
            match x {
                1 if inside => 1,
                2 | 3 if inside => 2,
                _ => 0,
            }
        })
        .collect();
    let vol =
        LabelVolume::from_values(Dims::new(5, 5, 5).unwrap(), &v, Geometry::identity()).unwrap();
    let (vol, r) = common::resolved_outside0(vol);
    let (_, mesh, _) = common::run(&vol, &r, Default::default());
    let path = dir.join("m.ply");
    septa::io::mesh_ply::write_ply(&path, &mesh).unwrap();
    let binary = std::fs::read(&path).unwrap();
    let mut ascii = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar int vertex_indices\nproperty int label_a\nproperty int label_b\nend_header\n",
        mesh.vertex_count(),
        mesh.triangle_count()
    );
    for p in &mesh.positions {
        ascii.push_str(&format!("{} {} {}\n", p.x, p.y, p.z));
    }
    for (t, &p) in mesh.triangles.iter().zip(&mesh.triangle_patch) {
        let [a, b] = mesh.patches[p as usize].labels.map(|l| mesh.label_value(l));
        ascii.push_str(&format!("3 {} {} {} {a} {b}\n", t[0], t[1], t[2]));
    }
    (binary, ascii.into_bytes())
}

#[test]
fn fuzz_plys() {
    let dir = tempfile::tempdir().unwrap();
    let (binary, ascii) = sample_ply(dir.path());
    let mut rng = Rng(SEED ^ 2);
    let (mut read, mut refused) = (0, 0);
    for i in 0..3000 {
        let mut bytes = if rng.below(2) == 0 {
            binary.clone()
        } else {
            ascii.clone()
        };
        // mostly in the header and the first elements, where counts and types are
        let header = bytes
            .windows(10)
            .position(|w| w == b"end_header")
            .unwrap_or(0)
            + 11;
        for _ in 0..1 + rng.below(3) {
            if rng.below(3) == 0 {
                damage(&mut bytes, &mut rng);
            } else {
                let at = rng.below((header + 64).min(bytes.len()) as u64) as usize;
                const BYTES: &[u8] = b"0123456789 -\nxyzeplf\xff\x00";
                bytes[at] = BYTES[rng.below(BYTES.len() as u64) as usize];
            }
        }
        match septa::io::mesh_ply::parse_ply(Path::new("fuzzed.ply"), &bytes) {
            Ok(ply) => {
                // whatever was read can be checked without a panic
                let report = validate(&ply.mesh, &Options::default());
                let _ = report.passed();
                read += 1;
            }
            Err(e) => {
                assert!(e.to_string().contains("fuzzed.ply"), "case {i}: {e}");
                refused += 1;
            }
        }
    }
    assert!(read > 50 && refused > 500, "{read} read, {refused} refused");
}
