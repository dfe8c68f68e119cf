//! Dissolving vertices inside flat stretches of one patch.
//!
//! Where the labels' boundary is flat over several faces (a terrace of a
//! staircase, the side of a fattened block), the VESTA construction puts a
//! vertex at every face's support point, though the surface there is one
//! plane. A vertex `v` off the junction curves whose triangles all lie in one
//! plane, face the same way and belong to one patch is the centre of a flat
//! disk: its triangles tile the polygon of its ring. Replacing them by a
//! triangulation of that polygon (ear by ear, the shortest diagonal first, so
//! no triangle is flat and no vertex lies on a new edge) leaves the surface
//! the very same point set, so every invariant of the extraction (closed,
//! manifold, oriented label surfaces, no crossings, shared junction curves)
//! holds after it as before. Flatness, orientation and every ear are decided
//! exactly on the integer lattice coordinates.
//!
//! Which stars are flat is found for every vertex at once, in parallel:
//! dissolving a vertex replaces triangles by others in the same plane, so no
//! star becomes flat that was not. The flat ones are then dissolved one by
//! one in id order, each on the mesh as the earlier ones left it, so the
//! result does not depend on the thread count.

use rayon::prelude::*;

use super::dissolve::{LatticeCoords, retain_live, rotate_to};
use crate::mesh::JunctionCurve;

/// A dead triangle.
const NONE: u32 = u32::MAX;

/// Buffers of [`plan_flat`], reused from vertex to vertex.
#[derive(Default)]
struct Scratch {
    /// The star's triangles (ids), and what takes their place.
    star: Vec<u32>,
    made: Vec<[u32; 3]>,
    edges: Vec<(u32, u32)>,
    ring: Vec<u32>,
    pts: Vec<[i64; 2]>,
    left: Vec<usize>,
}

/// Dissolves every vertex at the centre of a flat disk of one patch (see the
/// module docs); `tris` and `patch` keep only the live triangles. Returns the
/// number of vertices dissolved.
pub(crate) fn dissolve_flat<L: LatticeCoords + Sync + ?Sized>(
    lattice: &L,
    tris: &mut Vec<[u32; 3]>,
    patch: &mut Vec<u32>,
    curves: &[JunctionCurve],
) -> usize {
    let n = lattice.len();
    let mut on_curve = vec![false; n];
    for c in curves {
        for &v in &c.vertices {
            on_curve[v as usize] = true;
        }
    }
    // looked up many times each: once, in parallel
    let coords: Vec<Option<[i32; 3]>> = (0..n as u32)
        .into_par_iter()
        .map(|v| lattice.at(v))
        .collect();
    let candidates: Vec<u32> = (0..n as u32)
        .filter(|&v| !on_curve[v as usize] && coords[v as usize].is_some())
        .collect();
    let mut rows = Rows::new(n, tris);
    // which stars are flat, in parallel; dissolving a neighbour replaces
    // triangles by others in the same planes, so no other star becomes flat
    let mesh = Mesh {
        coords: &coords,
        tris,
        patch,
        rows: &rows,
    };
    let flat: Vec<u32> = candidates
        .par_iter()
        .copied()
        .filter(|&v| mesh.flat_normal(v).is_some())
        .collect();
    drop(candidates);
    // then one by one in id order, each on the mesh as the earlier ones left it
    let mut scratch = Scratch::default();
    let mut dissolved = 0;
    for v in flat {
        let mesh = Mesh {
            coords: &coords,
            tris,
            patch,
            rows: &rows,
        };
        if mesh.plan_flat(v, &mut scratch).is_none() {
            continue;
        }
        let (star, made) = (&scratch.star, &scratch.made);
        for &t in star {
            for x in tris[t as usize] {
                rows.remove(x, t);
            }
        }
        let (kept, gone) = star.split_at(made.len());
        for (&t, &m) in kept.iter().zip(made.iter()) {
            tris[t as usize] = m;
            for x in m {
                rows.add(x, t);
            }
        }
        for &t in gone {
            tris[t as usize] = [NONE; 3];
        }
        dissolved += 1;
    }
    retain_live(tris, patch);
    dissolved
}

