//! The junction network of an interface mesh: which vertices are corners
//! (where junction curves meet; they never move), which lie on a junction
//! curve (they move only along it), and which are interior to one patch.

use crate::geom::Dsu;
use crate::mesh::InterfaceMesh;

/// Role of a vertex during smoothing and remeshing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VertexKind {
    /// Interior to one patch: moves freely within it.
    Interior,
    /// On junction curve `curve` (not an end): moves along the curve.
    Curve(u32),
    /// An end of a junction curve, where curves meet: fixed.
    Corner,
    /// On a small island (a closed surface component without junctions,
    /// e.g. a few voxels of one label inside another): not smoothed, then
    /// remeshed like an interior vertex.
    Island,
}

/// A junction curve: ordered global vertex ids.
#[derive(Clone, Debug, PartialEq)]
pub struct Curve {
    pub vertices: Vec<u32>,
    pub closed: bool,
}

/// Vertex roles and curves.
#[derive(Clone, Debug)]
pub struct Network {
    pub kind: Vec<VertexKind>,
    pub curves: Vec<Curve>,
}

impl Network {
    /// Classifies the vertices of `mesh` from its junction curves.
    pub fn new(mesh: &InterfaceMesh) -> Network {
        let mut kind = vec![VertexKind::Interior; mesh.vertex_count()];
        let mut curves = Vec::with_capacity(mesh.junctions.len());
        for (c, j) in mesh.junctions.iter().enumerate() {
            let n = j.vertices.len();
            for (i, &v) in j.vertices.iter().enumerate() {
                let end = !j.closed && (i == 0 || i + 1 == n);
                kind[v as usize] = match (end, kind[v as usize]) {
                    (true, _) | (_, VertexKind::Corner) => VertexKind::Corner,
                    // a vertex on two curves: where they meet
                    (false, VertexKind::Curve(other)) if other != c as u32 => VertexKind::Corner,
                    (false, _) => VertexKind::Curve(c as u32),
                };
            }
            curves.push(Curve {
                vertices: j.vertices.clone(),
                closed: j.closed,
            });
        }
        Network { kind, curves }
    }

    /// Whether vertex `v` is on a junction (curve or corner).
    #[inline]
    pub fn on_junction(&self, v: u32) -> bool {
        matches!(
            self.kind[v as usize],
            VertexKind::Curve(_) | VertexKind::Corner
        )
    }

    /// Marks the vertices of small islands as [`VertexKind::Island`]:
    /// closed components of the mesh without junction vertices that enclose
    /// at most `max_voxels` voxels or are no longer than `extent` (mm) along
    /// every axis. Smoothing shrinks such a component toward a point or a
    /// needle (it is all high frequency), so they keep their extracted shape
    /// through it (the remesher then remeshes them, keeping their volume
    /// from passing through zero). Returns the number of islands marked.
    pub fn mark_islands(&mut self, mesh: &InterfaceMesh, max_voxels: f64, extent: f64) -> usize {
        let n = mesh.vertex_count();
        let mut dsu = Dsu::new(n);
        for t in &mesh.triangles {
            dsu.union(t[0], t[1]);
            dsu.union(t[0], t[2]);
        }
        let mut junction = vec![false; n];
        let mut lo = vec![glam::DVec3::splat(f64::MAX); n];
        let mut hi = vec![glam::DVec3::splat(f64::MIN); n];
        let mut roots = vec![0u32; n];
        for v in 0..n as u32 {
            let r = dsu.find(v) as usize;
            roots[v as usize] = r as u32;
            junction[r] |= self.on_junction(v);
            lo[r] = lo[r].min(mesh.positions[v as usize]);
            hi[r] = hi[r].max(mesh.positions[v as usize]);
        }
        // enclosed volume per component (about its box corner, for precision)
        let mut volume = vec![0.0f64; n];
        for t in &mesh.triangles {
            let r = roots[t[0] as usize] as usize;
            let [a, b, c] = t.map(|v| mesh.positions[v as usize] - lo[r]);
            volume[r] += a.dot(b.cross(c)) / 6.0;
        }
        let voxel = mesh.geometry.linear_matrix().determinant().abs();
        let small = |r: usize| {
            !junction[r]
                && lo[r].x <= hi[r].x
                && (volume[r].abs() <= max_voxels * voxel
                    || (hi[r] - lo[r]).max_element() <= extent)
        };
        let mut islands = 0;
        for v in 0..n {
            let r = roots[v] as usize;
            if small(r) {
                self.kind[v] = VertexKind::Island;
                islands += usize::from(r == v);
            }
        }
        islands
    }
}
