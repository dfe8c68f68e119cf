//! Nothing lost, nothing corrupt accepted, every failure explained: the cases
//! of a hostile stress test, run through the built binary.
//!
//! [`CASES`] is a table: each case lays out files in a fresh directory, runs
//! `septa` there, and the harness asserts the exit code, that stderr names
//! what it must, and that every file the case laid out is still there with
//! the same bytes, and nothing new is left but what the case expects to be
//! created (no temporary directories, no half output).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use septa::io::write_label_volume;
use septa::volume::{Dims, Geometry, LabelVolume};

/// The binary under test: this build's, or `SEPTA_BIN` (to show that a case
/// fails on another build, e.g. the one before the fixes).
fn bin() -> PathBuf {
    std::env::var_os("SEPTA_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_septa")))
}

fn septa_in(dir: &Path, args: &[String]) -> Output {
    Command::new(bin())
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run septa")
}

/// Every file and directory below `dir`, with the bytes of each file.
fn snapshot(dir: &Path) -> BTreeMap<String, Option<Vec<u8>>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let e = e.unwrap();
            let rel = e
                .path()
                .strip_prefix(dir)
                .unwrap()
                .to_string_lossy()
                .into_owned();
            let t = e.file_type().unwrap();
            if t.is_dir() {
                stack.push(e.path());
                out.insert(rel, None);
            } else {
                out.insert(rel, std::fs::read(e.path()).ok());
            }
        }
    }
    out
}

/// A label volume written as `name` (format from the extension).
fn volume(
    dir: &Path,
    name: &str,
    dims: [usize; 3],
    mut f: impl FnMut(usize, usize, usize) -> i64,
) -> PathBuf {
    let mut v = Vec::new();
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                v.push(f(x, y, z));
            }
        }
    }
    let vol = LabelVolume::from_values(
        Dims::new(dims[0], dims[1], dims[2]).unwrap(),
        &v,
        Geometry::identity(),
    )
    .unwrap();
    let path = dir.join(name);
    if let Some(p) = path.parent() {
        std::fs::create_dir_all(p).unwrap();
    }
    write_label_volume(&path, &vol).unwrap();
    path
}

/// Two boxes of labels 1 and 2 in background 0, 12³.
fn blocks(dir: &Path, name: &str) -> PathBuf {
    volume(dir, name, [12, 12, 12], |x, y, z| {
        let inside = (2..10).contains(&y) && (2..10).contains(&z);
        match x {
            2..=5 if inside => 1,
            6..=9 if inside => 2,
            _ => 0,
        }
    })
}

/// A smooth 0–255 "probability map" with noise, 24³: an intensity image.
fn gray(dir: &Path, name: &str) -> PathBuf {
    volume(dir, name, [24, 24, 24], |x, y, z| {
        let v = 127.5
            + 127.0
                * ((x as f64 * 0.3).sin() * (y as f64 * 0.25).cos() * (z as f64 * 0.2 + 1.0).sin());
        (v as i64 + ((x * 7 + y * 3 + z) % 3) as i64).min(255)
    })
}

fn put(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    if let Some(p) = path.parent() {
        std::fs::create_dir_all(p).unwrap();
    }
    std::fs::write(&path, bytes).unwrap();
    path
}

fn args(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

/// One hostile use.
struct Case {
    name: &'static str,
    /// Lays out the files in the directory; returns septa's arguments.
    setup: fn(&Path) -> Vec<String>,
    /// Expected exit code.
    code: i32,
    /// What stderr must mention (or stdout: `check` reports there).
    stderr: &'static [&'static str],
    /// Relative paths (prefixes) the run may create.
    creates: &'static [&'static str],
}