/// The live triangles around each vertex, as rows with room to grow: a
/// dissolution takes two triangles from each vertex of the ring and may give
/// it more (the ears cut at it).
struct Rows {
    start: Vec<u32>,
    list: Vec<u32>,
    /// What did not fit in a row.
    spill: hashbrown::HashMap<u32, Vec<u32>>,
}

impl Rows {
    /// Free slots per row besides the vertex's triangles.
    const ROOM: u32 = 2;

    /// The rows of the live triangles of `tris`.
    fn new(n: usize, tris: &[[u32; 3]]) -> Self {
        let mut start = vec![0u32; n + 1];
        for t in tris.iter().filter(|t| t[0] != NONE) {
            for &v in t {
                start[v as usize + 1] += 1;
            }
        }
        for v in 0..n {
            start[v + 1] += start[v] + Self::ROOM;
        }
        let mut fill = start.clone();
        let mut list = vec![NONE; start[n] as usize];
        for (i, t) in tris.iter().enumerate().filter(|(_, t)| t[0] != NONE) {
            for &v in t {
                list[fill[v as usize] as usize] = i as u32;
                fill[v as usize] += 1;
            }
        }
        Rows {
            start,
            list,
            spill: hashbrown::HashMap::new(),
        }
    }

    fn row(&self, v: u32) -> &[u32] {
        &self.list[self.start[v as usize] as usize..self.start[v as usize + 1] as usize]
    }

    /// The live triangles around `v`.
    fn live(&self, v: u32) -> impl Iterator<Item = u32> + '_ {
        let spilled = match self.spill.is_empty() {
            true => &[][..],
            false => self.spill.get(&v).map_or(&[][..], |s| s.as_slice()),
        };
        self.row(v)
            .iter()
            .chain(spilled)
            .copied()
            .filter(|&t| t != NONE)
    }

    fn remove(&mut self, v: u32, t: u32) {
        let r = self.start[v as usize] as usize..self.start[v as usize + 1] as usize;
        let spilled = self
            .spill
            .get_mut(&v)
            .map_or(&mut [][..], |s| s.as_mut_slice());
        if let Some(slot) = self.list[r].iter_mut().chain(spilled).find(|x| **x == t) {
            *slot = NONE;
        }
    }

    /// Adds `t` to `v`'s row (to its spill where the row is full).
    fn add(&mut self, v: u32, t: u32) {
        let r = self.start[v as usize] as usize..self.start[v as usize + 1] as usize;
        match self.list[r].iter_mut().find(|x| **x == NONE) {
            Some(slot) => *slot = t,
            None => self.spill.entry(v).or_default().push(t),
        }
    }
}

/// The mesh as the dissolution reads it: lattice coordinates, triangles,
/// their patches and the rows of triangles around each vertex.
struct Mesh<'a> {
    coords: &'a [Option<[i32; 3]>],
    tris: &'a [[u32; 3]],
    patch: &'a [u32],
    rows: &'a Rows,
}

