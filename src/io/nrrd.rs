//! NRRD: the reader (`.nrrd` with attached data, `.nhdr` with a detached
//! single `data file`; encodings raw, gzip and text) and the label-volume writer
//! (`.nrrd`, gzip, `space: left-posterior-superior`).
//!
//! The header is parsed here following the NRRD format definition (teem):
//! `field: value` lines after the `NRRD000X` magic, `#` comments and
//! `key:=value` pairs ignored, a blank line before attached data. Geometry comes
//! from `space directions` / `space origin` converted from the file's `space`
//! (RAS, LAS or LPS) to LPS, else from `spacings`. Up to three spatial axes are
//! read; a non-spatial leading axis of size 1 is dropped, trailing non-spatial
//! axes (time, list) become the 4th+ axes of the [`Image`].

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::error::{Error, Result};
use crate::io::nifti::{encode_labels, gzip, smallest_label_type};
use crate::io::raw::{
    byte_count, decode_at, decode_owned, decode_text, image_shape, in_file, truncated, voxel_count,
};
use crate::io::{DataType, Image, Samples, atomic_write, gz, read_file};
use crate::volume::{Geometry, LabelVolume};

/// Largest `dimension` accepted (the NRRD limit of teem).
const MAX_DIMENSION: usize = 16;

/// How the voxel bytes are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Raw,
    Gzip,
    Text,
}

/// Which way the file's `space` axes point, as signs to apply to reach LPS.
#[derive(Clone, Copy, Debug)]
struct Space {
    to_lps: [f64; 3],
}

/// The parsed header: fields by lower-cased name (spaces removed) and where the
/// attached data starts, if the header ended with a blank line.
struct Header {
    fields: HashMap<String, String>,
    data_start: Option<usize>,
}

/// Reads a `.nrrd` or `.nhdr` file.
pub fn read(path: &Path) -> Result<Image> {
    let file = read_file(path)?;
    let header = parse_header(path, &file)?;
    let layout = Layout::from_header(path, &header)?;
    let (data_path, payload) = payload(path, &header, file)?;
    let payload = skip_lines(
        &data_path,
        payload,
        header.usize_field(path, "lineskip")?.unwrap_or(0),
    )?;
    let samples = decode_payload(&data_path, &payload, &layout)?;
    Ok(Image {
        dims: image_shape(layout.dims.clone()),
        samples,
        geometry: layout.geometry,
        time_step: layout.time_step,
        path: path.to_path_buf(),
        sources: sources(path, &data_path),
    })
}

/// The header, and the detached data file if there is one.
pub(crate) fn sources(path: &Path, data_path: &Path) -> Vec<std::path::PathBuf> {
    let mut v = vec![path.to_path_buf()];
    if data_path != path {
        v.push(data_path.to_path_buf());
    }
    v
}

// ------------------------------------------------------------------- header

