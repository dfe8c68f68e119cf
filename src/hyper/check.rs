//! Checks that a set of tetrahedra is a closed, oriented 3-manifold (up to
//! isolated cone points):
//!
//! 1. every tetrahedron has four distinct vertices in range;
//! 2. every triangle lies in exactly two tetrahedra, which induce opposite
//!    orientations on it (the boundary of `[v0 v1 v2 v3]` is `[v1 v2 v3] −
//!    [v0 v2 v3] + [v0 v1 v3] − [v0 v1 v2]`);
//! 3. the tetrahedra around every edge form a single cycle (the edge's link
//!    is a circle);
//! 4. the link of every vertex is a closed connected surface; it is a sphere
//!    except at *cone points* (a link of higher genus), which are counted —
//!    STEVE produces them at the volume centres of toroidal polyhedra (see
//!    [`crate::hyper`]).

use rayon::prelude::*;

/// Result of [`check_closed_manifold`].
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ManifoldReport {
    pub tetrahedra: usize,
    /// Distinct triangles.
    pub triangles: usize,
    /// Tetrahedra with a repeated or out-of-range vertex.
    pub bad_tetrahedra: u64,
    /// Triangles in one or more than two tetrahedra.
    pub unpaired_triangles: u64,
    /// Triangles whose two tetrahedra induce the same orientation.
    pub misoriented_triangles: u64,
    /// Edges whose tetrahedra do not form a single cycle.
    pub bad_edge_links: u64,
    /// Vertices whose link is not a closed connected surface.
    pub bad_vertex_links: u64,
    /// Vertices whose link is a closed surface of genus > 0.
    pub cone_points: u64,
    /// Vertices used by no tetrahedron.
    pub unused_vertices: u64,
}

impl ManifoldReport {
    /// Checks 1–4 hold (cone points allowed; unused vertices not allowed).
    pub fn passed(&self) -> bool {
        self.bad_tetrahedra == 0
            && self.unpaired_triangles == 0
            && self.misoriented_triangles == 0
            && self.bad_edge_links == 0
            && self.bad_vertex_links == 0
            && self.unused_vertices == 0
    }

    /// Checks 1–4 hold and no vertex is a cone point.
    pub fn is_manifold(&self) -> bool {
        self.passed() && self.cone_points == 0
    }
}

/// Runs the checks on `tets` over `n_vertices` vertices, vertex by vertex in
/// parallel: the tetrahedra around each vertex (its star) give its link; a
/// triangle is checked at its smallest vertex, an edge at both ends.
pub fn check_closed_manifold(n_vertices: usize, tets: &[[u32; 4]]) -> ManifoldReport {
    let mut r = ManifoldReport {
        tetrahedra: tets.len(),
        ..Default::default()
    };
    r.bad_tetrahedra = tets
        .par_iter()
        .filter(|t| {
            t.iter().any(|&v| v as usize >= n_vertices)
                || (0..4).any(|i| (i + 1..4).any(|j| t[i] == t[j]))
        })
        .count() as u64;
    if r.bad_tetrahedra > 0 {
        return r;
    }
    // stars: tetrahedra around each vertex (compressed rows)
    let (start, star) = crate::geom::incidence::rows(n_vertices, tets);
    let results: Vec<VertexFindings> = (0..n_vertices)
        .into_par_iter()
        .with_min_len(1024)
        .map(|v| {
            let s = &star[start[v] as usize..start[v + 1] as usize];
            vertex_findings(v as u32, s, tets)
        })
        .collect();
    for f in results {
        r.triangles += f.triangles;
        r.unpaired_triangles += f.unpaired;
        r.misoriented_triangles += f.misoriented;
        r.bad_edge_links += f.bad_edges;
        match f.genus {
            None if f.unused => r.unused_vertices += 1,
            None => r.bad_vertex_links += 1,
            Some(0) => {}
            Some(_) => r.cone_points += 1,
        }
    }
    // an edge is checked from both ends
    r.bad_edge_links = r.bad_edge_links.div_ceil(2);
    r
}

/// What the star of one vertex shows.
#[derive(Default)]
struct VertexFindings {
    /// Triangles whose smallest vertex this is.
    triangles: usize,
    unpaired: u64,
    misoriented: u64,
    /// Edges at this vertex whose link is not one cycle.
    bad_edges: u64,
    /// Genus of the link if it is a closed connected surface.
    genus: Option<u32>,
    unused: bool,
}

