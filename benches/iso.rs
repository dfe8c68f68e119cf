//! VESTA iso-surface extraction on a 256³ CT-like volume (int16, Hounsfield
//! units): septa's heart phantom at size 256 with its labels mapped to the
//! gray values of a contrast-enhanced cardiac CT (left heart and aortic blood
//! 350 HU, right heart 250, myocardium 100, arterial walls 60, surroundings
//! −100), blurred with a Gaussian of σ = 1 voxel (the scanner's point spread)
//! and given Gaussian noise of σ = 25 HU. Iso value 200 HU: the blood pools.
//! `bench/compare_iso.py` builds the same recipe with numpy/scipy and times
//! scikit-image and VTK beside `septa iso`.
//!
//! Run with `cargo bench --bench iso`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use septa::iso::{Decompose, IsoOptions, Mode, iso_surface};
use septa::phantom::{PhantomParams, heart};
use septa::volume::{Dims, Geometry};

const N: usize = 256;
const ISO: f64 = 200.0;

/// Hounsfield units of the phantom's labels (by label value).
const HU: [f64; 8] = [-100.0, 350.0, 250.0, 350.0, 250.0, 100.0, 60.0, 60.0];

/// The CT-like volume described in the module docs.
fn ct_like() -> (Vec<i16>, Dims, Geometry) {
    let labels = heart(&PhantomParams {
        size: N,
        spacing: [0.8, 0.8, 0.8],
        ..Default::default()
    })
    .unwrap();
    let dims = labels.dims();
    let values = labels.values().to_vec();
    let mut v: Vec<f64> = labels
        .ids()
        .iter()
        .map(|&id| HU[values[id as usize] as usize])
        .collect();
    for axis in 0..3 {
        v = blur(&v, dims, axis, 1.0);
    }
    let noisy = v
        .iter()
        .enumerate()
        .map(|(i, &x)| (x + 25.0 * gaussian(i as u64)).round() as i16)
        .collect();
    (noisy, dims, *labels.geometry())
}

/// Gaussian blur along one axis (kernel radius 3σ, clamped at the border).
fn blur(v: &[f64], d: Dims, axis: usize, sigma: f64) -> Vec<f64> {
    let r = (3.0 * sigma).ceil() as isize;
    let w: Vec<f64> = (-r..=r)
        .map(|k| (-(k * k) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f64 = w.iter().sum();
    let n = [d.nx, d.ny, d.nz];
    let stride = d.strides()[axis] as isize;
    let mut out = vec![0.0; v.len()];
    for (i, o) in out.iter_mut().enumerate() {
        let c = d.coords(i)[axis] as isize;
        let mut s = 0.0;
        for (k, wk) in (-r..=r).zip(&w) {
            let cc = (c + k).clamp(0, n[axis] as isize - 1);
            s += wk * v[(i as isize + (cc - c) * stride) as usize];
        }
        *o = s / total;
    }
    out
}

/// A standard normal deviate from a counter (SplitMix64 + Box–Muller).
fn gaussian(i: u64) -> f64 {
    let mix = |mut z: u64| {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let u1 = ((mix(2 * i) >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = ((mix(2 * i + 1) >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn bench_iso(c: &mut Criterion) {
    let (v, dims, geometry) = ct_like();
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
