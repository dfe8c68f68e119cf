//! NIfTI-1 and NIfTI-2: the reader (single `.nii`/`.nii.gz` files and
//! `.hdr`/`.img` pairs, either byte order, gzip recognised by magic) and the
//! label-volume writer (NIfTI-1 `.nii`/`.nii.gz`).
//!
//! The header is parsed here, field by field at the offsets of the standard
//! (`nifti1.h`, `nifti2.h`). Geometry follows the standard's three methods: the
//! sform when `sform_code > 0`, else the qform (quaternion, `qfac = pixdim[0]`,
//! spacings `|pixdim[1..3]|`) when `qform_code > 0`, else the plain
//! `diag(pixdim[1..3])` of "method 1". NIfTI affines map to RAS; septa's
//! [`Geometry`] is LPS, converted by [`Geometry::from_ras_affine`]. Affines in
//! metres or microns (`xyzt_units`) are scaled to millimetres.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::raw::{byte_count, decode_owned, image_shape, voxel_count};
use crate::io::{DataType, Image, Samples, atomic_write, gz, read_file};
use crate::volume::{Geometry, LabelVolume};

const NIFTI1_HEADER: usize = 348;
const NIFTI2_HEADER: usize = 540;
/// Header plus the 4-byte extension flag: where a written `.nii`'s voxels start.
const NIFTI1_DATA_OFFSET: usize = 352;

/// Everything the reader uses from a NIfTI-1 or NIfTI-2 header, widened to the
/// NIfTI-2 types.
#[derive(Clone, Debug)]
struct Header {
    little_endian: bool,
    /// `sizeof_hdr`: 348 or 540.
    size: usize,
    /// True for `n+1`/`n+2` (voxels in the same file), false for `ni1`/`ni2`.
    single_file: bool,
    dim: [i64; 8],
    datatype: i16,
    pixdim: [f64; 8],
    vox_offset: f64,
    scl_slope: f64,
    scl_inter: f64,
    qform_code: i32,
    sform_code: i32,
    quatern: [f64; 3],
    qoffset: [f64; 3],
    srow: [[f64; 4]; 3],
    /// `xyzt_units`: bits 0-2 give the spatial unit.
    xyzt_units: i32,
}

/// Reads a NIfTI-1/2 file: `.nii`, `.nii.gz`, or either half of a `.hdr`/`.img`
/// pair (also gzipped).
pub fn read(path: &Path) -> Result<Image> {
    let header_path = header_path_of(path)?;
    let file = read_file(&header_path)?;
    let prefix = if gz::is_gzip(&file) {
        gz::gunzip_prefix(&header_path, &file, NIFTI2_HEADER)?
    } else {
        file[..file.len().min(NIFTI2_HEADER)].to_vec()
    };
    let h = parse_header(&header_path, &prefix)?;
    let dtype = data_type(&header_path, h.datatype)?;
    let dims = extents(&header_path, &h)?;
    let geometry = geometry(&header_path, &h)?;
    let mut sources = vec![header_path.clone()];
    let samples = if h.single_file {
        read_voxels(
            &header_path,
            file,
            h.data_offset_single(&header_path)?,
            &dims,
            dtype,
            h.little_endian,
        )?
    } else {
        if gz::is_gzip(&file) {
            // a gzipped .hdr is read only up to its header: verify the rest too
            gz::gunzip(&header_path, &file, gz::max_inflated_len(file.len()))?;
        }
        let data_path = data_path_of(&header_path)?;
        sources.push(data_path.clone());
        let offset = h.data_offset_pair(&header_path)?;
        read_voxels(
            &data_path,
            read_file(&data_path)?,
            offset,
            &dims,
            dtype,
            h.little_endian,
        )?
    };
    let dims = image_shape(dims);
    let time_step =
        (dims.len() > 3 && h.pixdim[4].is_finite() && h.pixdim[4] != 0.0).then_some(h.pixdim[4]);
    Ok(Image {
        dims,
        samples: apply_scaling(samples, h.scl_slope, h.scl_inter),
        geometry,
        time_step,
        path: path.to_path_buf(),
        sources,
    })
}

