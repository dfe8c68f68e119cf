//! Preprocess and preprocess + extract on the 256³ heart phantom, clean and with
//! `--noise 0.01`, called the way a library user calls them (default
//! `Resolved::defaults`, VESTA surface, L decomposition). The phantom is
//! generated in-process (`septa::phantom::heart`), so no file is read.
//!
//! Run with `cargo bench --bench pipeline`. `bench/compare.py` times the same
//! stages through the CLI next to VTK.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use septa::config::Resolved;
use septa::extract::{ExtractOptions, extract, label_infos};
use septa::phantom::{PhantomParams, heart};
use septa::preprocess::preprocess;
use septa::volume::LabelVolume;

const SIZE: usize = 256;

fn phantom(noise: f64) -> LabelVolume {
    heart(&PhantomParams {
        size: SIZE,
        noise,
        ..Default::default()
    })
    .unwrap()
}

fn bench_pipeline(c: &mut Criterion) {
    let mut group = c.benchmark_group("heart_256^3");
    group.sample_size(10);
    for (name, noise) in [("clean", 0.0), ("noise0.01", 0.01)] {
        let vol = phantom(noise);
        let resolved = Resolved::defaults(&vol);
        // what is being timed, once
        let pre = preprocess(&vol, &resolved);
        let mesh = extract(
            &pre.refined,
            label_infos(&vol, None),
            *vol.geometry(),
            &ExtractOptions::default(),
        )
        .unwrap();
        eprintln!(
            "{name}: {} refined voxels, guarantee {}; {} triangles, {} vertices",
            pre.refined.refined_count(),
            if pre.guarantee.passed() {
                "passed"
            } else {
                "FAILED"
            },
            mesh.triangle_count(),
            mesh.vertex_count()
        );
        drop((pre, mesh));

        group.bench_function(format!("preprocess/{name}"), |b| {
            b.iter(|| preprocess(black_box(&vol), black_box(&resolved)))
        });
        group.bench_function(format!("preprocess+extract/{name}"), |b| {
            b.iter(|| {
                let pre = preprocess(black_box(&vol), black_box(&resolved));
                extract(
                    &pre.refined,
                    label_infos(&vol, None),
                    *vol.geometry(),
                    &ExtractOptions::default(),
                )
                .unwrap()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_pipeline);
criterion_main!(benches);
