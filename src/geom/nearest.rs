//! Nearest-point queries: the nearest point on a triangle surface
//! ([`SurfaceRef`]: walks across the surface from a hint, made exact by a
//! uniform cell grid; and whether a triangle follows the surface), or on a
//! polyline ([`CurveRef`]: BVH nearest-item queries). The remesher projects
//! onto its smoothed reference with them; the quality report measures
//! distances with them.

use glam::DVec3;

use super::bvh::Bvh;
use super::grid::CellGrid;
use super::predicates::{closest_on_segment, closest_point_on_triangle as closest_on_triangle};

/// No triangle (no neighbour across an edge, or no hint).
pub const NO_TRIANGLE: u32 = u32::MAX;

/// Steps a walk may take before the BVH answers instead.
const WALK_STEPS: usize = 48;

/// Where a walk stopped: a triangle, its (unnormalised) normal, and the
/// squared distance to its plane if the query point projects into it (NaN
/// otherwise).
struct Reached {
    triangle: u32,
    normal: DVec3,
    plane_dist2: f64,
}

impl Reached {
    /// Squared distance from `p` (the walk's point) to the triangle.
    #[inline]
    fn dist2(&self, r: &SurfaceRef, p: DVec3) -> f64 {
        if self.plane_dist2.is_nan() {
            r.dist2(self.triangle, p)
        } else {
            self.plane_dist2
        }
    }
}

/// Reference triangles of one patch, with their neighbours across edges for
/// local walks and a cell grid for exact queries.
pub struct SurfaceRef {
    tris: Vec<[DVec3; 3]>,
    /// Neighbour across edge k (corners k, k + 1), or [`NO_TRIANGLE`];
    /// empty for a reference without adjacency.
    adjacent: Vec<[u32; 3]>,
    grid: CellGrid,
}

/// Squared distance from `p` to the bounding box of triangle `t`.
#[inline]
fn box_dist2(t: &[DVec3; 3], p: DVec3) -> f64 {
    let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
    (lo - p).max(p - hi).max(DVec3::ZERO).length_squared()
}

impl SurfaceRef {
    /// A reference without adjacency: every query goes to the BVH.
    pub fn new(tris: Vec<[DVec3; 3]>) -> Self {
        SurfaceRef {
            grid: Self::grid_over(&tris),
            tris,
            adjacent: Vec::new(),
        }
    }

    /// A reference whose triangle `t` has neighbour `adjacent[t][k]` across
    /// its edge k (corners k, k + 1).
    pub fn with_adjacency(tris: Vec<[DVec3; 3]>, adjacent: Vec<[u32; 3]>) -> Self {
        assert_eq!(tris.len(), adjacent.len(), "one adjacency row per triangle");
        SurfaceRef {
            grid: Self::grid_over(&tris),
            tris,
            adjacent,
        }
    }

