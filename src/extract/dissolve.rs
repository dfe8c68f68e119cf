//! Dissolving vertices that lie inside a straight segment of the surface.
//!
//! Along a straight junction line, and along the straight borders of the
//! merged rectangles of refined voxels, the VESTA construction puts a vertex
//! at every fine grid vertex and fine edge midpoint: a vertex `v` strictly
//! between two neighbours `u` and `w` on one line, whose triangles come in
//! pairs `(a, u, v)`, `(a, v, w)` around each far corner `a`. Each pair covers
//! exactly the triangle `(a, u, w)` (the three points are on one line), so
//! replacing the pair by that triangle and dropping `v` leaves the surface
//! the very same point set: every invariant of the extraction (closed,
//! manifold, oriented label surfaces, no crossings, shared junction curves)
//! holds after it as before. Collinearity is decided exactly, on the integer
//! lattice coordinates of the points.
//!
//! A vertex on a junction curve is dissolved only where the curve runs
//! straight through it (its curve neighbours are `u` and `w`); curve ends and
//! corners stay. Vertices are visited in id order, on the mesh as the earlier
//! removals left it, so chains of such vertices shrink to their two ends and
//! the result does not depend on the thread count.

use rayon::prelude::*;

use crate::geom::incidence;
use crate::mesh::JunctionCurve;

/// No vertex / a dead triangle.
const NONE: u32 = u32::MAX;
/// A curve end or corner: never dissolved.
const FIXED: u32 = u32::MAX - 1;

/// Exact lattice coordinates of the vertices.
pub(crate) trait LatticeCoords {
    /// Number of vertices.
    fn len(&self) -> usize;
    /// The lattice coordinates of vertex `v` (`None`: not on the lattice,
    /// never dissolved nor used as a segment end).
    fn at(&self, v: u32) -> Option<[i32; 3]>;
}

impl LatticeCoords for [Option<[i32; 3]>] {
    fn len(&self) -> usize {
        <[_]>::len(self)
    }
    fn at(&self, v: u32) -> Option<[i32; 3]> {
        self[v as usize]
    }
}

/// Dissolves every vertex inside a straight segment (see the module docs).
/// `lattice` gives the exact lattice coordinates of each vertex. Returns
/// which vertices were dissolved; `tris` and `patch` keep only the live
/// triangles.
pub(crate) fn dissolve_straight<L: LatticeCoords + Sync + ?Sized>(
    lattice: &L,
    tris: &mut Vec<[u32; 3]>,
    patch: &mut Vec<u32>,
    curves: &[JunctionCurve],
) -> Vec<bool> {
    let n = lattice.len();
    let mut curve_nb = curve_neighbours(n, curves);
    let (start, mut list) = incidence::rows(n, tris);
    let hinged = hinged_stars(lattice, tris, &start, &list);
    let mut dead = vec![false; n];
    let mut star: Vec<(u32, [u32; 3])> = Vec::with_capacity(16);
    let mut scratch = Scratch::default();
    for v in 0..n as u32 {
        let Some(pv) = lattice.at(v) else {
            continue;
        };
        if curve_nb[v as usize][0] == FIXED || !hinged[v as usize] {
            continue;
        }
        let row = start[v as usize] as usize..start[v as usize + 1] as usize;
        star.clear();
        star.extend(
            list[row.clone()]
                .iter()
                .filter(|&&t| t != NONE)
                .map(|&t| (t, rotate_to(tris[t as usize], v))),
        );
        let Some((u, w)) = straight_merge(pv, lattice, &star, patch, &mut scratch) else {
            continue;
        };
        let on_curve = curve_nb[v as usize];
        if on_curve[0] != NONE && !(on_curve == [u, w] || on_curve == [w, u]) {
            continue;
        }
        // an existing edge u–w would become shared by more triangles than its
        // two (it cannot exist in a conforming complex; checked, not assumed)
        let urow = start[u as usize] as usize..start[u as usize + 1] as usize;
        if list[urow]
            .iter()
            .any(|&t| t != NONE && tris[t as usize].contains(&w))
        {
            continue;
        }
        for &(keep, gone, merged, l2, apex) in &scratch.pairs {
            tris[keep as usize] = merged;
            tris[gone as usize] = [NONE; 3];
            replace_in_row(&start, &mut list, l2, gone, keep);
            replace_in_row(&start, &mut list, apex, gone, NONE);
        }
        list[row].iter_mut().for_each(|t| *t = NONE);
        dead[v as usize] = true;
        if on_curve[0] != NONE {
            for (x, y) in [(u, w), (w, u)] {
                let nb = &mut curve_nb[x as usize];
                if nb[0] != FIXED {
                    for slot in nb.iter_mut() {
                        if *slot == v {
                            *slot = y;
                        }
                    }
                }
            }
        }
    }
    retain_live(tris, patch);
    dead
}

