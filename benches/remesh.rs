//! Smoothing + remeshing (`septa::remesh::remesh`) of the extraction of the
//! 128³ heart phantom with `--noise 0.01`, at L = 2 voxels (2 mm), with the
//! default parameters. The extraction is done once, outside the timing.
//!
//! A second group times the whole pipeline a user runs, the `septa extract`
//! command (read → preprocess → extract → smooth → remesh → quality report
//! → validate with self-intersections → write), on the 256³ phantom with
//! `--noise 0.01` at L = 2 mm: issue 5's target is ≤ 5 s on 2 cores.
//!
//! Run with `cargo bench --bench remesh` (`-- whole` for the second group
//! only).

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
    let sizing = params.sizing(pre.refined.grid(), vol.geometry());
    let mut group = c.benchmark_group("heart_128^3_noise0.01");
    group.sample_size(10);
    group.bench_function("smooth+remesh L=2mm", |b| {
        b.iter(|| black_box(remesh(black_box(&mesh), &sizing, &params).unwrap()))
    });
    group.finish();
}

/// `septa extract PHANTOM -o OUT --force -q --target-edge 2` as a process
/// (the binary of this build), on a phantom written once to a temp dir.
fn bench_whole_command(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("septa-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let phantom = dir.join("heart256_noise0.01.nii.gz");
    let out = dir.join("out");
    let septa = env!("CARGO_BIN_EXE_septa");
    let run = |args: &[&std::ffi::OsStr]| {
        let status = std::process::Command::new(septa)
            .args(args)
            .status()
            .unwrap();
        assert!(status.success(), "septa {args:?} failed");
    };
    run(&[
        "phantom".as_ref(),
        "--size".as_ref(),
        "256".as_ref(),
        "--noise".as_ref(),
        "0.01".as_ref(),
        "-q".as_ref(),
        "-o".as_ref(),
        phantom.as_os_str(),
    ]);
    let mut group = c.benchmark_group("heart_256^3_noise0.01");
    group.sample_size(10);
    group.bench_function("whole septa extract --target-edge 2", |b| {
        b.iter(|| {
            run(&[
                "extract".as_ref(),
                phantom.as_os_str(),
                "-o".as_ref(),
                out.as_os_str(),
                "--force".as_ref(),
                "-q".as_ref(),
                "--target-edge".as_ref(),
                "2".as_ref(),
            ])
        })
    });
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench_remesh, bench_whole_command);
criterion_main!(benches);
