//! A label grid with one layer of "outside" cells around it.
//!
//! The outside of the volume counts as a label, so that every label's surface is
//! closed. Rather than test bounds in hot loops, the stages work on a copy of the
//! ids with a one-cell border holding the outside label: cell `(x, y, z)` of the
//! volume (x in `0..nx`) is cell `(x + 1, y + 1, z + 1)` of the padded buffer.
//! Grid vertex `(i, j, k)` (i in `0..=nx`) is the corner shared by padded cells
//! `i..=i+1`, `j..=j+1`, `k..=k+1`.

use rayon::prelude::*;

use super::{Dims, LabelId, LabelVolume};

/// Dense ids with a one-cell border of the outside label.
#[derive(Clone, Debug)]
pub struct PaddedLabels {
    dims: Dims,
    pdims: [usize; 3],
    data: Vec<LabelId>,
    outside: LabelId,
}

impl PaddedLabels {
    /// Copies the volume's ids into a buffer bordered by `outside`.
    pub fn new(volume: &LabelVolume, outside: LabelId) -> Self {
        let dims = volume.dims();
        let pdims = [dims.nx + 2, dims.ny + 2, dims.nz + 2];
        let plane = pdims[0] * pdims[1];
        let mut data = vec![outside; plane * pdims[2]];
        let ids = volume.ids();
        data.par_chunks_mut(plane)
            .enumerate()
            .for_each(|(pz, slab)| {
                if pz == 0 || pz == pdims[2] - 1 {
                    return;
                }
                let z = pz - 1;
                for y in 0..dims.ny {
                    let src = &ids[dims.index(0, y, z)..dims.index(0, y, z) + dims.nx];
                    let start = (y + 1) * pdims[0] + 1;
                    slab[start..start + dims.nx].copy_from_slice(src);
                }
            });
        PaddedLabels {
            dims,
            pdims,
            data,
            outside,
        }
    }

    /// Shape of the volume (without the border).
    #[inline]
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// Shape of the padded buffer.
    #[inline]
    pub fn padded_dims(&self) -> [usize; 3] {
        self.pdims
    }

    /// The label of everything outside the volume.
    #[inline]
    pub fn outside(&self) -> LabelId {
        self.outside
    }

    /// The padded buffer, x fastest.
    #[inline]
    pub fn data(&self) -> &[LabelId] {
        &self.data
    }

    /// Flat steps along x, y, z in the padded buffer.
    #[inline]
    pub fn strides(&self) -> [usize; 3] {
        [1, self.pdims[0], self.pdims[0] * self.pdims[1]]
    }

    /// Flat index of padded cell (px, py, pz).
    #[inline]
    pub fn padded_index(&self, px: usize, py: usize, pz: usize) -> usize {
        px + self.pdims[0] * (py + self.pdims[1] * pz)
    }

    /// Whether volume cell (x, y, z) — possibly −1 or n, the border — is in the buffer.
    #[inline]
    pub fn in_buffer(&self, x: i32, y: i32, z: i32) -> bool {
        x >= -1
            && y >= -1
            && z >= -1
            && (x as i64) <= self.dims.nx as i64
            && (y as i64) <= self.dims.ny as i64
            && (z as i64) <= self.dims.nz as i64
    }

    /// Label of volume cell (x, y, z); any cell outside the volume is `outside`.
    #[inline]
    pub fn get(&self, x: i32, y: i32, z: i32) -> LabelId {
        if self.in_buffer(x, y, z) {
            self.data[self.padded_index((x + 1) as usize, (y + 1) as usize, (z + 1) as usize)]
        } else {
            self.outside
        }
    }

    /// Labels of the 8 cells around grid vertex (i, j, k), in octant order
    /// (bit 0 = +x side, bit 1 = +y, bit 2 = +z). Vertices beyond the grid see
    /// the outside label.
    #[inline]
    pub fn vertex_octants(&self, i: i32, j: i32, k: i32) -> [LabelId; 8] {
        let mut out = [0; 8];
        for (o, slot) in out.iter_mut().enumerate() {
            *slot = self.get(
                i - 1 + (o & 1) as i32,
                j - 1 + ((o >> 1) & 1) as i32,
                k - 1 + ((o >> 2) & 1) as i32,
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Geometry;

    #[test]
    fn border_is_outside() {
        let dims = Dims::new(2, 3, 1).unwrap();
        let v = LabelVolume::from_values(dims, &[1, 2, 3, 4, 5, 6], Geometry::identity()).unwrap();
        let p = PaddedLabels::new(&v, 9);
        assert_eq!(p.get(-1, 0, 0), 9);
        assert_eq!(p.get(0, 0, 0), v.id_at(0, 0, 0));
        assert_eq!(p.get(1, 2, 0), v.id_at(1, 2, 0));
        assert_eq!(p.get(2, 0, 0), 9);
        assert_eq!(p.get(0, 0, 1), 9);
        assert_eq!(p.get(-5, 0, 0), 9);
        let o = p.vertex_octants(0, 0, 0);
        assert_eq!(o[7], v.id_at(0, 0, 0));
        assert!(o[..7].iter().all(|&l| l == 9));
    }
}