/// Decodes the voxels at `offset` of `file` (gunzipped and verified when it is gzip).
fn read_voxels(
    path: &Path,
    file: Vec<u8>,
    offset: usize,
    dims: &[usize],
    dtype: DataType,
    little_endian: bool,
) -> Result<Samples> {
    let needed = byte_count(path, dims, dtype)?;
    let total = offset
        .checked_add(needed)
        .ok_or_else(|| Error::input(path, "vox_offset plus the data size overflows"))?;
    let data = if gz::is_gzip(&file) {
        if total as u64 > gz::max_inflated_len(file.len()) {
            return Err(Error::input(
                path,
                format!(
                    "truncated: expected {needed} bytes of voxel data after offset {offset}, more than {} bytes of gzip data can hold",
                    file.len()
                ),
            ));
        }
        gz::gunzip(path, &file, total as u64)?
    } else {
        file
    };
    decode_owned(
        path,
        data,
        offset,
        voxel_count(path, dims)?,
        dtype,
        little_endian,
    )
}

/// Applies `scl_slope`/`scl_inter` (as f64) unless they are the identity or unset
/// (slope 0 or not finite).
fn apply_scaling(samples: Samples, slope: f64, inter: f64) -> Samples {
    let inter = if inter.is_finite() { inter } else { 0.0 };
    if !slope.is_finite() || slope == 0.0 || (slope == 1.0 && inter == 0.0) {
        return samples;
    }
    Samples::F64(
        samples
            .to_f64()
            .into_iter()
            .map(|x| x * slope + inter)
            .collect(),
    )
}

// ---------------------------------------------------------------- file names

/// Lower-cased file name split into stem and NIfTI extension (`nii`, `hdr`, `img`)
/// with whether a `.gz` follows.
fn split_name(path: &Path) -> Option<(String, String, bool)> {
    let name = path.file_name()?.to_string_lossy().into_owned();
    let lower = name.to_ascii_lowercase();
    let gz = lower.ends_with(".gz");
    let base = if gz {
        &name[..name.len() - 3]
    } else {
        &name[..]
    };
    let dot = base.rfind('.')?;
    Some((
        base[..dot].to_string(),
        base[dot + 1..].to_ascii_lowercase(),
        gz,
    ))
}

/// The file holding the header: the `.hdr` beside an `.img`, else `path` itself.
fn header_path_of(path: &Path) -> Result<PathBuf> {
    match split_name(path) {
        Some((stem, ext, _)) if ext == "img" => companion(path, &stem, "hdr"),
        _ => Ok(path.to_path_buf()),
    }
}

/// The `.img` (or `.img.gz`) beside a `ni1`/`ni2` header.
fn data_path_of(header_path: &Path) -> Result<PathBuf> {
    let stem = split_name(header_path)
        .map(|(s, _, _)| s)
        .unwrap_or_default();
    companion(header_path, &stem, "img")
}

/// The first existing sibling `stem.ext`, `stem.ext.gz`, `stem.EXT`, `stem.EXT.gz`
/// (`ext` is `hdr` or `img`).
fn companion(path: &Path, stem: &str, ext: &str) -> Result<PathBuf> {
    let upper = ext.to_ascii_uppercase();
    let candidates = [
        format!("{stem}.{ext}"),
        format!("{stem}.{ext}.gz"),
        format!("{stem}.{upper}"),
        format!("{stem}.{upper}.gz"),
    ];
    candidates
        .iter()
        .map(|name| path.with_file_name(name))
        .find(|p| p.is_file())
        .ok_or_else(|| {
            Error::input(
                path,
                format!(
                    "missing {} file: the .{ext} file of this .hdr/.img pair ({}) does not exist",
                    if ext == "hdr" { "header" } else { "data" },
                    candidates[0]
                ),
            )
        })
}

// ------------------------------------------------------------------- header

/// Reads fixed-offset fields of a header in its byte order. Out-of-range reads
/// give 0; callers check the header length first.
struct Fields<'a> {
    bytes: &'a [u8],
    little_endian: bool,
}

impl Fields<'_> {
    fn array<const N: usize>(&self, at: usize) -> [u8; N] {
        let mut a = [0u8; N];
        if let Some(s) = self.bytes.get(at..at + N) {
            a.copy_from_slice(s);
        }
        if self.little_endian == cfg!(target_endian = "big") {
            a.reverse();
        }
        a
    }
    fn i16(&self, at: usize) -> i16 {
        i16::from_ne_bytes(self.array(at))
    }
    fn i32(&self, at: usize) -> i32 {
        i32::from_ne_bytes(self.array(at))
    }
    fn i64(&self, at: usize) -> i64 {
        i64::from_ne_bytes(self.array(at))
    }
    fn f32(&self, at: usize) -> f64 {
        f64::from(f32::from_ne_bytes(self.array(at)))
    }
    fn f64(&self, at: usize) -> f64 {
        f64::from_ne_bytes(self.array(at))
    }
}