/// Splits the header into fields; checks the magic.
fn parse_header(path: &Path, file: &[u8]) -> Result<Header> {
    if !file.starts_with(b"NRRD") {
        let shown = String::from_utf8_lossy(&file[..file.len().min(8)]).into_owned();
        return Err(Error::input(
            path,
            format!("wrong magic {shown:?}: a NRRD file starts with \"NRRD000X\""),
        ));
    }
    let mut fields = HashMap::new();
    let mut pos = 0;
    let mut line_no = 0;
    let mut data_start = None;
    while pos < file.len() {
        let end = file[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(file.len(), |i| pos + i);
        let line = String::from_utf8_lossy(&file[pos..end]);
        let line = line.trim_end_matches('\r');
        pos = (end + 1).min(file.len());
        line_no += 1;
        if line_no == 1 || line.starts_with('#') || line.contains(":=") {
            continue;
        }
        if line.trim().is_empty() {
            data_start = Some(pos);
            break;
        }
        let Some((key, value)) = line.split_once(':') else {
            return Err(Error::input(
                path,
                format!("header line {line_no} ({line:?}) is not \"field: value\""),
            ));
        };
        let key: String = key
            .to_ascii_lowercase()
            .chars()
            .filter(|c| !c.is_whitespace())
            .collect();
        let value = value.trim().to_string();
        // `data file: LIST` is followed by file names up to the end of the header.
        let list = key == "datafile" && value.starts_with("LIST");
        fields.insert(key, value);
        if list {
            break;
        }
    }
    Ok(Header { fields, data_start })
}

impl Header {
    fn get(&self, key: &str) -> Option<&str> {
        self.fields.get(key).map(String::as_str)
    }

    fn require(&self, path: &Path, key: &str, name: &str) -> Result<&str> {
        self.get(key)
            .ok_or_else(|| Error::input(path, format!("the NRRD header has no \"{name}\" field")))
    }

    fn usize_field(&self, path: &Path, key: &str) -> Result<Option<usize>> {
        self.get(key)
            .map(|v| {
                v.parse::<usize>().map_err(|_| {
                    Error::input(
                        path,
                        format!("\"{key}\" is {v:?}: expected a non-negative integer"),
                    )
                })
            })
            .transpose()
    }
}

fn parse_type(path: &Path, name: &str) -> Result<DataType> {
    let norm = name
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .to_ascii_lowercase();
    Ok(match norm.as_str() {
        "signed char" | "int8" | "int8_t" => DataType::I8,
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => DataType::U8,
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            DataType::I16
        }
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => DataType::U16,
        "int" | "signed int" | "int32" | "int32_t" => DataType::I32,
        "uint" | "unsigned int" | "uint32" | "uint32_t" => DataType::U32,
        "longlong"
        | "long long"
        | "long long int"
        | "signed long long"
        | "signed long long int"
        | "int64"
        | "int64_t" => DataType::I64,
        "ulonglong" | "unsigned long long" | "unsigned long long int" | "uint64" | "uint64_t" => {
            DataType::U64
        }
        "float" => DataType::F32,
        "double" => DataType::F64,
        _ => {
            return Err(Error::input(
                path,
                format!(
                    "unsupported NRRD type {name:?}: septa reads integer, float and double samples"
                ),
            ));
        }
    })
}

fn parse_encoding(path: &Path, name: &str) -> Result<Encoding> {
    Ok(match name.to_ascii_lowercase().as_str() {
        "raw" => Encoding::Raw,
        "gzip" | "gz" => Encoding::Gzip,
        "text" | "txt" | "ascii" => Encoding::Text,
        _ => {
            return Err(Error::input(
                path,
                format!(
                    "unsupported NRRD encoding {name:?}: septa reads raw, gzip and text (convert with `unu save -e gzip`)"
                ),
            ));
        }
    })
}

fn parse_space(path: &Path, name: &str) -> Result<Space> {
    let signs = match name.to_ascii_lowercase().as_str() {
        "right-anterior-superior" | "ras" => [-1.0, -1.0, 1.0],
        "left-anterior-superior" | "las" => [1.0, -1.0, 1.0],
        "left-posterior-superior" | "lps" => [1.0, 1.0, 1.0],
        // Non-anatomical 3-D spaces: taken as they are.
        "scanner-xyz" | "3d-right-handed" | "3d-left-handed" => [1.0, 1.0, 1.0],
        _ => {
            return Err(Error::input(
                path,
                format!(
                    "unsupported NRRD space {name:?}: septa reads 3-D spaces (RAS, LAS, LPS, scanner-xyz)"
                ),
            ));
        }
    };
    Ok(Space { to_lps: signs })
}

/// Parses `(x,y,z)`; `what` names the field for messages.
fn parse_vector(path: &Path, text: &str, what: &str) -> Result<DVec3> {
    let bad = || {
        Error::input(
            path,
            format!("{what} {text:?} is not a vector \"(x,y,z)\" of 3 numbers"),
        )
    };
    let inner = text
        .trim()
        .strip_prefix('(')
        .and_then(|t| t.strip_suffix(')'))
        .ok_or_else(bad)?;
    let v: Vec<f64> = inner
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| bad())?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(DVec3::new(x, y, z)),
        _ => Err(bad()),
    }
}

