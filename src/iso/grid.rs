//! Which voxels are active, which voxel faces are boundary faces, the dense
//! id of each boundary face, and its support point.
//!
//! Everything lives on the *padded* grid: the volume with one layer of
//! inactive cells around it, so that the outside of the volume counts as
//! inactive and every surface closes. Padded cell `p = i + P0 (j + P1 k)` is
//! voxel `(i − 1, j − 1, k − 1)`.
//!
//! - [`Activity`]: one bit per padded cell, "value ≥ iso", behind a guard of
//!   zero words so that a 64-bit window at any cell offset can be read without
//!   bounds checks.
//! - [`Faces`]: one bit per padded cell and axis, "the face on the cell's low
//!   side along this axis separates an active from an inactive cell", plus
//!   per-word popcount prefixes: the id of a boundary face is its rank, found
//!   in O(1). Ids depend only on the volume (axis 0 faces first, then 1, then
//!   2, each by cell index), never on the thread count.
//! - [`support_points`]: the point of each boundary face, in index space: the
//!   face centre, or with displacement the linear interpolation of the iso
//!   value along the range vector from the active voxel centre to the inactive
//!   one (VESTA's Fig. 2). Faces on the border of the volume keep their centre
//!   (the outside has no value).

use glam::DVec3;
use rayon::prelude::*;

use super::Scalar;
use crate::volume::Dims;

/// Displaced support points stay this fraction of a voxel away from the voxel
/// centres, so that no two support points coincide and no triangle degenerates
/// when a voxel value equals the iso value exactly.
pub(crate) const MIN_FRACTION: f64 = 1e-3;

/// Padded extents and strides.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Padded {
    pub dims: Dims,
    pub p: [usize; 3],
    pub stride: [usize; 3],
    pub len: usize,
}

impl Padded {
    pub fn new(dims: Dims) -> Self {
        let p = [dims.nx + 2, dims.ny + 2, dims.nz + 2];
        Padded {
            dims,
            p,
            stride: [1, p[0], p[0] * p[1]],
            len: p[0] * p[1] * p[2],
        }
    }

    /// Padded cell coordinates of a padded index.
    #[inline]
    pub fn coords(&self, q: usize) -> [usize; 3] {
        [
            q % self.p[0],
            (q / self.p[0]) % self.p[1],
            q / self.stride[2],
        ]
    }

    /// Index into the unpadded samples of padded cell coordinates, if interior.
    #[inline]
    pub fn voxel(&self, c: [usize; 3]) -> Option<usize> {
        let d = self.dims;
        let inside =
            (1..=d.nx).contains(&c[0]) && (1..=d.ny).contains(&c[1]) && (1..=d.nz).contains(&c[2]);
        inside.then(|| (c[0] - 1) + d.nx * ((c[1] - 1) + d.ny * (c[2] - 1)))
    }

    /// Offsets of the 8 cells around the grid vertex whose octant-0 cell is
    /// `q` (bit 0 of the octant = +x, as in [`crate::star`]).
    pub fn octant_offsets(&self) -> [usize; 8] {
        let [sx, sy, sz] = self.stride;
        [0, sx, sy, sx + sy, sz, sz + sx, sz + sy, sz + sy + sx]
    }
}

/// One bit per padded cell: is it active?
pub(crate) struct Activity {
    pub grid: Padded,
    /// Zero bits before cell 0 (a multiple of 64, at least one z stride).
    pub guard: usize,
    pub bits: Vec<u64>,
    pub active: u64,
}

impl Activity {
    /// Marks every voxel with value ≥ `iso`, in parallel over 64-cell words.
    pub fn new<T: Scalar>(values: &[T], dims: Dims, iso: f64) -> Self {
        let grid = Padded::new(dims);
        let guard_words = (grid.stride[2] + grid.stride[1] + 64) / 64 + 1;
        let cell_words = grid.len.div_ceil(64);
        let tail_words = guard_words + 2;
        let mut bits = vec![0u64; guard_words + cell_words + tail_words];
        bits[guard_words..guard_words + cell_words]
            .par_chunks_mut(1024)
            .enumerate()
            .for_each(|(chunk, words)| {
                for (k, word) in words.iter_mut().enumerate() {
                    *word = active_word(values, &grid, (chunk * 1024 + k) * 64, iso);
                }
            });
        let active = bits.par_iter().map(|w| w.count_ones() as u64).sum();
        Activity {
            grid,
            guard: guard_words * 64,
            bits,
            active,
        }
    }

