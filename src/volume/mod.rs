//! Label volumes: a flat buffer of dense label ids on a 3-D grid, with the
//! physical geometry of the file it came from.
//!
//! This module owns the in-memory representation every later stage reads:
//! [`Dims`] (shape and strides, x fastest), [`Geometry`] (index ↔ LPS mm) and
//! [`LabelVolume`] (dense ids `0..n` plus the table of original label values, so
//! that outputs can name labels by the values the user knows).

mod geometry;
mod padded;

pub use geometry::Geometry;
pub use padded::PaddedLabels;

use crate::error::{Error, Result};
use rayon::prelude::*;

/// Largest number of voxels septa accepts in one volume (4 Gi voxels, 8 GiB of ids).
pub const MAX_VOXELS: usize = 1 << 32;
/// Largest extent along one axis (topology keys pack coordinates into 21 bits on a
/// grid refined up to 14 × per voxel).
pub const MAX_AXIS: usize = 100_000;

/// Shape of a 3-D grid, x fastest: the voxel `(x, y, z)` is at
/// `x + nx * (y + ny * z)` in every flat buffer of septa.
///
/// ```
/// use septa::volume::Dims;
/// let d = Dims::new(4, 3, 2).unwrap();
/// assert_eq!(d.len(), 24);
/// assert_eq!(d.index(1, 2, 1), 1 + 4 * (2 + 3 * 1));
/// assert_eq!(d.coords(d.index(3, 0, 1)), [3, 0, 1]);
/// assert_eq!(d.strides(), [1, 4, 12]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Dims {
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
}

impl Dims {
    /// Checks that every extent is positive and not absurd, and that the voxel
    /// count neither overflows nor exceeds [`MAX_VOXELS`].
    pub fn new(nx: usize, ny: usize, nz: usize) -> Result<Self> {
        for (axis, n) in [nx, ny, nz].into_iter().enumerate() {
            if n == 0 {
                return Err(Error::invalid(format!(
                    "dimension {axis} is 0: every extent must be at least 1"
                )));
            }
            if n > MAX_AXIS {
                return Err(Error::invalid(format!(
                    "dimension {axis} is {n}: larger than the supported {MAX_AXIS} voxels per axis"
                )));
            }
        }
        let len = nx.checked_mul(ny).and_then(|v| v.checked_mul(nz));
        match len {
            Some(len) if len <= MAX_VOXELS => Ok(Dims { nx, ny, nz }),
            _ => Err(Error::invalid(format!(
                "dimensions {nx}×{ny}×{nz} give more than the supported {MAX_VOXELS} voxels"
            ))),
        }
    }

    /// Number of voxels.
    #[inline]
    pub fn len(&self) -> usize {
        self.nx * self.ny * self.nz
    }

    /// Always false: a valid grid has at least one voxel.
    #[inline]
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Flat index of voxel (x, y, z).
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.nx * (y + self.ny * z)
    }

    /// Flat index steps along x, y, z.
    #[inline]
    pub fn strides(&self) -> [usize; 3] {
        [1, self.nx, self.nx * self.ny]
    }

    /// (x, y, z) of a flat index.
    #[inline]
    pub fn coords(&self, i: usize) -> [usize; 3] {
        let x = i % self.nx;
        let r = i / self.nx;
        [x, r % self.ny, r / self.ny]
    }

    /// Extents as an array.
    pub fn to_array(&self) -> [usize; 3] {
        [self.nx, self.ny, self.nz]
    }
}

/// A dense label id: `0..label_count()`, ordered like the original values.
pub type LabelId = u16;

/// Largest number of distinct labels in one volume.
pub const MAX_LABELS: usize = LabelId::MAX as usize;

/// A segmented volume: one label per voxel, in physical space.
///
/// Labels are stored as dense ids (`u16`, ascending with the original values), so
/// that hot loops index small tables; [`LabelVolume::value`] gives the original
/// label value back for output.
///
/// ```
/// use septa::volume::{Dims, Geometry, LabelVolume};
/// let dims = Dims::new(2, 1, 1).unwrap();
/// let v = LabelVolume::from_values(dims, &[7, -3], Geometry::identity()).unwrap();
/// assert_eq!(v.values(), &[-3, 7]);
/// assert_eq!(v.ids(), &[1, 0]);
/// assert_eq!(v.value(v.id_at(0, 0, 0)), 7);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct LabelVolume {
    dims: Dims,
    ids: Vec<LabelId>,
    values: Vec<i64>,
    geometry: Geometry,
}

impl LabelVolume {
    /// From original label values (x fastest).
    pub fn from_values(dims: Dims, values: &[i64], geometry: Geometry) -> Result<Self> {
        if values.len() != dims.len() {
            return Err(Error::invalid(format!(
                "{} label values given for a {}×{}×{} grid ({} voxels)",
                values.len(),
                dims.nx,
                dims.ny,
                dims.nz,
                dims.len()
            )));
        }
        let mut table: Vec<i64> = values
            .par_chunks(1 << 16)
            .flat_map_iter(unique_sorted)
            .collect();
        table.par_sort_unstable();
        table.dedup();
        if table.len() > MAX_LABELS {
            return Err(Error::invalid(format!(
                "the volume has {} distinct labels; septa supports at most {MAX_LABELS}",
                table.len()
            )));
        }
        let ids = values
            .par_iter()
            .map(|v| table.binary_search(v).expect("value is in the table") as LabelId)
            .collect();
        Ok(LabelVolume {
            dims,
            ids,
            values: table,
            geometry,
        })
    }