/// Version and byte order from `sizeof_hdr`, then the fields of that version.
fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    if bytes.len() < NIFTI1_HEADER {
        return Err(short_header(path, bytes.len(), NIFTI1_HEADER));
    }
    let first: [u8; 4] = [bytes[0], bytes[1], bytes[2], bytes[3]];
    let (le, be) = (i32::from_le_bytes(first), i32::from_be_bytes(first));
    let (size, little_endian) = match (le, be) {
        (348, _) => (NIFTI1_HEADER, true),
        (_, 348) => (NIFTI1_HEADER, false),
        (540, _) => (NIFTI2_HEADER, true),
        (_, 540) => (NIFTI2_HEADER, false),
        _ => {
            return Err(Error::input(
                path,
                format!(
                    "not a NIfTI file: sizeof_hdr is {le} (expected 348 for NIfTI-1 or 540 for NIfTI-2)"
                ),
            ));
        }
    };
    if bytes.len() < size {
        return Err(short_header(path, bytes.len(), size));
    }
    let f = Fields {
        bytes,
        little_endian,
    };
    if size == NIFTI1_HEADER {
        parse_nifti1(path, &f)
    } else {
        parse_nifti2(path, &f)
    }
}

fn short_header(path: &Path, found: usize, size: usize) -> Error {
    Error::input(
        path,
        format!("truncated: the file holds {found} bytes, less than the {size}-byte NIfTI header"),
    )
}

/// True for the single-file magic, false for the pair magic, else a "wrong magic" error.
fn check_magic(path: &Path, magic: &[u8], version: char) -> Result<bool> {
    let single = [b'n', b'+', version as u8, 0];
    let pair = [b'n', b'i', version as u8, 0];
    if magic == single {
        Ok(true)
    } else if magic == pair {
        Ok(false)
    } else {
        Err(Error::input(
            path,
            format!(
                "wrong magic {:?} for NIfTI-{version} (expected \"n+{version}\" or \"ni{version}\"; ANALYZE 7.5 files are not supported)",
                String::from_utf8_lossy(magic).trim_end_matches('\0')
            ),
        ))
    }
}

fn parse_nifti1(path: &Path, f: &Fields) -> Result<Header> {
    let single_file = check_magic(path, f.bytes.get(344..348).unwrap_or_default(), '1')?;
    Ok(Header {
        little_endian: f.little_endian,
        size: NIFTI1_HEADER,
        single_file,
        dim: std::array::from_fn(|i| i64::from(f.i16(40 + 2 * i))),
        datatype: f.i16(70),
        pixdim: std::array::from_fn(|i| f.f32(76 + 4 * i)),
        vox_offset: f.f32(108),
        scl_slope: f.f32(112),
        scl_inter: f.f32(116),
        qform_code: i32::from(f.i16(252)),
        sform_code: i32::from(f.i16(254)),
        quatern: std::array::from_fn(|i| f.f32(256 + 4 * i)),
        qoffset: std::array::from_fn(|i| f.f32(268 + 4 * i)),
        srow: std::array::from_fn(|r| std::array::from_fn(|c| f.f32(280 + 16 * r + 4 * c))),
        xyzt_units: i32::from(f.bytes.get(123).copied().unwrap_or(0)),
    })
}

fn parse_nifti2(path: &Path, f: &Fields) -> Result<Header> {
    let single_file = check_magic(path, f.bytes.get(4..8).unwrap_or_default(), '2')?;
    Ok(Header {
        little_endian: f.little_endian,
        size: NIFTI2_HEADER,
        single_file,
        dim: std::array::from_fn(|i| f.i64(16 + 8 * i)),
        datatype: f.i16(12),
        pixdim: std::array::from_fn(|i| f.f64(104 + 8 * i)),
        vox_offset: f.i64(168) as f64,
        scl_slope: f.f64(176),
        scl_inter: f.f64(184),
        qform_code: f.i32(344),
        sform_code: f.i32(348),
        quatern: std::array::from_fn(|i| f.f64(352 + 8 * i)),
        qoffset: std::array::from_fn(|i| f.f64(376 + 8 * i)),
        srow: std::array::from_fn(|r| std::array::from_fn(|c| f.f64(400 + 32 * r + 8 * c))),
        xyzt_units: f.i32(500),
    })
}

