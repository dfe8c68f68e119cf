//! Remeshing: smooth away the voxel staircase and remesh every patch to a
//! target edge length in mm, keeping the junction curves shared.
//!
//! [`remesh`] runs the stage: the [`network`] says which vertices are
//! corners, on junction curves or interior; [`smooth`] (Taubin λ/μ, confined to
//! a box of `max_displacement` voxels around each start position) gives the
//! smoothed *reference*; the isotropic remesher then splits, collapses, flips
//! and relaxes edges (curves first, then patches in parallel) and projects
//! vertices back onto the reference; a repair pass removes crossings
//! with local operations, and where it cannot, the patches are remeshed
//! again with shorter edges around the crossings, then with the smoothed
//! (crossing-free) surface kept around them, in growing regions up to all
//! of it: the result never self-intersects.
//!
//! ```
//! use septa::config::Resolved;
//! use septa::extract::{extract, label_infos, ExtractOptions};
//! use septa::preprocess::preprocess;
//! use septa::remesh::{remesh, RemeshParams};
//! use septa::volume::{Dims, Geometry, LabelVolume};
//! // a 6³ cube of label 1 in an 10³ volume
//! let v: Vec<i64> = (0..1000).map(|i| { let (x, y, z) = (i % 10, i / 10 % 10, i / 100); ((2..8).contains(&x) && (2..8).contains(&y) && (2..8).contains(&z)) as i64 }).collect();
//! let vol = LabelVolume::from_values(Dims::new(10, 10, 10).unwrap(), &v, Geometry::identity()).unwrap();
//! let pre = preprocess(&vol, &Resolved::defaults(&vol));
//! let mesh = extract(&pre.refined, label_infos(&vol, None), *vol.geometry(), &ExtractOptions::default()).unwrap();
//! let out = remesh(&mesh, &RemeshParams { target_edge: 2.0, ..Default::default() }).unwrap();
//! assert!(out.mesh.triangle_count() < mesh.triangle_count());
//! ```

pub mod halfedge;
mod isotropic;
pub mod network;
pub mod project;
mod repair;
mod sizing;
pub mod smooth;

pub use isotropic::triangle_quality;

use glam::DVec3;

use crate::error::{Error, Result};
use crate::mesh::InterfaceMesh;

/// Parameters of [`remesh`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RemeshParams {
    /// Target edge length in mm.
    pub target_edge: f64,
    /// Taubin λ/μ smoothing passes.
    pub smooth_iterations: u32,
    /// Largest displacement by smoothing, in voxels along each index axis.
    pub max_displacement: f64,
    /// Remeshing iterations.
    pub iterations: u32,
}

impl Default for RemeshParams {
    fn default() -> Self {
        RemeshParams {
            target_edge: 2.0,
            smooth_iterations: 10,
            max_displacement: 0.5,
            iterations: 8,
        }
    }
}

impl RemeshParams {
    /// The default target edge for a volume's geometry: twice the mean voxel spacing.
    pub fn default_target(geometry: &crate::volume::Geometry) -> f64 {
        2.0 * geometry.spacing().iter().sum::<f64>() / 3.0
    }

    /// Most smoothing passes: the displacement bound stops the vertices
    /// long before (the default is 10); more would only run for ever.
    pub const MAX_SMOOTH_ITERATIONS: u32 = 1000;

    /// Most remeshing rounds (the default is 8; each round costs as much as
    /// the first).
    pub const MAX_ITERATIONS: u32 = 100;

    /// Shortest target edge, in voxels of the smallest spacing: the
    /// extraction's own edges are about half a voxel, and the triangle count
    /// grows with 1/L² (0.01 voxel: ten thousand times the default's).
    pub const MIN_TARGET_VOXELS: f64 = 0.1;

