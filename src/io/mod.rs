//! Reading and writing files: volumes (NIfTI-1/2, NRRD, MetaImage, raw) and,
//! in submodules, meshes ([`mesh_ply`], [`mesh_formats`]), 2-D images
//! ([`image2d`]: PGM and PNG), the manifest ([`manifest`]) and the output
//! directory of `septa extract` ([`output`]).
//!
//! Every reader turns a file into an [`Image`]: its shape (up to 4-D), typed
//! samples in native byte order, and its [`Geometry`] in LPS millimetres. Label
//! commands then call [`Image::into_label_volume`], grayscale commands
//! [`Image::to_f64`]. Readers never panic on bad bytes: every problem becomes an
//! [`Error`] naming the file and what is wrong with it.
//!
//! Writers are atomic: they write a temporary file beside the target and rename
//! it into place ([`atomic_write`]), so an interrupted run never leaves half a
//! file; the temporary file is removed when the process is stopped by a signal
//! ([`temp`]).

pub mod gz;
pub mod image2d;
pub mod label_files;
pub mod manifest;
pub mod mesh_formats;
pub mod mesh_ply;
pub mod metaimage;
pub mod nifti;
pub mod nrrd;
pub mod output;
pub mod raw;
pub mod temp;

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::volume::{Dims, Geometry, LabelId, LabelVolume, MAX_LABELS};

/// The patient coordinate system mesh files are written in, in mm. septa
/// works in LPS (DICOM, ITK, 3D Slicer); RAS (NIfTI, nibabel, FreeSurfer)
/// is LPS with x and y negated, a rotation: triangles keep their orientation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Space {
    /// x toward patient left, y posterior, z superior.
    #[default]
    Lps,
    /// x toward patient right, y anterior, z superior.
    Ras,
}

impl Space {
    /// `LPS` or `RAS` (also 3D Slicer's `SPACE=` token).
    pub fn name(self) -> &'static str {
        match self {
            Space::Lps => "LPS",
            Space::Ras => "RAS",
        }
    }

    /// What the header comment of a mesh file says: `LPS mm SPACE=LPS`.
    pub fn comment(self) -> String {
        format!("{} mm SPACE={}", self.name(), self.name())
    }

    /// A position given in LPS, in this space.
    pub fn from_lps(self, p: glam::DVec3) -> glam::DVec3 {
        match self {
            Space::Lps => p,
            Space::Ras => glam::DVec3::new(-p.x, -p.y, p.z),
        }
    }

    /// `mesh` with its positions in this space (from LPS).
    pub fn mesh_from_lps(self, mesh: &crate::mesh::InterfaceMesh) -> crate::mesh::InterfaceMesh {
        let mut out = mesh.clone();
        if self != Space::Lps {
            out.positions
                .iter_mut()
                .for_each(|p| *p = self.from_lps(*p));
        }
        out
    }
}

/// Sample type of a voxel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DataType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
}

impl DataType {
    /// Bytes per sample.
    pub fn size(self) -> usize {
        match self {
            DataType::U8 | DataType::I8 => 1,
            DataType::U16 | DataType::I16 => 2,
            DataType::U32 | DataType::I32 | DataType::F32 => 4,
            DataType::U64 | DataType::I64 | DataType::F64 => 8,
        }
    }

    /// Lower-case name as accepted by `--dtype` (`uint8`, `int16`, `float32`, …).
    pub fn name(self) -> &'static str {
        match self {
            DataType::U8 => "uint8",
            DataType::I8 => "int8",
            DataType::U16 => "uint16",
            DataType::I16 => "int16",
            DataType::U32 => "uint32",
            DataType::I32 => "int32",
            DataType::U64 => "uint64",
            DataType::I64 => "int64",
            DataType::F32 => "float32",
            DataType::F64 => "float64",
        }
    }

    /// Parses the names of [`DataType::name`] and common aliases (`u8`, `uchar`,
    /// `short`, `float`, `double`, …).
    pub fn parse(s: &str) -> Option<Self> {
        Some(match s.trim().to_ascii_lowercase().as_str() {
            "uint8" | "u8" | "uchar" | "unsigned char" => DataType::U8,
            "int8" | "i8" | "char" | "signed char" => DataType::I8,
            "uint16" | "u16" | "ushort" | "unsigned short" => DataType::U16,
            "int16" | "i16" | "short" => DataType::I16,
            "uint32" | "u32" | "uint" | "unsigned int" => DataType::U32,
            "int32" | "i32" | "int" => DataType::I32,
            "uint64" | "u64" => DataType::U64,
            "int64" | "i64" => DataType::I64,
            "float32" | "f32" | "float" => DataType::F32,
            "float64" | "f64" | "double" => DataType::F64,
            _ => return None,
        })
    }
}

