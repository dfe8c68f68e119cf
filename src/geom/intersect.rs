//! Self-intersection queries over triangle sets: one traversal of a [`Bvh`]
//! against itself over `f32` boxes refitted to the current triangles (only
//! pairs whose boxes overlap reach the exact test,
//! [`super::predicates::triangles_intersect`]), or one query per member for
//! small subsets. Answers are sorted and independent of the thread count.

use glam::DVec3;
use rayon::prelude::*;

use super::bvh::Bvh;
use super::predicates::{f32_down, f32_up, triangles_intersect};

/// Pairs of triangles that intersect other than along what they share.
pub fn self_intersections(positions: &[DVec3], triangles: &[[u32; 3]]) -> Vec<(u32, u32)> {
    intersections_of(positions, triangles, None)
}

/// [`self_intersections`] that also returns the BVH it built (over
/// [`triangle_box`]es), to be refitted and reused.
pub fn self_intersections_and_bvh(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
) -> (Vec<(u32, u32)>, Bvh) {
    let bvh = triangle_bvh(positions, triangles);
    (intersections_in(positions, triangles, &bvh, None), bvh)
}

/// Pairs (i, j), i < j, of intersecting triangles with at least one of them in
/// `subset` (all triangles when `None`).
pub fn intersections_of(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    subset: Option<&[u32]>,
) -> Vec<(u32, u32)> {
    intersections_in(
        positions,
        triangles,
        &triangle_bvh(positions, triangles),
        subset,
    )
}

/// A BVH over the [`triangle_box`]es of `triangles`.
pub fn triangle_bvh(positions: &[DVec3], triangles: &[[u32; 3]]) -> Bvh {
    let boxes: Vec<(DVec3, DVec3)> = triangles
        .par_iter()
        .map(|t| triangle_box(positions, *t))
        .collect();
    Bvh::new_f32(&boxes)
}

/// The bounding box of triangle `t`, padded a little so that touching
/// triangles are found.
pub fn triangle_box(positions: &[DVec3], t: [u32; 3]) -> (DVec3, DVec3) {
    let [a, b, c] = t.map(|v| positions[v as usize]);
    let pad = DVec3::splat(1e-9 * (1.0 + a.abs().max_element()));
    (a.min(b).min(c) - pad, a.max(b).max(c) + pad)
}

/// [`intersections_of`] with a BVH whose boxes contain the triangles as they
/// are now (built earlier, possibly over larger boxes: it is only used to find
/// candidates).
///
/// The answer is exactly the pairs whose [`triangle_box`]es overlap and which
/// [`triangles_intersect`] (called with the subset member first when only one
/// of the two is in `subset`, else with the smaller id first), sorted; it does
/// not depend on the number of threads.
///
/// The whole mesh (and large subsets) is checked by one traversal of the tree
/// against itself, over node and triangle boxes recomputed for the current
/// positions (in `f32`, rounded outward), so only pairs of triangles whose
/// boxes overlap reach the exact test. Small subsets query the tree once per
/// member.
pub fn intersections_in(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    bvh: &Bvh,
    subset: Option<&[u32]>,
) -> Vec<(u32, u32)> {
    assert_eq!(bvh.items.len(), triangles.len(), "a BVH over the triangles");
    if triangles.is_empty() {
        return Vec::new();
    }
    let mark: Option<Vec<bool>> = subset.map(|s| {
        let mut mark = vec![false; triangles.len()];
        for &i in s {
            mark[i as usize] = true;
        }
        mark
    });
    let mut pairs = match subset {
        Some(s) if s.len() * SMALL_SUBSET < triangles.len() => {
            let mark = mark.as_deref().expect("subset marks");
            let mut ids = s.to_vec();
            ids.par_sort_unstable();
            ids.dedup();
            match query_margin(bvh) {
                Some(margin) => ids
                    .par_iter()
                    .flat_map_iter(|&i| query_pairs(positions, triangles, bvh, mark, margin, i))
                    .collect(),
                None => SelfPairs::new(positions, triangles, bvh, Some(mark)).run(),
            }
        }
        _ => SelfPairs::new(positions, triangles, bvh, mark.as_deref()).run(),
    };
    pairs.par_sort_unstable();
    pairs
}

/// A subset smaller than the triangles over this is checked by one query per
/// member.
const SMALL_SUBSET: usize = 64;

/// Item count above which a subtree (or pair of subtrees) is split between
/// threads.
const PARALLEL_PAIRS: usize = 1 << 12;

