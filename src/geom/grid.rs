//! A static uniform cell grid over boxes: compressed rows (counting sort) of
//! the items overlapping each cell. Queries near the items (the usual case:
//! a point a fraction of a cell from a surface) read one to eight cells,
//! which is cheaper than descending a tree.

use std::sync::atomic::{AtomicU32, Ordering};

use glam::DVec3;
use rayon::prelude::*;

/// Boxes (of triangles, segments...) binned into the cells of a uniform grid they overlap
/// (compressed rows by counting sort). Queries near the surface (the usual
/// case: a point a fraction of a cell from it) read one to eight cells, which
/// is cheaper than descending a tree.
pub struct CellGrid {
    pub lo: DVec3,
    /// Cell edge length (mm) and its inverse.
    pub cell: f64,
    inv: f64,
    pub dims: [usize; 3],
    /// Items of cell c: `items[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    items: Vec<u32>,
}

/// Cells per triangle the grid aims at (a few triangles per occupied cell).
const CELLS_PER_TRIANGLE: f64 = 8.0;

/// Boxes per parallel task when binning (fewer are not worth a task).
const PAR_BOXES: usize = 1 << 14;

/// Sorts the items of every cell (`items[start[c]..start[c + 1]]`), in
/// parallel over runs of cells.
fn sort_cells(items: &mut [u32], start: &[u32]) {
    let ncells = start.len() - 1;
    // runs of cells holding about PAR_BOXES items each, cut at cell borders
    let mut cuts = vec![0usize];
    let mut c = 0;
    while c < ncells {
        let want = start[c] as usize + PAR_BOXES;
        c = start[c..ncells]
            .partition_point(|&s| (s as usize) < want)
            .max(1)
            + c;
        cuts.push(c.min(ncells));
    }
    let mut runs = Vec::with_capacity(cuts.len());
    let mut rest = items;
    for w in cuts.windows(2) {
        let (run, tail) = rest.split_at_mut((start[w[1]] - start[w[0]]) as usize);
        runs.push((w[0], w[1], run));
        rest = tail;
    }
    runs.into_par_iter().for_each(|(a, b, run)| {
        let base = start[a];
        for c in a..b {
            run[(start[c] - base) as usize..(start[c + 1] - base) as usize].sort_unstable();
        }
    });
}

impl CellGrid {
    /// A grid over the boxes `boxes[i] = (lo, hi)`: cells of about the mean
    /// box size (at most a few per box), each listing the boxes it overlaps.
    pub fn new(boxes: &[(DVec3, DVec3)]) -> Self {
        Self::from_fn(boxes.len(), |i| boxes[i])
    }

