//! STEVE's vector-path table (the paper's Table I, which its text does not
//! include) derived from the construction, and the cell tracer that uses it.
//!
//! **The table.** The hypersurface is the dual of the boundary 3-complex of the
//! active toxels, as VESTA's surface is the dual of the boundary faces: a
//! boundary cube becomes a support point (its centre), a boundary square an
//! edge, a grid edge a 2-face (an N-cycle), a grid vertex a 3-cell (a
//! polyhedron). Within a 2⁴ cell a cube octant contains three half-edges, so
//! it takes part in three cycles: around half-edge `h` along axis `d` it links
//! the two connectivity points (squares) it shares with `h`, those spanned by
//! `d` and one of the cube's two other in-plane axes `x < y`. That is one
//! *vector path* (connectivity point → cube centre → connectivity point), three
//! per cube and orientation, 32 × 2 × 3 = 192 in all — eight times VESTA's 24,
//! as the paper notes.
//!
//! Each path's direction comes from a determinant. With `n` the cube's
//! outward normal (from its active toxel to its inactive one, ±e_a), `h` the
//! half-edge's unit vector and `x`, `y` the unit vectors from `g` toward the two
//! squares, the path runs from the `x` square to the `y` square when
//! `det[h, n, x, y] > 0` and the other way otherwise. This is VESTA's rule
//! (`det[n, e1, e2] > 0`: counter-clockwise about the outward normal) with the
//! half-edge prepended. Tests check that it is the only rule of the form
//! "VESTA's direction in the 3-space across `h`, times a sign per axis and
//! half-edge side" under which every polyhedron of every configuration is a
//! consistently oriented closed surface (up to the global sign), that its
//! cycles are exactly those VESTA's own tracer finds in the 3-space across
//! each half-edge, and that the resulting tetrahedra face outward.
//!
//! **Tracing.** Around each half-edge, paths are chained at connectivity
//! points: the successor of a cube is the other boundary cube at its outgoing
//! square whose path starts there. At a point of ambiguity (four boundary
//! cubes: two diagonal active toxels) two successors start there; "disconnect"
//! takes the one bounding the same active toxel, "connect" the other. Cycles
//! that share a cube share an edge, so they belong to one polyhedron; the
//! polyhedra of a cell are the classes of that relation.

use std::sync::OnceLock;

use super::cell::{
    CUBES, HALF_EDGES, SQUARES, active_toxel, cube_axis, cube_half_edges, cube_side, cube_square,
    cube_toxels, is_boundary, other_axes, square_cubes,
};

/// Most cube octants in the cycles of one cell (32 cubes × 3 half-edges).
pub const MAX_CYCLE_CUBES: usize = 96;
/// Most cycles in one cell.
pub const MAX_CYCLES: usize = 32;

/// Determinant of four signed unit axis vectors `(axis, sign)`: the sign of
/// the permutation times the product of the signs; 0 if an axis repeats.
fn axis_det(v: [(usize, i32); 4]) -> i32 {
    let mut perm = v.map(|(a, _)| a);
    for i in 0..4 {
        for j in i + 1..4 {
            if perm[i] == perm[j] {
                return 0;
            }
        }
    }
    let mut sign = v.iter().map(|&(_, s)| s).product::<i32>();
    // parity by selection sort
    for i in 0..4 {
        let m = (i..4).min_by_key(|&k| perm[k]).expect("nonempty");
        if m != i {
            perm.swap(i, m);
            sign = -sign;
        }
    }
    sign
}

