//! Self-intersection test: a bounding-volume hierarchy over triangles and an
//! exact-enough triangle–triangle test that understands shared vertices and
//! edges (neighbours touching along what they share is not an intersection).

use glam::DVec3;
use rayon::prelude::*;

use super::InterfaceMesh;
use super::validate::Check;

/// A flat BVH over triangle bounding boxes (median split on the longest axis).
pub struct Bvh {
    nodes: Vec<Node>,
    /// Triangle ids in leaf order.
    pub items: Vec<u32>,
}

#[derive(Clone, Copy)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: first item and count; inner: left child index and 0 (right = left + 1).
    start: u32,
    count: u32,
}

const LEAF: usize = 4;

/// Item count below which a subtree is built on the calling thread.
const PARALLEL_BUILD: usize = 1 << 14;

/// Number of nodes below the root of a median-split tree over `m` items
/// (a full binary tree: twice its leaves, less the root and one).
fn descendants(m: usize) -> usize {
    // Repeated halving leaves at most two distinct sizes per level, so the
    // leaves are counted level by level in O(log m).
    let mut level = [(m, 1usize), (0, 0)];
    let mut leaves = 0;
    while level[0].1 + level[1].1 > 0 {
        let mut next = [(0usize, 0usize); 2];
        for (size, count) in level {
            if count == 0 {
                continue;
            }
            if size <= LEAF {
                leaves += count;
                continue;
            }
            for half in [size / 2, size - size / 2] {
                match next.iter_mut().find(|e| e.1 == 0 || e.0 == half) {
                    Some(e) => *e = (half, e.1 + count),
                    None => unreachable!("halving gives at most two sizes per level"),
                }
            }
        }
        level = next;
    }
    2 * leaves - 2
}

/// An item while building: its box centre (doubled) and id, kept together so
/// that the median selections read memory in order.
type Entry<C> = ([C; 3], u32);

/// A coordinate type of build entries (`f64`, or `f32` for less memory
/// traffic where the exact tree does not matter).
trait Coord: Copy + Send + Sync + PartialOrd {
    const LOWEST: Self;
    const HIGHEST: Self;
    fn total(&self, o: &Self) -> std::cmp::Ordering;
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
}

macro_rules! coord {
    ($t:ty) => {
        impl Coord for $t {
            const LOWEST: Self = <$t>::MIN;
            const HIGHEST: Self = <$t>::MAX;
            #[inline]
            fn total(&self, o: &Self) -> std::cmp::Ordering {
                self.total_cmp(o)
            }
            #[inline]
            fn min(self, o: Self) -> Self {
                <$t>::min(self, o)
            }
            #[inline]
            fn max(self, o: Self) -> Self {
                <$t>::max(self, o)
            }
            #[inline]
            fn sub(self, o: Self) -> Self {
                self - o
            }
        }
    };
}
coord!(f64);
coord!(f32);

