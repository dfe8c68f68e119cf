//! The sizing field: the target edge length h(x) at every point, from the
//! geometry of the label volume.
//!
//! Where two sheets come closer than the target edge, a uniform target makes
//! them cross or fold (grey-matter banks 1 mm apart in a sulcus, a one-voxel
//! wall between two pools). Two sheets that are close always bound a thin
//! region of one label between them, so the field is built from the local
//! thickness of the label regions:
//!
//! 1. at every boundary voxel (a voxel with a 6-neighbour of another label),
//!    the thickness of its label's region: the shortest run of that label
//!    through the voxel along the 13 lattice directions (axes, face and space
//!    diagonals), in mm, looked for only as far as it matters (up to
//!    [`Sizing::max`] / [`THICKNESS_FACTOR`]);
//! 2. per cell of a coarse grid (about half the largest target, aligned with
//!    the voxels), h₀ = the smallest [`THICKNESS_FACTOR`] · thickness of the
//!    boundary voxels in it, or the largest target where there are none;
//! 3. graded: h(x) ≤ h₀(y) + g·|x − y| for all cells (g = [`GRADING`]), so
//!    neighbouring edges differ by at most a factor 1 + g; computed exactly
//!    by separable min-plus sweeps in the L1 metric with slope g/√3 (which
//!    bounds the Euclidean slope by g);
//! 4. looked up by trilinear interpolation of the cell values and clamped to
//!    [`Sizing::min`], [`Sizing::max`].
//!
//! The remesher then lowers it where the junction curves are finer than
//! the target ([`Sizing::limited`], from [`super::junction_sizing`]): runs
//! of curves shorter than it, and runs closer to each other than it.
//!
//! The remesher asks for h at an edge's midpoint ([`Sizing::edge`]); the
//! quality report measures edges against the same field.

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use crate::volume::{Geometry, PaddedLabels};

/// Target edge length as a multiple of the local thickness of the thinnest
/// region beside a sheet: an edge as long as the region is thick follows both
/// its sheets without crossing (a chord of length h deviates h²/8R from a
/// sheet of curvature radius R; at the rim of a region of thickness t, R is
/// about t/2, so the deviation is t/4 at h = t, less than half the gap).
pub const THICKNESS_FACTOR: f64 = 1.0;

/// Grading: the target may grow by this fraction of the distance (h grows by
/// at most g·h along an edge of length h, i.e. by a factor 1 + g).
pub const GRADING: f64 = 0.5;

/// Most cells the coarse grid may have (its memory is 4 bytes a cell).
const MAX_CELLS: usize = 1 << 24;

/// Target edge length (mm) at any point.
#[derive(Clone, Debug)]
pub struct Sizing {
    min: f64,
    max: f64,
    field: Option<Field>,
}

/// The graded cell values and how to find them from a position.
#[derive(Clone, Debug)]
struct Field {
    /// LPS mm → index space of the volume.
    to_index: DMat3,
    origin: DVec3,
    /// Voxels per cell along each index axis.
    cell: [usize; 3],
    /// Cells per axis (over the padded grid: voxel −1 to n).
    dims: [usize; 3],
    /// Edge lengths of a cell along each index axis (mm), for the grading.
    cell_len: [f64; 3],
    h: Vec<f32>,
}

impl Sizing {
    /// `target` everywhere.
    pub fn uniform(target: f64) -> Self {
        Sizing {
            min: target,
            max: target,
            field: None,
        }
    }

