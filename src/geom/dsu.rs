//! Union-find (disjoint sets) over dense ids.

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