/// Typed voxel samples, x fastest, in native byte order.
#[derive(Clone, Debug, PartialEq)]
pub enum Samples {
    U8(Vec<u8>),
    I8(Vec<i8>),
    U16(Vec<u16>),
    I16(Vec<i16>),
    U32(Vec<u32>),
    I32(Vec<i32>),
    U64(Vec<u64>),
    I64(Vec<i64>),
    F32(Vec<f32>),
    F64(Vec<f64>),
}

macro_rules! for_each_samples {
    ($s:expr, $v:ident => $body:expr) => {
        match $s {
            Samples::U8($v) => $body,
            Samples::I8($v) => $body,
            Samples::U16($v) => $body,
            Samples::I16($v) => $body,
            Samples::U32($v) => $body,
            Samples::I32($v) => $body,
            Samples::U64($v) => $body,
            Samples::I64($v) => $body,
            Samples::F32($v) => $body,
            Samples::F64($v) => $body,
        }
    };
}

impl Samples {
    /// Decodes `bytes` (exactly `n * dtype.size()` of them) in the given byte order.
    pub fn decode(dtype: DataType, bytes: &[u8], little_endian: bool) -> Samples {
        macro_rules! dec {
            ($t:ty, $var:ident) => {{
                const N: usize = std::mem::size_of::<$t>();
                Samples::$var(
                    bytes
                        .chunks_exact(N)
                        .map(|c| {
                            let a: [u8; N] = c.try_into().expect("chunk size");
                            if little_endian {
                                <$t>::from_le_bytes(a)
                            } else {
                                <$t>::from_be_bytes(a)
                            }
                        })
                        .collect(),
                )
            }};
        }
        match dtype {
            DataType::U8 => Samples::U8(bytes.to_vec()),
            DataType::I8 => Samples::I8(bytes.iter().map(|&b| b as i8).collect()),
            DataType::U16 => dec!(u16, U16),
            DataType::I16 => dec!(i16, I16),
            DataType::U32 => dec!(u32, U32),
            DataType::I32 => dec!(i32, I32),
            DataType::U64 => dec!(u64, U64),
            DataType::I64 => dec!(i64, I64),
            DataType::F32 => dec!(f32, F32),
            DataType::F64 => dec!(f64, F64),
        }
    }

    /// Encodes as little-endian bytes.
    pub fn to_le_bytes(&self) -> Vec<u8> {
        for_each_samples!(self, v => v.iter().flat_map(|x| x.to_le_bytes()).collect())
    }