/// Whether boxes `a` and `b` overlap (closed; boxes with NaN overlap all).
#[inline]
fn boxes_overlap(a: (DVec3, DVec3), b: (DVec3, DVec3)) -> bool {
    !(a.0.cmpgt(b.1).any() || a.1.cmplt(b.0).any())
}

/// The exact test of a candidate pair: their boxes overlap and the
/// triangles intersect (`s` is passed first to [`triangles_intersect`]).
#[inline]
fn exact_pair(positions: &[DVec3], s: [u32; 3], t: [u32; 3]) -> bool {
    // the boxes of triangles sharing a vertex overlap (both hold it)
    (s.iter().any(|v| t.contains(v))
        || boxes_overlap(triangle_box(positions, s), triangle_box(positions, t)))
        && triangles_intersect(positions, s, t)
}

/// The order in which candidate (`i`, `j`) is tested, or `None` when neither
/// is in the subset.
#[inline]
fn test_order(mark: Option<&[bool]>, i: u32, j: u32) -> Option<(u32, u32)> {
    match mark.map(|m| (m[i as usize], m[j as usize])) {
        Some((false, false)) => None,
        Some((true, false)) => Some((i, j)),
        Some((false, true)) => Some((j, i)),
        _ => Some((i.min(j), i.max(j))),
    }
}

/// How much to grow a triangle's padded box to query `bvh` (whose boxes hold
/// the triangles unpadded) so that every triangle whose padded box overlaps is
/// found: the largest pad of a triangle inside the root box. `None` when the
/// root box is not finite.
fn query_margin(bvh: &Bvh) -> Option<f64> {
    let root = bvh.nodes[0];
    let m = root.lo.abs().max(root.hi.abs()).max_element();
    let margin = 1e-9 * (1.0 + m) * 1.001;
    margin.is_finite().then_some(margin)
}

/// Pairs of subset member `i` with the triangles its box meets (each pair of
/// members once: by the smaller id).
fn query_pairs(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    bvh: &Bvh,
    mark: &[bool],
    margin: f64,
    i: u32,
) -> Vec<(u32, u32)> {
    let mut hits = Vec::new();
    let (lo, hi) = triangle_box(positions, triangles[i as usize]);
    let m = DVec3::splat(margin);
    bvh.query(lo - m, hi + m, |j| {
        if (!mark[j as usize] || j > i)
            && exact_pair(positions, triangles[i as usize], triangles[j as usize])
        {
            hits.push((i.min(j), i.max(j)));
        }
    });
    hits
}

/// An axis-aligned box in `f32` (rounded outward from `f64`): half the
/// memory of a `f64` box, for the broad phase of intersection tests.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Box32 {
    lo: [f32; 3],
    hi: [f32; 3],
}

impl Box32 {
    const EMPTY: Box32 = Box32 {
        lo: [f32::MAX; 3],
        hi: [f32::MIN; 3],
    };

    /// The smallest `f32` box holding `[lo, hi]` (NaN: everything).
    pub(crate) fn outward(lo: DVec3, hi: DVec3) -> Self {
        Box32 {
            lo: lo.to_array().map(f32_down),
            hi: hi.to_array().map(f32_up),
        }
    }

    #[inline]
    fn union(self, o: Box32) -> Box32 {
        Box32 {
            lo: [0, 1, 2].map(|k| self.lo[k].min(o.lo[k])),
            hi: [0, 1, 2].map(|k| self.hi[k].max(o.hi[k])),
        }
    }

    #[inline]
    pub(crate) fn overlaps(&self, o: &Box32) -> bool {
        (self.lo[0] <= o.hi[0])
            & (o.lo[0] <= self.hi[0])
            & (self.lo[1] <= o.hi[1])
            & (o.lo[1] <= self.hi[1])
            & (self.lo[2] <= o.hi[2])
            & (o.lo[2] <= self.hi[2])
    }
}

/// A node of [`SelfPairs`]: its box (refitted) and, as in [`Node`], its
/// items (leaf) or children (inner).
#[derive(Clone, Copy)]
struct Node32 {
    b: Box32,
    start: u32,
    count: u32,
}

/// The self-traversal: the tree of a [`Bvh`] with boxes refitted to the
/// current triangles, walked against itself (node pairs `(a, b)` whose boxes
/// overlap, each unordered pair once).
struct SelfPairs<'a> {
    /// The vertices in order of first use by the item slots, and the
    /// triangles per slot over them: the exact tests, walking the tree, then
    /// read memory mostly in order (the answers do not change: the ids are
    /// only compared for equality and the positions are the same).
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    items: &'a [u32],
    nodes: Vec<Node32>,
    /// Per item slot (leaf order): its triangle's box.
    item_boxes: Vec<Box32>,
    /// Per triangle: in the subset; per node: holds a subset member.
    mark: Option<(&'a [bool], Vec<bool>)>,
}

