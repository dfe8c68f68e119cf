//! Isotropic remeshing of interface patches to a target edge length L
//! (Botsch & Kobbelt 2004), aware of the junction curves the patches share.
//!
//! Each iteration has two passes:
//! 1. **Curves**, one after the other in a fixed order: curve edges longer than
//!    4/3 L are split, shorter than 4/5 L collapsed (never a corner), and curve
//!    vertices relaxed along the curve and projected onto its smoothed reference
//!    polyline. Every change is applied to all patches that share the edge, so
//!    the patches keep sharing their boundary exactly.
//! 2. **Patches**, in parallel: with the curves frozen, interior edges are split
//!    and collapsed, flipped toward valence 6 (4 on the boundary), and interior
//!    vertices relaxed tangentially and projected onto the patch's smoothed
//!    reference surface.
//!
//! Every collapse, flip and move is checked first: the link condition (the
//! patch stays a manifold), no triangle turning over (normal flip), no new edge
//! longer than 4/3 L from a collapse, and no triangle of poor quality where the
//! old ones were better.

use glam::DVec3;
use hashbrown::HashMap;
use rayon::prelude::*;

use super::halfedge::{HalfedgeMesh, NONE};
use super::network::{Network, VertexKind};
use super::sizing::Sizing;
use crate::error::{Error, Result};
use crate::geom::nearest::{CurveRef, NO_TRIANGLE, SurfaceRef};
use crate::geom::predicates::{is_degenerate, triangle_quality};
use crate::mesh::{InterfaceMesh, JunctionCurve};

/// Lowest quality a collapse, flip or move may create (unless the triangles
/// it replaces were worse).
const MIN_QUALITY: f64 = 0.15;

pub(super) struct PatchState {
    pub(super) mesh: HalfedgeMesh,
    pub(super) reference: SurfaceRef,
}

/// How closely new triangles must follow the reference surface.
#[derive(Clone, Copy)]
pub(super) struct Fit<'a> {
    pub(super) reference: &'a SurfaceRef,
    /// Largest distance of a triangle's centroid from the reference, in mm.
    pub(super) eps: f64,
}

impl Fit<'_> {
    /// Whether triangle (a, b, c) fits: `Some` with a reference triangle near
    /// it (a hint for the next check nearby), `None` if it does not fit.
    /// `hint` is a reference triangle near it (or [`NO_TRIANGLE`]); it only
    /// makes the answer faster.
    #[inline]
    pub(super) fn check(&self, a: DVec3, b: DVec3, c: DVec3, hint: u32) -> Option<u32> {
        // A triangle much smaller than eps between vertices on (or near) the
        // reference cannot stray from it; the local normal checks of the
        // operations already keep it from folding over.
        let small = (0.5 * self.eps).powi(2);
        if (b - a).length_squared() <= small
            && (c - b).length_squared() <= small
            && (a - c).length_squared() <= small
        {
            return Some(hint);
        }
        self.reference.fits(a, b, c, self.eps, hint)
    }

    /// [`Fit::check`] for a triangle that will replace face `f` of `m`: starts
    /// from the face's hint if it has one (else from `hint`), and leaves the
    /// reference triangle found in both.
    #[inline]
    pub(super) fn check_face(
        &self,
        m: &HalfedgeMesh,
        f: u32,
        a: DVec3,
        b: DVec3,
        c: DVec3,
        hint: &mut u32,
    ) -> bool {
        let own = m.face_hint[f as usize].get();
        let start = if own != NO_TRIANGLE { own } else { *hint };
        match self.check(a, b, c, start) {
            Some(near) => {
                *hint = near;
                m.face_hint[f as usize].set(near);
                true
            }
            None => false,
        }
    }

    /// Whether triangle (a, b, c) fits (see [`Fit::check`]).
    #[inline]
    pub(super) fn ok(&self, a: DVec3, b: DVec3, c: DVec3, hint: u32) -> bool {
        self.check(a, b, c, hint).is_some()
    }
}