    /// A cell grid over the triangles' boxes (computed as it bins them,
    /// rather than held: 48 bytes a triangle at the peak otherwise).
    fn grid_over(tris: &[[DVec3; 3]]) -> CellGrid {
        CellGrid::from_fn(tris.len(), |i| {
            let t = &tris[i];
            (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]))
        })
    }

    /// The neighbours of triangle `t` across its edges.
    #[inline]
    fn across(&self, t: u32) -> [u32; 3] {
        self.adjacent
            .get(t as usize)
            .copied()
            .unwrap_or([NO_TRIANGLE; 3])
    }

    #[inline]
    fn dist2(&self, t: u32, p: DVec3) -> f64 {
        let t = &self.tris[t as usize];
        (closest_on_triangle(p, t[0], t[1], t[2]) - p).length_squared()
    }

    #[inline]
    fn normal(&self, t: u32) -> DVec3 {
        let t = &self.tris[t as usize];
        (t[1] - t[0]).cross(t[2] - t[0])
    }

    /// Walks from triangle `start` toward `p`: across the edge beyond which
    /// `p` lies farthest (barycentric coordinates of `p` in the triangle's
    /// plane) until `p` projects into the triangle or a patch boundary stops
    /// the walk; returns that triangle, or `None` if the walk was too long
    /// (or `start` is no triangle).
    fn walk(&self, p: DVec3, start: u32) -> Option<Reached> {
        if start as usize >= self.tris.len() {
            return None;
        }
        let mut cur = start;
        // the last triangles visited are not entered again (no cycling)
        let mut recent = [NO_TRIANGLE; 8];
        for step in 0..WALK_STEPS {
            let [a, b, c] = self.tris[cur as usize];
            let n = (b - a).cross(c - a);
            // signed areas opposite a, b, c = beyond edges 1, 2, 0
            let beyond = [
                n.dot((b - a).cross(p - a)),
                n.dot((c - b).cross(p - b)),
                n.dot((a - c).cross(p - c)),
            ];
            let mut next = NO_TRIANGLE;
            let mut most = 0.0;
            for (&b, &across) in beyond.iter().zip(&self.across(cur)) {
                if b < most && across != NO_TRIANGLE && !recent.contains(&across) {
                    (next, most) = (across, b);
                }
            }
            if next == NO_TRIANGLE {
                // `p` projects into the triangle: its nearest point there is
                // the foot on the plane
                let inside = beyond.iter().all(|&b| b >= 0.0);
                let n2 = n.length_squared();
                let plane_dist2 = if inside && n2 > 0.0 {
                    let h = n.dot(p - a);
                    h * h / n2
                } else {
                    f64::NAN
                };
                return Some(Reached {
                    triangle: cur,
                    normal: n,
                    plane_dist2,
                });
            }
            recent[step % recent.len()] = cur;
            cur = next;
        }
        None
    }

    /// Whether triangle (a, b, c) follows the reference: within `eps` of its
    /// centroid lies a reference triangle that does not face against it.
    /// Returns such a triangle ([`NO_TRIANGLE`] if the reference is empty),
    /// which is a good hint for the next triangle nearby.
    ///
    /// `hint` (a reference triangle near the triangle, or [`NO_TRIANGLE`])
    /// only makes the answer faster: a walk from it usually finds such a
    /// triangle; the BVH answers otherwise.
    pub fn fits(&self, a: DVec3, b: DVec3, c: DVec3, eps: f64, hint: u32) -> Option<u32> {
        if self.tris.is_empty() {
            return Some(NO_TRIANGLE);
        }
        let centroid = (a + b + c) / 3.0;
        let n = (b - a).cross(c - a);
        let eps2 = eps * eps;
        let ok = |i: u32| self.normal(i).dot(n) > 0.0 && self.dist2(i, centroid) <= eps2;
        // the hint itself is often near enough: no walk then
        if (hint as usize) < self.tris.len() && ok(hint) {
            return Some(hint);
        }
        if let Some(reached) = self.walk(centroid, hint) {
            // the triangle reached or one of its neighbours
            let t = reached.triangle;
            if reached.normal.dot(n) > 0.0 && reached.dist2(self, centroid) <= eps2 {
                return Some(t);
            }
            if let Some(&i) = self.across(t).iter().find(|&&i| i != NO_TRIANGLE && ok(i)) {
                return Some(i);
            }
        }
        let e = DVec3::splat(eps);
        let (lo, hi) = (centroid - e, centroid + e);
        let mut found = None;
        self.grid.for_cells(lo, hi, |c| {
            if found.is_none() {
                found = self
                    .grid
                    .cell_items(c)
                    .iter()
                    .copied()
                    .find(|&i| box_dist2(&self.tris[i as usize], centroid) <= eps2 && ok(i));
            }
        });
        found
    }

    /// Whether the reference has no triangles.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Nearest point of the reference surface (or `p` itself if it is empty).
    pub fn project(&self, p: DVec3) -> DVec3 {
        self.project_from(p, NO_TRIANGLE).0
    }

    /// The nearest point of the reference to `p` and its triangle (`p` and
    /// [`NO_TRIANGLE`] if the reference is empty). `hint`, a reference
    /// triangle near `p` (or [`NO_TRIANGLE`]), only makes it faster: a walk
    /// from it gives a first guess that bounds the BVH search.
    pub fn project_from(&self, p: DVec3, hint: u32) -> (DVec3, u32) {
        let guess = self.walk(p, hint).map(|reached| {
            // the triangle reached if `p` projects into it, else the nearer
            // of it and its neighbours (the BVH search below is bounded by it)
            let t = reached.triangle;
            if !reached.plane_dist2.is_nan() {
                return (t, reached.plane_dist2);
            }
            self.across(t)
                .iter()
                .copied()
                .filter(|&i| i != NO_TRIANGLE)
                .map(|i| (i, self.dist2(i, p)))
                .fold((t, reached.dist2(self, p)), |best, x| {
                    if x.1 < best.1 { x } else { best }
                })
        });
        let found = self.nearest_below(p, guess);
        match found {
            Some((i, _)) => {
                let t = &self.tris[i as usize];
                (closest_on_triangle(p, t[0], t[1], t[2]), i)
            }
            None => (p, NO_TRIANGLE),
        }
    }
}

