//! Helpers shared by the integration tests.
#![allow(dead_code)]

use septa::config::Resolved;
use septa::extract::{ExtractOptions, extract, label_infos};
use septa::mesh::InterfaceMesh;
use septa::mesh::validate::{Options, Report, validate};
use septa::preprocess::{Preprocessed, preprocess};
use septa::volume::{Dims, Geometry, LabelVolume};

/// A volume from values (x fastest) with identity geometry.
pub fn volume(dims: [usize; 3], values: &[i64]) -> LabelVolume {
    LabelVolume::from_values(
        Dims::new(dims[0], dims[1], dims[2]).unwrap(),
        values,
        Geometry::identity(),
    )
    .unwrap()
}

/// Defaults with the outside = label value 0 (added if absent).
pub fn resolved_outside0(vol: LabelVolume) -> (LabelVolume, Resolved) {
    let vol = septa::config::with_extra_values(vol, &[0]);
    let mut r = Resolved::defaults(&vol);
    r.outside = vol.id_of(0).unwrap();
    (vol, r)
}

/// Preprocess + extract + validate (with fidelity to 1/2 voxel).
pub fn run(
    vol: &LabelVolume,
    r: &Resolved,
    opts: ExtractOptions,
) -> (Preprocessed, InterfaceMesh, Report) {
    let pre = preprocess(vol, r);
    let mesh = extract(&pre.refined, label_infos(vol, None), *vol.geometry(), &opts).unwrap();
    let report = validate(
        &mesh,
        &Options {
            intersections: false,
            fidelity: Some((&pre.refined, 0.5)),
        },
    );
    (pre, mesh, report)
}

/// All four surface/decomposition combinations, and both surfaces with
/// their flat stretches merged.
pub fn all_options() -> [ExtractOptions; 6] {
    use septa::extract::{Decompose, Surface};
    let with = |surface, decompose, merge_flat| ExtractOptions {
        surface,
        decompose,
        merge_flat,
    };
    [
        with(Surface::Vesta, Decompose::L, false),
        with(Surface::Vesta, Decompose::H, false),
        with(Surface::Faces, Decompose::L, false),
        with(Surface::Faces, Decompose::H, false),
        with(Surface::Vesta, Decompose::L, true),
        with(Surface::Faces, Decompose::L, true),
    ]
}

/// Deterministic small PRNG (SplitMix64) for tests.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}
