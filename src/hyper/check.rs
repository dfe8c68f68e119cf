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

/// Runs the checks on `tets` over `n_vertices` vertices.
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
    // 2. triangles with orientation signs
    let mut faces: Vec<([u32; 3], i8)> = tets
        .par_iter()
        .flat_map_iter(|t| {
            let f = [
                [t[1], t[2], t[3]],
                [t[0], t[3], t[2]],
                [t[0], t[1], t[3]],
                [t[0], t[2], t[1]],
            ];
            f.into_iter().map(canonical)
        })
        .collect();
    faces.par_sort_unstable();
    let (mut distinct, mut unpaired, mut misoriented) = (0, 0, 0);
    for run in faces.chunk_by(|a, b| a.0 == b.0) {
        distinct += 1;
        if run.len() != 2 {
            unpaired += 1;
        } else if run[0].1 == run[1].1 {
            misoriented += 1;
        }
    }
    r.triangles = distinct;
    r.unpaired_triangles = unpaired;
    r.misoriented_triangles = misoriented;
    // 3. edge links: the opposite edges of the tetrahedra around an edge form one cycle
    let mut edges: Vec<([u32; 2], [u32; 2])> = tets
        .par_iter()
        .flat_map_iter(|t| {
            const PAIRS: [(usize, usize, usize, usize); 6] = [
                (0, 1, 2, 3),
                (0, 2, 1, 3),
                (0, 3, 1, 2),
                (1, 2, 0, 3),
                (1, 3, 0, 2),
                (2, 3, 0, 1),
            ];
            PAIRS.into_iter().map(move |(a, b, c, d)| {
                let e = [t[a].min(t[b]), t[a].max(t[b])];
                (e, [t[c], t[d]])
            })
        })
        .collect();
    edges.par_sort_unstable();
    r.bad_edge_links = edges
        .par_chunk_by(|a, b| a.0 == b.0)
        .filter(|run| !is_single_cycle(run.iter().map(|x| x.1)))
        .count() as u64;
    // 4. vertex links
    let mut used = vec![false; n_vertices];
    for t in tets {
        for &v in t {
            used[v as usize] = true;
        }
    }
    r.unused_vertices = used.iter().filter(|&&u| !u).count() as u64;
    let mut star: Vec<(u32, [u32; 3])> = tets
        .par_iter()
        .flat_map_iter(|t| {
            (0..4).map(move |i| {
                let mut o = [0u32; 3];
                let mut k = 0;
                for (j, &v) in t.iter().enumerate() {
                    if j != i {
                        o[k] = v;
                        k += 1;
                    }
                }
                (t[i], o)
            })
        })
        .collect();
    star.par_sort_unstable();
    let (bad, cones) = star
        .par_chunk_by(|a, b| a.0 == b.0)
        .map(|run| match link_genus(run.iter().map(|x| x.1)) {
            Some(0) => (0u64, 0u64),
            Some(_) => (0, 1),
            None => (1, 0),
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    r.bad_vertex_links = bad;
    r.cone_points = cones;
    r
}

/// Sorted triangle and the orientation sign of the given order relative to it.
fn canonical(f: [u32; 3]) -> ([u32; 3], i8) {
    let mut s = f;
    let mut sign = 1i8;
    for i in 0..3 {
        for j in 0..2 - i {
            if s[j] > s[j + 1] {
                s.swap(j, j + 1);
                sign = -sign;
            }
        }
    }
    (s, sign)
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

/// Genus of a closed connected surface given by its triangles, or `None` if
/// the triangles do not form one (an edge not in exactly two triangles, not
/// connected, or odd Euler characteristic).
fn link_genus(tris: impl Iterator<Item = [u32; 3]>) -> Option<u32> {
    let tris: Vec<[u32; 3]> = tris.collect();
    let mut verts: Vec<u32> = tris.iter().flatten().copied().collect();
    verts.sort_unstable();
    verts.dedup();
    let mut edges: Vec<[u32; 2]> = tris
        .iter()
        .flat_map(|t| [(0, 1), (1, 2), (0, 2)].map(|(i, j)| [t[i].min(t[j]), t[i].max(t[j])]))
        .collect();
    edges.sort_unstable();
    if edges.chunk_by(|a, b| a == b).any(|r| r.len() != 2) {
        return None;
    }
    let e = edges.len() / 2;
    // connectivity (union-find over local vertex ids)
    let local = |v: u32| verts.binary_search(&v).expect("vertex listed");
    let mut parent: Vec<usize> = (0..verts.len()).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for t in &tris {
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
