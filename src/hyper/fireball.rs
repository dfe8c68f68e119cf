//! A generated 4-D example: a hot blob that cools and splits in two over
//! time, like the fireball of the STEVE paper's section IV.B.
//!
//! Frame `k` of `frames` (s = k / (frames − 1) from 0 to 1) holds
//! `A(s) · (G(x − c₁(s)) + G(x − c₂(s)))`: two Gaussian bumps of width
//! σ = 0.12 n that start at the centre of the n³ grid and move apart along x
//! to ± n/4, with amplitude A = 100 (1 − 0.3 s). At the iso value
//! [`FIREBALL_ISO`] the surface is one sphere at s = 0, a dumbbell in
//! between, and two spheres at the end.

use crate::io::{Image, Samples};
use crate::volume::Geometry;

/// The iso value the example is meant for.
pub const FIREBALL_ISO: f64 = 50.0;

/// The example as a 4-D image (float32 samples, `spacing` mm voxels, time
/// step `time_step`, `path` for messages). `n` ≥ 4 voxels per axis,
/// `frames` ≥ 2.
pub fn fireball(n: usize, frames: usize, spacing: f64, time_step: f64) -> Image {
    let n = n.max(4);
    let frames = frames.max(2);
    let sigma = 0.12 * n as f64;
    let centre = (n as f64 - 1.0) / 2.0;
    let mut v = Vec::with_capacity(n * n * n * frames);
    for k in 0..frames {
        let s = k as f64 / (frames - 1) as f64;
        let amp = 100.0 * (1.0 - 0.3 * s);
        let d = s * n as f64 / 4.0;
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let (dy, dz) = (y as f64 - centre, z as f64 - centre);
                    let r2 = dy * dy + dz * dz;
                    let g = |cx: f64| {
                        let dx = x as f64 - cx;
                        (-(dx * dx + r2) / (2.0 * sigma * sigma)).exp()
                    };
                    v.push((amp * (g(centre - d) + g(centre + d))) as f32);
                }
            }
        }
    }
    let half = spacing * (n as f64 - 1.0) / 2.0;
    let geometry = Geometry::new(
        [spacing; 3],
        [-half, -half, -half],
        Geometry::IDENTITY_DIRECTION,
    )
    .unwrap_or_else(|_| Geometry::identity());
    Image {
        dims: vec![n, n, n, frames],
        samples: Samples::F32(v),
        geometry,
        time_step: Some(time_step),
        path: "fireball".into(),
        sources: Vec::new(),
    }
}