impl Mesh<'_> {
    /// The normal of the plane of `v`'s triangles, if they all lie in it, face
    /// the same way and belong to one patch.
    fn flat_normal(&self, v: u32) -> Option<[i64; 3]> {
        let Mesh {
            coords,
            tris,
            patch,
            rows,
        } = *self;
        let pv = coords[v as usize]?;
        let rel = |x: u32| Some(offset(coords[x as usize]?, pv));
        let mut normal = [0i64; 3];
        let mut first_patch = None;
        let mut count = 0;
        for t in rows.live(v) {
            if *first_patch.get_or_insert(patch[t as usize]) != patch[t as usize] {
                return None;
            }
            let [_, a, b] = rotate_to(tris[t as usize], v);
            let n = cross(rel(a)?, rel(b)?);
            if n == [0; 3] || (normal != [0; 3] && !same_direction(n, normal)) {
                return None;
            }
            normal = n;
            count += 1;
        }
        (count >= 3).then_some(normal)
    }

    /// The replacement of vertex `v`'s triangles by a triangulation of its ring,
    /// if they form a flat disk of one patch: the triangles to replace in
    /// `scratch.star`, what takes their place in `scratch.made`.
    fn plan_flat(&self, v: u32, scratch: &mut Scratch) -> Option<()> {
        let normal = self.flat_normal(v)?;
        let Mesh {
            coords, tris, rows, ..
        } = *self;
        let Scratch {
            star,
            made,
            edges,
            ring,
            pts,
            left,
        } = scratch;
        star.clear();
        star.extend(rows.live(v));
        let k = star.len();
        edges.clear();
        edges.extend(star.iter().map(|&t| {
            let [_, a, b] = rotate_to(tris[t as usize], v);
            (a, b)
        }));
        ring_of(edges, ring)?;
        // in-plane coordinates, turned so that the triangles are counter-clockwise
        let pv = coords[v as usize]?;
        let axis = (0..3).max_by_key(|&i| normal[i].abs()).unwrap_or(2);
        let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
        let flip = normal[axis] < 0;
        pts.clear();
        for &x in ring.iter() {
            let d = offset(coords[x as usize]?, pv);
            pts.push(if flip { [d[j], d[i]] } else { [d[i], d[j]] });
        }
        // the ring winds once around v (upward crossings of the ray +x from v)
        let crossings = (0..k)
            .filter(|&m| pts[m][1] < 0 && pts[(m + 1) % k][1] >= 0)
            .count();
        if crossings != 1 {
            return None;
        }
        let star = &*star;
        clip_ears(ring, pts, left, made, |p, q| {
            // a diagonal that is an edge already (outside the star) would be
            // shared by more than two triangles: checked, not assumed
            rows.live(p)
                .any(|t| !star.contains(&t) && tris[t as usize].contains(&q))
        })
    }
}

/// The ring of a star from its outer edges `(a, b)`, into `ring`: one cycle
/// through every edge, in their direction; `None` if they make no single cycle.
fn ring_of(edges: &mut [(u32, u32)], ring: &mut Vec<u32>) -> Option<()> {
    edges.sort_unstable();
    if edges.windows(2).any(|w| w[0].0 == w[1].0) {
        return None;
    }
    let next = |a: u32| -> Option<u32> {
        let i = edges.binary_search_by_key(&a, |e| e.0).ok()?;
        Some(edges[i].1)
    };
    let first = edges[0].0;
    ring.clear();
    let mut x = first;
    for _ in 0..edges.len() {
        ring.push(x);
        x = next(x)?;
    }
    (x == first).then_some(())
}

/// A triangulation of the counter-clockwise simple polygon `pts` (vertex ids
/// `ring`), into `made`: ears cut one by one, each the one with the shortest diagonal
/// (the first in ring order among equals) whose tip is strictly convex and
/// whose triangle holds no other vertex of the polygon (nor on its sides).
/// `None` if no ear can be cut, or the one to cut has a diagonal `taken`
/// (which an embedded surface never has: checked, not assumed).
fn clip_ears(
    ring: &[u32],
    pts: &[[i64; 2]],
    left: &mut Vec<usize>,
    made: &mut Vec<[u32; 3]>,
    taken: impl Fn(u32, u32) -> bool,
) -> Option<()> {
    left.clear();
    left.extend(0..ring.len());
    made.clear();
    while left.len() > 3 {
        let m = left.len();
        let mut best: Option<(i64, usize)> = None;
        for e in 0..m {
            let (p, x, q) = (left[(e + m - 1) % m], left[e], left[(e + 1) % m]);
            if orient(pts[p], pts[x], pts[q]) <= 0 {
                continue;
            }
            let d = [pts[q][0] - pts[p][0], pts[q][1] - pts[p][1]];
            let len = d[0] * d[0] + d[1] * d[1];
            if best.is_some_and(|(b, _)| b <= len) {
                continue;
            }
            let holds_other = left.iter().any(|&o| {
                o != p && o != x && o != q && in_closed_triangle(pts[o], pts[p], pts[x], pts[q])
            });
            if !holds_other {
                best = Some((len, e));
            }
        }
        let (_, e) = best?;
        let (p, x, q) = (left[(e + m - 1) % m], left[e], left[(e + 1) % m]);
        if taken(ring[p], ring[q]) {
            return None;
        }
        made.push([ring[p], ring[x], ring[q]]);
        left.remove(e);
    }
    let [p, x, q] = [left[0], left[1], left[2]];
    if orient(pts[p], pts[x], pts[q]) <= 0 {
        return None;
    }
    made.push([ring[p], ring[x], ring[q]]);
    Some(())
}

