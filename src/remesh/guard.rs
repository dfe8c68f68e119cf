//! The crossing guard: every operation of the remesher (split, collapse,
//! flip, vertex move, on patches and on junction curves) is accepted only if
//! the triangles it makes cross no other triangle of any patch, nor each
//! other. Since the smoothed extraction the remesher starts from has no
//! crossing, none can ever appear: no repair afterwards, no fallback.
//!
//! The guard is a spatial hash of the current triangles (cells of about the
//! mean edge length, each listing the faces whose boxes overlap it), updated
//! with every accepted operation, plus fixed *obstacles*: triangles beside the
//! region being remeshed that no operation here may change. Vertices are
//! identified by keys, so that triangles sharing a vertex or an edge (in any
//! patch) are tested as neighbours, not as crossings.

use glam::DVec3;
use hashbrown::HashMap;

use super::halfedge::{HalfedgeMesh, NONE};
use super::isotropic::PatchState;
use crate::geom::predicates::triangles_cross;

/// A vertex's identity: equal keys are the same vertex.
pub(super) type Key = u64;

/// Keys of vertices that exist only in one patch's mesh (made by splits):
/// the patch and local id, with this bit set.
const LOCAL_KEY: Key = 1 << 63;

/// The key of local vertex `v` of patch `p`: its tag (shared by every copy
/// of a vertex, in every patch), or, for a vertex a split made, the patch
/// and local id.
#[inline]
pub(super) fn vertex_key(m: &HalfedgeMesh, p: u32, v: u32) -> Key {
    let tag = m.tag[v as usize];
    if tag != NONE {
        tag as Key
    } else {
        LOCAL_KEY | ((p as Key) << 32) | v as Key
    }
}

/// A triangle as the guard tests it: corners and their vertex keys.
#[derive(Clone, Copy, Debug)]
pub(super) struct Tri {
    pub p: [DVec3; 3],
    pub k: [Key; 3],
}

impl Tri {
    /// Face `f` of patch `p`, as it is now.
    #[inline]
    pub(super) fn of_face(m: &HalfedgeMesh, p: u32, f: u32) -> Tri {
        let v = m.face_vertices(f);
        Tri {
            p: [
                m.pos[v[0] as usize],
                m.pos[v[1] as usize],
                m.pos[v[2] as usize],
            ],
            k: [
                vertex_key(m, p, v[0]),
                vertex_key(m, p, v[1]),
                vertex_key(m, p, v[2]),
            ],
        }
    }

    #[inline]
    fn bounds(&self) -> (DVec3, DVec3) {
        let [a, b, c] = self.p;
        (a.min(b).min(c), a.max(b).max(c))
    }
}

/// Faces in a cell: `patch << 32 | face`, or an obstacle (`OBSTACLE << 32 | index`).
type Entry = u64;
const OBSTACLE: u32 = u32::MAX;

/// An inclusive range of cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Cells {
    lo: [i32; 3],
    hi: [i32; 3],
}

const UNREGISTERED: Cells = Cells {
    lo: [1, 1, 1],
    hi: [0, 0, 0],
};

/// Cells per axis a box may span before it is registered as one huge box
/// (see [`Guard::cells_of`]).
const MAX_SPAN: i32 = 64;

/// The spatial hash of current triangles and obstacles.
pub(super) struct Guard {
    inv: f64,
    cells: HashMap<u64, Vec<Entry>>,
    /// Faces whose box spans more than [`MAX_SPAN`] cells: tested by every query.
    huge: Vec<Entry>,
    /// Per patch and face: the cells it is registered in.
    registered: Vec<Vec<Cells>>,
    obstacles: Vec<Tri>,
    /// Per patch and face, and per obstacle: the last query that saw it.
    seen: Vec<Vec<u32>>,
    seen_obstacle: Vec<u32>,
    query: u32,
    /// New triangles must lie within this box (where the obstacles are complete).
    trusted: (DVec3, DVec3),
}