/// Checks the link of vertex `v` with star `s` (tetrahedron ids).
fn vertex_findings(v: u32, s: &[u32], tets: &[[u32; 4]]) -> VertexFindings {
    let mut f = VertexFindings::default();
    if s.is_empty() {
        f.unused = true;
        return f;
    }
    // link triangles, oriented as faces of the tetrahedra: the face opposite
    // v in [v0 v1 v2 v3] with v = vi, moved to the front (sign of the move)
    let mut link: Vec<[u32; 3]> = Vec::with_capacity(s.len());
    for &ti in s {
        let t = tets[ti as usize];
        let i = t.iter().position(|&x| x == v).expect("vertex in its star");
        // [v0 v1 v2 v3] with vi first: an even permutation keeps the order of the rest
        let rest: [u32; 3] = match i {
            0 => [t[1], t[2], t[3]],
            1 => [t[0], t[3], t[2]],
            2 => [t[0], t[1], t[3]],
            _ => [t[0], t[2], t[1]],
        };
        link.push(rest);
    }
    // link edges (a, b) with the triangle's direction: a closed oriented
    // surface has every edge once in each direction
    let mut edges: Vec<(u32, u32, bool)> = Vec::with_capacity(3 * link.len());
    for t in &link {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b), a < b));
        }
    }
    edges.sort_unstable();
    let mut closed = true;
    for run in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        // the triangle (v, a, b): count it at its smallest vertex
        let counted = v < run[0].0;
        if counted {
            f.triangles += 1;
        }
        if run.len() != 2 {
            closed = false;
            if counted {
                f.unpaired += 1;
            }
        } else if run[0].2 == run[1].2 && counted {
            f.misoriented += 1;
        }
    }
    // every link vertex: its rim in the link is one cycle (the edge's link)
    let mut rims: Vec<(u32, [u32; 2])> = Vec::with_capacity(3 * link.len());
    for t in &link {
        for k in 0..3 {
            rims.push((t[k], [t[(k + 1) % 3], t[(k + 2) % 3]]));
        }
    }
    rims.sort_unstable_by_key(|x| x.0);
    let mut verts: Vec<u32> = Vec::new();
    for run in rims.chunk_by(|x, y| x.0 == y.0) {
        verts.push(run[0].0);
        if !is_single_cycle(run.iter().map(|x| x.1)) {
            f.bad_edges += 1;
            closed = false;
        }
    }
    f.genus = if closed {
        link_genus(&verts, edges.len() / 2, &link)
    } else {
        None
    };
    f
}

/// Whether the edges form one cycle (every vertex in two edges, connected).
fn is_single_cycle(edges: impl Iterator<Item = [u32; 2]>) -> bool {
    let e: Vec<[u32; 2]> = edges.collect();
    if e.len() < 3 {
        return false;
    }
    let mut deg: Vec<(u32, u32)> = Vec::new();
    for &[a, b] in &e {
        for v in [a, b] {
            match deg.iter_mut().find(|x| x.0 == v) {
                Some(x) => x.1 += 1,
                None => deg.push((v, 1)),
            }
        }
    }
    if deg.len() != e.len() || deg.iter().any(|x| x.1 != 2) {
        return false;
    }
    // walk the cycle
    let mut used = vec![false; e.len()];
    let mut at = e[0][1];
    used[0] = true;
    let mut steps = 1;
    while at != e[0][0] {
        let Some(k) = (0..e.len()).find(|&k| !used[k] && (e[k][0] == at || e[k][1] == at)) else {
            return false;
        };
        used[k] = true;
        at = if e[k][0] == at { e[k][1] } else { e[k][0] };
        steps += 1;
    }
    steps == e.len()
}

/// Genus of a closed surface (every edge in two triangles, checked by the
/// caller) with sorted vertices `verts`, `e` edges and triangles `tris`, or
/// `None` if it is not connected or its Euler characteristic is odd or > 2.
fn link_genus(verts: &[u32], e: usize, tris: &[[u32; 3]]) -> Option<u32> {
    let local = |v: u32| verts.binary_search(&v).expect("vertex listed");
    let mut parent: Vec<usize> = (0..verts.len()).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for t in tris {
        let a = find(&mut parent, local(t[0]));
        for &v in &t[1..] {
            let b = find(&mut parent, local(v));
            parent[b] = a;
        }
    }
    let root = find(&mut parent, 0);
    if (0..verts.len()).any(|i| find(&mut parent, i) != root) {
        return None;
    }
    let chi = verts.len() as i64 - e as i64 + tris.len() as i64;
    if chi > 2 || chi % 2 != 0 {
        return None;
    }
    Some(((2 - chi) / 2) as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The boundary of a 4-simplex: 5 tetrahedra, consistently oriented.
    fn simplex_boundary() -> Vec<[u32; 4]> {
        // ∂[0 1 2 3 4] = Σ (−1)^i [.. without i ..]
        let all = [0u32, 1, 2, 3, 4];
        (0..5)
            .map(|i| {
                let mut f: Vec<u32> = all.iter().copied().filter(|&v| v != i as u32).collect();
                if i % 2 == 1 {
                    f.swap(0, 1);
                }
                [f[0], f[1], f[2], f[3]]
            })
            .collect()
    }

    #[test]
    fn simplex_boundary_is_a_manifold_and_every_check_can_fail() {
        let t = simplex_boundary();
        let r = check_closed_manifold(5, &t);
        assert!(r.is_manifold(), "{r:?}");
        assert_eq!(r.triangles, 10);
        let mut flipped = t.clone();
        flipped[0].swap(0, 1);
        let r = check_closed_manifold(5, &flipped);
        assert!(r.misoriented_triangles > 0 && !r.passed());
        let r = check_closed_manifold(5, &t[1..]);
        assert!(r.unpaired_triangles > 0 && !r.passed());
        let r = check_closed_manifold(6, &t);
        assert_eq!(r.unused_vertices, 1);
        let mut bad = t.clone();
        bad[0][1] = bad[0][0];
        assert!(check_closed_manifold(5, &bad).bad_tetrahedra > 0);
        // two copies sharing one vertex: the vertex link is two spheres
        let mut two = t.clone();
        two.extend(t.iter().map(|x| x.map(|v| if v == 0 { 0 } else { v + 4 })));
        let r = check_closed_manifold(9, &two);
        assert_eq!(r.bad_vertex_links, 1, "{r:?}");
    }
}