    /// The sample type.
    pub fn dtype(&self) -> DataType {
        match self {
            Samples::U8(_) => DataType::U8,
            Samples::I8(_) => DataType::I8,
            Samples::U16(_) => DataType::U16,
            Samples::I16(_) => DataType::I16,
            Samples::U32(_) => DataType::U32,
            Samples::I32(_) => DataType::I32,
            Samples::U64(_) => DataType::U64,
            Samples::I64(_) => DataType::I64,
            Samples::F32(_) => DataType::F32,
            Samples::F64(_) => DataType::F64,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        for_each_samples!(self, v => v.len())
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every sample as f64 (exact for all types but 64-bit integers beyond 2^53).
    #[allow(clippy::unnecessary_cast)] // one cast for all ten types, f64 among them
    pub fn to_f64(&self) -> Vec<f64> {
        for_each_samples!(self, v => v.iter().map(|&x| x as f64).collect())
    }
}

/// A decoded image file: shape (1 to 4 axes, trailing axes of extent 1 removed
/// down to 3), samples, geometry of the first three axes, and where it came from.
#[derive(Clone, Debug)]
pub struct Image {
    /// Extents; at least 3 entries (missing axes are 1), a 4th when the file is
    /// 4-D with more than one frame.
    pub dims: Vec<usize>,
    pub samples: Samples,
    pub geometry: Geometry,
    /// Time (or 4th-axis) step, when the file gives one.
    pub time_step: Option<f64>,
    /// The file the image was read from (for messages).
    pub path: PathBuf,
    /// Every file read for it: the header and any detached data file (so
    /// that writers can refuse to replace a directory holding them).
    pub sources: Vec<PathBuf>,
}

impl Image {
    /// The 3-D grid, or an error if the image has more than one frame in a 4th axis.
    pub fn dims3(&self) -> Result<Dims> {
        if self.dims.len() > 3 && self.dims[3..].iter().any(|&n| n > 1) {
            return Err(Error::input(
                &self.path,
                format!(
                    "is 4-D ({} axes: {:?}); this command takes a 3-D volume. 4-D (time-varying) data is for the hypersurface command `septa hyper`",
                    self.dims.len(),
                    self.dims
                ),
            ));
        }
        Dims::new(self.dims[0], self.dims[1], self.dims[2])
            .map_err(|e| Error::input(&self.path, e.to_string()))
    }

    /// Converts to a label volume. Floating-point samples must be integral
    /// (labels stored as float are common); anything else is an error naming the
    /// first offending voxel.
    pub fn into_label_volume(self) -> Result<LabelVolume> {
        let dims = self.dims3()?;
        if self.samples.len() != dims.len() {
            return Err(Error::input(
                &self.path,
                format!(
                    "holds {} samples for {} voxels",
                    self.samples.len(),
                    dims.len()
                ),
            ));
        }
        let path = self.path;
        let geometry = self.geometry;
        match self.samples {
            Samples::U8(v) => from_small(dims, &v, |x| x as usize, 256, geometry),
            Samples::I8(v) => from_small(dims, &v, |x| (x as i16 + 128) as usize, 256, geometry)
                .map(|lv| shift_values(lv, -128)),
            Samples::U16(v) => from_small(dims, &v, |x| x as usize, 65536, geometry),
            Samples::I16(v) => {
                from_small(dims, &v, |x| (x as i32 + 32768) as usize, 65536, geometry)
                    .map(|lv| shift_values(lv, -32768))
            }
            Samples::U32(v) => LabelVolume::from_values(
                dims,
                &v.iter().map(|&x| x as i64).collect::<Vec<_>>(),
                geometry,
            ),
            Samples::I32(v) => LabelVolume::from_values(
                dims,
                &v.iter().map(|&x| x as i64).collect::<Vec<_>>(),
                geometry,
            ),
            Samples::U64(v) => {
                let mut out = Vec::with_capacity(v.len());
                for (i, &x) in v.iter().enumerate() {
                    let Ok(x) = i64::try_from(x) else {
                        return Err(Error::input(
                            &path,
                            format!("label value {x} at voxel {:?} is too large", dims.coords(i)),
                        ));
                    };
                    out.push(x);
                }
                LabelVolume::from_values(dims, &out, geometry)
            }
            Samples::I64(v) => LabelVolume::from_values(dims, &v, geometry),
            Samples::F32(v) => float_labels(dims, v.iter().map(|&x| x as f64), &path, geometry),
            Samples::F64(v) => float_labels(dims, v.iter().copied(), &path, geometry),
        }
        .map_err(|e| match e {
            Error::Invalid(m) => Error::input(&path, m),
            other => other,
        })
    }

    /// Every sample as f64, for grayscale commands.
    pub fn to_f64(&self) -> Vec<f64> {
        self.samples.to_f64()
    }
}

/// Dense ids for small integer types through a counting table (fast path).
fn from_small<T: Copy + Sync>(
    dims: Dims,
    v: &[T],
    key: impl Fn(T) -> usize + Sync,
    range: usize,
    geometry: Geometry,
) -> Result<LabelVolume> {
    use rayon::prelude::*;
    let present = v
        .par_chunks(1 << 16)
        .fold(
            || vec![false; range],
            |mut p, c| {
                for &x in c {
                    p[key(x)] = true;
                }
                p
            },
        )
        .reduce(
            || vec![false; range],
            |mut a, b| {
                a.iter_mut().zip(b).for_each(|(x, y)| *x |= y);
                a
            },
        );
    let mut lut = vec![0 as LabelId; range];
    let mut values = Vec::new();
    for (k, &p) in present.iter().enumerate() {
        if p {
            if values.len() >= MAX_LABELS {
                return Err(Error::invalid(format!(
                    "more than {MAX_LABELS} distinct labels"
                )));
            }
            lut[k] = values.len() as LabelId;
            values.push(k as i64);
        }
    }
    let ids = v.par_iter().map(|&x| lut[key(x)]).collect();
    LabelVolume::from_ids(dims, ids, values, geometry)
}

fn shift_values(lv: LabelVolume, by: i64) -> LabelVolume {
    let values = lv.values().iter().map(|v| v + by).collect();
    LabelVolume::from_ids(lv.dims(), lv.ids().to_vec(), values, *lv.geometry())
        .expect("shift keeps order")
}

fn float_labels(
    dims: Dims,
    v: impl Iterator<Item = f64>,
    path: &Path,
    geometry: Geometry,
) -> Result<LabelVolume> {
    let mut out = Vec::with_capacity(dims.len());
    for (i, x) in v.enumerate() {
        if !x.is_finite() || x.fract() != 0.0 || x.abs() > 9.0e15 {
            return Err(Error::input(
                path,
                format!(
                    "non-integral label value {x} at voxel {:?}: a label map must hold whole numbers (is this a grayscale image? use `septa iso` for those)",
                    dims.coords(i)
                ),
            ));
        }
        out.push(x as i64);
    }
    LabelVolume::from_values(dims, &out, geometry)
}

/// Options for files that do not describe themselves (raw) and overrides.
#[derive(Clone, Debug, Default)]
pub struct ReadOptions {
    /// Raw files: extents.
    pub dims: Option<[usize; 3]>,
    /// Raw files: sample type.
    pub dtype: Option<DataType>,
    /// Raw files: voxel spacing in mm (default 1).
    pub spacing: Option<[f64; 3]>,
    /// Raw files: big-endian samples (default little-endian).
    pub big_endian: bool,
    /// Raw files: bytes to skip before the samples.
    pub header_bytes: u64,
}

/// File formats septa reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VolumeFormat {
    Nifti,
    Nrrd,
    MetaImage,
    Raw,
}

impl VolumeFormat {
    /// Guesses the format from the file name.
    pub fn from_path(path: &Path) -> Option<Self> {
        let name = path.file_name()?.to_string_lossy().to_ascii_lowercase();
        let name = name.strip_suffix(".gz").unwrap_or(&name);
        let ext = name.rsplit('.').next()?;
        Some(match ext {
            "nii" | "hdr" | "img" => VolumeFormat::Nifti,
            "nrrd" | "nhdr" => VolumeFormat::Nrrd,
            "mha" | "mhd" => VolumeFormat::MetaImage,
            "raw" | "bin" => VolumeFormat::Raw,
            _ => return None,
        })
    }
}

/// Reads any supported volume file (format from the extension; raw files need
/// `opts.dims` and `opts.dtype`).
pub fn read_image(path: &Path, opts: &ReadOptions) -> Result<Image> {
    let format = match VolumeFormat::from_path(path) {
        Some(f) => f,
        None if opts.dims.is_some() => VolumeFormat::Raw,
        None => {
            return Err(Error::input(
                path,
                "unknown file type: expected .nii, .nii.gz, .hdr/.img, .nrrd, .nhdr, .mha, .mhd, or a raw file with --dims and --dtype",
            ));
        }
    };
    match format {
        VolumeFormat::Nifti => nifti::read(path),
        VolumeFormat::Nrrd => nrrd::read(path),
        VolumeFormat::MetaImage => metaimage::read(path),
        VolumeFormat::Raw => raw::read(path, opts),
    }
}

/// Reads a label volume from any supported file.
pub fn read_label_volume(path: &Path, opts: &ReadOptions) -> Result<LabelVolume> {
    read_image(path, opts)?.into_label_volume()
}

/// Writes a label volume; the format follows the extension (`.nii`, `.nii.gz`,
/// `.nrrd`). Atomic (see [`atomic_write`]).
pub fn write_label_volume(path: &Path, volume: &LabelVolume) -> Result<()> {
    match VolumeFormat::from_path(path) {
        Some(VolumeFormat::Nifti) => nifti::write_labels(path, volume),
        Some(VolumeFormat::Nrrd) => nrrd::write_labels(path, volume),
        _ => Err(Error::input(
            path,
            "can only write label volumes as .nii, .nii.gz or .nrrd",
        )),
    }
}

/// Writes `bytes` to `path` atomically: a temporary file beside it, then a rename.
pub fn atomic_write(path: &Path, bytes: &[u8]) -> Result<()> {
    atomic_write_with(path, |w| w.write_all(bytes))
}

/// Like [`atomic_write`], with a closure that streams into a buffered writer.
///
/// The temporary file has a short name (see [`temp`]) and is removed if the
/// process is stopped by a signal. A file inside a temporary output directory
/// is not synced on its own: the directory is synced once when complete
/// ([`sync_tree`]); any other file is synced before the rename.
pub fn atomic_write_with(
    path: &Path,
    f: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if path.file_name().is_none() {
        return Err(Error::input(path, "is not a file path"));
    }
    temp::check_not_stopping(path)?;
    let sync = !temp::inside_registered_dir(path);
    if sync {
        // what killed runs left beside their files (inside a temporary
        // directory there is nothing to sweep)
        temp::sweep_stale(dir);
    }
    let tmp = temp::register(temp::temp_path(dir, temp::Kind::New));
    let result = (|| -> std::io::Result<()> {
        let file = std::fs::File::create(tmp.path())?;
        let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
        f(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        if sync {
            file.sync_all()?;
        }
        drop(file);
        std::fs::rename(tmp.path(), path)
    })();
    match result {
        Ok(()) => {
            drop(tmp);
            Ok(())
        }
        Err(e) => {
            tmp.remove();
            Err(Error::io(path, e))
        }
    }
}

/// Checks, before the work, that `path` can be written: creates and removes a
/// temporary file beside it (a read-only or missing folder fails now).
pub fn check_writable(path: &Path) -> Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let probe = temp::register(temp::temp_path(dir, temp::Kind::New));
    match std::fs::File::create(probe.path()) {
        Ok(_) => {
            probe.remove();
            Ok(())
        }
        Err(e) => {
            drop(probe);
            Err(Error::input(
                path,
                format!(
                    "cannot be written: creating a file in {} fails: {e}",
                    dir.display()
                ),
            ))
        }
    }
}

/// Syncs `dir` and every directory below it (the entries; their files'
/// data goes with them on the common journalling file systems), once each:
/// what a completed output directory needs before it is renamed into place.
pub fn sync_tree(dir: &Path) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    for e in entries {
        let e = e.map_err(|e| Error::io(dir, e))?;
        if e.file_type()
            .map_err(|err| Error::io(e.path(), err))?
            .is_dir()
        {
            sync_tree(&e.path())?;
        }
    }
    sync_dir(dir)
}