impl SurfaceRef {
    /// The reference triangle nearest to `p` and its squared distance, or
    /// `guess` if none is nearer: cells are searched in growing cubes around
    /// `p` until the best distance is below the distance to the cube's outside.
    fn nearest_below(&self, p: DVec3, guess: Option<(u32, f64)>) -> Option<(u32, f64)> {
        if self.tris.is_empty() {
            return guess;
        }
        let g = &self.grid;
        let mut best = guess.unwrap_or((NO_TRIANGLE, f64::INFINITY));
        // (the first triangle seen is taken even if its distance overflows)
        let visit = |c: usize, best: &mut (u32, f64)| {
            for &i in g.cell_items(c) {
                let t = &self.tris[i as usize];
                if best.0 == NO_TRIANGLE || box_dist2(t, p) < best.1 {
                    let d = self.dist2(i, p);
                    if best.0 == NO_TRIANGLE || d < best.1 {
                        *best = (i, d);
                    }
                }
            }
        };
        // the cell of p first: it usually holds the answer, which bounds the
        // rest of the search to a small box
        let centre = g.coords(p);
        visit(
            (centre[2] * g.dims[1] + centre[1]) * g.dims[0] + centre[0],
            &mut best,
        );
        if best.1.is_finite() {
            let r = DVec3::splat(best.1.sqrt());
            if g.cells_in(p - r, p + r) <= 27 {
                g.for_cells(p - r, p + r, |c| visit(c, &mut best));
                return Some(best);
            }
        }
        // growing cubes of cells around the cell of p (p may lie outside the grid)
        let max_r = g.dims.iter().copied().max().unwrap_or(1);
        for r in 0..=max_r {
            let (a, b) = (
                centre.map(|c| c.saturating_sub(r)),
                [0, 1, 2].map(|k| (centre[k] + r).min(g.dims[k] - 1)),
            );
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    let row = (z * g.dims[1] + y) * g.dims[0];
                    let shell_row = z == a[2] || z == b[2] || y == a[1] || y == b[1];
                    for x in a[0]..=b[0] {
                        // only the cells new in this cube
                        if r == 0 || shell_row || x == a[0] || x == b[0] {
                            visit(row + x, &mut best);
                        }
                    }
                }
            }
            // everything outside the cube is at least this far from p
            let cube_lo = g.lo + DVec3::from_array(a.map(|c| c as f64)) * g.cell;
            let cube_hi = g.lo + DVec3::from_array(b.map(|c| (c + 1) as f64)) * g.cell;
            let mut outside = f64::INFINITY;
            for k in 0..3 {
                if a[k] > 0 {
                    outside = outside.min(p[k] - cube_lo[k]);
                }
                if b[k] + 1 < g.dims[k] {
                    outside = outside.min(cube_hi[k] - p[k]);
                }
            }
            if outside == f64::INFINITY || (outside > 0.0 && best.1 <= outside * outside) {
                break;
            }
        }
        (best.0 != NO_TRIANGLE).then_some(best)
    }
}

/// Reference polyline of one junction curve.
pub struct CurveRef {
    segs: Vec<[DVec3; 2]>,
    /// Arc length from the first point to the start of each segment.
    arc: Vec<f64>,
    length: f64,
    closed: bool,
    bvh: Bvh,
}

