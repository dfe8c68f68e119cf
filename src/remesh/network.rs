//! The junction network of an interface mesh: which vertices are corners
//! (where junction curves meet; they never move), which lie on a junction
//! curve (they move only along it), and which are interior to one patch.

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
        self.kind[v as usize] != VertexKind::Interior
    }
}
