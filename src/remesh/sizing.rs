//! Target edge length as a function of position.
//!
//! The remesher asks for the target length at an edge's midpoint: the
//! user's target everywhere, except in boxes given a smaller one (regions
//! where a coarser mesh left two sheets crossing; see [`super::remesh`]).

use glam::DVec3;

use crate::geom::Bvh;

/// Target edge length (mm) at any point.
pub(crate) struct Sizing {
    target: f64,
    /// Boxes with their own (smaller) target.
    regions: Vec<(DVec3, DVec3, f64)>,
    bvh: Option<Bvh>,
}

impl Sizing {
    /// `target` everywhere.
    pub(crate) fn uniform(target: f64) -> Self {
        Sizing {
            target,
            regions: Vec::new(),
            bvh: None,
        }
    }

    /// `target`, but the smallest of the targets of the boxes a point lies in.
    pub(crate) fn with_regions(target: f64, regions: Vec<(DVec3, DVec3, f64)>) -> Self {
        let bvh = (!regions.is_empty())
            .then(|| Bvh::new(&regions.iter().map(|r| (r.0, r.1)).collect::<Vec<_>>()));
        Sizing {
            target,
            regions,
            bvh,
        }
    }

    /// The target edge length at `p`.
    #[inline]
    pub(crate) fn at(&self, p: DVec3) -> f64 {
        let Some(bvh) = &self.bvh else {
            return self.target;
        };
        let mut s = self.target;
        // (the tree reports every item of a leaf it reaches: test each box)
        bvh.query(p, p, |i| {
            let (lo, hi, t) = self.regions[i as usize];
            if p.cmpge(lo).all() && p.cmple(hi).all() {
                s = s.min(t);
            }
        });
        s
    }

    /// The target for edge (a, b): at its midpoint.
    #[inline]
    pub(crate) fn edge(&self, a: DVec3, b: DVec3) -> f64 {
        self.at((a + b) * 0.5)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_lower_the_target_inside_only() {
        let s = Sizing::with_regions(
            2.0,
            vec![
                (DVec3::ZERO, DVec3::ONE, 1.0),
                (DVec3::splat(0.5), DVec3::splat(3.0), 0.5),
                (DVec3::splat(10.0), DVec3::splat(11.0), 4.0),
            ],
        );
        assert_eq!(s.at(DVec3::splat(0.25)), 1.0);
        assert_eq!(s.at(DVec3::splat(0.75)), 0.5);
        assert_eq!(s.at(DVec3::splat(2.0)), 0.5);
        assert_eq!(s.at(DVec3::splat(5.0)), 2.0);
        // a larger target in a box does not raise the user's
        assert_eq!(s.at(DVec3::splat(10.5)), 2.0);
        assert_eq!(Sizing::uniform(3.0).at(DVec3::splat(0.5)), 3.0);
    }
}
