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

use flate2::bufread::{GzDecoder, ZlibDecoder};

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

/// Decompresses the whole gzip stream `data` (every member), verified as gzip
/// readers do: each member's CRC-32 and ISIZE must match its content, the file
/// must not end inside a member (its 8-byte trailer included), and nothing but
/// another member may follow one. Content beyond `limit` bytes is an error: the
/// header said how much voxel data there is.
pub fn gunzip(path: &Path, data: &[u8], limit: u64) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut rest = data;
    let mut member = 0;
    loop {
        let mut decoder = GzDecoder::new(rest);
        read_into(path, &mut decoder, &mut out, limit, "gzip", member)?;
        rest = decoder.into_inner();
        member += 1;
        if rest.is_empty() {
            return Ok(out);
        }
        if !is_gzip(rest) {
            return Err(Error::input(
                path,
                format!(
                    "corrupt gzip data: {} bytes of trailing junk after the gzip stream",
                    rest.len()
                ),
            ));
        }
    }
}

/// The first `n` bytes of the gzip stream `data`, not verified: for peeking at
/// a header whose whole file is read (and verified) by [`gunzip`] afterwards.
/// Only the first member is read: headers do not span members.
pub fn gunzip_prefix(path: &Path, data: &[u8], n: usize) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    GzDecoder::new(data)
        .take(n as u64)
        .read_to_end(&mut out)
        .map_err(|e| corrupt(path, "gzip", &e))?;
    Ok(out)
}

/// Decompresses the zlib stream `data`, its Adler-32 verified; content beyond
/// `limit` bytes is an error.
pub fn inflate_zlib(path: &Path, data: &[u8], limit: u64) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut decoder = ZlibDecoder::new(data);
    read_into(path, &mut decoder, &mut out, limit, "zlib", 0)?;
    let rest = decoder.into_inner();
    if !rest.is_empty() {
        return Err(Error::input(
            path,
            format!(
                "corrupt zlib data: {} bytes of trailing junk after the zlib stream",
                rest.len()
            ),
        ));
    }
    Ok(out)
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

/// `data` itself, or its gzip content (verified, at most `limit` bytes) if it
/// starts with the gzip magic.
pub fn maybe_gunzip(path: &Path, data: Vec<u8>, limit: u64) -> Result<Vec<u8>> {
    if is_gzip(&data) {
        gunzip(path, &data, limit)
    } else {
        Ok(data)
    }
}

/// Bytes added to the output buffer at a time: it grows with what the stream
/// really holds, never with what a header claims.
const CHUNK: usize = 1 << 20;

/// Appends the whole stream of `reader` to `out`, through to its end, so that
/// the decoder reaches and checks the stream's trailer. More than `limit`
/// bytes in all is an error; so is memory that cannot be had.
fn read_into(
    path: &Path,
    reader: &mut impl Read,
    out: &mut Vec<u8>,
    limit: u64,
    kind: &str,
    member: usize,
) -> Result<()> {
    loop {
        if out.len() as u64 > limit {
            return Err(Error::input(
                path,
                format!(
                    "the {kind} data decompresses to more than the {limit} bytes expected: \
                     the sizes or the sample type are wrong, or other data follows the voxels"
                ),
            ));
        }
        let start = out.len();
        crate::memory::fallible(|| out.try_reserve(CHUNK)).map_err(|_| {
            Error::input(
                path,
                format!(
                    "out of memory decompressing the {kind} data: {} MB read so far",
                    start >> 20
                ),
            )
        })?;
        out.resize(start + CHUNK, 0);
        let n = loop {
            match reader.read(&mut out[start..]) {
                Ok(n) => break n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    out.truncate(start);
                    return Err(corrupt_member(path, kind, &e, member));
                }
            }
        };
        out.truncate(start + n);
        if n == 0 {
            return Ok(());
        }
    }
}

fn corrupt_member(path: &Path, kind: &str, e: &std::io::Error, member: usize) -> Error {
    if member == 0 {
        corrupt(path, kind, e)
    } else {
        let hint = if e.kind() == std::io::ErrorKind::UnexpectedEof {
            " (the file is cut short)"
        } else {
            ""
        };
        Error::input(
            path,
            format!("corrupt {kind} data in member {}: {e}{hint}", member + 1),
        )
    }
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
        assert_eq!(gunzip_prefix(Path::new("x"), &z, 10).unwrap(), &data[..10]);
        let e = gunzip(Path::new("x"), &z, 10).unwrap_err().to_string();
        assert!(e.contains("more than the 10 bytes expected"), "{e}");
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
    fn members_are_concatenated_and_each_verified() {
        let mut z = gz(b"first ");
        z.extend(gz(b"second"));
        assert_eq!(gunzip(Path::new("m"), &z, 100).unwrap(), b"first second");
        let n = z.len();
        z[n - 6] ^= 1; // the second member's CRC
        let e = gunzip(Path::new("m"), &z, 100).unwrap_err().to_string();
        assert!(e.contains("member 2"), "{e}");
    }

    #[test]
    fn zlib_adler_and_trailing_junk_are_errors() {
        let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::none());
        e.write_all(b"some voxels").unwrap();
        let z = e.finish().unwrap();
        assert_eq!(
            inflate_zlib(Path::new("z"), &z, 100).unwrap(),
            b"some voxels"
        );
        let mut bad = z.clone();
        let n = bad.len();
        bad[n - 1] ^= 1;
        assert!(inflate_zlib(Path::new("z"), &bad, 100).is_err());
        let mut junk = z.clone();
        junk.push(0);
        let e = inflate_zlib(Path::new("z"), &junk, 100)
            .unwrap_err()
            .to_string();
        assert!(e.contains("trailing junk"), "{e}");
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
