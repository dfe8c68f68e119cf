//! A compact halfedge mesh for one patch (a 2-manifold with boundary), with the
//! local operations of isotropic remeshing: edge split, halfedge collapse (with
//! the link condition), edge flip, and garbage collection.
//!
//! Conventions follow pmp-library: halfedges come in pairs (`h ^ 1` is the
//! opposite of `h`); a boundary halfedge has no face; a boundary vertex's
//! outgoing halfedge is a boundary halfedge; deleted elements are flagged and
//! removed by [`HalfedgeMesh::collect_garbage`]. Vertices on the patch boundary
//! can be *locked* (junction curves): remeshing never moves or removes them.

use std::cell::Cell;

use glam::DVec3;

/// "No element".
pub const NONE: u32 = u32::MAX;

/// A halfedge mesh of triangles.
#[derive(Clone, Debug, Default)]
pub struct HalfedgeMesh {
    pub pos: Vec<DVec3>,
    /// Caller's id of each vertex (e.g. the global vertex id), carried through
    /// the operations (new vertices get `NONE` unless set).
    pub tag: Vec<u32>,
    pub locked: Vec<bool>,
    /// Vertices whose triangles formed several fans when the mesh was built:
    /// every copy (one per fan) is marked. An edge made at one copy could
    /// duplicate an edge of another, which the mesh cannot see.
    pub pinched: Vec<bool>,
    /// Caller's hint per vertex (e.g. a nearby reference triangle), carried
    /// like `tag`: a split's new vertex gets the hint of the edge's origin.
    pub hint: Vec<u32>,
    /// Caller's hint per face (e.g. a reference triangle near its centroid),
    /// advisory and so updatable through `&self`: a split's new face gets the
    /// hint of the face it came from.
    pub face_hint: Vec<Cell<u32>>,
    v_out: Vec<u32>,
    v_dead: Vec<bool>,
    h_to: Vec<u32>,
    h_next: Vec<u32>,
    h_prev: Vec<u32>,
    h_face: Vec<u32>,
    e_dead: Vec<bool>,
    f_h: Vec<u32>,
    f_dead: Vec<bool>,
}

/// Why a mesh could not be built.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BuildError {
    /// An edge is used by more than two triangles, or twice in the same direction.
    NonManifoldEdge(u32, u32),
    /// A triangle uses a vertex twice.
    DegenerateTriangle(usize),
}