impl CurveRef {
    pub fn new(points: &[DVec3], closed: bool) -> Self {
        let mut segs: Vec<[DVec3; 2]> = points.windows(2).map(|w| [w[0], w[1]]).collect();
        let closed = closed && points.len() > 2;
        if closed {
            segs.push([points[points.len() - 1], points[0]]);
        }
        let boxes: Vec<(DVec3, DVec3)> = segs
            .iter()
            .map(|s| (s[0].min(s[1]), s[0].max(s[1])))
            .collect();
        let mut arc = Vec::with_capacity(segs.len());
        let mut length = 0.0;
        for s in &segs {
            arc.push(length);
            length += (s[1] - s[0]).length();
        }
        CurveRef {
            bvh: Bvh::new(&boxes),
            segs,
            arc,
            length,
            closed,
        }
    }

    /// Nearest point of the reference curve.
    pub fn project(&self, p: DVec3) -> DVec3 {
        self.locate(p).map_or(p, |(q, _)| q)
    }

    /// Nearest point of the reference curve and its arc length from the
    /// curve's first point; `None` for an empty curve.
    pub fn locate(&self, p: DVec3) -> Option<(DVec3, f64)> {
        let segs = &self.segs;
        let (i, _) = self.bvh.nearest(p, |i| {
            (closest_on_segment(p, segs[i as usize][0], segs[i as usize][1]) - p).length_squared()
        })?;
        let [a, b] = segs[i as usize];
        let q = closest_on_segment(p, a, b);
        Some((q, self.arc[i as usize] + (q - a).length()))
    }

    /// Total arc length.
    pub fn length(&self) -> f64 {
        self.length
    }