/// Parses `space directions`: one `(x,y,z)` or `none` per axis.
fn parse_directions(path: &Path, text: &str) -> Result<Vec<Option<DVec3>>> {
    let mut out = Vec::new();
    let mut rest = text.trim();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("none") {
            out.push(None);
            rest = r.trim_start();
        } else if rest.starts_with('(') {
            let close = rest.find(')').ok_or_else(|| {
                Error::input(path, format!("space directions {text:?}: unclosed \"(\""))
            })?;
            out.push(Some(parse_vector(
                path,
                &rest[..=close],
                "space direction",
            )?));
            rest = rest[close + 1..].trim_start();
        } else {
            return Err(Error::input(
                path,
                format!("space directions {text:?}: expected \"(x,y,z)\" or \"none\" per axis"),
            ));
        }
    }
    Ok(out)
}

// ------------------------------------------------------------------- layout

/// Shape, sample format and geometry of the voxel data.
struct Layout {
    /// Extents as the [`Image`] sees them (spatial axes, then trailing axes).
    dims: Vec<usize>,
    dtype: DataType,
    encoding: Encoding,
    little_endian: bool,
    /// `byte skip` (−1: data at the end of the file).
    byte_skip: i64,
    geometry: Geometry,
    /// Spacing of the first trailing non-spatial axis (time), when given.
    time_step: Option<f64>,
}

impl Layout {
    fn from_header(path: &Path, h: &Header) -> Result<Layout> {
        let sizes = sizes(path, h)?;
        let spatial = spatial_axes(path, h, sizes.len())?;
        Ok(Layout {
            dims: image_dims(path, &sizes, &spatial)?,
            dtype: parse_type(path, h.require(path, "type", "type")?)?,
            encoding: parse_encoding(path, h.require(path, "encoding", "encoding")?)?,
            little_endian: little_endian(path, h)?,
            byte_skip: byte_skip(path, h)?,
            geometry: geometry(path, h, &spatial)?,
            time_step: time_step(h, &spatial),
        })
    }
}

/// `endian` (little when absent, as for single-byte types).
fn little_endian(path: &Path, h: &Header) -> Result<bool> {
    match h.get("endian").map(str::to_ascii_lowercase).as_deref() {
        None | Some("little") => Ok(true),
        Some("big") => Ok(false),
        Some(other) => Err(Error::input(
            path,
            format!("endian is {other:?}: expected \"little\" or \"big\""),
        )),
    }
}

/// `byte skip`: a byte count, or −1 for "the data ends the file".
fn byte_skip(path: &Path, h: &Header) -> Result<i64> {
    match h.get("byteskip") {
        None => Ok(0),
        Some(v) => match v.parse::<i64>() {
            Ok(n) if n >= -1 => Ok(n),
            _ => Err(Error::input(
                path,
                format!("byte skip is {v:?}: expected -1 or a byte count"),
            )),
        },
    }
}

/// The `spacings` entry of the first axis after the last spatial one.
fn time_step(h: &Header, spatial: &[bool]) -> Option<f64> {
    let axis = spatial.iter().rposition(|&s| s)? + 1;
    let token = h.get("spacings")?.split_whitespace().nth(axis)?;
    token
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && *v != 0.0)
}

/// `dimension` and `sizes`, each size at least 1.
fn sizes(path: &Path, h: &Header) -> Result<Vec<usize>> {
    let dim_text = h.require(path, "dimension", "dimension")?;
    let dimension = match dim_text.parse::<usize>() {
        Ok(n) if (1..=MAX_DIMENSION).contains(&n) => n,
        _ => {
            return Err(Error::input(
                path,
                format!("dimension is {dim_text:?}: expected 1 to {MAX_DIMENSION}"),
            ));
        }
    };
    let text = h.require(path, "sizes", "sizes")?;
    let sizes: Vec<usize> = text
        .split_whitespace()
        .map(|t| t.parse::<usize>().ok().filter(|&n| n >= 1))
        .collect::<Option<_>>()
        .ok_or_else(|| {
            Error::input(
                path,
                format!("sizes {text:?}: every extent must be an integer of at least 1"),
            )
        })?;
    if sizes.len() != dimension {
        return Err(Error::input(
            path,
            format!(
                "sizes {text:?} has {} entries for dimension {dimension}",
                sizes.len()
            ),
        ));
    }
    Ok(sizes)
}

