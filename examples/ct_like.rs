//! Writes the 256³ CT-like volume of `benches/iso.rs` as a MetaImage file
//! (int16 Hounsfield units, 0.8 mm voxels), for `bench/compare.py --iso`,
//! which times scikit-image and VTK on it beside `septa iso`.
//!
//! ```text
//! cargo run --release --example ct_like -- /tmp/ct_like_256.mha [--size 256]
//! ```
//!
//! The recipe: septa's heart phantom with its labels mapped to the gray
//! values of a contrast-enhanced cardiac CT (left heart and aortic blood
//! 350 HU, right heart 250, myocardium 100, arterial walls 60, surroundings
//! −100), blurred with a Gaussian of σ = 1 voxel (the scanner's point spread)
//! and given Gaussian noise of σ = 25 HU. `benches/iso.rs` includes this file
//! for the same volume.

use std::io::Write;
use std::path::PathBuf;

use septa::phantom::{PhantomParams, heart};
use septa::volume::{Dims, Geometry};

/// Iso value of the benchmarks: the blood pools.
pub const ISO: f64 = 200.0;

/// Hounsfield units of the phantom's labels (by label value).
const HU: [f64; 8] = [-100.0, 350.0, 250.0, 350.0, 250.0, 100.0, 60.0, 60.0];

/// The CT-like volume described in the module docs, `n`³ voxels.
pub fn ct_like(n: usize) -> (Vec<i16>, Dims, Geometry) {
    let labels = heart(&PhantomParams {
        size: n,
        spacing: [0.8 * 256.0 / n as f64; 3],
        ..Default::default()
    })
    .expect("phantom");
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

#[allow(dead_code)]
fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = PathBuf::from(
        args.first()
            .map(String::as_str)
            .unwrap_or("ct_like_256.mha"),
    );
    let n = match args.iter().position(|a| a == "--size") {
        Some(k) => args
            .get(k + 1)
            .and_then(|s| s.parse().ok())
            .expect("--size N"),
        None => 256,
    };
    let (v, dims, geometry) = ct_like(n);
    let s = geometry.spacing();
    let o = geometry.index_to_physical(glam::DVec3::ZERO);
    let mut bytes = format!(
        "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n\
         Offset = {} {} {}\nElementSpacing = {} {} {}\nDimSize = {} {} {}\n\
         ElementType = MET_SHORT\nElementDataFile = LOCAL\n",
        o.x, o.y, o.z, s[0], s[1], s[2], dims.nx, dims.ny, dims.nz
    )
    .into_bytes();
    for x in &v {
        bytes.extend_from_slice(&x.to_le_bytes());
    }
    std::fs::File::create(&out)
        .and_then(|mut f| f.write_all(&bytes))
        .unwrap_or_else(|e| panic!("{}: {e}", out.display()));
    println!(
        "{}: {} × {} × {} int16",
        out.display(),
        dims.nx,
        dims.ny,
        dims.nz
    );
}
