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
    let n = mesh.vertex_count();
    groups
        .par_iter()
        .map_init(
            || vec![u32::MAX; n],
            |local, tris| one_patch(mesh, tris, local),
        )
        .collect()
}

/// The statistics of the patch made of triangles `tris`. `local` (one slot
/// per mesh vertex, all `u32::MAX`, left so) numbers the patch's vertices;
/// edges are counted per row of their smaller end, as in a CSR matrix, so
/// that only each vertex's few edges are sorted, not the whole patch's.
fn one_patch(mesh: &InterfaceMesh, tris: &[u32], local: &mut [u32]) -> PatchStats {
    let mut verts: Vec<u32> = Vec::new();
    for &t in tris {
        for v in mesh.triangles[t as usize] {
            if local[v as usize] == u32::MAX {
                local[v as usize] = verts.len() as u32;
                verts.push(v);
            }
        }
    }
    let ids: &[u32] = local;
    let edges_of = |t: u32| {
        let tri = mesh.triangles[t as usize];
        (0..3).map(move |k| {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            (ids[a.min(b) as usize], ids[a.max(b) as usize])
        })
    };
    let mut start = vec![0u32; verts.len() + 1];
    for &t in tris {
        for (row, _) in edges_of(t) {
            start[row as usize + 1] += 1;
        }
    }
    for i in 0..verts.len() {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut cols = vec![0u32; start[verts.len()] as usize];
    for &t in tris {
        for (row, col) in edges_of(t) {
            cols[fill[row as usize] as usize] = col;
            fill[row as usize] += 1;
        }
    }
    let mut edges = 0;
    let mut boundary = Vec::new();
    for row in 0..verts.len() {
        let r = &mut cols[start[row] as usize..start[row + 1] as usize];
        r.sort_unstable();
        for g in r.chunk_by(|a, b| a == b) {
            edges += 1;
            if g.len() == 1 {
                boundary.push((row as u32, g[0]));
            }
        }
    }
    for &v in &verts {
        local[v as usize] = u32::MAX;
    }
    let area = tris.iter().map(|&t| mesh.triangle_area(t as usize)).sum();
    PatchStats {
        triangles: tris.len(),
        vertices: verts.len(),
        edges,
        boundary_edges: boundary.len(),
        boundary_loops: components(verts.len(), &boundary),
        euler_characteristic: verts.len() as i64 - edges as i64 + tris.len() as i64,
        area_mm2: area,
    }
}

/// Connected components of a set of edges over vertices `0..n` (vertices
/// on no edge not counted).
fn components(n: usize, edges: &[(u32, u32)]) -> usize {
    let mut dsu = Dsu::new(n);
    let mut on_edge = vec![false; n];
    let mut count = 0usize;
    for &(a, b) in edges {
        for v in [a, b] {
            if !on_edge[v as usize] {
                on_edge[v as usize] = true;
                count += 1;
            }
        }
    }
    for &(a, b) in edges {
        let (ra, rb) = (dsu.find(a), dsu.find(b));
        if ra != rb {
            dsu.union(ra, rb);
            count -= 1;
        }
    }
    count
}
