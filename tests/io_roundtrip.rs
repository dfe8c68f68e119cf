//! Round trips through every volume format septa reads, with a non-trivial
//! affine: a rotation by 0.7 rad about the oblique axis (1, 2, 3)/√14, spacing
//! 0.7 × 1.3 × 2.1 mm and an offset.
//!
//! Expected positions are computed here independently of septa's `Geometry`:
//! the rotation matrix comes from Rodrigues' formula, and a voxel (i, j, k) is at
//! `origin + R · (sx·i, sy·j, sz·k)`. For files that store RAS (NIfTI, NRRD with
//! `space: right-anterior-superior`) the same formula gives RAS millimetres, and
//! the expected LPS position is that with x and y negated.

use std::path::{Path, PathBuf};

use septa::io::{
    DataType, ReadOptions, Samples, read_image, read_label_volume, write_label_volume,
};
use septa::volume::{Dims, Geometry, LabelVolume};

type Mat3 = [[f64; 3]; 3];

const SPACING: [f64; 3] = [0.7, 1.3, 2.1];
const ORIGIN: [f64; 3] = [12.5, -30.25, 7.0];
const ANGLE: f64 = 0.7;
const DIMS: [usize; 3] = [5, 4, 3];
/// Voxels whose positions are checked: corners and an interior one.
const PROBES: [[usize; 3]; 6] = [
    [0, 0, 0],
    [4, 0, 0],
    [0, 3, 0],
    [0, 0, 2],
    [4, 3, 2],
    [1, 2, 1],
];

fn axis() -> [f64; 3] {
    let n = 14f64.sqrt();
    [1.0 / n, 2.0 / n, 3.0 / n]
}

/// Rows of the rotation by `angle` about the unit vector `u`:
/// `R = cos·I + sin·[u]× + (1 − cos)·u uᵀ`.
fn rodrigues(u: [f64; 3], angle: f64) -> Mat3 {
    let (s, c) = angle.sin_cos();
    let cross = [[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]];
    std::array::from_fn(|r| {
        std::array::from_fn(|k| {
            let id = if r == k { 1.0 } else { 0.0 };
            c * id + s * cross[r][k] + (1.0 - c) * u[r] * u[k]
        })
    })
}

/// `origin + R · (spacing ∘ ijk)`.
fn expected(r: &Mat3, spacing: [f64; 3], origin: [f64; 3], ijk: [usize; 3]) -> [f64; 3] {
    let v: [f64; 3] = std::array::from_fn(|c| spacing[c] * ijk[c] as f64);
    std::array::from_fn(|row| origin[row] + (0..3).map(|c| r[row][c] * v[c]).sum::<f64>())
}

fn ras_to_lps(p: [f64; 3]) -> [f64; 3] {
    [-p[0], -p[1], p[2]]
}

fn assert_positions(g: &Geometry, want: impl Fn([usize; 3]) -> [f64; 3], tol: f64) {
    for ijk in PROBES {
        let got = g
            .index_to_physical([ijk[0] as f64, ijk[1] as f64, ijk[2] as f64].into())
            .to_array();
        let want = want(ijk);
        for c in 0..3 {
            assert!(
                (got[c] - want[c]).abs() < tol,
                "voxel {ijk:?}: got {got:?}, want {want:?}"
            );
        }
    }
}

/// The label pattern used throughout (depends on all three coordinates).
fn pattern(x: usize, y: usize, z: usize) -> usize {
    (x + 2 * y + 3 * z) % 5
}

fn volume(values: [i64; 5], geometry: Geometry) -> LabelVolume {
    let dims = Dims::new(DIMS[0], DIMS[1], DIMS[2]).unwrap();
    let mut v = Vec::new();
    for z in 0..DIMS[2] {
        for y in 0..DIMS[1] {
            for x in 0..DIMS[0] {
                v.push(values[pattern(x, y, z)]);
            }
        }
    }
    LabelVolume::from_values(dims, &v, geometry).unwrap()
}

/// LPS geometry with direction columns = columns of the oblique rotation.
fn oblique_lps() -> (Mat3, Geometry) {
    let r = rodrigues(axis(), ANGLE);
    let dir = std::array::from_fn(|c| [r[0][c], r[1][c], r[2][c]]);
    (r, Geometry::new(SPACING, ORIGIN, dir).unwrap())
}

