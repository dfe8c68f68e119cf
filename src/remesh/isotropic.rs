//! Isotropic remeshing of one region of the interface patches to the sizing
//! field (Botsch & Kobbelt 2004, with a target per position as in Dunyach et
//! al. 2013), aware of the junction curves the patches share, and unable to
//! make two triangles cross.
//!
//! A [`Remesher`] holds the triangles of one slab of space (see
//! [`super::work`]): one halfedge mesh per patch, the junction-curve runs in
//! it, and a [`Guard`] over its triangles and the fixed ones beside it.
//! Vertices shared with triangles outside the slab are locked. One
//! iteration ([`Remesher::iterate`]) is:
//! 1. **Curves**, one run after the other: edges longer than 4/3 h split,
//!    shorter than 4/5 h collapsed (never a corner), vertices relaxed along
//!    the smoothed reference polyline, by arc length; every change
//!    applies to all patches that share the edge, so they keep sharing their
//!    boundary exactly.
//! 2. **Patches**, one after the other: interior edges split and collapsed,
//!    flipped toward valence 6 (4 on the boundary), interior vertices relaxed
//!    tangentially and projected onto the patch's smoothed reference.
//!
//! Every operation is checked before it is applied: the link condition (the
//! patch stays a manifold), no triangle turning over, no new edge from a
//! collapse longer than 4/3 of its own target, no triangle of poor quality
//! where the old ones were better, the new triangles follow the reference (centroid within `eps`),
//! and the guard: they cross no triangle of any patch. What cannot be done
//! safely is not done, here and now only; the rest of the mesh goes on.

use glam::DVec3;
use hashbrown::HashMap;

use super::guard::{
    FAN_MAX, Guard, Key, SimpleFans, Tri, is_simple_fan, is_simple_ring, vertex_key,
};
use super::halfedge::{HalfedgeMesh, NONE};
use super::network::VertexKind;
use super::sizing::Sizing;
use super::work::Sides;
use crate::geom::nearest::{CurveRef, NO_TRIANGLE, SurfaceRef};
use crate::geom::predicates::{is_degenerate, triangle_quality};
use crate::mesh::quality::{EDGE_RANGE_HI, EDGE_RANGE_LO};

/// Lowest quality a collapse, flip or move may create (unless the triangles
/// it replaces were worse).
const MIN_QUALITY: f64 = 0.15;

/// Relaxation moves shorter than this many targets are not made (the vertex
/// is at rest; the move would cost a projection and every check for nothing).
const RELAX_AT_REST: f64 = 0.02;

/// Edges longer than this many targets are split.
const SPLIT_ABOVE: f64 = EDGE_RANGE_HI;
/// Edges shorter than this many targets are collapsed.
const COLLAPSE_BELOW: f64 = EDGE_RANGE_LO;

/// One patch's part of the region.
pub(super) struct PatchState<'r> {
    pub(super) mesh: HalfedgeMesh,
    pub(super) reference: &'r SurfaceRef,
    /// Per face: unchanged since the extraction.
    pub(super) kept: Vec<bool>,
    /// Per face: the label surface components on its two sides (indices
    /// into [`Remesher::volumes`], or [`NONE`]).
    pub(super) component: Vec<Sides>,
    /// How far off the reference along the normal (mm) the vertices sit in
    /// the offset iterations, on top of their chord offsets: what keeps
    /// the labels' volumes (see `super::volume`).
    pub(super) offset: f64,
}

impl PatchState<'_> {
    /// Puts the faces from slot `first` on (those just made) in the
    /// components `c`.
    fn set_component_of_faces_from(&mut self, first: u32, c: Sides) {
        let first = first as usize;
        if self.component.len() < first {
            self.component.resize(first, [NONE; 2]);
        }
        self.component.truncate(first);
        self.component.resize(self.mesh.face_slots(), c);
    }
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
}

/// A junction curve (or the run of one inside the region): local vertex ids
/// in order; the ends of an open run are fixed.
pub(super) struct CurveRun<'r> {
    pub(super) vertices: Vec<u32>,
    pub(super) closed: bool,
    pub(super) reference: &'r CurveRef,
    /// The junction curve it is (part of): the kind of the vertices made on it.
    pub(super) curve: u32,
}

/// The remesher of one region.
pub(super) struct Remesher<'r> {
    /// Positions of the region's vertices at the start, and of junction
    /// vertices throughout (interior vertices live in the patch meshes).
    pub(super) pos: Vec<DVec3>,
    pub(super) kind: Vec<VertexKind>,
    pub(super) alive: Vec<bool>,
    pub(super) curves: Vec<CurveRun<'r>>,
    pub(super) patches: Vec<PatchState<'r>>,
    /// Local copies of each locked vertex: (patch, local vertex).
    pub(super) copies: HashMap<u32, Vec<(u32, u32)>>,
    pub(super) sizing: &'r Sizing,
    /// Largest distance of a new triangle's centroid from the reference (mm).
    pub(super) eps: f64,
    pub(super) guard: Guard,
    made: Vec<Tri>,
    /// Per triangle of `made`: the components of its sides (those of the
    /// faces it replaces).
    made_sides: Vec<Sides>,
    replaced: Vec<(u32, u32)>,
    /// Scratch: per component, the volume an operation adds to it.
    volume_changes: Vec<(u32, f64)>,
    /// Scratch: a vertex's fan, tested for [`is_simple_fan`].
    fan: Vec<Tri>,
    /// Per label surface component: the signed volume it may still lose
    /// here (see [`Region::volumes`]).
    volumes: Vec<f64>,
    /// Debug counters: guard queries, made triangles, guard ns, refusals; then per pass ns: curves, split, collapse, flip, relax
    pub(super) stats: [u64; 10],
    /// Whether relaxation moves vertices off the reference by their chord
    /// offset ([`chord_offset`]): set for the last two iterations.
    pub(super) offset_chords: bool,
    /// Whether guard queries are timed (`SEPTA_DEBUG_ITER`): two clock
    /// reads per query otherwise cost more than many of them.
    time_guard: bool,
}

/// What [`Remesher::new`] is built from: the region's vertices (ids are
/// positions in these arrays), its triangles by patch, and its curve runs.
pub(super) struct Region<'r> {
    pub(super) pos: Vec<DVec3>,
    /// Interior vertices move; every other kind is locked (`Corner` for
    /// vertices shared with triangles outside the region).
    pub(super) kind: Vec<VertexKind>,
    /// Per patch of the region: its triangles, their reference hints and
    /// whether they are unchanged since the extraction.
    pub(super) patches: Vec<RegionPatch<'r>>,
    pub(super) curves: Vec<CurveRun<'r>>,
    /// Fixed triangles beside the region (local vertex ids).
    pub(super) obstacles: Vec<[u32; 3]>,
    /// Operations may make triangles only within this box.
    pub(super) trusted: (DVec3, DVec3),
    /// Per label surface component (a connected piece of one label's closed
    /// surface) of which the region holds triangles: its share of the
    /// component's signed enclosed volume. No operation may take a
    /// component's volume past its share: the share is what keeps a label
    /// region from turning inside out.
    pub(super) volumes: Vec<f64>,
}

pub(super) struct RegionPatch<'r> {
    pub(super) reference: &'r SurfaceRef,
    pub(super) triangles: Vec<[u32; 3]>,
    pub(super) hints: Vec<u32>,
    pub(super) kept: Vec<bool>,
    /// Per triangle: the components on its two sides (indices into
    /// [`Region::volumes`]) or [`NONE`].
    pub(super) components: Vec<Sides>,
    /// Offset along the normal on top of the chord offsets (see
    /// [`PatchState::offset`]).
    pub(super) offset: f64,
}

