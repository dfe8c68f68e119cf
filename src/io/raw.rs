//! Headerless ("raw") volumes, and the sample-decoding helpers every reader
//! shares: checked byte counts, slicing the voxel data out of a file with a
//! "truncated" error when it is short, text (ASCII) samples, and the shape rules
//! of [`Image::dims`].
//!
//! A raw file is described entirely by [`ReadOptions`]: extents, sample type,
//! spacing, byte order and a number of header bytes to skip. Its length must be
//! exactly header + voxels × sample size: anything else means the options are
//! wrong, and the error says what was expected and what was found.

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::{DataType, Image, ReadOptions, Samples, gz, read_file};
use crate::volume::Geometry;

/// Reads a raw file (gzip-compressed raw files are recognised by their magic).
pub fn read(path: &Path, opts: &ReadOptions) -> Result<Image> {
    let (Some(dims), Some(dtype)) = (opts.dims, opts.dtype) else {
        return Err(Error::input(
            path,
            "a raw file needs its extents and sample type (--dims and --dtype)",
        ));
    };
    check_extents(path, &dims)?;
    let header = usize::try_from(opts.header_bytes).map_err(|_| {
        Error::input(
            path,
            format!("header size {} is too large", opts.header_bytes),
        )
    })?;
    let data_bytes = byte_count(path, &dims, dtype)?;
    let expected = header
        .checked_add(data_bytes)
        .ok_or_else(|| Error::input(path, "header plus data size overflows"))?;
    let data = gz::maybe_gunzip(path, read_file(path)?, expected as u64)?;
    if data.len() != expected {
        return Err(Error::input(
            path,
            format!(
                "expected {expected} bytes (header {header} + {} voxels × {} bytes of {}), found {}: check --dims, --dtype and --header-bytes",
                data_bytes / dtype.size(),
                dtype.size(),
                dtype.name(),
                data.len()
            ),
        ));
    }
    let samples = Samples::decode(dtype, &data[header..], !opts.big_endian);
    let spacing = opts.spacing.unwrap_or([1.0; 3]);
    let geometry = Geometry::new(spacing, [0.0; 3], Geometry::IDENTITY_DIRECTION)
        .map_err(|e| in_file(path, e))?;
    Ok(Image {
        dims: dims.to_vec(),
        samples,
        geometry,
        time_step: None,
        path: path.to_path_buf(),
        sources: vec![path.to_path_buf()],
    })
}

/// Attaches the file name to an error that lacks one (e.g. from [`Geometry`]).
pub(crate) fn in_file(path: &Path, e: Error) -> Error {
    match e {
        Error::Invalid(m) => Error::input(path, m),
        other => other,
    }
}

/// Checks that every extent is at least 1.
pub(crate) fn check_extents(path: &Path, dims: &[usize]) -> Result<()> {
    match dims.iter().position(|&n| n == 0) {
        Some(axis) => Err(Error::input(
            path,
            format!("dimension {axis} is 0 (extents {dims:?}): every extent must be at least 1"),
        )),
        None => Ok(()),
    }
}

/// Number of voxels, checked against overflow.
pub(crate) fn voxel_count(path: &Path, dims: &[usize]) -> Result<usize> {
    dims.iter()
        .try_fold(1usize, |acc, &n| acc.checked_mul(n))
        .ok_or_else(|| {
            Error::input(
                path,
                format!("dimensions {dims:?} overflow: the voxel count does not fit in memory"),
            )
        })
}

/// Bytes of voxel data for `dims` samples of `dtype`, checked against overflow.
pub(crate) fn byte_count(path: &Path, dims: &[usize], dtype: DataType) -> Result<usize> {
    voxel_count(path, dims)?.checked_mul(dtype.size()).ok_or_else(|| {
        Error::input(
            path,
            format!(
                "dimensions {dims:?} × {} bytes per sample overflow: the data size does not fit in memory",
                dtype.size()
            ),
        )
    })
}

/// Pads `dims` with 1s to 3 entries and removes trailing extents of 1 beyond the
/// third, the shape rule of [`Image::dims`].
pub(crate) fn image_shape(mut dims: Vec<usize>) -> Vec<usize> {
    while dims.len() < 3 {
        dims.push(1);
    }
    while dims.len() > 3 && dims.last() == Some(&1) {
        dims.pop();
    }
    dims
}

