//! The geometry kernel: what remeshing, validation and the quality report
//! share, with nothing above it.
//!
//! - [`predicates`]: triangle–triangle intersection (understanding shared
//!   vertices and edges), nearest points on triangles and segments,
//!   degeneracy, shape quality;
//! - [`bvh`]: a bounding-volume hierarchy over boxes;
//! - [`grid`]: a uniform cell grid over boxes;
//! - [`intersect`]: self-intersection queries over triangle sets;
//! - [`nearest`]: nearest points on a triangle surface or a polyline;
//! - [`dsu`]: union-find (disjoint sets).

pub mod bvh;
pub mod dsu;
pub mod grid;
pub mod intersect;
pub mod nearest;
pub mod predicates;

pub use bvh::Bvh;
pub use dsu::Dsu;
