//! MetaImage (ITK MetaIO): `.mha` with `ElementDataFile = LOCAL` and `.mhd`
//! with a separate data file; binary (optionally zlib- or gzip-compressed) or
//! text samples. Reading only.
//!
//! Geometry is LPS, as ITK writes it. **Direction convention**: ITK's
//! `MetaImageIO::ReadImageInformation` does
//! `directionAxis[jj] = transformMatrix[ii * N + jj]; SetDirection(ii, directionAxis)`
//! — the `ii`-th group of N consecutive `TransformMatrix` values is the direction
//! of index axis `ii`, i.e. a *column* of ITK's direction matrix. The file thus
//! lists the direction matrix column by column (`d00 d10 d20 d01 …`), which is
//! the same as its transpose row by row. (Checked against the ITK source of
//! `itkMetaImageIO.cxx`.)

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::raw::{
    byte_count, decode_at, decode_owned, decode_text, image_shape, in_file, truncated, voxel_count,
};
use crate::io::{DataType, Image, Samples, gz, read_file};
use crate::volume::Geometry;

/// Where the samples are and how they are stored.
struct DataSpec {
    dims: Vec<usize>,
    dtype: DataType,
    little_endian: bool,
    compressed: bool,
    binary: bool,
    /// `HeaderSize`: bytes to skip in the data file (−1: data at its end).
    header_size: i64,
    /// `CompressedDataSize`, when given.
    compressed_size: Option<usize>,
}

/// Reads a `.mha` or `.mhd` file.
pub fn read(path: &Path) -> Result<Image> {
    let file = read_file(path)?;
    let (fields, local_start) = parse_header(path, &file)?;
    let spec = data_spec(path, &fields)?;
    let geometry = geometry(path, &fields, spec.dims.len())?;
    let (data_path, data) = match local_start {
        Some(start) => (
            path.to_path_buf(),
            file.get(start..).unwrap_or_default().to_vec(),
        ),
        None => {
            let data_path = data_file(path, &fields)?;
            let data = read_file(&data_path)?;
            (data_path, data)
        }
    };
    let samples = decode(&data_path, &data, &spec)?;
    let time_step = time_step(&fields, spec.dims.len());
    Ok(Image {
        dims: image_shape(spec.dims),
        samples,
        geometry,
        time_step,
        path: path.to_path_buf(),
        sources: crate::io::nrrd::sources(path, &data_path),
    })
}

// ------------------------------------------------------------------- header

/// `Key = Value` lines up to `ElementDataFile` (which must be last). Returns the
/// fields by lower-cased key and, for `LOCAL`, where the data starts.
fn parse_header(path: &Path, file: &[u8]) -> Result<(HashMap<String, String>, Option<usize>)> {
    let mut fields = HashMap::new();
    let mut pos = 0;
    let mut line_no = 0;
    while pos < file.len() {
        let end = file[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(file.len(), |i| pos + i);
        let line = String::from_utf8_lossy(&file[pos..end]).trim().to_string();
        pos = (end + 1).min(file.len());
        line_no += 1;
        if line.is_empty() {
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            return Err(not_metaimage(path, line_no, &line));
        };
        let key = key.trim().to_ascii_lowercase();
        if line_no == 1
            && !matches!(
                key.as_str(),
                "objecttype" | "ndims" | "comment" | "objectsubtype"
            )
        {
            return Err(not_metaimage(path, line_no, &line));
        }
        let value = value.trim().to_string();
        if key == "elementdatafile" {
            let local = value.eq_ignore_ascii_case("local");
            fields.insert(key, value);
            return Ok((fields, local.then_some(pos)));
        }
        fields.insert(key, value);
    }
    Err(Error::input(
        path,
        "the MetaImage header has no ElementDataFile line",
    ))
}

fn not_metaimage(path: &Path, line_no: usize, line: &str) -> Error {
    let shown: String = line.chars().take(40).collect();
    Error::input(
        path,
        format!(
            "wrong magic: line {line_no} ({shown:?}) is not a MetaImage \"Key = Value\" header line"
        ),
    )
}

fn get<'a>(fields: &'a HashMap<String, String>, keys: &[&str]) -> Option<&'a str> {
    keys.iter().find_map(|k| fields.get(*k)).map(String::as_str)
}

fn is_true(value: Option<&str>) -> bool {
    value.is_some_and(|v| v.eq_ignore_ascii_case("true") || v == "1")
}

