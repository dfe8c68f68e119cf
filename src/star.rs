//! The star of a grid vertex: its 8 octant cells, 12 quarter-faces and 6
//! half-edges, and the boundary cycles of a label around it.
//!
//! Both the preprocessing (is this vertex critical?) and the extraction (which
//! polygon does this vertex contribute?) look at a grid vertex `g` through the
//! labels of the 8 cells that share it. For one label, an 8-bit *mask* says which
//! of those cells hold it. The faces of the label's region incident to `g` form
//! zero, one or several closed cycles around `g`; the vertex is *manifold* for the
//! label when they form exactly one cycle and no edge at `g` carries four of them.
//!
//! Conventions (used everywhere in septa):
//! - octant `o` in `0..8`: bit 0 set = the cell on the +x side of `g`, bit 1 = +y,
//!   bit 2 = +z;
//! - half-edge `e` in `0..6`: `2 * axis + (1 if positive)`, so 0 = −x, 1 = +x,
//!   2 = −y, 3 = +y, 4 = −z, 5 = +z;
//! - quarter-face `f` in `0..12`: `4 * a + sb + 2 * sc`, the face perpendicular to
//!   axis `a` spanning the two other axes `b < c` on sides `sb`, `sc` (0 = −, 1 = +);
//!   it separates octants `o` and `o | (1 << a)` where `o` has bit `a` clear.
//!
//! A cycle is listed in the order that makes it counter-clockwise seen from outside
//! the label (right-hand rule gives the outward normal): each face is entered
//! through one of its two half-edges and left through the other.

/// Maximum number of quarter-faces in one cycle (all 12 in the worst case).
pub const MAX_CYCLE: usize = 12;

/// The two axes other than `a`, ascending.
#[inline]
pub const fn other_axes(a: usize) -> (usize, usize) {
    match a {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// Quarter-face id from its normal axis and the sides along the other two axes.
#[inline]
pub const fn face_id(a: usize, sb: usize, sc: usize) -> usize {
    4 * a + sb + 2 * sc
}

/// Normal axis of a quarter-face.
#[inline]
pub const fn face_axis(f: usize) -> usize {
    f / 4
}

/// The two octants a quarter-face separates: (the one on the − side of its axis,
/// the one on the + side).
#[inline]
pub const fn face_octants(f: usize) -> (usize, usize) {
    let a = f / 4;
    let (b, c) = other_axes(a);
    let sb = f & 1;
    let sc = (f >> 1) & 1;
    let lo = (sb << b) | (sc << c);
    (lo, lo | (1 << a))
}

/// The two half-edges of a quarter-face (along its first, then its second in-plane axis).
#[inline]
pub const fn face_edges(f: usize) -> (usize, usize) {
    let a = f / 4;
    let (b, c) = other_axes(a);
    (2 * b + (f & 1), 2 * c + ((f >> 1) & 1))
}

/// Unit vector of a half-edge.
#[inline]
pub const fn edge_dir(e: usize) -> [i32; 3] {
    let mut d = [0; 3];
    d[e / 2] = if e & 1 == 1 { 1 } else { -1 };
    d
}

/// Offset of a quarter-face's centre from `g`, in half cells (each entry −1, 0, 1).
#[inline]
pub const fn face_center_offset(f: usize) -> [i32; 3] {
    let (e1, e2) = face_edges(f);
    let d1 = edge_dir(e1);
    let d2 = edge_dir(e2);
    [d1[0] + d2[0], d1[1] + d2[1], d1[2] + d2[2]]
}

/// The four octants around a half-edge, and the four quarter-faces around it.
pub fn edge_star(e: usize) -> ([usize; 4], [usize; 4]) {
    let axis = e / 2;
    let side = e & 1;
    let (b, c) = other_axes(axis);
    let mut octants = [0; 4];
    let mut k = 0;
    for sc in 0..2 {
        for sb in 0..2 {
            octants[k] = (side << axis) | (sb << b) | (sc << c);
            k += 1;
        }
    }
    // Faces around the edge lie in planes perpendicular to b or to c and contain e.
    let mut faces = [0; 4];
    let mut k = 0;
    for a in [b, c] {
        let (p, _) = other_axes(a);
        for s in 0..2 {
            // sides along (p, q): the edge's axis is one of them, with `side`
            let (sp, sq) = if p == axis { (side, s) } else { (s, side) };
            faces[k] = face_id(a, sp, sq);
            k += 1;
        }
    }
    (octants, faces)
}

/// One step of a cycle: the quarter-face and the half-edges it is entered and left by.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct CycleStep {
    pub face: u8,
    pub in_edge: u8,
    pub out_edge: u8,
}

/// The boundary of one label around a vertex, for one mask.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MaskStar {
    /// Number of boundary quarter-faces.
    pub face_count: u8,
    /// Number of closed cycles (0 for an empty or full mask).
    pub cycles: u8,
    /// Whether some half-edge carries four boundary faces (a critical edge).
    pub has_critical_edge: bool,
    /// Steps of all cycles, concatenated; `cycle_ends[i]` is one past cycle i's last step.
    pub steps: [CycleStep; MAX_CYCLE],
    pub cycle_ends: [u8; 4],
}

