//! # septa
//!
//! Consistent manifold interface meshes from segmented label volumes.
//!
//! A label volume (one tissue label per voxel) goes through four stages, each a
//! module with a small public API:
//!
//! 1. [`io`] reads it (NIfTI, NRRD, MetaImage, raw) into a [`volume::LabelVolume`]
//!    with its physical geometry;
//! 2. [`preprocess`] finds critical (non-manifold) edges and vertices and removes
//!    them by fattening on virtual 5³ / 7³ subvoxels;
//! 3. [`extract`] builds one manifold patch per pair of touching labels from
//!    VESTA voxel-face vectors; patches share their boundaries exactly;
//! 4. remeshing smooths and remeshes the patches to a target edge length.
//!
//! [`pipeline::run`] runs them all, from a volume and its config to the mesh,
//! the reports and the [`io::manifest::Manifest`]; the `septa` command line
//! and the Python package both call it.
//!
//! [`mesh`] holds the output type and the validator of the invariants every
//! output keeps; [`geom`] the geometry kernel they share; [`render`] draws
//! `preview.png` without a display. Beside the label pipeline: [`iso`]
//! (VESTA iso-surfaces of gray volumes), [`contour`] (DICONEX, its 2-D
//! analogue) and [`hyper`] (STEVE, one dimension up).

pub mod config;
pub mod contour;
pub mod error;
pub mod estimate;
pub mod extract;
pub mod geom;
pub mod hyper;
pub mod io;
pub mod iso;
pub mod labels;
pub mod memory;
pub mod mesh;
pub mod phantom;
pub mod pipeline;
pub mod preprocess;
pub mod remesh;
pub mod render;
pub mod star;
pub mod volume;

pub use error::{Error, Result};
/// The output directory writer, [`io::output`] (its old path, kept for the
/// command line and the Python package).
pub use io::output;