/// `n` numbers of the field `name`.
fn numbers(path: &Path, name: &str, text: &str, n: usize) -> Result<Vec<f64>> {
    let v: Option<Vec<f64>> = text
        .split_whitespace()
        .map(|t| t.parse::<f64>().ok())
        .collect();
    match v {
        Some(v) if v.len() == n && v.iter().all(|x| x.is_finite()) => Ok(v),
        _ => Err(Error::input(
            path,
            format!("{name} is {text:?}: expected {n} numbers"),
        )),
    }
}

fn element_type(path: &Path, name: &str) -> Result<DataType> {
    Ok(match name.to_ascii_uppercase().as_str() {
        "MET_UCHAR" => DataType::U8,
        "MET_CHAR" => DataType::I8,
        "MET_USHORT" => DataType::U16,
        "MET_SHORT" => DataType::I16,
        // MetaIO gives MET_(U)LONG 4 bytes, like MET_(U)INT.
        "MET_UINT" | "MET_ULONG" => DataType::U32,
        "MET_INT" | "MET_LONG" => DataType::I32,
        "MET_ULONG_LONG" => DataType::U64,
        "MET_LONG_LONG" => DataType::I64,
        "MET_FLOAT" => DataType::F32,
        "MET_DOUBLE" => DataType::F64,
        _ => {
            return Err(Error::input(
                path,
                format!(
                    "unsupported ElementType {name:?}: septa reads MET_(U)CHAR, (U)SHORT, (U)INT, (U)LONG, (U)LONG_LONG, FLOAT, DOUBLE"
                ),
            ));
        }
    })
}

/// Shape and storage of the samples.
fn data_spec(path: &Path, f: &HashMap<String, String>) -> Result<DataSpec> {
    let ndims_text = get(f, &["ndims"])
        .ok_or_else(|| Error::input(path, "the MetaImage header has no NDims"))?;
    let ndims = match ndims_text.parse::<usize>() {
        Ok(n) if (1..=4).contains(&n) => n,
        _ => {
            return Err(Error::input(
                path,
                format!("NDims is {ndims_text:?}: septa reads 1 to 4 dimensions"),
            ));
        }
    };
    let dim_text = get(f, &["dimsize"])
        .ok_or_else(|| Error::input(path, "the MetaImage header has no DimSize"))?;
    let dims: Vec<usize> = dim_text
        .split_whitespace()
        .map(|t| t.parse::<usize>().ok().filter(|&n| n >= 1))
        .collect::<Option<_>>()
        .filter(|d: &Vec<usize>| d.len() == ndims)
        .ok_or_else(|| {
            Error::input(
                path,
                format!("DimSize is {dim_text:?}: expected {ndims} extents of at least 1"),
            )
        })?;
    if let Some(c) = get(f, &["elementnumberofchannels"]).filter(|c| c.trim() != "1") {
        return Err(Error::input(
            path,
            format!("ElementNumberOfChannels is {c}: septa reads single-channel (scalar) images"),
        ));
    }
    let type_name = get(f, &["elementtype"])
        .ok_or_else(|| Error::input(path, "the MetaImage header has no ElementType"))?;
    let header_size = match get(f, &["headersize"]).map(|t| t.parse::<i64>()) {
        None => 0,
        Some(Ok(n)) if n >= -1 => n,
        Some(_) => return Err(Error::input(path, "HeaderSize must be -1 or a byte count")),
    };
    let compressed_size = get(f, &["compresseddatasize"]).and_then(|t| t.parse::<usize>().ok());
    Ok(DataSpec {
        dims,
        dtype: element_type(path, type_name)?,
        little_endian: !is_true(get(f, &["binarydatabyteordermsb", "elementbyteordermsb"])),
        compressed: is_true(get(f, &["compresseddata"])),
        binary: get(f, &["binarydata"]).is_none_or(|v| is_true(Some(v))),
        header_size,
        compressed_size,
    })
}

