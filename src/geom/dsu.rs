//! Union-find (disjoint sets) over dense ids.

use std::sync::atomic::{AtomicU32, Ordering};

/// Union-find over `0..n` (path halving; the smaller id becomes the root).
pub struct Dsu(Vec<u32>);

impl Dsu {
    /// `n` singletons.
    pub fn new(n: usize) -> Self {
        Dsu((0..n as u32).collect())
    }

    /// The root of `x`'s set.
    pub fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let p = self.0[x as usize];
            self.0[x as usize] = self.0[p as usize];
            x = p;
        }
        x
    }

    /// Merges the sets of `a` and `b`.
    pub fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.0[ra.max(rb) as usize] = ra.min(rb);
        }
    }
}

/// Union-find over `0..n` that many threads may merge sets in at once
/// (lock-free: a root is linked under the other root, the smaller id, by a
/// compare-and-swap, and finds halve paths as they go). As in [`Dsu`], the
/// smallest id of every set is its root, so the sets and their roots do not
/// depend on the order of the unions nor on the number of threads.
///
/// ```
/// use rayon::prelude::*;
/// use septa::geom::dsu::AtomicDsu;
/// let dsu = AtomicDsu::new(6);
/// [(5, 4), (4, 1), (2, 3)].par_iter().for_each(|&(a, b)| dsu.union(a, b));
/// assert_eq!((0..6).map(|x| dsu.find(x)).collect::<Vec<_>>(), [0, 1, 2, 2, 1, 1]);
/// ```
pub struct AtomicDsu(Vec<AtomicU32>);

impl AtomicDsu {
    /// `n` singletons.
    pub fn new(n: usize) -> Self {
        AtomicDsu((0..n as u32).map(AtomicU32::new).collect())
    }

    /// The root of `x`'s set (as of the unions finished so far).
    pub fn find(&self, mut x: u32) -> u32 {
        loop {
            let p = self.0[x as usize].load(Ordering::Acquire);
            if p == x {
                return x;
            }
            let g = self.0[p as usize].load(Ordering::Acquire);
            if g != p {
                // (parents only ever get smaller: a failed exchange means
                // another thread has already moved `x` higher up)
                let _ = self.0[x as usize].compare_exchange_weak(
                    p,
                    g,
                    Ordering::AcqRel,
                    Ordering::Relaxed,
                );
            }
            x = g;
        }
    }

    /// Merges the sets of `a` and `b`.
    pub fn union(&self, a: u32, b: u32) {
        let (mut a, mut b) = (a, b);
        loop {
            (a, b) = (self.find(a), self.find(b));
            if a == b {
                return;
            }
            let (lo, hi) = (a.min(b), a.max(b));
            // linked only while `hi` is still a root; otherwise again from
            // the roots now
            if self.0[hi as usize]
                .compare_exchange(hi, lo, Ordering::AcqRel, Ordering::Relaxed)
                .is_ok()
            {
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    /// Pairs of a small deterministic random graph.
    fn pairs(n: u32, m: usize, seed: u64) -> Vec<(u32, u32)> {
        let mut x = seed;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x % n as u64) as u32
        };
        (0..m).map(|_| (next(), next())).collect()
    }

    #[test]
    fn concurrent_unions_give_the_sets_and_roots_of_the_serial_ones() {
        for (n, m, seed) in [
            (10, 5, 1),
            (1000, 700, 2),
            (100_000, 90_000, 3),
            (50_000, 200_000, 4),
        ] {
            let edges = pairs(n, m, seed);
            let mut serial = Dsu::new(n as usize);
            for &(a, b) in &edges {
                serial.union(a, b);
            }
            let concurrent = AtomicDsu::new(n as usize);
            edges
                .par_iter()
                .with_max_len(64)
                .for_each(|&(a, b)| concurrent.union(a, b));
            for x in 0..n {
                assert_eq!(concurrent.find(x), serial.find(x), "n {n}, element {x}");
            }
        }
    }
}