impl Header {
    /// Number of axes, `dim[0]`, checked to be 1..=7.
    fn axes(&self, path: &Path) -> Result<usize> {
        match self.dim[0] {
            n @ 1..=7 => Ok(n as usize),
            n => Err(Error::input(
                path,
                format!("dim[0] is {n}: the number of axes must be 1 to 7"),
            )),
        }
    }

    /// `vox_offset` as a byte offset, if it is a finite non-negative number.
    fn vox_offset(&self, path: &Path) -> Result<usize> {
        let v = self.vox_offset;
        if !(0.0..9.0e15).contains(&v) {
            return Err(Error::input(
                path,
                format!("vox_offset {v} is not a valid byte offset"),
            ));
        }
        Ok(v as usize)
    }

    /// Offset of the voxels in a single `.nii`: `vox_offset`, or just after the
    /// header and extension flag when `vox_offset` points into the header.
    fn data_offset_single(&self, path: &Path) -> Result<usize> {
        let v = self.vox_offset(path)?;
        Ok(if v < self.size { self.size + 4 } else { v })
    }

    /// Offset of the voxels in the `.img` of a pair.
    fn data_offset_pair(&self, path: &Path) -> Result<usize> {
        self.vox_offset(path)
    }
}

/// Extents `dim[1..=dim[0]]`, each at least 1.
fn extents(path: &Path, h: &Header) -> Result<Vec<usize>> {
    let axes = h.axes(path)?;
    (1..=axes)
        .map(|i| match usize::try_from(h.dim[i]) {
            Ok(n) if n >= 1 => Ok(n),
            _ => Err(Error::input(
                path,
                format!("dim[{i}] is {}: every extent must be at least 1", h.dim[i]),
            )),
        })
        .collect()
}

/// The sample type of a NIfTI `datatype` code.
fn data_type(path: &Path, code: i16) -> Result<DataType> {
    Ok(match code {
        2 => DataType::U8,
        256 => DataType::I8,
        512 => DataType::U16,
        4 => DataType::I16,
        768 => DataType::U32,
        8 => DataType::I32,
        1280 => DataType::U64,
        1024 => DataType::I64,
        16 => DataType::F32,
        64 => DataType::F64,
        other => {
            let name = match other {
                0 => "unknown",
                1 => "binary",
                32 => "complex64",
                128 => "rgb24",
                1536 => "float128",
                1792 => "complex128",
                2048 => "complex256",
                2304 => "rgba32",
                _ => "not a NIfTI datatype code",
            };
            return Err(Error::input(
                path,
                format!(
                    "unsupported datatype {other} ({name}): septa reads (u)int8/16/32/64, float32 and float64 NIfTI files"
                ),
            ));
        }
    })
}

// ----------------------------------------------------------------- geometry

/// The index → LPS map: sform, else qform, else `diag(pixdim)`, in mm.
fn geometry(path: &Path, h: &Header) -> Result<Geometry> {
    let axes = h.axes(path)?;
    let mut ras = if h.sform_code > 0 {
        h.srow
    } else if h.qform_code > 0 {
        qform_affine(path, h, axes)?
    } else {
        pixdim_affine(path, h, axes)?
    };
    let which = if h.sform_code > 0 {
        "sform"
    } else if h.qform_code > 0 {
        "qform"
    } else {
        "pixdim"
    };
    let to_mm = mm_per_unit(h.xyzt_units);
    ras.iter_mut().flatten().for_each(|v| *v *= to_mm);
    Geometry::from_ras_affine(ras)
        .map_err(|e| Error::input(path, format!("invalid {which} geometry: {e}")))
}

/// Millimetres per spatial unit of `xyzt_units` (metre 1000, micron 0.001;
/// mm and "unknown" 1), scaling the whole affine as ITK's NIfTI reader does.
fn mm_per_unit(xyzt_units: i32) -> f64 {
    match xyzt_units & 0x07 {
        1 => 1000.0,
        3 => 0.001,
        _ => 1.0,
    }
}