impl HalfedgeMesh {
    /// Builds from triangles over `pos` (consistently oriented; each edge in at
    /// most two triangles, in opposite directions). Vertices whose triangles
    /// form several fans are duplicated (one copy per fan, same tag), so that
    /// the result is a manifold.
    pub fn from_triangles(
        pos: Vec<DVec3>,
        tag: Vec<u32>,
        tris: &[[u32; 3]],
    ) -> Result<Self, BuildError> {
        let nv = pos.len();
        let mut m = HalfedgeMesh {
            pos,
            tag,
            locked: vec![false; nv],
            pinched: vec![false; nv],
            hint: vec![NONE; nv],
            v_out: vec![NONE; nv],
            v_dead: vec![false; nv],
            ..Default::default()
        };
        if let Some(t) = tris
            .iter()
            .position(|t| t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
        {
            return Err(BuildError::DegenerateTriangle(t));
        }
        // Corner c = 3 t + k is the directed edge tri[k] -> tri[k + 1]. The
        // corners leaving each vertex, by counting sort, with the vertex each
        // goes to, find each corner's opposite without a hash map (and
        // without dividing corner ids by 3 in the scans).
        let mut start = vec![0u32; nv + 1];
        for t in tris {
            for &v in t {
                start[v as usize + 1] += 1;
            }
        }
        for v in 0..nv {
            start[v + 1] += start[v];
        }
        let mut fill = start.clone();
        // (corner, the vertex it goes to)
        let mut leaving = vec![(0u32, 0u32); 3 * tris.len()];
        for (t, tri) in tris.iter().enumerate() {
            for k in 0..3 {
                let a = tri[k] as usize;
                leaving[fill[a] as usize] = ((3 * t + k) as u32, tri[(k + 1) % 3]);
                fill[a] += 1;
            }
        }
        let leaving_from =
            |v: u32| &leaving[start[v as usize] as usize..start[v as usize + 1] as usize];
        // halfedges in order of first appearance (as a hash map would give)
        let mut corner_h = vec![NONE; 3 * tris.len()];
        m.f_h.reserve(tris.len());
        // about 3/2 edges per triangle (two halfedges each)
        let halfedges = 3 * tris.len() + 16;
        m.h_to.reserve(halfedges);
        m.h_next.reserve(halfedges);
        m.h_prev.reserve(halfedges);
        m.h_face.reserve(halfedges);
        m.e_dead.reserve(halfedges / 2);
        m.f_dead.reserve(tris.len());
        m.face_hint = vec![Cell::new(NONE); tris.len()];
        for (t, tri) in tris.iter().enumerate() {
            let f = m.f_h.len() as u32;
            m.f_h.push(NONE);
            m.f_dead.push(false);
            let mut hs = [0u32; 3];
            for k in 0..3 {
                let c = 3 * t + k;
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                // a second corner a -> b: the edge is used twice the same way
                if leaving_from(a)
                    .iter()
                    .any(|&(d, to)| d as usize != c && to == b)
                {
                    return Err(BuildError::NonManifoldEdge(a, b));
                }
                let h = if corner_h[c] != NONE {
                    corner_h[c]
                } else {
                    let h = m.new_edge(a, b);
                    if let Some(&(d, _)) = leaving_from(b).iter().find(|&&(_, to)| to == a) {
                        corner_h[d as usize] = h ^ 1;
                    }
                    h
                };
                m.h_face[h as usize] = f;
                hs[k] = h;
            }
            for k in 0..3 {
                m.link(hs[k], hs[(k + 1) % 3]);
            }
            m.f_h[f as usize] = hs[0];
        }
        m.link_boundary_and_split_fans();
        Ok(m)
    }

    fn new_edge(&mut self, from: u32, to: u32) -> u32 {
        let h = self.h_to.len() as u32;
        self.h_to.extend([to, from]);
        self.h_next.extend([NONE, NONE]);
        self.h_prev.extend([NONE, NONE]);
        self.h_face.extend([NONE, NONE]);
        self.e_dead.push(false);
        h
    }

    fn new_vertex(&mut self, p: DVec3, tag: u32, hint: u32) -> u32 {
        self.pos.push(p);
        self.tag.push(tag);
        self.hint.push(hint);
        self.locked.push(false);
        self.pinched.push(false);
        self.v_out.push(NONE);
        self.v_dead.push(false);
        (self.pos.len() - 1) as u32
    }

    fn new_face(&mut self, h: u32, hint: u32) -> u32 {
        self.f_h.push(h);
        self.f_dead.push(false);
        self.face_hint.push(Cell::new(hint));
        (self.f_h.len() - 1) as u32
    }

    #[inline]
    fn link(&mut self, a: u32, b: u32) {
        self.h_next[a as usize] = b;
        self.h_prev[b as usize] = a;
    }

    /// Links boundary halfedges into loops and duplicates vertices with several fans.
    fn link_boundary_and_split_fans(&mut self) {
        let nh = self.h_to.len() as u32;
        // outgoing boundary halfedges per vertex, in id order (a counting
        // sort into one array: a vector per vertex was an allocation per
        // boundary vertex, and blocks have many)
        let nv = self.pos.len();
        let mut b_start = vec![0u32; nv + 1];
        for h in 0..nh {
            if self.h_face[h as usize] == NONE {
                b_start[self.from(h) as usize + 1] += 1;
            }
        }
        for v in 0..nv {
            b_start[v + 1] += b_start[v];
        }
        let mut b_fill = b_start.clone();
        let mut out_b = vec![0u32; b_start[nv] as usize];
        for h in 0..nh {
            if self.h_face[h as usize] == NONE {
                let v = self.from(h) as usize;
                out_b[b_fill[v] as usize] = h;
                b_fill[v] += 1;
            }
        }
        for h in 0..nh {
            if self.h_face[h as usize] != NONE {
                continue;
            }
            // next boundary halfedge: rotate around to(h) from opposite(h) inside the fan
            let mut g = h ^ 1; // interior, from to(h) to from(h)
            loop {
                let cand = self.h_prev[g as usize] ^ 1; // next outgoing around to(h), clockwise
                if self.h_face[cand as usize] == NONE {
                    self.link(h, cand);
                    break;
                }
                g = cand;
            }
        }
        // outgoing halfedges; one per fan, duplicate vertices with several fans
        for v in 0..nv {
            let bs = &out_b[b_start[v] as usize..b_start[v + 1] as usize];
            for (i, &b) in bs.iter().enumerate() {
                let target = if i == 0 {
                    v as u32
                } else {
                    self.new_vertex(self.pos[v], self.tag[v], self.hint[v])
                };
                if bs.len() > 1 {
                    self.pinched[v] = true;
                    self.pinched[target as usize] = true;
                }
                // every outgoing halfedge of this fan now starts at `target`
                let mut h = b;
                loop {
                    self.h_to[(h ^ 1) as usize] = target;
                    h = self.h_prev[h as usize] ^ 1;
                    if h == b {
                        break;
                    }
                }
                self.v_out[target as usize] = b;
            }
        }
        // interior vertices: any outgoing halfedge
        for h in 0..nh {
            let v = self.from(h) as usize;
            if self.v_out[v] == NONE {
                self.v_out[v] = h;
            }
        }
    }

    /// Number of vertex slots (including deleted).
    pub fn vertex_slots(&self) -> usize {
        self.pos.len()
    }

    /// Number of halfedge slots.
    pub fn halfedge_slots(&self) -> usize {
        self.h_to.len()
    }

    /// Number of face slots.
    pub fn face_slots(&self) -> usize {
        self.f_h.len()
    }

    #[inline]
    pub fn to(&self, h: u32) -> u32 {
        self.h_to[h as usize]
    }
    #[inline]
    pub fn from(&self, h: u32) -> u32 {
        self.h_to[(h ^ 1) as usize]
    }
    #[inline]
    pub fn next(&self, h: u32) -> u32 {
        self.h_next[h as usize]
    }
    #[inline]
    pub fn prev(&self, h: u32) -> u32 {
        self.h_prev[h as usize]
    }
    #[inline]
    pub fn face(&self, h: u32) -> u32 {
        self.h_face[h as usize]
    }
    #[inline]
    pub fn out(&self, v: u32) -> u32 {
        self.v_out[v as usize]
    }
    #[inline]
    pub fn is_boundary_halfedge(&self, h: u32) -> bool {
        self.h_face[h as usize] == NONE
    }
    #[inline]
    pub fn is_boundary_edge(&self, h: u32) -> bool {
        self.is_boundary_halfedge(h) || self.is_boundary_halfedge(h ^ 1)
    }
    #[inline]
    pub fn is_boundary_vertex(&self, v: u32) -> bool {
        let h = self.v_out[v as usize];
        h == NONE || self.is_boundary_halfedge(h)
    }
    #[inline]
    pub fn vertex_dead(&self, v: u32) -> bool {
        self.v_dead[v as usize]
    }
    #[inline]
    pub fn edge_dead(&self, h: u32) -> bool {
        self.e_dead[(h / 2) as usize]
    }
    #[inline]
    pub fn face_dead(&self, f: u32) -> bool {
        self.f_dead[f as usize]
    }

    /// Outgoing halfedges of `v`, counter-clockwise (starting at the boundary one).
    pub fn outgoing(&self, v: u32) -> impl Iterator<Item = u32> + '_ {
        let start = self.v_out[v as usize];
        let mut h = start;
        let mut done = start == NONE;
        std::iter::from_fn(move || {
            if done {
                return None;
            }
            let cur = h;
            h = self.h_prev[h as usize] ^ 1;
            if h == start {
                done = true;
            }
            Some(cur)
        })
    }