/// A septa output directory, written by the binary itself.
fn septa_output(dir: &Path, out: &str) {
    let vol = blocks(dir, "prev/blocks.nii");
    let o = septa_in(
        dir,
        &args(&[
            "extract",
            vol.to_str().unwrap(),
            "-o",
            out,
            "-q",
            "--no-remesh",
        ]),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

const CASES: &[Case] = &[
    // ── 1. --force never deletes what the user had ──
    Case {
        name: "force: the config lies in OUTDIR",
        setup: |d| {
            blocks(d, "p.nii.gz");
            put(d, "cfgdir/my.toml", "[labels]\n1 = \"a\"\n");
            args(&[
                "extract",
                "p.nii.gz",
                "-c",
                "cfgdir/my.toml",
                "-o",
                "cfgdir",
                "--force",
            ])
        },
        code: 2,
        stderr: &["cfgdir", "my.toml", "which this run reads"],
        creates: &[],
    },
    Case {
        name: "force: the .mhd's detached data lies in OUTDIR",
        setup: |d| {
            put(d, "datadir/data.raw", [0u8, 1, 1, 0, 0, 1, 1, 0]);
            put(
                d,
                "hdrs/vol.mhd",
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = ../datadir/data.raw\n",
            );
            args(&[
                "extract",
                "hdrs/vol.mhd",
                "-o",
                "datadir",
                "--force",
                "--no-remesh",
            ])
        },
        code: 2,
        stderr: &["datadir", "not written by septa"],
        creates: &[],
    },
    Case {
        name: "force: the .mhd's data lies in what looks like septa's OUTDIR",
        setup: |d| {
            // a manifest listing the data file: only the inputs rule protects it
            put(d, "datadir/data.raw", [0u8, 1, 1, 0, 0, 1, 1, 0]);
            put(
                d,
                "datadir/manifest.json",
                r#"{"septa": "0.1.0", "files": ["data.raw", "manifest.json"]}"#,
            );
            put(
                d,
                "hdrs/vol.mhd",
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = ../datadir/data.raw\n",
            );
            args(&[
                "extract",
                "hdrs/vol.mhd",
                "-o",
                "datadir",
                "--force",
                "--no-remesh",
            ])
        },
        code: 2,
        stderr: &["datadir", "data.raw", "which this run reads"],
        creates: &[],
    },
    Case {
        name: "force: the .nhdr's detached data lies in OUTDIR",
        setup: |d| {
            put(d, "datadir/data.raw", [0u8, 1, 1, 0, 0, 1, 1, 0]);
            put(
                d,
                "datadir/manifest.json",
                r#"{"septa": "0.1.0", "files": ["data.raw", "manifest.json"]}"#,
            );
            put(
                d,
                "hdrs/vol.nhdr",
                "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: ../datadir/data.raw\n",
            );
            args(&[
                "extract",
                "hdrs/vol.nhdr",
                "-o",
                "datadir",
                "--force",
                "--no-remesh",
            ])
        },
        code: 2,
        stderr: &["data.raw", "which this run reads"],
        creates: &[],
    },
    Case {
        name: "force: the volume is hard-linked into OUTDIR",
        setup: |d| {
            septa_output(d, "out");
            blocks(d, "v.nii");
            std::fs::remove_file(d.join("out/interfaces.ply")).unwrap();
            std::fs::hard_link(d.join("v.nii"), d.join("out/interfaces.ply")).unwrap();
            args(&["extract", "v.nii", "-o", "out", "--force", "--no-remesh"])
        },
        code: 2,
        stderr: &["v.nii", "which this run reads"],
        creates: &[],
    },
    Case {
        name: "force: a directory septa did not write",
        setup: |d| {
            blocks(d, "v.nii");
            put(d, "mine/notes.txt", "keep");
            args(&["extract", "v.nii", "-o", "mine", "--force"])
        },
        code: 2,
        stderr: &["mine", "not written by septa"],
        creates: &[],
    },
    Case {
        name: "force: septa's output with a file added",
        setup: |d| {
            septa_output(d, "out");
            put(d, "out/patches/notes.txt", "mine");
            blocks(d, "v.nii");
            args(&["extract", "v.nii", "-o", "out", "--force", "--no-remesh"])
        },
        code: 2,
        stderr: &["patches/notes.txt", "septa did not write"],
        creates: &[],
    },
    Case {
        name: "force: hyper frames inside OUTDIR",
        setup: |d| {
            septa_output(d, "out");
            blocks(d, "out/f0.nii");
            blocks(d, "f1.nii");
            args(&[
                "hyper",
                "--frames",
                "out/f0.nii",
                "f1.nii",
                "--iso",
                "1",
                "-o",
                "out",
                "--force",
            ])
        },
        code: 2,
        stderr: &["f0.nii"],
        creates: &[],
    },
    // ── 2. patch file names never collide ──
    Case {
        name: "names: a/b next to a_b, label3 next to value 3",
        setup: |d| {
            volume(d, "v.nii", [10, 4, 4], |x, _, _| (x / 2) as i64 + 1);
            put(
                d,
                "names.toml",
                "outside = 1\n[labels]\n1 = \"a/b\"\n2 = \"a_b\"\n4 = \"label3\"\n5 = \"A_B\"\n",
            );
            args(&[
                "extract",
                "v.nii",
                "-c",
                "names.toml",
                "-o",
                "out",
                "--no-remesh",
                "-q",
            ])
        },
        code: 0,
        stderr: &[],
        creates: &["out"],
    },
    // ── 3. corrupt gzip is refused ──
    Case {
        name: "gzip: a flipped voxel byte in a stored block",
        setup: |d| {
            use std::io::Write;
            let nii = std::fs::read(blocks(d, "plain.nii")).unwrap();
            let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::none());
            e.write_all(&nii).unwrap();
            let mut z = e.finish().unwrap();
            let n = z.len();
            z[n - 20] = 200;
            put(d, "flip.nii.gz", z);
            args(&["info", "flip.nii.gz"])
        },
        code: 2,
        stderr: &["flip.nii.gz", "corrupt gzip data"],
        creates: &[],
    },
    // ── 9. the destination is checked first ──
    Case {
        name: "destination: a directory nothing can be created in",
        setup: |d| {
            blocks(d, "v.nii");
            let ro = if Path::new("/sys/kernel").is_dir()
                && std::fs::create_dir("/sys/septa-probe").is_err()
            {
                "/sys/septa-out".to_string()
            } else {
                // (as root, permission bits do not stop anything: /sys does)
                let ro = d.join("ro");
                std::fs::create_dir(&ro).unwrap();
                set_mode(&ro, 0o555);
                ro.join("out").to_string_lossy().into_owned()
            };
            args(&["extract", "v.nii", "-o", &ro])
        },
        code: 2,
        stderr: &["cannot be written"],
        creates: &[],
    },
    Case {
        name: "destination: iso into a folder nothing can be created in",
        setup: |d| {
            gray(d, "gray.nii");
            let out = if std::fs::create_dir("/sys/septa-probe").is_err() {
                "/sys/septa-out.ply".to_string()
            } else {
                let ro = d.join("ro");
                std::fs::create_dir(&ro).unwrap();
                set_mode(&ro, 0o555);
                ro.join("s.ply").to_string_lossy().into_owned()
            };
            args(&["iso", "gray.nii", "--iso", "100", "-o", &out])
        },
        code: 2,
        stderr: &["cannot be written"],
        creates: &[],
    },
    Case {
        name: "destination: a 245-byte OUTDIR name works",
        setup: |d| {
            blocks(d, "v.nii");
            args(&[
                "extract",
                "v.nii",
                "-o",
                &"o".repeat(245),
                "--no-remesh",
                "-q",
            ])
        },
        code: 0,
        stderr: &[],
        creates: &["ooooo"],
    },
    Case {
        name: "destination: a 256-byte OUTDIR name is refused at once",
        setup: |d| {
            blocks(d, "v.nii");
            args(&["extract", "v.nii", "-o", &"o".repeat(256)])
        },
        code: 2,
        stderr: &["256 bytes long"],
        creates: &[],
    },
    // ── 7. remeshing parameters have bounds; errors name the flag or key ──
    Case {
        name: "remesh: --target-edge 1e-9",
        setup: |d| {
            blocks(d, "v.nii");
            args(&["extract", "v.nii", "-o", "out", "--target-edge", "1e-9"])
        },
        code: 2,
        stderr: &["--target-edge 0.000000001", "shorter than 0.1 voxel"],
        creates: &[],
    },
    Case {
        name: "remesh: --target-edge 1e9",
        setup: |d| {
            blocks(d, "v.nii");
            args(&["extract", "v.nii", "-o", "out", "--target-edge", "1e9"])
        },
        code: 2,
        stderr: &["--target-edge 1000000000", "longer than the whole volume"],
        creates: &[],
    },
    Case {
        name: "remesh: --smooth-iterations 1000000000",
        setup: |d| {
            blocks(d, "v.nii");
            args(&[
                "extract",
                "v.nii",
                "-o",
                "out",
                "--smooth-iterations",
                "1000000000",
            ])
        },
        code: 2,
        stderr: &["--smooth-iterations 1000000000", "at most 1000"],
        creates: &[],
    },
    Case {
        name: "remesh: config smooth_iterations = 1000000000",
        setup: |d| {
            blocks(d, "v.nii");
            put(d, "bad.toml", "[remesh]\nsmooth_iterations = 1000000000\n");
            args(&["extract", "v.nii", "-c", "bad.toml", "-o", "out"])
        },
        code: 2,
        stderr: &["bad.toml", "remesh.smooth_iterations"],
        creates: &[],
    },
    Case {
        name: "remesh: config iterations = 1e9",
        setup: |d| {
            blocks(d, "v.nii");
            put(d, "bad.toml", "[remesh]\niterations = 1e9\n");
            args(&["extract", "v.nii", "-c", "bad.toml", "-o", "out"])
        },
        code: 2,
        stderr: &["bad.toml", "remesh.iterations"],
        creates: &[],
    },
    Case {
        name: "remesh: config target_edge = 1e9",
        setup: |d| {
            blocks(d, "v.nii");
            put(d, "bad.toml", "[remesh]\ntarget_edge = 1e9\n");
            args(&["extract", "v.nii", "-c", "bad.toml", "-o", "out"])
        },
        code: 2,
        stderr: &[
            "bad.toml",
            "remesh.target_edge",
            "longer than the whole volume",
        ],
        creates: &[],
    },
    Case {
        name: "remesh: config target_edge = -1",
        setup: |d| {
            blocks(d, "v.nii");
            put(d, "bad.toml", "[remesh]\ntarget_edge = -1.0\n");
            args(&["extract", "v.nii", "-c", "bad.toml", "-o", "out"])
        },
        code: 2,
        stderr: &["bad.toml", "remesh.target_edge", "positive"],
        creates: &[],
    },
    // ── 6. grayscale data given as labels ──
    Case {
        name: "intensity: extract refuses what would not fit, pointing to septa iso",
        setup: |d| {
            gray(d, "gray.nii");
            args(&["extract", "gray.nii", "-o", "out", "--max-memory", "50M"])
        },
        code: 2,
        stderr: &["gray.nii", "would need about", "50 MB", "septa iso"],
        creates: &[],
    },
    Case {
        name: "intensity: info says so",
        setup: |d| {
            gray(d, "gray.nii");
            args(&["info", "gray.nii"])
        },
        code: 0,
        stderr: &["looks like an intensity image", "septa iso"],
        creates: &[],
    },
    // ── 10. the silent oddities ──
    Case {
        name: "oddity: outside = 99 does not occur",
        setup: |d| {
            blocks(d, "v.nii");
            put(d, "o.toml", "outside = 99\n");
            args(&["info", "v.nii", "-c", "o.toml"])
        },
        code: 0,
        stderr: &["outside: label 99 does not occur"],
        creates: &[],
    },
    Case {
        name: "oddity: iso on NaN and infinite samples",
        setup: |d| {
            let mut data = Vec::new();
            for i in 0..27 {
                let v = match i {
                    13 => f32::NAN,
                    0 => f32::INFINITY,
                    _ => (i % 5) as f32,
                };
                data.extend(v.to_le_bytes());
            }
            let header = "NRRD0004\ntype: float\ndimension: 3\nsizes: 3 3 3\nendian: little\nencoding: raw\n\n";
            put(d, "nan.nrrd", [header.as_bytes(), &data].concat());
            args(&["iso", "nan.nrrd", "--iso", "2", "-o", "s.ply"])
        },
        code: 0,
        stderr: &["nan.nrrd", "1 samples are NaN and 1 infinite"],
        creates: &["s.ply"],
    },
    Case {
        name: "oddity: iso 1.5 on a 1-255 map",
        setup: |d| {
            gray(d, "gray.nii");
            args(&["iso", "gray.nii", "--iso", "1.5", "-o", "s.ply", "-q"])
        },
        code: 0,
        stderr: &["at the bottom of the values (1 to 255)"],
        creates: &["s.ply"],
    },
    Case {
        name: "oddity: hyper --at-time beyond the last frame",
        setup: |d| {
            blocks(d, "f0.nii");
            blocks(d, "f1.nii");
            args(&[
                "hyper",
                "--frames",
                "f0.nii",
                "f1.nii",
                "--iso",
                "1",
                "--at-time",
                "99",
                "-o",
                "out",
            ])
        },
        code: 2,
        stderr: &["slice time 99 lies outside", "0 to 1"],
        creates: &[],
    },
    Case {
        name: "oddity: NRRD sizes 8 8 8 on 16³ data",
        setup: |d| {
            let header = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 8 8 8\nencoding: raw\n\n";
            put(d, "small.nrrd", [header.as_bytes(), &[0u8; 4096]].concat());
            args(&["info", "small.nrrd"])
        },
        code: 2,
        stderr: &["small.nrrd", "3584 bytes would be ignored"],
        creates: &[],
    },
    Case {
        name: "oddity: the MHA data file is a directory",
        setup: |d| {
            std::fs::create_dir(d.join("data.raw")).unwrap();
            put(
                d,
                "v.mhd",
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = data.raw\n",
            );
            args(&["info", "v.mhd"])
        },
        code: 2,
        stderr: &["v.mhd", "data.raw", "is a directory"],
        creates: &[],
    },
    Case {
        name: "oddity: the MHA data file is /dev/zero",
        setup: |d| {
            put(
                d,
                "v.mhd",
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = /dev/zero\n",
            );
            args(&["info", "v.mhd"])
        },
        code: 2,
        stderr: &["v.mhd", "/dev/zero", "not a regular file"],
        creates: &[],
    },
    Case {
        name: "oddity: raw /dev/zero",
        setup: |_| {
            args(&[
                "info",
                "/dev/zero",
                "--dims",
                "10,10,10",
                "--dtype",
                "uint8",
            ])
        },
        code: 2,
        stderr: &["/dev/zero", "not a regular file"],
        creates: &[],
    },
    Case {
        name: "oddity: int64 labels too large for the PLY",
        setup: |d| {
            let mut data = Vec::new();
            for i in 0..8i64 {
                data.extend((if i == 3 { 1i64 << 40 } else { i % 2 }).to_le_bytes());
            }
            let header = "NRRD0004\ntype: int64\ndimension: 3\nsizes: 2 2 2\nendian: little\nencoding: raw\n\n";
            put(d, "big.nrrd", [header.as_bytes(), &data].concat());
            args(&["extract", "big.nrrd", "-o", "out"])
        },
        code: 2,
        stderr: &["big.nrrd", "1099511627776", "32-bit"],
        creates: &[],
    },
    Case {
        name: "oddity: check on faces of 0 and 1 vertices",
        setup: |d| {
            put(
                d,
                "short.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                 element face 3\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n1 2\n0\n",
            );
            args(&["check", "short.ply"])
        },
        code: 1,
        stderr: &["faces of at least three vertices"],
        creates: &[],
    },
    Case {
        name: "oddity: check on a face [0, 0, 5]",
        setup: |d| {
            put(
                d,
                "rep.ply",
                "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n\
                 element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 1 0\n1 1 1\n3 0 0 5\n",
            );
            args(&["check", "rep.ply"])
        },
        code: 1,
        stderr: &["three distinct corners per triangle"],
        creates: &[],
    },
    // ── 4. stale temporary output of killed runs is removed ──
    Case {
        name: "stale: leftovers of dead processes are removed",
        setup: |d| {
            blocks(d, "v.nii");
            // no process has pid 0 in /proc; the older names are recognised too
            std::fs::create_dir(d.join(".septa-0-0.tmp")).unwrap();
            put(d, ".out.tmp-septa-0/interfaces.ply", "half");
            args(&["extract", "v.nii", "-o", "out", "--no-remesh", "-q"])
        },
        code: 0,
        stderr: &[],
        creates: &["out"],
    },
];

#[cfg(unix)]
fn set_mode(p: &Path, mode: u32) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(mode)).unwrap();
}