/// Fills `node` (over `entries`, the first of which is item number `first`)
/// and its descendants in `below`, whose first node has index `below_index`.
/// Node boxes are made bottom-up from the item boxes.
fn build_subtree<C: Coord>(
    node: &mut Node,
    below: &mut [Node],
    below_index: u32,
    entries: &mut [Entry<C>],
    first: u32,
    boxes: &[(DVec3, DVec3)],
) {
    if entries.len() <= LEAF {
        let (lo, hi) = entries.iter().fold(
            (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
            |(lo, hi), e| (lo.min(boxes[e.1 as usize].0), hi.max(boxes[e.1 as usize].1)),
        );
        *node = Node {
            lo,
            hi,
            start: first,
            count: entries.len() as u32,
        };
        return;
    }
    let (clo, chi) =
        entries
            .iter()
            .fold(([C::HIGHEST; 3], [C::LOWEST; 3]), |(mut lo, mut hi), e| {
                for k in 0..3 {
                    lo[k] = lo[k].min(e.0[k]);
                    hi[k] = hi[k].max(e.0[k]);
                }
                (lo, hi)
            });
    let ext = [0, 1, 2].map(|k| chi[k].sub(clo[k]));
    let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
        0
    } else if ext[1] >= ext[2] {
        1
    } else {
        2
    };
    let mid = entries.len() / 2;
    entries.select_nth_unstable_by(mid, |a, b| a.0[axis].total(&b.0[axis]).then(a.1.cmp(&b.1)));
    let (children, rest) = below.split_at_mut(2);
    let (left, right) = children.split_at_mut(1);
    let left_below = descendants(mid);
    let (left_rest, right_rest) = rest.split_at_mut(left_below);
    let (left_entries, right_entries) = entries.split_at_mut(mid);
    let (left, right) = (&mut left[0], &mut right[0]);
    let mut left_job =
        || build_subtree(left, left_rest, below_index + 2, left_entries, first, boxes);
    let mut right_job = || {
        build_subtree(
            right,
            right_rest,
            below_index + 2 + left_below as u32,
            right_entries,
            first + mid as u32,
            boxes,
        )
    };
    if items_len_parallel(mid) {
        rayon::join(left_job, right_job);
    } else {
        left_job();
        right_job();
    }
    *node = Node {
        lo: left.lo.min(right.lo),
        hi: left.hi.max(right.hi),
        start: below_index,
        count: 0,
    };
}

#[inline]
fn items_len_parallel(half: usize) -> bool {
    half >= PARALLEL_BUILD
}

impl Bvh {
    /// Builds the hierarchy over boxes `boxes[i] = (lo, hi)`.
    ///
    /// Subtrees are built in parallel; the layout does not depend on the
    /// thread count: the shape of a median-split tree depends only on the item
    /// count, so every subtree gets its node range up front (the two children
    /// of an inner node are adjacent, followed by the left child's descendants,
    /// then the right child's).
    pub fn new(boxes: &[(DVec3, DVec3)]) -> Self {
        let entries: Vec<Entry<f64>> = boxes
            .par_iter()
            .enumerate()
            .map(|(i, b)| ((b.0 + b.1).to_array(), i as u32))
            .collect();
        Self::from_entries(entries, boxes)
    }

    /// [`Bvh::new`] splitting at medians of the box centres rounded to `f32`
    /// (half the memory traffic; a slightly different tree, as good).
    fn new_f32(boxes: &[(DVec3, DVec3)]) -> Self {
        let entries: Vec<Entry<f32>> = boxes
            .par_iter()
            .enumerate()
            .map(|(i, b)| ((b.0 + b.1).to_array().map(|x| x as f32), i as u32))
            .collect();
        Self::from_entries(entries, boxes)
    }

    fn from_entries<C: Coord>(mut entries: Vec<Entry<C>>, boxes: &[(DVec3, DVec3)]) -> Self {
        let empty = Node {
            lo: DVec3::ZERO,
            hi: DVec3::ZERO,
            start: 0,
            count: 0,
        };
        let mut nodes = vec![empty; 1 + descendants(boxes.len())];
        let (root, rest) = nodes.split_at_mut(1);
        build_subtree(&mut root[0], rest, 1, &mut entries, 0, boxes);
        Bvh {
            nodes,
            items: entries.into_iter().map(|e| e.1).collect(),
        }
    }

    /// Recomputes every node's box from new item boxes, keeping the tree
    /// (for items that moved a little: queries stay exact, only slower if
    /// the items moved far).
    pub fn refit(&mut self, boxes: &[(DVec3, DVec3)]) {
        assert_eq!(boxes.len(), self.items.len(), "one box per item");
        // children come after their parent in the layout
        for ni in (0..self.nodes.len()).rev() {
            let n = self.nodes[ni];
            let (lo, hi) = if n.count > 0 {
                self.items[n.start as usize..(n.start + n.count) as usize]
                    .iter()
                    .fold(
                        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
                        |(lo, hi), &i| (lo.min(boxes[i as usize].0), hi.max(boxes[i as usize].1)),
                    )
            } else if self.items.is_empty() {
                continue;
            } else {
                let (l, r) = (
                    self.nodes[n.start as usize],
                    self.nodes[n.start as usize + 1],
                );
                (l.lo.min(r.lo), l.hi.max(r.hi))
            };
            self.nodes[ni].lo = lo;
            self.nodes[ni].hi = hi;
        }
    }