    /// Number of edges at `v`.
    pub fn valence(&self, v: u32) -> usize {
        self.outgoing(v).count()
    }

    /// The three vertices of face `f`.
    /// A halfedge of face `f`.
    #[inline]
    pub fn face_halfedge(&self, f: u32) -> u32 {
        self.f_h[f as usize]
    }

    /// The three vertices of face `f`, in order.
    pub fn face_vertices(&self, f: u32) -> [u32; 3] {
        let h = self.f_h[f as usize];
        [self.to(self.prev(h)), self.to(h), self.to(self.next(h))]
    }

    /// Unnormalised normal (twice the area) of face `f`.
    pub fn face_normal(&self, f: u32) -> DVec3 {
        let [a, b, c] = self.face_vertices(f).map(|v| self.pos[v as usize]);
        (b - a).cross(c - a)
    }

    /// Length of the edge of `h`.
    pub fn edge_length(&self, h: u32) -> f64 {
        (self.pos[self.to(h) as usize] - self.pos[self.from(h) as usize]).length()
    }

    /// Makes the outgoing halfedge of a boundary vertex a boundary halfedge.
    fn adjust_outgoing(&mut self, v: u32) {
        let start = self.v_out[v as usize];
        if start == NONE {
            return;
        }
        let mut h = start;
        loop {
            if self.is_boundary_halfedge(h) {
                self.v_out[v as usize] = h;
                return;
            }
            h = self.h_prev[h as usize] ^ 1;
            if h == start {
                return;
            }
        }
    }

