//! The marching table of VESTA iso-surfaces: for every configuration of a
//! 2×2×2 voxel cell, its N-cycles, their L triangulations and their types.
//!
//! A configuration is the 8-bit mask of active cells around a grid vertex (see
//! [`crate::star`]) plus, for VESTA's mixed mode, the 6-bit set of ambiguous
//! half-edges at which the two diagonal active cells are joined. The table has
//! one [`CellEntry`] per (mask, connect) pair; connect bits on edges that are not
//! ambiguous are ignored, so the global modes use connect = 0 (disconnect) and
//! connect = 0x3f (connect).
//!
//! **Cycle types.** Two cycles have the same type when a rotation of the cell
//! (one of the 24 proper symmetries of the cube) maps the polygon of one's
//! support points onto the other's, traversed in either direction. Mirror
//! images count as different types, as in the paper's figures (one 6-cycle and
//! one 8-cycle type are mirror images of another). Mixed mode decides each
//! ambiguous edge by the mean of its four voxels, and not every combination of
//! decisions can arise that way: around a vertex the means of the edges `+a`
//! and `−a` always add up to twice the mean of all eight voxels, so joining at
//! both ends of one axis and at neither end of another is impossible (18 of
//! the 64 combinations of the two checkerboard masks). Over all realizable
//! configurations there are exactly the paper's 14 types: N = 3, 4, 4, 5, 6, 6,
//! 6, 6, 7 in the global modes, and 8, 8, 8, 9, 12 only in mixed mode (see
//! [`cycle_types`]). The unrealizable configurations are in the table too (for
//! completeness) but their cycles have no listed type.
//!
//! **L triangulation.** Each cycle is cut into N − 2 triangles on its own points
//! (no extra point): the minimum-area triangulation of the cycle's undisplaced
//! support points (the face centres) among those whose triangles do not
//! intersect each other and that respect how the two ends of an ambiguous
//! edge share the diagonals between its four faces (see `l_triangles`). Ties
//! (planar cycles) go to the lowest split index, so the table is
//! deterministic. Unit tests prove the result intersection-free: every cell
//! alone and every two neighbouring cells, for every configuration mixed mode
//! can produce.

use std::sync::OnceLock;

use glam::DVec3;

use crate::geom::predicates::is_degenerate;
use crate::star::{
    MAX_CYCLE, ambiguous_edges, edge_star, face_axis, face_center_offset, trace_per_edge,
};

/// Type id of cycles that only unrealizable mixed configurations produce.
pub(crate) const NO_TYPE: u8 = u8::MAX;

/// Most triangles one configuration produces (12 faces in one cycle → 10).
pub(crate) const MAX_TRIS: usize = 10;

/// One configuration: its cycles (as quarter-face ids) and their L triangles.
/// One cache line each.
#[derive(Clone, Copy, Debug, Default)]
#[repr(align(64))]
pub(crate) struct CellEntry {
    /// Quarter-face ids of all cycles, concatenated, in cycle order.
    pub faces: [u8; MAX_CYCLE],
    /// `ends[i]`: one past the last face of cycle `i`.
    pub ends: [u8; 4],
    /// Number of cycles.
    pub cycles: u8,
    /// Type id of each cycle (index into [`cycle_types`]; [`NO_TYPE`] for
    /// cycles of unrealizable mixed configurations).
    pub types: [u8; 4],
    /// L triangles as quarter-face ids, cycle after cycle.
    pub tris: [[u8; 3]; MAX_TRIS],
    /// `tri_ends[i]`: one past the last triangle of cycle `i`.
    pub tri_ends: [u8; 4],
}

impl CellEntry {
    /// Faces of cycle `i`.
    #[inline(always)]
    pub fn cycle(&self, i: usize) -> &[u8] {
        let start = if i == 0 { 0 } else { self.ends[i - 1] as usize };
        &self.faces[start..self.ends[i] as usize]
    }

    /// L triangles of cycle `i`.
    #[inline(always)]
    pub fn cycle_tris(&self, i: usize) -> &[[u8; 3]] {
        let start = if i == 0 {
            0
        } else {
            self.tri_ends[i - 1] as usize
        };
        &self.tris[start..self.tri_ends[i] as usize]
    }

    /// Number of boundary quarter-faces.
    #[cfg(test)]
    pub fn face_count(&self) -> usize {
        if self.cycles == 0 {
            0
        } else {
            self.ends[self.cycles as usize - 1] as usize
        }
    }