    /// The item nearest to `p`: `dist2(i)` gives the squared distance from `p`
    /// to item `i`; boxes farther than the best so far are skipped. Returns the
    /// item and its squared distance.
    pub fn nearest(&self, p: DVec3, dist2: impl FnMut(u32) -> f64) -> Option<(u32, f64)> {
        if self.items.is_empty() {
            return None;
        }
        self.nearest_below(p, None, dist2)
    }

    /// [`Bvh::nearest`] starting from a known candidate `(item, squared
    /// distance)`: only boxes nearer than it are visited, so a good guess
    /// (from a local search) makes the query cheap. Returns the guess if
    /// nothing is nearer.
    pub fn nearest_below(
        &self,
        p: DVec3,
        guess: Option<(u32, f64)>,
        mut dist2: impl FnMut(u32) -> f64,
    ) -> Option<(u32, f64)> {
        if self.items.is_empty() {
            return guess;
        }
        let box2 = |n: &Node| (n.lo - p).max(p - n.hi).max(DVec3::ZERO).length_squared();
        let mut best: Option<(u32, f64)> = guess;
        // median splits keep the depth near log2(n / LEAF); 128 levels is ample
        let mut stack = [(0u32, 0f64); 128];
        stack[0] = (0, box2(&self.nodes[0]));
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (ni, d) = stack[top];
            if best.is_some_and(|b| d >= b.1) {
                continue;
            }
            let n = self.nodes[ni as usize];
            if n.count > 0 {
                for &i in &self.items[n.start as usize..(n.start + n.count) as usize] {
                    let di = dist2(i);
                    if best.is_none_or(|b| di < b.1) {
                        best = Some((i, di));
                    }
                }
            } else {
                let (l, r) = (n.start, n.start + 1);
                let (dl, dr) = (box2(&self.nodes[l as usize]), box2(&self.nodes[r as usize]));
                // visit the nearer child first (pushed last)
                let (first, second) = if dl < dr {
                    ((l, dl), (r, dr))
                } else {
                    ((r, dr), (l, dl))
                };
                stack[top] = second;
                stack[top + 1] = first;
                top += 2;
            }
        }
        best
    }

    /// Whether `f` holds for some item whose box overlaps `[lo, hi]` (stops at
    /// the first).
    pub fn any(&self, lo: DVec3, hi: DVec3, mut f: impl FnMut(u32) -> bool) -> bool {
        if self.items.is_empty() {
            return false;
        }
        let mut stack = [0u32; 128];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = self.nodes[stack[top] as usize];
            if n.lo.cmpgt(hi).any() || n.hi.cmplt(lo).any() {
                continue;
            }
            if n.count > 0 {
                if self.items[n.start as usize..(n.start + n.count) as usize]
                    .iter()
                    .any(|&i| f(i))
                {
                    return true;
                }
            } else {
                stack[top] = n.start;
                stack[top + 1] = n.start + 1;
                top += 2;
            }
        }
        false
    }

    /// Calls `f` with every item whose box overlaps `[lo, hi]` (and possibly
    /// others of the same leaf: `f` makes the exact test).
    pub fn query(&self, lo: DVec3, hi: DVec3, mut f: impl FnMut(u32)) {
        self.any(lo, hi, |i| {
            f(i);
            false
        });
    }
}

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

/// An axis-aligned box in `f32`.
#[derive(Clone, Copy)]
struct Box32 {
    lo: [f32; 3],
    hi: [f32; 3],
}