/// The remesher's state.
pub(crate) struct Remesher {
    /// Positions of junction vertices (global ids); interior vertices live in the patches.
    pub(super) pos: Vec<DVec3>,
    pub(super) kind: Vec<VertexKind>,
    pub(super) alive: Vec<bool>,
    pub(super) curves: Vec<Vec<u32>>,
    pub(super) closed: Vec<bool>,
    pub(super) curve_labels: Vec<Vec<crate::volume::LabelId>>,
    pub(super) curve_ref: Vec<CurveRef>,
    pub(super) patches: Vec<PatchState>,
    /// Local copies of each junction vertex: (patch, local vertex).
    pub(super) copies: HashMap<u32, Vec<(u32, u32)>>,
    pub(super) sizing: Sizing,
    /// Largest distance of a new triangle's centroid from the reference (mm).
    pub(super) eps: f64,
}

impl Remesher {
    /// Sets up patch meshes at the smoothed positions `smoothed`.
    pub(crate) fn new(
        mesh: &InterfaceMesh,
        net: &Network,
        smoothed: &[DVec3],
        sizing: Sizing,
        eps: f64,
    ) -> Result<Self> {
        let groups = mesh.patch_triangles();
        let patches: Vec<PatchState> = groups
            .par_iter()
            .enumerate()
            .map(|(p, tris)| build_patch(mesh, net, smoothed, p, tris))
            .collect::<Result<_>>()?;
        let curve_ref = net
            .curves
            .par_iter()
            .map(|c| {
                CurveRef::new(
                    &c.vertices
                        .iter()
                        .map(|&v| smoothed[v as usize])
                        .collect::<Vec<_>>(),
                    c.closed,
                )
            })
            .collect();
        let mut r = Remesher {
            pos: smoothed.to_vec(),
            kind: net.kind.clone(),
            alive: vec![true; smoothed.len()],
            curves: net.curves.iter().map(|c| c.vertices.clone()).collect(),
            closed: net.curves.iter().map(|c| c.closed).collect(),
            curve_labels: mesh.junctions.iter().map(|j| j.labels.clone()).collect(),
            curve_ref,
            patches,
            copies: HashMap::new(),
            sizing,
            eps,
        };
        r.rebuild_copies();
        Ok(r)
    }

    fn rebuild_copies(&mut self) {
        self.copies.clear();
        for (p, st) in self.patches.iter().enumerate() {
            for v in st.mesh.vertices() {
                if st.mesh.locked[v as usize] {
                    self.copies
                        .entry(st.mesh.tag[v as usize])
                        .or_default()
                        .push((p as u32, v));
                }
            }
        }
    }

    /// Runs `iterations` curve + patch passes; returns the seconds spent on
    /// curves and on patches.
    pub(crate) fn run(&mut self, iterations: u32) -> (f64, f64) {
        let (mut curves, mut patches) = (0.0, 0.0);
        for _ in 0..iterations {
            let clock = std::time::Instant::now();
            for c in 0..self.curves.len() {
                self.remesh_curve(c);
            }
            curves += clock.elapsed().as_secs_f64();
            let clock = std::time::Instant::now();
            let (sizing, eps) = (&self.sizing, self.eps);
            self.patches
                .par_iter_mut()
                .for_each(|st| remesh_patch(st, sizing, eps));
            self.rebuild_copies();
            patches += clock.elapsed().as_secs_f64();
        }
        (curves, patches)
    }