/// Which axes are spatial: from `space directions` (non-`none`), else `kinds`
/// (`domain`/`space`), else the first three.
fn spatial_axes(path: &Path, h: &Header, dimension: usize) -> Result<Vec<bool>> {
    if let Some(text) = h.get("spacedirections") {
        let dirs = parse_directions(path, text)?;
        if dirs.len() != dimension {
            return Err(Error::input(
                path,
                format!(
                    "space directions has {} entries for dimension {dimension}",
                    dirs.len()
                ),
            ));
        }
        return Ok(dirs.iter().map(Option::is_some).collect());
    }
    if let Some(text) = h.get("kinds") {
        let kinds: Vec<String> = text
            .split_whitespace()
            .map(str::to_ascii_lowercase)
            .collect();
        if kinds.len() == dimension {
            return Ok(kinds
                .iter()
                .map(|k| k == "domain" || k == "space")
                .collect());
        }
    }
    Ok((0..dimension).map(|i| i < 3).collect())
}

/// Spatial extents followed by trailing non-spatial ones; a leading non-spatial
/// axis must have size 1 (it is dropped); other layouts are rejected.
fn image_dims(path: &Path, sizes: &[usize], spatial: &[bool]) -> Result<Vec<usize>> {
    let mut axes: Vec<(usize, bool)> = sizes.iter().copied().zip(spatial.iter().copied()).collect();
    if axes.len() > 1 && !axes[0].1 && axes.iter().skip(1).any(|a| a.1) {
        if axes[0].0 != 1 {
            return Err(Error::input(
                path,
                format!(
                    "has {} values per voxel (a leading non-spatial axis): septa reads scalar volumes",
                    axes[0].0
                ),
            ));
        }
        axes.remove(0);
    }
    let n_spatial = axes.iter().take_while(|a| a.1).count();
    if n_spatial == 0 || n_spatial > 3 || axes[n_spatial..].iter().any(|a| a.1) {
        return Err(Error::input(
            path,
            format!(
                "unsupported axis layout (sizes {sizes:?}, spatial {spatial:?}): expected 1 to 3 spatial axes first"
            ),
        ));
    }
    let mut dims: Vec<usize> = axes[..n_spatial].iter().map(|a| a.0).collect();
    dims.resize(3, 1);
    dims.extend(axes[n_spatial..].iter().map(|a| a.0));
    Ok(dims)
}

/// The LPS geometry of the spatial axes.
fn geometry(path: &Path, h: &Header, spatial: &[bool]) -> Result<Geometry> {
    let space = match h.get("space") {
        Some(name) => parse_space(path, name)?,
        None => Space { to_lps: [1.0; 3] },
    };
    if let Some(n) = h.get("spacedimension").filter(|v| v.trim() != "3") {
        return Err(Error::input(
            path,
            format!("space dimension is {n:?}: septa reads 3-D spaces"),
        ));
    }
    let to_lps = |v: DVec3| v * DVec3::from(space.to_lps);
    let origin = match h.get("spaceorigin") {
        Some(text) => to_lps(parse_vector(path, text, "space origin")?),
        None => DVec3::ZERO,
    };
    let columns = match h.get("spacedirections") {
        Some(text) => parse_directions(path, text)?
            .into_iter()
            .flatten()
            .map(to_lps)
            .collect(),
        None => spacing_columns(path, h, spatial)?,
    };
    let columns = complete_basis(columns);
    let mut affine = [[0.0; 4]; 3];
    for (c, col) in columns.iter().enumerate() {
        for r in 0..3 {
            affine[r][c] = col[r];
        }
    }
    for r in 0..3 {
        affine[r][3] = origin[r];
    }
    Geometry::from_affine(affine).map_err(|e| in_file(path, e))
}

/// Axis-aligned columns from `spacings` (missing or `nan` → 1; zero or negative
/// is an error).
fn spacing_columns(path: &Path, h: &Header, spatial: &[bool]) -> Result<Vec<DVec3>> {
    let given: Vec<&str> = h
        .get("spacings")
        .map(|t| t.split_whitespace().collect())
        .unwrap_or_default();
    let mut columns = Vec::new();
    for (axis, _) in spatial.iter().enumerate().filter(|(_, s)| **s) {
        let s = match given.get(axis) {
            None => 1.0,
            Some(t) => match t.parse::<f64>() {
                Ok(v) if v.is_nan() => 1.0,
                Ok(v) if v.is_finite() && v > 0.0 => v,
                _ => {
                    return Err(Error::input(
                        path,
                        format!("spacing of axis {axis} is {t:?}: it must be a positive number"),
                    ));
                }
            },
        };
        let mut col = DVec3::ZERO;
        if let Some(slot) = col.as_mut().get_mut(columns.len()) {
            *slot = s;
        }
        columns.push(col);
    }
    Ok(columns)
}