    /// Checks the parameters on their own: each finite, positive where it
    /// must be, iterations within [`Self::MAX_SMOOTH_ITERATIONS`] and
    /// [`Self::MAX_ITERATIONS`]. The error ([`Error::Parameter`]) names the
    /// field.
    pub fn validate(&self) -> Result<()> {
        if !(self.target_edge.is_finite() && self.target_edge > 0.0) {
            return Err(Error::parameter(
                "target_edge",
                self.target_edge,
                "the target edge length must be a positive number of mm",
            ));
        }
        if !(self.max_displacement.is_finite() && self.max_displacement >= 0.0) {
            return Err(Error::parameter(
                "max_displacement",
                self.max_displacement,
                "the largest smoothing displacement must be zero or a positive number of voxels",
            ));
        }
        if self.smooth_iterations > Self::MAX_SMOOTH_ITERATIONS {
            return Err(Error::parameter(
                "smooth_iterations",
                self.smooth_iterations,
                format!(
                    "at most {} smoothing passes (default {}): vertices stop moving long before",
                    Self::MAX_SMOOTH_ITERATIONS,
                    Self::default().smooth_iterations
                ),
            ));
        }
        if self.iterations > Self::MAX_ITERATIONS {
            return Err(Error::parameter(
                "iterations",
                self.iterations,
                format!(
                    "at most {} remeshing rounds (default {})",
                    Self::MAX_ITERATIONS,
                    Self::default().iterations
                ),
            ));
        }
        Ok(())
    }

    /// Checks the target edge against the data too: at least
    /// [`Self::MIN_TARGET_VOXELS`] of the smallest voxel spacing, at most the
    /// diagonal of the whole surface's (or volume's) box, `extent_mm` (or 4
    /// voxels, for tiny ones).
    pub fn validate_scale(&self, geometry: &crate::volume::Geometry, extent_mm: f64) -> Result<()> {
        self.validate()?;
        let spacing = geometry.spacing();
        let smallest = spacing.iter().copied().fold(f64::INFINITY, f64::min);
        let largest = spacing.iter().copied().fold(0.0, f64::max);
        let min = Self::MIN_TARGET_VOXELS * smallest;
        if self.target_edge < min {
            return Err(Error::parameter(
                "target_edge",
                self.target_edge,
                format!(
                    "shorter than {} voxel ({min} mm here): the mesh would have millions of \
                     times more triangles than the voxels can resolve",
                    Self::MIN_TARGET_VOXELS
                ),
            ));
        }
        if self.target_edge > extent_mm.max(4.0 * largest) {
            return Err(Error::parameter(
                "target_edge",
                self.target_edge,
                format!(
                    "longer than the whole volume ({extent_mm:.1} mm corner to corner): no edge \
                     of the surface can be that long"
                ),
            ));
        }
        Ok(())
    }
}

/// Result of [`remesh`].
pub struct Remeshed {
    /// The remeshed patches.
    pub mesh: InterfaceMesh,
    /// The smoothed extraction (the surface the remeshed vertices lie on).
    pub smoothed: InterfaceMesh,
    /// Pairs of intersecting triangles left (zero unless the smoothed
    /// extraction itself intersects, i.e. the input mesh did).
    pub intersections_left: usize,
    /// Vertices kept at their smoothed positions (not remeshed) around
    /// crossings the repair pass could not remove.
    pub kept: usize,
    /// Remeshing attempts: 1, or more where crossings were left (see
    /// [`remesh`]).
    pub attempts: usize,
    /// Wall time of each step.
    pub timings: RemeshTimings,
}

/// Wall time of the steps of [`remesh`], in seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct RemeshTimings {
    /// Staircase smoothing (with untangling): the reference surface.
    pub smooth: f64,
    /// Setting up patch meshes and reference search structures.
    pub setup: f64,
    /// Junction curve passes, all iterations.
    pub curves: f64,
    /// Patch passes, all iterations.
    pub patches: f64,
    /// Self-intersection repair.
    pub repair: f64,
}

/// Rounds of the self-intersection repair pass.
const REPAIR_ROUNDS: usize = 20;

/// Remeshing attempts with shorter target edges (L/2, then L/4, ...)
/// within L/2 of the crossings left, before those that also keep the
/// smoothed surface there. One: on the noisy 512³ phantom a second (L/4)
/// made more crossings than the first, and on a noisy 64³ it cost quality.
const REFINE_ATTEMPTS: usize = 1;

