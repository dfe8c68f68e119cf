//! Removal of the self-intersections remeshing leaves behind.
//!
//! Remeshed triangles are chords of the smoothed reference; where two sheets
//! of it come closer than a chord's deviation (a sharp dihedral angle at a
//! junction curve, a thin gap) two triangles can cross. This pass looks at
//! each intersecting pair and tries local operations on its triangles, in
//! order: move a free vertex (to its one-ring centroid on the reference, or
//! halfway there), flip an edge, collapse an edge. An operation is taken only
//! if it passes the remesher's own checks (no fold-over, quality, fit to the
//! reference) *and* none of the triangles it makes intersects any other
//! triangle of the mesh; so every accepted step removes intersections and
//! creates none. Rounds repeat until none is left or no step helps.

use glam::DVec3;
use hashbrown::HashSet;

use super::halfedge::{HalfedgeMesh, NONE};
use super::isotropic::{Fit, Remesher, Snapshot, collapse_geometry_ok, flip_geometry_ok, move_ok};
use crate::geom::Bvh;
use crate::geom::intersect::self_intersections;
use crate::geom::nearest::NO_TRIANGLE;
use crate::geom::predicates::triangles_intersect;

/// A candidate change: per patch it touches, the faces it replaces and the
/// triangles (local vertex ids, with an optional moved vertex) it makes.
struct Candidate {
    parts: Vec<Part>,
    op: Op,
}

struct Part {
    patch: u32,
    replaced: Vec<u32>,
    made: Vec<[u32; 3]>,
    moved: Option<(u32, DVec3)>,
}

/// Local id standing for the vertex a split creates (at the `moved` position).
const NEW_VERTEX: u32 = NONE - 1;

#[derive(Clone, Copy)]
enum Op {
    Move(u32, u32, DVec3),
    Flip(u32, u32),
    Collapse(u32, u32),
    Split(u32, u32, DVec3),
}