    /// All L triangles.
    #[inline(always)]
    pub fn all_tris(&self) -> &[[u8; 3]] {
        let n = if self.cycles == 0 {
            0
        } else {
            self.tri_ends[self.cycles as usize - 1] as usize
        };
        &self.tris[..n]
    }
}

/// One of VESTA's 14 cycle types.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct CycleType {
    /// Short name: the length, and a letter where several types share it ("6b").
    pub name: String,
    /// Number of support points N.
    pub length: usize,
    /// Whether the undisplaced support points lie in one plane.
    pub planar: bool,
    /// Whether the type occurs in the global connect / disconnect modes (the
    /// other types need mixed mode).
    pub global: bool,
    /// A configuration producing it: active-cell mask around the vertex (bit 0 =
    /// +x cell, bit 1 = +y, bit 2 = +z) and the half-edges joined in mixed mode.
    pub example_mask: u8,
    pub example_connect: u8,
}

/// The marching table and the type list, built once.
pub(crate) struct Table {
    entries: Vec<CellEntry>,
    types: Vec<CycleType>,
    /// [`ambiguous_edges`] of every mask (the march asks for each vertex).
    ambiguous: [u8; 256],
}

impl Table {
    /// The table (built on first use, a few milliseconds).
    pub(crate) fn get() -> &'static Table {
        static T: OnceLock<Table> = OnceLock::new();
        T.get_or_init(build)
    }

    /// Entry of a mask with the given joined half-edges.
    #[inline(always)]
    pub(crate) fn entry(&self, mask: u8, connect: u8) -> &CellEntry {
        &self.entries[((connect & 0x3f) as usize) << 8 | mask as usize]
    }

    pub(crate) fn types(&self) -> &[CycleType] {
        &self.types
    }

    /// The ambiguous half-edges of a mask, as [`ambiguous_edges`].
    #[inline(always)]
    pub(crate) fn ambiguous(&self, mask: u8) -> u8 {
        self.ambiguous[mask as usize]
    }
}

/// VESTA's cycle types, ordered by length (see the module docs for the
/// definition of a type).
pub fn cycle_types() -> &'static [CycleType] {
    Table::get().types()
}

/// Undisplaced support point of a quarter-face, in cells, relative to the vertex.
pub(crate) fn face_point(f: usize) -> DVec3 {
    let o = face_center_offset(f);
    DVec3::new(o[0] as f64, o[1] as f64, o[2] as f64) * 0.5
}

/// Canonical form of a cycle: the smallest sequence of face ids over the 24
/// rotations of the cube (which permute the 12 quarter-faces), the choice of
/// start and reversal. Unused entries are `u8::MAX`.
type Canonical = [u8; MAX_CYCLE];

fn canonical(cycle: &[u8]) -> Canonical {
    let n = cycle.len();
    let mut best = [u8::MAX; MAX_CYCLE];
    let mut first = true;
    for rot in rotations() {
        for rev in [false, true] {
            for start in 0..n {
                let mut seq = [u8::MAX; MAX_CYCLE];
                for (k, s) in seq.iter_mut().enumerate().take(n) {
                    let i = if rev {
                        (start + n - k) % n
                    } else {
                        (start + k) % n
                    };
                    *s = rot[cycle[i] as usize];
                }
                if first || seq < best {
                    best = seq;
                    first = false;
                }
            }
        }
    }
    best
}

/// The 24 rotations of the cube as permutations of the quarter-faces.
fn rotations() -> &'static [[u8; 12]] {
    static R: OnceLock<Vec<[u8; 12]>> = OnceLock::new();
    R.get_or_init(|| {
        let perms = [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ];
        // parity of each permutation above: +1 even, −1 odd
        let parity = [1, -1, -1, 1, 1, -1];
        let mut out = Vec::with_capacity(24);
        for (p, par) in perms.into_iter().zip(parity) {
            for signs in 0..8u32 {
                let flips = if signs.count_ones() % 2 == 1 { -1 } else { 1 };
                if par * flips < 0 {
                    continue;
                }
                let mut map = [0u8; 12];
                for (f, m) in map.iter_mut().enumerate() {
                    let c = face_center_offset(f);
                    let r = [0, 1, 2].map(|a| {
                        if signs >> a & 1 == 1 {
                            -c[p[a]]
                        } else {
                            c[p[a]]
                        }
                    });
                    *m = (0..12)
                        .find(|&g| face_center_offset(g) == r)
                        .expect("rotations map faces to faces") as u8;
                }
                out.push(map);
            }
        }
        out
    })
}