impl MaskStar {
    /// The vertex is a manifold point of the label's boundary (or not on it).
    #[inline]
    pub fn is_manifold(&self) -> bool {
        !self.has_critical_edge && self.cycles <= 1
    }

    /// Steps of cycle `i`.
    pub fn cycle(&self, i: usize) -> &[CycleStep] {
        let start = if i == 0 {
            0
        } else {
            self.cycle_ends[i - 1] as usize
        };
        &self.steps[start..self.cycle_ends[i] as usize]
    }
}

/// How two diagonal cells of a label at a critical edge are linked when tracing
/// cycles: kept apart (VESTA's "disconnect") or joined ("connect").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ambiguity {
    Disconnect,
    Connect,
}

/// Outward normal sign of a boundary face for a mask: +1 when the label is on the
/// − side (normal points toward +axis), −1 otherwise.
#[inline]
fn outward_sign(mask: u8, f: usize) -> i32 {
    let (lo, _) = face_octants(f);
    if mask >> lo & 1 == 1 { 1 } else { -1 }
}

/// Entering and leaving half-edges of a boundary face, so that the walk is
/// counter-clockwise about the outward normal.
fn face_in_out(mask: u8, f: usize) -> (usize, usize) {
    let (e1, e2) = face_edges(f);
    let d1 = edge_dir(e1);
    let d2 = edge_dir(e2);
    let cross = [
        d1[1] * d2[2] - d1[2] * d2[1],
        d1[2] * d2[0] - d1[0] * d2[2],
        d1[0] * d2[1] - d1[1] * d2[0],
    ];
    let a = face_axis(f);
    if cross[a] * outward_sign(mask, f) > 0 {
        (e1, e2)
    } else {
        (e2, e1)
    }
}

fn is_boundary(mask: u8, f: usize) -> bool {
    let (lo, hi) = face_octants(f);
    (mask >> lo & 1) != (mask >> hi & 1)
}

/// The boundary face entered through half-edge `e` after leaving `from` through it.
fn next_face(mask: u8, from: usize, e: usize, ambiguity: Ambiguity) -> usize {
    let (_, faces) = edge_star(e);
    let boundary: Vec<usize> = faces
        .iter()
        .copied()
        .filter(|&f| f != from && is_boundary(mask, f))
        .collect();
    if boundary.len() == 1 {
        return boundary[0];
    }
    // Four boundary faces at e: two diagonal cells of the label. The candidate
    // that enters through e is one that bounds the same cell as `from`
    // (disconnect) or the other cell (connect).
    let cell_of = |f: usize| {
        let (lo, hi) = face_octants(f);
        if mask >> lo & 1 == 1 { lo } else { hi }
    };
    let from_cell = cell_of(from);
    let candidates: Vec<usize> = boundary
        .into_iter()
        .filter(|&f| face_in_out(mask, f).0 == e)
        .collect();
    let same = candidates
        .iter()
        .copied()
        .find(|&f| cell_of(f) == from_cell);
    let other = candidates
        .iter()
        .copied()
        .find(|&f| cell_of(f) != from_cell);
    match ambiguity {
        Ambiguity::Disconnect => same.or(other),
        Ambiguity::Connect => other.or(same),
    }
    .expect("a boundary face continues the walk")
}

