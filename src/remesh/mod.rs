//! Remeshing: smooth away the voxel staircase and remesh every patch to a
//! target edge length that follows the geometry, keeping the junction
//! curves shared and never letting two triangles cross.
//!
//! [`remesh`] runs the stage:
//! 1. the [`network`] says which vertices are corners, on junction curves
//!    or interior (and which small islands keep their extracted shape
//!    through the smoothing, which would shrink them);
//! 2. [`smooth`] (Taubin λ/μ, confined to a box of `max_displacement` voxels
//!    around each start position, then untangled) gives the smoothed
//!    *reference*, which crosses itself nowhere;
//! 3. the isotropic remesher splits, collapses, flips and relaxes edges
//!    toward the [`sizing`] field h(x) (the user's target where there is
//!    room, less where label regions are thin), curves first, then
//!    patches, projecting vertices back onto the reference; every operation
//!    is checked by a crossing guard against every other triangle, so the
//!    result crosses itself nowhere either. Space is cut into blocks
//!    remeshed in parallel (see `work.rs`), with the same result for any
//!    number of threads.
//!
//! Every connected piece of every label's surface (closed, across the
//! patches it is made of) keeps its enclosed volume from passing through
//! zero: a label region thinner than an edge (an island, a one-voxel
//! region between junction curves) could otherwise jump through itself
//! between two operations and come out inside out, which no crossing test
//! sees.
//!
//! Where an operation cannot be done safely the triangles stay as they
//! are, there only; [`Remeshed::kept_share`] says how much of the surface
//! that left as extracted.
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
//! let params = RemeshParams { target_edge: 2.0, ..Default::default() };
//! let sizing = params.sizing(pre.refined.grid(), vol.geometry());
//! let out = remesh(&mesh, &sizing, &params).unwrap();
//! assert!(out.mesh.triangle_count() < mesh.triangle_count());
//! ```

mod guard;
pub mod halfedge;
mod isotropic;
mod junction_sizing;
pub mod network;
pub mod sizing;
pub mod smooth;
mod volume;
mod work;

use glam::DVec3;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::geom::nearest::{CurveRef, SurfaceRef};
use crate::mesh::{InterfaceMesh, JunctionCurve};
use crate::volume::{Geometry, PaddedLabels};
use halfedge::{HalfedgeMesh, NONE};
use network::VertexKind;
pub use sizing::Sizing;
use work::{Blocks, COLOURS, Shared, Work};

/// Parameters of [`remesh`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RemeshParams {
    /// Largest target edge length in mm: the target wherever the structures
    /// leave room for it.
    pub target_edge: f64,
    /// Smallest target edge length in mm (where label regions are thinner);
    /// `None`: half the smallest voxel spacing.
    pub min_edge: Option<f64>,
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
            min_edge: None,
            smooth_iterations: 10,
            max_displacement: 0.5,
            iterations: 5,
        }
    }
}

impl RemeshParams {
    /// The default target edge for a volume's geometry: twice the mean voxel spacing.
    pub fn default_target(geometry: &Geometry) -> f64 {
        2.0 * geometry.spacing().iter().sum::<f64>() / 3.0
    }

    /// The default smallest edge for a volume's geometry: half the smallest spacing.
    pub fn default_min_edge(geometry: &Geometry) -> f64 {
        0.5 * geometry
            .spacing()
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min)
    }

    /// The smallest target edge for `geometry` (never above the largest).
    pub fn min_edge_for(&self, geometry: &Geometry) -> f64 {
        self.min_edge
            .unwrap_or_else(|| Self::default_min_edge(geometry))
            .min(self.target_edge)
    }

    /// The sizing field of a label grid (the preprocessed volume's) for these
    /// parameters: targets from [`RemeshParams::min_edge_for`] to
    /// `target_edge`.
    pub fn sizing(&self, grid: &PaddedLabels, geometry: &Geometry) -> Sizing {
        Sizing::from_labels(
            grid,
            geometry,
            self.min_edge_for(geometry),
            self.target_edge,
        )
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
        if let Some(m) = self.min_edge {
            if !(m.is_finite() && m > 0.0) {
                return Err(Error::parameter(
                    "min_edge",
                    m,
                    "the smallest edge length must be a positive number of mm",
                ));
            }
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
    /// The sizing field the remesher aimed at: the one given, lowered
    /// near junction curves shorter than it or closer to
    /// each other (see [`junction_sizing`]).
    pub sizing: Sizing,
    /// Share of the output surface (by area) left as extracted: triangles no
    /// operation could change safely.
    pub kept_share: f64,
    /// The part of [`Remeshed::kept_share`] that is on small islands.
    pub island_share: f64,
    /// Output vertices all of whose triangles stayed as extracted.
    pub kept_vertices: usize,
    /// Wall time of each step.
    pub timings: RemeshTimings,
}

/// Wall time of the steps of [`remesh`], in seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct RemeshTimings {
    /// Staircase smoothing (with untangling): the reference surface.
    pub smooth: f64,
    /// The reference search structures.
    pub setup: f64,
    /// The remeshing iterations.
    pub iterations: f64,
}

