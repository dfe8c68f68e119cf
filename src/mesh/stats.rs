//! Per-patch topology and sizes for reports: triangles, vertices, edges,
//! boundary edges and loops, Euler characteristic, area.

use crate::geom::Dsu;
use rayon::prelude::*;

use super::InterfaceMesh;

/// Topology and size of one patch.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PatchStats {
    pub triangles: usize,
    pub vertices: usize,
    pub edges: usize,
    /// Edges used by one triangle of the patch (on its boundary).
    pub boundary_edges: usize,
    /// Connected components of the boundary edges (closed loops, or groups of
    /// loops touching at a vertex).
    pub boundary_loops: usize,
    /// V − E + F.
    pub euler_characteristic: i64,
    pub area_mm2: f64,
}

/// Statistics of every patch, in patch order.
pub fn patch_stats(mesh: &InterfaceMesh) -> Vec<PatchStats> {
    let groups = mesh.patch_triangles();
    groups
        .par_iter()
        .map(|tris| one_patch(mesh, tris))
        .collect()
}

fn one_patch(mesh: &InterfaceMesh, tris: &[u32]) -> PatchStats {
    let mut verts: Vec<u32> = tris
        .iter()
        .flat_map(|&t| mesh.triangles[t as usize])
        .collect();
    verts.sort_unstable();
    verts.dedup();
    let mut edges: Vec<(u32, u32)> = tris
        .iter()
        .flat_map(|&t| {
            let tri = mesh.triangles[t as usize];
            (0..3).map(move |k| {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                (a.min(b), a.max(b))
            })
        })
        .collect();
    edges.sort_unstable();
    let boundary: Vec<(u32, u32)> = edges
        .chunk_by(|a, b| a == b)
        .filter(|g| g.len() == 1)
        .map(|g| g[0])
        .collect();
    edges.dedup();
    let area = tris.iter().map(|&t| mesh.triangle_area(t as usize)).sum();
    PatchStats {
        triangles: tris.len(),
        vertices: verts.len(),
        edges: edges.len(),
        boundary_edges: boundary.len(),
        boundary_loops: components(&boundary),
        euler_characteristic: verts.len() as i64 - edges.len() as i64 + tris.len() as i64,
        area_mm2: area,
    }
}

/// Connected components of a set of edges.
fn components(edges: &[(u32, u32)]) -> usize {
    let mut ids: Vec<u32> = edges.iter().flat_map(|&(a, b)| [a, b]).collect();
    ids.sort_unstable();
    ids.dedup();
    let index = |v: u32| ids.binary_search(&v).expect("vertex listed") as u32;
    let mut dsu = Dsu::new(ids.len());
    let mut count = ids.len();
    for &(a, b) in edges {
        let (ra, rb) = (dsu.find(index(a)), dsu.find(index(b)));
        if ra != rb {
            dsu.union(ra, rb);
            count -= 1;
        }
    }
    count
}
