//! 2-D inputs of DICONEX: PGM/PBM and PNG files, and slices of volumes.
//!
//! - **PGM/PBM** (`.pgm`, `.pbm`, `.pnm`): `P2`/`P5` (8 or 16 bit) and
//!   `P1`/`P4` (bitmaps, 1 = black); comments allowed in the header.
//! - **PNG** (`.png`): grayscale at 1–16 bits, grayscale with alpha (the alpha
//!   is ignored) and palette images (the palette index is the value: useful
//!   for label images); not interlaced. Color (RGB) images are refused with a
//!   message (convert them to grayscale first). Chunk checksums are verified.
//! - **Slices** of any volume septa reads: [`slice()`] along x, y or z.
//!
//! Pixel `(i, j)` is sample `i + width · j`: for image files `j` counts rows
//! from the top of the file. For a slice the two axes are the volume's other
//! axes in increasing order: `z = K` gives (x, y), `y = K` gives (x, z),
//! `x = K` gives (y, z), and [`Image2d::physical`] maps pixel coordinates back
//! to LPS millimetres.

use std::io::Read;
use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};

use crate::error::{Error, Result};
use crate::io::Image;
use crate::volume::Geometry;

/// A 2-D image of values.
#[derive(Clone, Debug)]
pub struct Image2d {
    pub width: usize,
    pub height: usize,
    /// Samples, x fastest.
    pub values: Vec<f64>,
    /// The file it came from.
    pub path: PathBuf,
    /// For slices of volumes: where the slice lies.
    pub slice: Option<Slice>,
    /// The sample type in the file ("uint8", "uint16", "palette", ...).
    pub dtype: String,
}

/// Where a slice lies in its volume.
#[derive(Clone, Copy, Debug)]
pub struct Slice {
    /// Axis normal to the slice (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// Voxel index along that axis.
    pub index: usize,
    /// The volume's geometry (voxel indices → LPS mm).
    pub geometry: Geometry,
}

impl Slice {
    /// The two in-plane axes (increasing).
    pub fn plane_axes(&self) -> (usize, usize) {
        crate::star::other_axes(self.axis)
    }

    /// Voxel index coordinates of a pixel-coordinate point.
    pub fn voxel(&self, p: DVec2) -> DVec3 {
        let (u, v) = self.plane_axes();
        let mut q = DVec3::ZERO;
        q[u] = p.x;
        q[v] = p.y;
        q[self.axis] = self.index as f64;
        q
    }
}

impl Image2d {
    /// LPS millimetres of a pixel-coordinate point, for slices of volumes.
    pub fn physical(&self, p: DVec2) -> Option<DVec3> {
        self.slice.map(|s| s.geometry.index_to_physical(s.voxel(p)))
    }

    /// The values as integer labels; an error naming the first pixel that
    /// holds something else.
    pub fn labels(&self) -> Result<Vec<i64>> {
        self.values
            .iter()
            .enumerate()
            .map(|(k, &x)| {
                if x.is_finite() && x.fract() == 0.0 && x.abs() <= 9.0e15 {
                    Ok(x as i64)
                } else {
                    Err(Error::input(
                        &self.path,
                        format!(
                            "non-integral label value {x} at pixel ({}, {}): a label image must hold whole numbers",
                            k % self.width,
                            k / self.width
                        ),
                    ))
                }
            })
            .collect()
    }
}

/// Image files this module reads, by extension.
pub fn is_image_file(path: &Path) -> bool {
    matches!(extension(path).as_str(), "pgm" | "pbm" | "pnm" | "png")
}

fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// Reads a PGM/PBM or PNG file (by extension).
pub fn read_image2d(path: &Path) -> Result<Image2d> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    match extension(path).as_str() {
        "pgm" | "pbm" | "pnm" => parse_pnm(&bytes, path),
        "png" => parse_png(&bytes, path),
        _ => Err(Error::input(
            path,
            "unknown 2-D image type: expected .pgm, .pbm, .pnm or .png",
        )),
    }
}

