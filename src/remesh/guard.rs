//! The crossing guard: every operation of the remesher (split, collapse,
//! flip, vertex move, on patches and on junction curves) is accepted only if
//! the triangles it makes cross no other triangle of any patch, nor each
//! other. Since the smoothed extraction the remesher starts from has no
//! crossing, none can ever appear: no repair afterwards, no fallback.
//!
//! The guard is a hierarchy of loose uniform grids over the region being
//! remeshed (cells doubling in size from level to level): every face (and
//! every fixed *obstacle*: a triangle beside the region that no operation
//! here may change) is listed once, at the finest level whose cells are at
//! least twice its half box, in the bucket of the cell holding the centre of
//! its box (a cell's entries side by side, with their boxes, so that a scan
//! reads memory in order), so that registering and unregistering a face are
//! O(1) (amortised). A query looks, at every level that holds entries, at the
//! cells within half a cell of its own box, and tests the boxes (kept per
//! face, in `f32` rounded outward) before the triangles. Vertices
//! are identified by keys, so that triangles sharing a vertex or an edge (in
//! any patch) are tested as neighbours, not as crossings.

use glam::DVec3;

use super::halfedge::{HalfedgeMesh, NONE};
use super::isotropic::PatchState;
use crate::geom::predicates::triangles_cross;

/// A vertex's identity: equal keys are the same vertex.
pub(super) type Key = u64;

/// Keys of vertices that exist only in one patch's mesh (made by splits):
/// the patch and local id, with this bit set.
pub(super) const LOCAL_KEY: Key = 1 << 63;

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

/// Vertices whose whole fan in one patch's mesh is known to be simple (see
/// [`is_simple_fan`]) with the triangles being tested in it: every
/// triangle of that fan meets every other only along the edges they share.
/// A registered face of `patch` holding one of `apexes` is such a fan
/// member, and so is every triangle tested (each holds every apex), so the
/// guard need not test the two against each other. Mesh neighbours are
/// most of the pairs a query meets; one look at a fan replaces their tests.
#[derive(Clone, Copy, Debug)]
pub(super) struct SimpleFans {
    pub patch: u32,
    pub apexes: [Option<Key>; 3],
}

impl SimpleFans {
    /// Whether triangle `k` (by its vertex keys), a face of `patch`, lies in
    /// one of the fans.
    #[inline]
    fn hold(&self, patch: u32, k: &[Key; 3]) -> bool {
        patch == self.patch && k.iter().any(|&x| self.apexes.contains(&Some(x)))
    }
}

/// Most triangles a fan may have to be shown simple (more are rare; they
/// are then tested pair by pair).
pub(super) const FAN_MAX: usize = 24;

/// Whether `made` is a fan that cannot overlap itself, shown without testing
/// its triangles pairwise: all share one apex (the first corner of each, as
/// the remesher makes them) and form one chain around it (each triangle's
/// far corner is the next one's near corner: one start, or none for a
/// closed fan), and the chain's ring is simple around the apex
/// ([`is_simple_ring`]). `false` says only "not shown this way".
pub(super) fn is_simple_fan(made: &[Tri]) -> bool {
    let n = made.len();
    if n < 2 {
        return true;
    }
    if n > FAN_MAX {
        return false;
    }
    let apex = made[0].k[0];
    if made
        .iter()
        .any(|t| t.k[0] != apex || t.k[1] == apex || t.k[2] == apex)
    {
        return false;
    }
    // one chain: near corners distinct, far corners distinct, at most one
    // near corner that is no far corner
    let mut start = None;
    for (i, t) in made.iter().enumerate() {
        if made[i + 1..]
            .iter()
            .any(|u| u.k[1] == t.k[1] || u.k[2] == t.k[2])
        {
            return false;
        }
        if !made.iter().any(|u| u.k[2] == t.k[1]) {
            if start.is_some() {
                return false;
            }
            start = Some(i);
        }
    }
    // the ring in chain order
    let closed = start.is_none();
    let first = start.unwrap_or(0);
    let mut ring = [DVec3::ZERO; FAN_MAX + 1];
    let mut at = first;
    ring[0] = made[at].p[1];
    for i in 1..=n {
        ring[i] = made[at].p[2];
        if i == n {
            break;
        }
        let far = made[at].k[2];
        match made.iter().position(|u| u.k[1] == far) {
            Some(next) if next != first => at = next,
            // the chain ends or closes before it holds every triangle
            _ => return false,
        }
    }
    is_simple_ring(made[0].p[0], &ring[..n + usize::from(!closed)], closed)
}

