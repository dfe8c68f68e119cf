//! Extraction: interface patches from the fattened volume.
//!
//! This stage owns the construction of the [`InterfaceMesh`] from a
//! [`RefinedVolume`]:
//! - [`Surface::Vesta`] (default): VESTA's surface, the dual of the labels'
//!   boundary faces, one support point per boundary face, one N-cycle per
//!   boundary grid vertex and label, split at junctions (see [`vesta`](self)
//!   module docs in `vesta.rs`); a single voxel gives an octahedron.
//! - [`Surface::Faces`]: the boundary faces themselves (B-K §2.2), two triangles
//!   per square face or a fan around its centre where it has hanging vertices;
//!   a single voxel gives a cube. Used as a cross-check: it encloses exactly the
//!   voxels of each label.
//!
//! [`Decompose`] chooses how N-cycles with N > 3 become triangles.
//!
//! Vertices inside straight segments are always dissolved (`dissolve.rs`);
//! with [`ExtractOptions::merge_flat`], so are the vertices inside flat
//! stretches of a patch (`planar.rs`): the same point set in fewer triangles.
//!
//! Work is split into z slabs of grid vertices and into groups of refined voxels,
//! processed in parallel; parts are merged in a fixed order, so the output is
//! identical for any number of threads.
//!
//! ```
//! use septa::config::Resolved;
//! use septa::extract::{extract, ExtractOptions};
//! use septa::preprocess::preprocess;
//! use septa::volume::{Dims, Geometry, LabelVolume};
//! // one voxel of label 1 in label 0
//! let mut v = vec![0i64; 27];
//! v[13] = 1;
//! let vol = LabelVolume::from_values(Dims::new(3, 3, 3).unwrap(), &v, Geometry::identity()).unwrap();
//! let pre = preprocess(&vol, &Resolved::defaults(&vol));
//! let mesh = extract(&pre.refined, septa::extract::label_infos(&vol, None), *vol.geometry(), &ExtractOptions::default()).unwrap();
//! assert_eq!((mesh.vertex_count(), mesh.triangle_count()), (6, 8)); // an octahedron
//! ```

mod assemble;
mod coarse_faces;
mod dissolve;
mod lattice;
mod planar;
mod polygon;
mod primal;
mod vesta;

pub use polygon::min_area_triangulation;

use glam::DVec3;
use rayon::prelude::*;

use crate::config::Config;
use crate::error::{Error, Result};
use crate::mesh::{InterfaceMesh, LabelInfo};
use crate::preprocess::RefinedVolume;
use crate::volume::{Geometry, LabelId, LabelVolume};

/// How N-cycles with N > 3 are cut into triangles (VESTA's L and H modes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Decompose {
    /// No extra points: a minimum-area triangulation of the cycle.
    #[default]
    L,
    /// One extra point per cycle (the average of its points) and a fan around it.
    H,
}

/// Which surface to extract.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Surface {
    /// VESTA: the dual of the boundary faces (smooth enough to remesh).
    #[default]
    Vesta,
    /// The boundary faces themselves (blocky, exact voxel volumes).
    Faces,
}

/// Options of [`extract`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExtractOptions {
    pub surface: Surface,
    pub decompose: Decompose,
    /// Merge the flat stretches of each patch (staircase terraces, sides of
    /// fattened blocks) into large polygons: the very same surface in fewer,
    /// longer triangles. Off by default: smoothing, ours or another tool's,
    /// needs a point on every boundary face.
    pub merge_flat: bool,
}

/// A piece of output being produced by one task: triangles over tagged vertex
/// references (coarse face id, lattice key or local centroid), their label
/// pairs, new centroids and junction chords. A task reuses one `Part` as its
/// scratch and hands on what it made [`pack`](Part::pack)ed.
#[derive(Default)]
pub(crate) struct Part {
    pub tris: Vec<[u64; 3]>,
    pub pairs: Vec<u32>,
    pub centroids: Vec<DVec3>,
    pub chords: Vec<Chord>,
    refs: Vec<u64>,
}

