//! Decompression for the volume readers: gzip (`.nii.gz`, NRRD `encoding: gzip`)
//! and zlib (MetaImage `CompressedData = True`), recognised by their magic bytes
//! rather than by the file name.
//!
//! Every function takes an upper bound on the output it will produce, so that a
//! header that lies about the data size cannot make a reader allocate more than
//! the file could ever hold, and turns corrupt streams into an error naming the
//! file ("corrupt gzip data: …").

use std::io::Read;
use std::path::Path;

use flate2::read::{MultiGzDecoder, ZlibDecoder};

use crate::error::{Error, Result};

/// The largest ratio of decompressed to compressed size that DEFLATE can reach:
/// a 258-byte match costs at least 2 bits (length and distance codes of one bit
/// each), so one compressed byte yields at most 258 · 8 / 2 = 1032 bytes.
const MAX_DEFLATE_RATIO: u64 = 1032;

/// True when `bytes` starts with the gzip magic (`1f 8b`).
pub fn is_gzip(bytes: &[u8]) -> bool {
    bytes.len() >= 2 && bytes[0] == 0x1f && bytes[1] == 0x8b
}

/// True when `bytes` starts with a valid zlib header (deflate method, check bits).
pub fn is_zlib(bytes: &[u8]) -> bool {
    if bytes.len() < 2 {
        return false;
    }
    let (cmf, flg) = (bytes[0], bytes[1]);
    cmf & 0x0f == 8 && cmf >> 4 <= 7 && (u16::from(cmf) << 8 | u16::from(flg)) % 31 == 0
}

/// The most bytes `compressed_len` bytes of DEFLATE data can decompress to.
pub fn max_inflated_len(compressed_len: usize) -> u64 {
    (compressed_len as u64)
        .saturating_mul(MAX_DEFLATE_RATIO)
        .saturating_add(1024)
}

/// Decompresses at most `limit` bytes of the gzip stream `data` (all members).
/// Output beyond `limit` is not read; a corrupt or cut stream is an error.
pub fn gunzip(path: &Path, data: &[u8], limit: u64) -> Result<Vec<u8>> {
    read_limited(path, MultiGzDecoder::new(data), data.len(), limit, "gzip")
}

/// Decompresses at most `limit` bytes of the zlib stream `data`.
pub fn inflate_zlib(path: &Path, data: &[u8], limit: u64) -> Result<Vec<u8>> {
    read_limited(path, ZlibDecoder::new(data), data.len(), limit, "zlib")
}

/// Decompresses gzip or zlib data, whichever its magic says (for formats whose
/// writers disagree on the container, e.g. MetaImage).
pub fn inflate_any(path: &Path, data: &[u8], limit: u64) -> Result<Vec<u8>> {
    if is_gzip(data) {
        gunzip(path, data, limit)
    } else {
        inflate_zlib(path, data, limit)
    }
}

/// `data` itself, or its gzip content (at most `limit` bytes) if it starts with
/// the gzip magic.
pub fn maybe_gunzip(path: &Path, data: Vec<u8>, limit: u64) -> Result<Vec<u8>> {
    if is_gzip(&data) {
        gunzip(path, &data, limit)
    } else {
        Ok(data)
    }
}

fn read_limited(
    path: &Path,
    reader: impl Read,
    compressed_len: usize,
    limit: u64,
    kind: &str,
) -> Result<Vec<u8>> {
    let guess = limit.min(max_inflated_len(compressed_len)).min(1 << 32);
    let mut out = Vec::with_capacity(usize::try_from(guess).unwrap_or(0));
    reader
        .take(limit)
        .read_to_end(&mut out)
        .map_err(|e| corrupt(path, kind, &e))?;
    Ok(out)
}

fn corrupt(path: &Path, kind: &str, e: &std::io::Error) -> Error {
    let hint = if e.kind() == std::io::ErrorKind::UnexpectedEof {
        " (the file is cut short)"
    } else {
        ""
    };
    Error::input(path, format!("corrupt {kind} data: {e}{hint}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn gz(bytes: &[u8]) -> Vec<u8> {
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        e.write_all(bytes).unwrap();
        e.finish().unwrap()
    }

    #[test]
    fn round_trip_and_limit() {
        let data: Vec<u8> = (0..10_000u32).map(|i| (i % 7) as u8).collect();
        let z = gz(&data);
        assert!(is_gzip(&z));
        assert_eq!(gunzip(Path::new("x"), &z, u64::MAX).unwrap(), data);
        assert_eq!(gunzip(Path::new("x"), &z, 10).unwrap(), &data[..10]);
        assert_eq!(maybe_gunzip(Path::new("x"), data.clone(), 5).unwrap(), data);
    }

    #[test]
    fn corrupt_stream_is_an_error() {
        let data = vec![3u8; 5000];
        let mut z = gz(&data);
        let n = z.len();
        z.truncate(n / 2);
        let e = gunzip(Path::new("f.gz"), &z, u64::MAX)
            .unwrap_err()
            .to_string();
        assert!(e.contains("corrupt gzip data") && e.contains("f.gz"), "{e}");
        let mut z = gz(&data);
        z[12] ^= 0xff;
        z[13] ^= 0x5a;
        assert!(gunzip(Path::new("f.gz"), &z, u64::MAX).is_err());
    }

    #[test]
    fn zlib_detection() {
        let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        e.write_all(b"hello hello hello").unwrap();
        let z = e.finish().unwrap();
        assert!(is_zlib(&z) && !is_gzip(&z));
        assert_eq!(
            inflate_any(Path::new("x"), &z, 100).unwrap(),
            b"hello hello hello"
        );
    }
}