    /// The boundary halfedge from local copy of `u` to a local copy of `v` in each patch.
    fn curve_edge(&self, u: u32, v: u32) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for &(p, lu) in self.copies.get(&u).map(|c| c.as_slice()).unwrap_or(&[]) {
            let m = &self.patches[p as usize].mesh;
            if let Some(h) = m
                .outgoing(lu)
                .find(|&g| m.tag[m.to(g) as usize] == v && m.is_boundary_edge(g))
            {
                out.push((p, h));
            }
        }
        out
    }

    fn remesh_curve(&mut self, c: usize) {
        // splits
        let mut i = 0;
        while i < self.curve_edges(c) {
            let (u, v) = self.curve_edge_at(c, i);
            let (pu, pv) = (self.pos[u as usize], self.pos[v as usize]);
            if (pu - pv).length() > 4.0 / 3.0 * self.sizing.edge(pu, pv) {
                self.split_curve_edge(c, i);
                i += 2;
            } else {
                i += 1;
            }
        }
        // collapses
        let mut i = 0;
        while i < self.curve_edges(c) {
            let (u, v) = self.curve_edge_at(c, i);
            let (pu, pv) = (self.pos[u as usize], self.pos[v as usize]);
            let len = (pu - pv).length();
            if len < 4.0 / 5.0 * self.sizing.edge(pu, pv) && self.try_curve_collapse(c, i, u, v) {
                continue;
            }
            i += 1;
        }
        self.relax_curve(c);
    }

    /// Splits edge `i` of curve `c` at its midpoint projected onto the
    /// reference curve (where every patch allows the move), in every patch
    /// that shares it.
    fn split_curve_edge(&mut self, c: usize, i: usize) {
        let m = self.split_curve_edge_at_chord(c, i);
        let onto = self.curve_ref[c].project(self.pos[m as usize]);
        self.move_curve_vertex(m, onto);
    }

    /// Splits edge `i` of curve `c` at its chord midpoint (no triangle changes
    /// shape) in every patch that shares it; returns the new junction vertex.
    fn split_curve_edge_at_chord(&mut self, c: usize, i: usize) -> u32 {
        let (u, v) = self.curve_edge_at(c, i);
        let mid = (self.pos[u as usize] + self.pos[v as usize]) * 0.5;
        let sites = self.curve_edge(u, v);
        let m = self.pos.len() as u32;
        self.pos.push(mid);
        self.kind.push(VertexKind::Curve(c as u32));
        self.alive.push(true);
        for (p, h) in sites {
            let mesh = &mut self.patches[p as usize].mesh;
            let lm = mesh.split(h, mid);
            mesh.tag[lm as usize] = m;
            mesh.locked[lm as usize] = true;
            self.copies.entry(m).or_default().push((p, lm));
        }
        self.curves[c].insert(i + 1, m);
        m
    }

    /// Moves junction vertex `v` to `p` in every patch, if every patch allows it.
    fn move_curve_vertex(&mut self, v: u32, p: DVec3) -> bool {
        let copies = self.copies.get(&v).cloned().unwrap_or_default();
        let ok = copies.iter().all(|&(pi, lv)| {
            let st = &self.patches[pi as usize];
            move_ok(
                &st.mesh,
                lv,
                p,
                Fit {
                    reference: &st.reference,
                    eps: self.eps,
                },
            )
        });
        if ok {
            self.pos[v as usize] = p;
            for (pi, lv) in copies {
                self.patches[pi as usize].mesh.pos[lv as usize] = p;
            }
        }
        ok
    }

    fn curve_edges(&self, c: usize) -> usize {
        let n = self.curves[c].len();
        if self.closed[c] {
            if n > 2 { n } else { 0 }
        } else {
            n.saturating_sub(1)
        }
    }

    fn curve_edge_at(&self, c: usize, i: usize) -> (u32, u32) {
        let cv = &self.curves[c];
        (cv[i], cv[(i + 1) % cv.len()])
    }

    /// Collapses curve edge i (u, v) by removing a non-corner end; false if not allowed.
    fn try_curve_collapse(&mut self, c: usize, i: usize, u: u32, v: u32) -> bool {
        if self.closed[c] && self.curves[c].len() <= 3 {
            return false;
        }
        let n = self.curves[c].len();
        let (remove, keep, idx) = if self.kind[u as usize] != VertexKind::Corner {
            (u, v, i)
        } else if self.kind[v as usize] != VertexKind::Corner {
            (v, u, (i + 1) % n)
        } else {
            return false;
        };
        // the other curve neighbour of `remove` must stay within 4/3 L of `keep`
        let other = if remove == u {
            self.curves[c][(i + n - 1) % n]
        } else {
            self.curves[c][(i + 2) % n]
        };
        let (po, pk) = (self.pos[other as usize], self.pos[keep as usize]);
        if (po - pk).length() > 4.0 / 3.0 * self.sizing.edge(po, pk) {
            return false;
        }
        let sites = self.curve_edge(remove, keep);
        let expected = self.copies.get(&remove).map_or(0, |c| c.len());
        if sites.is_empty() || sites.len() != expected {
            return false;
        }
        let target_pos = self.pos[keep as usize];
        let ok = sites.iter().all(|&(p, h)| {
            let st = &self.patches[p as usize];
            let fit = Fit {
                reference: &st.reference,
                eps: self.eps,
            };
            st.mesh.is_collapse_ok(h)
                && collapse_geometry_ok(&st.mesh, h, target_pos, f64::INFINITY, fit)
        });
        if !ok {
            return false;
        }
        for (p, h) in sites {
            self.patches[p as usize].mesh.collapse(h);
        }
        self.copies.remove(&remove);
        self.alive[remove as usize] = false;
        self.curves[c].remove(idx);
        true
    }

    /// Moves curve vertices toward the middle of their curve neighbours, on the
    /// reference curve, where no triangle turns over.
    fn relax_curve(&mut self, c: usize) {
        let n = self.curves[c].len();
        if n < 3 {
            return;
        }
        let closed = self.closed[c];
        let targets: Vec<(u32, DVec3)> = (0..n)
            .filter(|&i| closed || (i > 0 && i + 1 < n))
            .filter_map(|i| {
                let v = self.curves[c][i];
                if self.kind[v as usize] == VertexKind::Corner {
                    return None;
                }
                let (a, b) = (self.curves[c][(i + n - 1) % n], self.curves[c][(i + 1) % n]);
                let mid = (self.pos[a as usize] + self.pos[b as usize]) * 0.5;
                Some((
                    v,
                    self.curve_ref[c]
                        .project(self.pos[v as usize] + (mid - self.pos[v as usize]) * 0.5),
                ))
            })
            .collect();
        for (v, p) in targets {
            self.move_curve_vertex(v, p);
        }
    }

    /// The current triangles over global vertex ids, with the (patch, face)
    /// each comes from.
    pub(super) fn snapshot(&self) -> Snapshot {
        // junction vertices keep a global numbering; interior ones follow per patch
        let mut new_id = vec![NONE; self.pos.len()];
        let mut positions = Vec::new();
        for (v, &alive) in self.alive.iter().enumerate() {
            if alive && self.copies.contains_key(&(v as u32)) {
                new_id[v] = positions.len() as u32;
                positions.push(self.pos[v]);
            }
        }
        let mut triangles = Vec::new();
        let mut origin = Vec::new();
        let mut local_ids = Vec::with_capacity(self.patches.len());
        let mut face_index = Vec::with_capacity(self.patches.len());
        for (p, st) in self.patches.iter().enumerate() {
            let m = &st.mesh;
            let mut local = vec![NONE; m.vertex_slots()];
            for v in m.vertices() {
                local[v as usize] = if m.locked[v as usize] {
                    new_id[m.tag[v as usize] as usize]
                } else {
                    positions.push(m.pos[v as usize]);
                    (positions.len() - 1) as u32
                };
            }
            let mut faces = vec![NONE; m.face_slots()];
            for f in 0..m.face_slots() as u32 {
                if m.face_dead(f) {
                    continue;
                }
                faces[f as usize] = triangles.len() as u32;
                triangles.push(m.face_vertices(f).map(|v| local[v as usize]));
                origin.push((p as u32, f));
            }
            local_ids.push(local);
            face_index.push(faces);
        }
        Snapshot {
            positions,
            triangles,
            origin,
            new_id,
            local_ids,
            face_index,
        }
    }

    /// The remeshed interface mesh (patches and labels of `like`).
    pub(crate) fn into_mesh(self, like: &InterfaceMesh) -> InterfaceMesh {
        let Snapshot {
            positions,
            triangles,
            origin,
            new_id,
            ..
        } = self.snapshot();
        let triangle_patch = origin.iter().map(|o| o.0).collect();
        let junctions = self
            .curves
            .iter()
            .enumerate()
            .filter(|(_, c)| c.len() >= 2)
            .map(|(i, c)| JunctionCurve {
                vertices: c.iter().map(|&v| new_id[v as usize]).collect(),
                closed: self.closed[i],
                labels: self.curve_labels[i].clone(),
            })
            .collect();
        InterfaceMesh {
            positions,
            triangles,
            triangle_patch,
            patches: like.patches.clone(),
            junctions,
            labels: like.labels.clone(),
            geometry: like.geometry,
        }
    }
}