/// Decodes `n` samples of `dtype` starting at `offset` in `data`; a short file is
/// a "truncated" error naming the expected and available byte counts.
pub(crate) fn decode_at(
    path: &Path,
    data: &[u8],
    offset: usize,
    n: usize,
    dtype: DataType,
    little_endian: bool,
) -> Result<Samples> {
    let needed = n
        .checked_mul(dtype.size())
        .ok_or_else(|| Error::input(path, format!("{n} samples of {} overflow", dtype.name())))?;
    let available = data.len().saturating_sub(offset);
    if available < needed {
        return Err(truncated(
            path,
            needed as u64,
            offset as u64,
            available as u64,
        ));
    }
    Ok(Samples::decode(
        dtype,
        &data[offset..offset + needed],
        little_endian,
    ))
}

/// Like [`decode_at`] for data the caller owns: uint8 samples reuse the buffer
/// instead of copying it.
pub(crate) fn decode_owned(
    path: &Path,
    mut data: Vec<u8>,
    offset: usize,
    n: usize,
    dtype: DataType,
    little_endian: bool,
) -> Result<Samples> {
    if dtype != DataType::U8 {
        return decode_at(path, &data, offset, n, dtype, little_endian);
    }
    let available = data.len().saturating_sub(offset);
    if available < n {
        return Err(truncated(path, n as u64, offset as u64, available as u64));
    }
    data.truncate(offset + n);
    data.drain(..offset);
    Ok(Samples::U8(data))
}

/// The error for voxel data shorter than the header says.
pub(crate) fn truncated(path: &Path, needed: u64, offset: u64, found: u64) -> Error {
    Error::input(
        path,
        format!(
            "truncated: expected {needed} bytes of voxel data after offset {offset}, found {found}"
        ),
    )
}

/// Parses `n` whitespace-separated numbers of type `dtype` (NRRD `encoding:
/// text`, MetaImage `BinaryData = False`).
pub(crate) fn decode_text(path: &Path, text: &[u8], n: usize, dtype: DataType) -> Result<Samples> {
    let text = std::str::from_utf8(text)
        .map_err(|_| Error::input(path, "text voxel data is not valid ASCII"))?;
    let mut tokens = text
        .split(|c: char| c.is_ascii_whitespace() || c == ',')
        .filter(|t| !t.is_empty());
    macro_rules! parse {
        ($t:ty, $var:ident) => {{
            let mut v: Vec<$t> = Vec::with_capacity(n.min(text.len() / 2 + 1));
            for i in 0..n {
                let Some(tok) = tokens.next() else {
                    return Err(Error::input(
                        path,
                        format!("truncated: expected {n} text samples, found {i}"),
                    ));
                };
                let x = tok.parse::<$t>().map_err(|_| {
                    Error::input(
                        path,
                        format!("text sample {i} is {tok:?}, not a valid {}", dtype.name()),
                    )
                })?;
                v.push(x);
            }
            Samples::$var(v)
        }};
    }
    Ok(match dtype {
        DataType::U8 => parse!(u8, U8),
        DataType::I8 => parse!(i8, I8),
        DataType::U16 => parse!(u16, U16),
        DataType::I16 => parse!(i16, I16),
        DataType::U32 => parse!(u32, U32),
        DataType::I32 => parse!(i32, I32),
        DataType::U64 => parse!(u64, U64),
        DataType::I64 => parse!(i64, I64),
        DataType::F32 => parse!(f32, F32),
        DataType::F64 => parse!(f64, F64),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shape_rule() {
        assert_eq!(image_shape(vec![4, 5]), vec![4, 5, 1]);
        assert_eq!(image_shape(vec![4, 5, 6, 1, 1]), vec![4, 5, 6]);
        assert_eq!(image_shape(vec![4, 5, 6, 2, 1]), vec![4, 5, 6, 2]);
        assert_eq!(image_shape(vec![4, 1, 1, 1]), vec![4, 1, 1]);
    }

    #[test]
    fn text_samples() {
        let p = Path::new("t");
        assert_eq!(
            decode_text(p, b" 1 2\n3 ", 3, DataType::I16).unwrap(),
            Samples::I16(vec![1, 2, 3])
        );
        assert!(decode_text(p, b"1 2", 3, DataType::U8).is_err());
        assert!(decode_text(p, b"1 300 2", 3, DataType::U8).is_err());
        assert_eq!(
            decode_text(p, b"1.5 2", 2, DataType::F64).unwrap(),
            Samples::F64(vec![1.5, 2.0])
        );
    }

    #[test]
    fn overflow_is_an_error() {
        let p = Path::new("o");
        assert!(byte_count(p, &[usize::MAX / 2, 3], DataType::U8).is_err());
        assert!(byte_count(p, &[usize::MAX / 2 + 1], DataType::U16).is_err());
        assert_eq!(byte_count(p, &[2, 3, 4], DataType::F32).unwrap(), 96);
    }
}