/// Derives one vector path: around half-edge `h` of cube `c` whose active
/// toxel is on the + side of its axis (`active_hi`) or the − side, the
/// (from, to) squares. `None` if `c` does not contain `h`.
pub fn derive_path(c: usize, active_hi: bool, h: usize) -> Option<(usize, usize)> {
    let a = cube_axis(c);
    let (d, hs) = (h / 2, h & 1);
    if d == a || cube_side(c, d) != hs {
        return None;
    }
    let others = other_axes(a);
    let mut xy = others.iter().copied().filter(|&o| o != d);
    let (x, y) = (xy.next()?, xy.next()?);
    let sign = |s: usize| if s == 1 { 1 } else { -1 };
    let n = if active_hi { -1 } else { 1 };
    let det = axis_det([
        (d, sign(hs)),
        (a, n),
        (x, sign(cube_side(c, x))),
        (y, sign(cube_side(c, y))),
    ]);
    let (sx, sy) = (cube_square(c, d, x), cube_square(c, d, y));
    Some(if det > 0 { (sx, sy) } else { (sy, sx) })
}

/// One row of the vector-path table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct VectorPath {
    /// Cube (support point) id, `0..32`.
    pub cube: u8,
    /// +1: the active toxel lies on the + side of the cube's axis (the range
    /// vector points toward −); −1: on the − side.
    pub orientation: i8,
    /// Half-edge the path turns around, `0..8`.
    pub half_edge: u8,
    /// Connectivity point (square id `0..24`) the path comes from …
    pub from: u8,
    /// … and goes to, through the cube centre.
    pub to: u8,
}

/// The 192 vector paths: cube by cube, orientation −1 then +1, the cube's
/// three half-edges by ascending axis.
pub fn vector_paths() -> &'static [VectorPath] {
    static T: OnceLock<Vec<VectorPath>> = OnceLock::new();
    T.get_or_init(|| {
        let mut out = Vec::with_capacity(192);
        for c in 0..CUBES {
            for (orientation, active_hi) in [(-1i8, false), (1, true)] {
                for h in cube_half_edges(c) {
                    let (from, to) = derive_path(c, active_hi, h).expect("cube contains h");
                    out.push(VectorPath {
                        cube: c as u8,
                        orientation,
                        half_edge: h as u8,
                        from: from as u8,
                        to: to as u8,
                    });
                }
            }
        }
        out
    })
}

/// `(from, to)` squares by `[cube][active_hi][half-edge]`.
type PathLookup = [[[(u8, u8); HALF_EDGES]; 2]; CUBES];

/// Paths indexed by `[cube][active_hi][half-edge]` → `(from, to)` squares
/// (`u8::MAX` where the cube does not contain the half-edge).
fn path_lookup() -> &'static PathLookup {
    static T: OnceLock<PathLookup> = OnceLock::new();
    T.get_or_init(|| {
        let mut t = [[[(u8::MAX, u8::MAX); HALF_EDGES]; 2]; CUBES];
        for p in vector_paths() {
            let hi = (p.orientation > 0) as usize;
            t[p.cube as usize][hi][p.half_edge as usize] = (p.from, p.to);
        }
        t
    })
}

/// The polyhedra of one cell: oriented cycles of cube ids, grouped.
#[derive(Clone, Copy, Debug)]
pub struct CellShape {
    /// Cube ids of all cycles, concatenated.
    pub cubes: [u8; MAX_CYCLE_CUBES],
    /// One past the last cube of each cycle.
    pub cycle_end: [u8; MAX_CYCLES],
    /// Half-edge each cycle goes around.
    pub cycle_half_edge: [u8; MAX_CYCLES],
    /// Polyhedron of each cycle (polyhedra numbered by their first cycle).
    pub cycle_poly: [u8; MAX_CYCLES],
    pub cycles: u8,
    pub polys: u8,
}

impl CellShape {
    /// Cube ids of cycle `i`, in path order.
    #[inline]
    pub fn cycle(&self, i: usize) -> &[u8] {
        let start = if i == 0 {
            0
        } else {
            self.cycle_end[i - 1] as usize
        };
        &self.cubes[start..self.cycle_end[i] as usize]
    }