impl Remesher {
    /// Runs up to `rounds` rounds; returns the number of intersecting pairs left.
    pub(crate) fn repair_intersections(&mut self, rounds: usize) -> usize {
        for _ in 0..rounds {
            let snap = self.snapshot();
            let pairs = self_intersections(&snap.positions, &snap.triangles);
            if pairs.is_empty() {
                return 0;
            }
            let boxes: Vec<(DVec3, DVec3)> = snap
                .triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|v| snap.positions[v as usize]);
                    (a.min(b).min(c), a.max(b).max(c))
                })
                .collect();
            let bvh = Bvh::new(&boxes);
            // snapshot triangles changed this round (their snapshot geometry is stale)
            let mut stale: HashSet<u32> = HashSet::new();
            let mut changed = false;
            for &(t1, t2) in &pairs {
                if stale.contains(&t1) || stale.contains(&t2) {
                    continue;
                }
                for t in [t1, t2] {
                    if self.fix_triangle(&snap, &bvh, &mut stale, t) {
                        changed = true;
                        break;
                    }
                }
            }
            if !changed {
                return pairs.len();
            }
        }
        let snap = self.snapshot();
        self_intersections(&snap.positions, &snap.triangles).len()
    }

    /// Bounding boxes of the triangles that intersect another one.
    pub(crate) fn crossing_boxes(&self) -> Vec<(DVec3, DVec3)> {
        let snap = self.snapshot();
        let pairs = self_intersections(&snap.positions, &snap.triangles);
        let mut tris: Vec<u32> = pairs.iter().flat_map(|&(a, b)| [a, b]).collect();
        tris.sort_unstable();
        tris.dedup();
        tris.iter()
            .map(|&t| {
                let [a, b, c] = snap.triangles[t as usize].map(|v| snap.positions[v as usize]);
                (a.min(b).min(c), a.max(b).max(c))
            })
            .collect()
    }

    /// Tries the operations on snapshot triangle `t`; applies the first that
    /// leaves its triangles free of intersections.
    fn fix_triangle(
        &mut self,
        snap: &Snapshot,
        bvh: &Bvh,
        stale: &mut HashSet<u32>,
        t: u32,
    ) -> bool {
        let (p, f) = snap.origin[t as usize];
        let st = &self.patches[p as usize];
        let m = &st.mesh;
        if m.face_dead(f) {
            return false;
        }
        let fit = Fit {
            reference: &st.reference,
            eps: self.eps,
        };
        let centroid = m.face_vertices(f).map(|v| m.pos[v as usize]);
        let hi = 4.0 / 3.0
            * self
                .sizing
                .at((centroid[0] + centroid[1] + centroid[2]) / 3.0);
        let cands = candidates(m, p, f, fit, hi);

        'cands: for c in cands {
            let mut replaced_all = Vec::new();
            for part in &c.parts {
                let faces = &snap.face_index[part.patch as usize];
                for &g in &part.replaced {
                    let r = faces.get(g as usize).copied().unwrap_or(NONE);
                    if r == NONE || stale.contains(&r) {
                        continue 'cands;
                    }
                    replaced_all.push(r);
                }
            }
            if c.parts
                .iter()
                .any(|part| self.intersects_any(snap, bvh, stale, part, &replaced_all))
            {
                continue;
            }
            match c.op {
                Op::Move(p, v, q) => self.patches[p as usize].mesh.pos[v as usize] = q,
                Op::Flip(p, h) => self.patches[p as usize].mesh.flip(h),
                Op::Collapse(p, h) => self.patches[p as usize].mesh.collapse(h),
                Op::Split(p, h, q) => {
                    self.patches[p as usize].mesh.split(h, q);
                }
            }
            stale.extend(replaced_all);
            return true;
        }
        false
    }

    /// Whether a triangle made by `part` meets a snapshot triangle other than
    /// the `replaced` ones, or comes near a stale one.
    fn intersects_any(
        &self,
        snap: &Snapshot,
        bvh: &Bvh,
        stale: &HashSet<u32>,
        part: &Part,
        replaced: &[u32],
    ) -> bool {
        let m = &self.patches[part.patch as usize].mesh;
        let ids = &snap.local_ids[part.patch as usize];
        let local_pos = |v: u32| match part.moved {
            Some((mv, q)) if mv == v => q,
            _ => m.pos[v as usize],
        };
        for tri in &part.made {
            let g = tri.map(|v| {
                if v == NEW_VERTEX {
                    NEW_VERTEX
                } else {
                    ids[v as usize]
                }
            });
            let q = tri.map(local_pos);
            let (lo, hi) = (q[0].min(q[1]).min(q[2]), q[0].max(q[1]).max(q[2]));
            let mut hit = false;
            bvh.query(lo, hi, |s| {
                if hit || replaced.contains(&s) {
                    return;
                }
                // a changed region: its snapshot geometry is stale, so keep away
                if stale.contains(&s) {
                    hit = true;
                    return;
                }
                let other = snap.triangles[s as usize];
                // positions of both triangles in one small array, shared ids once
                let mut pts = [DVec3::ZERO; 6];
                let mut keys = [NONE; 6];
                let mut n = 0;
                let mut index = |key: u32, pos: DVec3| -> u32 {
                    if let Some(i) = keys[..n].iter().position(|&k| k == key) {
                        return i as u32;
                    }
                    keys[n] = key;
                    pts[n] = pos;
                    n += 1;
                    (n - 1) as u32
                };
                let a = [index(g[0], q[0]), index(g[1], q[1]), index(g[2], q[2])];
                let b = other.map(|v| index(v, snap.positions[v as usize]));
                if triangles_intersect(&pts[..n], a, b) {
                    hit = true;
                }
            });
            if hit {
                return true;
            }
        }
        false
    }
}