/// Remeshing attempts keeping the smoothed surface in growing regions (the
/// crossing triangles' boxes grown by 0, L/2, 1.5 L, 3.5 L), then, last,
/// everywhere.
const KEEP_ATTEMPTS: usize = 5;

/// More crossing pairs than this after the first attempt: keep the smoothed
/// extraction everywhere at once (see [`remesh`]). The phantoms leave at
/// most 80 (64³, noise 0.02; 37 at 512³); a noisy k-means segmentation
/// (2 × 2 × 3 mm voxels, 17.5 M extracted triangles, L = 4.7 mm) left 7,757,
/// and its further attempts took 35 s, then up to 100 s each as more was
/// kept, 9 minutes in all, to keep 96 % anyway.
const CROSSINGS_ALL_OVER: usize = 1000;

/// More crossing pairs than this after a later attempt: keep the smoothed
/// extraction everywhere. The phantoms leave at most 17 after the second
/// attempt (512³); the MNI152 tissue map (1 mm, a folded grey-matter sheet
/// whose banks nearly touch in the sulci, L = 2 mm) left 523, 176, 226,
/// 100, 137, 93 pairs in six attempts at new places each time (regions
/// 511 → 1,244), 2 minutes to keep 98 % in the end.
const CROSSINGS_NOT_CONVERGING: usize = 100;

/// How far (in voxels) a remeshed triangle's centroid may lie from the
/// smoothed reference: keeps chords from cutting across thin structures.
const FIT_VOXELS: f64 = 0.3;

/// Islands (closed components without junctions) of at most this many
/// voxels, or at most [`ISLAND_TARGETS`] target edges long, are kept as
/// extracted (see [`network::Network::mark_islands`]).
const ISLAND_VOXELS: f64 = 27.0;
/// See [`ISLAND_VOXELS`].
const ISLAND_TARGETS: f64 = 2.0;

