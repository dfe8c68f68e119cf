//! Bad input, one test per problem: each asserts that reading fails with a
//! message that names the problem and the file.
//!
//! Most NIfTI cases start from a valid file written by septa and patch header
//! fields at their offsets in the NIfTI-1 standard (dim at 40, datatype at 70,
//! pixdim at 76, qform/sform codes at 252/254, magic at 344).

use std::path::{Path, PathBuf};

use septa::io::{DataType, ReadOptions, read_image, read_label_volume, write_label_volume};
use septa::volume::{Dims, Geometry, LabelVolume};

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// A valid 4×3×2 uint8 `.nii` (352-byte header + 24 bytes), as bytes.
fn valid_nii(dir: &Path) -> Vec<u8> {
    let dims = Dims::new(4, 3, 2).unwrap();
    let values: Vec<i64> = (0..24).map(|i| i % 3).collect();
    let vol = LabelVolume::from_values(dims, &values, Geometry::identity()).unwrap();
    let path = dir.join("valid.nii");
    write_label_volume(&path, &vol).unwrap();
    std::fs::read(path).unwrap()
}

fn put_i16(b: &mut [u8], at: usize, v: i16) {
    b[at..at + 2].copy_from_slice(&v.to_le_bytes());
}

fn put_f32(b: &mut [u8], at: usize, v: f32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Reads `path` as labels; the error must contain every one of `needles` and
/// the file name.
fn expect_error(path: &Path, opts: &ReadOptions, needles: &[&str]) -> String {
    let err = match read_label_volume(path, opts) {
        Ok(_) => panic!("{} read without error", path.display()),
        Err(e) => e.to_string(),
    };
    let name = path.file_name().unwrap().to_string_lossy();
    assert!(
        err.contains(&*name),
        "message does not name the file: {err}"
    );
    for n in needles {
        assert!(err.contains(n), "message lacks {n:?}: {err}");
    }
    err
}

fn no_opts() -> ReadOptions {
    ReadOptions::default()
}

#[test]
fn truncated_nifti() {
    let dir = tmp();
    let b = valid_nii(dir.path());
    let path = write(dir.path(), "short.nii", &b[..b.len() - 5]);
    expect_error(
        &path,
        &no_opts(),
        &["truncated: expected 24 bytes of voxel data after offset 352, found 19"],
    );
}

#[test]
fn truncated_header() {
    let dir = tmp();
    let b = valid_nii(dir.path());
    let path = write(dir.path(), "stub.nii", &b[..100]);
    expect_error(&path, &no_opts(), &["truncated", "348"]);
}

#[test]
fn wrong_magic() {
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    b[344..348].copy_from_slice(b"xyz\0");
    let path = write(dir.path(), "magic.nii", &b);
    expect_error(&path, &no_opts(), &["wrong magic", "xyz"]);
}

#[test]
fn not_a_nifti_header_size() {
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    b[0..4].copy_from_slice(&1234i32.to_le_bytes());
    let path = write(dir.path(), "size.nii", &b);
    expect_error(&path, &no_opts(), &["sizeof_hdr is 1234"]);
}

#[test]
fn nrrd_wrong_magic() {
    let dir = tmp();
    let path = write(dir.path(), "magic.nrrd", b"PNRD0004\ntype: uchar\n\n");
    expect_error(&path, &no_opts(), &["wrong magic"]);
}

#[test]
fn unsupported_datatype() {
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    put_i16(&mut b, 70, 128);
    let path = write(dir.path(), "rgb.nii", &b);
    expect_error(&path, &no_opts(), &["unsupported datatype 128 (rgb24)"]);
    put_i16(&mut b, 70, 1536);
    let path = write(dir.path(), "f128.nii", &b);
    expect_error(&path, &no_opts(), &["unsupported datatype 1536 (float128)"]);
}

#[test]
fn unsupported_metaimage_element_type() {
    let dir = tmp();
    let path = write(
        dir.path(),
        "vec.mha",
        b"NDims = 3\nDimSize = 1 1 1\nElementType = MET_FLOAT_ARRAY\nElementDataFile = LOCAL\n\0\0\0\0",
    );
    expect_error(
        &path,
        &no_opts(),
        &["unsupported ElementType", "MET_FLOAT_ARRAY"],
    );
}

#[test]
fn raw_dims_not_matching_data_length() {
    let dir = tmp();
    let path = write(dir.path(), "v.raw", &[0u8; 100]);
    let opts = ReadOptions {
        dims: Some([4, 3, 2]),
        dtype: Some(DataType::U16),
        ..ReadOptions::default()
    };
    expect_error(&path, &opts, &["expected 48 bytes", "found 100"]);
}

#[test]
fn nrrd_sizes_larger_than_data() {
    let dir = tmp();
    let path = write(
        dir.path(),
        "big.nrrd",
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 10 10 10\nencoding: raw\n\n0123456789",
    );
    expect_error(
        &path,
        &no_opts(),
        &["truncated: expected 1000 bytes of voxel data after offset 0, found 10"],
    );
}

#[test]
fn dims_times_bytes_overflow() {
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    put_i16(&mut b, 40, 7);
    for i in 1..=7 {
        put_i16(&mut b, 40 + 2 * i, 32_767);
    }
    let path = write(dir.path(), "overflow.nii", &b);
    expect_error(&path, &no_opts(), &["overflow"]);
}

#[test]
fn huge_dims_claim_errors_without_allocating() {
    // 10^12 voxels of float64 claimed by a 376-byte file: rejected by comparing
    // with the file length (an allocation would abort the test process).
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    put_i16(&mut b, 40, 4);
    for i in 1..=4 {
        put_i16(&mut b, 40 + 2 * i, 1000);
    }
    put_i16(&mut b, 70, 64);
    let path = write(dir.path(), "huge.nii", &b);
    expect_error(
        &path,
        &no_opts(),
        &["truncated: expected 8000000000000 bytes"],
    );
}

#[test]
fn negative_dims() {
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    put_i16(&mut b, 44, -3);
    let path = write(dir.path(), "neg.nii", &b);
    expect_error(&path, &no_opts(), &["dim[2] is -3", "at least 1"]);
}

#[test]
fn zero_dims() {
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    put_i16(&mut b, 42, 0);
    let path = write(dir.path(), "zero.nii", &b);
    expect_error(&path, &no_opts(), &["dim[1] is 0", "at least 1"]);
}

#[test]
fn bad_axis_count() {
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    put_i16(&mut b, 40, 9);
    let path = write(dir.path(), "axes.nii", &b);
    expect_error(&path, &no_opts(), &["dim[0] is 9"]);
}

#[test]
fn nrrd_zero_size() {
    let dir = tmp();
    let path = write(
        dir.path(),
        "zero.nrrd",
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 0 2\nencoding: raw\n\n",
    );
    expect_error(&path, &no_opts(), &["sizes", "at least 1"]);
}

/// No sform or qform: spacing comes from pixdim and must be positive.
fn nii_without_transforms(dir: &Path) -> Vec<u8> {
    let mut b = valid_nii(dir);
    put_i16(&mut b, 252, 0);
    put_i16(&mut b, 254, 0);
    b
}

#[test]
fn zero_spacing() {
    let dir = tmp();
    let mut b = nii_without_transforms(dir.path());
    put_f32(&mut b, 76 + 8, 0.0);
    let path = write(dir.path(), "zero_spacing.nii", &b);
    expect_error(&path, &no_opts(), &["pixdim[2] is 0", "spacing"]);
}

#[test]
fn negative_spacing() {
    let dir = tmp();
    let mut b = nii_without_transforms(dir.path());
    put_f32(&mut b, 76 + 12, -2.0);
    let path = write(dir.path(), "neg_spacing.nii", &b);
    expect_error(&path, &no_opts(), &["pixdim[3] is -2", "spacing"]);
}

#[test]
fn zero_spacing_in_qform() {
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    put_i16(&mut b, 254, 0);
    put_f32(&mut b, 76 + 4, 0.0);
    let path = write(dir.path(), "q0.nii", &b);
    expect_error(&path, &no_opts(), &["pixdim[1] is 0", "spacing"]);
}

#[test]
fn nrrd_negative_spacing() {
    let dir = tmp();
    let path = write(
        dir.path(),
        "neg.nrrd",
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\nspacings: 1 -1 1\nencoding: raw\n\n\0",
    );
    expect_error(&path, &no_opts(), &["spacing of axis 1", "positive"]);
}

#[test]
fn metaimage_zero_spacing() {
    let dir = tmp();
    let path = write(
        dir.path(),
        "zero.mha",
        b"NDims = 3\nDimSize = 1 1 1\nElementSpacing = 1 0 1\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n\0",
    );
    expect_error(&path, &no_opts(), &["spacing along axis 1 is 0"]);
}

#[test]
fn singular_sform() {
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    for at in (280..328).step_by(4) {
        put_f32(&mut b, at, 0.0);
    }
    let path = write(dir.path(), "singular.nii", &b);
    expect_error(&path, &no_opts(), &["invalid sform geometry", "singular"]);
}

#[test]
fn non_integral_float_labels() {
    let dir = tmp();
    let mut data = Vec::new();
    for v in [0.0f32, 1.0, 2.5, 1.0] {
        data.extend(v.to_le_bytes());
    }
    let header =
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 1\nendian: little\nencoding: raw\n\n";
    let path = write(dir.path(), "float.nrrd", &[&header[..], &data].concat());
    expect_error(
        &path,
        &no_opts(),
        &["non-integral label value 2.5", "[0, 1, 0]"],
    );
    // The same file reads fine as an image (grayscale commands).
    assert!(read_image(&path, &no_opts()).is_ok());
}

#[test]
fn four_d_where_three_d_expected() {
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    // dim = [4, 4, 3, 1, 2]: two frames of 4×3×1, the same 24 samples.
    put_i16(&mut b, 40, 4);
    put_i16(&mut b, 46, 1);
    put_i16(&mut b, 48, 2);
    let path = write(dir.path(), "frames.nii", &b);
    assert_eq!(
        read_image(&path, &no_opts()).unwrap().dims,
        vec![4, 3, 1, 2]
    );
    expect_error(&path, &no_opts(), &["4-D", "septa hyper"]);
}

#[test]
fn corrupt_gzip() {
    let dir = tmp();
    let b = valid_nii(dir.path());
    let vol_path = dir.path().join("ok.nii.gz");
    std::fs::write(&vol_path, gzip(&b)).unwrap();
    let mut z = std::fs::read(&vol_path).unwrap();
    let n = z.len();
    z.truncate(n * 2 / 3);
    let path = write(dir.path(), "cut.nii.gz", &z);
    expect_error(&path, &no_opts(), &["corrupt gzip data"]);
    let mut z = gzip(&b);
    for x in &mut z[20..40] {
        *x ^= 0xa5;
    }
    let path = write(dir.path(), "garbled.nii.gz", &z);
    expect_error(&path, &no_opts(), &["corrupt gzip data"]);
}

#[test]
fn corrupt_gzip_nrrd() {
    let dir = tmp();
    let header = b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\n\n";
    let path = write(
        dir.path(),
        "bad.nrrd",
        &[&header[..], &[0x1f, 0x8b, 8, 0, 1, 2, 3, 4, 5, 6, 7]].concat(),
    );
    expect_error(&path, &no_opts(), &["corrupt gzip data"]);
}

#[test]
fn unknown_nrrd_encoding() {
    let dir = tmp();
    let path = write(
        dir.path(),
        "bz.nrrd",
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: bzip2\n\nBZh9",
    );
    expect_error(&path, &no_opts(), &["unsupported NRRD encoding", "bzip2"]);
}

#[test]
fn missing_detached_nrrd_data_file() {
    let dir = tmp();
    let path = write(
        dir.path(),
        "h.nhdr",
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: gone.raw\n",
    );
    expect_error(&path, &no_opts(), &["missing data file", "gone.raw"]);
}

#[test]
fn multi_file_nrrd_rejected() {
    let dir = tmp();
    let path = write(
        dir.path(),
        "list.nhdr",
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: LIST\na.raw\nb.raw\n",
    );
    expect_error(&path, &no_opts(), &["multi-file", "LIST"]);
}

#[test]
fn missing_metaimage_data_file() {
    let dir = tmp();
    let path = write(
        dir.path(),
        "h.mhd",
        b"NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = gone.raw\n",
    );
    expect_error(&path, &no_opts(), &["missing data file", "gone.raw"]);
}

#[test]
fn missing_img_of_hdr_pair() {
    let dir = tmp();
    let mut b = valid_nii(dir.path());
    b[344..348].copy_from_slice(b"ni1\0");
    b.truncate(348);
    let path = write(dir.path(), "lonely.hdr", &b);
    expect_error(&path, &no_opts(), &["missing data file", "lonely.img"]);
}

#[test]
fn vector_valued_nrrd_rejected() {
    let dir = tmp();
    let path = write(
        dir.path(),
        "rgb.nrrd",
        b"NRRD0004\ntype: uchar\ndimension: 4\nsizes: 3 1 1 1\nkinds: RGB-color domain domain domain\nencoding: raw\n\nabc",
    );
    expect_error(&path, &no_opts(), &["3 values per voxel"]);
}

#[test]
fn metaimage_truncated() {
    let dir = tmp();
    let path = write(
        dir.path(),
        "short.mha",
        b"NDims = 3\nDimSize = 2 2 2\nElementType = MET_SHORT\nElementDataFile = LOCAL\n0123",
    );
    expect_error(
        &path,
        &no_opts(),
        &["truncated: expected 16 bytes of voxel data after offset 0, found 4"],
    );
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn gzip_stored(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::none());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

/// Every way a gzip file can be damaged without the DEFLATE data itself
/// failing: gzip readers check the CRC-32 and ISIZE of each member and the
/// whole trailer, and so must septa (these all read "fine" before).
fn damaged_gzips(plain: &[u8]) -> Vec<(&'static str, Vec<u8>, &'static str)> {
    let good = gzip_stored(plain);
    let n = good.len();
    // a stored block holds the bytes as they are: flip the last voxel
    let mut voxel = good.clone();
    voxel[n - 9] ^= 0xc8;
    let mut crc = good.clone();
    crc[n - 8] ^= 1;
    let mut isize = good.clone();
    isize[n - 1] ^= 1;
    let mut junk = good.clone();
    junk.extend_from_slice(b"junk after the stream");
    let mut zeros = good.clone();
    zeros.extend_from_slice(&[0; 16]);
    vec![
        ("voxel", voxel, "corrupt gzip data"),
        ("crc", crc, "corrupt gzip data"),
        ("isize", isize, "corrupt gzip data"),
        ("trailer", good[..n - 3].to_vec(), "cut short"),
        ("no_trailer", good[..n - 8].to_vec(), "cut short"),
        ("junk", junk, "trailing junk"),
        ("zeros", zeros, "trailing junk"),
    ]
}

#[test]
fn gzip_checksums_and_trailer_are_verified_nifti() {
    let dir = tmp();
    let b = valid_nii(dir.path());
    let ok = write(dir.path(), "ok.nii.gz", &gzip_stored(&b));
    assert!(read_label_volume(&ok, &no_opts()).is_ok());
    for (name, bytes, needle) in damaged_gzips(&b) {
        let path = write(dir.path(), &format!("{name}.nii.gz"), &bytes);
        expect_error(&path, &no_opts(), &[needle]);
    }
}

#[test]
fn gzip_checksums_and_trailer_are_verified_nrrd() {
    let dir = tmp();
    let header = b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 3 2\nencoding: gzip\n\n";
    let voxels: Vec<u8> = (0..24).map(|i| (i % 3) as u8).collect();
    let ok = write(
        dir.path(),
        "ok.nrrd",
        &[&header[..], &gzip_stored(&voxels)].concat(),
    );
    assert!(read_label_volume(&ok, &no_opts()).is_ok());
    for (name, bytes, needle) in damaged_gzips(&voxels) {
        let path = write(
            dir.path(),
            &format!("{name}.nrrd"),
            &[&header[..], &bytes].concat(),
        );
        expect_error(&path, &no_opts(), &[needle]);
    }
    // more voxel data than the sizes say: sizes 2 3 2 on 24 bytes
    let small = b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 3 2\nencoding: gzip\n\n";
    let path = write(
        dir.path(),
        "sizes.nrrd",
        &[&small[..], &gzip_stored(&voxels)].concat(),
    );
    expect_error(&path, &no_opts(), &["more than the 12 bytes expected"]);
}