/// `p - origin`, widened for exact products.
#[inline]
fn offset(p: [i32; 3], origin: [i32; 3]) -> [i64; 3] {
    [0, 1, 2].map(|i| (p[i] - origin[i]) as i64)
}

/// Twice the signed area of (a, b, c): positive when counter-clockwise.
#[inline]
fn orient(a: [i64; 2], b: [i64; 2], c: [i64; 2]) -> i64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Whether `o` lies in the closed counter-clockwise triangle (a, b, c).
#[inline]
fn in_closed_triangle(o: [i64; 2], a: [i64; 2], b: [i64; 2], c: [i64; 2]) -> bool {
    orient(a, b, o) >= 0 && orient(b, c, o) >= 0 && orient(c, a, o) >= 0
}

#[inline]
fn cross(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Whether two normals point the same way. Lattice coordinates have 20
/// bits, so a normal's components have up to 43 and products of two normals
/// need 128 bits.
#[inline]
fn same_direction(a: [i64; 3], b: [i64; 3]) -> bool {
    let [a, b] = [a, b].map(|v| v.map(i128::from));
    let cross = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    cross == [0; 3] && a[0] * b[0] + a[1] * b[1] + a[2] * b[2] > 0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An n × n grid of lattice points in the plane z = 0 (x fastest), two
    /// counter-clockwise triangles per square, all in patch 0; the border
    /// points on a closed junction curve (so they stay).
    type Grid = (Vec<Option<[i32; 3]>>, Vec<[u32; 3]>, Vec<JunctionCurve>);

    fn grid(n: u32) -> Grid {
        let at = |x: u32, y: u32| x + n * y;
        let lattice = (0..n * n)
            .map(|i| Some([(i % n) as i32 * 2, (i / n) as i32 * 2, 0]))
            .collect();
        let mut tris = Vec::new();
        for y in 0..n - 1 {
            for x in 0..n - 1 {
                tris.push([at(x, y), at(x + 1, y), at(x + 1, y + 1)]);
                tris.push([at(x, y), at(x + 1, y + 1), at(x, y + 1)]);
            }
        }
        let mut border: Vec<u32> = (0..n - 1).map(|x| at(x, 0)).collect();
        border.extend((0..n - 1).map(|y| at(n - 1, y)));
        border.extend((1..n).rev().map(|x| at(x, n - 1)));
        border.extend((1..n).rev().map(|y| at(0, y)));
        let curve = JunctionCurve {
            vertices: border,
            closed: true,
            labels: vec![0, 1, 2],
        };
        (lattice, tris, vec![curve])
    }

    /// Twice the signed area (z component) of each triangle.
    fn areas(lattice: &[Option<[i32; 3]>], tris: &[[u32; 3]]) -> Vec<i64> {
        tris.iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| lattice[v as usize].unwrap().map(i64::from));
                (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
            })
            .collect()
    }

    #[test]
    fn a_flat_grid_keeps_only_its_border() {
        for n in [3, 4, 6] {
            let (lattice, mut tris, curves) = grid(n);
            let before: i64 = areas(&lattice, &tris).iter().sum();
            let mut patch = vec![0; tris.len()];
            let gone = dissolve_flat(lattice.as_slice(), &mut tris, &mut patch, &curves);
            assert_eq!(gone, ((n - 2) * (n - 2)) as usize, "n = {n}");
            // the border polygon's 4 (n - 1) points, in 4 (n - 1) - 2 triangles
            assert_eq!(tris.len(), (4 * (n - 1) - 2) as usize);
            let a = areas(&lattice, &tris);
            assert!(a.iter().all(|&x| x > 0), "a flat or flipped triangle");
            assert_eq!(a.iter().sum::<i64>(), before, "the same area");
            let interior = |v: u32| v % n > 0 && v % n < n - 1 && v / n > 0 && v / n < n - 1;
            assert!(tris.iter().flatten().all(|&v| !interior(v)));
        }
    }

    #[test]
    fn bent_mixed_or_curve_stars_stay() {
        let (lattice, tris0, curves) = grid(3);
        let centre = 4;
        // the centre raised: its triangles are in four planes
        let mut bent = lattice.clone();
        bent[centre] = Some([2, 2, 1]);
        // one triangle in another patch
        let mut mixed = vec![0; tris0.len()];
        mixed[3] = 1;
        // the centre on a junction curve
        let mut on_curve = curves.clone();
        on_curve.push(JunctionCurve {
            vertices: vec![1, 4, 7],
            closed: false,
            labels: vec![0, 1, 2],
        });
        for (lat, patch, curves) in [
            (&bent, vec![0; tris0.len()], &curves),
            (&lattice, mixed, &curves),
            (&lattice, vec![0; tris0.len()], &on_curve),
        ] {
            let mut tris = tris0.clone();
            let mut patch = patch;
            assert_eq!(
                dissolve_flat(lat.as_slice(), &mut tris, &mut patch, curves),
                0
            );
            assert_eq!(tris, tris0);
        }
    }

    #[test]
    fn a_star_folded_onto_itself_stays() {
        // the centre's ring winds twice around it: each triangle is fine,
        // together they cover the disk twice
        // once around at radius 100, then once more at radius 50, turned
        // by 45 degrees
        let mut lattice = vec![Some([0, 0, 0])];
        for (deg, r) in [
            (0, 100),
            (90, 100),
            (180, 100),
            (270, 100),
            (315, 50),
            (45, 50),
            (135, 50),
            (225, 50),
        ] {
            let a = (deg as f64).to_radians();
            lattice.push(Some([
                (r as f64 * a.cos()).round() as i32,
                (r as f64 * a.sin()).round() as i32,
                0,
            ]));
        }
        let k = 8;
        let tris0: Vec<[u32; 3]> = (0..k).map(|i| [0, 1 + i, 1 + (i + 1) % k]).collect();
        let mut tris = tris0.clone();
        let mut patch = vec![0; k as usize];
        assert_eq!(
            dissolve_flat(lattice.as_slice(), &mut tris, &mut patch, &[]),
            0
        );
        assert_eq!(tris, tris0);
    }

    #[test]
    fn normals_compare_exactly_at_any_size() {
        // in 64 bits the cross product's 2^64 would wrap to 0: "parallel"
        assert!(!same_direction([1 << 32, 0, 0], [1, 1 << 32, 0]));
        assert!(!same_direction(
            [1 << 42, 1 << 42, 3],
            [1 << 42, 1 << 42, 4]
        ));
        assert!(same_direction([3 << 40, 5 << 40, 7], [3 << 40, 5 << 40, 7]));
        assert!(!same_direction(
            [3 << 40, 5 << 40, 7],
            [-3 << 40, -5 << 40, -7]
        ));
    }

    #[test]
    fn ears_skip_points_on_their_diagonal() {
        // a square with a point in the middle of each side: the corners'
        // diagonals pass no other point, the cut leaves no flat triangle
        let ring = [0u32, 1, 2, 3, 4, 5, 6, 7];
        let pts = [
            [0, 0],
            [1, 0],
            [2, 0],
            [2, 1],
            [2, 2],
            [1, 2],
            [0, 2],
            [0, 1],
        ];
        let mut made = Vec::new();
        clip_ears(&ring, &pts, &mut Vec::new(), &mut made, |_, _| false).unwrap();
        assert_eq!(made.len(), 6);
        for t in &made {
            let [a, b, c] = t.map(|v| pts[v as usize]);
            assert!(orient(a, b, c) > 0, "{t:?}");
        }
        // a diagonal already taken everywhere: no ear
        assert!(clip_ears(&ring, &pts, &mut Vec::new(), &mut made, |_, _| true).is_none());
    }
}