/// Whether the triangles (`apex`, `ring[i]`, `ring[i + 1]`) (and
/// (`apex`, last, first) when `closed`) form a simple fan: seen along the
/// sum of their normals, every one keeps its orientation by a margin (its
/// normal within 84° of that axis), and going round the ring from its first
/// point, the directions from the apex turn less than once (open) or
/// exactly once (closed). Their projections are then consecutive sectors
/// around the apex that meet only along their sides, so the triangles meet
/// only along their shared edges. `false` says only "not shown this way".
///
/// The turn is counted without angles: each sector turns counter-clockwise
/// by less than a half turn (it keeps its orientation), so the directions
/// turn less than once exactly when, seen from the first direction, they
/// run through the upper half plane, at most past the opposite direction,
/// then through the lower one, and never back (with a margin at the first
/// direction itself).
pub(super) fn is_simple_ring(apex: DVec3, ring: &[DVec3], closed: bool) -> bool {
    let sectors = if closed {
        ring.len()
    } else {
        ring.len().saturating_sub(1)
    };
    if sectors < 2 {
        // no two triangles
        return true;
    }
    let d = |i: usize| ring[i % ring.len()] - apex;
    let mut axis = DVec3::ZERO;
    for i in 0..sectors {
        axis += d(i).cross(d(i + 1));
    }
    let axis = axis.normalize_or_zero();
    if axis == DVec3::ZERO {
        return false;
    }
    // every sector faces along the axis by at least cos 84° (compared
    // squared: no roots)
    for i in 0..sectors {
        let n = d(i).cross(d(i + 1));
        let along = n.dot(axis);
        if !(along > 0.0 && along * along > 0.01 * n.length_squared()) {
            return false;
        }
    }
    // the half planes seen from the first direction, in order
    let d0 = d(0);
    let (d0a, d02) = (d0.dot(axis), d0.length_squared());
    const UPPER: u8 = 0;
    const OPPOSITE: u8 = 1;
    const LOWER: u8 = 2;
    let mut phase = UPPER;
    for i in 1..ring.len() {
        let di = d(i);
        let y = axis.dot(d0.cross(di));
        let x = d0.dot(di) - d0a * di.dot(axis);
        let side = if y * y > 1e-18 * d02 * di.length_squared() {
            if y > 0.0 { UPPER } else { LOWER }
        } else if x < 0.0 {
            OPPOSITE
        } else {
            // along the first direction again: a full turn, or nearly
            return false;
        };
        // (one opposite direction at most, and never back up)
        if side < phase || side == OPPOSITE && phase == OPPOSITE {
            return false;
        }
        phase = side;
    }
    // a closed ring comes back to the first direction from below
    !closed || phase == LOWER
}

/// Most cells the finest grid may have.
const MAX_CELLS: usize = 1 << 22;

/// A cell's entries: a stretch of [`Guard::pool`].
#[derive(Clone, Copy, Default)]
struct Bucket {
    start: u32,
    len: u32,
    cap: u32,
}

/// One level of the hierarchy: a grid of buckets.
struct Level {
    cell: f64,
    inv: f64,
    dims: [usize; 3],
    buckets: Vec<Bucket>,
    /// Entries listed here.
    count: usize,
}

impl Level {
    fn new(ext: DVec3, cell: f64) -> Self {
        let dims = ext.to_array().map(|e| (e / cell).floor() as usize + 1);
        Level {
            cell,
            inv: 1.0 / cell,
            dims,
            buckets: vec![Bucket::default(); dims.iter().product()],
            count: 0,
        }
    }

    /// The cell holding point `p` (offset from the grid's corner; clamped).
    #[inline]
    fn cell_at(&self, d: DVec3) -> [usize; 3] {
        let q = d * self.inv;
        let c = |k: usize| {
            let x = q[k];
            if x.is_nan() || x <= 0.0 {
                0
            } else {
                // (through u32: see `CellGrid::coords`)
                (x as u32 as usize).min(self.dims[k] - 1)
            }
        };
        [c(0), c(1), c(2)]
    }

    #[inline]
    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }
}

/// A box in the guard's 16-bit grid coordinates, rounded outward: what a
/// scan compares before any exact test (16 bytes an item with the id, four
/// to a cache line; the scans read about a hundred items each).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
struct QBox {
    lo: [u16; 3],
    hi: [u16; 3],
}

impl QBox {
    const EMPTY: QBox = QBox {
        lo: [0; 3],
        hi: [0; 3],
    };

    /// Whether the boxes meet (scans use [`QueryBox::meets`] on x86_64).
    #[cfg(any(test, not(target_arch = "x86_64")))]
    #[inline]
    fn overlaps(&self, o: &QBox) -> bool {
        (0..3).all(|k| self.lo[k] <= o.hi[k] && o.lo[k] <= self.hi[k])
    }
}

/// The frame of [`QBox`]es: coordinates `(x - lo) · inv`, floored for lower
/// corners and raised for upper ones, clamped to 16 bits (a box beyond the
/// frame lands on its border: still outward, only less selective).
#[derive(Clone, Copy, Debug)]
struct Quantizer {
    lo: DVec3,
    inv: f64,
}