fn assert_same_labels(a: &LabelVolume, b: &LabelVolume) {
    assert_eq!(a.dims(), b.dims());
    assert_eq!(a.values(), b.values());
    assert_eq!(a.ids(), b.ids());
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

// ------------------------------------------------------------- NIfTI writer

#[test]
fn nifti_writer_round_trip_sform() {
    let dir = tmp();
    let (r, g) = oblique_lps();
    for name in ["v.nii", "v.nii.gz"] {
        let vol = volume([-3, 0, 7, 250, 1000], g);
        let path = dir.path().join(name);
        write_label_volume(&path, &vol).unwrap();
        let back = read_label_volume(&path, &ReadOptions::default()).unwrap();
        assert_same_labels(&vol, &back);
        // NIfTI-1 stores the affine as f32.
        assert_positions(
            back.geometry(),
            |ijk| expected(&r, SPACING, ORIGIN, ijk),
            1e-4,
        );
    }
}

/// The writer's qform agrees with its sform: with sform_code set to 0 the file
/// reads to the same positions.
#[test]
fn nifti_writer_qform_matches_sform() {
    let dir = tmp();
    let (r, g) = oblique_lps();
    // Also with a mirrored third axis (qfac = −1).
    let mirrored = Geometry::new(
        SPACING,
        ORIGIN,
        std::array::from_fn(|c| {
            let s = if c == 2 { -1.0 } else { 1.0 };
            [s * r[0][c], s * r[1][c], s * r[2][c]]
        }),
    )
    .unwrap();
    for (i, geom) in [g, mirrored].into_iter().enumerate() {
        let path = dir.path().join(format!("q{i}.nii"));
        write_label_volume(&path, &volume([0, 1, 2, 3, 4], geom)).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        assert_eq!(
            i16::from_le_bytes([bytes[252], bytes[253]]),
            1,
            "qform_code"
        );
        bytes[254..256].copy_from_slice(&0i16.to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        let back = read_image(&path, &ReadOptions::default()).unwrap();
        let want = |ijk: [usize; 3]| {
            geom.index_to_physical([ijk[0] as f64, ijk[1] as f64, ijk[2] as f64].into())
                .to_array()
        };
        assert_positions(&back.geometry, want, 1e-4);
    }
}

// ----------------------------------------------------- hand-built NIfTI-1

/// A NIfTI-1 header (348 bytes + 4-byte extension flag), little- or big-endian.
struct Nifti1 {
    dim: [i16; 8],
    datatype: i16,
    pixdim: [f32; 8],
    qform_code: i16,
    sform_code: i16,
    quatern: [f32; 3],
    qoffset: [f32; 3],
    srow: [[f32; 4]; 3],
    scl: [f32; 2],
    magic: &'static [u8; 4],
    big_endian: bool,
}

impl Nifti1 {
    fn new(dims: [usize; 3], datatype: i16) -> Self {
        Nifti1 {
            dim: [
                3,
                dims[0] as i16,
                dims[1] as i16,
                dims[2] as i16,
                1,
                1,
                1,
                1,
            ],
            datatype,
            pixdim: [1.0; 8],
            qform_code: 0,
            sform_code: 0,
            quatern: [0.0; 3],
            qoffset: [0.0; 3],
            srow: [[0.0; 4]; 3],
            scl: [0.0, 0.0],
            magic: b"n+1\0",
            big_endian: false,
        }
    }

    fn bytes(&self) -> Vec<u8> {
        let mut b = vec![0u8; 352];
        let be = self.big_endian;
        let mut put = |at: usize, v: &[u8]| {
            let mut v = v.to_vec();
            if be {
                v.reverse();
            }
            b[at..at + v.len()].copy_from_slice(&v);
        };
        put(0, &348i32.to_le_bytes());
        for i in 0..8 {
            put(40 + 2 * i, &self.dim[i].to_le_bytes());
            put(76 + 4 * i, &self.pixdim[i].to_le_bytes());
        }
        put(70, &self.datatype.to_le_bytes());
        put(108, &352f32.to_le_bytes());
        put(112, &self.scl[0].to_le_bytes());
        put(116, &self.scl[1].to_le_bytes());
        put(252, &self.qform_code.to_le_bytes());
        put(254, &self.sform_code.to_le_bytes());
        for i in 0..3 {
            put(256 + 4 * i, &self.quatern[i].to_le_bytes());
            put(268 + 4 * i, &self.qoffset[i].to_le_bytes());
            for c in 0..4 {
                put(280 + 16 * i + 4 * c, &self.srow[i][c].to_le_bytes());
            }
        }
        b[344..348].copy_from_slice(self.magic);
        b
    }
}

fn pattern_u8() -> Vec<u8> {
    let mut v = Vec::new();
    for z in 0..DIMS[2] {
        for y in 0..DIMS[1] {
            for x in 0..DIMS[0] {
                v.push(pattern(x, y, z) as u8);
            }
        }
    }
    v
}

fn write(path: &Path, parts: &[&[u8]]) -> PathBuf {
    std::fs::write(path, parts.concat()).unwrap();
    path.to_path_buf()
}

fn check_pattern(path: &Path) {
    let v = read_label_volume(path, &ReadOptions::default()).unwrap();
    for z in 0..DIMS[2] {
        for y in 0..DIMS[1] {
            for x in 0..DIMS[0] {
                assert_eq!(
                    v.value(v.id_at(x, y, z)),
                    pattern(x, y, z) as i64,
                    "voxel {x},{y},{z}"
                );
            }
        }
    }
}

/// qform only: quaternion of the rotation about `u` by θ is
/// (cos θ/2, u·sin θ/2); qfac = ±1 flips the third axis.
#[test]
fn nifti_qform_hand_built() {
    let dir = tmp();
    let u = axis();
    let r = rodrigues(u, ANGLE);
    let offset = [-20.0, 15.5, 3.25];
    for qfac in [1.0f64, -1.0] {
        let mut h = Nifti1::new(DIMS, 2);
        h.qform_code = 1;
        h.pixdim = [qfac as f32, 0.7, 1.3, 2.1, 1.0, 1.0, 1.0, 1.0];
        h.quatern = std::array::from_fn(|i| (u[i] * (ANGLE / 2.0).sin()) as f32);
        h.qoffset = offset.map(|v| v as f32);
        let path = write(
            &dir.path().join(format!("q{qfac}.nii")),
            &[&h.bytes(), &pattern_u8()],
        );
        let img = read_image(&path, &ReadOptions::default()).unwrap();
        let spacing = [SPACING[0], SPACING[1], SPACING[2] * qfac];
        assert_positions(
            &img.geometry,
            |ijk| ras_to_lps(expected(&r, spacing, offset, ijk)),
            1e-4,
        );
        check_pattern(&path);
    }
}

/// sform wins over qform; big-endian header and data.
#[test]
fn nifti_sform_big_endian_hand_built() {
    let dir = tmp();
    let r = rodrigues(axis(), ANGLE);
    let mut h = Nifti1::new(DIMS, 512); // uint16
    h.big_endian = true;
    h.sform_code = 2;
    h.qform_code = 1; // ignored: identity quaternion, unit spacing
    h.srow = std::array::from_fn(|row| {
        let mut s = [0f32; 4];
        for c in 0..3 {
            s[c] = (r[row][c] * SPACING[c]) as f32;
        }
        s[3] = ORIGIN[row] as f32;
        s
    });
    let data: Vec<u8> = pattern_u8()
        .iter()
        .flat_map(|&v| (u16::from(v) * 1000).to_be_bytes())
        .collect();
    let path = write(&dir.path().join("be.nii"), &[&h.bytes(), &data]);
    let img = read_image(&path, &ReadOptions::default()).unwrap();
    assert_eq!(img.samples.dtype(), DataType::U16);
    assert_positions(
        &img.geometry,
        |ijk| ras_to_lps(expected(&r, SPACING, ORIGIN, ijk)),
        1e-4,
    );
    let v = img.into_label_volume().unwrap();
    assert_eq!(v.values(), &[0, 1000, 2000, 3000, 4000]);
}

/// No sform, no qform: "method 1", diag(pixdim).
#[test]
fn nifti_pixdim_only() {
    let dir = tmp();
    let mut h = Nifti1::new(DIMS, 2);
    h.pixdim = [0.0, 0.7, 1.3, 2.1, 0.0, 0.0, 0.0, 0.0];
    let path = write(&dir.path().join("m1.nii"), &[&h.bytes(), &pattern_u8()]);
    let img = read_image(&path, &ReadOptions::default()).unwrap();
    let id = rodrigues([1.0, 0.0, 0.0], 0.0);
    assert_positions(
        &img.geometry,
        |ijk| ras_to_lps(expected(&id, SPACING, [0.0; 3], ijk)),
        1e-6,
    );
}

/// Spatial units other than mm (xyzt_units & 7: 1 = metre, 3 = micron) scale
/// the affine to mm.
#[test]
fn nifti_units_scale_to_mm() {
    let dir = tmp();
    let (r, g) = oblique_lps();
    let path = dir.path().join("units.nii");
    write_label_volume(&path, &volume([0, 1, 2, 3, 4], g)).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    assert_eq!(bytes[123], 2, "written in mm");
    for (unit, scale) in [(1u8, 1000.0), (3, 0.001), (0, 1.0), (2 | 8, 1.0)] {
        bytes[123] = unit;
        std::fs::write(&path, &bytes).unwrap();
        let img = read_image(&path, &ReadOptions::default()).unwrap();
        let spacing = SPACING.map(|s| s * scale);
        let origin = ORIGIN.map(|o| o * scale);
        let tol = 1e-4 * scale.max(1.0);
        assert_positions(&img.geometry, |ijk| expected(&r, spacing, origin, ijk), tol);
    }
}

/// scl_slope/scl_inter are applied (samples become float64).
#[test]
fn nifti_scaling() {
    let dir = tmp();
    let mut h = Nifti1::new(DIMS, 2);
    h.scl = [2.0, -1.0];
    let path = write(&dir.path().join("scl.nii"), &[&h.bytes(), &pattern_u8()]);
    let img = read_image(&path, &ReadOptions::default()).unwrap();
    assert_eq!(img.samples.dtype(), DataType::F64);
    assert_eq!(img.into_label_volume().unwrap().values(), &[-1, 1, 3, 5, 7]);
    // (1, 0) is the identity: the samples keep their type.
    h.scl = [1.0, 0.0];
    let path = write(&dir.path().join("id.nii"), &[&h.bytes(), &pattern_u8()]);
    assert_eq!(
        read_image(&path, &ReadOptions::default())
            .unwrap()
            .samples
            .dtype(),
        DataType::U8
    );
}

/// `.hdr` + `.img` pair (magic "ni1"), opened by either name, also gzipped.
#[test]
fn nifti_hdr_img_pair() {
    let dir = tmp();
    let mut h = Nifti1::new(DIMS, 2);
    h.magic = b"ni1\0";
    let mut header = h.bytes();
    header.truncate(348);
    header[108..112].copy_from_slice(&0f32.to_le_bytes()); // vox_offset 0 in the .img
    write(&dir.path().join("pair.hdr"), &[&header]);
    write(&dir.path().join("pair.img"), &[&pattern_u8()]);
    check_pattern(&dir.path().join("pair.hdr"));
    check_pattern(&dir.path().join("pair.img"));
    write(&dir.path().join("zpair.hdr.gz"), &[&gzip(&header)]);
    write(&dir.path().join("zpair.img.gz"), &[&gzip(&pattern_u8())]);
    check_pattern(&dir.path().join("zpair.hdr.gz"));
}

/// A `.nii` that is really gzip still reads.
#[test]
fn nifti_gzip_detected_by_magic() {
    let dir = tmp();
    let h = Nifti1::new(DIMS, 2);
    let path = write(
        &dir.path().join("secretly_gz.nii"),
        &[&gzip(&[h.bytes(), pattern_u8()].concat())],
    );
    check_pattern(&path);
}

/// 4-D: dims keep the 4th axis, time step from pixdim[4]; trailing 1s trimmed.
#[test]
fn nifti_four_d() {
    let dir = tmp();
    let mut h = Nifti1::new(DIMS, 2);
    h.dim = [5, 5, 4, 3, 2, 1, 1, 1];
    h.pixdim[4] = 2.5;
    let data = [pattern_u8(), pattern_u8()].concat();
    let path = write(&dir.path().join("t.nii"), &[&h.bytes(), &data]);
    let img = read_image(&path, &ReadOptions::default()).unwrap();
    assert_eq!(img.dims, vec![5, 4, 3, 2]);
    assert_eq!(img.time_step, Some(2.5));
    assert_eq!(img.samples.len(), 120);
    // One frame in 4-D is 3-D.
    h.dim = [4, 5, 4, 3, 1, 1, 1, 1];
    let path = write(&dir.path().join("t1.nii"), &[&h.bytes(), &pattern_u8()]);
    assert_eq!(
        read_image(&path, &ReadOptions::default()).unwrap().dims,
        vec![5, 4, 3]
    );
    check_pattern(&path);
}

/// 4-D NRRD (time axis last, its spacing the time step) and MetaImage (the 4th
/// ElementSpacing).
#[test]
fn four_d_nrrd_and_metaimage() {
    let dir = tmp();
    let data = [pattern_u8(), pattern_u8()].concat();
    let header = "NRRD0004\ntype: uint8\ndimension: 4\nsizes: 5 4 3 2\nspacings: 0.7 1.3 2.1 0.25\nkinds: domain domain domain time\nencoding: raw\n\n";
    let nrrd = write(&dir.path().join("t.nrrd"), &[header.as_bytes(), &data]);
    let header = "NDims = 4\nDimSize = 5 4 3 2\nElementSpacing = 0.7 1.3 2.1 0.25\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n";
    let mha = write(&dir.path().join("t.mha"), &[header.as_bytes(), &data]);
    for path in [nrrd, mha] {
        let img = read_image(&path, &ReadOptions::default()).unwrap();
        assert_eq!(img.dims, vec![5, 4, 3, 2], "{}", path.display());
        assert_eq!(img.time_step, Some(0.25), "{}", path.display());
        assert_eq!(img.geometry.spacing(), SPACING);
    }
}

/// NIfTI-2 (540-byte header, f64 affine), little- and big-endian.
#[test]
fn nifti2_sform() {
    let dir = tmp();
    let r = rodrigues(axis(), ANGLE);
    for big in [false, true] {
        let mut b = vec![0u8; 544];
        let mut put = |at: usize, v: &[u8]| {
            let mut v = v.to_vec();
            if big {
                v.reverse();
            }
            b[at..at + v.len()].copy_from_slice(&v);
        };
        put(0, &540i32.to_le_bytes());
        put(12, &4i16.to_le_bytes()); // int16
        let dim = [3i64, 5, 4, 3, 1, 1, 1, 1];
        for (i, d) in dim.iter().enumerate() {
            put(16 + 8 * i, &d.to_le_bytes());
            put(104 + 8 * i, &1f64.to_le_bytes());
        }
        put(168, &544i64.to_le_bytes());
        put(348, &1i32.to_le_bytes()); // sform_code
        for row in 0..3 {
            for c in 0..3 {
                put(
                    400 + 32 * row + 8 * c,
                    &(r[row][c] * SPACING[c]).to_le_bytes(),
                );
            }
            put(400 + 32 * row + 24, &ORIGIN[row].to_le_bytes());
        }
        b[4..12].copy_from_slice(b"n+2\0\r\n\x1a\n");
        let data: Vec<u8> = pattern_u8()
            .iter()
            .flat_map(|&v| {
                let v = i16::from(v) - 2;
                if big {
                    v.to_be_bytes()
                } else {
                    v.to_le_bytes()
                }
            })
            .collect();
        let path = write(&dir.path().join(format!("n2{big}.nii")), &[&b, &data]);
        let img = read_image(&path, &ReadOptions::default()).unwrap();
        assert_positions(
            &img.geometry,
            |ijk| ras_to_lps(expected(&r, SPACING, ORIGIN, ijk)),
            1e-9,
        );
        assert_eq!(
            img.into_label_volume().unwrap().values(),
            &[-2, -1, 0, 1, 2]
        );
    }
}

// --------------------------------------------------------------------- NRRD

#[test]
fn nrrd_writer_round_trip() {
    let dir = tmp();
    let (r, g) = oblique_lps();
    let vol = volume([-70_000, 0, 1, 2, 70_000], g);
    let path = dir.path().join("v.nrrd");
    write_label_volume(&path, &vol).unwrap();
    let back = read_label_volume(&path, &ReadOptions::default()).unwrap();
    assert_same_labels(&vol, &back);
    assert_positions(
        back.geometry(),
        |ijk| expected(&r, SPACING, ORIGIN, ijk),
        1e-9,
    );
}

fn vec3(v: [f64; 3]) -> String {
    format!("({},{},{})", v[0], v[1], v[2])
}

/// Header lines for the oblique geometry given in `space` coordinates.
fn nrrd_geometry_lines(space: &str, r: &Mat3, origin: [f64; 3]) -> String {
    let cols: Vec<String> = (0..3)
        .map(|c| vec3(std::array::from_fn(|row| r[row][c] * SPACING[c])))
        .collect();
    format!(
        "space: {space}\nspace directions: {}\nspace origin: {}\n",
        cols.join(" "),
        vec3(origin)
    )
}

#[test]
fn nrrd_ras_and_lps_spaces() {
    let dir = tmp();
    let r = rodrigues(axis(), ANGLE);
    for (space, to_lps) in [
        (
            "right-anterior-superior",
            ras_to_lps as fn([f64; 3]) -> [f64; 3],
        ),
        ("RAS", ras_to_lps),
        ("left-posterior-superior", |p| p),
        ("LPS", |p| p),
    ] {
        let header = format!(
            "NRRD0004\n# comment\ntype: uchar\ndimension: 3\nsizes: 5 4 3\n{}kinds: domain domain domain\nencoding: raw\nmeta:=data\n\n",
            nrrd_geometry_lines(space, &r, ORIGIN)
        );
        let path = write(
            &dir.path().join(format!("{space}.nrrd")),
            &[header.as_bytes(), &pattern_u8()],
        );
        let img = read_image(&path, &ReadOptions::default()).unwrap();
        assert_positions(
            &img.geometry,
            |ijk| to_lps(expected(&r, SPACING, ORIGIN, ijk)),
            1e-9,
        );
        check_pattern(&path);
    }
}

/// Detached header with a gzip data file, big-endian shorts, a leading axis of
/// size 1 (`none` direction), line skip and byte skip.
#[test]
fn nhdr_detached_gzip() {
    let dir = tmp();
    let r = rodrigues(axis(), ANGLE);
    let dirs: Vec<String> = (0..3)
        .map(|c| vec3(std::array::from_fn(|row| r[row][c] * SPACING[c])))
        .collect();
    let header = format!(
        "NRRD0005\ntype: short\ndimension: 4\nspace: RAS\nsizes: 1 5 4 3\nspace directions: none {}\nspace origin: {}\nendian: big\nencoding: gz\ndata file: sub/d.raw.gz\nline skip: 1\nbyte skip: 3\n",
        dirs.join(" "),
        vec3(ORIGIN)
    );
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    let mut data = vec![1u8, 2, 3];
    data.extend(
        pattern_u8()
            .iter()
            .flat_map(|&v| i16::from(v).to_be_bytes()),
    );
    write(
        &dir.path().join("sub/d.raw.gz"),
        &[b"a line to skip\n", &gzip(&data)],
    );
    let path = write(&dir.path().join("d.nhdr"), &[header.as_bytes()]);
    let img = read_image(&path, &ReadOptions::default()).unwrap();
    assert_eq!(img.dims, vec![5, 4, 3]);
    assert_positions(
        &img.geometry,
        |ijk| ras_to_lps(expected(&r, SPACING, ORIGIN, ijk)),
        1e-9,
    );
    check_pattern(&path);
}

/// `spacings` without space directions; text encoding; byte skip −1.
#[test]
fn nrrd_spacings_text_and_byte_skip_minus_one() {
    let dir = tmp();
    let text: Vec<String> = pattern_u8().iter().map(u8::to_string).collect();
    let header = "NRRD0004\ntype: int\ndimension: 3\nsizes: 5 4 3\nspacings: 0.7 1.3 2.1\nencoding: text\n\n";
    let path = write(
        &dir.path().join("t.nrrd"),
        &[header.as_bytes(), text.join(" ").as_bytes()],
    );
    let img = read_image(&path, &ReadOptions::default()).unwrap();
    let id = rodrigues([1.0, 0.0, 0.0], 0.0);
    assert_positions(
        &img.geometry,
        |ijk| expected(&id, SPACING, [0.0; 3], ijk),
        1e-12,
    );
    check_pattern(&path);

    let header = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 5 4 3\nencoding: raw\nbyte skip: -1\ndata file: d.bin\n";
    write(
        &dir.path().join("d.bin"),
        &[b"some leading junk", &pattern_u8()],
    );
    let path = write(&dir.path().join("d.nhdr"), &[header.as_bytes()]);
    check_pattern(&path);
}

// ---------------------------------------------------------------- MetaImage

/// `TransformMatrix` listed as ITK writes it: the direction of axis 0, then of
/// axis 1, then of axis 2 (i.e. the direction matrix column by column).
fn mhd_header(r: &Mat3, extra: &str, data_file: &str) -> String {
    let tm: Vec<String> = (0..3)
        .flat_map(|c| (0..3).map(move |row| r[row][c].to_string()))
        .collect();
    format!(
        "ObjectType = Image\nNDims = 3\nBinaryData = True\n{extra}TransformMatrix = {}\nOffset = {} {} {}\nCenterOfRotation = 0 0 0\nAnatomicalOrientation = RAI\nElementSpacing = 0.7 1.3 2.1\nDimSize = 5 4 3\nElementType = MET_UCHAR\nElementDataFile = {data_file}\n",
        tm.join(" "),
        ORIGIN[0],
        ORIGIN[1],
        ORIGIN[2]
    )
}

#[test]
fn metaimage_mha_transform_matrix() {
    let dir = tmp();
    let r = rodrigues(axis(), ANGLE);
    let header = mhd_header(&r, "BinaryDataByteOrderMSB = False\n", "LOCAL");
    let path = write(
        &dir.path().join("v.mha"),
        &[header.as_bytes(), &pattern_u8()],
    );
    let img = read_image(&path, &ReadOptions::default()).unwrap();
    assert_positions(
        &img.geometry,
        |ijk| expected(&r, SPACING, ORIGIN, ijk),
        1e-9,
    );
    check_pattern(&path);
}

#[test]
fn metaimage_compressed_zlib_and_gzip() {
    let dir = tmp();
    let r = rodrigues(axis(), ANGLE);
    for (name, data) in [("z", zlib(&pattern_u8())), ("g", gzip(&pattern_u8()))] {
        let header = mhd_header(
            &r,
            &format!(
                "CompressedData = True\nCompressedDataSize = {}\n",
                data.len()
            ),
            "LOCAL",
        );
        let path = write(
            &dir.path().join(format!("{name}.mha")),
            &[header.as_bytes(), &data],
        );
        check_pattern(&path);
    }
}

/// `.mhd` + data file: big-endian shorts, HeaderSize, and HeaderSize = −1.
#[test]
fn metaimage_mhd_separate_file() {
    let dir = tmp();
    let r = rodrigues(axis(), ANGLE);
    let data: Vec<u8> = pattern_u8()
        .iter()
        .flat_map(|&v| i16::from(v).to_be_bytes())
        .collect();
    for (i, header_size) in ["4", "-1"].iter().enumerate() {
        let header = mhd_header(
            &r,
            &format!("ElementByteOrderMSB = True\nHeaderSize = {header_size}\n"),
            "d.raw",
        )
        .replace("MET_UCHAR", "MET_SHORT");
        write(&dir.path().join("d.raw"), &[b"junk", &data]);
        let path = write(&dir.path().join(format!("v{i}.mhd")), &[header.as_bytes()]);
        let img = read_image(&path, &ReadOptions::default()).unwrap();
        assert_eq!(img.samples.dtype(), DataType::I16);
        assert_positions(
            &img.geometry,
            |ijk| expected(&r, SPACING, ORIGIN, ijk),
            1e-9,
        );
        check_pattern(&path);
    }
}

// ---------------------------------------------------------------------- raw

#[test]
fn raw_with_options() {
    let dir = tmp();
    let data: Vec<u8> = pattern_u8()
        .iter()
        .flat_map(|&v| (f32::from(v) * 2.0).to_be_bytes())
        .collect();
    let path = write(&dir.path().join("v.raw"), &[&[9u8; 16], &data]);
    let opts = ReadOptions {
        dims: Some(DIMS),
        dtype: Some(DataType::F32),
        spacing: Some(SPACING),
        big_endian: true,
        header_bytes: 16,
    };
    let img = read_image(&path, &opts).unwrap();
    assert_eq!(img.geometry.spacing(), SPACING);
    assert_eq!(
        read_label_volume(&path, &opts).unwrap().values(),
        &[0, 2, 4, 6, 8]
    );
}

// ----------------------------------------------------------- all label types

/// Samples of every integer type and integral floats keep their values, read
/// from both NIfTI and NRRD.
#[test]
fn all_label_dtypes_keep_values() {
    let dir = tmp();
    let cases: [(DataType, i16, &str, [f64; 5]); 10] = [
        (DataType::U8, 2, "uchar", [0.0, 1.0, 7.0, 200.0, 255.0]),
        (
            DataType::I8,
            256,
            "signed char",
            [-128.0, -1.0, 0.0, 5.0, 127.0],
        ),
        (
            DataType::U16,
            512,
            "ushort",
            [0.0, 1.0, 300.0, 40_000.0, 65_535.0],
        ),
        (
            DataType::I16,
            4,
            "short",
            [-32_768.0, -300.0, 0.0, 2.0, 32_767.0],
        ),
        (
            DataType::U32,
            768,
            "uint",
            [0.0, 1.0, 70_000.0, 3.0e9, 4_294_967_295.0],
        ),
        (
            DataType::I32,
            8,
            "int",
            [-2_147_483_648.0, -70_000.0, 0.0, 9.0, 2_147_483_647.0],
        ),
        (
            DataType::U64,
            1280,
            "ulonglong",
            [0.0, 1.0, 2.0, 1.0e12, 5.0e12],
        ),
        (
            DataType::I64,
            1024,
            "longlong",
            [-5.0e12, -1.0, 0.0, 1.0, 5.0e12],
        ),
        (
            DataType::F32,
            16,
            "float",
            [-1000.0, -1.0, 0.0, 3.0, 16_777_216.0],
        ),
        (
            DataType::F64,
            64,
            "double",
            [-3.0e9, -2.0, 0.0, 1.0, 4.0e15],
        ),
    ];
    for (dtype, code, nrrd_type, values) in cases {
        let data = encode(dtype, &values);
        let h = Nifti1::new(DIMS, code);
        let nii = write(
            &dir.path().join(format!("{}.nii", dtype.name())),
            &[&h.bytes(), &data],
        );
        let header = format!(
            "NRRD0004\ntype: {nrrd_type}\ndimension: 3\nsizes: 5 4 3\nendian: little\nencoding: raw\n\n"
        );
        let nrrd = write(
            &dir.path().join(format!("{}.nrrd", dtype.name())),
            &[header.as_bytes(), &data],
        );
        for path in [nii, nrrd] {
            let img = read_image(&path, &ReadOptions::default()).unwrap();
            assert_eq!(img.samples.dtype(), dtype, "{}", path.display());
            let v = img.into_label_volume().unwrap();
            let want: Vec<i64> = values.iter().map(|&x| x as i64).collect();
            assert_eq!(v.values(), &want[..], "{}", path.display());
            assert_eq!(v.value(v.id_at(4, 3, 2)), want[pattern(4, 3, 2)]);
        }
    }
}

/// Little-endian samples of `dtype` following [`pattern`] through `values`.
fn encode(dtype: DataType, values: &[f64; 5]) -> Vec<u8> {
    let mut out = Vec::new();
    for &p in &pattern_u8() {
        let x = values[p as usize];
        let samples = match dtype {
            DataType::U8 => Samples::U8(vec![x as u8]),
            DataType::I8 => Samples::I8(vec![x as i8]),
            DataType::U16 => Samples::U16(vec![x as u16]),
            DataType::I16 => Samples::I16(vec![x as i16]),
            DataType::U32 => Samples::U32(vec![x as u32]),
            DataType::I32 => Samples::I32(vec![x as i32]),
            DataType::U64 => Samples::U64(vec![x as u64]),
            DataType::I64 => Samples::I64(vec![x as i64]),
            DataType::F32 => Samples::F32(vec![x as f32]),
            DataType::F64 => Samples::F64(vec![x]),
        };
        out.extend(samples.to_le_bytes());
    }
    out
}

#[test]
fn writers_pick_types_that_keep_values() {
    let dir = tmp();
    let (_, g) = oblique_lps();
    for values in [
        [0, 1, 2, 3, 255],
        [-128, 0, 1, 2, 127],
        [0, 1, 2, 3, 65_535],
        [-32_768, 0, 1, 2, 32_767],
        [0, 1, 2, 3, 4_294_967_295],
        [-2_147_483_648, 0, 1, 2, 2_147_483_647],
        [-(1 << 40), 0, 1, 2, 1 << 40],
    ] {
        let vol = volume(values, g);
        for name in ["w.nii", "w.nii.gz", "w.nrrd"] {
            let path = dir.path().join(name);
            write_label_volume(&path, &vol).unwrap();
            assert_same_labels(
                &vol,
                &read_label_volume(&path, &ReadOptions::default()).unwrap(),
            );
        }
    }
}

// ---------------------------------------------------------------- real data

/// ITK's k-means head segmentation (see data/NOTICE.md).
#[test]
fn itk_kmeans_head() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/itk_kmeans_head.nii.gz");
    let v = read_label_volume(&path, &ReadOptions::default()).unwrap();
    assert_eq!(v.dims().to_array(), [128, 128, 62]);
    let g = v.geometry();
    for (a, b) in g.spacing().iter().zip([2.0, 2.0, 3.0]) {
        assert!((a - b).abs() < 1e-9);
    }
    assert_eq!(g.orientation_code(), "LSA");
    // RAS affine of the header: [-2 0 0 0; 0 0 3 -254; 0 2 0 0].
    let ras = g.to_ras();
    let want = [
        [-2.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 3.0, -254.0],
        [0.0, 2.0, 0.0, 0.0],
    ];
    for r in 0..3 {
        for c in 0..4 {
            assert!((ras[r][c] - want[r][c]).abs() < 1e-6, "{ras:?}");
        }
    }
    assert_eq!(v.values(), &[0, 1, 2, 3, 4, 5, 6]);
    assert_eq!(
        v.voxel_counts(),
        vec![126, 729_202, 114_711, 43_423, 24_061, 57_084, 47_201]
    );
}

// ------------------------------------------------------------------ helpers

fn gzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn zlib(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}