    /// Splits the edge of `h` at a new vertex at `p`; returns the new vertex.
    /// Faces on both sides are split in two.
    pub fn split(&mut self, h: u32, p: DVec3) -> u32 {
        // before: h = a->b in face (a, b, c) [or boundary]; o = b->a in face (b, a, d) [or boundary]
        let o = h ^ 1;
        let (a, b) = (self.from(h), self.to(h));
        let m = self.new_vertex(p, NONE, self.hint[a as usize]);
        // h becomes a->m, o becomes m->a; new pair t: m->b, t^1: b->m
        let t = self.new_edge(m, b);
        self.h_to[h as usize] = m;
        self.h_to[o as usize] = a; // unchanged target, from-vertex now m via t pairing
        let (hn, hp) = (self.next(h), self.prev(h));
        let (on, op) = (self.next(o), self.prev(o));
        let (fh, fo) = (self.face(h), self.face(o));
        if fh != NONE {
            // face (a, b, c): h: a->m, new s: m->c, hp: c->a | t: m->b, hn: b->c, s^1: c->m
            let c = self.to(hn);
            let s = self.new_edge(m, c);
            let f2 = self.new_face(t, self.face_hint[fh as usize].get());
            self.link(h, s);
            self.link(s, hp);
            self.link(hp, h);
            self.h_face[s as usize] = fh;
            self.f_h[fh as usize] = h;
            self.link(t, hn);
            self.link(hn, s ^ 1);
            self.link(s ^ 1, t);
            self.h_face[t as usize] = f2;
            self.h_face[hn as usize] = f2;
            self.h_face[(s ^ 1) as usize] = f2;
        } else {
            // boundary: ... hp -> h(a->m) -> t(m->b) -> hn ...
            self.link(hp, h);
            self.link(h, t);
            self.link(t, hn);
            self.h_face[t as usize] = NONE;
        }
        if fo != NONE {
            // face (b, a, d): o was b->a; now t^1: b->m, new r: m->d, op: d->b | o: m->a, on: a->d, r^1: d->m
            let d = self.to(on);
            let r = self.new_edge(m, d);
            let f2 = self.new_face(t ^ 1, self.face_hint[fo as usize].get());
            self.link(t ^ 1, r);
            self.link(r, op);
            self.link(op, t ^ 1);
            self.h_face[(t ^ 1) as usize] = f2;
            self.h_face[r as usize] = f2;
            self.h_face[op as usize] = f2;
            self.link(o, on);
            self.link(on, r ^ 1);
            self.link(r ^ 1, o);
            self.h_face[o as usize] = fo;
            self.h_face[(r ^ 1) as usize] = fo;
            self.f_h[fo as usize] = o;
        } else {
            // boundary: ... op -> t^1(b->m) -> o(m->a) -> on ...
            self.link(op, t ^ 1);
            self.link(t ^ 1, o);
            self.link(o, on);
            self.h_face[(t ^ 1) as usize] = NONE;
        }
        // outgoing halfedges
        self.v_out[m as usize] = if fh == NONE {
            t
        } else if fo == NONE {
            o
        } else {
            t
        };
        if self.v_out[b as usize] == o {
            self.v_out[b as usize] = t ^ 1;
        }
        self.adjust_outgoing(m);
        self.adjust_outgoing(a);
        self.adjust_outgoing(b);
        m
    }

