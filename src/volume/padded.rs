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
    candidates: std::sync::OnceLock<Vec<u64>>,
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
            candidates: std::sync::OnceLock::new(),
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

    /// Grid vertices whose 8 cells may hold more than one label: one bit per
    /// padded index `b`, where vertex (i, j, k) has `b` = padded index of
    /// (i, j, k) (its octant-0 cell). A superset of the non-uniform vertices,
    /// computed once (in parallel, 64 cells per word) and cached; scanning its
    /// set bits skips the uniform bulk of a volume.
    pub fn vertex_candidates(&self) -> &[u64] {
        self.candidates.get_or_init(|| self.compute_candidates())
    }

    /// Candidate vertices (see [`Self::vertex_candidates`]) of vertex plane `k`,
    /// as `(i, j, b)` with `b` the padded index of octant 0, in (j, i) order.
    pub fn candidates_in_plane(&self, k: usize) -> impl Iterator<Item = (i32, i32, usize)> + '_ {
        let bits = self.vertex_candidates();
        let (nx, ny) = (self.dims.nx, self.dims.ny);
        let first = self.padded_index(0, 0, k);
        let last = self.padded_index(nx, ny, k);
        let pd0 = self.pdims[0];
        (first / 64..=last / 64).flat_map(move |w| {
            let mut word = bits[w];
            if w == first / 64 {
                word &= !0u64 << (first % 64);
            }
            if w == last / 64 && last % 64 < 63 {
                word &= (1u64 << (last % 64 + 1)) - 1;
            }
            std::iter::from_fn(move || {
                while word != 0 {
                    let b = w * 64 + word.trailing_zeros() as usize;
                    word &= word - 1;
                    let r = b - first;
                    let (i, j) = (r % pd0, r / pd0);
                    if i <= nx && j <= ny {
                        return Some((i as i32, j as i32, b));
                    }
                }
                None
            })
        })
    }

    fn compute_candidates(&self) -> Vec<u64> {
        let n = self.data.len();
        let [sx, sy, sz] = self.strides();
        let words = n.div_ceil(64);
        let data = &self.data;
        // D: the cell differs from a +x, +y or +z neighbour
        let differs: Vec<u64> = (0..words)
            .into_par_iter()
            .map(|w| {
                let mut word = 0u64;
                let start = w * 64;
                let end = (start + 64).min(n.saturating_sub(sz + sy + sx));
                for i in start..end {
                    let c = data[i];
                    if c != data[i + sx] || c != data[i + sy] || c != data[i + sz] {
                        word |= 1 << (i - start);
                    }
                }
                word
            })
            .collect();
        // a vertex is a candidate when one of its 7 low cells differs: OR of D
        // shifted down by each of the 7 octant offsets
        let offsets = [0, sx, sy, sx + sy, sz, sz + sx, sz + sy];
        (0..words)
            .into_par_iter()
            .map(|w| {
                offsets
                    .iter()
                    .fold(0u64, |acc, &off| acc | shifted_word(&differs, w, off))
            })
            .collect()
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

/// Word `w` of the bitset `bits` shifted toward lower indices by `off` bits
/// (bit b of the result = bit b + off of `bits`).
#[inline]
fn shifted_word(bits: &[u64], w: usize, off: usize) -> u64 {
    let (q, r) = (w + off / 64, off % 64);
    let lo = bits.get(q).copied().unwrap_or(0);
    if r == 0 {
        return lo;
    }
    let hi = bits.get(q + 1).copied().unwrap_or(0);
    (lo >> r) | (hi << (64 - r))
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

    #[test]
    fn candidates_cover_every_non_uniform_vertex() {
        let dims = Dims::new(9, 7, 5).unwrap();
        let values: Vec<i64> = (0..dims.len() as i64)
            .map(|i| ((i * 7919) % 13 == 0) as i64 + ((i * 31) % 17 == 0) as i64)
            .collect();
        let v = LabelVolume::from_values(dims, &values, Geometry::identity()).unwrap();
        let p = PaddedLabels::new(&v, 0);
        let bits = p.vertex_candidates();
        let mut candidates = 0;
        for k in 0..=dims.nz as i32 {
            for j in 0..=dims.ny as i32 {
                for i in 0..=dims.nx as i32 {
                    let o = p.vertex_octants(i, j, k);
                    let b = p.padded_index(i as usize, j as usize, k as usize);
                    let set = bits[b / 64] >> (b % 64) & 1 == 1;
                    candidates += set as usize;
                    if o.iter().any(|&l| l != o[0]) {
                        assert!(
                            set,
                            "vertex ({i},{j},{k}) is not uniform but not a candidate"
                        );
                    }
                }
            }
        }
        assert!(candidates < (dims.nx + 1) * (dims.ny + 1) * (dims.nz + 1));
    }
}