/// Spacing of spatial axis `i` (1-based) for the qform: `|pixdim[i]|`, 1 for
/// axes the image does not have; zero is an error.
fn qform_spacing(path: &Path, h: &Header, axes: usize, i: usize) -> Result<f64> {
    if i > axes {
        return Ok(1.0);
    }
    let s = h.pixdim[i].abs();
    if s > 0.0 && s.is_finite() {
        Ok(s)
    } else {
        Err(Error::input(
            path,
            format!(
                "pixdim[{i}] is {}: voxel spacing must be a positive number of mm",
                h.pixdim[i]
            ),
        ))
    }
}

/// "Method 2": rotation from the quaternion (b, c, d), spacings `|pixdim|`,
/// `qfac = pixdim[0]` (−1 flips the third axis), offset `qoffset`.
fn qform_affine(path: &Path, h: &Header, axes: usize) -> Result<[[f64; 4]; 3]> {
    let r = quaternion_to_rotation(h.quatern);
    let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
    let s = [
        qform_spacing(path, h, axes, 1)?,
        qform_spacing(path, h, axes, 2)?,
        qform_spacing(path, h, axes, 3)? * qfac,
    ];
    Ok(std::array::from_fn(|row| {
        [
            r[row][0] * s[0],
            r[row][1] * s[1],
            r[row][2] * s[2],
            h.qoffset[row],
        ]
    }))
}

/// Rotation matrix (rows) of the unit quaternion (a, b, c, d) with
/// `a = sqrt(1 − b² − c² − d²)`, as in `nifti_quatern_to_mat44`.
pub(crate) fn quaternion_to_rotation([b, c, d]: [f64; 3]) -> [[f64; 3]; 3] {
    let mut a = 1.0 - (b * b + c * c + d * d);
    let (b, c, d) = if a < 1.0e-7 {
        // Not a unit quaternion: normalise (b, c, d) and take a 180° rotation.
        let n = (b * b + c * c + d * d).sqrt();
        a = 0.0;
        if n > 0.0 {
            (b / n, c / n, d / n)
        } else {
            (0.0, 0.0, 0.0)
        }
    } else {
        a = a.sqrt();
        (b, c, d)
    };
    [
        [
            a * a + b * b - c * c - d * d,
            2.0 * (b * c - a * d),
            2.0 * (b * d + a * c),
        ],
        [
            2.0 * (b * c + a * d),
            a * a + c * c - b * b - d * d,
            2.0 * (c * d - a * b),
        ],
        [
            2.0 * (b * d - a * c),
            2.0 * (c * d + a * b),
            a * a + d * d - c * c - b * b,
        ],
    ]
}

/// "Method 1": `diag(pixdim[1..3])`, no rotation, zero offset. Spacings of the
/// image's axes must be positive.
fn pixdim_affine(path: &Path, h: &Header, axes: usize) -> Result<[[f64; 4]; 3]> {
    let mut ras = [[0.0; 4]; 3];
    for i in 1..=3 {
        let s = if i > axes { 1.0 } else { h.pixdim[i] };
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::input(
                path,
                format!(
                    "pixdim[{i}] is {s}: voxel spacing must be a positive number of mm (no sform or qform gives another)"
                ),
            ));
        }
        ras[i - 1][i - 1] = s;
    }
    Ok(ras)
}

// ------------------------------------------------------------------- writer

/// Writes a label volume as NIfTI-1 (`.nii`, or `.nii.gz` when the name ends in
/// `.gz`) with the smallest integer datatype that holds its label values, sform
/// and (when the direction is a rotation) qform set to the geometry, units mm.
pub fn write_labels(path: &Path, volume: &LabelVolume) -> Result<()> {
    match split_name(path) {
        Some((_, ext, _)) if ext == "nii" => {}
        _ => {
            return Err(Error::input(
                path,
                "label volumes are written as .nii or .nii.gz",
            ));
        }
    }
    if let Some(n) = volume
        .dims()
        .to_array()
        .into_iter()
        .find(|&n| n > i16::MAX as usize)
    {
        return Err(Error::input(
            path,
            format!(
                "an extent of {n} voxels does not fit a NIfTI-1 header (at most 32767): write .nrrd instead"
            ),
        ));
    }
    let dtype = smallest_label_type(volume.values());
    let mut bytes = nifti1_header(volume, dtype);
    bytes.extend_from_slice(&encode_labels(volume, dtype));
    if split_name(path).is_some_and(|(_, _, gz)| gz) {
        bytes = gzip(&bytes).map_err(|e| Error::io(path, e))?;
    }
    atomic_write(path, &bytes)
}