    /// The field of a label grid with its geometry: targets between `min`
    /// and `max` mm, from the thickness of the label regions (see the module
    /// docs). `min` ≤ `max`, both positive.
    pub fn from_labels(grid: &PaddedLabels, geometry: &Geometry, min: f64, max: f64) -> Self {
        assert!(min > 0.0 && min <= max, "0 < min {min} <= max {max}");
        let spacing = geometry.spacing();
        let pdims = grid.padded_dims();
        // cells of about max/2 mm (at least one voxel), at most MAX_CELLS
        let mut cell_mm = 0.5 * max;
        let cells_for = |mm: f64| {
            let c = spacing.map(|s| ((mm / s).round() as usize).max(1));
            let dims = [0, 1, 2].map(|a| pdims[a].div_ceil(c[a]));
            (c, dims)
        };
        let (mut cell, mut dims) = cells_for(cell_mm);
        while dims.iter().product::<usize>() > MAX_CELLS {
            cell_mm *= 1.25;
            (cell, dims) = cells_for(cell_mm);
        }
        let h0 = thinnest_per_cell(grid, geometry, cell, dims, max);
        let cell_len = [0, 1, 2].map(|a| cell[a] as f64 * spacing[a]);
        let h = graded(h0, dims, cell_len);
        Sizing {
            min,
            max,
            field: Some(Field {
                to_index: geometry.linear_matrix().inverse(),
                origin: DVec3::from(geometry.origin()),
                cell,
                dims,
                cell_len,
                h,
            }),
        }
    }

    /// This field with the target at each point `p` of `limits` at most its
    /// `t` (mm; never below [`Sizing::min`]), graded again around them. The
    /// remesher limits the target near junction curves shorter than it (see
    /// [`super::junction_sizing`]). A uniform sizing stays uniform: it has no
    /// field to lower.
    pub fn limited(&self, limits: &[(DVec3, f64)]) -> Sizing {
        let Some(field) = &self.field else {
            return self.clone();
        };
        let mut h = field.h.clone();
        let mut lowered = false;
        for &(p, t) in limits {
            if !(t < self.max) || !p.is_finite() {
                continue;
            }
            let t = t.max(self.min) as f32;
            // every cell of the interpolation stencil at p, so that h(p),
            // a weighted mean of them, is at most t
            let (i, [sx, sy, sz]) = field.stencil(p);
            for o in [0, sx, sy, sy + sx, sz, sz + sx, sz + sy, sz + sy + sx] {
                if t < h[i + o] {
                    h[i + o] = t;
                    lowered = true;
                }
            }
        }
        if !lowered {
            return self.clone();
        }
        Sizing {
            min: self.min,
            max: self.max,
            field: Some(Field {
                h: graded(h, field.dims, field.cell_len),
                ..field.clone()
            }),
        }
    }

    /// The smallest target (mm).
    pub fn min(&self) -> f64 {
        self.min
    }

    /// The largest target (mm): the user's target edge.
    pub fn max(&self) -> f64 {
        self.max
    }

    /// The target edge length at `p` (LPS mm).
    #[inline]
    pub fn at(&self, p: DVec3) -> f64 {
        match &self.field {
            None => self.max,
            Some(f) => f.at(p).clamp(self.min, self.max),
        }
    }

    /// The target for edge (a, b): at its midpoint.
    #[inline]
    pub fn edge(&self, a: DVec3, b: DVec3) -> f64 {
        self.at((a + b) * 0.5)
    }
}

impl crate::mesh::quality::TargetEdges for Sizing {
    fn target_at(&self, p: DVec3) -> f64 {
        self.at(p)
    }
}

impl Field {
    /// The interpolation stencil at `p` (LPS mm): the index of its first
    /// cell, the index steps to the next cell along each axis (0 along an
    /// axis with one cell) and the fractions along each axis.
    #[inline]
    fn stencil_and_fractions(&self, p: DVec3) -> (usize, [usize; 3], [f64; 3]) {
        // padded voxel coordinates (voxel centres at integers, −1 → 0) in
        // cell units, with cell centres at integers
        let q = self.to_index * (p - self.origin);
        let mut base = [0usize; 3];
        let mut frac = [0f64; 3];
        // (conversions through u32, exact for these small counts: between
        // f64 and u64 they take several instructions each on x86_64)
        let float = |n: usize| f64::from(n as u32);
        for a in 0..3 {
            let c = (q[a] + 1.5) / float(self.cell[a]) - 0.5;
            // clamped into the grid (NaN → 0: `max` takes the number)
            let c = c.max(0.0).min(float(self.dims[a] - 1));
            // (c ≥ 0: the cast is the floor, without a call to libm's)
            let f = (c as u32 as usize).min(self.dims[a].max(2) - 2);
            base[a] = f;
            frac[a] = c - float(f);
        }
        let [nx, ny, _] = self.dims;
        let step = |a: usize| usize::from(self.dims[a] > 1);
        let steps = [step(0), step(1) * nx, step(2) * nx * ny];
        let i = base[0] + nx * (base[1] + ny * base[2]);
        (i, steps, frac)
    }