    /// 64 activity bits starting at padded cell `q` (which may lie up to the
    /// guard before cell 0 or past the end).
    #[inline]
    pub fn window(&self, q: isize) -> u64 {
        let bit = (self.guard as isize + q) as usize;
        let (w, s) = (bit >> 6, bit & 63);
        if s == 0 {
            self.bits[w]
        } else {
            (self.bits[w] >> s) | (self.bits[w + 1] << (64 - s))
        }
    }

    /// Whether padded cell `q` is active.
    #[inline]
    pub fn get(&self, q: usize) -> bool {
        let bit = self.guard + q;
        self.bits[bit >> 6] >> (bit & 63) & 1 == 1
    }
}

/// Activity bits of padded cells `start .. start + 64`.
fn active_word<T: Scalar>(values: &[T], grid: &Padded, start: usize, iso: f64) -> u64 {
    let mut word = 0u64;
    if start >= grid.len {
        return word;
    }
    let [mut i, mut j, mut k] = grid.coords(start);
    let d = grid.dims;
    let end = (start + 64).min(grid.len);
    let mut t = 0;
    while start + t < end {
        // run of interior cells along x in this row
        let row_interior = (1..=d.ny).contains(&j) && (1..=d.nz).contains(&k);
        let run = (grid.p[0] - i).min(end - start - t);
        if row_interior {
            let lo = i.max(1);
            let hi = (i + run).min(d.nx + 1);
            if lo < hi {
                let row = d.nx * ((j - 1) + d.ny * (k - 1));
                // branch-free, so that the comparison vectorizes
                let mut run_bits = 0u64;
                for (x, v) in values[row + lo - 1..row + hi - 1].iter().enumerate() {
                    run_bits |= ((v.to_f64() >= iso) as u64) << x;
                }
                word |= run_bits << (t + lo - i);
            }
        }
        t += run;
        i += run;
        if i == grid.p[0] {
            i = 0;
            j += 1;
            if j == grid.p[1] {
                j = 0;
                k += 1;
            }
        }
    }
    word
}

/// Dense ids of the boundary faces.
pub(crate) struct Faces {
    /// Bit `t` of word `w`: the face on the low side of cell `64 w + t` along the axis.
    pub bits: [Vec<u64>; 3],
    rank: [Vec<u32>; 3],
    base: [u32; 3],
    pub total: u64,
}

impl Faces {
    /// Finds and numbers the boundary faces (word-parallel XOR of shifted activity).
    pub fn new(act: &Activity) -> Self {
        let words = act.grid.len.div_ceil(64);
        let mut bits: [Vec<u64>; 3] = Default::default();
        let mut rank: [Vec<u32>; 3] = Default::default();
        let mut base = [0u32; 3];
        let mut total = 0u64;
        for a in 0..3 {
            let st = act.grid.stride[a] as isize;
            bits[a] = (0..words)
                .into_par_iter()
                .map(|w| {
                    let q = (w * 64) as isize;
                    act.window(q) ^ act.window(q - st)
                })
                .collect();
            let mut acc = 0u64;
            rank[a] = bits[a]
                .iter()
                .map(|w| {
                    let r = acc as u32;
                    acc += w.count_ones() as u64;
                    r
                })
                .collect();
            base[a] = total.min(u32::MAX as u64) as u32;
            total += acc;
        }
        Faces {
            bits,
            rank,
            base,
            total,
        }
    }

    /// Id of the boundary face on the low side of padded cell `q` along `axis`.
    #[inline]
    pub fn id(&self, axis: usize, q: usize) -> u32 {
        let w = self.bits[axis][q >> 6];
        let below = w & ((1u64 << (q & 63)) - 1);
        debug_assert!(w >> (q & 63) & 1 == 1, "not a boundary face");
        self.base[axis] + self.rank[axis][q >> 6] + below.count_ones()
    }
}

/// Support points of all boundary faces in id order, in index space (voxel
/// centres at integer coordinates).
pub(crate) fn support_points<T: Scalar>(
    values: &[T],
    act: &Activity,
    faces: &Faces,
    iso: f64,
    displace: bool,
) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(faces.total as usize);
    for a in 0..3 {
        let parts: Vec<Vec<DVec3>> = faces.bits[a]
            .par_chunks(1024)
            .enumerate()
            .map(|(chunk, words)| {
                let mut v = Vec::new();
                for (k, &word) in words.iter().enumerate() {
                    let mut left = word;
                    while left != 0 {
                        let t = left.trailing_zeros() as usize;
                        left &= left - 1;
                        let q = (chunk * 1024 + k) * 64 + t;
                        v.push(support_point(values, act, a, q, iso, displace));
                    }
                }
                v
            })
            .collect();
        for p in parts {
            out.extend(p);
        }
    }
    out
}