impl<'r> Remesher<'r> {
    /// Sets up the patch meshes and the guard of a region; `cell` is the
    /// guard's cell size (mm).
    pub(super) fn new(region: Region<'r>, sizing: &'r Sizing, eps: f64, cell: f64) -> Self {
        let Region {
            pos,
            kind,
            patches,
            curves,
            obstacles,
            trusted,
            volumes,
        } = region;
        let mut local_ids = vec![NONE; pos.len()];
        let patches: Vec<PatchState> = patches
            .into_iter()
            .map(|rp| build_patch(&pos, &kind, rp, &mut local_ids))
            .collect();
        let obstacles = obstacles
            .iter()
            .map(|t| Tri {
                p: t.map(|v| pos[v as usize]),
                k: t.map(|v| v as Key),
            })
            .collect();
        let guard = Guard::new(cell, &patches, obstacles, trusted);
        let mut r = Remesher {
            alive: vec![true; pos.len()],
            pos,
            kind,
            curves,
            patches,
            copies: HashMap::new(),
            sizing,
            eps,
            guard,
            made: Vec::new(),
            made_sides: Vec::new(),
            replaced: Vec::new(),
            volume_changes: Vec::new(),
            fan: Vec::new(),
            volumes,
            stats: [0; 10],
            offset_chords: false,
            time_guard: std::env::var_os("SEPTA_DEBUG_ITER").is_some(),
        };
        r.rebuild_copies();
        r
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

    /// Whether an interior edge of patch `p` between its junction vertices
    /// `a` and `b` (local ids) would be an edge of no other patch: shown
    /// when one of them lies on a curve within this region (so that every
    /// patch around it is here, in `copies`) and no other patch has an
    /// edge between its copies of the two. `false` where that cannot be
    /// shown (both are corners, or vertices shared with other blocks).
    fn junction_edge_free(&self, p: u32, a: u32, b: u32) -> bool {
        let m = &self.patches[p as usize].mesh;
        let (ta, tb) = (m.tag[a as usize], m.tag[b as usize]);
        let on_curve =
            |t: u32| t != NONE && matches!(self.kind.get(t as usize), Some(VertexKind::Curve(_)));
        let (seen, other) = if on_curve(ta) {
            (ta, tb)
        } else if on_curve(tb) {
            (tb, ta)
        } else {
            return false;
        };
        if other == NONE {
            return false;
        }
        let Some(copies) = self.copies.get(&seen) else {
            return false;
        };
        copies.iter().all(|&(q, lv)| {
            let mq = &self.patches[q as usize].mesh;
            q == p || !mq.outgoing(lv).any(|k| mq.tag[mq.to(k) as usize] == other)
        })
    }

    /// One curve pass and one pass over every patch.
    pub(super) fn iterate(&mut self) {
        let t = std::time::Instant::now();
        for c in 0..self.curves.len() {
            self.remesh_curve(c);
        }
        self.stats[4] += t.elapsed().as_nanos() as u64;
        for p in 0..self.patches.len() {
            self.remesh_patch(p as u32);
        }
    }

    // ---- guarded application -------------------------------------------

    /// Whether the triangles in `self.made` (of sides `self.made_sides`) may
    /// replace those in `self.replaced` (the guard).
    fn guard_clear(&mut self, fans: Option<SimpleFans>) -> bool {
        self.stats[0] += 1;
        self.stats[1] += self.made.len() as u64;
        self.find_volume_changes();
        // every label surface keeps the sign of its volume: a region cannot
        // jump through itself and come out inside out (which no crossing
        // test sees)
        let flips = |&(c, change): &(u32, f64)| {
            let left = self.volumes[c as usize];
            !(left * (left + change) > 0.0)
        };
        if self.volume_changes.iter().any(flips) {
            self.stats[3] += 1;
            return false;
        }
        let t = self.time_guard.then(std::time::Instant::now);
        let ok = self.guard.clear(&self.made, &self.replaced, fans);
        if let Some(t) = t {
            self.stats[2] += t.elapsed().as_nanos() as u64;
        }
        self.stats[3] += u64::from(!ok);
        if ok {
            for &(c, change) in &self.volume_changes {
                self.volumes[c as usize] += change;
            }
        }
        ok
    }

    /// Per label surface component, the signed volume it gains when
    /// `self.made` replaces `self.replaced` (into `self.volume_changes`).
    /// The made and the replaced faces of one component bound the same ring,
    /// so the difference is the volume between them, whatever the origin.
    fn find_volume_changes(&mut self) {
        let mut changes = std::mem::take(&mut self.volume_changes);
        changes.clear();
        debug_assert_eq!(self.made.len(), self.made_sides.len());
        let o = match self.made.first() {
            Some(t) => t.p[0],
            None => match self.replaced.first() {
                Some(&(p, f)) => {
                    let m = &self.patches[p as usize].mesh;
                    m.pos[m.face_vertices(f)[0] as usize]
                }
                None => return,
            },
        };
        let cone = |p: [DVec3; 3]| (p[0] - o).dot((p[1] - o).cross(p[2] - o)) / 6.0;
        for (t, sides) in self.made.iter().zip(&self.made_sides) {
            add_to_sides(&mut changes, *sides, cone(t.p));
        }
        for &(p, f) in &self.replaced {
            let st = &self.patches[p as usize];
            if st.mesh.face_dead(f) {
                continue;
            }
            let sides = st.component.get(f as usize).copied().unwrap_or([NONE; 2]);
            let face = st.mesh.face_vertices(f).map(|v| st.mesh.pos[v as usize]);
            add_to_sides(&mut changes, sides, -cone(face));
        }
        self.volume_changes = changes;
    }

    /// The components of face `f` of patch `p`.
    fn sides_of(&self, p: u32, f: u32) -> Sides {
        self.patches[p as usize]
            .component
            .get(f as usize)
            .copied()
            .unwrap_or([NONE; 2])
    }

    /// Before faces change: takes them out of the guard.
    fn unregister(&mut self, faces: &[(u32, u32)]) {
        for &(p, f) in faces {
            self.guard.remove(p, f);
        }
    }

    /// After faces changed (or were made): registers the live ones and marks
    /// them changed.
    fn register(&mut self, faces: &[(u32, u32)]) {
        for &(p, f) in faces {
            let st = &mut self.patches[p as usize];
            if st.mesh.face_dead(f) {
                continue;
            }
            if st.kept.len() <= f as usize {
                st.kept.resize(st.mesh.face_slots(), false);
            }
            st.kept[f as usize] = false;
            self.guard.insert(&st.mesh, p, f);
        }
    }

    /// Faces of patch `p` around local vertex `v`, appended to `out`.
    fn faces_around(m: &HalfedgeMesh, p: u32, v: u32, out: &mut Vec<(u32, u32)>) {
        for h in m.outgoing(v) {
            let f = m.face(h);
            if f != NONE && !out.contains(&(p, f)) {
                out.push((p, f));
            }
        }
    }

    /// The triangles around `v` in patch `p` with `v` at `at` (and key
    /// `key`), leaving out faces holding `skip`, appended to `out`.
    fn fan_moved(
        m: &HalfedgeMesh,
        p: u32,
        v: u32,
        at: DVec3,
        key: Key,
        skip: u32,
        out: &mut Vec<Tri>,
    ) {
        for h in m.outgoing(v) {
            if m.is_boundary_halfedge(h) {
                continue;
            }
            let (a, b) = (m.to(h), m.to(m.next(h)));
            if a == skip || b == skip {
                continue;
            }
            out.push(Tri {
                p: [at, m.pos[a as usize], m.pos[b as usize]],
                k: [key, vertex_key(m, p, a), vertex_key(m, p, b)],
            });
        }
    }

    /// Collapses halfedge `h` of patch `p` (its from-vertex merges into its
    /// to-vertex, which moves to `at`), if the guard allows it.
    fn guarded_collapse(&mut self, p: u32, h: u32, at: DVec3) -> bool {
        let mut made = std::mem::take(&mut self.made);
        let mut replaced = std::mem::take(&mut self.replaced);
        made.clear();
        replaced.clear();
        let m = &self.patches[p as usize].mesh;
        let (v0, v1) = (m.from(h), m.to(h));
        let k1 = vertex_key(m, p, v1);
        Self::fan_moved(m, p, v0, at, k1, v1, &mut made);
        if at != m.pos[v1 as usize] {
            Self::fan_moved(m, p, v1, at, k1, v0, &mut made);
        }
        // the faces that change: those around v0 (the two on the edge die),
        // and those around v1 if it moves; the rest around v1 stay and are
        // tested like any other face
        Self::faces_around(m, p, v0, &mut replaced);
        if at != m.pos[v1 as usize] {
            Self::faces_around(m, p, v1, &mut replaced);
        }
        // v1's fan after the collapse: the triangles made, and its faces
        // that stay (when it stays)
        let mut fan = std::mem::take(&mut self.fan);
        fan.clear();
        fan.extend_from_slice(&made);
        if at == m.pos[v1 as usize] {
            Self::fan_moved(m, p, v1, at, k1, v0, &mut fan);
        }
        let fans = is_simple_fan(&fan).then_some(SimpleFans {
            patch: p,
            apexes: [Some(k1), None, None],
        });
        // (the faces around an interior vertex are of one piece of each label's surface)
        let sides = replaced
            .first()
            .map_or([NONE; 2], |&(p, f)| self.sides_of(p, f));
        self.made_sides.clear();
        self.made_sides.resize(made.len(), sides);
        self.fan = fan;
        self.made = made;
        self.replaced = replaced;
        if !self.guard_clear(fans) {
            return false;
        }
        let changed = std::mem::take(&mut self.replaced);
        self.unregister(&changed);
        let m = &mut self.patches[p as usize].mesh;
        m.pos[v1 as usize] = at;
        m.collapse(h);
        self.register(&changed);
        self.replaced = changed;
        true
    }

    /// Flips the edge of `h` in patch `p`, if the guard allows it.
    fn guarded_flip(&mut self, p: u32, h: u32) -> bool {
        let mut made = std::mem::take(&mut self.made);
        made.clear();
        let m = &self.patches[p as usize].mesh;
        let (a, b) = (m.from(h), m.to(h));
        let (c, d) = (m.to(m.next(h)), m.to(m.next(h ^ 1)));
        let tri = |x: u32, y: u32, z: u32| Tri {
            p: [x, y, z].map(|v| m.pos[v as usize]),
            k: [x, y, z].map(|v| vertex_key(m, p, v)),
        };
        made.push(tri(d, c, a));
        made.push(tri(c, d, b));
        let faces = [(p, m.face(h)), (p, m.face(h ^ 1))];
        let sides = self.sides_of(p, faces[0].1);
        self.made_sides.clear();
        self.made_sides.resize(made.len(), sides);
        self.made = made;
        self.replaced.clear();
        self.replaced.extend_from_slice(&faces);
        if !self.guard_clear(None) {
            return false;
        }
        self.unregister(&faces);
        self.patches[p as usize].mesh.flip(h);
        self.register(&faces);
        true
    }

    /// Splits the edge of `h` in patch `p` at its midpoint; returns the new
    /// vertex. The two new triangles of each side tile the old one (same
    /// plane, same points), so a split cannot make a crossing: the guard
    /// only learns of it.
    fn split_at_midpoint(&mut self, p: u32, h: u32) -> u32 {
        let m = &self.patches[p as usize].mesh;
        let at = (m.pos[m.from(h) as usize] + m.pos[m.to(h) as usize]) * 0.5;
        let old: Vec<(u32, u32)> = [h, h ^ 1]
            .into_iter()
            .filter(|&g| !m.is_boundary_halfedge(g))
            .map(|g| (p, m.face(g)))
            .collect();
        self.unregister(&old);
        let st = &mut self.patches[p as usize];
        let before = st.mesh.face_slots() as u32;
        let v = st.mesh.split(h, at);
        // the new faces are of the split faces' components
        let c = old
            .first()
            .and_then(|&(_, f)| st.component.get(f as usize).copied())
            .unwrap_or([NONE; 2]);
        st.set_component_of_faces_from(before, c);
        let mut changed = old;
        changed.extend((before..st.mesh.face_slots() as u32).map(|f| (p, f)));
        self.register(&changed);
        v
    }

    // ---- curves ----------------------------------------------------------

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
            if (pu - pv).length() > SPLIT_ABOVE * self.sizing.edge(pu, pv)
                && self.split_curve_edge(c, i)
            {
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
            if len < COLLAPSE_BELOW * self.sizing.edge(pu, pv)
                && self.try_curve_collapse(c, i, u, v)
            {
                continue;
            }
            i += 1;
        }
        self.relax_curve(c);
    }