    /// [`Field::stencil_and_fractions`] without the fractions.
    fn stencil(&self, p: DVec3) -> (usize, [usize; 3]) {
        let (i, steps, _) = self.stencil_and_fractions(p);
        (i, steps)
    }

    /// Trilinear interpolation of the cell values at `p` (LPS mm).
    fn at(&self, p: DVec3) -> f64 {
        let (i, [sx, sy, sz], frac) = self.stencil_and_fractions(p);
        let v = |o: usize| self.h[i + o] as f64;
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let x0 = lerp(v(0), v(sx), frac[0]);
        let x1 = lerp(v(sy), v(sy + sx), frac[0]);
        let x2 = lerp(v(sz), v(sz + sx), frac[0]);
        let x3 = lerp(v(sz + sy), v(sz + sy + sx), frac[0]);
        lerp(lerp(x0, x1, frac[1]), lerp(x2, x3, frac[1]), frac[2])
    }
}

/// Per cell: the smallest [`THICKNESS_FACTOR`] · thickness of the boundary
/// voxels within one voxel of it, at most `max` (one voxel further, so that
/// both sheets of a thin region, which lie on its voxels' faces, get its
/// target wherever the cells' borders fall).
fn thinnest_per_cell(
    grid: &PaddedLabels,
    geometry: &Geometry,
    cell: [usize; 3],
    dims: [usize; 3],
    max: f64,
) -> Vec<f32> {
    let pdims = grid.padded_dims();
    let spacing = geometry.spacing();
    // runs longer than this cannot lower the target
    let cap = max / THICKNESS_FACTOR;
    let reach = spacing.map(|s| (cap / s).ceil() as usize);
    // thin boundary voxels (x, y, target) per padded z plane
    let thin: Vec<Vec<(u32, u32, f32)>> = (0..pdims[2])
        .into_par_iter()
        .map(|z| thin_voxels_in_plane(grid, z, spacing, reach, cap))
        .collect();
    let plane = dims[0] * dims[1];
    let mut h = vec![max as f32; plane * dims[2]];
    h.par_chunks_mut(plane).enumerate().for_each(|(cz, out)| {
        let z0 = (cz * cell[2]).saturating_sub(1);
        let z1 = ((cz + 1) * cell[2] + 1).min(pdims[2]);
        for entries in &thin[z0..z1] {
            for &(x, y, v) in entries {
                let (x, y) = (x as usize, y as usize);
                let cx = [
                    x.saturating_sub(1) / cell[0],
                    ((x + 1) / cell[0]).min(dims[0] - 1),
                ];
                let cy = [
                    y.saturating_sub(1) / cell[1],
                    ((y + 1) / cell[1]).min(dims[1] - 1),
                ];
                for j in cy[0]..=cy[1] {
                    for i in cx[0]..=cx[1] {
                        let c = &mut out[i + dims[0] * j];
                        *c = c.min(v);
                    }
                }
            }
        }
    });
    h
}

/// The boundary voxels of padded plane `z` whose region is thinner than
/// `cap` mm, with their targets: the region's thickness at a voxel is the
/// shortest run of its label through it along an index axis (a run stops at
/// another label or at the buffer's edge, beyond the outside padding), in mm.
fn thin_voxels_in_plane(
    grid: &PaddedLabels,
    z: usize,
    spacing: [f64; 3],
    reach: [usize; 3],
    cap: f64,
) -> Vec<(u32, u32, f32)> {
    let pdims = grid.padded_dims();
    let strides = grid.strides();
    let data = grid.data();
    let mut out = Vec::new();
    for y in 0..pdims[1] {
        for x in 0..pdims[0] {
            let at = [x, y, z];
            let i = (z * pdims[1] + y) * pdims[0] + x;
            let l = data[i];
            // a neighbour of another label (not the buffer's edge) makes a boundary voxel
            let boundary = (0..3).any(|a| {
                (at[a] + 1 < pdims[a] && data[i + strides[a]] != l)
                    || (at[a] > 0 && data[i - strides[a]] != l)
            });
            if !boundary {
                continue;
            }
            let mut thinnest = f64::INFINITY;
            for a in 0..3 {
                let (mut fwd, mut back) = (0, 0);
                while fwd < reach[a]
                    && at[a] + fwd + 1 < pdims[a]
                    && data[i + (fwd + 1) * strides[a]] == l
                {
                    fwd += 1;
                }
                while back < reach[a] && at[a] > back && data[i - (back + 1) * strides[a]] == l {
                    back += 1;
                }
                thinnest = thinnest.min((fwd + back + 1) as f64 * spacing[a]);
            }
            if thinnest < cap {
                out.push((x as u32, y as u32, (THICKNESS_FACTOR * thinnest) as f32));
            }
        }
    }
    out
}