/// Writes any [`Image`] of 1 to 4 axes (e.g. a 4-D time series) as NIfTI-1
/// (`.nii`, or `.nii.gz` when the name ends in `.gz`): its own sample type,
/// sform (and qform when the direction is a rotation) from its geometry, and
/// `pixdim[4]` = its time step (units mm and s). The reader gives the image
/// back unchanged.
pub fn write_image(path: &Path, image: &Image) -> Result<()> {
    match split_name(path) {
        Some((_, ext, _)) if ext == "nii" => {}
        _ => return Err(Error::input(path, "images are written as .nii or .nii.gz")),
    }
    let dims = &image.dims;
    if dims.is_empty() || dims.len() > 4 {
        return Err(Error::input(
            path,
            format!("{} axes: septa writes images of 1 to 4 axes", dims.len()),
        ));
    }
    if let Some(&n) = dims.iter().find(|&&n| n == 0 || n > i16::MAX as usize) {
        return Err(Error::input(
            path,
            format!("an extent of {n} does not fit a NIfTI-1 header (1 to 32767)"),
        ));
    }
    let count: usize = dims.iter().product();
    if count != image.samples.len() {
        return Err(Error::input(
            path,
            format!("{} samples for the extents {dims:?}", image.samples.len()),
        ));
    }
    if let Some(dt) = image.time_step {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::input(
                path,
                format!("time step {dt} is not positive"),
            ));
        }
    }
    let dtype = image.samples.dtype();
    let g = &image.geometry;
    let spacing = g.spacing();
    let ras = g.to_ras();
    let qform = rotation_quaternion(&ras, spacing);
    let mut p = Put(vec![0u8; NIFTI1_DATA_OFFSET]);
    p.bytes(0, &348i32.to_le_bytes());
    p.bytes(38, b"r");
    let mut dim = [dims.len().max(3) as i16, 1, 1, 1, 1, 1, 1, 1];
    for (i, &n) in dims.iter().enumerate() {
        dim[i + 1] = n as i16;
    }
    for (i, &n) in dim.iter().enumerate() {
        p.i16(40 + 2 * i, n);
    }
    p.i16(70, nifti_code(dtype));
    p.i16(72, (dtype.size() * 8) as i16);
    let qfac = qform.map_or(1.0, |q| q.qfac);
    let dt = image.time_step.unwrap_or(1.0);
    let pixdim = [qfac, spacing[0], spacing[1], spacing[2], dt, 1.0, 1.0, 1.0];
    for (i, &v) in pixdim.iter().enumerate() {
        p.f32(76 + 4 * i, v);
    }
    p.f32(108, NIFTI1_DATA_OFFSET as f64);
    p.f32(112, 1.0);
    // xyzt_units: mm, plus seconds when there is a time step
    p.bytes(123, &[if image.time_step.is_some() { 2 | 8 } else { 2 }]);
    p.bytes(148, b"septa image");
    p.i16(252, if qform.is_some() { 1 } else { 0 });
    p.i16(254, 1);
    if let Some(q) = qform {
        for (i, &v) in q.bcd.iter().enumerate() {
            p.f32(256 + 4 * i, v);
        }
    }
    for (r, row) in ras.iter().enumerate() {
        p.f32(268 + 4 * r, row[3]);
        for (c, &v) in row.iter().enumerate() {
            p.f32(280 + 16 * r + 4 * c, v);
        }
    }
    p.bytes(344, b"n+1\0");
    let mut bytes = p.0;
    bytes.extend_from_slice(&image.samples.to_le_bytes());
    if split_name(path).is_some_and(|(_, _, gz)| gz) {
        bytes = gzip(&bytes).map_err(|e| Error::io(path, e))?;
    }
    atomic_write(path, &bytes)
}

/// gzip-compresses `bytes` (level 6).
pub(crate) fn gzip(bytes: &[u8]) -> std::io::Result<Vec<u8>> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(
        Vec::with_capacity(bytes.len() / 8),
        flate2::Compression::new(6),
    );
    e.write_all(bytes)?;
    e.finish()
}