    /// Splits edge `i` of curve `c` at its midpoint, then moves the new vertex
    /// onto the reference curve where every patch allows it.
    fn split_curve_edge(&mut self, c: usize, i: usize) -> bool {
        let Some(m) = self.split_curve_edge_at_chord(c, i) else {
            return false;
        };
        let onto = self.curves[c].reference.project(self.pos[m as usize]);
        self.move_curve_vertex(m, onto);
        true
    }

    /// Splits edge `i` of curve `c` at its chord midpoint in every patch
    /// that shares it (no triangle changes shape: see
    /// [`Remesher::split_at_midpoint`]); returns the new junction vertex.
    fn split_curve_edge_at_chord(&mut self, c: usize, i: usize) -> Option<u32> {
        let (u, v) = self.curve_edge_at(c, i);
        let mid = (self.pos[u as usize] + self.pos[v as usize]) * 0.5;
        let sites = self.curve_edge(u, v);
        if sites.is_empty() {
            return None;
        }
        let new = self.pos.len() as u32;
        let old: Vec<(u32, u32)> = sites
            .iter()
            .map(|&(p, h)| {
                let m = &self.patches[p as usize].mesh;
                let g = if m.is_boundary_halfedge(h) { h ^ 1 } else { h };
                (p, m.face(g))
            })
            .collect();
        self.unregister(&old);
        self.pos.push(mid);
        self.kind.push(self.kind_of_new_curve_vertex(c));
        self.alive.push(true);
        let mut changed = old.clone();
        for (&(p, h), &(_, f)) in sites.iter().zip(&old) {
            let st = &mut self.patches[p as usize];
            let sides = st.component.get(f as usize).copied().unwrap_or([NONE; 2]);
            let before = st.mesh.face_slots() as u32;
            let lm = st.mesh.split(h, mid);
            st.mesh.tag[lm as usize] = new;
            st.mesh.locked[lm as usize] = true;
            // the new face is of the split face's components
            st.set_component_of_faces_from(before, sides);
            changed.extend((before..st.mesh.face_slots() as u32).map(|f| (p, f)));
            self.copies.entry(new).or_default().push((p, lm));
        }
        self.register(&changed);
        self.curves[c].vertices.insert(i + 1, new);
        Some(new)
    }

    /// The kind of a vertex made on curve run `c`.
    fn kind_of_new_curve_vertex(&self, c: usize) -> VertexKind {
        VertexKind::Curve(self.curves[c].curve)
    }

