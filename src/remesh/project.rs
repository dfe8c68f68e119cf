//! Projection onto the smoothed reference: the nearest point on a patch's
//! reference triangles, or on a junction curve's reference polyline (BVH
//! nearest-point queries).

use glam::DVec3;

use crate::mesh::intersect::Bvh;

/// Nearest point to `p` on triangle (a, b, c) (the one of the quality report).
pub use crate::mesh::quality::closest_point_on_triangle as closest_on_triangle;

/// Nearest point to `p` on segment [a, b].
pub fn closest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let d = b - a;
    let l2 = d.length_squared();
    if l2 == 0.0 {
        return a;
    }
    a + d * ((p - a).dot(d) / l2).clamp(0.0, 1.0)
}

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
/// local walks and a BVH for global queries.
pub struct SurfaceRef {
    tris: Vec<[DVec3; 3]>,
    /// Neighbour across edge k (corners k, k + 1), or [`NO_TRIANGLE`].
    adjacent: Vec<[u32; 3]>,
    bvh: Bvh,
}

impl SurfaceRef {
    /// A reference without adjacency: every query goes to the BVH.
    pub fn new(tris: Vec<[DVec3; 3]>) -> Self {
        let adjacent = vec![[NO_TRIANGLE; 3]; tris.len()];
        Self::with_adjacency(tris, adjacent)
    }

    /// A reference whose triangle `t` has neighbour `adjacent[t][k]` across
    /// its edge k (corners k, k + 1).
    pub fn with_adjacency(tris: Vec<[DVec3; 3]>, adjacent: Vec<[u32; 3]>) -> Self {
        assert_eq!(tris.len(), adjacent.len(), "one adjacency row per triangle");
        let boxes: Vec<(DVec3, DVec3)> = tris
            .iter()
            .map(|t| (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2])))
            .collect();
        SurfaceRef {
            bvh: Bvh::new(&boxes),
            tris,
            adjacent,
        }
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
            for k in 0..3 {
                let across = self.adjacent[cur as usize][k];
                if beyond[k] < most && across != NO_TRIANGLE && !recent.contains(&across) {
                    (next, most) = (across, beyond[k]);
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
            if let Some(&i) = self.adjacent[t as usize]
                .iter()
                .find(|&&i| i != NO_TRIANGLE && ok(i))
            {
                return Some(i);
            }
        }
        let e = DVec3::splat(eps);
        let mut found = None;
        self.bvh.any(centroid - e, centroid + e, |i| {
            let hit = ok(i);
            if hit {
                found = Some(i);
            }
            hit
        });
        found
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
            self.adjacent[t as usize]
                .iter()
                .copied()
                .filter(|&i| i != NO_TRIANGLE)
                .map(|i| (i, self.dist2(i, p)))
                .fold((t, reached.dist2(self, p)), |best, x| {
                    if x.1 < best.1 { x } else { best }
                })
        });
        let found = self.bvh.nearest_below(p, guess, |i| self.dist2(i, p));
        match found {
            Some((i, _)) => {
                let t = &self.tris[i as usize];
                (closest_on_triangle(p, t[0], t[1], t[2]), i)
            }
            None => (p, NO_TRIANGLE),
        }
    }
}

/// Reference polyline of one junction curve.
pub struct CurveRef {
    segs: Vec<[DVec3; 2]>,
    bvh: Bvh,
}

impl CurveRef {
    pub fn new(points: &[DVec3], closed: bool) -> Self {
        let mut segs: Vec<[DVec3; 2]> = points.windows(2).map(|w| [w[0], w[1]]).collect();
        if closed && points.len() > 2 {
            segs.push([points[points.len() - 1], points[0]]);
        }
        let boxes: Vec<(DVec3, DVec3)> = segs
            .iter()
            .map(|s| (s[0].min(s[1]), s[0].max(s[1])))
            .collect();
        CurveRef {
            bvh: Bvh::new(&boxes),
            segs,
        }
    }

    /// Nearest point of the reference curve.
    pub fn project(&self, p: DVec3) -> DVec3 {
        let segs = &self.segs;
        match self.bvh.nearest(p, |i| {
            (closest_on_segment(p, segs[i as usize][0], segs[i as usize][1]) - p).length_squared()
        }) {
            Some((i, _)) => closest_on_segment(p, segs[i as usize][0], segs[i as usize][1]),
            None => p,
        }
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