/// Whether mixed mode can produce this choice of joined edges: the means of
/// the edges `+a` and `−a` sum to twice the mean of the cell, so one axis with
/// both ends joined and another with neither end joined contradict each other.
pub(crate) fn realizable(mask: u8, connect: u8) -> bool {
    let amb = ambiguous_edges(mask);
    let connect = connect & amb;
    let (mut both, mut neither) = (false, false);
    for a in 0..3 {
        let pair = 0b11 << (2 * a);
        if amb & pair == pair {
            both |= connect & pair == pair;
            neither |= connect & pair == 0;
        }
    }
    !(both && neither)
}

fn is_planar(cycle: &[u8]) -> bool {
    let p: Vec<DVec3> = cycle.iter().map(|&f| face_point(f as usize)).collect();
    let n = (p[1] - p[0]).cross(p[2] - p[0]);
    p.iter().all(|q| (*q - p[0]).dot(n).abs() < 1e-12)
}

/// L triangles of one cycle (as quarter-face ids) at a vertex with the given
/// ambiguous half-edges.
///
/// Two things can make a triangulation of a cell cycle intersect the surface:
///
/// - **Its own triangles.** The long cycles of mixed mode (8, 9 and 12 points)
///   are far from planar, and the minimum-area triangulation of a skew polygon
///   can fold over itself: for the 9-cycle of three cells that pairwise share
///   an edge (two of the three edges joined), the minimum-area triangulation
///   has two pairs of crossing triangles. So the triangulation is the
///   minimum-area one *among those whose triangles do not intersect each
///   other* (see `min_area_embedded`).
/// - **The triangles of the other end of an ambiguous edge.** The four faces
///   around an ambiguous edge lie in the stars of both ends of the edge, and a
///   cycle at either end may pass through all four (always when the edge is
///   joined; when it is separated, if the two voxels meet elsewhere in the
///   cell). If both ends used the same diagonal between two of them, it would
///   carry four triangles; if both ends had a triangle on three of them (they
///   are coplanar), the two would overlap. So:
///   1. preferably a cycle uses no diagonal between two faces of an ambiguous
///      edge at all. Then a principal plane through the voxel centres cuts the
///      surface exactly in the DICONEX contours of that slice (the segments in
///      the plane are cycle sides). Every cycle of the global modes, and every
///      mixed cycle up to length 7, has such a triangulation;
///   2. otherwise (some 8-, 9- and 12-cycles of mixed mode) the two ends share
///      the six segments: the four sides of the ring around the edge (faces of
///      different axes) belong to the upper end (where the half-edge points to
///      −axis), the two segments across the edge (faces of the same axis) to
///      the lower end. A triangle on three of the faces needs one segment of
///      each kind, so neither end has one, and no segment is used from both
///      ends.
///
/// Every configuration mixed mode can produce is covered by 1 or 2 (unit tests
/// check it, and that no cell and no two neighbouring cells of any realizable
/// configuration intersect); unrealizable ones fall back to the unconstrained
/// minimum.
fn l_triangles(cycle: &[u8], ambiguous: u8) -> Vec<[u8; 3]> {
    let pts: Vec<DVec3> = cycle.iter().map(|&f| face_point(f as usize)).collect();
    let tris = min_area_embedded(&pts, |i, j| chord_allowed(cycle, ambiguous, i, j, false))
        .or_else(|| min_area_embedded(&pts, |i, j| chord_allowed(cycle, ambiguous, i, j, true)))
        .or_else(|| min_area_embedded(&pts, |_, _| true))
        .expect("a cell cycle has an embedded triangulation");
    tris.into_iter().map(|t| t.map(|i| cycle[i])).collect()
}

/// Whether the segment between cycle positions `i` and `j` may be used: a
/// side always; a diagonal unless both faces surround one ambiguous edge
/// (with `shared`, unless the segment belongs to the other end of that edge).
fn chord_allowed(cycle: &[u8], ambiguous: u8, i: usize, j: usize, shared: bool) -> bool {
    let n = cycle.len();
    if (i + 1) % n == j || (j + 1) % n == i {
        return true;
    }
    let (a, b) = (cycle[i] as usize, cycle[j] as usize);
    !(0..6).any(|e| {
        let (_, faces) = edge_star(e);
        if ambiguous >> e & 1 == 0 || !faces.contains(&a) || !faces.contains(&b) {
            return false;
        }
        let across = face_axis(a) == face_axis(b);
        let lower_end = e & 1 == 1;
        !shared || across != lower_end
    })
}