#[cfg(not(unix))]
fn set_mode(_: &Path, _: u32) {}

/// Case 7 through the library: `remesh` refuses absurd targets at once
/// instead of running out of memory or for minutes.
#[test]
fn remesh_refuses_absurd_targets() {
    use septa::remesh::{RemeshParams, remesh};
    let dir = tempfile::tempdir().unwrap();
    let vol =
        septa::io::read_label_volume(&blocks(dir.path(), "v.nii"), &Default::default()).unwrap();
    let r = septa::config::Resolved::defaults(&vol);
    let pre = septa::preprocess::preprocess(&vol, &r);
    let mesh = septa::extract::extract(
        &pre.refined,
        septa::extract::label_infos(&vol, None),
        *vol.geometry(),
        &Default::default(),
    )
    .unwrap();
    for (target, smooth, iterations, needle) in [
        (1e-9, 10, 8, "shorter than"),
        (0.01, 10, 8, "shorter than"),
        (1e9, 10, 8, "longer than"),
        (f64::NAN, 10, 8, "positive"),
        (2.0, 1_000_000_000, 8, "smooth_iterations"),
        (2.0, 10, 1_000_000_000, "iterations"),
    ] {
        let p = RemeshParams {
            target_edge: target,
            smooth_iterations: smooth,
            iterations,
            ..Default::default()
        };
        let started = std::time::Instant::now();
        let e = remesh(&mesh, &septa::remesh::Sizing::uniform(2.0), &p)
            .err()
            .expect("refused")
            .to_string();
        assert!(e.contains(needle), "{e}");
        assert!(started.elapsed().as_secs() < 1);
    }
}