    /// Moves junction vertex `v` to `p` in every patch, if every patch and the
    /// guard allow it.
    fn move_curve_vertex(&mut self, v: u32, p: DVec3) -> bool {
        let copies = self.copies.get(&v).cloned().unwrap_or_default();
        let ok = copies.iter().all(|&(pi, lv)| {
            let st = &self.patches[pi as usize];
            move_ok(
                &st.mesh,
                lv,
                p,
                Fit {
                    reference: st.reference,
                    eps: self.eps,
                },
            )
        });
        if !ok {
            return false;
        }
        let mut made = std::mem::take(&mut self.made);
        made.clear();
        self.replaced.clear();
        self.made_sides.clear();
        for &(pi, lv) in &copies {
            let m = &self.patches[pi as usize].mesh;
            Self::fan_moved(m, pi, lv, p, v as Key, NONE, &mut made);
            let first = self.replaced.len();
            Self::faces_around(m, pi, lv, &mut self.replaced);
            let sides = self
                .replaced
                .get(first)
                .map_or([NONE; 2], |&(q, f)| self.sides_of(q, f));
            self.made_sides.resize(made.len(), sides);
        }
        self.made = made;
        if !self.guard_clear(None) {
            return false;
        }
        let faces = self.replaced.clone();
        self.unregister(&faces);
        self.pos[v as usize] = p;
        for (pi, lv) in copies {
            self.patches[pi as usize].mesh.pos[lv as usize] = p;
        }
        self.register(&faces);
        true
    }

    fn curve_edges(&self, c: usize) -> usize {
        let n = self.curves[c].vertices.len();
        if self.curves[c].closed {
            if n > 2 { n } else { 0 }
        } else {
            n.saturating_sub(1)
        }
    }

    fn curve_edge_at(&self, c: usize, i: usize) -> (u32, u32) {
        let cv = &self.curves[c].vertices;
        (cv[i], cv[(i + 1) % cv.len()])
    }

    fn movable_on_curve(&self, v: u32) -> bool {
        matches!(self.kind[v as usize], VertexKind::Curve(_))
    }

    /// Collapses curve edge i (u, v) by removing a movable end, the one that
    /// leaves the shorter edge first, then the other; false if neither may go.
    fn try_curve_collapse(&mut self, c: usize, i: usize, u: u32, v: u32) -> bool {
        if self.curves[c].closed && self.curves[c].vertices.len() <= 3 {
            return false;
        }
        let n = self.curves[c].vertices.len();
        let closed = self.curves[c].closed;
        // (remove, keep, its index, the other curve neighbour of `remove`)
        let mut ends: Vec<(u32, u32, usize, u32)> = Vec::with_capacity(2);
        if self.movable_on_curve(u) && (closed || i > 0) {
            ends.push((u, v, i, self.curves[c].vertices[(i + n - 1) % n]));
        }
        if self.movable_on_curve(v) && (closed || i + 2 < n) {
            ends.push((v, u, (i + 1) % n, self.curves[c].vertices[(i + 2) % n]));
        }
        let left = |s: &Self, &(_, keep, _, other): &(u32, u32, usize, u32)| {
            (s.pos[other as usize] - s.pos[keep as usize]).length()
        };
        if ends.len() == 2 && left(self, &ends[1]) < left(self, &ends[0]) {
            ends.swap(0, 1);
        }
        ends.into_iter()
            .any(|(remove, keep, idx, other)| self.collapse_curve_end(c, remove, keep, idx, other))
    }

