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

    /// Boxes of a pseudo-random cloud of small triangles: centres within
    /// `spread` of the origin, half sizes up to 0.7.
    pub(crate) fn random_boxes(
        n: usize,
        seed: u64,
        spread: f64,
    ) -> Vec<(glam::DVec3, glam::DVec3)> {
        let mut rng = Rng(seed);
        let mut next = move || rng.next();
        (0..n)
            .map(|_| {
                let c = glam::DVec3::new(next(), next(), next()) * spread;
                let r = glam::DVec3::new(next(), next(), next()) * 0.7;
                (c - r, c + r)
            })
            .collect()
    }
}