impl Part {
    /// What was emitted since the last call, packed (every vertex reference
    /// once, triangles and chords as indices into them: 12 rather than 24
    /// bytes per triangle, in buffers of exactly their size, since all parts
    /// wait until they are merged); the part is left empty for reuse, its
    /// buffers kept.
    pub(crate) fn pack(&mut self) -> PackedPart {
        let refs = &mut self.refs;
        refs.clear();
        refs.extend(self.tris.iter().flatten());
        refs.extend(self.chords.iter().flat_map(|c| [c.a, c.b]));
        refs.sort_unstable();
        refs.dedup();
        let refs = &*refs;
        let local = |r: u64| refs.binary_search(&r).expect("reference collected") as u32;
        let packed = PackedPart {
            refs: refs.to_vec(),
            tris: self.tris.iter().map(|t| t.map(local)).collect(),
            pairs: self.pairs.to_vec(),
            centroids: self.centroids.to_vec(),
            chords: self
                .chords
                .iter()
                .map(|c| PackedChord {
                    a: local(c.a),
                    b: local(c.b),
                    labels: c.labels,
                    count: c.count,
                })
                .collect(),
        };
        self.tris.clear();
        self.pairs.clear();
        self.centroids.clear();
        self.chords.clear();
        packed
    }
}

/// A piece `a – b` of a junction curve and the labels around it.
pub(crate) struct Chord {
    pub a: u64,
    pub b: u64,
    pub labels: [LabelId; 4],
    pub count: u8,
}

/// A [`Part`] as it waits to be merged: `refs` are its vertex references,
/// sorted, once each; triangles and chords index them.
pub(crate) struct PackedPart {
    pub refs: Vec<u64>,
    pub tris: Vec<[u32; 3]>,
    pub pairs: Vec<u32>,
    pub centroids: Vec<DVec3>,
    pub chords: Vec<PackedChord>,
}

/// A [`Chord`] in a [`PackedPart`].
pub(crate) struct PackedChord {
    pub a: u32,
    pub b: u32,
    pub labels: [LabelId; 4],
    pub count: u8,
}

/// Label table of a mesh: values of the volume, names from the config.
pub fn label_infos(volume: &LabelVolume, config: Option<&Config>) -> Vec<LabelInfo> {
    volume
        .values()
        .iter()
        .map(|&value| LabelInfo {
            value,
            name: config
                .map(|c| c.display_name(value))
                .unwrap_or_else(|| format!("label{value}")),
        })
        .collect()
}

/// Extracts the interface patches of a fattened volume.
pub fn extract(
    rv: &RefinedVolume,
    labels: Vec<LabelInfo>,
    geometry: Geometry,
    opts: &ExtractOptions,
) -> Result<InterfaceMesh> {
    let s = rv.subdivision();
    let dims = rv.dims();
    let limit = lattice::max_extent(s);
    if dims.to_array().iter().any(|&n| n > limit) {
        return Err(Error::invalid(format!(
            "extraction supports at most {limit} voxels per axis"
        )));
    }
    let lat = lattice::Lattice { s };
    match opts.surface {
        Surface::Vesta => {
            let faces = coarse_faces::CoarseFaces::new(rv);
            let ctx = vesta::Ctx {
                rv,
                faces: &faces,
                lat,
                positions: lattice::Positions::new(lat, dims.to_array()),
                decompose: opts.decompose,
            };
            let planes = dims.nz as i32 + 1;
            let slab = slab_size(planes);
            let mut parts: Vec<PackedPart> = (0..(planes + slab - 1) / slab)
                .into_par_iter()
                .map_init(Part::default, |part, b| {
                    vesta::coarse_slab(&ctx, part, b * slab, ((b + 1) * slab).min(planes));
                    part.pack()
                })
                .collect();
            let coarse_tris: usize = parts.iter().map(|p| p.tris.len()).sum();
            let coarse_chords: usize = parts.iter().map(|p| p.chords.len()).sum();
            parts.extend(
                rv.refined_cells()
                    .par_chunks(32)
                    .map_init(Part::default, |part, cells| {
                        vesta::refined_cells(&ctx, part, cells);
                        part.pack()
                    })
                    .collect::<Vec<_>>(),
            );
            if std::env::var_os("SEPTA_DEBUG_EXTRACT").is_some() {
                let all: usize = parts.iter().map(|p| p.tris.len()).sum();
                let ch: usize = parts.iter().map(|p| p.chords.len()).sum();
                eprintln!(
                    "extract: coarse {coarse_tris} tris {coarse_chords} chords; refined {} tris {} chords; {} refined voxels",
                    all - coarse_tris,
                    ch - coarse_chords,
                    rv.refined_cells().len()
                );
            }
            Ok(assemble::assemble(
                parts,
                Some(&faces),
                lat,
                labels,
                geometry,
                opts.merge_flat,
            ))
        }
        Surface::Faces => {
            let parts = primal::primal_parts(rv, lat);
            Ok(assemble::assemble(
                parts,
                None,
                lat,
                labels,
                geometry,
                opts.merge_flat,
            ))
        }
    }
}

/// Vertex planes per parallel task: enough tasks to balance, few enough to
/// keep per-task overhead small.
fn slab_size(planes: i32) -> i32 {
    (planes / 64).clamp(1, 8)
}