/// Completes 1 or 2 axis columns to 3 with unit vectors perpendicular to them.
fn complete_basis(mut columns: Vec<DVec3>) -> Vec<DVec3> {
    columns.truncate(3);
    while columns.len() < 3 {
        let next = match columns[..] {
            [a, b] => a.cross(b).normalize_or_zero(),
            [a] => a.normalize_or(DVec3::X).any_orthonormal_vector(),
            _ => DVec3::X,
        };
        columns.push(next);
    }
    columns
}

// --------------------------------------------------------------------- data

/// The bytes holding the data (from `data file` or after the attached header)
/// and the path to name in messages.
fn payload(path: &Path, h: &Header, file: Vec<u8>) -> Result<(PathBuf, Vec<u8>)> {
    let Some(name) = h.get("datafile") else {
        let Some(start) = h.data_start else {
            return Err(Error::input(
                path,
                "no data: the header has neither a \"data file\" nor a blank line followed by attached data",
            ));
        };
        let mut file = file;
        file.drain(..start);
        return Ok((path.to_path_buf(), file));
    };
    let words: Vec<&str> = name.split_whitespace().collect();
    if words.first() == Some(&"LIST") || (name.contains('%') && words.len() >= 4) {
        return Err(Error::input(
            path,
            format!(
                "multi-file \"data file: {name}\" is not supported: write the data as one file"
            ),
        ));
    }
    let data_path = path.parent().unwrap_or(Path::new("")).join(name);
    if std::fs::metadata(&data_path).is_err() {
        return Err(Error::input(
            path,
            format!(
                "missing data file: the detached data file {} does not exist",
                data_path.display()
            ),
        ));
    }
    crate::io::metaimage::detached_is_file(path, &data_path, "data file")?;
    let data = read_file(&data_path)?;
    Ok((data_path, data))
}

/// Drops the first `lines` lines of the data.
fn skip_lines(path: &Path, mut data: Vec<u8>, lines: usize) -> Result<Vec<u8>> {
    let mut pos = 0;
    for i in 0..lines {
        match data[pos..].iter().position(|&b| b == b'\n') {
            Some(n) => pos += n + 1,
            None => {
                return Err(Error::input(
                    path,
                    format!("truncated: line skip {lines} but only {i} lines of data"),
                ));
            }
        }
    }
    data.drain(..pos);
    Ok(data)
}

/// Decodes the samples of `layout` from `data` (after line skip).
fn decode_payload(path: &Path, data: &[u8], layout: &Layout) -> Result<Samples> {
    let n = voxel_count(path, &layout.dims)?;
    let needed = byte_count(path, &layout.dims, layout.dtype)?;
    let skip = usize::try_from(layout.byte_skip).unwrap_or(0);
    match layout.encoding {
        Encoding::Raw => {
            let offset = if layout.byte_skip == -1 {
                data.len()
                    .checked_sub(needed)
                    .ok_or_else(|| truncated(path, needed as u64, 0, data.len() as u64))?
            } else {
                skip
            };
            // more data than the sizes describe: the sizes (or the type) are wrong
            let extra = data.len().saturating_sub(offset).saturating_sub(needed);
            if extra > 0 && layout.byte_skip != -1 {
                return Err(Error::input(
                    path,
                    format!(
                        "holds {} bytes of voxel data after offset {offset}, but the sizes {:?} of \
                         {} need {needed}: {extra} bytes would be ignored (check sizes and type)",
                        data.len() - offset,
                        layout.dims,
                        layout.dtype.name()
                    ),
                ));
            }
            decode_at(path, data, offset, n, layout.dtype, layout.little_endian)
        }
        Encoding::Gzip => {
            if layout.byte_skip == -1 {
                return Err(Error::input(
                    path,
                    "byte skip -1 is only allowed with raw encoding",
                ));
            }
            let total = skip.checked_add(needed).map_or(u64::MAX, |t| t as u64);
            if total > gz::max_inflated_len(data.len()) {
                return Err(Error::input(
                    path,
                    format!(
                        "truncated: expected {needed} bytes of voxel data after offset {skip}, more than {} bytes of gzip data can hold",
                        data.len()
                    ),
                ));
            }
            let raw = gz::gunzip(path, data, total)?;
            decode_owned(path, raw, skip, n, layout.dtype, layout.little_endian)
        }
        Encoding::Text => decode_text(path, data.get(skip..).unwrap_or_default(), n, layout.dtype),
    }
}

