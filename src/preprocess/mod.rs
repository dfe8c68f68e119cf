//! Preprocessing: make every label's region a manifold before extraction.
//!
//! This stage owns B-K §2.1: [`critical_elements`] finds grid edges and vertices
//! where some label's boundary is not a 2-manifold (and, with separation
//! constraints, faces between labels that must not touch); [`fatten`] removes
//! them by giving small neighbourhoods of subvoxels (5³ per voxel, 7³ with
//! constraints) to a dominant label; [`check_guarantee`] proves on the result
//! that nothing critical is left. [`preprocess`] runs the three.
//!
//! ```
//! use septa::config::Resolved;
//! use septa::preprocess::preprocess;
//! use septa::volume::{Dims, Geometry, LabelVolume};
//! // two voxels of label 1 touching only along an edge, in label 0
//! let mut v = vec![0i64; 8];
//! v[0] = 1;
//! v[3] = 1;
//! let vol = LabelVolume::from_values(Dims::new(2, 2, 2).unwrap(), &v, Geometry::identity()).unwrap();
//! let out = preprocess(&vol, &Resolved::defaults(&vol));
//! assert!(out.critical.counts().1 > 0); // a critical edge
//! assert!(out.guarantee.passed()); // gone after fattening
//! assert!(out.refined.refined_count() > 0);
//! ```

mod check;
mod critical;
mod fatten;
mod refined;

pub use check::{GuaranteeReport, Violation, check_guarantee};
pub use critical::{CriticalElement, CriticalSet, ElementKind, SeparationTable, critical_elements};
pub use fatten::{fatten, neighbourhood_box, neighbourhoods};
pub use refined::{RefinedVolume, RefinedVoxel};

use crate::config::Resolved;
use crate::volume::{LabelVolume, PaddedLabels};

/// Output of [`preprocess`].
#[derive(Clone, Debug)]
pub struct Preprocessed {
    /// The fattened volume.
    pub refined: RefinedVolume,
    /// What was critical in the input.
    pub critical: CriticalSet,
    /// The check of the result.
    pub guarantee: GuaranteeReport,
    /// The constrained pairs.
    pub separation: SeparationTable,
}

/// Subdivision factor: 5, or 7 when separation constraints are given.
pub fn subdivision_for(resolved: &Resolved) -> i32 {
    if resolved.has_constraints() { 7 } else { 5 }
}

/// Detects critical elements, fattens them and checks the result.
pub fn preprocess(volume: &LabelVolume, resolved: &Resolved) -> Preprocessed {
    let grid = PaddedLabels::new(volume, resolved.outside);
    let separation = SeparationTable::new(resolved, volume.label_count());
    let critical = critical_elements(&grid, resolved, &separation);
    let refined = fatten(
        grid,
        &critical,
        subdivision_for(resolved),
        &resolved.rank,
        &separation,
    );
    let guarantee = check_guarantee(&refined, &separation, &critical);
    Preprocessed {
        refined,
        critical,
        guarantee,
        separation,
    }
}