impl Box32 {
    const EMPTY: Box32 = Box32 {
        lo: [f32::MAX; 3],
        hi: [f32::MIN; 3],
    };

    /// The smallest `f32` box holding `[lo, hi]` (NaN: everything).
    fn outward(lo: DVec3, hi: DVec3) -> Self {
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
    fn overlaps(&self, o: &Box32) -> bool {
        (self.lo[0] <= o.hi[0])
            & (o.lo[0] <= self.hi[0])
            & (self.lo[1] <= o.hi[1])
            & (o.lo[1] <= self.hi[1])
            & (self.lo[2] <= o.hi[2])
            & (o.lo[2] <= self.hi[2])
    }
}

/// The largest `f32` not above `x` (NaN: the lowest `f32`).
pub(crate) fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    if f.is_nan() {
        return f32::MIN;
    }
    if (f as f64) <= x {
        f
    } else if f == f32::INFINITY {
        f32::MAX
    } else {
        f - (f.abs() * f32::EPSILON).max(f32::MIN_POSITIVE)
    }
}

/// The smallest `f32` not below `x` (NaN: the largest `f32`).
pub(crate) fn f32_up(x: f64) -> f32 {
    -f32_down(-x)
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

/// The validator's check.
pub fn check_self_intersections(mesh: &InterfaceMesh) -> Check {
    let mut c = Check {
        name: "no self-intersections",
        failures: 0,
        examples: Vec::new(),
    };
    for (i, j) in self_intersections(&mesh.positions, &mesh.triangles) {
        c.failures += 1;
        if c.examples.len() < 8 {
            c.examples.push(format!(
                "triangles {i} {:?} and {j} {:?}",
                mesh.triangles[i as usize], mesh.triangles[j as usize]
            ));
        }
    }
    c
}

/// Whether triangles `s` and `t` intersect beyond their shared vertices/edge.
pub fn triangles_intersect(p: &[DVec3], s: [u32; 3], t: [u32; 3]) -> bool {
    let mut shared = [(0usize, 0usize); 3];
    let mut n_shared = 0;
    for i in 0..3 {
        for j in 0..3 {
            if s[i] == t[j] {
                shared[n_shared] = (i, j);
                n_shared += 1;
            }
        }
    }
    let shared = &shared[..n_shared];
    // (built element by element: `map` copies through the stack in a way
    // that stalls store forwarding)
    let sp = [p[s[0] as usize], p[s[1] as usize], p[s[2] as usize]];
    let tp = [p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]];
    if n_shared < 2 && (separated_by_plane(&sp, &tp) || separated_by_plane(&tp, &sp)) {
        return false;
    }
    match shared.len() {
        0 => disjoint_intersect(&sp, &tp),
        1 => {
            let (i, j) = shared[0];
            // the opposite edge of each against the other triangle
            let (s1, s2) = (sp[(i + 1) % 3], sp[(i + 2) % 3]);
            let (t1, t2) = (tp[(j + 1) % 3], tp[(j + 2) % 3]);
            segment_hits_triangle(s1, s2, &tp)
                || segment_hits_triangle(t1, t2, &sp)
                || coplanar_wedges_overlap(sp[i], s1, s2, t1, t2)
        }
        2 => {
            // folded onto each other: coplanar with both free vertices on one side
            let free_s = (0..3)
                .find(|&i| !shared.iter().any(|x| x.0 == i))
                .expect("one free vertex");
            let free_t = (0..3)
                .find(|&j| !shared.iter().any(|x| x.1 == j))
                .expect("one free vertex");
            let (a, b) = (sp[shared[0].0], sp[shared[1].0]);
            let n = (b - a).cross(sp[free_s] - a);
            if off_plane(n, b - a, tp[free_t] - a) {
                return false;
            }
            // same side of the shared edge within the plane
            let e = b - a;
            let side = |q: DVec3| e.cross(q - a).dot(n);
            side(sp[free_s]) * side(tp[free_t]) > 0.0
        }
        _ => true,
    }
}