// ------------------------------------------------------------------- writer

fn nrrd_type_name(dtype: DataType) -> &'static str {
    match dtype {
        DataType::U8 => "uint8",
        DataType::I8 => "int8",
        DataType::U16 => "uint16",
        DataType::I16 => "int16",
        DataType::U32 => "uint32",
        DataType::I32 => "int32",
        DataType::U64 => "uint64",
        DataType::I64 => "int64",
        DataType::F32 => "float",
        DataType::F64 => "double",
    }
}

/// The NRRD header of a label volume (LPS space, gzip encoding).
fn label_header(volume: &LabelVolume, dtype: DataType) -> String {
    let d = volume.dims();
    let a = volume.geometry().affine();
    let column = |c: usize| format!("({},{},{})", a[0][c], a[1][c], a[2][c]);
    format!(
        "NRRD0004\n# Complete NRRD file format specification at:\n# http://teem.sourceforge.net/nrrd/format.html\n\
         type: {}\ndimension: 3\nspace: left-posterior-superior\nsizes: {} {} {}\n\
         space directions: {} {} {}\nkinds: domain domain domain\nendian: little\nencoding: gzip\n\
         space origin: ({},{},{})\n\n",
        nrrd_type_name(dtype),
        d.nx,
        d.ny,
        d.nz,
        column(0),
        column(1),
        column(2),
        a[0][3],
        a[1][3],
        a[2][3],
    )
}

/// Writes a label volume as `.nrrd` (gzip encoding, LPS space, smallest integer
/// type holding the label values).
pub fn write_labels(path: &Path, volume: &LabelVolume) -> Result<()> {
    let is_nrrd = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("nrrd"));
    if !is_nrrd {
        return Err(Error::input(
            path,
            "label volumes are written as .nrrd (attached, gzip-encoded)",
        ));
    }
    let dtype = smallest_label_type(volume.values());
    let data = gzip(&encode_labels(volume, dtype)).map_err(|e| Error::io(path, e))?;
    let mut bytes = label_header(volume, dtype).into_bytes();
    bytes.extend_from_slice(&data);
    atomic_write(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directions_with_none() {
        let d = parse_directions(Path::new("x"), "none (1,0,0) ( 0, 2 ,0)(0,0,3)").unwrap();
        assert_eq!(d.len(), 4);
        assert!(d[0].is_none());
        assert_eq!(d[2], Some(DVec3::new(0.0, 2.0, 0.0)));
        assert!(parse_directions(Path::new("x"), "(1,0) none").is_err());
        assert!(parse_directions(Path::new("x"), "(1,0,0").is_err());
    }

    #[test]
    fn axis_layouts() {
        let p = Path::new("x");
        assert_eq!(
            image_dims(p, &[1, 4, 5, 6], &[false, true, true, true]).unwrap(),
            vec![4, 5, 6]
        );
        assert!(image_dims(p, &[3, 4, 5, 6], &[false, true, true, true]).is_err());
        assert_eq!(
            image_dims(p, &[4, 5, 6, 7], &[true, true, true, false]).unwrap(),
            vec![4, 5, 6, 7]
        );
        assert_eq!(
            image_dims(p, &[4, 5, 7], &[true, true, false]).unwrap(),
            vec![4, 5, 1, 7]
        );
        assert!(image_dims(p, &[4, 5, 6], &[true, false, true]).is_err());
    }

    #[test]
    fn type_synonyms() {
        let p = Path::new("x");
        assert_eq!(parse_type(p, "unsigned  short").unwrap(), DataType::U16);
        assert_eq!(parse_type(p, "signed char").unwrap(), DataType::I8);
        assert_eq!(parse_type(p, "long long int").unwrap(), DataType::I64);
        assert!(parse_type(p, "block").is_err());
    }
}