    /// Cycles of polyhedron `p`.
    pub fn poly_cycles(&self, p: usize) -> impl Iterator<Item = usize> + '_ {
        (0..self.cycles as usize).filter(move |&i| self.cycle_poly[i] as usize == p)
    }

    /// Whether polyhedron `p` is a single tetrahedron (four 3-cycles).
    pub fn is_tetrahedron(&self, p: usize) -> bool {
        let mut n = 0;
        for i in self.poly_cycles(p) {
            if self.cycle(i).len() != 3 {
                return false;
            }
            n += 1;
        }
        n == 4
    }

    /// Tetrahedra of polyhedron `p` after the paper's decomposition: 1 for a
    /// tetrahedron; otherwise one per 3-cycle plus N per N-cycle with N > 3
    /// (a fan around the face centre, each triangle coned to the volume centre).
    pub fn tet_count(&self, p: usize) -> usize {
        if self.is_tetrahedron(p) {
            return 1;
        }
        self.poly_cycles(p)
            .map(|i| match self.cycle(i).len() {
                3 => 1,
                n => n,
            })
            .sum()
    }

    /// Cycle lengths of polyhedron `p`, sorted.
    pub fn poly_lengths(&self, p: usize) -> Vec<usize> {
        let mut v: Vec<usize> = self.poly_cycles(p).map(|i| self.cycle(i).len()).collect();
        v.sort_unstable();
        v
    }
}

/// Cubes containing each half-edge (12 each).
fn half_edge_cubes() -> &'static [[u8; 12]; HALF_EDGES] {
    static T: OnceLock<[[u8; 12]; HALF_EDGES]> = OnceLock::new();
    T.get_or_init(|| {
        let mut t = [[0u8; 12]; HALF_EDGES];
        for (h, row) in t.iter_mut().enumerate() {
            let mut k = 0;
            for c in 0..CUBES {
                if cube_half_edges(c).contains(&h) {
                    row[k] = c as u8;
                    k += 1;
                }
            }
        }
        t
    })
}

/// The cycles and polyhedra of a cell: `mask` has bit `o` set for each active
/// toxel, `connect` bit `s` set to join the two active toxels at point of
/// ambiguity `s` (bits of other squares are ignored).
pub fn cell_shape(mask: u16, connect: u32) -> CellShape {
    let paths = path_lookup();
    let mut shape = CellShape {
        cubes: [0; MAX_CYCLE_CUBES],
        cycle_end: [0; MAX_CYCLES],
        cycle_half_edge: [0; MAX_CYCLES],
        cycle_poly: [0; MAX_CYCLES],
        cycles: 0,
        polys: 0,
    };
    // cycle of each (cube, half-edge)
    let mut cycle_of = [[u8::MAX; HALF_EDGES]; CUBES];
    let mut n = 0usize;
    let path_of = |c: usize, h: usize| paths[c][is_hi_active(mask, c) as usize][h];
    for h in 0..HALF_EDGES {
        for &c0 in &half_edge_cubes()[h] {
            let c0 = c0 as usize;
            if !is_boundary(mask, c0) || cycle_of[c0][h] != u8::MAX {
                continue;
            }
            let k = shape.cycles as usize;
            let mut c = c0;
            loop {
                cycle_of[c][h] = k as u8;
                shape.cubes[n] = c as u8;
                n += 1;
                let (_, out) = path_of(c, h);
                c = next_cube(mask, connect, c, out as usize, h, &path_of);
                if c == c0 {
                    break;
                }
                if n >= MAX_CYCLE_CUBES || cycle_of[c][h] != u8::MAX {
                    debug_assert!(false, "cycle does not close: mask {mask:016b}");
                    break;
                }
            }
            shape.cycle_end[k] = n as u8;
            shape.cycle_half_edge[k] = h as u8;
            shape.cycles += 1;
        }
    }
    // union the three cycles through each boundary cube
    let mut parent: [u8; MAX_CYCLES] = std::array::from_fn(|i| i as u8);
    fn find(p: &mut [u8; MAX_CYCLES], mut i: usize) -> usize {
        while p[i] as usize != i {
            p[i] = p[p[i] as usize];
            i = p[i] as usize;
        }
        i
    }
    for (c, row) in cycle_of.iter().enumerate() {
        if !is_boundary(mask, c) {
            continue;
        }
        let hs = cube_half_edges(c);
        let r0 = find(&mut parent, row[hs[0]] as usize);
        for &h in &hs[1..] {
            let r = find(&mut parent, row[h] as usize);
            if r != r0 {
                let (lo, hi) = (r.min(r0), r.max(r0));
                parent[hi] = lo as u8;
            }
            let r0n = find(&mut parent, r0);
            debug_assert!(r0n <= r0);
        }
    }
    let mut label = [u8::MAX; MAX_CYCLES];
    for i in 0..shape.cycles as usize {
        let r = find(&mut parent, i);
        if label[r] == u8::MAX {
            label[r] = shape.polys;
            shape.polys += 1;
        }
        shape.cycle_poly[i] = label[r];
    }
    shape
}