/// Whether triangle `t` intersects one of `tris` (beyond what they share).
fn hits_any(p: &[DVec3], tris: &[[usize; 3]], t: [usize; 3]) -> bool {
    let t = t.map(|v| v as u32);
    tris.iter()
        .any(|s| crate::geom::predicates::triangles_intersect(p, s.map(|v| v as u32), t))
}

/// Whether two triangles of one triangulation intersect.
fn folds(p: &[DVec3], tris: &[[usize; 3]]) -> bool {
    (1..tris.len()).any(|k| hits_any(p, &tris[..k], tris[k]))
}

/// Minimum areas of the sub-polygons `i..=j` (closed by the chord `i j`)
/// triangulated without degenerate triangles and with allowed diagonals only
/// (infinite if impossible), and the apex of the best triangle on each chord
/// (ties go to the lowest apex).
struct AreaTable {
    n: usize,
    cost: Vec<f64>,
    split: Vec<usize>,
}

impl AreaTable {
    fn new(p: &[DVec3], allowed: &impl Fn(usize, usize) -> bool) -> Self {
        let n = p.len();
        let mut cost = vec![f64::INFINITY; n * n];
        let mut split = vec![usize::MAX; n * n];
        for i in 0..n - 1 {
            cost[i * n + i + 1] = 0.0;
        }
        for len in 2..n {
            for i in 0..n - len {
                let j = i + len;
                if !allowed(i, j) {
                    continue;
                }
                for k in i + 1..j {
                    if is_degenerate(p[i], p[k], p[j]) {
                        continue;
                    }
                    let c = cost[i * n + k] + cost[k * n + j] + tri_area(p, [i, k, j]);
                    if c < cost[i * n + j] - 1e-12 {
                        cost[i * n + j] = c;
                        split[i * n + j] = k;
                    }
                }
            }
        }
        AreaTable { n, cost, split }
    }

    #[inline]
    fn cost(&self, i: usize, j: usize) -> f64 {
        self.cost[i * self.n + j]
    }

    /// The minimum triangulation of the whole polygon, if there is one.
    fn best(&self) -> Option<Vec<[usize; 3]>> {
        let n = self.n;
        if !self.cost(0, n - 1).is_finite() {
            return None;
        }
        let mut out = Vec::with_capacity(n - 2);
        let mut stack = vec![(0, n - 1)];
        while let Some((i, j)) = stack.pop() {
            if j - i < 2 {
                continue;
            }
            let k = self.split[i * n + j];
            out.push([i, k, j]);
            stack.push((i, k));
            stack.push((k, j));
        }
        Some(out)
    }
}

fn tri_area(p: &[DVec3], [a, b, c]: [usize; 3]) -> f64 {
    0.5 * (p[b] - p[a]).cross(p[c] - p[a]).length()
}

/// The minimum-area triangulation of a closed polygon whose triangles are not
/// degenerate, use only allowed diagonals and do not intersect each other
/// (sorted triangles of polygon positions); `None` if there is none.
///
/// The dynamic-programming minimum when it is embedded (the common case);
/// otherwise a depth-first branch and bound over all triangulations that
/// rejects a triangle as soon as it hits one already placed and prunes with
/// the dynamic-programming minima of the open sub-polygons (a lower bound).
/// Deterministic: apices are tried in increasing order and only a strictly
/// smaller area replaces the best found.
fn min_area_embedded(
    p: &[DVec3],
    allowed: impl Fn(usize, usize) -> bool,
) -> Option<Vec<[usize; 3]>> {
    let table = AreaTable::new(p, &allowed);
    let mut best = table.best()?;
    if folds(p, &best) {
        let mut search = Search {
            p,
            table: &table,
            best: None,
            best_area: f64::INFINITY,
        };
        let mut tris = Vec::with_capacity(p.len() - 2);
        search.run(&mut vec![(0, p.len() - 1)], &mut tris, 0.0);
        best = search.best?;
    }
    best.sort_unstable();
    Some(best)
}

/// State of the branch and bound of [`min_area_embedded`].
struct Search<'a> {
    p: &'a [DVec3],
    table: &'a AreaTable,
    best: Option<Vec<[usize; 3]>>,
    best_area: f64,
}

