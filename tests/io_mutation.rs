//! Mutation test of the volume readers: small valid files of every format are
//! damaged thousands of times (byte flips, interesting values, insertions,
//! deletions, truncations, numbers replaced by huge or negative ones; mostly in
//! the header) and read with `read_image` + `into_label_volume`. Errors are
//! fine; a panic fails the test.
//!
//! A counting global allocator records the largest single allocation: a header
//! that claims far more voxels than the file holds must be rejected by comparing
//! sizes with the file length, never by trying to allocate them.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use septa::io::{ReadOptions, read_image, write_label_volume};
use septa::volume::{Dims, Geometry, LabelVolume};

/// The system allocator, remembering the largest request.
struct PeakAlloc;

static LARGEST: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for PeakAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: PeakAlloc = PeakAlloc;

/// No read of these small files may allocate more than this at once.
const ALLOCATION_LIMIT: usize = 32 << 20;

/// Mutated cases per format.
const CASES: usize = 1500;

/// xorshift64*: a tiny fixed-seed generator (no rand crate).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn chance(&mut self, percent: u64) -> bool {
        self.next() % 100 < percent
    }
}

/// One valid file (plus its detached data file, if any) to mutate.
struct Base {
    name: &'static str,
    main: Vec<u8>,
    companion: Option<(&'static str, Vec<u8>)>,
    /// Leading bytes of `main` that are header: most mutations land there.
    header_len: usize,
    /// `main` is the gzip of these bytes: half the cases mutate them instead.
    inner: Option<(Vec<u8>, usize)>,
    /// The header is text (numbers may be swapped for extreme ones).
    text: bool,
}

const DIMS: [usize; 3] = [6, 5, 4];

fn labels() -> Vec<u8> {
    (0..DIMS.iter().product::<usize>())
        .map(|i| ((i * 7) % 5) as u8)
        .collect()
}

fn volume() -> LabelVolume {
    let dims = Dims::new(DIMS[0], DIMS[1], DIMS[2]).unwrap();
    let values: Vec<i64> = labels().iter().map(|&v| i64::from(v) * 3 - 2).collect();
    let (s, c) = 0.3f64.sin_cos();
    let g = Geometry::new(
        [0.5, 1.5, 2.0],
        [3.0, -4.0, 5.0],
        [[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]],
    )
    .unwrap();
    LabelVolume::from_values(dims, &values, g).unwrap()
}

fn written(dir: &Path, name: &str) -> Vec<u8> {
    let path = dir.join(name);
    write_label_volume(&path, &volume()).unwrap();
    std::fs::read(path).unwrap()
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn zlib(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

const MHD_FIELDS: &str = "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\nTransformMatrix = 0.8 0.6 0 -0.6 0.8 0 0 0 1\nOffset = 1 2 3\nElementSpacing = 0.5 1.5 2\nDimSize = 6 5 4\nElementType = MET_SHORT\n";

fn shorts() -> Vec<u8> {
    labels()
        .iter()
        .flat_map(|&v| (i16::from(v) - 1).to_le_bytes())
        .collect()
}

fn bases(dir: &Path) -> Vec<Base> {
    let nii = written(dir, "w.nii");
    let nrrd_gz = written(dir, "w.nrrd");
    let nrrd_gz_header = nrrd_gz.windows(2).position(|w| w == b"\n\n").unwrap() + 2;
    let nrrd_header = "NRRD0004\ntype: short\ndimension: 3\nspace: right-anterior-superior\nsizes: 6 5 4\nspace directions: (0.5,0,0) (0,1.5,0) (0,0,2)\nspace origin: (1,2,3)\nendian: little\nencoding: raw\n\n";
    let nhdr = "NRRD0004\ntype: short\ndimension: 4\nsizes: 1 6 5 4\nspace: LPS\nspace directions: none (0.5,0,0) (0,1.5,0) (0,0,2)\nkinds: scalar domain domain domain\nendian: little\nencoding: raw\nbyte skip: 0\ndata file: d.raw\n";
    let mha = format!("{MHD_FIELDS}ElementDataFile = LOCAL\n");
    let mha_z = format!("{MHD_FIELDS}CompressedData = True\nElementDataFile = LOCAL\n");
    let mhd = format!("{MHD_FIELDS}HeaderSize = 0\nElementDataFile = d.raw\n");
    vec![
        Base {
            name: "m.nii",
            header_len: 352,
            main: nii.clone(),
            companion: None,
            inner: None,
            text: false,
        },
        Base {
            name: "m.nii.gz",
            header_len: 64,
            main: gzip(&nii),
            companion: None,
            inner: Some((nii, 352)),
            text: false,
        },
        Base {
            name: "m.nrrd",
            header_len: nrrd_header.len(),
            main: [nrrd_header.as_bytes(), &shorts()].concat(),
            companion: None,
            inner: None,
            text: true,
        },
        Base {
            name: "z.nrrd",
            header_len: nrrd_gz_header,
            main: nrrd_gz,
            companion: None,
            inner: None,
            text: true,
        },
        Base {
            name: "m.nhdr",
            header_len: nhdr.len(),
            main: nhdr.as_bytes().to_vec(),
            companion: Some(("d.raw", shorts())),
            inner: None,
            text: true,
        },
        Base {
            name: "m.mha",
            header_len: mha.len(),
            main: [mha.as_bytes(), &shorts()].concat(),
            companion: None,
            inner: None,
            text: true,
        },
        Base {
            name: "z.mha",
            header_len: mha_z.len(),
            main: [mha_z.as_bytes(), &zlib(&shorts())].concat(),
            companion: None,
            inner: None,
            text: true,
        },
        Base {
            name: "m.mhd",
            header_len: mhd.len(),
            main: mhd.into_bytes(),
            companion: Some(("d.raw", shorts())),
            inner: None,
            text: true,
        },
    ]
}

/// Values that make header fields interesting: zero, −1, extremes, NaN, ∞.
const INTERESTING_I16: [i16; 8] = [0, -1, 1, 2, 7, 8, 32_767, -32_768];
const INTERESTING_F32: [f32; 7] = [0.0, -1.0, f32::NAN, f32::INFINITY, 1e30, -1e-30, 3.0e9];
const INTERESTING_TEXT: [&str; 10] = [
    "0",
    "-1",
    "99999999999999999999",
    "1000000",
    "nan",
    "1e308",
    "-0",
    "",
    "none",
    "4294967296",
];

/// A position: in the header with 85 % probability.
fn position(rng: &mut Rng, len: usize, header_len: usize) -> usize {
    if rng.chance(85) && header_len > 0 {
        rng.below(header_len.min(len))
    } else {
        rng.below(len)
    }
}

/// Applies 1 to 4 random mutations.
fn mutate(bytes: &mut Vec<u8>, header_len: usize, text: bool, rng: &mut Rng) {
    for _ in 0..1 + rng.below(4) {
        let len = bytes.len();
        if len == 0 {
            return;
        }
        let at = position(rng, len, header_len);
        match rng.below(9) {
            0 | 1 => bytes[at] ^= 1 << rng.below(8),
            2 => bytes[at] = rng.next() as u8,
            3 => bytes.insert(at, rng.next() as u8),
            4 => {
                let n = (1 + rng.below(8)).min(len - at);
                bytes.drain(at..at + n);
            }
            5 => bytes.truncate(rng.below(len)),
            6 | 7 if text => replace_number(bytes, at, rng),
            6 => {
                let at = at & !1;
                let v = INTERESTING_I16[rng.below(INTERESTING_I16.len())].to_le_bytes();
                if at + 2 <= len {
                    bytes[at..at + 2].copy_from_slice(&v);
                }
            }
            _ => {
                let at = at & !3;
                let v = INTERESTING_F32[rng.below(INTERESTING_F32.len())].to_le_bytes();
                if at + 4 <= len {
                    bytes[at..at + 4].copy_from_slice(&v);
                }
            }
        }
    }
}

/// Replaces the run of digits at or after `at` by an interesting token.
fn replace_number(bytes: &mut Vec<u8>, at: usize, rng: &mut Rng) {
    let Some(start) = (at..bytes.len()).find(|&i| bytes[i].is_ascii_digit()) else {
        return;
    };
    let end = (start..bytes.len())
        .find(|&i| !bytes[i].is_ascii_digit())
        .unwrap_or(bytes.len());
    let token = INTERESTING_TEXT[rng.below(INTERESTING_TEXT.len())];
    bytes.splice(start..end, token.bytes());
}

/// Reads `path` as an image and a label volume; only panics matter. True when
/// both succeed.
fn read_all(path: &Path) -> bool {
    match read_image(path, &ReadOptions::default()) {
        Ok(img) => {
            assert!(img.dims.len() >= 3);
            img.into_label_volume().is_ok()
        }
        Err(_) => false,
    }
}

/// Writes a new file in place of the old one. (Truncating and rewriting makes
/// ext4 flush the file on close, which costs milliseconds per case on a busy
/// disk; a fresh file does not.)
fn replace_file(path: &Path, bytes: &[u8]) {
    let _ = std::fs::remove_file(path);
    std::fs::write(path, bytes).unwrap();
}

fn run_mutations(base: &Base, dir: &Path, seed: u64) {
    let mut rng = Rng(seed);
    let path = dir.join(base.name);
    let mut read_ok = 0;
    for case in 0..CASES {
        let main = match &base.inner {
            Some((inner, inner_header)) if rng.chance(50) => {
                let mut b = inner.clone();
                mutate(&mut b, *inner_header, base.text, &mut rng);
                gzip(&b)
            }
            _ => {
                let mut b = base.main.clone();
                mutate(&mut b, base.header_len, base.text, &mut rng);
                b
            }
        };
        replace_file(&path, &main);
        if let Some((name, data)) = &base.companion {
            let mut data = data.clone();
            if rng.chance(20) {
                let n = rng.below(data.len() + 1);
                data.truncate(n);
            }
            replace_file(&dir.join(name), &data);
        }
        read_ok += usize::from(read_all(&path));
        let largest = LARGEST.load(Ordering::Relaxed);
        assert!(
            largest <= ALLOCATION_LIMIT,
            "{} case {case}: an allocation of {largest} bytes",
            base.name
        );
    }
    // The mutations must neither all be harmless nor all be fatal.
    eprintln!(
        "{}: {read_ok} of {CASES} mutated files still read",
        base.name
    );
    assert!(
        read_ok > 0 && read_ok < CASES,
        "{}: {read_ok} of {CASES} read",
        base.name
    );
}

#[test]
fn valid_bases_read() {
    let dir = tempfile::tempdir().unwrap();
    for base in bases(dir.path()) {
        let path = dir.path().join(base.name);
        std::fs::write(&path, &base.main).unwrap();
        if let Some((name, data)) = &base.companion {
            std::fs::write(dir.path().join(name), data).unwrap();
        }
        let v = read_image(&path, &ReadOptions::default())
            .and_then(|i| i.into_label_volume())
            .unwrap_or_else(|e| panic!("{}: {e}", base.name));
        assert_eq!(v.dims().to_array(), DIMS, "{}", base.name);
        assert_eq!(v.label_count(), 5, "{}", base.name);
    }
}

macro_rules! mutation_test {
    ($name:ident, $index:expr, $seed:expr) => {
        #[test]
        fn $name() {
            let dir = tempfile::tempdir().unwrap();
            let bases = bases(dir.path());
            run_mutations(&bases[$index], dir.path(), $seed);
        }
    };
}

mutation_test!(mutate_nii, 0, 0x9e37_79b9_7f4a_7c15);
mutation_test!(mutate_nii_gz, 1, 0xd1b5_4a32_d192_ed03);
mutation_test!(mutate_nrrd_raw, 2, 0x8cb9_2ba7_2f3d_8dd7);
mutation_test!(mutate_nrrd_gzip, 3, 0xabc9_8388_fb8f_ac03);
mutation_test!(mutate_nhdr, 4, 0x2545_f491_4f6c_dd1d);
mutation_test!(mutate_mha, 5, 0x5851_f42d_4c95_7f2d);
mutation_test!(mutate_mha_zlib, 6, 0x1405_7b7e_f767_814f);
mutation_test!(mutate_mhd, 7, 0xa076_1d64_78bd_642f);

/// Headers claiming 10¹² voxels (10000³) in every format: an error, and no
/// allocation of that size.
#[test]
fn huge_claims_error_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    for base in bases(dir.path()) {
        let huge = |b: &[u8]| -> Vec<u8> {
            if base.text {
                let s = String::from_utf8_lossy(b).into_owned();
                s.replace("sizes: 6 5 4", "sizes: 10000 10000 10000")
                    .replace("sizes: 1 6 5 4", "sizes: 1 10000 10000 10000")
                    .replace("DimSize = 6 5 4", "DimSize = 10000 10000 10000")
                    .into_bytes()
            } else {
                let mut b = b.to_vec();
                for i in 1..=3 {
                    b[40 + 2 * i..42 + 2 * i].copy_from_slice(&10_000i16.to_le_bytes());
                }
                b
            }
        };
        let main = match &base.inner {
            Some((inner, _)) => gzip(&huge(inner)),
            None if base.text => {
                let header = huge(&base.main[..base.header_len]);
                [&header[..], &base.main[base.header_len..]].concat()
            }
            None => huge(&base.main),
        };
        let path = dir.path().join(base.name);
        std::fs::write(&path, &main).unwrap();
        if let Some((name, data)) = &base.companion {
            std::fs::write(dir.path().join(name), data).unwrap();
        }
        let err = read_image(&path, &ReadOptions::default())
            .err()
            .unwrap_or_else(|| panic!("{}: a 10^12-voxel claim was accepted", base.name));
        assert!(
            err.to_string().contains("truncated"),
            "{}: {err}",
            base.name
        );
        assert!(
            LARGEST.load(Ordering::Relaxed) <= ALLOCATION_LIMIT,
            "{}",
            base.name
        );
    }
}