/// One slice of a volume: `axis` 0, 1, 2 = x, y, z; `index` a voxel index.
pub fn slice(image: &Image, axis: usize, index: usize) -> Result<Image2d> {
    let dims = image.dims3()?;
    let d = dims.to_array();
    if axis > 2 {
        return Err(Error::invalid(format!("slice axis {axis}: use x, y or z")));
    }
    if index >= d[axis] {
        return Err(Error::input(
            &image.path,
            format!(
                "has {} voxels along {}: slice {index} does not exist (0 to {})",
                d[axis],
                ["x", "y", "z"][axis],
                d[axis] - 1
            ),
        ));
    }
    let all = image.to_f64();
    let (u, v) = crate::star::other_axes(axis);
    let (w, h) = (d[u], d[v]);
    let mut values = Vec::with_capacity(w * h);
    for j in 0..h {
        for i in 0..w {
            let mut c = [0; 3];
            c[u] = i;
            c[v] = j;
            c[axis] = index;
            values.push(all[dims.index(c[0], c[1], c[2])]);
        }
    }
    Ok(Image2d {
        width: w,
        height: h,
        values,
        path: image.path.clone(),
        slice: Some(Slice {
            axis,
            index,
            geometry: image.geometry,
        }),
        dtype: image.samples.dtype().name().to_string(),
    })
}

// ------------------------------------------------------------------ PNM

/// Parses PGM (`P2`, `P5`) and PBM (`P1`, `P4`) data.
pub fn parse_pnm(bytes: &[u8], path: &Path) -> Result<Image2d> {
    let bad = |m: String| Error::input(path, m);
    if bytes.len() < 2 || bytes[0] != b'P' {
        return Err(bad(
            "not a PGM/PBM file (no `P1`, `P2`, `P4` or `P5` magic number)".into(),
        ));
    }
    let kind = bytes[1];
    if !matches!(kind, b'1' | b'2' | b'4' | b'5') {
        return Err(bad(format!(
            "PNM type P{} is not supported: septa reads grayscale PGM (P2, P5) and bitmaps (P1, P4)",
            kind as char
        )));
    }
    let mut pos = 2;
    let bitmap = matches!(kind, b'1' | b'4');
    let n_fields = if bitmap { 2 } else { 3 };
    let mut header = Vec::new();
    while header.len() < n_fields {
        header.push(next_token(bytes, &mut pos).ok_or_else(|| bad("truncated header".into()))?);
    }
    let num = |t: &[u8], what: &str| -> Result<usize> {
        std::str::from_utf8(t)
            .ok()
            .and_then(|s| s.parse::<usize>().ok())
            .ok_or_else(|| {
                bad(format!(
                    "bad {what} `{}` in the header",
                    String::from_utf8_lossy(t)
                ))
            })
    };
    let w = num(header[0], "width")?;
    let h = num(header[1], "height")?;
    let maxval = if bitmap {
        1
    } else {
        num(header[2], "maximum value")?
    };
    if w == 0 || h == 0 {
        return Err(bad(format!("an image of {w} × {h} pixels has no pixels")));
    }
    if !(1..=65535).contains(&maxval) {
        return Err(bad(format!("maximum value {maxval}: must be 1 to 65535")));
    }
    let n = w
        .checked_mul(h)
        .filter(|&n| n <= 1 << 31)
        .ok_or_else(|| bad(format!("{w} × {h} pixels is too large")))?;
    let mut values = Vec::with_capacity(n);
    match kind {
        b'1' | b'2' => {
            // ASCII samples (P1 digits may be run together)
            while values.len() < n {
                if bitmap {
                    skip_space(bytes, &mut pos);
                    match bytes.get(pos) {
                        Some(b'0') => values.push(0.0),
                        Some(b'1') => values.push(1.0),
                        _ => {
                            return Err(bad(format!(
                                "truncated or bad data: {} of {n} pixels",
                                values.len()
                            )));
                        }
                    }
                    pos += 1;
                } else {
                    let t = next_token(bytes, &mut pos).ok_or_else(|| {
                        bad(format!("truncated data: {} of {n} pixels", values.len()))
                    })?;
                    let x = num(t, "sample")?;
                    if x > maxval {
                        return Err(bad(format!(
                            "sample {x} exceeds the maximum value {maxval}"
                        )));
                    }
                    values.push(x as f64);
                }
            }
        }
        _ => {
            // one whitespace byte after the header, then binary samples
            pos += 1;
            let data = bytes.get(pos..).unwrap_or(&[]);
            if kind == b'4' {
                let row = w.div_ceil(8);
                if data.len() < row * h {
                    return Err(bad(format!(
                        "truncated data: {} of {} bytes",
                        data.len(),
                        row * h
                    )));
                }
                for j in 0..h {
                    for i in 0..w {
                        values.push((data[j * row + i / 8] >> (7 - i % 8) & 1) as f64);
                    }
                }
            } else {
                let size = if maxval > 255 { 2 } else { 1 };
                if data.len() < n * size {
                    return Err(bad(format!(
                        "truncated data: {} of {} bytes",
                        data.len(),
                        n * size
                    )));
                }
                for k in 0..n {
                    let x = if size == 2 {
                        u16::from_be_bytes([data[2 * k], data[2 * k + 1]]) as usize
                    } else {
                        data[k] as usize
                    };
                    if x > maxval {
                        return Err(bad(format!(
                            "sample {x} exceeds the maximum value {maxval}"
                        )));
                    }
                    values.push(x as f64);
                }
            }
        }
    }
    Ok(Image2d {
        width: w,
        height: h,
        values,
        path: path.to_path_buf(),
        slice: None,
        dtype: if bitmap {
            "bit".into()
        } else if maxval > 255 {
            "uint16".into()
        } else {
            "uint8".into()
        },
    })
}