    /// Whether the curve closes on itself (arc lengths wrap around).
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The point at arc length `s` (wrapped on a closed curve, clamped to
    /// the ends on an open one).
    pub fn at(&self, s: f64) -> DVec3 {
        let Some(first) = self.segs.first() else {
            return DVec3::NAN;
        };
        let s = if self.closed && self.length > 0.0 {
            s.rem_euclid(self.length)
        } else {
            s.clamp(0.0, self.length)
        };
        let i = self.arc.partition_point(|&a| a <= s).saturating_sub(1);
        let [a, b] = self.segs[i];
        let l = (b - a).length();
        if l <= 0.0 {
            return if i == 0 { first[0] } else { a };
        }
        a + (b - a) * ((s - self.arc[i]) / l).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_near(a: DVec3, b: DVec3) {
        assert!((a - b).length() < 1e-12, "{a} != {b}");
    }

    #[test]
    fn nearest_points() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        assert_near(
            closest_on_triangle(DVec3::new(0.2, 0.2, 5.0), a, b, c),
            DVec3::new(0.2, 0.2, 0.0),
        );
        assert_near(closest_on_triangle(DVec3::new(-1.0, -1.0, 0.0), a, b, c), a);
        assert_near(closest_on_triangle(DVec3::new(2.0, 0.5, 0.0), a, b, c), b);
        let r = SurfaceRef::new(vec![[a, b, c], [b, DVec3::new(1.0, 1.0, 0.0), c]]);
        assert_near(
            r.project(DVec3::new(0.9, 0.9, 1.0)),
            DVec3::new(0.9, 0.9, 0.0),
        );
        let cr = CurveRef::new(&[a, b, DVec3::new(1.0, 1.0, 0.0)], false);
        let (q, s) = cr.locate(DVec3::new(1.5, 0.5, 0.0)).unwrap();
        assert_near(q, DVec3::new(1.0, 0.5, 0.0));
        assert!((s - 1.5).abs() < 1e-12);
        assert_near(cr.at(1.5), q);
        assert_near(cr.at(9.0), DVec3::new(1.0, 1.0, 0.0));
        let ring = CurveRef::new(&[a, b, DVec3::new(1.0, 1.0, 0.0), c], true);
        assert!(ring.is_closed() && (ring.length() - 4.0).abs() < 1e-12);
        assert_near(ring.at(4.5), DVec3::new(0.5, 0.0, 0.0));
        assert_near(ring.at(-0.5), DVec3::new(0.0, 0.5, 0.0));
        assert_near(
            cr.project(DVec3::new(1.5, 0.5, 0.0)),
            DVec3::new(1.0, 0.5, 0.0),
        );
    }

    /// A wavy height field z = f(x, y) on an n × n grid, with adjacency.
    fn wavy(n: usize) -> SurfaceRef {
        let at = |i: usize, j: usize| {
            let (x, y) = (i as f64 * 0.5, j as f64 * 0.5);
            DVec3::new(x, y, (x * 0.7).sin() + (y * 0.4).cos())
        };
        let mut tris = Vec::new();
        for j in 0..n {
            for i in 0..n {
                tris.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                tris.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        // cell (i, j): lower t = 2 (j n + i) with edges (ij)-(i+1 j), (i+1 j)-(i+1 j+1), diagonal;
        // upper t + 1 with edges diagonal, (i+1 j+1)-(i j+1), (i j+1)-(ij)
        let id = |i: usize, j: usize| 2 * (j * n + i) as u32;
        let mut adjacent = vec![[NO_TRIANGLE; 3]; tris.len()];
        for j in 0..n {
            for i in 0..n {
                let t = id(i, j) as usize;
                adjacent[t] = [
                    if j > 0 { id(i, j - 1) + 1 } else { NO_TRIANGLE },
                    if i + 1 < n {
                        id(i + 1, j) + 1
                    } else {
                        NO_TRIANGLE
                    },
                    t as u32 + 1,
                ];
                adjacent[t + 1] = [
                    t as u32,
                    if j + 1 < n { id(i, j + 1) } else { NO_TRIANGLE },
                    if i > 0 { id(i - 1, j) } else { NO_TRIANGLE },
                ];
            }
        }
        SurfaceRef::with_adjacency(tris, adjacent)
    }

    #[test]
    fn grid_answers_equal_brute_force() {
        let r = wavy(20);
        let mut x = 987654321u64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        for k in 0..3000 {
            // near the surface, and (every tenth) far from it or outside the grid
            let spread = if k % 10 == 0 { 40.0 } else { 1.0 };
            let p = DVec3::new(
                next() * 10.0 + (next() - 0.5) * spread,
                next() * 10.0 + (next() - 0.5) * spread,
                (next() - 0.5) * 4.0 * spread,
            );
            let brute = (0..r.tris.len() as u32)
                .map(|i| r.dist2(i, p))
                .fold(f64::INFINITY, f64::min);
            let (q, t) = r.project_from(p, NO_TRIANGLE);
            assert!(((q - p).length_squared() - brute).abs() < 1e-9, "{p}");
            assert!((r.dist2(t, p) - brute).abs() < 1e-9);
            let hint = (next() * r.tris.len() as f64) as u32;
            assert!(((r.project_from(p, hint).0 - p).length_squared() - brute).abs() < 1e-9);
            let (b, c) = (
                p + DVec3::new(0.4, 0.1, 0.0),
                p + DVec3::new(0.1, 0.3, 0.05),
            );
            let n = (b - p).cross(c - p);
            let centroid = (p + b + c) / 3.0;
            for eps in [0.05, 0.3, 1.0] {
                let exists = (0..r.tris.len() as u32)
                    .any(|i| r.normal(i).dot(n) > 0.0 && r.dist2(i, centroid) <= eps * eps);
                assert_eq!(r.fits(p, b, c, eps, NO_TRIANGLE).is_some(), exists);
            }
        }
    }

    #[test]
    fn hints_change_speed_not_answers() {
        let r = wavy(30);
        let plain = SurfaceRef::new(r.tris.clone());
        let mut x = 12345u64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..2000 {
            let p = DVec3::new(next() * 15.0, next() * 15.0, next() * 4.0 - 2.0);
            let hint = (next() * r.tris.len() as f64) as u32;
            let (a, ta) = r.project_from(p, hint);
            let (b, _) = plain.project_from(p, NO_TRIANGLE);
            assert!(((a - p).length() - (b - p).length()).abs() < 1e-12);
            assert!((r.dist2(ta, p) - (a - p).length_squared()).abs() < 1e-9);
            let (q, s) = (p + DVec3::new(0.6, 0.1, 0.0), p + DVec3::new(0.2, 0.5, 0.1));
            for eps in [0.05, 0.3, 1.0] {
                assert_eq!(
                    r.fits(p, q, s, eps, hint).is_some(),
                    plain.fits(p, q, s, eps, NO_TRIANGLE).is_some()
                );
            }
        }
    }
}