/// Files of the stale case that must be gone afterwards.
const REMOVED: &[&str] = &[".septa-0-0.tmp", ".out.tmp-septa-0"];

#[test]
fn hostile_cases() {
    let mut failures = Vec::new();
    for case in CASES {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let argv = (case.setup)(d);
        let before = snapshot(d);
        let o = septa_in(d, &argv);
        let after = snapshot(d);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        let mut problems = Vec::new();
        if o.status.code() != Some(case.code) {
            problems.push(format!(
                "exit code {:?}, expected {}",
                o.status.code(),
                case.code
            ));
        }
        if err.contains("panicked") {
            problems.push("panicked".to_string());
        }
        for n in case.stderr {
            if !err.contains(n) && !out.contains(n) {
                problems.push(format!("stderr lacks {n:?}"));
            }
        }
        for (path, content) in &before {
            let removed_on_purpose = REMOVED.iter().any(|r| path.starts_with(r));
            match after.get(path) {
                None if removed_on_purpose => {}
                None => problems.push(format!("{path} was deleted")),
                Some(c) if c != content => problems.push(format!("{path} was changed")),
                Some(_) if removed_on_purpose => problems.push(format!("{path} was left")),
                Some(_) => {}
            }
        }
        for path in after.keys().filter(|p| !before.contains_key(*p)) {
            if !case.creates.iter().any(|c| path.starts_with(c)) {
                problems.push(format!("{path} was left behind"));
            }
        }
        if !problems.is_empty() {
            failures.push(format!(
                "{}: {}\n  stderr: {}",
                case.name,
                problems.join("; "),
                err.trim()
            ));
        }
    }
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}