impl Guard {
    /// A guard over every live face of `patches`
    /// and the `obstacles`, with cells of `cell` mm; operations may make
    /// triangles only within `trusted`.
    pub(super) fn new(
        cell: f64,
        patches: &[PatchState],
        obstacles: Vec<Tri>,
        trusted: (DVec3, DVec3),
    ) -> Self {
        let mut g = Guard {
            inv: 1.0 / cell,
            cells: HashMap::new(),
            huge: Vec::new(),
            registered: patches
                .iter()
                .map(|st| vec![UNREGISTERED; st.mesh.face_slots()])
                .collect(),
            seen: patches
                .iter()
                .map(|st| vec![0; st.mesh.face_slots()])
                .collect(),
            seen_obstacle: vec![0; obstacles.len()],
            obstacles: Vec::new(),
            query: 0,
            trusted,
        };
        for (i, t) in obstacles.iter().enumerate() {
            let c = g.cells_of(t.bounds());
            g.add(c, (OBSTACLE as Entry) << 32 | i as Entry);
        }
        g.obstacles = obstacles;
        for (p, st) in patches.iter().enumerate() {
            for f in 0..st.mesh.face_slots() as u32 {
                if !st.mesh.face_dead(f) {
                    g.insert(&st.mesh, p as u32, f);
                }
            }
        }
        g
    }

    #[inline]
    fn cell_key(c: [i32; 3]) -> u64 {
        const OFF: i64 = 1 << 20;
        let k = c.map(|x| (x as i64 + OFF) as u64 & ((1 << 21) - 1));
        k[0] | k[1] << 21 | k[2] << 42
    }

    /// The cells a box overlaps (every query cell of a box spanning more
    /// than [`MAX_SPAN`] per axis would be too many: such a box goes to the
    /// `huge` list, marked by an empty range with `lo` = [−1; 3]).
    #[inline]
    fn cells_of(&self, (lo, hi): (DVec3, DVec3)) -> Cells {
        let f = |x: f64| {
            let c = (x * self.inv).floor();
            c.clamp(-(1 << 20) as f64 + 1.0, (1 << 20) as f64 - 2.0) as i32
        };
        let c = Cells {
            lo: [f(lo.x), f(lo.y), f(lo.z)],
            hi: [f(hi.x), f(hi.y), f(hi.z)],
        };
        if (0..3).any(|a| c.hi[a] - c.lo[a] >= MAX_SPAN) || lo.is_nan() || hi.is_nan() {
            Cells {
                lo: [-1; 3],
                hi: [-2; 3],
            }
        } else {
            c
        }
    }

    fn add(&mut self, c: Cells, e: Entry) {
        if c.lo == [-1; 3] && c.hi == [-2; 3] {
            self.huge.push(e);
            return;
        }
        for z in c.lo[2]..=c.hi[2] {
            for y in c.lo[1]..=c.hi[1] {
                for x in c.lo[0]..=c.hi[0] {
                    self.cells
                        .entry(Self::cell_key([x, y, z]))
                        .or_default()
                        .push(e);
                }
            }
        }
    }

    /// Registers face `f` of patch `p` (`m` = its mesh) as it is now.
    pub(super) fn insert(&mut self, m: &HalfedgeMesh, p: u32, f: u32) {
        let pu = p as usize;
        if self.registered[pu].len() <= f as usize {
            self.registered[pu].resize(m.face_slots(), UNREGISTERED);
            self.seen[pu].resize(m.face_slots(), 0);
        }
        debug_assert_eq!(self.registered[pu][f as usize], UNREGISTERED);
        let c = self.cells_of(Tri::of_face(m, p, f).bounds());
        self.registered[pu][f as usize] = c;
        self.add(c, (p as Entry) << 32 | f as Entry);
    }

