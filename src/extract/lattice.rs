//! Identities of output points that are not coarse face centres.
//!
//! Every point the extraction emits lies on a lattice of spacing 1/(2s) voxel:
//! fine grid vertices, fine face centres, fine and coarse edge midpoints, and
//! coarse face centres. A point's lattice coordinates, shifted by one coarse cell
//! so that the outside border is non-negative, pack into a [`Key`]; equal points
//! get equal keys wherever they are computed, which is what makes patches share
//! their boundary vertices exactly.
//!
//! Lattice coordinate `L` relates to fine grid coordinate `f` by `L = 2 (f + s)`
//! and to index space (voxel centres at integers) by `L / (2s) − 1.5`.

use glam::DVec3;

/// Bits per lattice coordinate in a key.
const BITS: u32 = 20;
const MASK: u64 = (1 << BITS) - 1;

/// Largest volume extent (voxels per axis) whose lattice coordinates fit a key.
pub fn max_extent(s: i32) -> usize {
    (((1u64 << BITS) - 1) / (2 * s as u64)) as usize - 3
}

/// A packed lattice point (60 bits).
pub type Key = u64;

/// Lattice conversions for one subdivision factor.
#[derive(Clone, Copy, Debug)]
pub struct Lattice {
    pub s: i32,
}

impl Lattice {
    /// Lattice coordinates of fine grid vertex `f`.
    #[inline]
    pub fn of_fine_vertex(&self, f: [i32; 3]) -> [i32; 3] {
        f.map(|v| 2 * (v + self.s))
    }

    /// Packs lattice coordinates.
    #[inline]
    pub fn key(&self, l: [i32; 3]) -> Key {
        debug_assert!(l.iter().all(|&v| v >= 0 && (v as u64) <= MASK));
        (l[0] as u64) | ((l[1] as u64) << BITS) | ((l[2] as u64) << (2 * BITS))
    }

    /// Unpacks a key.
    #[inline]
    pub fn unpack(&self, k: Key) -> [i32; 3] {
        [
            (k & MASK) as i32,
            ((k >> BITS) & MASK) as i32,
            ((k >> (2 * BITS)) & MASK) as i32,
        ]
    }

    /// Index-space position of lattice coordinates.
    #[inline]
    pub fn position(&self, l: [i32; 3]) -> DVec3 {
        let d = 2.0 * self.s as f64;
        DVec3::new(
            l[0] as f64 / d - 1.5,
            l[1] as f64 / d - 1.5,
            l[2] as f64 / d - 1.5,
        )
    }

    /// Index-space position of a key.
    #[inline]
    pub fn key_position(&self, k: Key) -> DVec3 {
        self.position(self.unpack(k))
    }
}

/// The index-space positions of every lattice coordinate of a volume, per
/// axis: [`Lattice::position`] as a table lookup (the very same values,
/// computed once), since the fine path asks for a position at every step of
/// every cycle and a division per coordinate showed in its profile.
pub(crate) struct Positions {
    lat: Lattice,
    axes: [Vec<f64>; 3],
}

impl Positions {
    /// The table for a volume of `dims` voxels: lattice coordinates 0 to
    /// 2s (n + 2) along an axis of n voxels (the outside ring included).
    pub(crate) fn new(lat: Lattice, dims: [usize; 3]) -> Self {
        let d = 2.0 * lat.s as f64;
        let axes = dims.map(|n| {
            (0..=2 * lat.s as usize * (n + 3))
                .map(|l| l as f64 / d - 1.5)
                .collect()
        });
        Positions { lat, axes }
    }

    /// [`Lattice::position`] of `l`.
    #[inline]
    pub(crate) fn at(&self, l: [i32; 3]) -> DVec3 {
        let get = |a: usize| self.axes[a].get(l[a] as usize).copied();
        match (get(0), get(1), get(2)) {
            (Some(x), Some(y), Some(z)) => DVec3::new(x, y, z),
            _ => self.lat.position(l),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coarse_vertex_and_face_centre_positions() {
        let lat = Lattice { s: 5 };
        // coarse vertex (0,0,0) = fine vertex (0,0,0): index position -0.5
        let l = lat.of_fine_vertex([0, 0, 0]);
        assert_eq!(lat.position(l), DVec3::splat(-0.5));
        // fine vertex (5, 10, 15) = coarse vertex (1, 2, 3)
        assert_eq!(
            lat.position(lat.of_fine_vertex([5, 10, 15])),
            DVec3::new(0.5, 1.5, 2.5)
        );
        let k = lat.key([1, 2, 3]);
        assert_eq!(lat.unpack(k), [1, 2, 3]);
        assert!(max_extent(7) > 70_000);
    }

    #[test]
    fn the_position_table_gives_the_computed_positions() {
        for s in [5, 7] {
            let lat = Lattice { s };
            let table = Positions::new(lat, [3, 4, 2]);
            for x in 0..2 * s * 6 {
                for (y, z) in [(0, 0), (x, 2 * s * 4), (2 * s * 5, x)] {
                    let l = [x, y, z];
                    assert_eq!(
                        table.at(l).to_array().map(f64::to_bits),
                        lat.position(l).to_array().map(f64::to_bits)
                    );
                }
            }
        }
    }
}