    /// Removes curve vertex `remove` (at index `idx` of curve `c`) into its
    /// neighbour `keep`, if the edge left to `other` (its other neighbour)
    /// is not too long and every patch and the guard allow it.
    fn collapse_curve_end(
        &mut self,
        c: usize,
        remove: u32,
        keep: u32,
        idx: usize,
        other: u32,
    ) -> bool {
        let (po, pk) = (self.pos[other as usize], self.pos[keep as usize]);
        if (po - pk).length() > SPLIT_ABOVE * self.sizing.edge(po, pk) {
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
                reference: st.reference,
                eps: self.eps,
            };
            st.mesh.is_collapse_ok(h)
                && collapse_geometry_ok(&st.mesh, h, target_pos, None, fit, &|_, _| false)
        });
        if !ok {
            return false;
        }
        let mut made = std::mem::take(&mut self.made);
        made.clear();
        self.replaced.clear();
        self.made_sides.clear();
        for &(p, h) in &sites {
            let m = &self.patches[p as usize].mesh;
            let (v0, v1) = (m.from(h), m.to(h));
            Self::fan_moved(m, p, v0, target_pos, keep as Key, v1, &mut made);
            let first = self.replaced.len();
            Self::faces_around(m, p, v0, &mut self.replaced);
            let sides = self
                .replaced
                .get(first)
                .map_or([NONE; 2], |&(q, f)| self.sides_of(q, f));
            self.made_sides.resize(made.len(), sides);
        }
        self.made = made;
        if !self.guard_clear(None) {
            return false;
        }
        let faces = self.replaced.clone();
        self.unregister(&faces);
        for (p, h) in sites {
            self.patches[p as usize].mesh.collapse(h);
        }
        self.register(&faces);
        self.copies.remove(&remove);
        self.alive[remove as usize] = false;
        self.curves[c].vertices.remove(idx);
        true
    }

    /// Moves curve vertices halfway toward the middle, along the
    /// reference curve, of their curve neighbours (by arc length: a
    /// straight-line midpoint lies off the curve, across a small loop even
    /// on its far side), where no triangle turns over and the guard allows it;
    /// a vertex closer to its target than [`RELAX_AT_REST`] of the local
    /// target edge stays (a move that small changes nothing worth a query).
    fn relax_curve(&mut self, c: usize) {
        let n = self.curves[c].vertices.len();
        if n < 3 {
            return;
        }
        let closed = self.curves[c].closed;
        let reference = self.curves[c].reference;
        // each vertex's arc length once (a BVH query), not once per
        // neighbour that needs it
        let arcs: Vec<Option<f64>> = self.curves[c]
            .vertices
            .iter()
            .map(|&u| reference.locate(self.pos[u as usize]).map(|(_, s)| s))
            .collect();
        let targets: Vec<(u32, DVec3)> = (0..n)
            .filter(|&i| closed || (i > 0 && i + 1 < n))
            .filter_map(|i| {
                let v = self.curves[c].vertices[i];
                if !self.movable_on_curve(v) {
                    return None;
                }
                let (a, b) = (arcs[(i + n - 1) % n]?, arcs[(i + 1) % n]?);
                let s = relaxed_arc(reference, a, arcs[i]?, b)?;
                let (from, to) = (self.pos[v as usize], reference.at(s));
                // a vertex at rest stays, as on the patches
                (from.distance(to) >= RELAX_AT_REST * self.sizing.at(from)).then_some((v, to))
            })
            .collect();
        for (v, p) in targets {
            self.move_curve_vertex(v, p);
        }
    }

    // ---- patches -----------------------------------------------------------

    /// One B&K iteration on the interior of patch `p` (curves frozen).
    fn remesh_patch(&mut self, p: u32) {
        let t = std::time::Instant::now();
        self.split_long_edges(p);
        self.stats[5] += t.elapsed().as_nanos() as u64;
        let t = std::time::Instant::now();
        self.collapse_short_edges(p);
        self.stats[6] += t.elapsed().as_nanos() as u64;
        let t = std::time::Instant::now();
        self.equalize_valences(p);
        self.stats[7] += t.elapsed().as_nanos() as u64;
        let t = std::time::Instant::now();
        self.relax_and_project(p);
        self.stats[8] += t.elapsed().as_nanos() as u64;
    }

    fn fit(&self, p: u32) -> Fit<'r> {
        Fit {
            reference: self.patches[p as usize].reference,
            eps: self.eps,
        }
    }

    fn split_long_edges(&mut self, p: u32) {
        let edges: Vec<u32> = self.patches[p as usize].mesh.edges().collect();
        for h in edges {
            let m = &self.patches[p as usize].mesh;
            if m.is_boundary_edge(h) {
                continue;
            }
            let (a, b) = (m.pos[m.from(h) as usize], m.pos[m.to(h) as usize]);
            if (a - b).length() > SPLIT_ABOVE * self.sizing.at((a + b) * 0.5) {
                self.split_at_midpoint(p, h);
            }
        }
    }

    fn collapse_short_edges(&mut self, p: u32) {
        let fit = self.fit(p);
        // no new edge that the split pass would split again
        let max_edge = Some(self.sizing);
        let edges: Vec<u32> = self.patches[p as usize].mesh.edges().collect();
        'edges: for e in edges {
            let m = &self.patches[p as usize].mesh;
            if m.edge_dead(e) {
                continue;
            }
            let target = self
                .sizing
                .edge(m.pos[m.from(e) as usize], m.pos[m.to(e) as usize]);
            if m.edge_length(e) >= COLLAPSE_BELOW * target {
                continue;
            }
            for h in [e, e ^ 1] {
                let m = &self.patches[p as usize].mesh;
                let v0 = m.from(h);
                if m.locked[v0 as usize] || m.is_boundary_vertex(v0) {
                    continue;
                }
                let at = m.pos[m.to(h) as usize];
                let free = |a: u32, b: u32| self.junction_edge_free(p, a, b);
                if m.is_collapse_ok(h)
                    && collapse_geometry_ok(m, h, at, max_edge, fit, &free)
                    && self.guarded_collapse(p, h, at)
                {
                    continue 'edges;
                }
            }
            // both ends free: try merging them at the midpoint, on the reference
            let m = &self.patches[p as usize].mesh;
            let (v0, v1) = (m.from(e), m.to(e));
            if m.locked[v0 as usize]
                || m.locked[v1 as usize]
                || m.is_boundary_vertex(v0)
                || m.is_boundary_vertex(v1)
                || !m.is_collapse_ok(e)
            {
                continue;
            }
            let (at, near) = fit.reference.project_from(
                (m.pos[v0 as usize] + m.pos[v1 as usize]) * 0.5,
                m.hint[v1 as usize],
            );
            let free = |a: u32, b: u32| self.junction_edge_free(p, a, b);
            if collapse_geometry_ok(m, e, at, max_edge, fit, &free)
                && collapse_geometry_ok(m, e ^ 1, at, max_edge, fit, &free)
                && self.guarded_collapse(p, e, at)
            {
                self.patches[p as usize].mesh.hint[v1 as usize] = near;
            }
        }
    }

    fn equalize_valences(&mut self, p: u32) {
        let fit = self.fit(p);
        let edges: Vec<u32> = self.patches[p as usize].mesh.edges().collect();
        for h in edges {
            let m = &self.patches[p as usize].mesh;
            if m.edge_dead(h) || m.is_boundary_edge(h) || !m.is_flip_ok(h) {
                continue;
            }
            let (a, b) = (m.from(h), m.to(h));
            let (c, d) = (m.to(m.next(h)), m.to(m.next(h ^ 1)));
            if (m.locked[c as usize] && m.locked[d as usize])
                || m.pinched[c as usize]
                || m.pinched[d as usize]
            {
                continue; // see collapse_geometry_ok: no new edge between junction vertices, none at a pinch
            }
            let dev =
                |v: u32, delta: i32| (m.valence(v) as i32 + delta - target_valence(m, v)).abs();
            let before = dev(a, 0) + dev(b, 0) + dev(c, 0) + dev(d, 0);
            let after = dev(a, -1) + dev(b, -1) + dev(c, 1) + dev(d, 1);
            if after < before && flip_geometry_ok(m, a, b, c, d, fit) {
                self.guarded_flip(p, h);
            }
        }
    }

    /// Tangential relaxation toward the density-weighted centroid of the
    /// one-ring (Dunyach et al. 2013: the barycentres of the incident
    /// triangles weighted by area / h², so that vertices settle where the
    /// triangles have the local target size), then projection onto the
    /// reference; moves that would turn a triangle over, or that the guard
    /// refuses, are skipped, and so are moves too small to matter.
    fn relax_and_project(&mut self, p: u32) {
        let fit = self.fit(p);
        let sizing = self.sizing;
        let m = &self.patches[p as usize].mesh;
        let offset_chords = self.offset_chords;
        let patch_offset = self.patches[p as usize].offset;
        // (the offsets come from the mesh before this pass moves anything:
        // offsets computed from offset vertices would feed on themselves)
        let gaps = if offset_chords {
            face_gaps(m, fit.reference)
        } else {
            Vec::new()
        };
        // the target at each face's barycentre, once per face rather than
        // once per corner
        let targets: Vec<f64> = (0..m.face_slots() as u32)
            .map(|f| {
                if m.face_dead(f) {
                    return 0.0;
                }
                let [a, b, c] = m.face_vertices(f).map(|v| m.pos[v as usize]);
                sizing.at((a + b + c) / 3.0)
            })
            .collect();
        let moves: Vec<(u32, DVec3, u32)> = m
            .vertices()
            .filter(|&v| !m.locked[v as usize] && !m.is_boundary_vertex(v))
            .filter_map(|v| {
                let at = m.pos[v as usize];
                let mut centroid = DVec3::ZERO;
                let mut weights = 0.0;
                let mut normal = DVec3::ZERO;
                for h in m.outgoing(v) {
                    if m.is_boundary_halfedge(h) {
                        continue;
                    }
                    let (a, b) = (m.pos[m.to(h) as usize], m.pos[m.to(m.next(h)) as usize]);
                    let n = (a - at).cross(b - at);
                    let bary = (at + a + b) / 3.0;
                    let target = targets[m.face(h) as usize];
                    let w = n.length().max(f64::MIN_POSITIVE) / (target * target);
                    centroid += bary * w;
                    weights += w;
                    normal += n;
                }
                if weights <= 0.0 {
                    return None;
                }
                let n = normal.normalize_or_zero();
                let d = centroid / weights - at;
                let tangential = d - n * d.dot(n);
                // (a vertex at rest stays: no projection, no checks; in
                // the offset iterations each vertex takes its offset anew)
                let rest = RELAX_AT_REST * sizing.at(at);
                if tangential.length() < rest && !offset_chords {
                    return None;
                }
                let (onto, near) = fit
                    .reference
                    .project_from(at + tangential, m.hint[v as usize]);
                // the offset off the reference: the chord offset, 3/4 of the
                // centroid gap the triangles would have with their corners
                // on the reference (the gap they have now plus the offset
                // the vertex has now, which the projection undid), and the
                // patch's offset that keeps the labels' volumes
                let off = if offset_chords {
                    let now = (at + tangential - onto).dot(n);
                    0.75 * now + chord_offset(m, v, &gaps) + patch_offset
                } else {
                    0.0
                };
                Some((v, onto + n * off, near))
            })
            .collect();
        self.move_together(p, &moves, fit);
    }

    /// Makes the `moves` (vertex, position, reference hint) of patch `p`
    /// all at once, as B&K's tangential relaxation does, then checks every
    /// face they changed once: it must keep its orientation, a fair shape
    /// and the reference ([`face_move_ok`]), and cross nothing (the guard);
    /// closed components keep the sign of their volume. Where a face fails,
    /// the moves of its vertices (and of the face it crosses) are taken
    /// back and the faces around them checked again, until every face
    /// passes: the state with every move taken back is the one before, which
    /// passes, so this ends. Each changed face is tested once rather than
    /// once per moved corner (three times), as moving the vertices one at a
    /// time with a guard query per fan did.
    fn move_together(&mut self, p: u32, moves: &[(u32, DVec3, u32)], fit: Fit) {
        if moves.is_empty() {
            return;
        }
        let pu = p as usize;
        let m = &self.patches[pu].mesh;
        let mut from: Vec<Option<(DVec3, u32)>> = vec![None; m.vertex_slots()];
        // per face: out of the guard (changed, not yet accepted), and queued
        let mut out = vec![false; m.face_slots()];
        let mut queued = vec![false; m.face_slots()];
        let mut queue: Vec<u32> = Vec::new();
        // per vertex: its fan as the mesh is now not looked at (0), simple
        // (1) or not shown so (2)
        let mut simple = vec![0u8; m.vertex_slots()];
        for &(v, to, near) in moves {
            let m = &mut self.patches[pu].mesh;
            from[v as usize] = Some((m.pos[v as usize], m.hint[v as usize]));
            m.pos[v as usize] = to;
            m.hint[v as usize] = near;
            Self::recheck_faces_at(m, &mut self.guard, p, v, &mut out, &mut queued, &mut queue);
        }
        let mut back: Vec<u32> = Vec::new();
        let mut failed: Vec<u32> = Vec::new();
        loop {
            for f in std::mem::take(&mut queue) {
                queued[f as usize] = false;
                let m = &self.patches[pu].mesh;
                let moved = |g: u32| {
                    m.face_vertices(g)
                        .into_iter()
                        .filter(|&v| from[v as usize].is_some())
                };
                let own = back.len();
                back.extend(moved(f));
                // (a face as it was before needs no local check: only what
                // it may cross has changed)
                if back.len() > own && !face_move_ok(m, f, &from, fit) {
                    failed.push(f);
                    continue;
                }
                back.truncate(own);
                self.stats[0] += 1;
                self.stats[1] += 1;
                let fans = Self::simple_fans_of(m, p, f, &mut simple);
                let t = self.time_guard.then(std::time::Instant::now);
                let hit = self.guard.crossing(&Tri::of_face(m, p, f), fans);
                if let Some(t) = t {
                    self.stats[2] += t.elapsed().as_nanos() as u64;
                }
                let Some(other) = hit else {
                    self.guard.insert(m, p, f);
                    out[f as usize] = false;
                    continue;
                };
                self.stats[3] += 1;
                back.extend(moved(f));
                if let Some((q, g)) = other {
                    if q == p {
                        back.extend(moved(g));
                    }
                }
                if back.len() == own {
                    // two faces as they were cross: the mesh before this
                    // pass would have; nothing to take back (not expected)
                    debug_assert!(false, "faces as they were cross");
                    self.guard.insert(m, p, f);
                    out[f as usize] = false;
                } else {
                    failed.push(f);
                }
            }
            if back.is_empty() {
                let changes = self.component_volume_changes(p, moves, &from);
                back = self.volume_sign_changes(p, &changes, &from);
                if back.is_empty() {
                    // what the components' volumes lost
                    for (c, change) in changes {
                        self.volumes[c as usize] += change;
                    }
                    break;
                }
            }
            for v in back.drain(..) {
                let Some((at, hint)) = from[v as usize].take() else {
                    continue;
                };
                let m = &mut self.patches[pu].mesh;
                m.pos[v as usize] = at;
                m.hint[v as usize] = hint;
                // the fans holding v change
                simple[v as usize] = 0;
                for h in m.outgoing(v) {
                    simple[m.to(h) as usize] = 0;
                }
                Self::recheck_faces_at(m, &mut self.guard, p, v, &mut out, &mut queued, &mut queue);
            }
            // the faces that failed, checked again with what was taken back
            for f in failed.drain(..) {
                if !queued[f as usize] {
                    queued[f as usize] = true;
                    queue.push(f);
                }
            }
        }
        debug_assert!(!out.iter().any(|&o| o), "every face back in the guard");
        // the faces that did change: no longer as extracted
        let st = &mut self.patches[pu];
        for f in 0..st.mesh.face_slots() as u32 {
            if !st.mesh.face_dead(f)
                && st
                    .mesh
                    .face_vertices(f)
                    .iter()
                    .any(|&v| from[v as usize].is_some())
            {
                if st.kept.len() <= f as usize {
                    st.kept.resize(st.mesh.face_slots(), false);
                }
                st.kept[f as usize] = false;
            }
        }
    }

    /// Takes the faces around `v` out of the guard (those not out already)
    /// and queues them to be checked (those not queued already).
    /// The corners of face `f` of patch `p` whose fans are simple as the
    /// mesh is now (`simple`: per vertex, 0 not looked at yet, 1 simple,
    /// 2 not shown so; filled in here).
    fn simple_fans_of(m: &HalfedgeMesh, p: u32, f: u32, simple: &mut [u8]) -> Option<SimpleFans> {
        let mut apexes = [None; 3];
        for (apex, v) in apexes.iter_mut().zip(m.face_vertices(f)) {
            let vu = v as usize;
            if simple[vu] == 0 {
                simple[vu] = if fan_is_simple(m, v) { 1 } else { 2 };
            }
            if simple[vu] == 1 {
                *apex = Some(vertex_key(m, p, v));
            }
        }
        apexes
            .iter()
            .any(Option::is_some)
            .then_some(SimpleFans { patch: p, apexes })
    }

    fn recheck_faces_at(
        m: &HalfedgeMesh,
        guard: &mut Guard,
        p: u32,
        v: u32,
        out: &mut [bool],
        queued: &mut [bool],
        queue: &mut Vec<u32>,
    ) {
        for h in m.outgoing(v) {
            let f = m.face(h) as usize;
            if f == NONE as usize {
                continue;
            }
            if !out[f] {
                out[f] = true;
                guard.remove(p, f as u32);
            }
            if !queued[f] {
                queued[f] = true;
                queue.push(f as u32);
            }
        }
    }

    /// Per label surface component of patch `p` whose faces the moves
    /// (`moves`, of which those still in `from`, the old position of each
    /// moved vertex) changed: the signed volume it gains (the moved vertices
    /// are interior to the patch, so the old and the new faces of a
    /// component bound the same ring, and the difference is the volume
    /// between them, whatever the origin).
    fn component_volume_changes(
        &self,
        p: u32,
        moves: &[(u32, DVec3, u32)],
        from: &[Option<(DVec3, u32)>],
    ) -> Vec<(u32, f64)> {
        let st = &self.patches[p as usize];
        let m = &st.mesh;
        let mut changes: Vec<(u32, f64)> = Vec::new();
        let mut origin = None;
        for &(v, _, _) in moves {
            if from[v as usize].is_none() {
                continue;
            }
            for h in m.outgoing(v) {
                let f = m.face(h);
                if f == NONE {
                    continue;
                }
                let vs = m.face_vertices(f);
                // each face once: from its first moved corner
                if vs.iter().find(|&&w| from[w as usize].is_some()) != Some(&v) {
                    continue;
                }
                let sides = st.component.get(f as usize).copied().unwrap_or([NONE; 2]);
                if sides == [NONE; 2] {
                    continue;
                }
                let new = vs.map(|w| m.pos[w as usize]);
                let old = vs.map(|w| from[w as usize].map_or(m.pos[w as usize], |x| x.0));
                let o = *origin.get_or_insert(old[0]);
                let cone = |q: [DVec3; 3]| (q[0] - o).dot((q[1] - o).cross(q[2] - o)) / 6.0;
                add_to_sides(&mut changes, sides, cone(new) - cone(old));
            }
        }
        changes
    }

    /// The moved vertices (in `from`) of the label surface components whose
    /// volume `changes` would take through zero (which no crossing test
    /// sees: a region jumping through itself comes out inside out).
    fn volume_sign_changes(
        &self,
        p: u32,
        changes: &[(u32, f64)],
        from: &[Option<(DVec3, u32)>],
    ) -> Vec<u32> {
        let flipped: Vec<u32> = changes
            .iter()
            .filter(|&&(c, change)| {
                let left = self.volumes[c as usize];
                !(left * (left + change) > 0.0)
            })
            .map(|&(c, _)| c)
            .collect();
        if flipped.is_empty() {
            return Vec::new();
        }
        let st = &self.patches[p as usize];
        let m = &st.mesh;
        let mut back = Vec::new();
        for f in 0..m.face_slots() as u32 {
            let sides = st.component.get(f as usize).copied().unwrap_or([NONE; 2]);
            if !m.face_dead(f) && sides.iter().any(|c| *c != NONE && flipped.contains(c)) {
                back.extend(
                    m.face_vertices(f)
                        .into_iter()
                        .filter(|&v| from[v as usize].is_some()),
                );
            }
        }
        back
    }

    // ---- result --------------------------------------------------------------

    /// The region after remeshing: every live face of every patch, over the
    /// region's vertex ids (vertices made here get ids from `pos.len()` at
    /// the start on; interior ones made by splits get ids after those).
    pub(super) fn finish(self) -> RegionResult {
        let mut pos = self.pos;
        let mut kind = self.kind;
        let mut alive = self.alive;
        let mut triangles = Vec::new();
        for (p, st) in self.patches.iter().enumerate() {
            let m = &st.mesh;
            let mut local = vec![NONE; m.vertex_slots()];
            for v in m.vertices() {
                let tag = m.tag[v as usize];
                local[v as usize] = if tag != NONE {
                    if !m.locked[v as usize] {
                        pos[tag as usize] = m.pos[v as usize];
                    }
                    tag
                } else {
                    pos.push(m.pos[v as usize]);
                    kind.push(VertexKind::Interior);
                    alive.push(true);
                    (pos.len() - 1) as u32
                };
            }
            for f in 0..m.face_slots() as u32 {
                if m.face_dead(f) {
                    continue;
                }
                triangles.push(ResultTriangle {
                    vertices: m.face_vertices(f).map(|v| local[v as usize]),
                    patch: p as u32,
                    hint: m.face_hint[f as usize].get(),
                    kept: st.kept.get(f as usize).copied().unwrap_or(false),
                    component: st.component.get(f as usize).copied().unwrap_or([NONE; 2]),
                });
            }
        }
        // interior vertices that a collapse removed
        for st in &self.patches {
            let m = &st.mesh;
            for v in 0..m.vertex_slots() as u32 {
                let tag = m.tag[v as usize];
                if m.vertex_dead(v) && tag != NONE && !m.locked[v as usize] {
                    alive[tag as usize] = false;
                }
            }
        }
        RegionResult {
            stats: self.stats,
            pos,
            kind,
            alive,
            triangles,
            volumes: self.volumes,
            curves: self.curves.into_iter().map(|c| c.vertices).collect(),
        }
    }
}