impl Search<'_> {
    /// Triangulates the open chords `open` given the placed `tris` of total `area`.
    fn run(&mut self, open: &mut Vec<(usize, usize)>, tris: &mut Vec<[usize; 3]>, area: f64) {
        let bound = area
            + open
                .iter()
                .map(|&(i, j)| self.table.cost(i, j))
                .sum::<f64>();
        if bound >= self.best_area - 1e-12 {
            return;
        }
        let Some((i, j)) = open.pop() else {
            self.best_area = area;
            self.best = Some(tris.clone());
            return;
        };
        for k in i + 1..j {
            let t = [i, k, j];
            // sub-chords must be triangulable (this also checks they are allowed)
            if !self.table.cost(i, k).is_finite()
                || !self.table.cost(k, j).is_finite()
                || is_degenerate(self.p[i], self.p[k], self.p[j])
                || hits_any(self.p, tris, t)
            {
                continue;
            }
            let depth = open.len();
            for (a, b) in [(i, k), (k, j)] {
                if b - a >= 2 {
                    open.push((a, b));
                }
            }
            tris.push(t);
            self.run(open, tris, area + tri_area(self.p, t));
            tris.pop();
            open.truncate(depth);
        }
        open.push((i, j));
    }
}

/// A cycle type while the table is built: length, canonical form, example
/// mask and connect set, planar, seen in a global mode.
type Form = (usize, Canonical, u8, u8, bool, bool);

/// One configuration with its cycles (faces and canonical form).
struct Config {
    mask: u8,
    connect: u8,
    cycles: Vec<(Vec<u8>, Canonical)>,
}

fn build() -> Table {
    let raw = configurations();
    let forms = collect_forms(&raw);
    let types = name_types(&forms);
    let mut canonical_entries = vec![CellEntry::default(); 256 * 64];
    let mut memo = std::collections::HashMap::new();
    for c in &raw {
        canonical_entries[(c.mask as usize) << 6 | c.connect as usize] =
            make_entry(c, &forms, &mut memo);
    }
    // Non-canonical connect sets copy the entry of their ambiguous part. By
    // connect set, then mask: the entries of one connect set (in the global
    // modes, the only ones used) are contiguous.
    let entries = (0..256 * 64)
        .map(|i| {
            let mask = (i & 255) as u8;
            let connect = (i >> 8) as u8 & ambiguous_edges(mask);
            canonical_entries[(mask as usize) << 6 | connect as usize]
        })
        .collect();
    let ambiguous = std::array::from_fn(|m| ambiguous_edges(m as u8));
    Table {
        entries,
        types,
        ambiguous,
    }
}

/// Every mask with every joining set of its ambiguous edges, traced.
fn configurations() -> Vec<Config> {
    let mut forms: std::collections::HashMap<Vec<u8>, Canonical> = Default::default();
    let mut raw = Vec::new();
    for mask in 0..=255u8 {
        let amb = ambiguous_edges(mask);
        for connect in (0..64u8).filter(|c| c & !amb == 0) {
            let star = trace_per_edge(mask, connect);
            let cycles = (0..star.cycles as usize)
                .map(|i| {
                    let c: Vec<u8> = star.cycle(i).iter().map(|s| s.face).collect();
                    let form = *forms.entry(c.clone()).or_insert_with(|| canonical(&c));
                    (c, form)
                })
                .collect();
            raw.push(Config {
                mask,
                connect,
                cycles,
            });
        }
    }
    raw
}

/// The distinct forms of realizable configurations, sorted by length then form.
fn collect_forms(raw: &[Config]) -> Vec<Form> {
    let mut forms: Vec<Form> = Vec::new();
    for cfg in raw.iter().filter(|c| realizable(c.mask, c.connect)) {
        let global = cfg.connect == 0 || cfg.connect == ambiguous_edges(cfg.mask);
        for (c, form) in &cfg.cycles {
            match forms.iter_mut().find(|f| f.1 == *form) {
                Some(f) => f.5 |= global,
                None => forms.push((c.len(), *form, cfg.mask, cfg.connect, is_planar(c), global)),
            }
        }
    }
    forms.sort_by(|a, b| (a.0, &a.1).cmp(&(b.0, &b.1)));
    forms
}

/// Types with names: the length, plus a letter where several share it.
fn name_types(forms: &[Form]) -> Vec<CycleType> {
    forms
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let same: Vec<usize> = (0..forms.len()).filter(|&j| forms[j].0 == f.0).collect();
            let name = if same.len() == 1 {
                f.0.to_string()
            } else {
                let k = same.iter().position(|&j| j == i).unwrap_or(0);
                format!("{}{}", f.0, (b'a' + k as u8) as char)
            };
            CycleType {
                name,
                length: f.0,
                planar: f.4,
                global: f.5,
                example_mask: f.2,
                example_connect: f.3,
            }
        })
        .collect()
}