/// The diagonal of the points' bounding box (0 for none).
fn bbox_diagonal(points: &[DVec3]) -> f64 {
    let Some(first) = points.first() else {
        return 0.0;
    };
    let (lo, hi) = points
        .iter()
        .fold((*first, *first), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    (hi - lo).length()
}

/// Smooths and remeshes all patches of `mesh`.
pub fn remesh(mesh: &InterfaceMesh, params: &RemeshParams) -> Result<Remeshed> {
    params.validate_scale(&mesh.geometry, bbox_diagonal(&mesh.positions))?;
    let mut timings = RemeshTimings::default();
    let clock = std::time::Instant::now();
    let mut net = network::Network::new(mesh);
    net.mark_islands(mesh, ISLAND_VOXELS, ISLAND_TARGETS * params.target_edge);
    let smoothed_pos = smooth::smooth(
        mesh,
        &net,
        params.smooth_iterations,
        params.max_displacement,
    );
    timings.smooth = clock.elapsed().as_secs_f64();
    let voxel = mesh
        .geometry
        .spacing()
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    // Where the repair cannot remove a crossing, remesh again: first with
    // shorter target edges around the crossings (finer chords follow the
    // smoothed surface more closely), then also keeping the smoothed surface
    // (crossing-free) there, in growing regions; the last attempt keeps
    // everything, so the result never self-intersects.
    let target = params.target_edge;
    let last = REFINE_ATTEMPTS + KEEP_ATTEMPTS;
    let mut regions: Vec<(DVec3, DVec3)> = Vec::new();
    let mut kept = 0;
    let mut attempt = 0;
    let mut runs = 0;
    let (r, intersections_left) = loop {
        runs += 1;
        let sizing = if attempt == 0 {
            sizing::Sizing::uniform(target)
        } else {
            let finer = target / (1u32 << attempt.min(REFINE_ATTEMPTS)) as f64;
            let grow = DVec3::splat(0.5 * target);
            sizing::Sizing::with_regions(
                target,
                regions
                    .iter()
                    .map(|&(lo, hi)| (lo - grow, hi + grow, finer))
                    .collect(),
            )
        };
        let mut net = net.clone();
        if attempt == last {
            kept = net.keep_all();
        } else if attempt > REFINE_ATTEMPTS {
            let k = attempt - REFINE_ATTEMPTS;
            let r = target * ((1u32 << (k - 1)) as f64 - 1.0) * 0.5;
            let grown: Vec<_> = regions
                .iter()
                .map(|&(lo, hi)| (lo - DVec3::splat(r), hi + DVec3::splat(r)))
                .collect();
            kept = net.keep_within(&smoothed_pos, &grown);
        }
        let clock = std::time::Instant::now();
        let mut r =
            isotropic::Remesher::new(mesh, &net, &smoothed_pos, sizing, FIT_VOXELS * voxel)?;
        timings.setup += clock.elapsed().as_secs_f64();
        // (with every vertex kept the output is the smoothed extraction as is)
        let iterations = if attempt == last {
            0
        } else {
            params.iterations
        };
        let (curves, patches) = r.run(iterations);
        timings.curves += curves;
        timings.patches += patches;
        let clock = std::time::Instant::now();
        let left = r.repair_intersections(REPAIR_ROUNDS);
        timings.repair += clock.elapsed().as_secs_f64();
        if left == 0 || attempt == last {
            break (r, left);
        }
        // Crossings all over (structures much thinner than L: a noisy
        // segmentation at a coarse target), or still many after the shorter
        // edges (each attempt makes new ones elsewhere, as a change of target
        // in one place changes its patch's whole sequence of operations):
        // further attempts would be slower and slower as more is kept, and
        // end keeping nearly everything; keep everything at once.
        let too_many = if attempt == 0 {
            CROSSINGS_ALL_OVER
        } else {
            CROSSINGS_NOT_CONVERGING
        };
        if left > too_many {
            attempt = last;
            continue;
        }
        regions.extend(r.crossing_boxes());
        attempt += 1;
    };
    let out = r.into_mesh(mesh);
    let smoothed = InterfaceMesh {
        positions: smoothed_pos,
        ..mesh.clone()
    };
    Ok(Remeshed {
        mesh: out,
        smoothed,
        intersections_left,
        kept,
        attempts: runs,
        timings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Resolved;
    use crate::extract::{ExtractOptions, extract, label_infos};
    use crate::preprocess::preprocess;
    use crate::volume::{Dims, Geometry, LabelVolume};

    /// With every vertex kept, remeshing (all its iterations) changes
    /// nothing: the output is the smoothed extraction, the last resort of
    /// [`remesh`] against crossings.
    #[test]
    fn keeping_everything_gives_the_smoothed_extraction() {
        // two labels side by side in a background: three patches, junction curves
        let v: Vec<i64> = (0..512)
            .map(|i| {
                let (x, y, z) = (i % 8, i / 8 % 8, i / 64);
                let inside = (1..7).contains(&x) && (2..6).contains(&y) && (2..6).contains(&z);
                if !inside {
                    0
                } else if x < 4 {
                    1
                } else {
                    2
                }
            })
            .collect();
        let vol = LabelVolume::from_values(Dims::new(8, 8, 8).unwrap(), &v, Geometry::identity())
            .unwrap();
        let pre = preprocess(&vol, &Resolved::defaults(&vol));
        let mesh = extract(
            &pre.refined,
            label_infos(&vol, None),
            *vol.geometry(),
            &ExtractOptions::default(),
        )
        .unwrap();
        assert!(!mesh.junctions.is_empty());
        let mut net = network::Network::new(&mesh);
        let smoothed = smooth::smooth(&mesh, &net, 10, 0.5);
        assert_eq!(net.keep_all(), mesh.vertex_count());
        let mut r =
            isotropic::Remesher::new(&mesh, &net, &smoothed, sizing::Sizing::uniform(2.0), 0.3)
                .unwrap();
        r.run(8);
        assert_eq!(r.repair_intersections(REPAIR_ROUNDS), 0);
        let out = r.into_mesh(&mesh);
        assert_eq!(out.triangle_count(), mesh.triangle_count());
        let key = |p: &DVec3| p.to_array().map(f64::to_bits);
        let mut a: Vec<_> = out.positions.iter().map(key).collect();
        let mut b: Vec<_> = smoothed.iter().map(key).collect();
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b);
    }
}