    /// [`CellGrid::new`] over the `n` boxes `box_of(i)`, computed as they
    /// are needed (each a few times) rather than held.
    pub fn from_fn(n: usize, box_of: impl Fn(usize) -> (DVec3, DVec3) + Sync) -> Self {
        let (lo, hi) = (0..n)
            .into_par_iter()
            .with_min_len(PAR_BOXES)
            .map(&box_of)
            .fold(
                || (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
                |(lo, hi), b| (lo.min(b.0), hi.max(b.1)),
            )
            .reduce(
                || (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
                |a, b| (a.0.min(b.0), a.1.max(b.1)),
            );
        if n == 0 {
            return CellGrid {
                lo: DVec3::ZERO,
                cell: 1.0,
                inv: 1.0,
                dims: [1; 3],
                start: vec![0, 0],
                items: Vec::new(),
            };
        }
        // cells of about the mean triangle size, at most a few per triangle
        let ext = (hi - lo).max(DVec3::splat(1e-9));
        // (summed in fixed chunks, in order: the same whatever the threads)
        let chunk_sums: Vec<f64> = (0..n.div_ceil(PAR_BOXES))
            .into_par_iter()
            .map(|c| {
                (c * PAR_BOXES..((c + 1) * PAR_BOXES).min(n))
                    .map(|i| {
                        let b = box_of(i);
                        (b.1 - b.0).max_element()
                    })
                    .sum::<f64>()
            })
            .collect();
        let mean_size = chunk_sums.iter().sum::<f64>() / n as f64;
        let by_count = (ext.x * ext.y * ext.z / (CELLS_PER_TRIANGLE * n as f64)).cbrt();
        let cell = mean_size.max(by_count).max(ext.max_element() * 1e-6);
        let dims = (ext / cell).to_array().map(|d| d.floor() as usize + 1);
        let mut grid = CellGrid {
            lo,
            cell,
            inv: 1.0 / cell,
            dims,
            start: Vec::new(),
            items: Vec::new(),
        };
        let ncells = dims[0] * dims[1] * dims[2];
        // counts by atomic increments, in parallel; then each cell's items
        // are put in order (the order of a serial fill), so that the grid
        // does not depend on the number of threads
        let counts: Vec<AtomicU32> = (0..ncells).map(|_| AtomicU32::new(0)).collect();
        grid.par_for_cells_of(n, &box_of, |_, c| {
            counts[c].fetch_add(1, Ordering::Relaxed);
        });
        let mut start = vec![0u32; ncells + 1];
        for c in 0..ncells {
            start[c + 1] = start[c] + counts[c].load(Ordering::Relaxed);
        }
        let fill: Vec<AtomicU32> = start[..ncells].iter().map(|&s| AtomicU32::new(s)).collect();
        drop(counts);
        let items: Vec<AtomicU32> = (0..start[ncells]).map(|_| AtomicU32::new(0)).collect();
        grid.par_for_cells_of(n, &box_of, |i, c| {
            let at = fill[c].fetch_add(1, Ordering::Relaxed);
            items[at as usize].store(i as u32, Ordering::Relaxed);
        });
        drop(fill);
        let mut items: Vec<u32> = items.into_iter().map(AtomicU32::into_inner).collect();
        sort_cells(&mut items, &start);
        grid.start = start;
        grid.items = items;
        grid
    }

    /// Calls `f(i, c)`, in parallel, for every box `i < n` and every cell
    /// `c` its box `box_of(i)` overlaps.
    fn par_for_cells_of(
        &self,
        n: usize,
        box_of: &(impl Fn(usize) -> (DVec3, DVec3) + Sync),
        f: impl Fn(usize, usize) + Sync,
    ) {
        (0..n)
            .into_par_iter()
            .with_min_len(PAR_BOXES)
            .for_each(|i| {
                let b = box_of(i);
                self.for_cells(b.0, b.1, |c| f(i, c));
            });
    }

    /// Cell coordinates of `p`, clamped to the grid.
    #[inline]
    pub fn coords(&self, p: DVec3) -> [usize; 3] {
        let q = (p - self.lo) * self.inv;
        // (through u32, which saturates as usize would for any grid this
        // size: from f64 to u64 is a sequence of several instructions on
        // x86_64, to u32 one conversion and a clamp)
        let c = |k: usize| (q[k].max(0.0) as u32 as usize).min(self.dims[k] - 1);
        [c(0), c(1), c(2)]
    }

    /// Calls `f` with every cell overlapping box [lo, hi] (clamped to the grid).
    #[inline]
    pub fn for_cells(&self, lo: DVec3, hi: DVec3, mut f: impl FnMut(usize)) {
        let (a, b) = (self.coords(lo), self.coords(hi));
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                let row = (z * self.dims[1] + y) * self.dims[0];
                for x in a[0]..=b[0] {
                    f(row + x);
                }
            }
        }
    }

    #[inline]
    pub fn cell_items(&self, c: usize) -> &[u32] {
        &self.items[self.start[c] as usize..self.start[c + 1] as usize]
    }

    /// Number of cells overlapping box [lo, hi].
    pub fn cells_in(&self, lo: DVec3, hi: DVec3) -> usize {
        let (a, b) = (self.coords(lo), self.coords(hi));
        (0..3).map(|k| b[k] - a[k] + 1).product()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::test_rng::random_boxes;

    #[test]
    fn every_cell_lists_the_boxes_over_it_in_order_whatever_the_threads() {
        // enough boxes for several parallel tasks
        let boxes = random_boxes(5 * PAR_BOXES, 7, 40.0);
        let build = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| CellGrid::new(&boxes))
        };
        let (one, three) = (build(1), build(3));
        assert_eq!(one.start, three.start);
        assert_eq!(one.items, three.items);
        // the rows a serial counting sort makes: each box in every cell its
        // box overlaps, in the order of the boxes
        let ncells = one.dims.iter().product::<usize>();
        let mut rows = vec![Vec::new(); ncells];
        for (i, b) in boxes.iter().enumerate() {
            one.for_cells(b.0, b.1, |c| rows[c].push(i as u32));
        }
        assert!(rows.iter().any(|r| r.len() > 1));
        for (c, row) in rows.iter().enumerate() {
            assert_eq!(one.cell_items(c), row.as_slice(), "cell {c}");
        }
    }
}