pub(super) struct Snapshot {
    pub(super) positions: Vec<DVec3>,
    pub(super) triangles: Vec<[u32; 3]>,
    pub(super) origin: Vec<(u32, u32)>,
    pub(super) new_id: Vec<u32>,
    /// Per patch: snapshot vertex id of each local vertex.
    pub(super) local_ids: Vec<Vec<u32>>,
    /// Per patch: snapshot triangle of each face (`NONE` if dead).
    pub(super) face_index: Vec<Vec<u32>>,
}

fn build_patch(
    mesh: &InterfaceMesh,
    net: &Network,
    smoothed: &[DVec3],
    p: usize,
    tris: &[u32],
) -> Result<PatchState> {
    // local ids in order of first use (a flat map: a few MB, cheaper than hashing)
    let mut local_of = vec![NONE; mesh.positions.len()];
    let mut pos = Vec::new();
    let mut tag = Vec::new();
    let mut local_tris = Vec::with_capacity(tris.len());
    let mut ref_tris = Vec::with_capacity(tris.len());
    for &t in tris {
        let tri = mesh.triangles[t as usize];
        ref_tris.push(tri.map(|v| smoothed[v as usize]));
        local_tris.push(tri.map(|v| {
            if local_of[v as usize] == NONE {
                local_of[v as usize] = pos.len() as u32;
                pos.push(smoothed[v as usize]);
                tag.push(v);
            }
            local_of[v as usize]
        }));
    }
    let mut m = HalfedgeMesh::from_triangles(pos, tag, &local_tris).map_err(|e| {
        let [a, b] = mesh.patches[p].labels;
        Error::invalid(format!(
            "patch {} | {} is not a manifold ({e:?}); remeshing needs valid patches (run `septa check`)",
            mesh.label_name(a),
            mesh.label_name(b)
        ))
    })?;
    for v in 0..m.vertex_slots() {
        // islands are locked like junction vertices: nothing moves them
        m.locked[v] = net.on_junction(m.tag[v])
            || matches!(
                net.kind[m.tag[v] as usize],
                VertexKind::Island | VertexKind::Kept
            );
    }
    // Faces are numbered like the reference triangles (the mesh is what the
    // reference was made of): the neighbours across edges come from the
    // halfedges, and every vertex starts with one of its own triangles as hint.
    let mut adjacent = vec![[NO_TRIANGLE; 3]; ref_tris.len()];
    for (f, row) in adjacent.iter_mut().enumerate() {
        let mut h = m.face_halfedge(f as u32);
        for slot in row.iter_mut() {
            let across = m.face(h ^ 1);
            if across != NONE {
                *slot = across;
            }
            let from = m.from(h) as usize;
            m.hint[from] = f as u32;
            m.face_hint[f].set(f as u32);
            h = m.next(h);
        }
    }
    Ok(PatchState {
        mesh: m,
        reference: SurfaceRef::with_adjacency(ref_tris, adjacent),
    })
}