/// The smallest integer type holding every value (unsigned preferred).
pub(crate) fn smallest_label_type(values: &[i64]) -> DataType {
    let lo = values.first().copied().unwrap_or(0);
    let hi = values.last().copied().unwrap_or(0);
    let fits = |min: i64, max: i64| lo >= min && hi <= max;
    if fits(0, u8::MAX.into()) {
        DataType::U8
    } else if fits(i8::MIN.into(), i8::MAX.into()) {
        DataType::I8
    } else if fits(0, u16::MAX.into()) {
        DataType::U16
    } else if fits(i16::MIN.into(), i16::MAX.into()) {
        DataType::I16
    } else if fits(0, u32::MAX.into()) {
        DataType::U32
    } else if fits(i32::MIN.into(), i32::MAX.into()) {
        DataType::I32
    } else {
        DataType::I64
    }
}

/// Original label values as little-endian samples of `dtype` (an integer type
/// from [`smallest_label_type`]), through a per-label byte table.
pub(crate) fn encode_labels(volume: &LabelVolume, dtype: DataType) -> Vec<u8> {
    use rayon::prelude::*;
    let size = dtype.size();
    let table: Vec<[u8; 8]> = volume.values().iter().map(|&v| v.to_le_bytes()).collect();
    let ids = volume.ids();
    let mut out = vec![0u8; ids.len() * size];
    if size == 1 {
        out.par_iter_mut()
            .zip(ids.par_iter())
            .for_each(|(o, &id)| *o = table[id as usize][0]);
    } else {
        out.par_chunks_exact_mut(size)
            .zip(ids.par_iter())
            .for_each(|(o, &id)| o.copy_from_slice(&table[id as usize][..size]));
    }
    out
}

fn nifti_code(dtype: DataType) -> i16 {
    match dtype {
        DataType::U8 => 2,
        DataType::I8 => 256,
        DataType::U16 => 512,
        DataType::I16 => 4,
        DataType::U32 => 768,
        DataType::I32 => 8,
        DataType::U64 => 1280,
        DataType::I64 => 1024,
        DataType::F32 => 16,
        DataType::F64 => 64,
    }
}

/// Little-endian header writer over a zeroed buffer.
struct Put(Vec<u8>);

impl Put {
    fn bytes(&mut self, at: usize, b: &[u8]) {
        self.0[at..at + b.len()].copy_from_slice(b);
    }
    fn i16(&mut self, at: usize, v: i16) {
        self.bytes(at, &v.to_le_bytes());
    }
    fn f32(&mut self, at: usize, v: f64) {
        self.bytes(at, &(v as f32).to_le_bytes());
    }
}

/// The 348-byte NIfTI-1 header plus the 4-byte (empty) extension flag.
fn nifti1_header(volume: &LabelVolume, dtype: DataType) -> Vec<u8> {
    let g = volume.geometry();
    let d = volume.dims();
    let spacing = g.spacing();
    let ras = g.to_ras();
    let qform = rotation_quaternion(&ras, spacing);
    let mut p = Put(vec![0u8; NIFTI1_DATA_OFFSET]);
    p.bytes(0, &348i32.to_le_bytes());
    p.bytes(38, b"r");
    let dims = [3, d.nx, d.ny, d.nz, 1, 1, 1, 1];
    for (i, &n) in dims.iter().enumerate() {
        p.i16(40 + 2 * i, n as i16);
    }
    p.i16(70, nifti_code(dtype));
    p.i16(72, (dtype.size() * 8) as i16);
    let qfac = qform.map_or(1.0, |q| q.qfac);
    let pixdim = [qfac, spacing[0], spacing[1], spacing[2], 1.0, 1.0, 1.0, 1.0];
    for (i, &v) in pixdim.iter().enumerate() {
        p.f32(76 + 4 * i, v);
    }
    p.f32(108, NIFTI1_DATA_OFFSET as f64);
    p.f32(112, 1.0);
    p.bytes(123, &[2]); // xyzt_units: NIFTI_UNITS_MM
    p.bytes(148, b"septa label volume");
    p.i16(252, if qform.is_some() { 1 } else { 0 });
    p.i16(254, 1);
    if let Some(q) = qform {
        for (i, &v) in q.bcd.iter().enumerate() {
            p.f32(256 + 4 * i, v);
        }
    }
    for (r, row) in ras.iter().enumerate() {
        p.f32(268 + 4 * r, row[3]);
        for (c, &v) in row.iter().enumerate() {
            p.f32(280 + 16 * r + 4 * c, v);
        }
    }
    p.bytes(344, b"n+1\0");
    p.0
}