/// LPS geometry from `ElementSpacing`, `Offset` and `TransformMatrix` (each
/// with its MetaIO synonyms); only the first three axes are spatial.
fn geometry(path: &Path, f: &HashMap<String, String>, ndims: usize) -> Result<Geometry> {
    let spatial = ndims.min(3);
    let mut spacing = [1.0; 3];
    if let Some(t) = get(f, &["elementspacing", "elementsize"]) {
        let s = numbers(path, "ElementSpacing", t, ndims)?;
        spacing[..spatial].copy_from_slice(&s[..spatial]);
    }
    let mut origin = [0.0; 3];
    if let Some(t) = get(f, &["offset", "position", "origin"]) {
        let o = numbers(path, "Offset", t, ndims)?;
        origin[..spatial].copy_from_slice(&o[..spatial]);
    }
    let mut direction = Geometry::IDENTITY_DIRECTION;
    if let Some(t) = get(f, &["transformmatrix", "rotation", "orientation"]) {
        let m = numbers(path, "TransformMatrix", t, ndims * ndims)?;
        // Group `axis` of `ndims` consecutive values: the direction of that axis.
        for (axis, dir) in direction.iter_mut().enumerate().take(spatial) {
            for (comp, d) in dir.iter_mut().enumerate().take(spatial) {
                *d = m[axis * ndims + comp];
            }
        }
    }
    Geometry::new(spacing, origin, direction).map_err(|e| in_file(path, e))
}

/// The 4th `ElementSpacing` of a 4-D image.
fn time_step(f: &HashMap<String, String>, ndims: usize) -> Option<f64> {
    let text = get(f, &["elementspacing", "elementsize"])?;
    let v = text.split_whitespace().nth(3)?.parse::<f64>().ok()?;
    (ndims == 4 && v.is_finite() && v != 0.0).then_some(v)
}

// --------------------------------------------------------------------- data

/// The separate data file of a `.mhd` (relative to the header's folder).
fn data_file(path: &Path, f: &HashMap<String, String>) -> Result<PathBuf> {
    let name = get(f, &["elementdatafile"]).unwrap_or_default();
    let words: Vec<&str> = name.split_whitespace().collect();
    if words
        .first()
        .is_some_and(|w| w.eq_ignore_ascii_case("list"))
        || (name.contains('%') && words.len() >= 4)
    {
        return Err(Error::input(
            path,
            format!(
                "multi-file \"ElementDataFile = {name}\" is not supported: write the data as one file"
            ),
        ));
    }
    let data_path = path.parent().unwrap_or(Path::new("")).join(name);
    if name.is_empty() || std::fs::metadata(&data_path).is_err() {
        return Err(Error::input(
            path,
            format!(
                "missing data file: the ElementDataFile {} does not exist",
                data_path.display()
            ),
        ));
    }
    detached_is_file(path, &data_path, "ElementDataFile")?;
    Ok(data_path)
}

/// A detached data file must be a regular file; the error names the header.
pub(crate) fn detached_is_file(header: &Path, data: &Path, field: &str) -> Result<()> {
    crate::io::check_regular_file(data).map_err(|e| match e {
        Error::Input { problem, .. } => {
            Error::input(header, format!("the {field} {} {problem}", data.display()))
        }
        other => other,
    })
}

/// Decodes the samples of `spec` from the data bytes.
fn decode(path: &Path, data: &[u8], spec: &DataSpec) -> Result<Samples> {
    let n = voxel_count(path, &spec.dims)?;
    let needed = byte_count(path, &spec.dims, spec.dtype)?;
    if !spec.binary {
        return decode_text(path, data, n, spec.dtype);
    }
    if spec.compressed {
        let skip = usize::try_from(spec.header_size).unwrap_or(0);
        let stream = data.get(skip..).unwrap_or_default();
        let stream = match spec.compressed_size {
            Some(size) if size <= stream.len() => &stream[..size],
            _ => stream,
        };
        if needed as u64 > gz::max_inflated_len(stream.len()) {
            return Err(Error::input(
                path,
                format!(
                    "truncated: expected {needed} bytes of voxel data, more than {} bytes of compressed data can hold",
                    stream.len()
                ),
            ));
        }
        let raw = gz::inflate_any(path, stream, needed as u64)?;
        return decode_owned(path, raw, 0, n, spec.dtype, spec.little_endian);
    }
    let offset = if spec.header_size == -1 {
        data.len()
            .checked_sub(needed)
            .ok_or_else(|| truncated(path, needed as u64, 0, data.len() as u64))?
    } else {
        usize::try_from(spec.header_size).unwrap_or(0)
    };
    decode_at(path, data, offset, n, spec.dtype, spec.little_endian)
}
