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
//! - [`dsu`]: union-find (disjoint sets);
//! - [`incidence`]: the cells around each vertex, as compressed rows.

pub mod bvh;
pub mod dsu;
pub mod grid;
pub mod incidence;
pub mod intersect;
pub mod nearest;
pub mod predicates;

pub use bvh::Bvh;
pub use dsu::Dsu;

/// A small pseudo-random generator for the kernel's tests.
#[cfg(test)]
pub(crate) mod test_rng {
    pub(crate) struct Rng(pub(crate) u64);

    impl Rng {
        pub(crate) fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        pub(crate) fn below(&mut self, n: usize) -> usize {
            ((self.next() * n as f64) as usize).min(n - 1)
        }
    }
}