/// Syncs one directory's entries (a no-op where directories cannot be opened).
pub fn sync_dir(dir: &Path) -> Result<()> {
    match std::fs::File::open(dir) {
        Ok(f) => f.sync_all().or_else(|e| {
            // some file systems refuse fsync on directories: nothing to do there
            if matches!(
                e.kind(),
                std::io::ErrorKind::InvalidInput | std::io::ErrorKind::Unsupported
            ) {
                Ok(())
            } else {
                Err(Error::io(dir, e))
            }
        }),
        Err(_) => Ok(()),
    }
}

/// Reads a whole file into memory, with the path in the error. Only
/// regular files: a directory, a device (`/dev/zero` reads for ever) or a
/// pipe is an error that says so.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>> {
    check_regular_file(path)?;
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut bytes = Vec::new();
    crate::memory::fallible(|| bytes.try_reserve_exact(usize::try_from(len).unwrap_or(usize::MAX)))
        .map_err(|_| {
            Error::input(
                path,
                format!("out of memory reading the file ({len} bytes)"),
            )
        })?;
    std::io::Read::read_to_end(&mut file, &mut bytes).map_err(|e| Error::io(path, e))?;
    Ok(bytes)
}

/// An error unless `path` is a regular file (or a link to one).
pub fn check_regular_file(path: &Path) -> Result<()> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return Err(Error::input(path, "is a directory, not a file"));
    }
    if !meta.is_file() {
        return Err(Error::input(
            path,
            "is not a regular file (a device, pipe or socket): septa reads files",
        ));
    }
    Ok(())
}