    /// Whether collapsing `h` (from(h) merges into to(h)) keeps the mesh a
    /// manifold (pmp's link condition).
    pub fn is_collapse_ok(&self, h: u32) -> bool {
        let o = h ^ 1;
        let (v0, v1) = (self.from(h), self.to(h));
        let mut vl = NONE;
        let mut vr = NONE;
        if !self.is_boundary_halfedge(h) {
            vl = self.to(self.next(h));
            let h1 = self.next(h);
            let h2 = self.next(h1);
            if self.is_boundary_halfedge(h1 ^ 1) && self.is_boundary_halfedge(h2 ^ 1) {
                return false;
            }
        }
        if !self.is_boundary_halfedge(o) {
            vr = self.to(self.next(o));
            let h1 = self.next(o);
            let h2 = self.next(h1);
            if self.is_boundary_halfedge(h1 ^ 1) && self.is_boundary_halfedge(h2 ^ 1) {
                return false;
            }
        }
        if vl == vr {
            return false;
        }
        if self.is_boundary_vertex(v0) && self.is_boundary_vertex(v1) && !self.is_boundary_edge(h) {
            return false;
        }
        // the one-rings of v0 and v1 may share only vl and vr
        // (on the stack: this runs for every collapse candidate)
        let mut ring0 = [NONE; 32];
        let mut n0 = 0;
        for g in self.outgoing(v0) {
            if n0 == ring0.len() {
                return self.rings_share_only(v0, v1, vl, vr);
            }
            ring0[n0] = self.to(g);
            n0 += 1;
        }
        let ring0 = &ring0[..n0];
        self.outgoing(v1).all(|g| {
            let w = self.to(g);
            w == vl || w == vr || !ring0.contains(&w)
        })
    }

    /// The link condition's ring test for vertices of very high valence.
    fn rings_share_only(&self, v0: u32, v1: u32, vl: u32, vr: u32) -> bool {
        let ring0: Vec<u32> = self.outgoing(v0).map(|g| self.to(g)).collect();
        self.outgoing(v1).all(|g| {
            let w = self.to(g);
            w == vl || w == vr || !ring0.contains(&w)
        })
    }

    /// Collapses `h`: its from-vertex is removed and its triangles merged into
    /// to(h). Call [`Self::is_collapse_ok`] first.
    pub fn collapse(&mut self, h: u32) {
        let h0 = h;
        let h1 = self.prev(h0);
        let o0 = h0 ^ 1;
        let o1 = self.next(o0);
        self.remove_edge_helper(h0);
        if self.next(self.next(h1)) == h1 {
            self.remove_loop_helper(h1);
        }
        if self.next(self.next(o1)) == o1 {
            self.remove_loop_helper(o1);
        }
    }

    fn remove_edge_helper(&mut self, h: u32) {
        let (hn, hp) = (self.next(h), self.prev(h));
        let o = h ^ 1;
        let (on, op) = (self.next(o), self.prev(o));
        let (fh, fo) = (self.face(h), self.face(o));
        let vh = self.to(h);
        let vo = self.to(o);
        let outgoing: Vec<u32> = self.outgoing(vo).collect();
        for hc in outgoing {
            self.h_to[(hc ^ 1) as usize] = vh;
        }
        self.link(hp, hn);
        self.link(op, on);
        if fh != NONE {
            self.f_h[fh as usize] = hn;
        }
        if fo != NONE {
            self.f_h[fo as usize] = on;
        }
        if self.v_out[vh as usize] == o {
            self.v_out[vh as usize] = hn;
        }
        self.adjust_outgoing(vh);
        self.v_out[vo as usize] = NONE;
        self.v_dead[vo as usize] = true;
        self.e_dead[(h / 2) as usize] = true;
    }