    /// From dense ids and their value table. `values` must be strictly ascending
    /// and every id must index into it.
    pub fn from_ids(
        dims: Dims,
        ids: Vec<LabelId>,
        values: Vec<i64>,
        geometry: Geometry,
    ) -> Result<Self> {
        if ids.len() != dims.len() {
            return Err(Error::invalid(format!(
                "{} ids given for {} voxels",
                ids.len(),
                dims.len()
            )));
        }
        if values.is_empty() || values.len() > MAX_LABELS || values.windows(2).any(|w| w[0] >= w[1])
        {
            return Err(Error::invalid(
                "label values must be non-empty and strictly ascending",
            ));
        }
        let n = values.len() as LabelId;
        if ids.par_iter().any(|&i| i >= n) {
            return Err(Error::invalid("a label id is outside the value table"));
        }
        Ok(LabelVolume {
            dims,
            ids,
            values,
            geometry,
        })
    }

    /// Grid shape.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// Index ↔ physical map.
    pub fn geometry(&self) -> &Geometry {
        &self.geometry
    }

    /// Replaces the geometry (same grid).
    pub fn set_geometry(&mut self, geometry: Geometry) {
        self.geometry = geometry;
    }

    /// Dense ids, x fastest.
    pub fn ids(&self) -> &[LabelId] {
        &self.ids
    }

    /// Original label values, indexed by dense id (ascending).
    pub fn values(&self) -> &[i64] {
        &self.values
    }

    /// Number of distinct labels.
    pub fn label_count(&self) -> usize {
        self.values.len()
    }

    /// Original value of a dense id.
    pub fn value(&self, id: LabelId) -> i64 {
        self.values[id as usize]
    }

    /// Dense id of an original value, if it occurs.
    pub fn id_of(&self, value: i64) -> Option<LabelId> {
        self.values.binary_search(&value).ok().map(|i| i as LabelId)
    }

    /// Dense id at voxel (x, y, z).
    #[inline]
    pub fn id_at(&self, x: usize, y: usize, z: usize) -> LabelId {
        self.ids[self.dims.index(x, y, z)]
    }

    /// Voxel count per dense id.
    pub fn voxel_counts(&self) -> Vec<u64> {
        let n = self.values.len();
        self.ids
            .par_chunks(1 << 16)
            .fold(
                || vec![0u64; n],
                |mut acc, chunk| {
                    for &i in chunk {
                        acc[i as usize] += 1;
                    }
                    acc
                },
            )
            .reduce(
                || vec![0u64; n],
                |mut a, b| {
                    a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                    a
                },
            )
    }

    /// The label that is most frequent on the six border faces of the volume (ties
    /// go to the smaller label): septa's default for "outside the volume".
    pub fn most_frequent_border_label(&self) -> LabelId {
        let d = self.dims;
        let mut counts = vec![0u64; self.values.len()];
        for z in 0..d.nz {
            for y in 0..d.ny {
                let on_yz_border = z == 0 || z + 1 == d.nz || y == 0 || y + 1 == d.ny;
                if on_yz_border {
                    for x in 0..d.nx {
                        counts[self.id_at(x, y, z) as usize] += 1;
                    }
                } else {
                    counts[self.id_at(0, y, z) as usize] += 1;
                    if d.nx > 1 {
                        counts[self.id_at(d.nx - 1, y, z) as usize] += 1;
                    }
                }
            }
        }
        let mut best = 0;
        for (i, &c) in counts.iter().enumerate() {
            if c > counts[best] {
                best = i;
            }
        }
        best as LabelId
    }
}

fn unique_sorted(chunk: &[i64]) -> Vec<i64> {
    let mut u = Vec::new();
    let mut last = None;
    for &v in chunk {
        if last != Some(v) {
            last = Some(v);
            u.push(v);
        }
    }
    u.sort_unstable();
    u.dedup();
    u
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dims_reject_zero_and_overflow() {
        assert!(Dims::new(0, 1, 1).is_err());
        assert!(Dims::new(MAX_AXIS + 1, 1, 1).is_err());
        assert!(Dims::new(MAX_AXIS, MAX_AXIS, MAX_AXIS).is_err());
        assert!(Dims::new(3, 4, 5).is_ok());
    }

    #[test]
    fn dense_ids_and_counts() {
        let dims = Dims::new(3, 2, 1).unwrap();
        let v = LabelVolume::from_values(dims, &[5, 5, 0, 9, 0, 5], Geometry::identity()).unwrap();
        assert_eq!(v.values(), &[0, 5, 9]);
        assert_eq!(v.voxel_counts(), vec![2, 3, 1]);
        assert_eq!(v.id_of(9), Some(2));
        assert_eq!(v.id_of(4), None);
        assert_eq!(v.most_frequent_border_label(), 1);
    }
}
