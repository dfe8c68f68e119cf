//! Smoothing + remeshing (`septa::remesh::remesh`) of the extraction of the
//! 128³ heart phantom with `--noise 0.01`, at L = 2 voxels (2 mm), with the
//! default parameters. The extraction is done once, outside the timing.
//!
//! Run with `cargo bench --bench remesh`. The whole pipeline at 256³ is timed
//! through the CLI (see BENCHMARKS.md).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use septa::config::Resolved;
use septa::extract::{ExtractOptions, extract, label_infos};
use septa::phantom::{PhantomParams, heart};
use septa::preprocess::preprocess;
use septa::remesh::{RemeshParams, remesh};

fn bench_remesh(c: &mut Criterion) {
    let vol = heart(&PhantomParams {
        size: 128,
        noise: 0.01,
        ..Default::default()
    })
    .unwrap();
    let pre = preprocess(&vol, &Resolved::defaults(&vol));
    let mesh = extract(
        &pre.refined,
        label_infos(&vol, None),
        *vol.geometry(),
        &ExtractOptions::default(),
    )
    .unwrap();
    let params = RemeshParams {
        target_edge: 2.0,
        ..Default::default()
    };
    let mut group = c.benchmark_group("heart_128^3_noise0.01");
    group.sample_size(10);
    group.bench_function("smooth+remesh L=2mm", |b| {
        b.iter(|| black_box(remesh(black_box(&mesh), &params).unwrap()))
    });
    group.finish();
}

criterion_group!(benches, bench_remesh);
criterion_main!(benches);
