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

/// Reference triangles of one patch.
pub struct SurfaceRef {
    tris: Vec<[DVec3; 3]>,
    bvh: Bvh,
}

impl SurfaceRef {
    pub fn new(tris: Vec<[DVec3; 3]>) -> Self {
        let boxes: Vec<(DVec3, DVec3)> = tris
            .iter()
            .map(|t| (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2])))
            .collect();
        SurfaceRef {
            bvh: Bvh::new(&boxes),
            tris,
        }
    }

    /// Nearest point of the reference surface and the unit normal of the
    /// triangle it lies on (`None` if the reference is empty).
    pub fn nearest(&self, p: DVec3) -> Option<(DVec3, DVec3)> {
        let tris = &self.tris;
        let (i, _) = self.bvh.nearest(p, |i| {
            let t = &tris[i as usize];
            (closest_on_triangle(p, t[0], t[1], t[2]) - p).length_squared()
        })?;
        let t = &tris[i as usize];
        Some((
            closest_on_triangle(p, t[0], t[1], t[2]),
            (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero(),
        ))
    }

    /// Whether triangle (a, b, c) follows the reference: within `eps` of its
    /// centroid lies a reference triangle that does not face against it.
    pub fn fits(&self, a: DVec3, b: DVec3, c: DVec3, eps: f64) -> bool {
        if self.tris.is_empty() {
            return true;
        }
        let centroid = (a + b + c) / 3.0;
        let n = (b - a).cross(c - a);
        let e = DVec3::splat(eps);
        let eps2 = eps * eps;
        let tris = &self.tris;
        self.bvh.any(centroid - e, centroid + e, |i| {
            let t = &tris[i as usize];
            (t[1] - t[0]).cross(t[2] - t[0]).dot(n) > 0.0
                && (closest_on_triangle(centroid, t[0], t[1], t[2]) - centroid).length_squared()
                    <= eps2
        })
    }

    /// Nearest point of the reference surface (or `p` itself if it is empty).
    pub fn project(&self, p: DVec3) -> DVec3 {
        let tris = &self.tris;
        match self.bvh.nearest(p, |i| {
            let t = &tris[i as usize];
            (closest_on_triangle(p, t[0], t[1], t[2]) - p).length_squared()
        }) {
            Some((i, _)) => {
                let t = &tris[i as usize];
                closest_on_triangle(p, t[0], t[1], t[2])
            }
            None => p,
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
}
