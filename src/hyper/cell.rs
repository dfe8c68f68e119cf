//! The 2⁴ cell around a grid vertex `g` of a 4-D grid: its 16 toxels, 32
//! boundary-cube octants, 24 connectivity points (squares) and 8 half-edges.
//!
//! Conventions (axes `0..4` = x, y, z, t; offsets from `g` in half cells):
//! - toxel `o` in `0..16`: bit `a` set = the toxel on the + side of `g` along
//!   axis `a`. Toxels `0..8` are the "past" (t −), `8..16` the "future" (t +).
//! - cube `c` in `0..32`: `8 a + k`, the 3-face perpendicular to axis `a`
//!   between toxels `lo` and `lo | 1 << a`; bit `i` of `k` is the side along
//!   the `i`-th of the three other axes (ascending). Its centre — a support
//!   point of the hypersurface — is at offset 0 along `a` and ±1 (half cells)
//!   along the others; `g` is one of its corners.
//! - square `s` in `0..24`: `4 p + sp + 2 sq` for the axis pair `PAIRS[p] =
//!   (u, v)` with sides `sp` along `u`, `sq` along `v`. Its centre (±1 along
//!   `u`, `v`, 0 along the others) is a *connectivity point*: vector paths of
//!   neighbouring cubes meet there. Four toxels share a square; when two of
//!   them that lie diagonally are active and the other two are not, the square
//!   is a *point of ambiguity*.
//! - half-edge `h` in `0..8`: `2 d + side`, the grid edge from `g` along −d
//!   (side 0) or +d (side 1). The boundary cubes containing a half-edge are
//!   linked into closed *cycles* (the 2-faces of the hypersurface, dual to the
//!   edge), and the cycles of one cell glue into closed polyhedra (the 3-cells,
//!   dual to `g`).

/// Number of axes.
pub const AXES: usize = 4;
/// Toxels of a cell.
pub const TOXELS: usize = 16;
/// Boundary-cube octants of a cell.
pub const CUBES: usize = 32;
/// Connectivity points (squares) of a cell.
pub const SQUARES: usize = 24;
/// Half-edges at a grid vertex.
pub const HALF_EDGES: usize = 8;

/// The six axis pairs, in the order of the square ids.
pub const PAIRS: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// The three axes other than `a`, ascending.
#[inline]
pub const fn other_axes(a: usize) -> [usize; 3] {
    match a {
        0 => [1, 2, 3],
        1 => [0, 2, 3],
        2 => [0, 1, 3],
        _ => [0, 1, 2],
    }
}

/// The two axes not in the pair `(u, v)`, ascending.
#[inline]
pub const fn complement(u: usize, v: usize) -> (usize, usize) {
    let mut out = [0usize; 2];
    let mut n = 0;
    let mut a = 0;
    while a < 4 {
        if a != u && a != v {
            out[n] = a;
            n += 1;
        }
        a += 1;
    }
    (out[0], out[1])
}

/// Index of the pair `{u, v}` in [`PAIRS`].
#[inline]
pub const fn pair_index(u: usize, v: usize) -> usize {
    let (u, v) = if u < v { (u, v) } else { (v, u) };
    match (u, v) {
        (0, 1) => 0,
        (0, 2) => 1,
        (0, 3) => 2,
        (1, 2) => 3,
        (1, 3) => 4,
        _ => 5,
    }
}

/// Normal axis of a cube.
#[inline]
pub const fn cube_axis(c: usize) -> usize {
    c / 8
}

/// The two toxels a cube separates: (− side of its axis, + side).
#[inline]
pub const fn cube_toxels(c: usize) -> (usize, usize) {
    let a = c / 8;
    let others = other_axes(a);
    let mut lo = 0;
    let mut i = 0;
    while i < 3 {
        lo |= ((c >> i) & 1) << others[i];
        i += 1;
    }
    (lo, lo | 1 << a)
}

/// Side (0 = −, 1 = +) of a cube along one of its in-plane axes `d` (≠ its normal).
#[inline]
pub const fn cube_side(c: usize, d: usize) -> usize {
    let (lo, _) = cube_toxels(c);
    (lo >> d) & 1
}

/// The cube with normal `a` whose toxel on the − side is `lo` (bit `a` ignored).
#[inline]
pub const fn cube_id(a: usize, lo: usize) -> usize {
    let others = other_axes(a);
    let mut k = 0;
    let mut i = 0;
    while i < 3 {
        k |= ((lo >> others[i]) & 1) << i;
        i += 1;
    }
    8 * a + k
}

/// Offset of a cube centre from `g`, in half cells.
#[inline]
pub const fn cube_offset(c: usize) -> [i32; 4] {
    let a = c / 8;
    let (lo, _) = cube_toxels(c);
    let mut o = [0i32; 4];
    let mut d = 0;
    while d < 4 {
        if d != a {
            o[d] = if (lo >> d) & 1 == 1 { 1 } else { -1 };
        }
        d += 1;
    }
    o
}

/// The half-edges a cube contains (one per in-plane axis, ascending axis).
#[inline]
pub const fn cube_half_edges(c: usize) -> [usize; 3] {
    let others = other_axes(c / 8);
    let (lo, _) = cube_toxels(c);
    [
        2 * others[0] + ((lo >> others[0]) & 1),
        2 * others[1] + ((lo >> others[1]) & 1),
        2 * others[2] + ((lo >> others[2]) & 1),
    ]
}

/// Square id from its axis pair and the sides along them.
#[inline]
pub const fn square_id(u: usize, su: usize, v: usize, sv: usize) -> usize {
    let (u, su, v, sv) = if u < v {
        (u, su, v, sv)
    } else {
        (v, sv, u, su)
    };
    4 * pair_index(u, v) + su + 2 * sv
}