/// A triangle of a [`RegionResult`].
pub(super) struct ResultTriangle {
    pub(super) vertices: [u32; 3],
    /// The region's patch index.
    pub(super) patch: u32,
    pub(super) hint: u32,
    pub(super) kept: bool,
    /// The label surface components on its two sides (indices into the
    /// region's volumes) or [`NONE`].
    pub(super) component: Sides,
}

/// A remeshed region (see [`Remesher::finish`]).
pub(super) struct RegionResult {
    pub(super) stats: [u64; 10],
    /// Positions of every region vertex (then of the vertices made).
    pub(super) pos: Vec<DVec3>,
    pub(super) kind: Vec<VertexKind>,
    pub(super) alive: Vec<bool>,
    pub(super) triangles: Vec<ResultTriangle>,
    /// Per component of [`Region::volumes`]: the share of its volume left.
    pub(super) volumes: Vec<f64>,
    /// The curve runs, in the order given, with their vertices now.
    pub(super) curves: Vec<Vec<u32>>,
}

/// Adds volume `v` to the component on the first side of a triangle in
/// `changes` and takes it from the one on its second side (the same faces,
/// turned over).
fn add_to_sides(changes: &mut Vec<(u32, f64)>, sides: Sides, v: f64) {
    for (c, v) in [(sides[0], v), (sides[1], -v)] {
        if c == NONE {
            continue;
        }
        match changes.iter_mut().find(|x| x.0 == c) {
            Some(x) => x.1 += v,
            None => changes.push((c, v)),
        }
    }
}