/// Drops the dead triangles (first corner `NONE`) and their patch entries,
/// keeping the order of the others.
pub(crate) fn retain_live(tris: &mut Vec<[u32; 3]>, patch: &mut Vec<u32>) {
    let mut k = 0;
    for i in 0..tris.len() {
        if tris[i][0] != NONE {
            tris[k] = tris[i];
            patch[k] = patch[i];
            k += 1;
        }
    }
    tris.truncate(k);
    patch.truncate(k);
}

/// Per vertex: whether the planes of its triangles (as the mesh is now)
/// have a direction in common, or the vertex has no lattice coordinates
/// itself or at a neighbour (then it is not decided here). A vertex that is
/// dissolved has all its triangles hinged on the line through it, so one
/// without such a direction never is; and dissolving other vertices keeps
/// the planes of a vertex's triangles (a pair is replaced by one triangle in
/// the pair's plane), so this, found for every vertex at once and in
/// parallel, holds through the whole serial pass. Decided exactly on the
/// lattice coordinates.
fn hinged_stars<L: LatticeCoords + Sync + ?Sized>(
    lattice: &L,
    tris: &[[u32; 3]],
    start: &[u32],
    list: &[u32],
) -> Vec<bool> {
    let cross = |a: [i128; 3], b: [i128; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let normal = |t: [u32; 3]| -> Option<[i128; 3]> {
        let [a, b, c] = [lattice.at(t[0])?, lattice.at(t[1])?, lattice.at(t[2])?];
        let d = |p: [i32; 3], q: [i32; 3]| [0, 1, 2].map(|k| (q[k] - p[k]) as i128);
        Some(cross(d(a, b), d(a, c)))
    };
    (0..lattice.len())
        .into_par_iter()
        .map(|v| {
            let row = &list[start[v] as usize..start[v + 1] as usize];
            // the first normal, then the first one not parallel to it: their
            // cross product is the only direction every plane could share
            let mut first: Option<[i128; 3]> = None;
            let mut axis: Option<[i128; 3]> = None;
            for &t in row {
                let Some(n) = normal(tris[t as usize]) else {
                    return true;
                };
                match (first, axis) {
                    (None, _) => first = Some(n),
                    (Some(f), None) => {
                        let c = cross(f, n);
                        if c != [0; 3] {
                            axis = Some(c);
                        }
                    }
                    (_, Some(d)) => {
                        if n[0] * d[0] + n[1] * d[1] + n[2] * d[2] != 0 {
                            return false;
                        }
                    }
                }
            }
            true
        })
        .collect()
}

/// Buffers of [`straight_merge`], reused from vertex to vertex.
#[derive(Default)]
struct Scratch {
    /// The replacement of a vertex's triangles: per far corner, (kept slot,
    /// dead slot, merged triangle, the line end whose row must name the kept
    /// slot, the far corner).
    pairs: Vec<(u32, u32, [u32; 3], u32, u32)>,
    apexes: Vec<u32>,
    neighbours: Vec<u32>,
    offsets: Vec<Option<[i64; 3]>>,
    lines: Vec<(u32, u32)>,
}

/// Whether the triangles around `v` (each rotated to start at `v`) pair up
/// along one straight line through it: its two line neighbours, with the
/// merge in `scratch.pairs`. Where two lines would do (a flat star of four
/// triangles, straight both ways), the first one found is taken: either
/// gives the same point set.
fn straight_merge<L: LatticeCoords + ?Sized>(
    pv: [i32; 3],
    lattice: &L,
    star: &[(u32, [u32; 3])],
    patch: &[u32],
    scratch: &mut Scratch,
) -> Option<(u32, u32)> {
    if star.len() < 2 || star.len() % 2 == 1 {
        return None;
    }
    lines_through(
        pv,
        lattice,
        star,
        &mut scratch.neighbours,
        &mut scratch.offsets,
        &mut scratch.lines,
    );
    let Scratch {
        pairs,
        apexes,
        lines,
        ..
    } = scratch;
    lines
        .iter()
        .copied()
        .find(|&line| merge_along(line, star, patch, pairs, apexes))
}

/// Whether every triangle of `star` is in one pair along the line
/// `u – v – w`; the pairs go to `pairs`.
fn merge_along(
    (u, w): (u32, u32),
    star: &[(u32, [u32; 3])],
    patch: &[u32],
    pairs: &mut Vec<(u32, u32, [u32; 3], u32, u32)>,
    apexes: &mut Vec<u32>,
) -> bool {
    let on_line = |x: u32| x == u || x == w;
    if !star.iter().all(|&(_, [_, x, y])| on_line(x) != on_line(y)) {
        return false;
    }
    pairs.clear();
    for &(t, [_, x, y]) in star {
        // (v, a, L1): pair it with the (v, L2, a) of the same corner
        if on_line(x) {
            continue;
        }
        let (a, l1) = (x, y);
        let mut partner = star
            .iter()
            .filter(|&&(_, [_, p, q])| q == a && on_line(p) && p != l1);
        let Some(&(t2, [_, l2, _])) = partner.next() else {
            return false;
        };
        if partner.next().is_some() || patch[t as usize] != patch[t2 as usize] {
            return false;
        }
        pairs.push((t, t2, [a, l1, l2], l2, a));
    }
    // every triangle in exactly one pair: one pair per far corner
    apexes.clear();
    apexes.extend(pairs.iter().map(|p| p.4));
    apexes.sort_unstable();
    pairs.len() * 2 == star.len() && apexes.windows(2).all(|w| w[0] != w[1])
}

/// The pairs of neighbours of `v` (at `pv`) on a line through it, with `v`
/// strictly between them, in the order of their ids, into `found`.
fn lines_through<L: LatticeCoords + ?Sized>(
    pv: [i32; 3],
    lattice: &L,
    star: &[(u32, [u32; 3])],
    nbs: &mut Vec<u32>,
    offsets: &mut Vec<Option<[i64; 3]>>,
    found: &mut Vec<(u32, u32)>,
) {
    nbs.clear();
    nbs.extend(star.iter().flat_map(|&(_, [_, x, y])| [x, y]));
    nbs.sort_unstable();
    nbs.dedup();
    offsets.clear();
    offsets.extend(nbs.iter().map(|&x| {
        let p = lattice.at(x)?;
        Some([0, 1, 2].map(|k| (p[k] - pv[k]) as i64))
    }));
    found.clear();
    for (i, (&a, da)) in nbs.iter().zip(offsets.iter()).enumerate() {
        let Some(da) = da else { continue };
        for (&b, db) in nbs[i + 1..].iter().zip(&offsets[i + 1..]) {
            let Some(db) = db else { continue };
            let cross = [
                da[1] * db[2] - da[2] * db[1],
                da[2] * db[0] - da[0] * db[2],
                da[0] * db[1] - da[1] * db[0],
            ];
            let dot = da[0] * db[0] + da[1] * db[1] + da[2] * db[2];
            if cross == [0; 3] && dot < 0 {
                found.push((a, b));
            }
        }
    }
}

/// `t` rotated so that it starts at `v` (orientation kept).
#[inline]
pub(crate) fn rotate_to(t: [u32; 3], v: u32) -> [u32; 3] {
    if t[0] == v {
        t
    } else if t[1] == v {
        [t[1], t[2], t[0]]
    } else {
        [t[2], t[0], t[1]]
    }
}

/// Per vertex: its two neighbours along the junction curve through it,
/// `[FIXED; 2]` at curve ends, corners and vertices on several curves, and
/// `[NONE; 2]` off the curves.
fn curve_neighbours(n: usize, curves: &[JunctionCurve]) -> Vec<[u32; 2]> {
    let mut nb = vec![[NONE; 2]; n];
    for c in curves {
        let k = c.vertices.len();
        for (i, &v) in c.vertices.iter().enumerate() {
            let interior = c.closed || (i > 0 && i + 1 < k);
            let slot = &mut nb[v as usize];
            if !interior || slot[0] != NONE || k < 3 {
                *slot = [FIXED; 2];
                continue;
            }
            *slot = [c.vertices[(i + k - 1) % k], c.vertices[(i + 1) % k]];
        }
    }
    nb
}

/// In vertex `v`'s row, `from` becomes `to`.
#[inline]
fn replace_in_row(start: &[u32], list: &mut [u32], v: u32, from: u32, to: u32) {
    let row = start[v as usize] as usize..start[v as usize + 1] as usize;
    if let Some(slot) = list[row].iter_mut().find(|t| **t == from) {
        *slot = to;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(vertices: Vec<u32>, closed: bool) -> JunctionCurve {
        JunctionCurve {
            vertices,
            closed,
            labels: vec![0, 1, 2],
        }
    }

    /// A square 0..4 in the z = 0 plane split along x = 2 through vertices
    /// 4 (bottom middle) and 5 (top middle), fanned from 6 and 7.
    fn strip() -> (Vec<Option<[i32; 3]>>, Vec<[u32; 3]>) {
        // 0 (0,0) 4 (2,0) 1 (4,0); 3 (0,4) 5 (2,4) 2 (4,4); apex 6 = (2,2) ... use
        // a line of three points 0 – 4 – 1 with two apexes on either side
        let lattice = vec![
            Some([0, 0, 0]),  // 0
            Some([4, 0, 0]),  // 1
            Some([1, 3, 0]),  // 2: apex above the line
            Some([2, -3, 0]), // 3: apex below
            Some([2, 0, 0]),  // 4: on the line between 0 and 1
        ];
        let tris = vec![[2, 0, 4], [2, 4, 1], [3, 4, 0], [3, 1, 4]];
        (lattice, tris)
    }

    #[test]
    fn a_vertex_inside_a_straight_line_between_two_fans_goes() {
        let (lattice, mut tris) = strip();
        let mut patch = vec![0, 0, 1, 1];
        let dead = dissolve_straight(lattice.as_slice(), &mut tris, &mut patch, &[]);
        assert_eq!(dead, vec![false, false, false, false, true]);
        assert_eq!(tris, vec![[2, 0, 1], [3, 1, 0]]);
        assert_eq!(patch, vec![0, 1]);
    }

    #[test]
    fn pairs_in_different_patches_or_a_bent_line_stay() {
        let (lattice, tris0) = strip();
        let mut tris = tris0.clone();
        let mut patch = vec![0, 1, 1, 1];
        let dead = dissolve_straight(lattice.as_slice(), &mut tris, &mut patch, &[]);
        assert!(dead.iter().all(|d| !d));
        assert_eq!(tris, tris0);
        let mut bent = lattice.clone();
        bent[4] = Some([2, 1, 0]);
        let mut tris = tris0.clone();
        let mut patch = vec![0, 0, 1, 1];
        let dead = dissolve_straight(bent.as_slice(), &mut tris, &mut patch, &[]);
        assert!(dead.iter().all(|d| !d));
    }

    #[test]
    fn curve_ends_stay_and_straight_curve_interiors_go() {
        let (lattice, tris0) = strip();
        // vertex 4 ends a curve: it stays
        let mut tris = tris0.clone();
        let mut patch = vec![0, 0, 1, 1];
        let ends = [curve(vec![4, 2], false)];
        assert!(!dissolve_straight(lattice.as_slice(), &mut tris, &mut patch, &ends)[4]);
        // vertex 4 inside the curve 0 – 4 – 1: it goes
        let mut tris = tris0.clone();
        let mut patch = vec![0, 0, 1, 1];
        let through = [curve(vec![0, 4, 1], false)];
        assert!(dissolve_straight(lattice.as_slice(), &mut tris, &mut patch, &through)[4]);
        // a curve turning at 4 (0 – 4 – 2) keeps it
        let mut tris = tris0.clone();
        let mut patch = vec![0, 0, 1, 1];
        let turning = [curve(vec![0, 4, 2], false)];
        assert!(!dissolve_straight(lattice.as_slice(), &mut tris, &mut patch, &turning)[4]);
    }

    #[test]
    fn a_chain_shrinks_to_its_ends() {
        // 0 – 3 – 4 – 5 – 1 on the x axis, apex 2 above
        let lattice = vec![
            Some([0, 0, 0]),
            Some([8, 0, 0]),
            Some([4, 5, 0]),
            Some([2, 0, 0]),
            Some([4, 0, 0]),
            Some([6, 0, 0]),
        ];
        let mut tris = vec![[2, 0, 3], [2, 3, 4], [2, 4, 5], [2, 5, 1]];
        // close it below with a second apex so that every line vertex has two fans
        let mut lattice = lattice;
        lattice.push(Some([3, -5, 0])); // 6
        tris.extend([[6, 3, 0], [6, 4, 3], [6, 5, 4], [6, 1, 5]]);
        let mut patch = vec![0; 8];
        let dead = dissolve_straight(lattice.as_slice(), &mut tris, &mut patch, &[]);
        assert_eq!(dead, vec![false, false, false, true, true, true, false]);
        assert_eq!(tris, vec![[2, 0, 1], [6, 1, 0]]);
    }

    #[test]
    fn a_flat_star_straight_both_ways_goes_along_one_line() {
        // the apexes 2, 3 are also on a line through 4: either merge is the same quad
        let (mut lattice, mut tris) = strip();
        lattice[2] = Some([2, 3, 0]);
        let mut patch = vec![0, 0, 1, 1];
        let dead = dissolve_straight(lattice.as_slice(), &mut tris, &mut patch, &[]);
        assert!(dead[4]);
        assert_eq!(tris, vec![[2, 0, 1], [3, 1, 0]]);
    }

    #[test]
    fn only_stars_hinged_on_a_line_are_candidates() {
        // the strip, folded along the x axis (apex 3 below the plane, out
        // of it): every plane at vertex 4 holds the x direction
        let (mut lattice, tris) = strip();
        lattice[3] = Some([2, -3, 5]);
        let (start, list) = incidence::rows(lattice.len(), &tris);
        assert!(hinged_stars(&lattice[..], &tris, &start, &list)[4]);
        // a corner of a box: three planes with no direction in common
        let corner = vec![
            Some([0, 0, 0]),
            Some([1, 0, 0]),
            Some([0, 1, 0]),
            Some([0, 0, 1]),
        ];
        let tris = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2]];
        let (start, list) = incidence::rows(corner.len(), &tris);
        let hinged = hinged_stars(&corner[..], &tris, &start, &list);
        assert!(!hinged[0], "three planes at the corner");
        assert!(hinged[1], "two planes at the other corners");
        // a neighbour off the lattice: not decided here
        let mut off = corner.clone();
        off[3] = None;
        let hinged = hinged_stars(&off[..], &tris, &start, &list);
        assert!(hinged[0]);
    }

    #[test]
    fn a_vertex_off_the_lattice_stays() {
        let (mut lattice, mut tris) = strip();
        lattice[4] = None;
        let mut patch = vec![0, 0, 1, 1];
        let dead = dissolve_straight(lattice.as_slice(), &mut tris, &mut patch, &[]);
        assert!(dead.iter().all(|d| !d));
    }
}