/// Case 2 in detail: every patch of the manifest has its own file, and the
/// file holds that patch.
#[test]
fn colliding_label_names_get_unique_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let argv = (CASES
        .iter()
        .find(|c| c.name.starts_with("names:"))
        .unwrap()
        .setup)(d);
    let o = septa_in(d, &argv);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("out/manifest.json")).unwrap()).unwrap();
    let patches = m["patches"].as_array().unwrap();
    assert!(patches.len() >= 4);
    let mut seen = std::collections::BTreeSet::new();
    for p in patches {
        let file = p["file"].as_str().unwrap();
        assert!(seen.insert(file.to_lowercase()), "{file} twice");
        let ply = septa::io::mesh_ply::read_ply(&d.join("out").join(file)).unwrap();
        let values: Vec<i64> = ply.mesh.labels.iter().map(|l| l.value).collect();
        assert_eq!(
            values,
            vec![
                p["label_a"].as_i64().unwrap(),
                p["label_b"].as_i64().unwrap()
            ],
            "{file}"
        );
    }
    let on_disk = std::fs::read_dir(d.join("out/patches")).unwrap().count();
    assert_eq!(on_disk, patches.len());
}

/// A volume of 40³ voxels in 3³ blocks of random labels: thousands of patch
/// files, so that writing takes long enough to be interrupted.
fn many_labels(dir: &Path) -> PathBuf {
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let mut label = std::collections::HashMap::new();
    volume(dir, "many.nii", [40, 40, 40], |x, y, z| {
        *label.entry((x / 3, y / 3, z / 3)).or_insert_with(|| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % 30_000) as i64 + 1
        })
    })
}