/// The patch mesh of `rp`. `local_ids` (one slot per region vertex) is
/// [`NONE`] everywhere and is left so.
fn build_patch<'r>(
    pos: &[DVec3],
    kind: &[VertexKind],
    rp: RegionPatch<'r>,
    local_ids: &mut [u32],
) -> PatchState<'r> {
    // local ids in order of first use (about half as many as triangles,
    // a few more at the borders)
    let mut lpos = Vec::with_capacity(rp.triangles.len() / 2 + 64);
    let mut tag = Vec::with_capacity(rp.triangles.len() / 2 + 64);
    let local_tris: Vec<[u32; 3]> = rp
        .triangles
        .iter()
        .map(|t| {
            t.map(|v| {
                let l = &mut local_ids[v as usize];
                if *l == NONE {
                    *l = lpos.len() as u32;
                    lpos.push(pos[v as usize]);
                    tag.push(v);
                }
                *l
            })
        })
        .collect();
    for &v in &tag {
        local_ids[v as usize] = NONE;
    }
    let mut m = HalfedgeMesh::from_triangles(lpos, tag, &local_tris)
        .expect("patches of a valid interface mesh are manifolds");
    for v in 0..m.vertex_slots() {
        // small islands are remeshed like the rest, from their unsmoothed shape
        m.locked[v] = !matches!(
            kind[m.tag[v] as usize],
            VertexKind::Interior | VertexKind::Island
        );
    }
    // every vertex starts with the hint of one of its faces
    for (f, &hint) in rp.hints.iter().enumerate() {
        m.face_hint[f].set(hint);
        let h = m.face_halfedge(f as u32);
        for g in [h, m.next(h), m.prev(h)] {
            let from = m.from(g) as usize;
            if m.hint[from] == NONE {
                m.hint[from] = hint;
            }
        }
    }
    PatchState {
        mesh: m,
        reference: rp.reference,
        kept: rp.kept,
        component: rp.components,
        offset: rp.offset,
    }
}

/// How far the reference stands off each live face of `m` at its centroid,
/// along the face's normal (indexed by face; 0 for a dead face).
fn face_gaps(m: &HalfedgeMesh, reference: &SurfaceRef) -> Vec<f64> {
    (0..m.face_slots() as u32)
        .map(|f| {
            if m.face_dead(f) {
                return 0.0;
            }
            let [a, b, c] = m.face_vertices(f).map(|v| m.pos[v as usize]);
            let n = (b - a).cross(c - a).normalize_or_zero();
            let centroid = (a + b + c) / 3.0;
            let hint = match m.face_hint[f as usize].get() {
                NONE => NO_TRIANGLE,
                h => h,
            };
            let (onto, _) = reference.project_from(centroid, hint);
            (onto - centroid).dot(n)
        })
        .collect()
}