/// Whether moving vertex `v` to `p` keeps every incident triangle facing the
/// same way and of acceptable quality.
pub(super) fn move_ok(m: &HalfedgeMesh, v: u32, p: DVec3, fit: Fit) -> bool {
    let mut hint = m.hint[v as usize];
    for h in m.outgoing(v) {
        if m.is_boundary_halfedge(h) {
            continue;
        }
        let (a, b) = (m.pos[m.to(h) as usize], m.pos[m.to(m.next(h)) as usize]);
        let old_n = (a - m.pos[v as usize]).cross(b - m.pos[v as usize]);
        let new_n = (a - p).cross(b - p);
        if old_n.dot(new_n) <= 0.0 || is_degenerate(p, a, b) {
            return false;
        }
        let (q_old, q_new) = (
            triangle_quality(m.pos[v as usize], a, b),
            triangle_quality(p, a, b),
        );
        if q_new < MIN_QUALITY && q_new < q_old {
            return false;
        }
        if !fit.check_face(m, m.face(h), p, a, b, &mut hint) {
            return false;
        }
    }
    true
}

/// Whether collapsing `h` (from(h) moves to `p`, then merges into to(h)) keeps
/// the triangles facing the same way, of acceptable quality, and its new edges
/// no longer than `max_edge`.
pub(super) fn collapse_geometry_ok(
    m: &HalfedgeMesh,
    h: u32,
    p: DVec3,
    max_edge: f64,
    fit: Fit,
) -> bool {
    let (v0, v1) = (m.from(h), m.to(h));
    // the triangles that stay, as (w, b) with the new triangle (p, w, b)
    let kept = |g: u32| {
        let w = m.to(g);
        if m.is_boundary_halfedge(g) {
            return None;
        }
        let b = m.to(m.next(g));
        // triangles containing both v0 and v1 disappear
        (w != v1 && b != v1).then_some((w, b))
    };
    // cheap checks first, for every triangle: the fits cost the most
    for g in m.outgoing(v0) {
        let w = m.to(g);
        if w != v1 && (m.pos[w as usize] - p).length() > max_edge {
            return false;
        }
        // an edge between two junction vertices may only appear on the boundary:
        // inside a patch it could duplicate an edge of a neighbouring patch
        if w != v1
            && m.locked[v1 as usize]
            && m.locked[w as usize]
            && !m.is_boundary_edge(g)
            && !m.outgoing(v1).any(|k| m.to(k) == w)
        {
            return false;
        }
        let Some((w, b)) = kept(g) else {
            continue;
        };
        // (v1, w, b) must not already exist reversed (a two-triangle pillow)
        let o = m.next(g) ^ 1;
        if !m.is_boundary_halfedge(o) && m.to(m.next(o)) == v1 {
            return false;
        }
        // a triangle on three junction vertices may be a patch's last piece
        // between two curves; making one could flatten a small region into
        // coincident triangles of two patches
        if !m.locked[v0 as usize]
            && m.locked[v1 as usize]
            && m.locked[w as usize]
            && m.locked[b as usize]
        {
            return false;
        }
        let (pa, pb, p0) = (m.pos[w as usize], m.pos[b as usize], m.pos[v0 as usize]);
        let old_n = (pa - p0).cross(pb - p0);
        let new_n = (pa - p).cross(pb - p);
        if old_n.dot(new_n) <= 0.0 || is_degenerate(p, pa, pb) {
            return false;
        }
        let (q_old, q_new) = (triangle_quality(p0, pa, pb), triangle_quality(p, pa, pb));
        if q_new < MIN_QUALITY && q_new < q_old {
            return false;
        }
    }
    let mut hint = m.hint[v1 as usize];
    for g in m.outgoing(v0) {
        let Some((w, b)) = kept(g) else {
            continue;
        };
        if !fit.check_face(
            m,
            m.face(g),
            p,
            m.pos[w as usize],
            m.pos[b as usize],
            &mut hint,
        ) {
            return false;
        }
    }
    true
}

