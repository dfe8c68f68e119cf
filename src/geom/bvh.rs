//! A flat bounding-volume hierarchy over boxes: median splits on the longest
//! axis, built in parallel with a layout that depends only on the item
//! count (never on the thread count); box queries, nearest-item queries and
//! refits. The self-intersection traversal over it is in
//! [`super::intersect`].

use glam::DVec3;
use rayon::prelude::*;

/// A flat BVH over triangle bounding boxes (median split on the longest axis).
pub struct Bvh {
    pub(super) nodes: Vec<Node>,
    /// Triangle ids in leaf order.
    pub items: Vec<u32>,
}

#[derive(Clone, Copy)]
pub(super) struct Node {
    pub(super) lo: DVec3,
    pub(super) hi: DVec3,
    /// Leaf: first item and count; inner: left child index and 0 (right = left + 1).
    pub(super) start: u32,
    pub(super) count: u32,
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
    pub(super) fn new_f32(boxes: &[(DVec3, DVec3)]) -> Self {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::test_rng::random_boxes;

    #[test]
    fn descendants_counts_the_nodes_of_the_median_split_tree() {
        fn by_recursion(m: usize) -> usize {
            if m <= LEAF {
                0
            } else {
                2 + by_recursion(m / 2) + by_recursion(m - m / 2)
            }
        }
        for m in (1..3000).chain([65_537, 100_003]) {
            assert_eq!(descendants(m), by_recursion(m), "m = {m}");
        }
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
}