/// Operations on face `f` that pass the remesher's checks.
fn candidates(m: &HalfedgeMesh, patch: u32, f: u32, fit: Fit, hi: f64) -> Vec<Candidate> {
    let h0 = m.face_halfedge(f);
    let hs = [h0, m.next(h0), m.prev(h0)];
    let mut out = Vec::new();
    // moves of free vertices
    for &h in &hs {
        let v = m.from(h);
        if m.locked[v as usize] || m.is_boundary_vertex(v) {
            continue;
        }
        let p = m.pos[v as usize];
        let ring: Vec<u32> = m.outgoing(v).map(|g| m.to(g)).collect();
        let centroid = ring.iter().map(|&w| m.pos[w as usize]).sum::<DVec3>() / ring.len() as f64;
        // along the vertex normal, both ways, onto the reference: where a
        // small patch lies flat against another (a thin lens between two
        // patches on one junction loop) its vertex must go back to its own
        // side of the lens
        let normal = m
            .outgoing(v)
            .filter(|&g| !m.is_boundary_halfedge(g))
            .map(|g| m.face_normal(m.face(g)))
            .sum::<DVec3>()
            .normalize_or_zero();
        let offsets = [0.25, 0.5, -0.25, -0.5].map(|k| {
            fit.reference
                .project_from(p + normal * (k * hi), m.hint[v as usize])
                .0
        });
        for target in [
            fit.reference.project(centroid),
            fit.reference.project((p + centroid) * 0.5),
            centroid,
        ]
        .into_iter()
        .chain(offsets)
        {
            if move_ok(m, v, target, fit) {
                let faces: Vec<u32> = m
                    .outgoing(v)
                    .filter(|&g| !m.is_boundary_halfedge(g))
                    .map(|g| m.face(g))
                    .collect();
                out.push(Candidate {
                    parts: vec![Part {
                        patch,
                        made: faces.iter().map(|&g| m.face_vertices(g)).collect(),
                        replaced: faces,
                        moved: Some((v, target)),
                    }],
                    op: Op::Move(patch, v, target),
                });
            }
        }
    }
    // flips
    for &h in &hs {
        if m.is_boundary_edge(h) || !m.is_flip_ok(h) {
            continue;
        }
        let (a, b) = (m.from(h), m.to(h));
        let (c, d) = (m.to(m.next(h)), m.to(m.next(h ^ 1)));
        if m.locked[c as usize] && m.locked[d as usize] {
            continue;
        }
        if flip_geometry_ok(m, a, b, c, d, fit) {
            out.push(Candidate {
                parts: vec![Part {
                    patch,
                    replaced: vec![m.face(h), m.face(h ^ 1)],
                    made: vec![[a, d, c], [b, c, d]],
                    moved: None,
                }],
                op: Op::Flip(patch, h),
            });
        }
    }
    // collapses of a free vertex into a neighbour
    for &h in &hs {
        for g in [h, h ^ 1] {
            let (v0, v1) = (m.from(g), m.to(g));
            if m.locked[v0 as usize] || m.is_boundary_vertex(v0) || !m.is_collapse_ok(g) {
                continue;
            }
            let p = m.pos[v1 as usize];
            if !collapse_geometry_ok(m, g, p, hi, fit) {
                continue;
            }
            let faces: Vec<u32> = m
                .outgoing(v0)
                .filter(|&k| !m.is_boundary_halfedge(k))
                .map(|k| m.face(k))
                .collect();
            let made = faces
                .iter()
                .map(|&k| m.face_vertices(k))
                .filter(|t| !t.contains(&v1))
                .map(|t| t.map(|v| if v == v0 { v1 } else { v }))
                .collect();
            out.push(Candidate {
                parts: vec![Part {
                    patch,
                    replaced: faces,
                    made,
                    moved: None,
                }],
                op: Op::Collapse(patch, g),
            });
        }
    }
    // splits of interior edges, the new vertex on the reference: lets the
    // patch follow its reference where an edge cuts across (typically an edge
    // between two junction vertices that skips a bend of the curve)
    for &h in &hs {
        if m.is_boundary_edge(h) {
            continue;
        }
        let (a, b) = (m.from(h), m.to(h));
        let (c, d) = (m.to(m.next(h)), m.to(m.next(h ^ 1)));
        let [pa, pb, pc, pd] = [a, b, c, d].map(|v| m.pos[v as usize]);
        let q = fit.reference.project((pa + pb) * 0.5);
        let made = [
            [a, NEW_VERTEX, c],
            [NEW_VERTEX, b, c],
            [b, NEW_VERTEX, d],
            [NEW_VERTEX, a, d],
        ];
        let (n1, n2) = ((pb - pa).cross(pc - pa), (pa - pb).cross(pd - pb));
        let ok = made.iter().zip([n1, n1, n2, n2]).all(|(t, n)| {
            let [x, y, z] = t.map(|v| {
                if v == NEW_VERTEX {
                    q
                } else {
                    m.pos[v as usize]
                }
            });
            (y - x).cross(z - x).dot(n) > 0.0
                && !crate::geom::predicates::is_degenerate(x, y, z)
                && fit.ok(x, y, z, NO_TRIANGLE)
        });
        if ok {
            out.push(Candidate {
                parts: vec![Part {
                    patch,
                    replaced: vec![m.face(h), m.face(h ^ 1)],
                    made: made.to_vec(),
                    moved: Some((NEW_VERTEX, q)),
                }],
                op: Op::Split(patch, h, q),
            });
        }
    }
    out
}
