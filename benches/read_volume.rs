//! Time to read a 256³ label volume (uint8) from `.nii` and `.nii.gz` with
//! `read_label_volume`: header parsing, gunzip, sample decoding and the
//! conversion to dense label ids.
//!
//! Run with `cargo bench --bench read_volume`.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use septa::io::{ReadOptions, read_label_volume, write_label_volume};
use septa::volume::{Dims, Geometry, LabelVolume};

const N: usize = 256;

/// Nested spheres of 6 labels: realistic runs of equal labels for gzip.
fn phantom() -> LabelVolume {
    let dims = Dims::new(N, N, N).unwrap();
    let c = N as f64 / 2.0;
    let mut values = Vec::with_capacity(dims.len());
    for z in 0..N {
        for y in 0..N {
            for x in 0..N {
                let r = ((x as f64 - c).powi(2) + (y as f64 - c).powi(2) + (z as f64 - c).powi(2))
                    .sqrt();
                values.push(((c - r).max(0.0) / 22.0).ceil().min(5.0) as i64);
            }
        }
    }
    let geometry = Geometry::new(
        [0.9, 0.9, 1.2],
        [-115.0, -115.0, -150.0],
        Geometry::IDENTITY_DIRECTION,
    )
    .unwrap();
    LabelVolume::from_values(dims, &values, geometry).unwrap()
}

fn bench_read(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let volume = phantom();
    let mut group = c.benchmark_group("read_label_volume_256^3_uint8");
    group.sample_size(20);
    for name in ["v.nii", "v.nii.gz"] {
        let path = dir.path().join(name);
        write_label_volume(&path, &volume).unwrap();
        let size = std::fs::metadata(&path).unwrap().len();
        eprintln!("{name}: {size} bytes");
        group.bench_function(name, |b| b.iter(|| read(black_box(&path))));
    }
    group.finish();
}

fn read(path: &Path) -> LabelVolume {
    read_label_volume(path, &ReadOptions::default()).unwrap()
}

criterion_group!(benches, bench_read);
criterion_main!(benches);