/// The table entry of one configuration.
/// `memo`: L triangles by cycle and the ambiguous edges it passes (many
/// configurations share cycles).
fn make_entry(
    cfg: &Config,
    forms: &[Form],
    memo: &mut std::collections::HashMap<(Vec<u8>, u8), Vec<[u8; 3]>>,
) -> CellEntry {
    let mut e = CellEntry::default();
    let (mut nf, mut nt) = (0usize, 0usize);
    for (i, (c, form)) in cfg.cycles.iter().enumerate() {
        e.faces[nf..nf + c.len()].copy_from_slice(c);
        nf += c.len();
        e.ends[i] = nf as u8;
        e.types[i] = forms
            .iter()
            .position(|f| f.1 == *form)
            .map_or(NO_TYPE, |t| t as u8);
        // only the ambiguous edges whose faces the cycle meets matter
        let amb = ambiguous_edges(cfg.mask);
        let relevant = (0..6)
            .filter(|&e| {
                amb >> e & 1 == 1 && edge_star(e).1.iter().any(|&f| c.contains(&(f as u8)))
            })
            .fold(0u8, |m, e| m | 1 << e);
        let tris = memo
            .entry((c.clone(), relevant))
            .or_insert_with(|| l_triangles(c, relevant));
        for &t in tris.iter() {
            e.tris[nt] = t;
            nt += 1;
        }
        e.tri_ends[i] = nt as u8;
    }
    e.cycles = cfg.cycles.len() as u8;
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotations_are_the_24_proper_symmetries() {
        let r = rotations();
        let mut distinct = r.to_vec();
        distinct.sort();
        distinct.dedup();
        assert_eq!(distinct.len(), 24);
        for map in r {
            let mut seen = [false; 12];
            for &f in map {
                seen[f as usize] = true;
            }
            assert!(seen.iter().all(|&s| s));
        }
    }

    #[test]
    fn fourteen_types_nine_global() {
        let t = cycle_types();
        let names: Vec<&str> = t.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(t.len(), 14, "{names:?}");
        let lengths: Vec<usize> = t.iter().map(|c| c.length).collect();
        assert_eq!(lengths, [3, 4, 4, 5, 6, 6, 6, 6, 7, 8, 8, 8, 9, 12]);
        let global: Vec<usize> = t.iter().filter(|c| c.global).map(|c| c.length).collect();
        assert_eq!(global, [3, 4, 4, 5, 6, 6, 6, 6, 7]);
        // planar: the triangle, both 4-cycles and one hexagon (the paper's 7.f)
        let planar: Vec<usize> = t.iter().filter(|c| c.planar).map(|c| c.length).collect();
        assert_eq!(planar, [3, 4, 4, 6], "{names:?}");
    }

    /// Every joining pattern the mean rule can produce, by trying all small
    /// integer values (voxel minus iso) with ties included.
    fn realizable_by_search(mask: u8) -> [bool; 64] {
        let amb = ambiguous_edges(mask);
        let mut seen = [false; 64];
        let k = 3u64;
        let active = mask.count_ones();
        let total = (k + 1).pow(active) * k.pow(8 - active);
        for code in 0..total {
            let mut c = code;
            let mut x = [0i64; 8];
            for (o, xo) in x.iter_mut().enumerate() {
                if mask >> o & 1 == 1 {
                    *xo = (c % (k + 1)) as i64;
                    c /= k + 1;
                } else {
                    *xo = -1 - (c % k) as i64;
                    c /= k;
                }
            }
            let mut connect = 0u8;
            for e in 0..6 {
                let (octs, _) = edge_star(e);
                if amb >> e & 1 == 1 && octs.iter().map(|&o| x[o]).sum::<i64>() >= 0 {
                    connect |= 1 << e;
                }
            }
            seen[connect as usize] = true;
        }
        seen
    }

    #[test]
    fn realizability_rule_matches_search() {
        for mask in 0..=255u8 {
            let amb = ambiguous_edges(mask);
            if amb.count_ones() < 2 {
                continue;
            }
            let seen = realizable_by_search(mask);
            for connect in 0..64u8 {
                if connect & !amb == 0 {
                    assert_eq!(
                        realizable(mask, connect),
                        seen[connect as usize],
                        "mask {mask:08b} connect {connect:06b}"
                    );
                }
            }
        }
    }

    /// Segments of a cycle's L triangles between two faces of one ambiguous
    /// edge that are not sides: (across the edge, at the lower end).
    fn tube_chords(c: &[u8], amb: u8) -> Vec<(bool, bool)> {
        let mut out = Vec::new();
        for t in l_triangles(c, amb) {
            for k in 0..3 {
                let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
                let pa = c.iter().position(|&f| f as usize == a).unwrap();
                let pb = c.iter().position(|&f| f as usize == b).unwrap();
                if (pa + 1) % c.len() == pb || (pb + 1) % c.len() == pa {
                    continue;
                }
                for e in (0..6).filter(|e| amb >> e & 1 == 1) {
                    let (_, faces) = edge_star(e);
                    if faces.contains(&a) && faces.contains(&b) {
                        out.push((face_axis(a) == face_axis(b), e & 1 == 1));
                    }
                }
            }
        }
        out
    }

    #[test]
    fn ambiguous_edges_are_respected_by_every_realizable_triangulation() {
        let mut shared = 0;
        for mask in 0..=255u8 {
            let amb = ambiguous_edges(mask);
            for connect in (0..64u8).filter(|&c| c & !amb == 0 && realizable(mask, c)) {
                let star = trace_per_edge(mask, connect);
                for i in 0..star.cycles as usize {
                    let c: Vec<u8> = star.cycle(i).iter().map(|s| s.face).collect();
                    let chords = tube_chords(&c, amb);
                    let what = format!("mask {mask:08b} connect {connect:06b} cycle {c:?}");
                    if c.len() <= 7 {
                        assert!(chords.is_empty(), "{what}");
                    }
                    for (across, lower_end) in chords {
                        assert_eq!(across, lower_end, "{what}");
                        shared += 1;
                    }
                }
            }
        }
        assert!(shared > 0);
    }

    #[test]
    fn entries_cover_every_boundary_face_and_triangulate_fully() {
        let table = Table::get();
        for mask in 0..=255u8 {
            for connect in 0..64u8 {
                let e = table.entry(mask, connect);
                let star = trace_per_edge(mask, connect);
                assert_eq!(e.face_count(), star.face_count as usize);
                for i in 0..e.cycles as usize {
                    assert_eq!(e.cycle_tris(i).len(), e.cycle(i).len() - 2);
                    if realizable(mask, connect) {
                        assert_ne!(e.types[i], NO_TYPE, "mask {mask:08b} connect {connect:06b}");
                    }
                }
            }
        }
    }

    /// Undisplaced triangles of a cell entry at grid vertex `at`, as doubled
    /// integer coordinates of the support points.
    fn cell_tris(e: &CellEntry, at: [i32; 3]) -> Vec<[[i32; 3]; 3]> {
        e.all_tris()
            .iter()
            .map(|t| {
                t.map(|f| {
                    let o = face_center_offset(f as usize);
                    [0, 1, 2].map(|a| 2 * at[a] + o[a])
                })
            })
            .collect()
    }

    /// Problems of a set of triangles: intersections (the library's check) or
    /// an edge used twice in one direction (more than two triangles on it, or
    /// two on one side).
    fn embedding_problem(tris: &[[[i32; 3]; 3]]) -> Option<String> {
        let mut keys: Vec<[i32; 3]> = Vec::new();
        let idx: Vec<[u32; 3]> = tris
            .iter()
            .map(|t| {
                t.map(|k| match keys.iter().position(|x| *x == k) {
                    Some(i) => i as u32,
                    None => {
                        keys.push(k);
                        keys.len() as u32 - 1
                    }
                })
            })
            .collect();
        let pos: Vec<DVec3> = keys
            .iter()
            .map(|k| DVec3::new(k[0] as f64, k[1] as f64, k[2] as f64) * 0.5)
            .collect();
        let hits = crate::geom::intersect::self_intersections(&pos, &idx);
        if !hits.is_empty() {
            return Some(format!("intersecting triangles {hits:?}"));
        }
        let mut directed = std::collections::HashSet::new();
        for t in &idx {
            for k in 0..3 {
                if !directed.insert((t[k], t[(k + 1) % 3])) {
                    return Some(format!("edge {}-{} used twice", t[k], t[(k + 1) % 3]));
                }
            }
        }
        None
    }

    /// Every configuration mixed mode can produce (so every configuration of
    /// the global modes too): the L triangles of one cell never intersect.
    #[test]
    fn every_realizable_cell_is_embedded() {
        let table = Table::get();
        let mut cells = 0;
        for mask in 0..=255u8 {
            let amb = ambiguous_edges(mask);
            for connect in (0..64u8).filter(|&c| c & !amb == 0 && realizable(mask, c)) {
                let e = table.entry(mask, connect);
                if let Some(p) = embedding_problem(&cell_tris(e, [0; 3])) {
                    panic!(
                        "mask {mask:08b} connect {connect:06b}: {p}: {:?}",
                        e.all_tris()
                    );
                }
                cells += 1;
            }
        }
        assert!(cells > 256);
    }

    /// The regression: three voxels pairwise sharing an edge, two of the
    /// edges joined, give a 9-cycle whose minimum-area triangulation folds
    /// over itself (two pairs of crossing triangles); the table must not use it.
    #[test]
    fn the_folding_nine_cycle_is_triangulated_without_folds() {
        let mask = 0b0110_1000; // octants 3, 5, 6
        let mut nines = 0;
        for connect in 0..64u8 {
            let star = trace_per_edge(mask, connect);
            let e = Table::get().entry(mask, connect);
            for i in (0..e.cycles as usize).filter(|&i| e.cycle(i).len() == 9) {
                let c = e.cycle(i);
                let pts: Vec<DVec3> = c.iter().map(|&f| face_point(f as usize)).collect();
                let tris: Vec<[usize; 3]> = e
                    .cycle_tris(i)
                    .iter()
                    .map(|t| t.map(|f| c.iter().position(|&g| g == f).unwrap()))
                    .collect();
                assert!(!folds(&pts, &tris), "connect {connect:06b}: {tris:?}");
                assert_eq!(star.cycle(i).len(), 9);
                nines += 1;
            }
        }
        assert!(nines >= 3);
        // and without the search, the minimum under the sharing rule folds
        // (so the search is what makes the difference)
        let amb = ambiguous_edges(mask);
        let folding = (0..64u8)
            .filter(|&connect| {
                let e = Table::get().entry(mask, connect);
                (0..e.cycles as usize).any(|i| {
                    let c = e.cycle(i);
                    let pts: Vec<DVec3> = c.iter().map(|&f| face_point(f as usize)).collect();
                    let allowed = |a, b| chord_allowed(c, amb, a, b, true);
                    c.len() == 9
                        && AreaTable::new(&pts, &allowed)
                            .best()
                            .is_some_and(|t| folds(&pts, &t))
                })
            })
            .count();
        assert!(folding > 0);
    }

    /// Two neighbouring grid vertices share the four faces around the edge
    /// between them. For every activity pattern of their 2×2×3 cells, along
    /// each axis, and every pair of realizable joining sets that agree on the
    /// shared edge (a superset of what mixed mode produces; both global modes
    /// included), the L triangles of the two cells together are embedded.
    /// With [`every_realizable_cell_is_embedded`] this proves that
    /// undisplaced L surfaces never self-intersect: cells further apart have
    /// disjoint cubes but for one shared support point.
    #[test]
    fn neighbouring_cells_never_intersect() {
        let table = Table::get();
        let mut pairs = 0;
        for axis in 0..3 {
            let (b, c) = crate::star::other_axes(axis);
            let mut off = [0; 3];
            off[axis] = 1;
            for pat in 0..4096u32 {
                // octant `o` of the vertex shifted by `s` along the axis
                let mask_at = |s: usize| -> u8 {
                    (0..8)
                        .filter(|&o| {
                            let x = (o >> axis & 1) + s;
                            pat >> (4 * x + (o >> b & 1) + 2 * (o >> c & 1)) & 1 == 1
                        })
                        .fold(0u8, |m, o| m | 1 << o)
                };
                let (ma, mb) = (mask_at(0), mask_at(1));
                let (aa, ab) = (ambiguous_edges(ma), ambiguous_edges(mb));
                let (ea, eb) = (2 * axis + 1, 2 * axis);
                for ca in (0..64u8).filter(|&x| x & !aa == 0 && realizable(ma, x)) {
                    for cb in (0..64u8).filter(|&x| x & !ab == 0 && realizable(mb, x)) {
                        if aa >> ea & 1 == 1 && (ca >> ea & 1) != (cb >> eb & 1) {
                            continue;
                        }
                        let mut tris = cell_tris(table.entry(ma, ca), [0; 3]);
                        tris.extend(cell_tris(table.entry(mb, cb), off));
                        if let Some(p) = embedding_problem(&tris) {
                            panic!(
                                "axis {axis}: mask {ma:08b} connect {ca:06b} next to \
                                 mask {mb:08b} connect {cb:06b}: {p}"
                            );
                        }
                        pairs += 1;
                    }
                }
            }
        }
        assert!(pairs > 3 * 4096);
    }
}