/// Case 4: a run stopped while it writes leaves nothing behind.
#[cfg(unix)]
#[test]
fn stopped_while_writing_leaves_nothing() {
    use std::os::unix::process::ExitStatusExt;
    for signal in ["INT", "TERM"] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        many_labels(d);
        let before = snapshot(d);
        let mut child = Command::new(bin())
            .args(["extract", "many.nii", "-o", "out", "--no-remesh", "-q"])
            .current_dir(d)
            .spawn()
            .unwrap();
        // wait for the temporary output directory to fill (not the probe of
        // the destination at the start), then stop the run
        let started = std::time::Instant::now();
        let mut seen = false;
        while started.elapsed().as_secs() < 60 {
            seen = std::fs::read_dir(d).unwrap().flatten().any(|e| {
                e.file_name().to_string_lossy().starts_with(".septa-")
                    && e.path().join("patches").is_dir()
            });
            if seen || child.try_wait().unwrap().is_some() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        assert!(seen, "never saw the temporary directory");
        let killed = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let status = child.wait().unwrap();
        assert!(
            status.signal().is_some() || status.code().is_some_and(|c| c > 128),
            "SIG{signal}: {status:?}"
        );
        assert_eq!(snapshot(d), before, "SIG{signal}: something was left");
    }
}