impl Quantizer {
    /// A frame over the box from `lo` spanning `ext`.
    fn over(lo: DVec3, ext: DVec3) -> Self {
        let span = ext.max_element().max(1e-9);
        Quantizer {
            lo,
            inv: f64::from(u16::MAX - 2) / span,
        }
    }

    #[inline]
    fn qbox(&self, (lo, hi): (DVec3, DVec3)) -> QBox {
        let top = f64::from(u16::MAX);
        let a = (lo - self.lo) * self.inv;
        let b = (hi - self.lo) * self.inv;
        // (rounding in the products is far below one unit: floor and ceil
        // keep the boxes outward; NaN gives the whole frame. Both by casts,
        // which truncate and saturate: on x86_64 without SSE4.1, `floor` and
        // `ceil` are calls into libm, and these run for every box)
        let down = |x: f64| if x > 0.0 { x as u16 } else { 0 };
        let up = |x: f64| {
            if x < top {
                if x > 0.0 {
                    let t = x as u16;
                    t + u16::from(f64::from(t) < x)
                } else {
                    0
                }
            } else {
                u16::MAX
            }
        };
        QBox {
            lo: [down(a.x), down(a.y), down(a.z)],
            hi: [up(b.x), up(b.y), up(b.z)],
        }
    }
}

/// What a scan reads of an entry, stored in its cell's bucket: its box and
/// its id (16 bytes: one SSE2 register, see [`QueryBox`]).
#[derive(Clone, Copy)]
#[repr(C)]
struct Item {
    b: QBox,
    e: u32,
}

/// A query's box, prepared to test items against it without branches: a
/// scan meets overlapping and apart items in no order a branch predictor
/// could learn, and six compare-and-branch steps per item were a third of
/// the guard's time. As eight `u16` lanes over an [`Item`] (lo, hi, id):
/// `above` = (query hi, all ones), `below` = (zeros, query lo, zeros); the
/// saturating differences item − above and below − item are all zero
/// exactly when every lo ≤ query hi and every query lo ≤ hi.
#[derive(Clone, Copy)]
struct QueryBox {
    #[cfg(not(target_arch = "x86_64"))]
    q: QBox,
    #[cfg(target_arch = "x86_64")]
    above: std::arch::x86_64::__m128i,
    #[cfg(target_arch = "x86_64")]
    below: std::arch::x86_64::__m128i,
}

impl QueryBox {
    fn new(q: QBox) -> Self {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: SSE2 is part of every x86_64 target; these only build
        // registers from values
        let (above, below) = unsafe {
            use std::arch::x86_64::_mm_setr_epi16;
            let v = |x: u16| x as i16;
            (
                _mm_setr_epi16(v(q.hi[0]), v(q.hi[1]), v(q.hi[2]), -1, -1, -1, -1, -1),
                _mm_setr_epi16(0, 0, 0, v(q.lo[0]), v(q.lo[1]), v(q.lo[2]), 0, 0),
            )
        };
        QueryBox {
            #[cfg(not(target_arch = "x86_64"))]
            q,
            #[cfg(target_arch = "x86_64")]
            above,
            #[cfg(target_arch = "x86_64")]
            below,
        }
    }

    /// Whether `item`'s box meets the query's (the same answer as
    /// [`QBox::overlaps`]).
    #[inline(always)]
    fn meets(&self, item: &Item) -> bool {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: SSE2 is part of every x86_64 target; `Item` is 16 bytes
        // (`repr(C)`: the six `u16` of its box, then its id), read unaligned
        unsafe {
            use std::arch::x86_64::*;
            let x = _mm_loadu_si128((item as *const Item).cast());
            let apart = _mm_or_si128(_mm_subs_epu16(x, self.above), _mm_subs_epu16(self.below, x));
            _mm_movemask_epi8(_mm_cmpeq_epi16(apart, _mm_setzero_si128())) == 0xffff
        }
        #[cfg(not(target_arch = "x86_64"))]
        item.b.overlaps(&self.q)
    }
}