/// Traces the boundary cycles of `mask` around a vertex.
pub fn trace(mask: u8, ambiguity: Ambiguity) -> MaskStar {
    let mut star = MaskStar {
        face_count: 0,
        cycles: 0,
        has_critical_edge: false,
        steps: [CycleStep::default(); MAX_CYCLE],
        cycle_ends: [0; 4],
    };
    let mut used = [false; 12];
    for f in 0..12 {
        if is_boundary(mask, f) {
            star.face_count += 1;
        }
    }
    for e in 0..6 {
        let (_, faces) = edge_star(e);
        if faces.iter().filter(|&&f| is_boundary(mask, f)).count() == 4 {
            star.has_critical_edge = true;
        }
    }
    let mut n = 0;
    for start in 0..12 {
        if used[start] || !is_boundary(mask, start) {
            continue;
        }
        let mut f = start;
        loop {
            used[f] = true;
            let (i, o) = face_in_out(mask, f);
            star.steps[n] = CycleStep {
                face: f as u8,
                in_edge: i as u8,
                out_edge: o as u8,
            };
            n += 1;
            f = next_face(mask, f, o, ambiguity);
            if f == start {
                break;
            }
        }
        star.cycle_ends[star.cycles as usize] = n as u8;
        star.cycles += 1;
    }
    star
}

/// Precomputed [`MaskStar`] for all 256 masks, for one ambiguity rule.
pub struct StarTable {
    entries: Vec<MaskStar>,
}

impl StarTable {
    fn build(ambiguity: Ambiguity) -> Self {
        StarTable {
            entries: (0..=255u8).map(|m| trace(m, ambiguity)).collect(),
        }
    }

    /// The table with diagonal cells kept apart (used after preprocessing, where
    /// no label has a critical edge and the rule never matters).
    pub fn disconnect() -> &'static StarTable {
        static T: std::sync::OnceLock<StarTable> = std::sync::OnceLock::new();
        T.get_or_init(|| StarTable::build(Ambiguity::Disconnect))
    }

    /// The table with diagonal cells joined.
    pub fn connect() -> &'static StarTable {
        static T: std::sync::OnceLock<StarTable> = std::sync::OnceLock::new();
        T.get_or_init(|| StarTable::build(Ambiguity::Connect))
    }

    /// The entry of a mask.
    #[inline]
    pub fn get(&self, mask: u8) -> &MaskStar {
        &self.entries[mask as usize]
    }
}

/// 256-bit set of masks that are critical (not manifold) for their label.
pub fn critical_mask_bits() -> &'static [u64; 4] {
    static T: std::sync::OnceLock<[u64; 4]> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        let mut bits = [0u64; 4];
        let table = StarTable::disconnect();
        for m in 0..256usize {
            if !table.get(m as u8).is_manifold() {
                bits[m / 64] |= 1 << (m % 64);
            }
        }
        bits
    })
}

/// Whether a label with this octant mask is critical at the vertex.
#[inline]
pub fn is_critical_mask(mask: u8) -> bool {
    let bits = critical_mask_bits();
    bits[(mask >> 6) as usize] >> (mask & 63) & 1 == 1
}

/// Half-edges at `g` where the mask's boundary has four faces (two diagonal
/// cells of the mask around the edge: VESTA's points of ambiguity), as a 6-bit
/// set (bit `e` for half-edge `e`).
pub fn ambiguous_edges(mask: u8) -> u8 {
    let mut bits = 0;
    for e in 0..6 {
        let (octs, _) = edge_star(e);
        // octants come as (sb, sc) = (0,0), (1,0), (0,1), (1,1): diagonals 0–3 and 1–2
        let m = octs.map(|o| mask >> o & 1);
        if m[0] == m[3] && m[1] == m[2] && m[0] != m[1] {
            bits |= 1 << e;
        }
    }
    bits
}