/// How far (in voxels) a remeshed triangle's centroid may lie from the
/// smoothed reference: keeps chords from cutting across thin structures.
const FIT_VOXELS: f64 = 0.3;

/// The last iterations, in which relaxation offsets vertices so that the
/// triangles lie on the reference on average (see `isotropic::chord_offset`):
/// two. (Chosen when a vertex on a block border was relaxed only in the
/// iteration that had it inside a block. With halos every vertex is relaxed
/// in each iteration, but one offset iteration still fits worse: MNI152
/// Hausdorff 0.52 -> 0.63 vx, mean distance 0.0855 -> 0.0870 mm.)
const CHORD_OFFSET_ITERATIONS: u32 = 2;

/// Islands (closed components without junctions) of at most this many
/// voxels, or at most [`ISLAND_TARGETS`] target edges long, are not
/// smoothed (see [`network::Network::mark_islands`]).
const ISLAND_VOXELS: f64 = 27.0;
/// See [`ISLAND_VOXELS`].
const ISLAND_TARGETS: f64 = 2.0;

/// Blocks are at least this many times as wide as an operation's reach.
/// Two blocks of one colour are a block width apart; each makes triangles
/// within one reach of itself and sees (as obstacles) those within one
/// reach, so more than two reaches keep them from ever meeting. Five keep a
/// small volume in a few blocks (the vertices on block borders are locked
/// for a pass).
const BLOCK_REACHES: f64 = 5.0;

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