/// The loose grids of current triangles and obstacles.
pub(super) struct Guard {
    lo: DVec3,
    levels: Vec<Level>,
    /// The buckets' items. A cell's entries lie side by side, so a scan
    /// reads them in one stretch (a linked list made every entry a
    /// dependent cache miss); a full bucket moves to the end with twice the
    /// room, leaving its old stretch unused (the guard lives for one pass).
    pool: Vec<Item>,
    // per entry
    /// Level, cell and place in the bucket of each listed entry (`NONE`
    /// cell: not listed).
    level_of: Vec<u8>,
    cell_of: Vec<u32>,
    place_of: Vec<u32>,
    /// The triangle of each entry as it was registered (faces change only
    /// after they are unregistered).
    tris: Vec<Tri>,
    /// Per patch and face: its entry (or [`NONE`]).
    entry: Vec<Vec<u32>>,
    /// Per entry: its (patch, face), or ([`NONE`], [`NONE`]) for an obstacle.
    owner: Vec<(u32, u32)>,
    made_boxes: Vec<QueryBox>,
    /// The frame of the items' boxes.
    quantizer: Quantizer,
    /// Entries a query passes over (the faces an operation replaces).
    skipped: Vec<u32>,
    /// New triangles must lie within this box (where the obstacles are complete).
    trusted: (DVec3, DVec3),
}