/// A qform: quaternion (b, c, d) and `qfac`.
#[derive(Clone, Copy, Debug)]
struct Qform {
    bcd: [f64; 3],
    qfac: f64,
}

/// The qform of a RAS affine whose direction (columns / spacing) is a rotation,
/// possibly with a flipped third axis (`qfac = −1`); `None` for a sheared
/// direction, which a qform cannot express.
fn rotation_quaternion(ras: &[[f64; 4]; 3], spacing: [f64; 3]) -> Option<Qform> {
    let mut r: [[f64; 3]; 3] =
        std::array::from_fn(|row| std::array::from_fn(|c| ras[row][c] / spacing[c]));
    let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
        - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
        + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
    let qfac = if det < 0.0 { -1.0 } else { 1.0 };
    for row in &mut r {
        row[2] *= qfac;
    }
    let orthogonal = (0..3).all(|i| {
        (0..3).all(|j| {
            let dot: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
            (dot - if i == j { 1.0 } else { 0.0 }).abs() < 1e-4
        })
    });
    orthogonal.then(|| Qform {
        bcd: rotation_to_quaternion(&r),
        qfac,
    })
}

/// Quaternion (b, c, d) with a ≥ 0 of a proper rotation (rows), as in
/// `nifti_mat44_to_quatern`.
fn rotation_to_quaternion(r: &[[f64; 3]; 3]) -> [f64; 3] {
    let trace = r[0][0] + r[1][1] + r[2][2] + 1.0;
    let (a, b, c, d);
    if trace > 0.5 {
        a = 0.5 * trace.sqrt();
        b = 0.25 * (r[2][1] - r[1][2]) / a;
        c = 0.25 * (r[0][2] - r[2][0]) / a;
        d = 0.25 * (r[1][0] - r[0][1]) / a;
    } else {
        let xd = 1.0 + r[0][0] - (r[1][1] + r[2][2]);
        let yd = 1.0 + r[1][1] - (r[0][0] + r[2][2]);
        let zd = 1.0 + r[2][2] - (r[0][0] + r[1][1]);
        if xd > 1.0 {
            b = 0.5 * xd.sqrt();
            c = 0.25 * (r[0][1] + r[1][0]) / b;
            d = 0.25 * (r[0][2] + r[2][0]) / b;
            a = 0.25 * (r[2][1] - r[1][2]) / b;
        } else if yd > 1.0 {
            c = 0.5 * yd.sqrt();
            b = 0.25 * (r[0][1] + r[1][0]) / c;
            d = 0.25 * (r[1][2] + r[2][1]) / c;
            a = 0.25 * (r[0][2] - r[2][0]) / c;
        } else {
            d = 0.5 * zd.sqrt();
            b = 0.25 * (r[0][2] + r[2][0]) / d;
            c = 0.25 * (r[1][2] + r[2][1]) / d;
            a = 0.25 * (r[1][0] - r[0][1]) / d;
        }
    }
    if a < 0.0 { [-b, -c, -d] } else { [b, c, d] }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternion_round_trip() {
        // 120° about (1,1,1)/√3 permutes the axes; plus a generic rotation.
        let perm = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let q = rotation_to_quaternion(&perm);
        let back = quaternion_to_rotation(q);
        for r in 0..3 {
            for c in 0..3 {
                assert!((back[r][c] - perm[r][c]).abs() < 1e-12);
            }
        }
        let flip = [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]];
        let back = quaternion_to_rotation(rotation_to_quaternion(&flip));
        assert!((back[0][0] + 1.0).abs() < 1e-12 && (back[2][2] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn label_types() {
        assert_eq!(smallest_label_type(&[0, 255]), DataType::U8);
        assert_eq!(smallest_label_type(&[-1, 5]), DataType::I8);
        assert_eq!(smallest_label_type(&[0, 256]), DataType::U16);
        assert_eq!(smallest_label_type(&[-129, 0]), DataType::I16);
        assert_eq!(smallest_label_type(&[0, 70_000]), DataType::U32);
        assert_eq!(smallest_label_type(&[-40_000, 0]), DataType::I32);
        assert_eq!(smallest_label_type(&[0, 1 << 40]), DataType::I64);
    }
}