/// Smooths and remeshes all patches of `mesh` toward the targets of
/// `sizing` (see the module docs).
pub fn remesh(mesh: &InterfaceMesh, sizing: &Sizing, params: &RemeshParams) -> Result<Remeshed> {
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
    let clock = std::time::Instant::now();
    let sizing = &sizing.limited(&junction_sizing::limits(&net, &smoothed_pos, sizing));
    if std::env::var_os("SEPTA_DEBUG_ITER").is_some() {
        eprintln!("junction sizing {:.3} s", clock.elapsed().as_secs_f64());
    }

    let clock = std::time::Instant::now();
    let groups = mesh.patch_triangles();
    // largest first: the patches' sizes differ by orders of magnitude
    let references: Vec<SurfaceRef> = work::by_size_largest_first(
        groups.len(),
        |p| groups[p].len(),
        |p| patch_reference(mesh, &smoothed_pos, &groups[p]),
    )
    .into_iter()
    .collect::<Result<_>>()?;
    let curve_references: Vec<CurveRef> = net
        .curves
        .par_iter()
        .map(|c| {
            let pts: Vec<DVec3> = c
                .vertices
                .iter()
                .map(|&v| smoothed_pos[v as usize])
                .collect();
            CurveRef::new(&pts, c.closed)
        })
        .collect();
    // every triangle starts as its own reference triangle (the references
    // number each patch's triangles in mesh order)
    let mut hint = vec![0u32; mesh.triangle_count()];
    for tris in &groups {
        for (i, &t) in tris.iter().enumerate() {
            hint[t as usize] = i as u32;
        }
    }
    let mut work = Work::new(
        smoothed_pos.clone(),
        net.kind.clone(),
        mesh.triangles.clone(),
        mesh.triangle_patch.clone(),
        mesh.patches
            .iter()
            .map(|p| p.labels.map(u32::from))
            .collect(),
        hint,
        net.curves.iter().map(|c| c.vertices.clone()).collect(),
        net.curves.iter().map(|c| c.closed).collect(),
    );
    timings.setup = clock.elapsed().as_secs_f64();

    let clock = std::time::Instant::now();
    let voxel = mesh
        .geometry
        .spacing()
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    let mut shared = Shared {
        references: &references,
        curve_references: &curve_references,
        sizing,
        eps: FIT_VOXELS * voxel,
        offset_chords: false,
        patch_offsets: vec![0.0; mesh.patches.len()],
    };
    // every label's volume in the extraction, which the offset iterations
    // give back (see `volume`)
    let patch_labels: Vec<[usize; 2]> = mesh
        .patches
        .iter()
        .map(|p| p.labels.map(usize::from))
        .collect();
    let extracted_volumes = volume::label_volumes(
        &mesh.positions,
        &mesh.triangles,
        &mesh.triangle_patch,
        &patch_labels,
        mesh.labels.len(),
    );
    for it in 0..params.iterations {
        if work.tris.is_empty() {
            break;
        }
        shared.offset_chords = it + CHORD_OFFSET_ITERATIONS >= params.iterations;
        // the volume offsets only in the last iteration: the chord offsets of
        // the one before it correct most of the same loss (the chords inside a
        // curved sheet), and both at once corrected it about twice (a ball:
        // 5.7 % short, then 6.6 % over)
        if it + 1 == params.iterations {
            let now = volume::label_volumes(
                &work.pos,
                &work.tris,
                &work.patch,
                &patch_labels,
                mesh.labels.len(),
            );
            let deficit: Vec<f64> = extracted_volumes
                .iter()
                .zip(&now)
                .map(|(want, have)| want - have)
                .collect();
            let areas = volume::patch_areas(&work.pos, &work.tris, &work.patch, patch_labels.len());
            let more = volume::volume_offsets(&patch_labels, &areas, &deficit);
            if std::env::var_os("SEPTA_DEBUG_ITER").is_some() {
                let rel: Vec<String> = deficit
                    .iter()
                    .zip(&extracted_volumes)
                    .map(|(d, v)| format!("{:.2}%", 100.0 * d / v.abs().max(1e-9)))
                    .collect();
                eprintln!("volume deficits before iteration {it}: {rel:?}");
            }
            for (o, m) in shared.patch_offsets.iter_mut().zip(more) {
                *o += m;
            }
        }
        let longest = work
            .tris
            .par_iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| work.pos[v as usize]);
                (a - b).length().max((b - c).length()).max((c - a).length())
            })
            .reduce(|| 0.0, f64::max);
        // a block's triangles are those whose centroid it holds, so their
        // vertices lie within 2/3 of a longest edge of it (a vertex is 2/3
        // of a median from the centroid); the triangles an operation makes
        // join those vertices, points between them and points projected
        // from there onto the reference, which one edge covers
        let reach = longest.max(sizing.max() * isotropic_split_above());
        // a block's pass takes a strip of its later neighbours as wide as
        // the longest edge an operation makes: enough that the vertices
        // locked at the strip's far side are free in the neighbour's pass.
        // Not in iteration 0, which coarsens the dense extraction: its
        // strips would be the densest to remesh twice, and the later
        // iterations free its seams (measured: the same edges in range,
        // MNI152 Hausdorff 0.52 vx against 0.62, fewer instructions)
        let halo = if it == 0 {
            0.0
        } else {
            sizing.max() * isotropic_split_above()
        };
        let blocks = Blocks::over(
            &work,
            BLOCK_REACHES * reach,
            reach,
            halo,
            0.5 * (it % 2) as f64,
        );
        let t = std::time::Instant::now();
        work.assign_blocks(&blocks);
        for colour in 0..COLOURS {
            work.pass(&blocks, colour, &shared);
        }
        if std::env::var_os("SEPTA_DEBUG_ITER").is_some() {
            eprintln!(
                "iteration {it}: {:.3} s, {} triangles, {} blocks",
                t.elapsed().as_secs_f64(),
                work.tris.len(),
                blocks.len()
            );
        }
    }
    timings.iterations = clock.elapsed().as_secs_f64();
    if std::env::var_os("SEPTA_DEBUG_ITER").is_some() {
        let now = volume::label_volumes(
            &work.pos,
            &work.tris,
            &work.patch,
            &patch_labels,
            mesh.labels.len(),
        );
        let rel: Vec<String> = extracted_volumes
            .iter()
            .zip(&now)
            .map(|(v, n)| format!("{:.2}%", 100.0 * (v - n) / v.abs().max(1e-9)))
            .collect();
        eprintln!("volume deficits after: {rel:?}");
    }
    if std::env::var_os("SEPTA_DEBUG_ITER").is_some() {
        eprintln!(
            "remesh: smooth {:.3} s, setup {:.3} s, iterations {:.3} s",
            timings.smooth, timings.setup, timings.iterations
        );
    }

    let out = into_mesh(&work, mesh);
    let area = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|v| work.pos[v as usize]);
        0.5 * (b - a).cross(c - a).length()
    };
    let island = |t: &[u32; 3]| {
        t.iter()
            .all(|&v| work.kind[v as usize] == VertexKind::Island)
    };
    // (summed in fixed chunks, in order: the same whatever the threads)
    const CHUNK: usize = 1 << 14;
    let parts: Vec<(f64, f64, f64)> = work
        .tris
        .par_chunks(CHUNK)
        .zip(work.kept.par_chunks(CHUNK))
        .map(|(ts, ks)| {
            ts.iter().zip(ks).fold((0.0, 0.0, 0.0), |s, (t, &k)| {
                let a = area(t);
                let isl = k && island(t);
                (
                    s.0 + a,
                    s.1 + if k { a } else { 0.0 },
                    s.2 + if isl { a } else { 0.0 },
                )
            })
        })
        .collect();
    let (total, kept, islands) = parts
        .iter()
        .fold((0.0, 0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1, x.2 + y.2));
    let share = |x: f64| if total > 0.0 { x / total } else { 0.0 };
    // per vertex: 1 while every triangle seen at it was kept, 2 once one was not
    let mut state = vec![0u8; work.pos.len()];
    for (t, &k) in work.tris.iter().zip(&work.kept) {
        for &v in t {
            let s = &mut state[v as usize];
            *s = (*s).max(if k { 1 } else { 2 });
        }
    }
    let kept_vertices = state.iter().filter(|&&s| s == 1).count();
    let smoothed = InterfaceMesh {
        positions: smoothed_pos,
        ..mesh.clone()
    };
    Ok(Remeshed {
        mesh: out,
        smoothed,
        sizing: sizing.clone(),
        kept_share: share(kept),
        island_share: share(islands),
        kept_vertices,
        timings,
    })
}