impl Guard {
    /// A guard over every live face of `patches` and the `obstacles`, with
    /// finest cells of about `cell` mm; operations may make triangles only
    /// within `trusted`.
    pub(super) fn new(
        cell: f64,
        patches: &[PatchState],
        obstacles: Vec<Tri>,
        trusted: (DVec3, DVec3),
    ) -> Self {
        // the grids cover every vertex now, within the trusted box
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for st in patches {
            for v in st.mesh.vertices() {
                lo = lo.min(st.mesh.pos[v as usize]);
                hi = hi.max(st.mesh.pos[v as usize]);
            }
        }
        for t in &obstacles {
            let (a, b) = t.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        if !(lo.is_finite() && hi.is_finite()) {
            lo = DVec3::ZERO;
            hi = DVec3::ZERO;
        }
        lo = lo.max(trusted.0);
        hi = hi.min(trusted.1).max(lo);
        let ext = (hi - lo).max(DVec3::splat(1e-9));
        let mut cell = cell.max(ext.max_element() * 1e-6).max(1e-9);
        let cells = |c: f64| {
            ext.to_array()
                .iter()
                .map(|e| (e / c).floor() as usize + 1)
                .product::<usize>()
        };
        while cells(cell) > MAX_CELLS {
            cell *= 1.26;
        }
        let mut levels = vec![Level::new(ext, cell)];
        while levels.last().is_some_and(|l| l.dims.iter().any(|&d| d > 1)) {
            let c = 2.0 * levels.last().expect("a level").cell;
            levels.push(Level::new(ext, c));
        }
        let mut g = Guard {
            lo,
            levels,
            pool: Vec::new(),
            level_of: Vec::new(),
            cell_of: Vec::new(),
            place_of: Vec::new(),
            tris: Vec::new(),
            entry: patches
                .iter()
                .map(|st| vec![NONE; st.mesh.face_slots()])
                .collect(),
            owner: Vec::new(),
            made_boxes: Vec::new(),
            quantizer: Quantizer::over(lo, ext),
            skipped: Vec::new(),
            trusted,
        };
        // the entries: the obstacles, then every live face (each triangle
        // copied once, each box computed once)
        g.tris = obstacles;
        g.owner = vec![(NONE, NONE); g.tris.len()];
        for (p, st) in patches.iter().enumerate() {
            for f in 0..st.mesh.face_slots() as u32 {
                if !st.mesh.face_dead(f) {
                    g.entry[p][f as usize] = g.tris.len() as u32;
                    g.tris.push(Tri::of_face(&st.mesh, p as u32, f));
                    g.owner.push((p as u32, f));
                }
            }
        }
        // first the buckets' sizes, then each bucket's stretch in the order
        // of its cell (a bucket's room: its entries and a few more, so that
        // the first operations there need not move it)
        let places: Vec<(usize, u32, QBox)> = g
            .tris
            .iter()
            .map(|t| {
                let b = t.bounds();
                let (level, c) = g.place_of_box(b);
                (level, c, g.quantizer.qbox(b))
            })
            .collect();
        for &(level, c, _) in &places {
            g.levels[level].buckets[c as usize].cap += 1;
        }
        let mut start = 0u32;
        for l in &mut g.levels {
            for b in &mut l.buckets {
                if b.cap > 0 {
                    b.start = start;
                    b.cap += 2;
                    start += b.cap;
                }
            }
        }
        g.pool.resize(
            start as usize,
            Item {
                b: QBox::EMPTY,
                e: NONE,
            },
        );
        g.level_of = vec![0; places.len()];
        g.cell_of = vec![NONE; places.len()];
        g.place_of = vec![NONE; places.len()];
        for (e, (level, c, b)) in places.into_iter().enumerate() {
            g.append(e as u32, level, c, b);
        }
        g
    }

    /// The level and cell that triangle `t` is listed in: the finest level
    /// whose cells are at least twice its half box, the cell of its centre.
    fn place(&self, t: &Tri) -> (usize, u32) {
        self.place_of_box(t.bounds())
    }

    /// [`Guard::place`] of a triangle with box `b`.
    fn place_of_box(&self, b: (DVec3, DVec3)) -> (usize, u32) {
        let half = ((b.1 - b.0) * 0.5).max_element();
        let top = self.levels.len() - 1;
        let level = if half.is_finite() {
            self.levels
                .iter()
                .position(|l| 2.0 * half <= l.cell)
                .unwrap_or(top)
        } else {
            top
        };
        let l = &self.levels[level];
        (
            level,
            l.index(l.cell_at((b.0 + b.1) * 0.5 - self.lo)) as u32,
        )
    }

    /// Lists a new entry for triangle `t`, face `owner` (patch, face).
    fn add(&mut self, t: Tri, owner: (u32, u32)) -> u32 {
        let (level, c) = self.place(&t);
        self.add_at(t, owner, level, c)
    }

    /// [`Guard::add`] at its [`Guard::place`], known.
    fn add_at(&mut self, t: Tri, owner: (u32, u32), level: usize, c: u32) -> u32 {
        let e = self.tris.len() as u32;
        self.owner.push(owner);
        self.level_of.push(0);
        self.cell_of.push(NONE);
        self.place_of.push(NONE);
        self.tris.push(t);
        self.link_at(e, t, level, c);
        e
    }

    /// Puts entry `e` (triangle `t`) in a bucket: at the finest level whose
    /// cells are at least twice its half box, in the cell of its centre.
    fn link(&mut self, e: u32, t: Tri) {
        let (level, c) = self.place(&t);
        self.link_at(e, t, level, c);
    }

    /// [`Guard::link`] at its [`Guard::place`], known.
    fn link_at(&mut self, e: u32, t: Tri, level: usize, c: u32) {
        let l = &mut self.levels[level];
        let b = &mut l.buckets[c as usize];
        if b.len == b.cap {
            // move to the end with twice the room
            let start = self.pool.len();
            let cap = (2 * b.cap).max(4);
            self.pool
                .extend_from_within(b.start as usize..(b.start + b.len) as usize);
            self.pool.resize(
                start + cap as usize,
                Item {
                    b: QBox::EMPTY,
                    e: NONE,
                },
            );
            b.start = start as u32;
            b.cap = cap;
        }
        self.append(e, level, c, self.quantizer.qbox(t.bounds()));
        self.tris[e as usize] = t;
    }

    /// Puts entry `e`, with box `b`, at the end of the bucket of cell `c`
    /// of `level`, which has room for it.
    fn append(&mut self, e: u32, level: usize, c: u32, b: QBox) {
        let l = &mut self.levels[level];
        let bucket = &mut l.buckets[c as usize];
        debug_assert!(bucket.len < bucket.cap, "a bucket with room");
        self.pool[(bucket.start + bucket.len) as usize] = Item { b, e };
        self.place_of[e as usize] = bucket.len;
        bucket.len += 1;
        l.count += 1;
        self.level_of[e as usize] = level as u8;
        self.cell_of[e as usize] = c;
    }

    /// Takes entry `e` out of its bucket.
    fn unlink(&mut self, e: u32) {
        let c = self.cell_of[e as usize];
        if c == NONE {
            return;
        }
        let l = &mut self.levels[self.level_of[e as usize] as usize];
        let b = &mut l.buckets[c as usize];
        let at = self.place_of[e as usize];
        b.len -= 1;
        let last = self.pool[(b.start + b.len) as usize];
        self.pool[(b.start + at) as usize] = last;
        self.place_of[last.e as usize] = at;
        l.count -= 1;
        self.cell_of[e as usize] = NONE;
    }

    /// Registers face `f` of patch `p` (`m` = its mesh) as it is now.
    pub(super) fn insert(&mut self, m: &HalfedgeMesh, p: u32, f: u32) {
        let pu = p as usize;
        if self.entry[pu].len() <= f as usize {
            self.entry[pu].resize(m.face_slots(), NONE);
        }
        let t = Tri::of_face(m, p, f);
        match self.entry[pu][f as usize] {
            NONE => {
                let e = self.add(t, (p, f));
                self.entry[pu][f as usize] = e;
            }
            e => {
                debug_assert_eq!(self.cell_of[e as usize], NONE, "registered twice");
                self.link(e, t);
            }
        }
    }

    /// Unregisters face `f` of patch `p` (before it changes or dies).
    pub(super) fn remove(&mut self, p: u32, f: u32) {
        if let Some(&e) = self.entry[p as usize].get(f as usize) {
            if e != NONE {
                self.unlink(e);
            }
        }
    }

    /// Whether the triangles `made` cross neither each other nor anything
    /// registered except the faces `replaced` (patch, face), and lie within
    /// the trusted box. Faces in `fans` are known not to cross `made`, nor
    /// do the triangles of `made` cross each other when `fans` is given
    /// (they lie in those fans).
    pub(super) fn clear(
        &mut self,
        made: &[Tri],
        replaced: &[(u32, u32)],
        fans: Option<SimpleFans>,
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
        if !(lo.is_finite() && hi.is_finite())
            || lo.cmplt(self.trusted.0).any()
            || hi.cmpgt(self.trusted.1).any()
        {
            return false;
        }
        if fans.is_none() && !is_simple_fan(made) {
            for (i, s) in made.iter().enumerate() {
                for t in &made[i + 1..] {
                    if triangles_cross(&s.p, &s.k, &t.p, &t.k) {
                        return false;
                    }
                }
            }
        }
        let mut skipped = std::mem::take(&mut self.skipped);
        skipped.clear();
        for &(p, f) in replaced {
            if let Some(&e) = self.entry[p as usize].get(f as usize) {
                if e != NONE && self.cell_of[e as usize] != NONE {
                    skipped.push(e);
                }
            }
        }
        let mut made_boxes = std::mem::take(&mut self.made_boxes);
        made_boxes.clear();
        made_boxes.extend(
            made.iter()
                .map(|t| QueryBox::new(self.quantizer.qbox(t.bounds()))),
        );
        let crossed = self.scan(made, &made_boxes, lo, hi, &skipped, fans);
        self.made_boxes = made_boxes;
        self.skipped = skipped;
        crossed.is_none()
    }

    /// What the one triangle `t` would cross among the registered entries:
    /// `None` if nothing (and it lies within the trusted box); `Some(face)`
    /// for the (patch, face) it crosses, `Some(None)` for an obstacle or
    /// for leaving the trusted box. Faces in `fans` are known not to cross `t`.
    pub(super) fn crossing(
        &mut self,
        t: &Tri,
        fans: Option<SimpleFans>,
    ) -> Option<Option<(u32, u32)>> {
        let (lo, hi) = t.bounds();
        if !(lo.is_finite() && hi.is_finite())
            || lo.cmplt(self.trusted.0).any()
            || hi.cmpgt(self.trusted.1).any()
        {
            return Some(None);
        }
        let b = QueryBox::new(self.quantizer.qbox((lo, hi)));
        let e = self.scan(std::slice::from_ref(t), &[b], lo, hi, &[], fans)?;
        let (p, f) = self.owner[e as usize];
        Some((p != NONE).then_some((p, f)))
    }

    /// The cells near [lo, hi]: the first entry, not one of `skipped` nor
    /// in `fans`, that crosses a triangle of `made`, if any.
    fn scan(
        &self,
        made: &[Tri],
        made_boxes: &[QueryBox],
        lo: DVec3,
        hi: DVec3,
        skipped: &[u32],
        fans: Option<SimpleFans>,
    ) -> Option<u32> {
        let query_box = QueryBox::new(self.quantizer.qbox((lo, hi)));
        for l in &self.levels {
            if l.count == 0 {
                continue;
            }
            // entries are listed by the centre of their box, at most half a cell away
            let r = DVec3::splat(0.5 * l.cell);
            let (a, b) = (l.cell_at(lo - r - self.lo), l.cell_at(hi + r - self.lo));
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    let row = (z * l.dims[1] + y) * l.dims[0];
                    for bucket in &l.buckets[row + a[0]..=row + b[0]] {
                        let items =
                            &self.pool[bucket.start as usize..(bucket.start + bucket.len) as usize];
                        for item in items {
                            if query_box.meets(item) {
                                if let Some(e) =
                                    self.crossing_item(item, made, made_boxes, skipped, fans)
                                {
                                    return Some(e);
                                }
                            }
                        }
                    }
                }
            }
        }
        None
    }

    /// Whether the entry of `item` (whose box meets the query's), unless it
    /// is one of `skipped` or in `fans`, crosses a triangle of `made`.
    #[inline]
    fn crossing_item(
        &self,
        item: &Item,
        made: &[Tri],
        made_boxes: &[QueryBox],
        skipped: &[u32],
        fans: Option<SimpleFans>,
    ) -> Option<u32> {
        if skipped.contains(&item.e) {
            return None;
        }
        let t = &self.tris[item.e as usize];
        if fans.is_some_and(|f| f.hold(self.owner[item.e as usize].0, &t.k)) {
            return None;
        }
        made.iter()
            .zip(made_boxes)
            .any(|(s, sb)| sb.meets(item) && triangles_cross(&s.p, &s.k, &t.p, &t.k))
            .then_some(item.e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::test_rng::Rng;

    /// The quantized boxes are floor and ceil of the frame coordinates,
    /// clamped to 16 bits (NaN: the whole frame), whatever the value:
    /// negative, whole, just off whole, at and beyond the top.
    #[test]
    fn quantized_boxes_round_outward_like_floor_and_ceil() {
        let top = f64::from(u16::MAX);
        let floor = |x: f64| {
            if x > 0.0 {
                x.floor().min(top) as u16
            } else {
                0
            }
        };
        let ceil = |x: f64| {
            if x < top {
                x.ceil().max(0.0) as u16
            } else {
                u16::MAX
            }
        };
        let q = Quantizer {
            lo: DVec3::ZERO,
            inv: 1.0,
        };
        let mut values = vec![
            f64::NAN,
            f64::NEG_INFINITY,
            f64::INFINITY,
            -1.0,
            -0.5,
            -0.0,
            0.0,
            1e-300,
            0.5,
            1.0,
            top - 1.0,
            top - 0.5,
            top,
            top + 0.5,
            1e300,
        ];
        for k in 1..2000 {
            let x = f64::from(k) * 0.37;
            values.extend([
                x,
                x.next_up(),
                x.next_down(),
                x.floor(),
                x.floor().next_up(),
            ]);
        }
        for x in values {
            let b = q.qbox((DVec3::splat(x), DVec3::splat(x)));
            assert_eq!(b.lo, [floor(x); 3], "floor of {x}");
            assert_eq!(b.hi, [ceil(x); 3], "ceil of {x}");
        }
    }

    /// A ring around the origin at the given angles (radians), radii and heights.
    fn ring_at(angles: &[f64], radii: &[f64], heights: &[f64]) -> Vec<DVec3> {
        angles
            .iter()
            .zip(radii)
            .zip(heights)
            .map(|((a, r), z)| DVec3::new(r * a.cos(), r * a.sin(), *z))
            .collect()
    }

    /// The fan's triangles as the guard tests them: apex key 0, ring keys 1...
    fn fan_tris(apex: DVec3, ring: &[DVec3], closed: bool) -> Vec<Tri> {
        let sectors = if closed { ring.len() } else { ring.len() - 1 };
        (0..sectors)
            .map(|i| {
                let j = (i + 1) % ring.len();
                Tri {
                    p: [apex, ring[i], ring[j]],
                    k: [0, i as Key + 1, j as Key + 1],
                }
            })
            .collect()
    }

    #[test]
    fn rings_that_turn_once_are_simple_and_twice_are_not() {
        let o = DVec3::ZERO;
        let turn = std::f64::consts::TAU;
        let flat = |n: usize, span: f64, closed: bool| {
            let steps = if closed { n } else { n - 1 };
            let a: Vec<f64> = (0..n).map(|i| span * i as f64 / steps as f64).collect();
            ring_at(&a, &vec![1.0; n], &vec![0.0; n])
        };
        assert!(is_simple_ring(o, &flat(6, turn, true), true));
        assert!(is_simple_ring(o, &flat(7, 0.97 * turn, false), false));
        // twice round, and open rings that come back over their start
        assert!(!is_simple_ring(o, &flat(12, 2.0 * turn, true), true));
        assert!(!is_simple_ring(o, &flat(9, 1.03 * turn, false), false));
        assert!(!is_simple_ring(o, &flat(9, turn, false), false));
        // a sector turned over
        let mut folded = flat(6, turn, true);
        folded.swap(2, 3);
        assert!(!is_simple_ring(o, &folded, true));
        // the same fans as the remesher hands them over, in any order
        for (ring, closed, simple) in [
            (flat(6, turn, true), true, true),
            (flat(7, 0.97 * turn, false), false, true),
            (flat(12, 2.0 * turn, true), true, false),
            (folded, true, false),
        ] {
            let mut tris = fan_tris(o, &ring, closed);
            tris.rotate_left(2);
            tris.swap(0, 1);
            assert_eq!(is_simple_fan(&tris), simple);
        }
    }

    /// Quantized boxes hold the boxes they stand for, so that two boxes that
    /// meet (touching included) meet quantized, in the frame, beyond it
    /// (clamped) and at its corner (rounding in the products).
    #[test]
    fn quantized_boxes_are_outward() {
        let mut rng = Rng(0x09b0_c5e5);
        let (lo, ext) = (DVec3::new(-3.7, 10.1, 250.3), DVec3::new(180.0, 90.0, 3.0));
        let q = Quantizer::over(lo, ext);
        let back = |u: u16, k: usize| lo[k] + f64::from(u) / q.inv;
        let (mut met, mut apart) = (0, 0);
        for case in 0..50_000 {
            let point = |rng: &mut Rng| {
                // inside, around and beyond the frame, and on grid lines
                let t = DVec3::new(rng.next(), rng.next(), rng.next()) * 1.4 - DVec3::splat(0.2);
                let p = lo + t * ext.max_element();
                if case % 5 == 0 {
                    (p * 8.0).round() / 8.0
                } else {
                    p
                }
            };
            let a = point(&mut rng);
            let b = a + DVec3::new(rng.next(), rng.next(), rng.next())
                * [0.0, 0.01, 1.0, 40.0][rng.below(4)];
            let qa = q.qbox((a.min(b), a.max(b)));
            for k in 0..3 {
                let (l, h) = (a.min(b)[k], a.max(b)[k]);
                assert!(
                    qa.lo[k] == 0 || back(qa.lo[k], k) <= l,
                    "{k}: {qa:?} {a} {b}"
                );
                assert!(
                    qa.hi[k] == u16::MAX || back(qa.hi[k], k) >= h,
                    "{k}: {qa:?} {a} {b}"
                );
            }
            // a box touching the first along one axis, overlapping along the others
            let axis = rng.below(3);
            let mut c = a.min(b);
            c[axis] = a.max(b)[axis];
            let d = c + DVec3::new(rng.next(), rng.next(), rng.next());
            assert!(
                q.qbox((c, d)).overlaps(&qa),
                "touching boxes meet quantized"
            );
            // and one well apart
            let mut e = a.max(b) + DVec3::splat(1.0);
            e[axis] = a.min(b)[axis];
            if !q.qbox((e, e + DVec3::splat(0.5))).overlaps(&qa) {
                apart += 1;
            } else {
                met += 1;
            }
        }
        // the filter is selective, not only safe (boxes apart beyond the
        // frame's border may meet there)
        assert!(apart > 10 * met, "{apart} apart, {met} met");
    }

    /// The branch-free test of items against a query box answers as the
    /// comparisons do, at the ends of the 16-bit range and on touching
    /// faces too, whatever the item's id (which shares the register).
    #[test]
    fn query_boxes_meet_items_as_boxes_overlap() {
        let mut rng = Rng(0x0b0c_5e55);
        // coordinates from a few values, so that equal ones are common
        let values = [0u16, 1, 2, 3, 100, 101, 32_767, 32_768, 65_534, u16::MAX];
        let value = |rng: &mut Rng| values[rng.below(values.len())];
        let qbox = |rng: &mut Rng| {
            let (mut lo, mut hi) = ([0u16; 3], [0u16; 3]);
            for k in 0..3 {
                let (x, y) = (value(rng), value(rng));
                (lo[k], hi[k]) = (x.min(y), x.max(y));
            }
            QBox { lo, hi }
        };
        let (mut met, mut apart) = (0, 0);
        for _ in 0..200_000 {
            let (q, b) = (qbox(&mut rng), qbox(&mut rng));
            let e = [0, 1, 0xffff, 0x8000_0000, u32::MAX][rng.below(5)];
            let meets = QueryBox::new(q).meets(&Item { b, e });
            assert_eq!(meets, b.overlaps(&q), "{q:?} {b:?} {e}");
            if meets {
                met += 1;
            } else {
                apart += 1;
            }
        }
        assert!(met > 1000 && apart > 1000, "{met} met, {apart} apart");
    }

    /// Whatever the ring, a fan called simple has no two triangles that
    /// cross (beyond their shared apex and edges).
    #[test]
    fn simple_fans_do_not_cross() {
        let mut rng = Rng(0x5eed_fa45);
        let (mut simple, mut not) = (0, 0);
        for case in 0..20_000 {
            let n = 3 + rng.below(9);
            let closed = case % 2 == 0;
            // angles mostly increasing, sometimes past one turn or back
            let mut a = 0.0;
            let mut angles = Vec::with_capacity(n);
            let step = std::f64::consts::TAU / n as f64 * (0.6 + 0.8 * rng.next());
            for _ in 0..n {
                angles.push(a);
                a += step * (rng.next() * 2.0 - 0.3);
            }
            let radii: Vec<f64> = (0..n).map(|_| 0.2 + rng.next()).collect();
            let bumps = [0.0, 0.3, 1.5, 6.0][rng.below(4)];
            let heights: Vec<f64> = (0..n).map(|_| bumps * (rng.next() - 0.5)).collect();
            let ring = ring_at(&angles, &radii, &heights);
            let apex = DVec3::new(0.0, 0.0, bumps * (rng.next() - 0.5));
            if !is_simple_ring(apex, &ring, closed) {
                not += 1;
                continue;
            }
            simple += 1;
            let tris = fan_tris(apex, &ring, closed);
            assert!(
                is_simple_fan(&tris),
                "case {case}: the fan of a simple ring"
            );
            for (i, s) in tris.iter().enumerate() {
                for t in &tris[i + 1..] {
                    assert!(
                        !triangles_cross(&s.p, &s.k, &t.p, &t.k),
                        "case {case}: a simple fan's triangles cross"
                    );
                }
            }
        }
        // both answers are common, so the test shows something
        assert!(simple > 2_000 && not > 2_000, "{simple} simple, {not} not");
    }
}