/// Whether `w` is off the plane of normal `n` (= `e × f` for the shared edge
/// `e`): `|n·w| / (|n| |e|) > 1e-9` (denominator at least `1e-300`). Compared
/// squared first; the quotient is computed only when the two are within
/// rounding of each other (the answer is the same).
#[inline]
fn off_plane(n: DVec3, e: DVec3, w: DVec3) -> bool {
    let num = n.dot(w);
    let scale = e.length_squared().max(1e-300);
    let n2 = n.length_squared();
    const SAFE: std::ops::RangeInclusive<f64> = 1e-250..=1e250;
    if SAFE.contains(&n2) && SAFE.contains(&scale) && SAFE.contains(&(n2 * scale)) {
        let (num2, lim) = (num * num, 1e-18 * (n2 * scale));
        if num2 > lim * (1.0 + 1e-9) {
            return true;
        }
        if num2 < lim * (1.0 - 1e-9) {
            return false;
        }
    }
    off_plane_reference(n, e, w)
}

/// [`off_plane`] as it was written first.
fn off_plane_reference(n: DVec3, e: DVec3, w: DVec3) -> bool {
    let scale = e.length_squared().max(1e-300);
    let off = n.dot(w) / (n.length() * scale.sqrt()).max(1e-300);
    off.abs() > 1e-9
}

/// Whether all of `t` lies strictly on one side of the plane of `s` (then they
/// cannot intersect; shared vertices lie on the plane and do not count).
///
/// A vertex of `t` is on the plane when its distance `d` (scaled by the normal
/// `n = (s1 - s0) × (s2 - s0)`) is at most `eps = 1e-12 |n| max|t_k - s0|`.
/// `d²` is first compared with `eps²` (no square roots); only when they are
/// within rounding of each other is `eps` computed (the answer is the same).
fn separated_by_plane(s: &[DVec3; 3], t: &[DVec3; 3]) -> bool {
    let n = (s[1] - s[0]).cross(s[2] - s[0]);
    let r = [t[0] - s[0], t[1] - s[0], t[2] - s[0]];
    let d = [n.dot(r[0]), n.dot(r[1]), n.dot(r[2])];
    let n2 = n.length_squared();
    let l2 = r[0]
        .length_squared()
        .max(r[1].length_squared())
        .max(r[2].length_squared());
    // side of each vertex: 1 above, -1 below, 0 on the plane
    let mut side = [0i8; 3];
    let mut decided = false;
    const SAFE: std::ops::RangeInclusive<f64> = 1e-250..=1e250;
    if SAFE.contains(&n2) && SAFE.contains(&l2) && SAFE.contains(&(n2 * l2)) {
        // eps² with a margin far above the rounding of either form
        let e2 = 1e-24 * (n2 * l2);
        let (above, below) = (e2 * (1.0 + 1e-9), e2 * (1.0 - 1e-9));
        decided = true;
        for k in 0..3 {
            let d2 = d[k] * d[k];
            if d2 > above {
                side[k] = if d[k] > 0.0 { 1 } else { -1 };
            } else if d2 >= below || d2.is_nan() {
                decided = false;
                break;
            }
        }
    }
    if !decided {
        let scale = n.length() * r[0].length().max(r[1].length()).max(r[2].length());
        let eps = 1e-12 * scale;
        side = d.map(|x| {
            if x > eps {
                1
            } else if x < -eps {
                -1
            } else {
                0
            }
        });
    }
    let pos = side.iter().filter(|&&x| x > 0).count();
    let neg = side.iter().filter(|&&x| x < 0).count();
    let zero = 3 - pos - neg;
    // vertices on the plane may be shared ones: separated if the others agree and
    // those on the plane are vertices of s
    (pos + zero == 3 && pos > 0 || neg + zero == 3 && neg > 0)
        && (0..3).all(|k| side[k] != 0 || s.contains(&t[k]))
}