/// Axis pair `(u, v)` and sides `(su, sv)` of a square.
#[inline]
pub const fn square_axes(s: usize) -> ((usize, usize), (usize, usize)) {
    (PAIRS[s / 4], (s & 1, (s >> 1) & 1))
}

/// Offset of a square's centre from `g`, in half cells.
#[inline]
pub const fn square_offset(s: usize) -> [i32; 4] {
    let ((u, v), (su, sv)) = square_axes(s);
    let mut o = [0i32; 4];
    o[u] = if su == 1 { 1 } else { -1 };
    o[v] = if sv == 1 { 1 } else { -1 };
    o
}

/// The square of cube `c` spanned by its in-plane axes `d1`, `d2`.
#[inline]
pub const fn cube_square(c: usize, d1: usize, d2: usize) -> usize {
    square_id(d1, cube_side(c, d1), d2, cube_side(c, d2))
}

/// The two half-edges contained in a square.
#[inline]
pub const fn square_half_edges(s: usize) -> [usize; 2] {
    let ((u, v), (su, sv)) = square_axes(s);
    [2 * u + su, 2 * v + sv]
}

/// The four toxels sharing a square, ordered so that `0, 3` and `1, 2` are the
/// diagonals (the square's own sides fixed; the two other axes `r < w` vary as
/// (−,−), (+,−), (−,+), (+,+)).
#[inline]
pub const fn square_toxels(s: usize) -> [usize; 4] {
    let ((u, v), (su, sv)) = square_axes(s);
    let (r, w) = complement(u, v);
    let base = (su << u) | (sv << v);
    [base, base | 1 << r, base | 1 << w, base | 1 << r | 1 << w]
}

/// The four cubes containing a square (normals along the two axes the square
/// does not span).
#[inline]
pub const fn square_cubes(s: usize) -> [usize; 4] {
    let t = square_toxels(s);
    let ((u, v), _) = square_axes(s);
    let (r, w) = complement(u, v);
    // toxel pairs differing along r: (t0, t1), (t2, t3); along w: (t0, t2), (t1, t3)
    [
        cube_id(r, t[0]),
        cube_id(r, t[2]),
        cube_id(w, t[0]),
        cube_id(w, t[1]),
    ]
}

/// Whether a square is a point of ambiguity for the active-toxel mask: exactly
/// two of its toxels are active and they lie diagonally.
#[inline]
pub const fn is_ambiguous(mask: u16, s: usize) -> bool {
    let t = square_toxels(s);
    let b = [
        (mask >> t[0]) & 1,
        (mask >> t[1]) & 1,
        (mask >> t[2]) & 1,
        (mask >> t[3]) & 1,
    ];
    b[0] == b[3] && b[1] == b[2] && b[0] != b[1]
}

/// 24-bit set of the points of ambiguity of a mask.
pub fn ambiguous_squares(mask: u16) -> u32 {
    let mut bits = 0;
    for s in 0..SQUARES {
        if is_ambiguous(mask, s) {
            bits |= 1 << s;
        }
    }
    bits
}

/// Whether cube `c` separates an active from an inactive toxel.
#[inline]
pub const fn is_boundary(mask: u16, c: usize) -> bool {
    let (lo, hi) = cube_toxels(c);
    ((mask >> lo) & 1) != ((mask >> hi) & 1)
}

/// The active toxel of a boundary cube.
#[inline]
pub const fn active_toxel(mask: u16, c: usize) -> usize {
    let (lo, hi) = cube_toxels(c);
    if (mask >> lo) & 1 == 1 { lo } else { hi }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incidences_are_consistent() {
        for c in 0..CUBES {
            let (lo, hi) = cube_toxels(c);
            assert_eq!(lo ^ hi, 1 << cube_axis(c));
            assert_eq!(cube_id(cube_axis(c), lo), c);
            // a cube contains exactly the squares spanned by two of its in-plane axes
            let others = other_axes(cube_axis(c));
            for i in 0..3 {
                for j in i + 1..3 {
                    let s = cube_square(c, others[i], others[j]);
                    assert!(square_cubes(s).contains(&c), "cube {c} square {s}");
                }
            }
        }
        for s in 0..SQUARES {
            let mut cubes = square_cubes(s).to_vec();
            cubes.sort();
            cubes.dedup();
            assert_eq!(cubes.len(), 4);
            for c in cubes {
                let (lo, hi) = cube_toxels(c);
                assert!(square_toxels(s).contains(&lo) && square_toxels(s).contains(&hi));
                for h in square_half_edges(s) {
                    assert!(cube_half_edges(c).contains(&h));
                }
            }
            // centre offsets: the square centre is the midpoint of g and ... (±1, ±1 on its axes)
            let o = square_offset(s);
            assert_eq!(o.iter().filter(|&&x| x != 0).count(), 2);
        }
        // every half-edge lies in 12 cubes and 6 squares
        for h in 0..HALF_EDGES {
            assert_eq!(
                (0..CUBES)
                    .filter(|&c| cube_half_edges(c).contains(&h))
                    .count(),
                12
            );
            assert_eq!(
                (0..SQUARES)
                    .filter(|&s| square_half_edges(s).contains(&h))
                    .count(),
                6
            );
        }
    }

    #[test]
    fn ambiguity_is_two_diagonal_toxels() {
        // two toxels differing in exactly two axes share exactly one square
        let mask: u16 = 1 | 1 << 3; // toxels 0 and 3 (differ in x and y)
        let amb = ambiguous_squares(mask);
        assert_eq!(amb.count_ones(), 1);
        let s = amb.trailing_zeros() as usize;
        assert_eq!(square_axes(s).0, (2, 3));
    }
}