/// One B&K iteration on the interior of a patch (curves frozen).
fn remesh_patch(st: &mut PatchState, sizing: &Sizing, eps: f64) {
    let fit = Fit {
        reference: &st.reference,
        eps,
    };
    split_long_edges(&mut st.mesh, sizing);
    collapse_short_edges(&mut st.mesh, sizing, fit);
    st.mesh.collect_garbage();
    equalize_valences(&mut st.mesh, fit);
    relax_and_project(&mut st.mesh, fit);
}

fn split_long_edges(m: &mut HalfedgeMesh, sizing: &Sizing) {
    let edges: Vec<u32> = m.edges().collect();
    for h in edges {
        if m.is_boundary_edge(h) {
            continue;
        }
        let p = (m.pos[m.from(h) as usize] + m.pos[m.to(h) as usize]) * 0.5;
        if m.edge_length(h) > 4.0 / 3.0 * sizing.at(p) {
            m.split(h, p);
        }
    }
}

fn collapse_short_edges(m: &mut HalfedgeMesh, sizing: &Sizing, fit: Fit) {
    let edges: Vec<u32> = m.edges().collect();
    'edges: for e in edges {
        if m.edge_dead(e) {
            continue;
        }
        let target = sizing.edge(m.pos[m.from(e) as usize], m.pos[m.to(e) as usize]);
        let (lo, hi) = (4.0 / 5.0 * target, 4.0 / 3.0 * target);
        if m.edge_length(e) >= lo {
            continue;
        }
        for h in [e, e ^ 1] {
            let v0 = m.from(h);
            if m.locked[v0 as usize] || m.is_boundary_vertex(v0) {
                continue;
            }
            let p = m.pos[m.to(h) as usize];
            if m.is_collapse_ok(h) && collapse_geometry_ok(m, h, p, hi, fit) {
                m.collapse(h);
                continue 'edges;
            }
        }
        // both ends free: try merging them at the midpoint, on the reference
        let (v0, v1) = (m.from(e), m.to(e));
        if m.locked[v0 as usize]
            || m.locked[v1 as usize]
            || m.is_boundary_vertex(v0)
            || m.is_boundary_vertex(v1)
            || !m.is_collapse_ok(e)
        {
            continue;
        }
        let (p, near) = fit.reference.project_from(
            (m.pos[v0 as usize] + m.pos[v1 as usize]) * 0.5,
            m.hint[v1 as usize],
        );
        if collapse_geometry_ok(m, e, p, hi, fit) && collapse_geometry_ok(m, e ^ 1, p, hi, fit) {
            m.pos[v1 as usize] = p;
            m.hint[v1 as usize] = near;
            m.collapse(e);
        }
    }
}

