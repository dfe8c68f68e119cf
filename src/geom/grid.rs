//! A static uniform cell grid over boxes: compressed rows (counting sort) of
//! the items overlapping each cell. Queries near the items (the usual case:
//! a point a fraction of a cell from a surface) read one to eight cells,
//! which is cheaper than descending a tree.

use glam::DVec3;

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

impl CellGrid {
    /// A grid over the boxes `boxes[i] = (lo, hi)`: cells of about the mean
    /// box size (at most a few per box), each listing the boxes it overlaps.
    pub fn new(boxes: &[(DVec3, DVec3)]) -> Self {
        let (lo, hi) = boxes.iter().fold(
            (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
            |(lo, hi), b| (lo.min(b.0), hi.max(b.1)),
        );
        if boxes.is_empty() {
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
        let mean_size =
            boxes.iter().map(|b| (b.1 - b.0).max_element()).sum::<f64>() / boxes.len() as f64;
        let by_count = (ext.x * ext.y * ext.z / (CELLS_PER_TRIANGLE * boxes.len() as f64)).cbrt();
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
        let mut start = vec![0u32; ncells + 1];
        for b in boxes {
            grid.for_cells(b.0, b.1, |c| start[c + 1] += 1);
        }
        for c in 0..ncells {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; start[ncells] as usize];
        for (i, b) in boxes.iter().enumerate() {
            grid.for_cells(b.0, b.1, |c| {
                items[fill[c] as usize] = i as u32;
                fill[c] += 1;
            });
        }
        grid.start = start;
        grid.items = items;
        grid
    }

    /// Cell coordinates of `p`, clamped to the grid.
    #[inline]
    pub fn coords(&self, p: DVec3) -> [usize; 3] {
        let q = (p - self.lo) * self.inv;
        [0, 1, 2].map(|k| (q[k].max(0.0) as usize).min(self.dims[k] - 1))
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
