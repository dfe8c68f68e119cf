//! VESTA iso-surface extraction on a 256³ CT-like volume (int16, Hounsfield
//! units): septa's heart phantom at size 256 with its labels mapped to the
//! gray values of a contrast-enhanced cardiac CT (left heart and aortic blood
//! 350 HU, right heart 250, myocardium 100, arterial walls 60, surroundings
//! −100), blurred with a Gaussian of σ = 1 voxel (the scanner's point spread)
//! and given Gaussian noise of σ = 25 HU. Iso value 200 HU: the blood pools.
//! The generator is `examples/ct_like.rs` (which writes the volume for
//! `bench/compare.py --iso`: scikit-image and VTK beside `septa iso`).
//!
//! Run with `cargo bench --bench iso`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use septa::iso::{Decompose, IsoOptions, Mode, iso_surface};

#[allow(dead_code)]
#[path = "../examples/ct_like.rs"]
mod ct_like;
use ct_like::{ISO, ct_like};

const N: usize = 256;

fn bench_iso(c: &mut Criterion) {
    let (v, dims, geometry) = ct_like(N);
    let mut group = c.benchmark_group("iso_256^3_ct_like");
    group.sample_size(10);
    for (mode, decompose) in [
        (Mode::Mixed, Decompose::L),
        (Mode::Disconnect, Decompose::L),
        (Mode::Connect, Decompose::L),
        (Mode::Mixed, Decompose::H),
    ] {
        let opts = IsoOptions {
            mode,
            decompose,
            ..IsoOptions::new(ISO)
        };
        let s = iso_surface(&v, dims, geometry, &opts).unwrap();
        eprintln!(
            "{mode:?} {decompose:?}: {} points, {} triangles, cycles {:?}",
            s.stats.points,
            s.stats.triangles,
            &s.stats.cycles_by_length[3..]
        );
        let name = format!("{}_{decompose:?}", mode.name());
        group.bench_function(name, |b| {
            b.iter(|| iso_surface(black_box(&v), dims, geometry, &opts).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench_iso);
criterion_main!(benches);