/// [`separated_by_plane`] as it was written first (the reference for tests).
#[cfg(test)]
fn separated_by_plane_reference(s: &[DVec3; 3], t: &[DVec3; 3]) -> bool {
    let n = (s[1] - s[0]).cross(s[2] - s[0]);
    let scale = n.length()
        * (t[0] - s[0])
            .length()
            .max((t[1] - s[0]).length())
            .max((t[2] - s[0]).length());
    let eps = 1e-12 * scale;
    let d = t.map(|q| n.dot(q - s[0]));
    let pos = d.iter().filter(|&&x| x > eps).count();
    let neg = d.iter().filter(|&&x| x < -eps).count();
    let zero = 3 - pos - neg;
    (pos + zero == 3 && pos > 0 || neg + zero == 3 && neg > 0)
        && (0..3).all(|k| d[k].abs() > eps || s.contains(&t[k]))
}

fn disjoint_intersect(s: &[DVec3; 3], t: &[DVec3; 3]) -> bool {
    for k in 0..3 {
        if segment_hits_triangle(s[k], s[(k + 1) % 3], t)
            || segment_hits_triangle(t[k], t[(k + 1) % 3], s)
        {
            return true;
        }
    }
    coplanar_overlap(s, t)
}

/// Segment [a, b] against triangle t (closed), non-coplanar case.
fn segment_hits_triangle(a: DVec3, b: DVec3, t: &[DVec3; 3]) -> bool {
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let d = b - a;
    let h = d.cross(e2);
    let det = e1.dot(h);
    let scale = e1.length() * e2.length() * d.length();
    if det.abs() <= 1e-12 * scale {
        return false; // parallel: handled by the coplanar tests
    }
    let inv = 1.0 / det;
    let sv = a - t[0];
    let u = sv.dot(h) * inv;
    let q = sv.cross(e1);
    let v = d.dot(q) * inv;
    let w = e2.dot(q) * inv;
    let eps = 1e-12;
    u >= -eps && v >= -eps && u + v <= 1.0 + eps && (-eps..=1.0 + eps).contains(&w)
}

fn normal(t: &[DVec3; 3]) -> DVec3 {
    (t[1] - t[0]).cross(t[2] - t[0])
}

fn is_coplanar(s: &[DVec3; 3], t: &[DVec3; 3]) -> bool {
    let n = normal(s);
    let len = n.length();
    if len == 0.0 {
        return false;
    }
    let size = (s[1] - s[0]).length().max((s[2] - s[0]).length());
    t.iter()
        .all(|q| (n.dot(*q - s[0]) / len).abs() <= 1e-9 * size)
}

/// Projects onto the plane of the dominant normal axis.
fn project(n: DVec3, q: DVec3) -> [f64; 2] {
    let a = n.abs();
    if a.x >= a.y && a.x >= a.z {
        [q.y, q.z]
    } else if a.y >= a.z {
        [q.x, q.z]
    } else {
        [q.x, q.y]
    }
}