fn target_valence(m: &HalfedgeMesh, v: u32) -> i32 {
    if m.is_boundary_vertex(v) { 4 } else { 6 }
}

fn equalize_valences(m: &mut HalfedgeMesh, fit: Fit) {
    let edges: Vec<u32> = m.edges().collect();
    for h in edges {
        if m.is_boundary_edge(h) || !m.is_flip_ok(h) {
            continue;
        }
        let (a, b) = (m.from(h), m.to(h));
        let (c, d) = (m.to(m.next(h)), m.to(m.next(h ^ 1)));
        if m.locked[c as usize] && m.locked[d as usize] {
            continue; // see collapse_geometry_ok: no new edge between junction vertices
        }
        let dev = |v: u32, delta: i32| (m.valence(v) as i32 + delta - target_valence(m, v)).abs();
        let before = dev(a, 0) + dev(b, 0) + dev(c, 0) + dev(d, 0);
        let after = dev(a, -1) + dev(b, -1) + dev(c, 1) + dev(d, 1);
        if after < before && flip_geometry_ok(m, a, b, c, d, fit) {
            m.flip(h);
        }
    }
}

/// Flipping a-b into c-d keeps both triangles facing the same way and good enough.
pub(super) fn flip_geometry_ok(m: &HalfedgeMesh, a: u32, b: u32, c: u32, d: u32, fit: Fit) -> bool {
    let [pa, pb, pc, pd] = [a, b, c, d].map(|v| m.pos[v as usize]);
    let n_old = (pb - pa).cross(pc - pa) + (pa - pb).cross(pd - pb);
    let (n1, n2) = ((pd - pa).cross(pc - pa), (pc - pb).cross(pd - pb));
    if n1.dot(n_old) <= 0.0 || n2.dot(n_old) <= 0.0 || n1.dot(n2) <= 0.0 {
        return false;
    }
    if is_degenerate(pd, pc, pa) || is_degenerate(pc, pd, pb) {
        return false;
    }
    let q_old = triangle_quality(pa, pb, pc).min(triangle_quality(pb, pa, pd));
    let q_new = triangle_quality(pd, pc, pa).min(triangle_quality(pc, pd, pb));
    let h = m
        .outgoing(a)
        .find(|&h| m.to(h) == b)
        .expect("a-b is an edge");
    let mut hint = m.hint[a as usize];
    q_new >= q_old.min(MIN_QUALITY)
        && fit.check_face(m, m.face(h), pd, pc, pa, &mut hint)
        && fit.check_face(m, m.face(h ^ 1), pc, pd, pb, &mut hint)
}

/// Tangential relaxation toward the centroid of the one-ring, then projection
/// onto the reference; moves that would turn a triangle over are skipped.
fn relax_and_project(m: &mut HalfedgeMesh, fit: Fit) {
    let moves: Vec<(u32, DVec3, u32)> = m
        .vertices()
        .collect::<Vec<_>>()
        .into_iter()
        .filter(|&v| !m.locked[v as usize] && !m.is_boundary_vertex(v))
        .map(|v| {
            let p = m.pos[v as usize];
            let mut centroid = DVec3::ZERO;
            let mut normal = DVec3::ZERO;
            let mut k = 0.0;
            for h in m.outgoing(v) {
                centroid += m.pos[m.to(h) as usize];
                k += 1.0;
                if !m.is_boundary_halfedge(h) {
                    normal += m.face_normal(m.face(h));
                }
            }
            let n = normal.normalize_or_zero();
            let d = centroid / k - p;
            let (onto, near) = fit
                .reference
                .project_from(p + d - n * d.dot(n), m.hint[v as usize]);
            (v, onto, near)
        })
        .collect();
    for (v, p, near) in moves {
        // the triangle under the new position starts the fit walks
        let old_hint = std::mem::replace(&mut m.hint[v as usize], near);
        if move_ok(m, v, p, fit) {
            m.pos[v as usize] = p;
        } else {
            m.hint[v as usize] = old_hint;
        }
    }
}