    fn remove_loop_helper(&mut self, h: u32) {
        let h0 = h;
        let h1 = self.next(h0);
        let o0 = h0 ^ 1;
        let o1 = h1 ^ 1;
        let v0 = self.to(h0);
        let v1 = self.to(h1);
        let fh = self.face(h0);
        let fo = self.face(o0);
        let (o0n, o0p) = (self.next(o0), self.prev(o0));
        self.link(h1, o0n);
        self.link(o0p, h1);
        self.h_face[h1 as usize] = fo;
        self.v_out[v0 as usize] = h1;
        self.adjust_outgoing(v0);
        self.v_out[v1 as usize] = o1;
        self.adjust_outgoing(v1);
        if fo != NONE && self.f_h[fo as usize] == o0 {
            self.f_h[fo as usize] = h1;
        }
        if fh != NONE {
            self.f_dead[fh as usize] = true;
        }
        self.e_dead[(h0 / 2) as usize] = true;
    }

    /// Whether the edge of `h` can be flipped (interior, and the new edge does not exist yet).
    pub fn is_flip_ok(&self, h: u32) -> bool {
        if self.is_boundary_edge(h) {
            return false;
        }
        let c = self.to(self.next(h));
        let d = self.to(self.next(h ^ 1));
        if c == d {
            return false;
        }
        !self.outgoing(c).any(|g| self.to(g) == d)
    }

    /// Flips the edge of `h` (a->b in (a, b, c), b->a in (b, a, d)) into c-d.
    pub fn flip(&mut self, h: u32) {
        let o = h ^ 1;
        let (a, b) = (self.from(h), self.to(h));
        let (hn, hp) = (self.next(h), self.prev(h)); // b->c, c->a
        let (on, op) = (self.next(o), self.prev(o)); // a->d, d->b
        let (fh, fo) = (self.face(h), self.face(o));
        let c = self.to(hn);
        let d = self.to(on);
        // h: d->c in face (d, c, a) = h, hp(c->a), on(a->d); o: c->d in face (c, d, b) = o, op(d->b), hn(b->c)
        self.h_to[h as usize] = c;
        self.h_to[o as usize] = d;
        self.link(h, hp);
        self.link(hp, on);
        self.link(on, h);
        self.link(o, op);
        self.link(op, hn);
        self.link(hn, o);
        self.h_face[on as usize] = fh;
        self.h_face[hn as usize] = fo;
        self.f_h[fh as usize] = h;
        self.f_h[fo as usize] = o;
        if self.v_out[a as usize] == h {
            self.v_out[a as usize] = on;
        }
        if self.v_out[b as usize] == o {
            self.v_out[b as usize] = hn;
        }
    }