/// How much farther off the reference, along its normal, interior vertex
/// `v` should sit so that the triangles around it lie on the reference on average
/// rather than inside its bends. Vertices on a curved surface span chords,
/// which cut convex parts and bridge concave ones: an interpolating mesh
/// shrinks every bump and fills every dent by about h²/(8 r) (a one-voxel
/// bump of a noisy segmentation loses a third of its volume). Over a
/// triangle whose corners lie on a smooth surface the surface stands off it
/// by 3/4 of its gap at the centroid on average (exact for a quadric: the
/// mean is (1/3) Σ s_e and the centroid's (4/9) Σ s_e over the sagittas s_e
/// of its edges); when every vertex moves by the area-weighted mean of that
/// over its triangles, the mesh moves onto the reference on average and
/// encloses the volume it does. `gaps` are the centroid gaps of
/// [`face_gaps`].
fn chord_offset(m: &HalfedgeMesh, v: u32, gaps: &[f64]) -> f64 {
    let pv = m.pos[v as usize];
    let (mut sum, mut area) = (0.0, 0.0);
    for h in m.outgoing(v) {
        if m.is_boundary_halfedge(h) {
            continue;
        }
        let (pa, pb) = (m.pos[m.to(h) as usize], m.pos[m.to(m.next(h)) as usize]);
        let w = (pa - pv).cross(pb - pv).length();
        sum += w * gaps[m.face(h) as usize];
        area += w;
    }
    if area > 0.0 { 0.75 * sum / area } else { 0.0 }
}

/// Whether moving vertex `v` to `p` keeps every incident triangle facing the
/// same way, of acceptable quality, and following the reference.
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

/// Whether face `f` of `m`, some of whose vertices moved (`from`: the old
/// position of each vertex that moved), keeps its orientation, an
/// acceptable shape (or one no worse than before) and follows the reference.
fn face_move_ok(m: &HalfedgeMesh, f: u32, from: &[Option<(DVec3, u32)>], fit: Fit) -> bool {
    let vs = m.face_vertices(f);
    let [a, b, c] = vs.map(|v| m.pos[v as usize]);
    let [a0, b0, c0] = vs.map(|v| from[v as usize].map_or(m.pos[v as usize], |x| x.0));
    let (old_n, new_n) = ((b0 - a0).cross(c0 - a0), (b - a).cross(c - a));
    if old_n.dot(new_n) <= 0.0 || is_degenerate(a, b, c) {
        return false;
    }
    let q_new = triangle_quality(a, b, c);
    if q_new < MIN_QUALITY && q_new < triangle_quality(a0, b0, c0) {
        return false;
    }
    let mut hint = vs
        .iter()
        .find(|&&v| from[v as usize].is_some())
        .map_or(NO_TRIANGLE, |&v| m.hint[v as usize]);
    fit.check_face(m, f, a, b, c, &mut hint)
}

/// Whether collapsing `h` (from(h) moves to `p`, then merges into to(h)) keeps
/// the triangles facing the same way, of acceptable quality, following the
/// reference, and each new edge no longer than 4/3 of its own target in
/// Whether the faces around vertex `v` form a simple fan as the mesh is now
/// ([`is_simple_ring`]): they then meet one another only along their
/// shared edges.
fn fan_is_simple(m: &HalfedgeMesh, v: u32) -> bool {
    let mut ring = [DVec3::ZERO; FAN_MAX + 1];
    let mut ids = [NONE; 2];
    let mut len = 0;
    let mut closed = true;
    for h in m.outgoing(v) {
        if m.is_boundary_halfedge(h) {
            closed = false;
            continue;
        }
        let (a, b) = (m.to(h), m.to(m.next(h)));
        if len == 0 {
            ring[0] = m.pos[a as usize];
            ids[0] = a;
            len = 1;
        } else if a != ids[1] || len > FAN_MAX {
            // (the faces come round the vertex in order, each one's far
            // corner the next one's near corner)
            return false;
        }
        ring[len] = m.pos[b as usize];
        ids[1] = b;
        len += 1;
    }
    if len == 0 {
        return true;
    }
    if closed {
        // the last far corner is the first near corner
        ids[1] == ids[0] && is_simple_ring(m.pos[v as usize], &ring[..len - 1], true)
    } else {
        is_simple_ring(m.pos[v as usize], &ring[..len], false)
    }
}

/// `max_edge` (the split pass's bound); `None`: no length bound.
pub(super) fn collapse_geometry_ok(
    m: &HalfedgeMesh,
    h: u32,
    p: DVec3,
    max_edge: Option<&Sizing>,
    fit: Fit,
    junction_edge_free: &dyn Fn(u32, u32) -> bool,
) -> bool {
    let (v0, v1) = (m.from(h), m.to(h));
    // a pinched vertex's other copies are out of sight: the new edges at it
    // could duplicate theirs
    if m.pinched[v1 as usize] || m.pinched[v0 as usize] {
        return false;
    }
    // the link condition by identity: a copy of a pinched vertex next to v0
    // and another next to v1 would become one edge twice
    if m.outgoing(v0).any(|g| m.pinched[m.to(g) as usize]) {
        for g in m.outgoing(v0) {
            let w0 = m.to(g);
            if !m.pinched[w0 as usize] {
                continue;
            }
            if m.outgoing(v1).any(|k| {
                let w1 = m.to(k);
                w1 != w0 && m.tag[w1 as usize] == m.tag[w0 as usize]
            }) {
                return false;
            }
        }
    }
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
        if w != v1
            && max_edge.is_some_and(|sizing| {
                let pw = m.pos[w as usize];
                (pw - p).length() > SPLIT_ABOVE * sizing.edge(pw, p)
            })
        {
            return false;
        }
        // an edge between two junction vertices inside a patch must not be
        // an edge of another patch too (the label surfaces would meet
        // along it, four triangles at one edge)
        if w != v1
            && m.locked[v1 as usize]
            && m.locked[w as usize]
            && !m.is_boundary_edge(g)
            && !m.outgoing(v1).any(|k| m.to(k) == w)
            && !junction_edge_free(v1, w)
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
        // (a triangle on three junction vertices may be made: where another
        // patch has the same one, the guard refuses it, as triangles that
        // share all three corners cross)
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

/// The arc length halfway from `v` (at arc length `sv`) to the middle of
/// its curve neighbours at `sa` and `sb`, on the arc between them that
/// holds `v`; `None` where `v` is not between them (an open curve whose
/// vertices the projections put out of order).
fn relaxed_arc(reference: &CurveRef, sa: f64, sv: f64, sb: f64) -> Option<f64> {
    let halfway = |from: f64, to: f64| from + 0.5 * (0.5 * to - from);
    if reference.is_closed() {
        let length = reference.length();
        if !(length > 0.0) {
            return None;
        }
        let ahead = |x: f64, y: f64| (y - x).rem_euclid(length);
        // along the curve from a through v to b, or the other way round
        let (start, to_v, to_end) = if ahead(sa, sv) <= ahead(sa, sb) {
            (sa, ahead(sa, sv), ahead(sa, sb))
        } else {
            (sb, ahead(sb, sv), ahead(sb, sa))
        };
        return Some(start + halfway(to_v, to_end));
    }
    if (sa <= sv && sv <= sb) || (sb <= sv && sv <= sa) {
        Some(sa + halfway(sv - sa, sb - sa))
    } else {
        None
    }
}

fn target_valence(m: &HalfedgeMesh, v: u32) -> i32 {
    if m.is_boundary_vertex(v) { 4 } else { 6 }
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