/// Like [`next_face`], with the ambiguity rule given for this half-edge only.
fn next_face_at(mask: u8, from: usize, e: usize, connect: bool) -> usize {
    let (_, faces) = edge_star(e);
    let cell_of = |f: usize| {
        let (lo, hi) = face_octants(f);
        if mask >> lo & 1 == 1 { lo } else { hi }
    };
    let from_cell = cell_of(from);
    let (mut count, mut only) = (0, from);
    let (mut same, mut other) = (None, None);
    for &f in &faces {
        if f == from || !is_boundary(mask, f) {
            continue;
        }
        count += 1;
        only = f;
        if face_in_out(mask, f).0 == e {
            if cell_of(f) == from_cell {
                same = Some(f);
            } else {
                other = Some(f);
            }
        }
    }
    if count == 1 {
        return only;
    }
    let pick = if connect {
        other.or(same)
    } else {
        same.or(other)
    };
    pick.expect("a boundary face continues the walk")
}

/// Traces the boundary cycles of `mask` around a vertex with a choice per
/// half-edge: at a point of ambiguity on half-edge `e` the two diagonal cells
/// are joined when bit `e` of `connect` is set and kept apart otherwise (VESTA's
/// "mixed" mode). Bits of edges that are not ambiguous do not matter, so
/// `trace_per_edge(m, 0) == trace(m, Disconnect)` and
/// `trace_per_edge(m, 0x3f) == trace(m, Connect)`.
pub fn trace_per_edge(mask: u8, connect: u8) -> MaskStar {
    let mut star = MaskStar {
        face_count: 0,
        cycles: 0,
        has_critical_edge: ambiguous_edges(mask) != 0,
        steps: [CycleStep::default(); MAX_CYCLE],
        cycle_ends: [0; 4],
    };
    let mut used = [false; 12];
    star.face_count = (0..12).filter(|&f| is_boundary(mask, f)).count() as u8;
    let mut n = 0;
    for start in 0..12 {
        if used[start] || !is_boundary(mask, start) {
            continue;
        }
        let mut f = start;
        loop {
            used[f] = true;
            let (i, o) = face_in_out(mask, f);
            star.steps[n] = CycleStep {
                face: f as u8,
                in_edge: i as u8,
                out_edge: o as u8,
            };
            n += 1;
            f = next_face_at(mask, f, o, connect >> o & 1 == 1);
            if f == start {
                break;
            }
        }
        star.cycle_ends[star.cycles as usize] = n as u8;
        star.cycles += 1;
    }
    star
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn face_tables_are_consistent() {
        for f in 0..12 {
            let (lo, hi) = face_octants(f);
            assert_eq!(lo ^ hi, 1 << face_axis(f));
            let (e1, e2) = face_edges(f);
            assert_ne!(e1 / 2, e2 / 2);
            assert_ne!(e1 / 2, face_axis(f));
            // both octants contain both edges' directions
            for e in [e1, e2] {
                let (octs, faces) = edge_star(e);
                assert!(faces.contains(&f), "face {f} around edge {e}");
                assert!(octs.contains(&lo) && octs.contains(&hi));
            }
        }
        for e in 0..6 {
            let (octs, faces) = edge_star(e);
            let mut o = octs.to_vec();
            o.sort();
            o.dedup();
            assert_eq!(o.len(), 4);
            let mut f = faces.to_vec();
            f.sort();
            f.dedup();
            assert_eq!(f.len(), 4);
        }
    }

    #[test]
    fn single_cell_is_a_triangle() {
        for o in 0..8 {
            let s = trace(1 << o, Ambiguity::Disconnect);
            assert_eq!(s.cycles, 1);
            assert_eq!(s.face_count, 3);
            assert!(s.is_manifold());
        }
    }

    #[test]
    fn walks_are_closed_and_oriented() {
        for m in 0..=255u8 {
            for amb in [Ambiguity::Disconnect, Ambiguity::Connect] {
                let s = trace(m, amb);
                let total: usize = (0..s.cycles as usize).map(|i| s.cycle(i).len()).sum();
                assert_eq!(total, s.face_count as usize);
                for i in 0..s.cycles as usize {
                    let c = s.cycle(i);
                    for k in 0..c.len() {
                        assert_eq!(c[k].out_edge, c[(k + 1) % c.len()].in_edge, "mask {m:08b}");
                    }
                    // counter-clockwise about the outward normal: the polygon of face
                    // centres has positive orientation w.r.t. the label's outside.
                    let pts: Vec<[f64; 3]> = c
                        .iter()
                        .map(|st| face_center_offset(st.face as usize).map(|v| v as f64 * 0.5))
                        .collect();
                    let mut n = [0.0; 3];
                    for k in 0..pts.len() {
                        let (p, q) = (pts[k], pts[(k + 1) % pts.len()]);
                        n[0] += p[1] * q[2] - p[2] * q[1];
                        n[1] += p[2] * q[0] - p[0] * q[2];
                        n[2] += p[0] * q[1] - p[1] * q[0];
                    }
                    // outward: away from the centroid of the label's octants
                    let mut inside = [0.0; 3];
                    let mut cnt = 0.0;
                    for o in 0..8 {
                        if m >> o & 1 == 1 {
                            for a in 0..3 {
                                inside[a] += if o >> a & 1 == 1 { 0.5 } else { -0.5 };
                            }
                            cnt += 1.0;
                        }
                    }
                    if cnt > 0.0 && cnt < 8.0 && c.len() >= 3 && s.is_manifold() {
                        let dot: f64 = (0..3).map(|a| n[a] * inside[a]).sum();
                        assert!(dot < 0.0, "mask {m:08b} cycle oriented inward");
                    }
                }
            }
        }
    }

    #[test]
    fn criticality_counts() {
        // Masks up to complement symmetry: the table of manifold masks is closed
        // under complement, and a diagonal pair across the vertex is critical.
        for m in 0..=255u8 {
            assert_eq!(is_critical_mask(m), is_critical_mask(!m), "mask {m:08b}");
        }
        assert!(is_critical_mask(0b1000_0001));
        assert!(is_critical_mask(0b0000_1001)); // diagonal around the z edges
        assert!(!is_critical_mask(0b0000_0011));
        assert!(!is_critical_mask(0));
        assert!(!is_critical_mask(255));
        let n = (0..=255u8).filter(|&m| !is_critical_mask(m)).count();
        // 2 trivial + the manifold configurations of a 2×2×2 block
        assert_eq!(
            n,
            2 + (0..=255u8)
                .filter(|&m| m != 0 && m != 255 && trace(m, Ambiguity::Disconnect).is_manifold())
                .count()
        );
    }

    #[test]
    fn per_edge_trace_matches_global_rules() {
        for m in 0..=255u8 {
            assert_eq!(
                trace_per_edge(m, 0),
                trace(m, Ambiguity::Disconnect),
                "mask {m:08b}"
            );
            assert_eq!(
                trace_per_edge(m, 0x3f),
                trace(m, Ambiguity::Connect),
                "mask {m:08b}"
            );
            assert_eq!(
                ambiguous_edges(m) != 0,
                trace(m, Ambiguity::Disconnect).has_critical_edge
            );
        }
    }

    #[test]
    fn per_edge_trace_is_closed_and_uses_every_face_once() {
        for m in 0..=255u8 {
            let amb = ambiguous_edges(m);
            for connect in 0..64u8 {
                let s = trace_per_edge(m, connect);
                // only ambiguous edges matter
                assert_eq!(s, trace_per_edge(m, connect & amb), "mask {m:08b}");
                let mut seen = [0u8; 12];
                for i in 0..s.cycles as usize {
                    let c = s.cycle(i);
                    assert!(c.len() >= 3, "mask {m:08b} connect {connect:06b}");
                    for k in 0..c.len() {
                        seen[c[k].face as usize] += 1;
                        assert_eq!(c[k].out_edge, c[(k + 1) % c.len()].in_edge);
                    }
                }
                for (f, &n) in seen.iter().enumerate() {
                    assert_eq!(n as usize, is_boundary(m, f) as usize);
                }
            }
        }
    }
}
