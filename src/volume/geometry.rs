//! Index space ↔ physical space (millimetres).
//!
//! septa keeps all topology in integer index space and converts to physical space
//! once, here. Physical space is **LPS** (x toward patient Left, y toward Posterior,
//! z toward Superior), the convention of DICOM, ITK, ITK-SNAP and of 3D Slicer's
//! model files, so that meshes written by septa overlay the image they came from.
//! NIfTI affines (RAS) are converted when read; [`Geometry::to_ras`] goes back.
//!
//! Voxel centres sit at integer indices: voxel `(i, j, k)` has its centre at
//! `affine · (i, j, k, 1)`, and its faces at half-integer indices.

use glam::DVec3;

use crate::error::{Error, Result};

/// The affine map from voxel index `(i, j, k)` to LPS millimetres.
///
/// ```
/// use septa::volume::Geometry;
/// let g = Geometry::new([2.0, 2.0, 3.0], [10.0, 0.0, -5.0], Geometry::IDENTITY_DIRECTION).unwrap();
/// let p = g.index_to_physical([1.0, 0.0, 2.0].into());
/// assert_eq!(p.to_array(), [12.0, 0.0, 1.0]);
/// assert_eq!(g.physical_to_index(p).to_array(), [1.0, 0.0, 2.0]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geometry {
    /// Rows of the 3×4 matrix `[M | t]`: physical = M · index + t (LPS, mm).
    affine: [[f64; 4]; 3],
}

impl Geometry {
    /// Direction cosines of the identity orientation (index axes = LPS axes).
    pub const IDENTITY_DIRECTION: [[f64; 3]; 3] =
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

    /// Unit spacing, zero origin, identity direction.
    pub fn identity() -> Self {
        Self::new([1.0; 3], [0.0; 3], Self::IDENTITY_DIRECTION).expect("identity is valid")
    }

    /// From spacing (mm per index step along each axis), origin (physical position
    /// of voxel (0,0,0)'s centre) and direction cosines. `direction[c]` is the unit
    /// LPS direction of index axis `c` (a column of the ITK direction matrix).
    pub fn new(spacing: [f64; 3], origin: [f64; 3], direction: [[f64; 3]; 3]) -> Result<Self> {
        for (axis, s) in spacing.iter().enumerate() {
            if !(s.is_finite() && *s > 0.0) {
                return Err(Error::invalid(format!(
                    "spacing along axis {axis} is {s}: it must be a positive finite number of mm"
                )));
            }
        }
        let mut affine = [[0.0; 4]; 3];
        for c in 0..3 {
            let d = DVec3::from(direction[c]);
            let len = d.length();
            if !(len.is_finite() && len > 1e-12) {
                return Err(Error::invalid(format!(
                    "direction of axis {c} is zero or not finite"
                )));
            }
            let col = d / len * spacing[c];
            for r in 0..3 {
                affine[r][c] = col[r];
            }
        }
        for r in 0..3 {
            affine[r][3] = origin[r];
        }
        Self::from_affine(affine)
    }