/// Case 5: a 4.8 MB gzip NIfTI whose header declares 1700³ voxels: `info`
/// under an address-space limit fails with a message (the data is short),
/// instead of aborting on a 4 GiB allocation made up front.
#[cfg(unix)]
#[test]
fn a_huge_claim_in_a_small_gzip_is_an_error_not_an_abort() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let nii = std::fs::read(blocks(d, "small.nii")).unwrap();
    let mut header = nii[..352].to_vec();
    for (k, v) in [3i16, 1700, 1700, 1700].iter().enumerate() {
        header[40 + 2 * k..42 + 2 * k].copy_from_slice(&v.to_le_bytes());
    }
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::none());
    e.write_all(&header).unwrap();
    e.write_all(&vec![1u8; 4_800_000]).unwrap();
    put(d, "huge.nii.gz", e.finish().unwrap());
    let o = Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 1000000 && exec \"$0\" info huge.nii.gz")
        .arg(bin())
        .current_dir(d)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("huge.nii.gz") && err.contains("truncated"),
        "{err}"
    );
}

/// Running out of memory is an error message and exit status 2 at whatever
/// point the system refuses (`ulimit -v` from tight to ample, past the
/// estimate with `--max-memory`): never Rust's abort (`memory allocation of
/// N bytes failed`, SIGABRT), a panic (a thread that could not start) or a
/// backtrace; and a run that failed leaves no output directory.
#[test]
#[cfg(target_os = "linux")]
fn out_of_memory_is_an_error_at_any_limit() {
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/heart_phantom_48.nii.gz");
    let mut refused = 0;
    let mut finished = 0;
    for limit_mb in [24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 1024] {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let out = Command::new("sh")
            .arg("-c")
            .arg(format!(
                "ulimit -v {} && exec \"$0\" \"$@\"",
                limit_mb * 1024
            ))
            .arg(bin())
            .args([
                "extract",
                "--no-remesh",
                "--max-memory",
                "100G",
                "-q",
                "-o",
                "out",
            ])
            .arg(&input)
            .current_dir(dir)
            .env_remove("RUST_BACKTRACE")
            .output()
            .expect("run septa under ulimit");
        let err = String::from_utf8_lossy(&out.stderr);
        let case = format!("ulimit -v {limit_mb} MB: {:?}\n{err}", out.status);
        for bad in ["panicked", "memory allocation of", "backtrace"] {
            assert!(!err.contains(bad), "{case}");
        }
        match out.status.code() {
            Some(0) => finished += 1,
            Some(2) => {
                assert!(err.starts_with("error: "), "{case}");
                assert!(!dir.join("out").exists(), "{case}");
                refused += usize::from(err.contains("out of memory"));
            }
            _ => panic!("{case}"),
        }
    }
    assert!(refused > 0, "no limit was tight enough to test anything");
    assert!(finished > 0, "no limit was ample enough to finish");
}