#[inline]
fn is_hi_active(mask: u16, c: usize) -> bool {
    let (_, hi) = cube_toxels(c);
    (mask >> hi) & 1 == 1
}

/// The cube after `c` around half-edge `h`, leaving `c` through square `s`.
fn next_cube(
    mask: u16,
    connect: u32,
    c: usize,
    s: usize,
    h: usize,
    path_of: &impl Fn(usize, usize) -> (u8, u8),
) -> usize {
    let mut count = 0;
    let mut only = c;
    let (mut same, mut other) = (None, None);
    let from_toxel = active_toxel(mask, c);
    for n in square_cubes(s) {
        if n == c || !is_boundary(mask, n) {
            continue;
        }
        count += 1;
        only = n;
        if path_of(n, h).0 as usize == s {
            if active_toxel(mask, n) == from_toxel {
                same = Some(n);
            } else {
                other = Some(n);
            }
        }
    }
    if count == 1 {
        return only;
    }
    let joined = (connect >> s) & 1 == 1;
    let pick = if joined {
        other.or(same)
    } else {
        same.or(other)
    };
    pick.unwrap_or(only)
}

/// Connect bits for the global modes: none (disconnect) or all (connect).
pub const CONNECT_ALL: u32 = (1 << SQUARES) - 1;