impl<'a> SelfPairs<'a> {
    fn new(
        positions: &'a [DVec3],
        triangles: &'a [[u32; 3]],
        bvh: &'a Bvh,
        mark: Option<&'a [bool]>,
    ) -> Self {
        let mut local = vec![u32::MAX; positions.len()];
        let mut local_positions = Vec::with_capacity(positions.len());
        let local_triangles: Vec<[u32; 3]> = bvh
            .items
            .iter()
            .map(|&t| {
                triangles[t as usize].map(|v| {
                    let l = &mut local[v as usize];
                    if *l == u32::MAX {
                        *l = local_positions.len() as u32;
                        local_positions.push(positions[v as usize]);
                    }
                    *l
                })
            })
            .collect();
        drop(local);
        let item_boxes: Vec<Box32> = local_triangles
            .par_iter()
            .map(|&t| {
                let (lo, hi) = triangle_box(&local_positions, t);
                Box32::outward(lo, hi)
            })
            .collect();
        let mut nodes: Vec<Node32> = bvh
            .nodes
            .iter()
            .map(|n| Node32 {
                b: Box32::EMPTY,
                start: n.start,
                count: n.count,
            })
            .collect();
        let mut flags = mark.map(|_| vec![false; nodes.len()]);
        // children come after their parent
        for ni in (0..nodes.len()).rev() {
            let n = nodes[ni];
            let range = n.start as usize..(n.start + n.count) as usize;
            if n.count > 0 {
                nodes[ni].b = item_boxes[range.clone()]
                    .iter()
                    .fold(Box32::EMPTY, |a, b| a.union(*b));
                if let (Some(f), Some(m)) = (flags.as_mut(), mark) {
                    f[ni] = bvh.items[range].iter().any(|&t| m[t as usize]);
                }
            } else if !bvh.items.is_empty() {
                let c = n.start as usize;
                nodes[ni].b = nodes[c].b.union(nodes[c + 1].b);
                if let Some(f) = flags.as_mut() {
                    f[ni] = f[c] || f[c + 1];
                }
            }
        }
        SelfPairs {
            positions: local_positions,
            triangles: local_triangles,
            items: &bvh.items,
            nodes,
            item_boxes,
            mark: mark.zip(flags),
        }
    }