    /// Live faces as vertex triples.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        (0..self.f_h.len() as u32)
            .filter(|&f| !self.f_dead[f as usize])
            .map(|f| self.face_vertices(f))
            .collect()
    }

    /// Live vertices.
    pub fn vertices(&self) -> impl Iterator<Item = u32> + '_ {
        (0..self.pos.len() as u32).filter(|&v| !self.v_dead[v as usize])
    }

    /// Live edges, as one halfedge each.
    pub fn edges(&self) -> impl Iterator<Item = u32> + '_ {
        (0..self.e_dead.len() as u32)
            .filter(|&e| !self.e_dead[e as usize])
            .map(|e| 2 * e)
    }

    /// Checks every structural invariant (for tests and debugging).
    pub fn check(&self) -> Result<(), String> {
        for h in 0..self.h_to.len() as u32 {
            if self.edge_dead(h) {
                continue;
            }
            let (n, p) = (self.next(h), self.prev(h));
            if n == NONE || p == NONE || self.prev(n) != h || self.next(p) != h {
                return Err(format!("halfedge {h}: next/prev broken"));
            }
            if self.edge_dead(n) || self.edge_dead(p) {
                return Err(format!("halfedge {h} links a dead edge"));
            }
            if self.to(p) != self.from(h) {
                return Err(format!("halfedge {h}: prev does not end at its start"));
            }
            if self.face(n) != self.face(h) {
                return Err(format!("halfedge {h}: next in another face"));
            }
            let f = self.face(h);
            if f != NONE {
                if self.f_dead[f as usize] {
                    return Err(format!("halfedge {h} in dead face {f}"));
                }
                if self.next(self.next(self.next(h))) != h {
                    return Err(format!("face {f} is not a triangle"));
                }
            }
            if self.vertex_dead(self.to(h)) {
                return Err(format!("halfedge {h} points to dead vertex"));
            }
        }
        for v in self.vertices() {
            let h = self.v_out[v as usize];
            if h == NONE {
                continue;
            }
            if self.edge_dead(h) || self.from(h) != v {
                return Err(format!("vertex {v}: bad outgoing halfedge"));
            }
            let mut boundary = 0;
            let mut count = 0;
            for g in self.outgoing(v) {
                count += 1;
                if count > 10_000 {
                    return Err(format!("vertex {v}: outgoing loop does not close"));
                }
                if self.from(g) != v {
                    return Err(format!("vertex {v}: circulator leaves the vertex"));
                }
                boundary += usize::from(self.is_boundary_halfedge(g));
            }
            if boundary > 1 || (boundary == 1 && !self.is_boundary_halfedge(h)) {
                return Err(format!(
                    "vertex {v}: non-manifold or outgoing not on the boundary"
                ));
            }
        }
        for f in 0..self.f_h.len() as u32 {
            if !self.f_dead[f as usize] && self.face(self.f_h[f as usize]) != f {
                return Err(format!("face {f}: its halfedge is elsewhere"));
            }
        }
        Ok(())
    }

    /// Removes deleted elements; returns the new index of every old vertex (`NONE` if deleted).
    pub fn collect_garbage(&mut self) -> Vec<u32> {
        let tris = self.triangles();
        let mut vmap = vec![NONE; self.pos.len()];
        let mut pos = Vec::new();
        let mut tag = Vec::new();
        let mut locked = Vec::new();
        let mut pinched = Vec::new();
        let mut hint = Vec::new();
        for v in 0..self.pos.len() {
            if !self.v_dead[v] && self.v_out[v] != NONE {
                vmap[v] = pos.len() as u32;
                pos.push(self.pos[v]);
                tag.push(self.tag[v]);
                locked.push(self.locked[v]);
                pinched.push(self.pinched[v]);
                hint.push(self.hint[v]);
            }
        }
        let tris: Vec<[u32; 3]> = tris.iter().map(|t| t.map(|v| vmap[v as usize])).collect();
        let mut m =
            HalfedgeMesh::from_triangles(pos, tag, &tris).expect("a valid mesh stays valid");
        // fans were already split; the rebuild adds no vertices
        m.locked = locked;
        m.locked.resize(m.pos.len(), false);
        m.pinched = pinched;
        m.pinched.resize(m.pos.len(), false);
        m.hint = hint;
        m.hint.resize(m.pos.len(), NONE);
        // faces keep their order
        m.face_hint = (0..self.f_h.len())
            .filter(|&f| !self.f_dead[f])
            .map(|f| self.face_hint[f].clone())
            .collect();
        *self = m;
        vmap
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3×3 grid of squares (16 vertices, 18 triangles) in the plane z = 0.
    fn grid() -> HalfedgeMesh {
        let mut pos = Vec::new();
        for y in 0..4 {
            for x in 0..4 {
                pos.push(DVec3::new(x as f64, y as f64, 0.0));
            }
        }
        let mut tris = Vec::new();
        for y in 0..3u32 {
            for x in 0..3u32 {
                let v = x + 4 * y;
                tris.push([v, v + 1, v + 5]);
                tris.push([v, v + 5, v + 4]);
            }
        }
        let tag = (0..16).collect();
        HalfedgeMesh::from_triangles(pos, tag, &tris).unwrap()
    }

    fn area(m: &HalfedgeMesh) -> f64 {
        m.triangles()
            .iter()
            .map(|t| {
                0.5 * (m.pos[t[1] as usize] - m.pos[t[0] as usize])
                    .cross(m.pos[t[2] as usize] - m.pos[t[0] as usize])
                    .z
            })
            .sum()
    }

    #[test]
    fn build_and_circulate() {
        let m = grid();
        m.check().unwrap();
        assert_eq!(m.valence(5), 6);
        assert_eq!(m.valence(0), 3);
        assert!(m.is_boundary_vertex(0) && !m.is_boundary_vertex(5));
        assert_eq!(m.edges().count(), 33);
    }

    #[test]
    fn split_flip_collapse_keep_the_mesh_valid() {
        let mut m = grid();
        let total = area(&m);
        // split every edge once (interior and boundary)
        let edges: Vec<u32> = m.edges().collect();
        for h in edges {
            let p = (m.pos[m.from(h) as usize] + m.pos[m.to(h) as usize]) * 0.5;
            m.split(h, p);
            m.check().unwrap();
        }
        assert_eq!(m.triangles().len(), 18 * 4);
        assert!((area(&m) - total).abs() < 1e-12);
        // flip what can be flipped
        let edges: Vec<u32> = m.edges().collect();
        for h in edges.into_iter().take(20) {
            if m.is_flip_ok(h) {
                m.flip(h);
                m.check().unwrap();
            }
        }
        // collapse short edges until nothing more is allowed
        for _ in 0..3 {
            let edges: Vec<u32> = m.edges().collect();
            for h in edges {
                if m.edge_dead(h) || m.is_boundary_edge(h) {
                    continue;
                }
                for hh in [h, h ^ 1] {
                    if !m.edge_dead(hh) && !m.is_boundary_vertex(m.from(hh)) && m.is_collapse_ok(hh)
                    {
                        m.collapse(hh);
                        m.check().unwrap();
                        break;
                    }
                }
            }
        }
        assert!(m.triangles().len() < 18 * 4);
        m.collect_garbage();
        m.check().unwrap();
    }

    #[test]
    fn boundary_collapse() {
        let mut m = grid();
        // collapse boundary edge 1 -> 2 (vertex 1 onto 2)
        let h = m.outgoing(1).find(|&g| m.to(g) == 2).unwrap();
        assert!(m.is_boundary_edge(h));
        assert!(m.is_collapse_ok(h));
        m.collapse(h);
        m.check().unwrap();
        assert_eq!(m.triangles().len(), 17);
    }

    #[test]
    fn fans_are_split() {
        // two triangles sharing only vertex 0
        let pos = vec![DVec3::ZERO, DVec3::X, DVec3::Y, -DVec3::X, -DVec3::Y];
        let m =
            HalfedgeMesh::from_triangles(pos, (0..5).collect(), &[[0, 1, 2], [0, 3, 4]]).unwrap();
        m.check().unwrap();
        assert_eq!(m.vertex_slots(), 6);
        assert_eq!(m.tag[5], 0);
    }

    #[test]
    fn random_operations_keep_the_mesh_valid() {
        let mut state = 12345u64;
        let mut rand = |n: usize| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) as usize) % n.max(1)
        };
        let mut m = grid();
        for step in 0..3000 {
            let edges: Vec<u32> = m.edges().collect();
            let h = edges[rand(edges.len())] ^ (rand(2) as u32);
            match rand(3) {
                0 if m.triangles().len() < 400 => {
                    let p = (m.pos[m.from(h) as usize] + m.pos[m.to(h) as usize]) * 0.5;
                    m.split(h, p);
                }
                1 if m.is_collapse_ok(h) && !m.is_boundary_vertex(m.from(h)) => m.collapse(h),
                1 if m.is_collapse_ok(h) && m.is_boundary_edge(h) => m.collapse(h),
                2 if m.is_flip_ok(h) => m.flip(h),
                _ => {}
            }
            if let Err(e) = m.check() {
                panic!("step {step}: {e}");
            }
            if step % 500 == 499 {
                m.collect_garbage();
                m.check().unwrap();
            }
        }
        // Euler characteristic of a disk: V - E + F = 1
        m.collect_garbage();
        let (v, e, f) = (
            m.vertices().count() as i64,
            m.edges().count() as i64,
            m.triangles().len() as i64,
        );
        assert_eq!(v - e + f, 1);
    }
}