fn orient2(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

fn segments_cross_2d(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let (d1, d2) = (orient2(c, d, a), orient2(c, d, b));
    let (d3, d4) = (orient2(a, b, c), orient2(a, b, d));
    d1 * d2 < 0.0 && d3 * d4 < 0.0
}

fn point_in_triangle_2d(p: [f64; 2], t: [[f64; 2]; 3]) -> bool {
    let (a, b, c) = (
        orient2(t[0], t[1], p),
        orient2(t[1], t[2], p),
        orient2(t[2], t[0], p),
    );
    (a > 0.0 && b > 0.0 && c > 0.0) || (a < 0.0 && b < 0.0 && c < 0.0)
}

fn coplanar_overlap(s: &[DVec3; 3], t: &[DVec3; 3]) -> bool {
    if !is_coplanar(s, t) {
        return false;
    }
    let n = normal(s);
    let ps = s.map(|q| project(n, q));
    let pt = t.map(|q| project(n, q));
    for i in 0..3 {
        for j in 0..3 {
            if segments_cross_2d(ps[i], ps[(i + 1) % 3], pt[j], pt[(j + 1) % 3]) {
                return true;
            }
        }
    }
    point_in_triangle_2d(ps[0], pt) || point_in_triangle_2d(pt[0], ps)
}

/// Two triangles sharing apex `v`, coplanar, whose angular sectors overlap.
fn coplanar_wedges_overlap(v: DVec3, s1: DVec3, s2: DVec3, t1: DVec3, t2: DVec3) -> bool {
    let s = [v, s1, s2];
    let t = [v, t1, t2];
    if !is_coplanar(&s, &t) {
        return false;
    }
    let n = normal(&s);
    let ps = s.map(|q| project(n, q));
    let pt = t.map(|q| project(n, q));
    // overlap iff an edge from v of one lies strictly inside the other's sector
    let inside = |w: [[f64; 2]; 3], q: [f64; 2]| {
        let (a, b) = (orient2(w[0], w[1], q), orient2(w[0], w[2], q));
        let o = orient2(w[0], w[1], w[2]);
        if o > 0.0 {
            a > 0.0 && b < 0.0
        } else {
            a < 0.0 && b > 0.0
        }
    };
    inside(ps, pt[1])
        || inside(ps, pt[2])
        || inside(pt, ps[1])
        || inside(pt, ps[2])
        || segments_cross_2d(ps[1], ps[2], pt[1], pt[2])
}

#[cfg(test)]
mod tests {
    #[test]
    fn descendants_counts_the_nodes_of_the_median_split_tree() {
        fn by_recursion(m: usize) -> usize {
            if m <= super::LEAF {
                0
            } else {
                2 + by_recursion(m / 2) + by_recursion(m - m / 2)
            }
        }
        for m in (1..3000).chain([65_537, 100_003]) {
            assert_eq!(super::descendants(m), by_recursion(m), "m = {m}");
        }
    }

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

    /// Boxes of a pseudo-random cloud of small triangles.
    fn random_boxes(n: usize, seed: u64, spread: f64) -> Vec<(DVec3, DVec3)> {
        let mut x = seed;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| {
                let c = DVec3::new(next(), next(), next()) * spread;
                let r = DVec3::new(next(), next(), next()) * 0.7;
                (c - r, c + r)
            })
            .collect()
    }

    fn overlapping(bvh: &Bvh, lo: DVec3, hi: DVec3) -> Vec<u32> {
        let mut hits = Vec::new();
        bvh.query(lo, hi, |i| hits.push(i));
        hits.sort_unstable();
        hits
    }

    #[test]
    fn queries_match_brute_force_before_and_after_refit() {
        for (n, seed) in [(1, 3), (5, 4), (37, 5), (5000, 6), (40_000, 7)] {
            let boxes = random_boxes(n, seed, 20.0);
            let mut bvh = Bvh::new(&boxes);
            let moved = random_boxes(n, seed + 100, 20.0);
            for (boxes, refit) in [(&boxes, false), (&moved, true)] {
                if refit {
                    bvh.refit(boxes);
                }
                for probe in random_boxes(50, seed + 7, 20.0) {
                    let brute: Vec<u32> = (0..n as u32)
                        .filter(|&i| {
                            let b = boxes[i as usize];
                            !(b.0.cmpgt(probe.1).any() || b.1.cmplt(probe.0).any())
                        })
                        .collect();
                    let found = overlapping(&bvh, probe.0, probe.1);
                    assert!(
                        brute.iter().all(|i| found.binary_search(i).is_ok()),
                        "n {n} refit {refit}"
                    );
                    let far = DVec3::splat(1000.0);
                    assert!(overlapping(&bvh, far, far + DVec3::ONE).is_empty());
                    let c = (probe.0 + probe.1) * 0.5;
                    let d2 = |i: u32| {
                        let b = boxes[i as usize];
                        (b.0 - c).max(c - b.1).max(DVec3::ZERO).length_squared()
                    };
                    let best = (0..n as u32).map(d2).fold(f64::INFINITY, f64::min);
                    assert_eq!(bvh.nearest(c, d2).unwrap().1, best);
                    // a guess never makes the answer worse
                    assert_eq!(bvh.nearest_below(c, Some((0, d2(0))), d2).unwrap().1, best);
                }
            }
        }
    }

    #[test]
    fn the_tree_does_not_depend_on_the_thread_count() {
        let boxes = random_boxes(100_000, 11, 50.0);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| Bvh::new(&boxes));
        let three = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap()
            .install(|| Bvh::new(&boxes));
        assert_eq!(one.items, three.items);
        assert!(one.nodes.iter().zip(&three.nodes).all(|(a, b)| a.lo == b.lo
            && a.hi == b.hi
            && a.start == b.start
            && a.count == b.count));
    }

    /// A small pseudo-random generator for the tests.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        fn below(&mut self, n: usize) -> usize {
            ((self.next() * n as f64) as usize).min(n - 1)
        }
    }

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

    #[test]
    fn off_plane_matches_its_reference() {
        let mut r = Rng(78);
        let mut seen = [0usize; 2];
        for k in 0..200_000 {
            let scale = [1e-3, 1.0, 300.0, 1e-160][k % 4];
            let v =
                |r: &mut Rng| DVec3::new(r.next() - 0.5, r.next() - 0.5, r.next() - 0.5) * scale;
            let (e, f, mut w) = (v(&mut r), v(&mut r), v(&mut r));
            let n = e.cross(f);
            if r.below(2) == 0 {
                // near the threshold
                let target = 1e-9 * n.length() * e.length();
                let x = [0.999_999_999, 1.0, 1.000_000_001, 1.0 + 1e-15, 0.5][r.below(5)];
                w += n * ((x * target - n.dot(w)) / n.length_squared());
            }
            let want = off_plane_reference(n, e, w);
            seen[want as usize] += 1;
            assert_eq!(off_plane(n, e, w), want, "{n:?} {e:?} {w:?}");
        }
        assert!(seen[0] > 1000 && seen[1] > 1000, "{seen:?}");
    }

    #[test]
    fn separated_by_plane_matches_its_reference() {
        let mut r = Rng(77);
        let mut seen = [0usize; 2];
        for k in 0..200_000 {
            let scale = [1e-3, 1.0, 300.0][k % 3];
            let pt = |r: &mut Rng| DVec3::new(r.next(), r.next(), r.next()) * scale;
            let s = [pt(&mut r), pt(&mut r), pt(&mut r)];
            let n = (s[1] - s[0]).cross(s[2] - s[0]);
            let mut t = [pt(&mut r), pt(&mut r), pt(&mut r)];
            // put vertices on the plane, near the threshold, or on shared vertices
            for q in t.iter_mut() {
                match r.below(6) {
                    0 => *q = s[r.below(3)],
                    1 | 2 => {
                        let d = n.dot(*q - s[0]);
                        let l = (*q - s[0]).length() * 1.5;
                        let eps = 1e-12 * n.length() * l;
                        let f = [
                            0.0,
                            0.5,
                            0.999_999_999,
                            1.0,
                            1.000_000_001,
                            2.0,
                            1.0 + 1e-12,
                        ][r.below(7)];
                        let sign = if r.next() < 0.5 { -1.0 } else { 1.0 };
                        *q += n * ((sign * f * eps - d) / n.length_squared());
                    }
                    _ => {}
                }
            }
            let want = separated_by_plane_reference(&s, &t);
            seen[want as usize] += 1;
            assert_eq!(separated_by_plane(&s, &t), want, "{s:?} {t:?}");
        }
        assert!(seen[0] > 1000 && seen[1] > 1000, "{seen:?}");
    }
}