/// The split threshold (a multiple of the target) the remesher uses.
fn isotropic_split_above() -> f64 {
    crate::mesh::quality::EDGE_RANGE_HI
}

/// The smoothed reference of one patch: its triangles at the smoothed
/// positions, with their neighbours across edges (for walks).
fn patch_reference(mesh: &InterfaceMesh, smoothed: &[DVec3], tris: &[u32]) -> Result<SurfaceRef> {
    // local ids in order of first appearance, looked up in the thread's
    // dense table (a hash map cost most of the build)
    let mut local = work::take_local_ids(smoothed.len());
    let mut pos = Vec::new();
    let mut tag = Vec::new();
    let mut local_tris = Vec::with_capacity(tris.len());
    let mut ref_tris = Vec::with_capacity(tris.len());
    for &t in tris {
        let tri = mesh.triangles[t as usize];
        ref_tris.push(tri.map(|v| smoothed[v as usize]));
        local_tris.push(tri.map(|v| {
            let l = &mut local[v as usize];
            if *l == work::NO_LOCAL {
                *l = pos.len() as u32;
                pos.push(smoothed[v as usize]);
                tag.push(v);
            }
            *l
        }));
    }
    work::return_local_ids(local, &tag);
    let m = HalfedgeMesh::from_triangles(pos, tag, &local_tris).map_err(|e| {
        let p = mesh.triangle_patch[tris[0] as usize] as usize;
        let [a, b] = mesh.patches[p].labels;
        Error::invalid(format!(
            "patch {} | {} is not a manifold ({e:?}); remeshing needs valid patches (run `septa check`)",
            mesh.label_name(a),
            mesh.label_name(b)
        ))
    })?;
    let adjacent: Vec<[u32; 3]> = (0..ref_tris.len() as u32)
        .map(|f| {
            let h = m.face_halfedge(f);
            let mut row = [crate::geom::nearest::NO_TRIANGLE; 3];
            for (k, g) in [h, m.next(h), m.prev(h)].into_iter().enumerate() {
                let across = m.face(g ^ 1);
                if across != NONE {
                    row[k] = across;
                }
            }
            row
        })
        .collect();
    Ok(SurfaceRef::with_adjacency(ref_tris, adjacent))
}

/// The working mesh as an interface mesh (patches and labels of `like`).
fn into_mesh(work: &Work, like: &InterfaceMesh) -> InterfaceMesh {
    let junctions = work
        .curves
        .iter()
        .enumerate()
        .filter(|(_, c)| c.len() >= 2)
        .map(|(i, c)| JunctionCurve {
            vertices: c.clone(),
            closed: work.closed[i],
            labels: like.junctions[i].labels.clone(),
        })
        .collect();
    InterfaceMesh {
        positions: work.pos.clone(),
        triangles: work.tris.clone(),
        triangle_patch: work.patch.clone(),
        patches: like.patches.clone(),
        junctions,
        labels: like.labels.clone(),
        geometry: like.geometry,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Resolved;
    use crate::extract::{ExtractOptions, extract, label_infos};
    use crate::preprocess::preprocess;
    use crate::volume::{Dims, LabelVolume};

    /// With no iterations, the output is the smoothed extraction, all of it kept.
    #[test]
    fn no_iterations_give_the_smoothed_extraction() {
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
        let params = RemeshParams {
            iterations: 0,
            ..Default::default()
        };
        let out = remesh(&mesh, &Sizing::uniform(2.0), &params).unwrap();
        assert_eq!(out.mesh.triangles, mesh.triangles);
        assert_eq!(out.mesh.positions, out.smoothed.positions);
        assert_eq!(out.kept_share, 1.0);
        assert_eq!(out.kept_vertices, out.mesh.vertex_count());
    }
}
