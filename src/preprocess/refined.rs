//! [`RefinedVolume`]: the coarse label grid plus a sparse set of voxels split
//! into s³ subvoxels (s = 5, or 7 with separation constraints).
//!
//! Coordinates: coarse cells are `(x, y, z)` with the volume at `0..n` and the
//! outside beyond it; fine cells are `(fx, fy, fz)` with coarse cell `c` covering
//! fine cells `s·c .. s·c + s`. Fine grid vertex `f` sits at coarse position
//! `f / s`. Only refined voxels store subvoxels ("virtual" subdivision): a
//! few thousand on real data, never a full fine volume.

use hashbrown::HashMap;

use crate::volume::{Dims, LabelId, PaddedLabels};

/// Packs coarse cell coordinates (each ≥ −1) into a map key.
#[inline]
pub(crate) fn cell_key(c: [i32; 3]) -> u64 {
    ((c[0] + 1) as u64) | (((c[1] + 1) as u64) << 21) | (((c[2] + 1) as u64) << 42)
}

/// One refined voxel: its coarse position and its s³ subvoxel labels (x fastest).
#[derive(Clone, Copy, Debug)]
pub struct RefinedVoxel<'a> {
    pub cell: [i32; 3],
    pub labels: &'a [LabelId],
}

/// The label volume after fattening: coarse voxels plus sparse refined voxels.
#[derive(Clone, Debug)]
pub struct RefinedVolume {
    grid: PaddedLabels,
    s: i32,
    /// Refined cells, sorted by (z, y, x).
    cells: Vec<[i32; 3]>,
    /// Subvoxel labels, s³ per refined cell, in the order of `cells`.
    sub: Vec<LabelId>,
    slot_of: HashMap<u64, u32>,
    /// One bit per padded cell: refined or not.
    refined_bits: Vec<u64>,
}

impl RefinedVolume {
    /// Assembles a refined volume from sorted refined cells and their subvoxels.
    pub(crate) fn new(grid: PaddedLabels, s: i32, cells: Vec<[i32; 3]>, sub: Vec<LabelId>) -> Self {
        debug_assert_eq!(sub.len(), cells.len() * (s * s * s) as usize);
        let [px, py, pz] = grid.padded_dims();
        let mut refined_bits = vec![0u64; (px * py * pz).div_ceil(64)];
        let mut slot_of = HashMap::with_capacity(cells.len());
        for (slot, c) in cells.iter().enumerate() {
            slot_of.insert(cell_key(*c), slot as u32);
            if grid.in_buffer(c[0], c[1], c[2]) {
                let i = grid.padded_index(
                    (c[0] + 1) as usize,
                    (c[1] + 1) as usize,
                    (c[2] + 1) as usize,
                );
                refined_bits[i / 64] |= 1 << (i % 64);
            }
        }
        RefinedVolume {
            grid,
            s,
            cells,
            sub,
            slot_of,
            refined_bits,
        }
    }

    /// A volume with nothing refined.
    pub fn unrefined(grid: PaddedLabels, s: i32) -> Self {
        Self::new(grid, s, Vec::new(), Vec::new())
    }

    /// The subdivision factor s (5, or 7 with separation constraints).
    #[inline]
    pub fn subdivision(&self) -> i32 {
        self.s
    }

    /// The coarse grid with its outside border.
    #[inline]
    pub fn grid(&self) -> &PaddedLabels {
        &self.grid
    }

    /// Shape of the volume.
    #[inline]
    pub fn dims(&self) -> Dims {
        self.grid.dims()
    }

    /// The label of everything outside the volume.
    #[inline]
    pub fn outside(&self) -> LabelId {
        self.grid.outside()
    }

    /// Label of coarse cell `c` before refinement (outside the volume: the outside label).
    #[inline]
    pub fn coarse_label(&self, c: [i32; 3]) -> LabelId {
        self.grid.get(c[0], c[1], c[2])
    }

    /// Whether coarse cell `c` is refined.
    #[inline]
    pub fn is_refined(&self, c: [i32; 3]) -> bool {
        if self.cells.is_empty() || !self.grid.in_buffer(c[0], c[1], c[2]) {
            return false;
        }
        let i = self.grid.padded_index(
            (c[0] + 1) as usize,
            (c[1] + 1) as usize,
            (c[2] + 1) as usize,
        );
        self.refined_bits[i / 64] >> (i % 64) & 1 == 1
    }

    /// Whether padded cell with flat padded index `i` is refined (fast path).
    #[inline]
    pub fn is_refined_padded(&self, i: usize) -> bool {
        !self.cells.is_empty() && self.refined_bits[i / 64] >> (i % 64) & 1 == 1
    }

    /// Subvoxels of a refined coarse cell.
    #[inline]
    pub fn subvoxels(&self, c: [i32; 3]) -> Option<&[LabelId]> {
        let n = (self.s * self.s * self.s) as usize;
        self.slot_of
            .get(&cell_key(c))
            .map(|&slot| &self.sub[slot as usize * n..(slot as usize + 1) * n])
    }

    /// Label of fine cell `f` (the subvoxel if its coarse cell is refined, else
    /// the coarse label).
    #[inline]
    pub fn fine_label(&self, f: [i32; 3]) -> LabelId {
        let s = self.s;
        let c = [f[0].div_euclid(s), f[1].div_euclid(s), f[2].div_euclid(s)];
        if self.is_refined(c) {
            let l = [f[0] - c[0] * s, f[1] - c[1] * s, f[2] - c[2] * s];
            let sub = self.subvoxels(c).expect("refined cell has subvoxels");
            sub[(l[0] + s * (l[1] + s * l[2])) as usize]
        } else {
            self.coarse_label(c)
        }
    }

    /// Number of refined voxels.
    pub fn refined_count(&self) -> usize {
        self.cells.len()
    }

    /// Refined voxels in (z, y, x) order.
    pub fn refined_voxels(&self) -> impl ExactSizeIterator<Item = RefinedVoxel<'_>> + '_ {
        let n = (self.s * self.s * self.s) as usize;
        self.cells
            .iter()
            .enumerate()
            .map(move |(slot, &cell)| RefinedVoxel {
                cell,
                labels: &self.sub[slot * n..(slot + 1) * n],
            })
    }

    /// Refined cells in (z, y, x) order.
    pub fn refined_cells(&self) -> &[[i32; 3]] {
        &self.cells
    }
}
