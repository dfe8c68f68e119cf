//! Remeshing (work in progress).
pub mod halfedge;
pub mod network;