    /// Unregisters face `f` of patch `p` (before it changes or dies).
    pub(super) fn remove(&mut self, p: u32, f: u32) {
        let Some(c) = self.registered[p as usize].get_mut(f as usize) else {
            return;
        };
        let c = std::mem::replace(c, UNREGISTERED);
        if c == UNREGISTERED {
            return;
        }
        let e = (p as Entry) << 32 | f as Entry;
        if c.lo == [-1; 3] && c.hi == [-2; 3] {
            if let Some(i) = self.huge.iter().position(|&x| x == e) {
                self.huge.swap_remove(i);
            }
            return;
        }
        for z in c.lo[2]..=c.hi[2] {
            for y in c.lo[1]..=c.hi[1] {
                for x in c.lo[0]..=c.hi[0] {
                    if let Some(list) = self.cells.get_mut(&Self::cell_key([x, y, z])) {
                        if let Some(i) = list.iter().position(|&x| x == e) {
                            list.swap_remove(i);
                        }
                    }
                }
            }
        }
    }

    /// Whether the triangles `made` cross neither each other nor anything
    /// registered except the faces `replaced` (patch, face), and lie within
    /// the trusted box. `patches[p]` is patch `p` as it is now.
    pub(super) fn clear(
        &mut self,
        patches: &[PatchState],
        made: &[Tri],
        replaced: &[(u32, u32)],
    ) -> bool {
        if made.is_empty() {
            return true;
        }
        let (mut lo, mut hi) = made[0].bounds();
        for t in &made[1..] {
            let (l, h) = t.bounds();
            lo = lo.min(l);
            hi = hi.max(h);
        }
        if lo.cmplt(self.trusted.0).any()
            || hi.cmpgt(self.trusted.1).any()
            || !lo.is_finite()
            || !hi.is_finite()
        {
            return false;
        }
        for (i, s) in made.iter().enumerate() {
            for t in &made[i + 1..] {
                if triangles_cross(&s.p, &s.k, &t.p, &t.k) {
                    return false;
                }
            }
        }
        self.query = self.query.wrapping_add(1);
        if self.query == 0 {
            // the stamps wrapped: start them afresh
            self.seen.iter_mut().for_each(|s| s.fill(0));
            self.seen_obstacle.fill(0);
            self.query = 1;
        }
        let q = self.query;
        for &(p, f) in replaced {
            if let Some(s) = self.seen[p as usize].get_mut(f as usize) {
                *s = q;
            }
        }
        let bounds: Vec<(DVec3, DVec3)> = made.iter().map(|t| t.bounds()).collect();
        let c = self.cells_of((lo, hi));
        let hit = |e: Entry, seen: &mut Vec<Vec<u32>>, seen_obstacle: &mut Vec<u32>| -> bool {
            let (p, f) = ((e >> 32) as u32, e as u32);
            let t = if p == OBSTACLE {
                let s = &mut seen_obstacle[f as usize];
                if *s == q {
                    return false;
                }
                *s = q;
                self.obstacles[f as usize]
            } else {
                let s = &mut seen[p as usize][f as usize];
                if *s == q {
                    return false;
                }
                *s = q;
                Tri::of_face(&patches[p as usize].mesh, p, f)
            };
            let (tl, th) = t.bounds();
            if tl.cmpgt(hi).any() || th.cmplt(lo).any() {
                return false;
            }
            made.iter().zip(&bounds).any(|(s, b)| {
                !(tl.cmpgt(b.1).any() || th.cmplt(b.0).any())
                    && triangles_cross(&s.p, &s.k, &t.p, &t.k)
            })
        };
        let (seen, seen_obstacle) = (&mut self.seen, &mut self.seen_obstacle);
        for &e in &self.huge {
            if hit(e, seen, seen_obstacle) {
                return false;
            }
        }
        let whole = c.lo == [-1; 3] && c.hi == [-2; 3];
        if whole {
            // a query box spanning too many cells: every registered face
            for list in self.cells.values() {
                for &e in list {
                    if hit(e, seen, seen_obstacle) {
                        return false;
                    }
                }
            }
            return true;
        }
        for z in c.lo[2]..=c.hi[2] {
            for y in c.lo[1]..=c.hi[1] {
                for x in c.lo[0]..=c.hi[0] {
                    if let Some(list) = self.cells.get(&Self::cell_key([x, y, z])) {
                        for &e in list {
                            if hit(e, seen, seen_obstacle) {
                                return false;
                            }
                        }
                    }
                }
            }
        }
        true
    }
}