/// The grading of `h0` (cells `dims`, cell edge lengths `cell_len` mm):
/// h(x) = min over cells y of h0(y) + (g/√3)·|x − y|₁, by two sweeps per
/// axis (the L1 cone is separable); rows, columns and planes in parallel.
fn graded(mut h: Vec<f32>, dims: [usize; 3], cell_len: [f64; 3]) -> Vec<f32> {
    let slope = GRADING / 3f64.sqrt();
    let rise = cell_len.map(|c| (slope * c) as f32);
    let [nx, ny, nz] = dims;
    let lower = |cur: &mut f32, from: f32, rise: f32| *cur = cur.min(from + rise);
    // along x: within each row
    h.par_chunks_mut(nx).for_each(|row| {
        for k in 1..nx {
            let from = row[k - 1];
            lower(&mut row[k], from, rise[0]);
        }
        for k in (0..nx - 1).rev() {
            let from = row[k + 1];
            lower(&mut row[k], from, rise[0]);
        }
    });
    // along y: within each plane, row by row
    h.par_chunks_mut(nx * ny).for_each(|plane| {
        for k in 1..ny {
            let (done, rest) = plane.split_at_mut(k * nx);
            for (c, &f) in rest[..nx].iter_mut().zip(&done[(k - 1) * nx..]) {
                lower(c, f, rise[1]);
            }
        }
        for k in (0..ny - 1).rev() {
            let (head, done) = plane.split_at_mut((k + 1) * nx);
            for (c, &f) in head[k * nx..].iter_mut().zip(&done[..nx]) {
                lower(c, f, rise[1]);
            }
        }
    });
    // along z: plane by plane, each plane in parallel
    let plane = nx * ny;
    for k in 1..nz {
        let (done, rest) = h.split_at_mut(k * plane);
        rest[..plane]
            .par_iter_mut()
            .zip(&done[(k - 1) * plane..])
            .for_each(|(c, &f)| lower(c, f, rise[2]));
    }
    for k in (0..nz.saturating_sub(1)).rev() {
        let (head, done) = h.split_at_mut((k + 1) * plane);
        head[k * plane..]
            .par_iter_mut()
            .zip(&done[..plane])
            .for_each(|(c, &f)| lower(c, f, rise[2]));
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Dims, LabelVolume};

    fn grid_of(
        n: [usize; 3],
        f: impl Fn(usize, usize, usize) -> i64,
        g: Geometry,
    ) -> (PaddedLabels, Geometry) {
        let v: Vec<i64> = (0..n[0] * n[1] * n[2])
            .map(|i| f(i % n[0], i / n[0] % n[1], i / (n[0] * n[1])))
            .collect();
        let vol = LabelVolume::from_values(Dims::new(n[0], n[1], n[2]).unwrap(), &v, g).unwrap();
        (PaddedLabels::new(&vol, 0), g)
    }

    #[test]
    fn uniform_is_the_target_everywhere() {
        let s = Sizing::uniform(3.0);
        assert_eq!(s.at(DVec3::splat(0.5)), 3.0);
        assert_eq!(s.edge(DVec3::ZERO, DVec3::X), 3.0);
    }

    #[test]
    fn a_one_voxel_wall_lowers_the_target_near_it_only() {
        // label 1 | wall of label 2 (x = 20) | label 3, in a 40 × 24 × 24 box
        let (grid, g) = grid_of(
            [40, 24, 24],
            |x, y, z| {
                if !(2..22).contains(&y) || !(2..22).contains(&z) || !(2..38).contains(&x) {
                    0
                } else if x < 20 {
                    1
                } else if x == 20 {
                    2
                } else {
                    3
                }
            },
            Geometry::identity(),
        );
        let s = Sizing::from_labels(&grid, &g, 0.5, 4.0);
        let wall = s.at(DVec3::new(20.0, 12.0, 12.0));
        assert!(wall <= 1.0 + 1e-6, "on the wall: {wall}");
        // far from it (and from the outer walls: 10 voxels) the user's target
        let far = s.at(DVec3::new(10.0, 12.0, 12.0));
        assert!(far > 3.0, "far from the wall: {far}");
        // graded in between: slope at most GRADING
        let mut prev = wall;
        for k in 1..=10 {
            let h = s.at(DVec3::new(20.0 - k as f64, 12.0, 12.0));
            assert!(h - prev <= GRADING * 1.0 + 1e-6, "step {k}: {prev} -> {h}");
            prev = h;
        }
    }

    #[test]
    fn limits_lower_the_target_at_their_points_graded_around_them() {
        // one label in a box: the thickness leaves the target alone inside
        let (grid, g) = grid_of(
            [40, 40, 40],
            |x, y, z| i64::from([x, y, z].iter().all(|c| (2..38).contains(c))),
            Geometry::identity(),
        );
        let s = Sizing::from_labels(&grid, &g, 0.5, 4.0);
        let p = DVec3::splat(20.0);
        assert_eq!(s.at(p), 4.0);
        let l = s.limited(&[(p, 1.0), (DVec3::new(20.0, 20.0, 10.0), 0.1)]);
        assert!(l.at(p) <= 1.0 + 1e-6, "at the limit: {}", l.at(p));
        // never below the smallest target
        assert!((l.at(DVec3::new(20.0, 20.0, 10.0)) - 0.5).abs() < 1e-6);
        let mut prev = l.at(p);
        for k in 1..=8 {
            let h = l.at(p + DVec3::X * k as f64);
            assert!(h - prev <= GRADING + 1e-6, "step {k}: {prev} -> {h}");
            prev = h;
        }
        assert_eq!(l.at(DVec3::new(8.0, 30.0, 30.0)), 4.0, "far away");
        // limits above the target change nothing
        assert_eq!(s.limited(&[(p, 9.0)]).at(p), 4.0);
    }

    #[test]
    fn anisotropic_spacing_is_in_mm() {
        // a wall one voxel thick along z, with 3 mm voxels: 3 mm thick
        let g = Geometry::new(
            [1.0, 1.0, 3.0],
            [0.0; 3],
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        )
        .unwrap();
        let (grid, g) = grid_of(
            [24, 24, 12],
            |x, y, z| {
                if !(2..22).contains(&x) || !(2..22).contains(&y) || !(1..11).contains(&z) {
                    0
                } else if z == 6 {
                    2
                } else {
                    1
                }
            },
            g,
        );
        let s = Sizing::from_labels(&grid, &g, 0.5, 6.0);
        let at_wall = s.at(g.index_to_physical(DVec3::new(12.0, 12.0, 6.0)));
        assert!((2.5..=3.0 + 1e-6).contains(&at_wall), "{at_wall}");
    }

    #[test]
    fn the_field_is_clamped_to_min_and_max() {
        // pure noise: every voxel is one voxel thick
        let (grid, g) = grid_of(
            [12, 12, 12],
            |x, y, z| ((x * 7 + y * 13 + z * 29) % 3) as i64,
            Geometry::identity(),
        );
        let s = Sizing::from_labels(&grid, &g, 1.5, 3.0);
        for p in [
            DVec3::splat(5.0),
            DVec3::splat(-100.0),
            DVec3::new(f64::NAN, 0.0, 0.0),
        ] {
            let h = s.at(p);
            assert!((1.5..=3.0).contains(&h), "{p}: {h}");
        }
        assert_eq!(s.at(DVec3::splat(6.0)), 1.5);
    }
}