    fn run(&self) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        self.within(0, self.items.len(), &mut out);
        out
    }

    #[inline]
    fn marked(&self, node: usize) -> bool {
        self.mark.as_ref().is_none_or(|(_, f)| f[node])
    }

    /// Whether the pair (`a`, `b`) of nodes is to be walked.
    #[inline(always)]
    fn meet(&self, a: usize, b: usize) -> bool {
        self.nodes[a].b.overlaps(&self.nodes[b].b) && (self.marked(a) || self.marked(b))
    }

    /// Candidate item slots `a`, `b` (boxes overlapping): the exact test.
    #[inline]
    fn pair(&self, a: usize, b: usize, out: &mut Vec<(u32, u32)>) {
        let (i, j) = (self.items[a], self.items[b]);
        if let Some((first, _)) = test_order(self.mark.as_ref().map(|m| m.0), i, j) {
            let (s, t) = (self.triangles[a], self.triangles[b]);
            let (s, t) = if first == i { (s, t) } else { (t, s) };
            if exact_pair(&self.positions, s, t) {
                out.push((i.min(j), i.max(j)));
            }
        }
    }

    /// Pairs within node `ni` (over `size` items).
    fn within(&self, ni: usize, size: usize, out: &mut Vec<(u32, u32)>) {
        if !self.marked(ni) {
            return;
        }
        let n = self.nodes[ni];
        if n.count > 0 {
            let (s, e) = (n.start as usize, (n.start + n.count) as usize);
            for a in s..e {
                let ba = self.item_boxes[a];
                for b in a + 1..e {
                    if ba.overlaps(&self.item_boxes[b]) {
                        self.pair(a, b, out);
                    }
                }
            }
            return;
        }
        let (l, r) = (n.start as usize, n.start as usize + 1);
        let (sl, sr) = (size / 2, size - size / 2);
        let meet = self.meet(l, r);
        if size >= PARALLEL_PAIRS {
            let ((mut x, y), z) = rayon::join(
                || {
                    rayon::join(
                        || {
                            let mut v = Vec::new();
                            self.within(l, sl, &mut v);
                            v
                        },
                        || {
                            let mut v = Vec::new();
                            self.within(r, sr, &mut v);
                            v
                        },
                    )
                },
                || {
                    let mut v = Vec::new();
                    if meet {
                        self.across(l, sl, r, sr, &mut v);
                    }
                    v
                },
            );
            x.extend(y);
            x.extend(z);
            out.extend(x);
        } else {
            self.within(l, sl, out);
            self.within(r, sr, out);
            if meet {
                self.across(l, sl, r, sr, out);
            }
        }
    }

    /// Pairs between the disjoint nodes `a` and `b` (over `sa`, `sb` items),
    /// which [`SelfPairs::meet`].
    fn across(&self, a: usize, sa: usize, b: usize, sb: usize, out: &mut Vec<(u32, u32)>) {
        let (na, nb) = (self.nodes[a], self.nodes[b]);
        if na.count > 0 && nb.count > 0 {
            for x in na.start as usize..(na.start + na.count) as usize {
                let bx = self.item_boxes[x];
                if !bx.overlaps(&nb.b) {
                    continue;
                }
                for y in nb.start as usize..(nb.start + nb.count) as usize {
                    if bx.overlaps(&self.item_boxes[y]) {
                        self.pair(x, y, out);
                    }
                }
            }
            return;
        }
        // split the larger node (an inner one)
        let split_a = nb.count > 0 || (na.count == 0 && sa >= sb);
        let (n, s, other, so) = if split_a {
            (na, sa, b, sb)
        } else {
            (nb, sb, a, sa)
        };
        let (l, r) = (n.start as usize, n.start as usize + 1);
        let (sl, sr) = (s / 2, s - s / 2);
        let (ml, mr) = (self.meet(l, other), self.meet(r, other));
        if ml && mr && s >= PARALLEL_PAIRS && so >= PARALLEL_PAIRS {
            let (mut x, y) = rayon::join(
                || {
                    let mut v = Vec::new();
                    self.across(l, sl, other, so, &mut v);
                    v
                },
                || {
                    let mut v = Vec::new();
                    self.across(r, sr, other, so, &mut v);
                    v
                },
            );
            x.extend(y);
            out.extend(x);
        } else {
            if ml {
                self.across(l, sl, other, so, out);
            }
            if mr {
                self.across(r, sr, other, so, out);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossing_and_touching() {
        let p = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
            DVec3::new(0.5, 0.5, -1.0),
            DVec3::new(0.5, 0.5, 1.0),
            DVec3::new(3.0, 3.0, 1.0),
            DVec3::new(0.0, -2.0, 0.0),
        ];
        assert!(triangles_intersect(&p, [0, 1, 2], [3, 4, 5]));
        // sharing an edge, unfolded: no
        assert!(!triangles_intersect(&p, [0, 1, 2], [1, 0, 6]));
        // folded onto each other: yes
        let mut q = p.clone();
        q[6] = DVec3::new(0.5, 1.0, 0.0);
        assert!(triangles_intersect(&q, [0, 1, 2], [1, 0, 6]));
        let found = self_intersections(&p, &[[0, 1, 2], [3, 4, 5], [1, 0, 6]]);
        assert_eq!(found, vec![(0, 1)]);
    }

    use crate::geom::test_rng::Rng;

    /// A soup of small triangles over a pool of points that they share (so
    /// there are shared vertices and edges), some of them on a few planes with
    /// quantised coordinates (coplanar and collinear cases), some degenerate.
    fn soup(n: usize, seed: u64) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let mut r = Rng(seed);
        let m = n.max(4);
        let positions: Vec<DVec3> = (0..m)
            .map(|k| match k % 3 {
                // on the plane z = 0 or x = y, coordinates in quarters
                0 => {
                    let (x, y) = ((r.below(24) as f64) * 0.25, (r.below(24) as f64) * 0.25);
                    if r.next() < 0.5 {
                        DVec3::new(x, y, 0.0)
                    } else {
                        DVec3::new(x, x, y)
                    }
                }
                _ => DVec3::new(r.next(), r.next(), r.next()) * 6.0,
            })
            .collect();
        // some points twice (zero-length edges, zero-area triangles)
        let mut positions = positions;
        for k in (5..m).step_by(17) {
            positions[k] = positions[k - 1];
        }
        let tris = (0..n)
            .map(|_| {
                let a = r.below(m);
                // near neighbours in the pool share vertices often
                let near = |r: &mut Rng| ((a + 1 + r.below(12)) % m) as u32;
                [a as u32, near(&mut r), near(&mut r)]
            })
            // (a triangle repeating a vertex id is not tested: see the report)
            .filter(|t: &[u32; 3]| t[0] != t[1] && t[1] != t[2] && t[2] != t[0])
            .collect();
        (positions, tris)
    }

    /// A triangulated grid surface, jittered and folded (many neighbours
    /// crossing each other).
    fn crumpled(side: usize, seed: u64, amount: f64) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let mut r = Rng(seed);
        let positions: Vec<DVec3> = (0..side * side)
            .map(|k| {
                let (x, y) = ((k % side) as f64, (k / side) as f64);
                let fold = (x * 0.7).sin() * 2.0;
                DVec3::new(x, y, fold)
                    + DVec3::new(r.next() - 0.5, r.next() - 0.5, r.next() - 0.5) * amount
            })
            .collect();
        let mut tris = Vec::new();
        for y in 0..side - 1 {
            for x in 0..side - 1 {
                let v = (y * side + x) as u32;
                let s = side as u32;
                tris.push([v, v + 1, v + s + 1]);
                tris.push([v, v + s + 1, v + s]);
            }
        }
        (positions, tris)
    }

    /// Pairs by testing every pair: boxes overlap and the triangles intersect
    /// (the subset member first, else the smaller id).
    fn brute_force(p: &[DVec3], t: &[[u32; 3]], subset: Option<&[u32]>) -> Vec<(u32, u32)> {
        let mut mark = vec![subset.is_none(); t.len()];
        for &i in subset.unwrap_or(&[]) {
            mark[i as usize] = true;
        }
        let mut pairs = Vec::new();
        for i in 0..t.len() as u32 {
            for j in i + 1..t.len() as u32 {
                let (a, b) = match (mark[i as usize], mark[j as usize]) {
                    (false, false) => continue,
                    (false, true) => (j, i),
                    _ => (i, j),
                };
                let (s, u) = (t[a as usize], t[b as usize]);
                if boxes_overlap(triangle_box(p, s), triangle_box(p, u))
                    && triangles_intersect(p, s, u)
                {
                    pairs.push((i, j));
                }
            }
        }
        pairs
    }

    fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(f)
    }

    #[test]
    fn pairs_match_brute_force_for_any_thread_count() {
        let mut cases: Vec<(Vec<DVec3>, Vec<[u32; 3]>)> = Vec::new();
        for (n, seed) in [
            (0, 1),
            (1, 2),
            (3, 3),
            (40, 4),
            (300, 5),
            (1500, 6),
            (5000, 7),
        ] {
            cases.push(soup(n, seed));
        }
        for (side, seed, amount) in [(12, 8, 0.0), (30, 9, 0.6), (50, 10, 1.5)] {
            cases.push(crumpled(side, seed, amount));
        }
        let mut total = 0;
        for (ci, (p, t)) in cases.iter().enumerate() {
            let n = t.len() as u32;
            let mut r = Rng(100 + ci as u64);
            let small: Vec<u32> = (0..n).filter(|_| r.next() < 0.01).collect();
            let half: Vec<u32> = (0..n).filter(|_| r.next() < 0.5).collect();
            let mut repeated = small.clone();
            repeated.extend(small.iter().rev());
            for subset in [None, Some(&small[..]), Some(&half[..])] {
                let want = brute_force(p, t, subset);
                total += want.len();
                for threads in [1, 2, 3] {
                    let got = in_pool(threads, || intersections_of(p, t, subset));
                    assert_eq!(
                        got,
                        want,
                        "case {ci}, {threads} threads, subset {:?}",
                        subset.map(|s| s.len())
                    );
                }
                // with a BVH over larger boxes (as after a refit over two positions)
                let moved: Vec<DVec3> = p.iter().map(|q| *q + DVec3::new(0.3, -0.2, 0.1)).collect();
                let boxes: Vec<(DVec3, DVec3)> = t
                    .iter()
                    .map(|&tri| {
                        let (a, b) = (triangle_box(p, tri), triangle_box(&moved, tri));
                        (a.0.min(b.0), a.1.max(b.1))
                    })
                    .collect();
                let bvh = Bvh::new(&boxes);
                assert_eq!(
                    intersections_in(p, t, &bvh, subset),
                    want,
                    "case {ci}, refitted BVH"
                );
            }
            // a subset listing members twice gives each pair once
            assert_eq!(
                intersections_of(p, t, Some(&repeated)),
                brute_force(p, t, Some(&small))
            );
        }
        assert!(total > 1000, "the cases have crossings ({total})");
    }
}