/// Support point of the face on the low side of padded cell `q` along `axis`.
fn support_point<T: Scalar>(
    values: &[T],
    act: &Activity,
    axis: usize,
    q: usize,
    iso: f64,
    displace: bool,
) -> DVec3 {
    let g = &act.grid;
    let hi = g.coords(q);
    let mut lo = hi;
    lo[axis] -= 1;
    // index space of the high cell's voxel; the face centre is half a voxel below
    let centre = DVec3::new(hi[0] as f64 - 1.0, hi[1] as f64 - 1.0, hi[2] as f64 - 1.0);
    let mut p = centre;
    p[axis] -= 0.5;
    if !displace {
        return p;
    }
    let (Some(vh), Some(vl)) = (g.voxel(hi), g.voxel(lo)) else {
        return p;
    };
    let (vh, vl) = (values[vh].to_f64(), values[vl].to_f64());
    let hi_active = act.get(q);
    let (va, vi) = if hi_active { (vh, vl) } else { (vl, vh) };
    let t = interpolation_fraction(va, vi, iso);
    // t: fraction of the way from the active centre to the inactive one
    if hi_active {
        p[axis] = centre[axis] - t;
    } else {
        p[axis] = centre[axis] - 1.0 + t;
    }
    p
}

/// Where the iso value lies between an active value `va` (≥ iso) and an
/// inactive one `vi` (< iso), as a fraction from the active end, kept within
/// [`MIN_FRACTION`], 1 − [`MIN_FRACTION`]; ½ if it is not a number (NaN or
/// infinite voxel values).
#[inline]
pub(crate) fn interpolation_fraction(va: f64, vi: f64, iso: f64) -> f64 {
    let t = (va - iso) / (va - vi);
    if t.is_finite() {
        t.clamp(MIN_FRACTION, 1.0 - MIN_FRACTION)
    } else {
        0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn activity_matches_values_and_padding() {
        let dims = Dims::new(5, 3, 2).unwrap();
        let values: Vec<f64> = (0..30).map(|i| ((i * 7) % 11) as f64).collect();
        let act = Activity::new(&values, dims, 5.0);
        let g = act.grid;
        let mut n = 0;
        for q in 0..g.len {
            let expect = g.voxel(g.coords(q)).is_some_and(|v| values[v] >= 5.0);
            assert_eq!(act.get(q), expect, "cell {q}");
            n += expect as u64;
        }
        assert_eq!(act.active, n);
        // windows read across word boundaries and into the guard
        for q in -70isize..(g.len as isize + 10) {
            let w = act.window(q);
            for t in 0..64isize {
                let c = q + t;
                let expect = c >= 0 && (c as usize) < g.len && act.get(c as usize);
                assert_eq!(w >> t & 1 == 1, expect);
            }
        }
    }

    #[test]
    fn faces_are_numbered_densely() {
        let dims = Dims::new(4, 4, 4).unwrap();
        let values: Vec<u8> = (0..64).map(|i| ((i * 37) % 5 == 0) as u8).collect();
        let act = Activity::new(&values, dims, 1.0);
        let faces = Faces::new(&act);
        let g = act.grid;
        let mut expect = 0u32;
        for a in 0..3 {
            for q in g.stride[a]..g.len {
                if act.get(q) != act.get(q - g.stride[a]) {
                    assert_eq!(faces.id(a, q), expect);
                    expect += 1;
                }
            }
        }
        assert_eq!(faces.total, expect as u64);
        let pts = support_points(&values, &act, &faces, 1.0, false);
        assert_eq!(pts.len(), expect as usize);
    }

    #[test]
    fn interpolation_is_linear_and_clamped() {
        assert_eq!(interpolation_fraction(133.0, 0.0, 100.0), 33.0 / 133.0);
        assert_eq!(interpolation_fraction(100.0, 0.0, 100.0), MIN_FRACTION);
        assert_eq!(interpolation_fraction(f64::NAN, 0.0, 1.0), 0.5);
        assert_eq!(interpolation_fraction(f64::INFINITY, 0.0, 1.0), 0.5);
    }
}