fn skip_space(bytes: &[u8], pos: &mut usize) {
    while *pos < bytes.len() {
        if bytes[*pos] == b'#' {
            while *pos < bytes.len() && bytes[*pos] != b'\n' {
                *pos += 1;
            }
        } else if bytes[*pos].is_ascii_whitespace() {
            *pos += 1;
        } else {
            break;
        }
    }
}

fn next_token<'a>(bytes: &'a [u8], pos: &mut usize) -> Option<&'a [u8]> {
    skip_space(bytes, pos);
    let start = *pos;
    while *pos < bytes.len() && !bytes[*pos].is_ascii_whitespace() && bytes[*pos] != b'#' {
        *pos += 1;
    }
    (*pos > start).then(|| &bytes[start..*pos])
}

// ------------------------------------------------------------------ PNG

const PNG_SIGNATURE: [u8; 8] = [137, 80, 78, 71, 13, 10, 26, 10];

/// Parses a PNG file (grayscale, grayscale + alpha, palette; not interlaced).
pub fn parse_png(bytes: &[u8], path: &Path) -> Result<Image2d> {
    let bad = |m: String| Error::input(path, m);
    if bytes.len() < 8 || bytes[..8] != PNG_SIGNATURE {
        return Err(bad("not a PNG file (bad signature)".into()));
    }
    let mut pos = 8;
    let mut ihdr: Option<[u8; 13]> = None;
    let mut idat = Vec::new();
    let mut ended = false;
    while pos < bytes.len() {
        if pos + 8 > bytes.len() {
            return Err(bad("truncated chunk header".into()));
        }
        let len = u32::from_be_bytes(bytes[pos..pos + 4].try_into().expect("4 bytes")) as usize;
        let kind = &bytes[pos + 4..pos + 8];
        let end = pos
            .checked_add(12)
            .and_then(|x| x.checked_add(len))
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| {
                bad(format!(
                    "truncated chunk `{}`",
                    String::from_utf8_lossy(kind)
                ))
            })?;
        let data = &bytes[pos + 8..pos + 8 + len];
        let crc = u32::from_be_bytes(bytes[end - 4..end].try_into().expect("4 bytes"));
        let mut c = flate2::Crc::new();
        c.update(kind);
        c.update(data);
        if c.sum() != crc {
            return Err(bad(format!(
                "checksum mismatch in chunk `{}` (corrupt file)",
                String::from_utf8_lossy(kind)
            )));
        }
        match kind {
            b"IHDR" => {
                if len != 13 {
                    return Err(bad("bad IHDR chunk".into()));
                }
                ihdr = Some(data.try_into().expect("13 bytes"));
            }
            b"IDAT" => idat.extend_from_slice(data),
            b"IEND" => {
                ended = true;
                break;
            }
            _ => {}
        }
        pos = end;
    }
    let h = ihdr.ok_or_else(|| bad("no IHDR chunk".into()))?;
    if !ended {
        return Err(bad("no IEND chunk (truncated file)".into()));
    }
    let w = u32::from_be_bytes(h[0..4].try_into().expect("4")) as usize;
    let ht = u32::from_be_bytes(h[4..8].try_into().expect("4")) as usize;
    let (depth, color, interlace) = (h[8] as usize, h[9], h[12]);
    if w == 0 || ht == 0 {
        return Err(bad(format!("an image of {w} × {ht} pixels has no pixels")));
    }
    if w.checked_mul(ht).is_none_or(|n| n > 1 << 31) {
        return Err(bad(format!("{w} × {ht} pixels is too large")));
    }
    if interlace != 0 {
        return Err(bad(
            "interlaced PNG is not supported (save it without interlacing)".into(),
        ));
    }
    let (channels, dtype) = match (color, depth) {
        (0, 1 | 2 | 4 | 8 | 16) => (1, if depth == 16 { "uint16" } else { "uint8" }),
        (3, 1 | 2 | 4 | 8) => (1, "palette"),
        (4, 8 | 16) => (2, if depth == 16 { "uint16" } else { "uint8" }),
        (2 | 6, _) => {
            return Err(bad(
                "is a color (RGB) PNG: DICONEX needs one value per pixel; convert it to grayscale (or a palette/label image) first".into(),
            ));
        }
        _ => {
            return Err(bad(format!(
                "bad PNG color type {color} with bit depth {depth}"
            )));
        }
    };
    let bits = depth * channels;
    let stride = (w * bits).div_ceil(8);
    let bpp = bits.div_ceil(8).max(1);
    let mut raw = Vec::with_capacity((stride + 1) * ht);
    flate2::read::ZlibDecoder::new(&idat[..])
        .take(((stride + 1) * ht) as u64 + 1)
        .read_to_end(&mut raw)
        .map_err(|e| bad(format!("corrupt image data: {e}")))?;
    if raw.len() < (stride + 1) * ht {
        return Err(bad(format!(
            "truncated image data: {} of {} bytes",
            raw.len(),
            (stride + 1) * ht
        )));
    }
    let mut prev = vec![0u8; stride];
    let mut cur = vec![0u8; stride];
    let mut values = Vec::with_capacity(w * ht);
    for j in 0..ht {
        let line = &raw[j * (stride + 1)..(j + 1) * (stride + 1)];
        let filter = line[0];
        cur.copy_from_slice(&line[1..]);
        unfilter(filter, &mut cur, &prev, bpp).map_err(|m| bad(format!("row {j}: {m}")))?;
        for i in 0..w {
            let x = if depth < 8 {
                let bit = i * depth;
                (cur[bit / 8] >> (8 - depth - bit % 8)) & ((1 << depth) - 1) as u8
            } else if depth == 8 {
                cur[i * channels]
            } else {
                let k = 2 * i * channels;
                values.push(u16::from_be_bytes([cur[k], cur[k + 1]]) as f64);
                continue;
            };
            values.push(x as f64);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    Ok(Image2d {
        width: w,
        height: ht,
        values,
        path: path.to_path_buf(),
        slice: None,
        dtype: dtype.into(),
    })
}

fn unfilter(
    filter: u8,
    cur: &mut [u8],
    prev: &[u8],
    bpp: usize,
) -> std::result::Result<(), String> {
    match filter {
        0 => {}
        1 => {
            for k in bpp..cur.len() {
                cur[k] = cur[k].wrapping_add(cur[k - bpp]);
            }
        }
        2 => {
            for k in 0..cur.len() {
                cur[k] = cur[k].wrapping_add(prev[k]);
            }
        }
        3 => {
            for k in 0..cur.len() {
                let left = if k >= bpp { cur[k - bpp] as u16 } else { 0 };
                cur[k] = cur[k].wrapping_add(((left + prev[k] as u16) / 2) as u8);
            }
        }
        4 => {
            for k in 0..cur.len() {
                let a = if k >= bpp { cur[k - bpp] as i16 } else { 0 };
                let b = prev[k] as i16;
                let c = if k >= bpp { prev[k - bpp] as i16 } else { 0 };
                let p = a + b - c;
                let (pa, pb, pc) = ((p - a).abs(), (p - b).abs(), (p - c).abs());
                let pred = if pa <= pb && pa <= pc {
                    a
                } else if pb <= pc {
                    b
                } else {
                    c
                };
                cur[k] = cur[k].wrapping_add(pred as u8);
            }
        }
        f => return Err(format!("bad filter type {f}")),
    }
    Ok(())
}

/// Encodes 8- or 16-bit grayscale samples as a PNG (no filtering), for tests
/// and examples.
pub fn encode_png_gray(width: usize, height: usize, values: &[u16], sixteen: bool) -> Vec<u8> {
    use std::io::Write;
    let mut raw = Vec::new();
    for j in 0..height {
        raw.push(0);
        for i in 0..width {
            let x = values[i + width * j];
            if sixteen {
                raw.extend_from_slice(&x.to_be_bytes());
            } else {
                raw.push(x as u8);
            }
        }
    }
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    z.write_all(&raw).expect("in memory");
    let idat = z.finish().expect("in memory");
    let mut out = PNG_SIGNATURE.to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
        let mut c = flate2::Crc::new();
        c.update(kind);
        c.update(data);
        out.extend_from_slice(&c.sum().to_be_bytes());
    };
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&(width as u32).to_be_bytes());
    ihdr.extend_from_slice(&(height as u32).to_be_bytes());
    ihdr.extend_from_slice(&[if sixteen { 16 } else { 8 }, 0, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    chunk(b"IDAT", &idat);
    chunk(b"IEND", &[]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pgm_ascii_and_binary_agree() {
        let p = Path::new("x.pgm");
        let a = parse_pnm(b"P2\n# comment\n3 2\n255\n0 1 2\n3 4 255\n", p).unwrap();
        let mut b = b"P5 3 2 255\n".to_vec();
        b.extend_from_slice(&[0, 1, 2, 3, 4, 255]);
        let b = parse_pnm(&b, p).unwrap();
        assert_eq!((a.width, a.height), (3, 2));
        assert_eq!(a.values, b.values);
        assert_eq!(a.values, [0.0, 1.0, 2.0, 3.0, 4.0, 255.0]);
        let mut c = b"P5 2 1 1000\n".to_vec();
        c.extend_from_slice(&[3, 232, 0, 7]);
        assert_eq!(parse_pnm(&c, p).unwrap().values, [1000.0, 7.0]);
        let bits = parse_pnm(b"P1 3 2\n101\n0 1 0\n", p).unwrap();
        assert_eq!(bits.values, [1.0, 0.0, 1.0, 0.0, 1.0, 0.0]);
        let mut b4 = b"P4 3 2\n".to_vec();
        b4.extend_from_slice(&[0b1010_0000, 0b0100_0000]);
        assert_eq!(parse_pnm(&b4, p).unwrap().values, bits.values);
    }

    #[test]
    fn bad_pnm_is_an_error() {
        let p = Path::new("x.pgm");
        for bad in [
            &b""[..],
            b"P6 1 1 255\n\0\0\0",
            b"P2 2 2 255\n1 2 3",
            b"P2 2 2 255\n1 2 3 256",
            b"P2 0 2 255\n",
            b"P5 2 2 255\n\0",
            b"P2 x 2 255\n",
            b"P2 2 2 70000\n",
        ] {
            assert!(
                parse_pnm(bad, p).is_err(),
                "{:?}",
                String::from_utf8_lossy(bad)
            );
        }
    }

    #[test]
    fn png_round_trip_and_corruption() {
        let p = Path::new("x.png");
        let v: Vec<u16> = (0..35).map(|k| (k * 37 % 251) as u16).collect();
        let img = parse_png(&encode_png_gray(7, 5, &v, false), p).unwrap();
        assert_eq!((img.width, img.height), (7, 5));
        assert_eq!(img.values, v.iter().map(|&x| x as f64).collect::<Vec<_>>());
        let v16: Vec<u16> = (0..35).map(|k| (k * 1871) as u16).collect();
        let img = parse_png(&encode_png_gray(7, 5, &v16, true), p).unwrap();
        assert_eq!(
            img.values,
            v16.iter().map(|&x| x as f64).collect::<Vec<_>>()
        );
        let good = encode_png_gray(7, 5, &v, false);
        for cut in [4, 20, 40, good.len() - 3] {
            assert!(parse_png(&good[..cut], p).is_err(), "cut at {cut}");
        }
        for k in [9, 20, 33, 45] {
            let mut b = good.clone();
            b[k] ^= 0x40;
            assert!(parse_png(&b, p).is_err(), "flip at {k}");
        }
    }

    #[test]
    fn png_filters_are_undone() {
        // a 3 × 2 8-bit image with Sub on row 0 and Paeth on row 1
        let rows = [[1u8, 10, 20, 30], [4, 5, 5, 5]];
        let mut cur = rows[0][1..].to_vec();
        unfilter(rows[0][0], &mut cur, &[0, 0, 0], 1).unwrap();
        assert_eq!(cur, [10, 30, 60]);
        let prev = cur.clone();
        let mut cur = rows[1][1..].to_vec();
        unfilter(rows[1][0], &mut cur, &prev, 1).unwrap();
        // Paeth predictors: 10 (b), then 30 (b: p = 15 + 30 − 10), then 60 (b)
        assert_eq!(cur, [15, 35, 65]);
        assert!(unfilter(9, &mut cur, &prev, 1).is_err());
    }
}