    /// From rows of a 3×4 affine matrix (index → LPS mm). The linear part must be
    /// invertible and finite.
    pub fn from_affine(affine: [[f64; 4]; 3]) -> Result<Self> {
        if affine.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Error::invalid("the affine matrix has a non-finite entry"));
        }
        let g = Geometry { affine };
        let det = g.linear().determinant();
        // Relative test: a 0.01 mm voxel grid is fine, a degenerate axis is not.
        let scale = g.spacing().iter().product::<f64>();
        if !(det.abs() > 1e-9 * scale.max(1e-300)) || scale == 0.0 {
            return Err(Error::invalid(
                "the affine matrix is singular: two index axes map to the same physical direction, or a spacing is zero",
            ));
        }
        Ok(g)
    }

    /// From a NIfTI-style RAS affine (rows of the 3×4 matrix).
    pub fn from_ras_affine(ras: [[f64; 4]; 3]) -> Result<Self> {
        let mut lps = ras;
        for c in 0..4 {
            lps[0][c] = -ras[0][c];
            lps[1][c] = -ras[1][c];
        }
        Self::from_affine(lps)
    }

    /// Rows of the 3×4 affine (index → LPS mm).
    pub fn affine(&self) -> [[f64; 4]; 3] {
        self.affine
    }

    /// Rows of the 3×4 affine (index → RAS mm), as NIfTI stores it.
    pub fn to_ras(&self) -> [[f64; 4]; 3] {
        let mut ras = self.affine;
        for c in 0..4 {
            ras[0][c] = -ras[0][c];
            ras[1][c] = -ras[1][c];
        }
        ras
    }

    fn linear(&self) -> glam::DMat3 {
        let a = &self.affine;
        glam::DMat3::from_cols(
            DVec3::new(a[0][0], a[1][0], a[2][0]),
            DVec3::new(a[0][1], a[1][1], a[2][1]),
            DVec3::new(a[0][2], a[1][2], a[2][2]),
        )
    }

    /// The linear part (index offsets → mm offsets) as a matrix.
    pub fn linear_matrix(&self) -> glam::DMat3 {
        self.linear()
    }

    /// Millimetres per index step along each index axis (the column norms).
    pub fn spacing(&self) -> [f64; 3] {
        let m = self.linear();
        [m.x_axis.length(), m.y_axis.length(), m.z_axis.length()]
    }

    /// Physical position of voxel (0,0,0)'s centre.
    pub fn origin(&self) -> [f64; 3] {
        [self.affine[0][3], self.affine[1][3], self.affine[2][3]]
    }

    /// Unit LPS direction of each index axis (`direction()[c]` for axis `c`).
    pub fn direction(&self) -> [[f64; 3]; 3] {
        let m = self.linear();
        [
            m.x_axis.normalize().to_array(),
            m.y_axis.normalize().to_array(),
            m.z_axis.normalize().to_array(),
        ]
    }

    /// Index coordinates (voxel centres at integers) → LPS millimetres.
    #[inline]
    pub fn index_to_physical(&self, p: DVec3) -> DVec3 {
        let a = &self.affine;
        DVec3::new(
            a[0][0] * p.x + a[0][1] * p.y + a[0][2] * p.z + a[0][3],
            a[1][0] * p.x + a[1][1] * p.y + a[1][2] * p.z + a[1][3],
            a[2][0] * p.x + a[2][1] * p.y + a[2][2] * p.z + a[2][3],
        )
    }

    /// LPS millimetres → index coordinates.
    pub fn physical_to_index(&self, p: DVec3) -> DVec3 {
        let t = DVec3::from(self.origin());
        self.linear().inverse() * (p - t)
    }

    /// The linear part applied to a direction/offset in index units (no origin).
    #[inline]
    pub fn index_vector_to_physical(&self, v: DVec3) -> DVec3 {
        self.linear() * v
    }

    /// Volume of one voxel in mm³ (|det| of the linear part).
    pub fn voxel_volume_mm3(&self) -> f64 {
        self.linear().determinant().abs()
    }

    /// True when the index→physical map flips handedness (det < 0). Meshes are
    /// oriented in index space; writers flip triangles when this is true so that
    /// normals still point from the lower label into the higher one in mm.
    pub fn is_mirroring(&self) -> bool {
        self.linear().determinant() < 0.0
    }

    /// Anatomical orientation code in the RAS+ convention of NIfTI/nibabel: for each
    /// index axis, the letter of the world direction it increases toward (e.g.
    /// `"RAS"`, `"LPS"`, `"LSA"`).
    pub fn orientation_code(&self) -> String {
        let ras = self.to_ras();
        let mut code = String::with_capacity(3);
        for c in 0..3 {
            let col = [ras[0][c], ras[1][c], ras[2][c]];
            let (mut best, mut best_abs) = (0, -1.0);
            for (r, v) in col.iter().enumerate() {
                if v.abs() > best_abs {
                    best = r;
                    best_abs = v.abs();
                }
            }
            let positive = col[best] >= 0.0;
            code.push(match (best, positive) {
                (0, true) => 'R',
                (0, false) => 'L',
                (1, true) => 'A',
                (1, false) => 'P',
                (2, true) => 'S',
                _ => 'I',
            });
        }
        code
    }
}

impl Default for Geometry {
    fn default() -> Self {
        Self::identity()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_codes() {
        assert_eq!(Geometry::identity().orientation_code(), "LPS");
        let ras = Geometry::from_ras_affine([
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ])
        .unwrap();
        assert_eq!(ras.orientation_code(), "RAS");
        // The ITK k-means head: -2 0 0 / 0 0 3 / 0 2 0 in RAS.
        let lsa = Geometry::from_ras_affine([
            [-2.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 3.0, -254.0],
            [0.0, 2.0, 0.0, 0.0],
        ])
        .unwrap();
        assert_eq!(lsa.orientation_code(), "LSA");
        assert_eq!(lsa.spacing(), [2.0, 2.0, 3.0]);
    }

    #[test]
    fn rejects_bad_spacing_and_singular() {
        assert!(Geometry::new([0.0, 1.0, 1.0], [0.0; 3], Geometry::IDENTITY_DIRECTION).is_err());
        assert!(Geometry::new([-1.0, 1.0, 1.0], [0.0; 3], Geometry::IDENTITY_DIRECTION).is_err());
        assert!(
            Geometry::new([1.0, 1.0, f64::NAN], [0.0; 3], Geometry::IDENTITY_DIRECTION).is_err()
        );
        let dup = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(Geometry::new([1.0; 3], [0.0; 3], dup).is_err());
    }

    #[test]
    fn round_trip_rotated() {
        let c = 0.6f64;
        let s = 0.8f64;
        let g = Geometry::new(
            [0.5, 1.5, 2.5],
            [3.0, -4.0, 7.0],
            [[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]],
        )
        .unwrap();
        let p = DVec3::new(3.0, 5.0, 7.0);
        let q = g.physical_to_index(g.index_to_physical(p));
        assert!((p - q).length() < 1e-12);
        assert!((g.voxel_volume_mm3() - 0.5 * 1.5 * 2.5).abs() < 1e-12);
    }
}