/// The vector-path table as Markdown, in the style of the paper's Table I:
/// one row per boundary-cube centre, its three paths for each orientation,
/// each path `from → centre → to` in global point ids (toxels 0–15, cube
/// centres 16–47, connectivity points 48–71), followed by the coordinates of
/// every point (offsets from the grid vertex in half cells, axes x y z t).
/// `docs/hyper_table.md` holds this text (a test keeps it current).
pub fn table_markdown() -> String {
    use super::cell::{TOXELS, cube_offset, square_offset};
    use std::fmt::Write;
    let fmt_off = |o: [i32; 4]| -> String {
        o.iter()
            .map(|&v| match v {
                -1 => "−",
                0 => "0",
                _ => "+",
            })
            .collect::<Vec<_>>()
            .join("")
    };
    let mut s = String::new();
    s.push_str(
        "# STEVE vector paths (the paper's Table I, derived)\n\n\
         Generated by `septa::hyper::table::table_markdown()`; `tests/hyper.rs` checks that this \
         file is current. Point ids: toxels 0–15, boundary-cube centres 16–47 (`16 + cube`), \
         connectivity points 48–71 (`48 + square`), numbered as in `src/hyper/cell.rs`. \
         Orientation −1: the cube's active toxel is on the − side of its axis (the range vector \
         points to +); +1: on the + side. A path `a → c → b` runs from connectivity point `a` \
         through the cube centre `c` to `b`, around the half-edge in brackets (±x, ±y, ±z, ±t); \
         the three paths of one orientation are those of the three half-edges the cube \
         contains, by axis. Direction rule: from the square toward `x` to the one toward `y` \
         (the cube's other two in-plane axes, `x < y`) iff det[h, n, x, y] > 0, with `h` the \
         half-edge, `n` the outward normal (from the active toxel to the inactive one).\n\n",
    );
    s.push_str("| centre | axis | orientation −1: path 1 | path 2 | path 3 | orientation +1: path 1 | path 2 | path 3 |\n");
    s.push_str("|---|---|---|---|---|---|---|---|\n");
    let axis = ["x", "y", "z", "t"];
    let he = |h: u8| {
        format!(
            "{}{}",
            if h & 1 == 1 { "+" } else { "−" },
            axis[h as usize / 2]
        )
    };
    for c in 0..CUBES {
        let _ = write!(s, "| {} | {} |", 16 + c, axis[cube_axis(c)]);
        for p in vector_paths().iter().filter(|p| p.cube as usize == c) {
            let _ = write!(
                s,
                " {} → {} → {} [{}] |",
                48 + p.from as usize,
                16 + c,
                48 + p.to as usize,
                he(p.half_edge)
            );
        }
        s.push('\n');
    }
    s.push_str("\n## Points (offsets from the grid vertex in half cells, order x y z t)\n\n");
    s.push_str("| id | kind | offset |\n|---|---|---|\n");
    for o in 0..TOXELS {
        let off: [i32; 4] = std::array::from_fn(|a| if (o >> a) & 1 == 1 { 1 } else { -1 });
        let _ = writeln!(
            s,
            "| {o} | toxel ({}) | {} |",
            if o < 8 { "past" } else { "future" },
            fmt_off(off)
        );
    }
    for c in 0..CUBES {
        let _ = writeln!(
            s,
            "| {} | cube centre | {} |",
            16 + c,
            fmt_off(cube_offset(c))
        );
    }
    for q in 0..SQUARES {
        let _ = writeln!(
            s,
            "| {} | connectivity point | {} |",
            48 + q,
            fmt_off(square_offset(q))
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hyper::cell::square_half_edges;

    #[test]
    fn table_has_192_paths_each_square_pair_once_per_orientation() {
        let t = vector_paths();
        assert_eq!(t.len(), 192);
        for p in t {
            assert_ne!(p.from, p.to);
            // the path's squares are both in the cube and contain its half-edge
            for s in [p.from, p.to] {
                assert!(square_cubes(s as usize).contains(&(p.cube as usize)));
                assert!(square_half_edges(s as usize).contains(&(p.half_edge as usize)));
            }
        }
        // the two orientations of a cube run every path the other way
        for c in 0..CUBES {
            for h in cube_half_edges(c) {
                let (a, b) = derive_path(c, false, h).unwrap();
                assert_eq!(derive_path(c, true, h), Some((b, a)));
            }
        }
    }

    #[test]
    fn axis_det_is_the_determinant() {
        assert_eq!(axis_det([(0, 1), (1, 1), (2, 1), (3, 1)]), 1);
        assert_eq!(axis_det([(1, 1), (0, 1), (2, 1), (3, 1)]), -1);
        assert_eq!(axis_det([(3, 1), (0, 1), (1, 1), (2, 1)]), -1);
        assert_eq!(axis_det([(3, -1), (0, 1), (1, 1), (2, 1)]), 1);
        assert_eq!(axis_det([(0, 1), (0, 1), (2, 1), (3, 1)]), 0);
    }

    #[test]
    fn every_boundary_cube_is_in_three_cycles() {
        for mask in (0..=u16::MAX).step_by(7) {
            for connect in [0, CONNECT_ALL] {
                let s = cell_shape(mask, connect);
                let total: usize = (0..s.cycles as usize).map(|i| s.cycle(i).len()).sum();
                let boundary = (0..CUBES).filter(|&c| is_boundary(mask, c)).count();
                assert_eq!(total, 3 * boundary, "mask {mask:016b}");
            }
        }
    }
}
