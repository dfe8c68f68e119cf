//! The 4-D grid: which toxels are active, the dense id of each boundary cube
//! and its support point.
//!
//! As in the 3-D iso-surface code, everything lives on the *padded* grid: the
//! volume with one layer of inactive toxels around it along all four axes, so
//! that everything outside the volume — before the first frame and after the
//! last one too — is inactive and the hypersurface closes. Padded toxel
//! `q = x + P0 (y + P1 (z + P2 t))` is toxel `(x − 1, y − 1, z − 1, t − 1)`.
//!
//! - [`Activity`]: one bit per padded toxel, "value ≥ iso".
//! - [`Cubes`]: one bit per padded toxel and axis, "the cube on the toxel's low
//!   side along this axis separates an active from an inactive toxel", with
//!   per-word popcount prefixes: a cube's id is its rank (axis 0 cubes first,
//!   then 1, 2, 3, each by toxel index), independent of the thread count.
//! - [`support_points`]: each boundary cube's support point in index space
//!   (x, y, z voxel indices, t frame index): the cube centre, or with
//!   displacement the linear interpolation of the iso value along the range
//!   vector from the active toxel's centre to the inactive one's — the same
//!   arithmetic as the 3-D VESTA code, so that spatial cubes of a frame get
//!   exactly the points VESTA gives that frame. Cubes on the border of the
//!   volume keep their centre (the outside has no value).

use rayon::prelude::*;

use crate::iso::{Scalar, interpolation_fraction};

/// Padded extents and strides of a 4-D grid.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Grid {
    /// Unpadded extents (x, y, z, t).
    pub dims: [usize; 4],
    pub p: [usize; 4],
    pub stride: [usize; 4],
    pub len: usize,
}

impl Grid {
    pub fn new(dims: [usize; 4]) -> Self {
        let p = dims.map(|n| n + 2);
        let stride = [1, p[0], p[0] * p[1], p[0] * p[1] * p[2]];
        Grid {
            dims,
            p,
            stride,
            len: stride[3] * p[3],
        }
    }

    /// Padded coordinates of a padded index.
    #[inline]
    pub fn coords(&self, q: usize) -> [usize; 4] {
        [
            q % self.p[0],
            (q / self.stride[1]) % self.p[1],
            (q / self.stride[2]) % self.p[2],
            q / self.stride[3],
        ]
    }

    /// Index into the unpadded samples of padded coordinates, if interior.
    #[inline]
    pub fn toxel(&self, c: [usize; 4]) -> Option<usize> {
        let d = self.dims;
        if (0..4).all(|a| (1..=d[a]).contains(&c[a])) {
            Some((c[0] - 1) + d[0] * ((c[1] - 1) + d[1] * ((c[2] - 1) + d[2] * (c[3] - 1))))
        } else {
            None
        }
    }

    /// Offsets of the 16 toxels of the cell whose lowest toxel is `q` (bit `a`
    /// of the toxel id = +1 along axis `a`).
    pub fn cell_offsets(&self) -> [usize; 16] {
        std::array::from_fn(|o| (0..4).map(|a| ((o >> a) & 1) * self.stride[a]).sum())
    }
}

/// One bit per padded toxel: is it active?
pub(crate) struct Activity {
    pub grid: Grid,
    pub bits: Vec<u64>,
    pub active: u64,
}

impl Activity {
    /// Marks every toxel with value ≥ `iso`, in parallel over 64-toxel words.
    pub fn new<T: Scalar>(values: &[T], grid: Grid, iso: f64) -> Self {
        let words = grid.len.div_ceil(64);
        let bits: Vec<u64> = (0..words)
            .into_par_iter()
            .map(|w| {
                let mut word = 0u64;
                for t in 0..64 {
                    let q = w * 64 + t;
                    if q >= grid.len {
                        break;
                    }
                    if let Some(v) = grid.toxel(grid.coords(q)) {
                        if values[v].to_f64() >= iso {
                            word |= 1 << t;
                        }
                    }
                }
                word
            })
            .collect();
        let active = bits.par_iter().map(|w| w.count_ones() as u64).sum();
        Activity { grid, bits, active }
    }

    /// Whether padded toxel `q` is active.
    #[inline]
    pub fn get(&self, q: usize) -> bool {
        self.bits[q >> 6] >> (q & 63) & 1 == 1
    }

    /// 64 activity bits from padded toxel `q` on (zeros outside the grid).
    #[inline]
    pub fn window(&self, q: isize) -> u64 {
        let word = |w: isize| -> u64 {
            if w < 0 || w as usize >= self.bits.len() {
                0
            } else {
                self.bits[w as usize]
            }
        };
        let (w, s) = (q.div_euclid(64), q.rem_euclid(64) as u32);
        if s == 0 {
            word(w)
        } else {
            (word(w) >> s) | (word(w + 1) << (64 - s))
        }
    }
}

/// Dense ids of the boundary cubes.
pub(crate) struct Cubes {
    /// Bit `t` of word `w`: the cube on the low side of toxel `64 w + t` along the axis.
    pub bits: [Vec<u64>; 4],
    rank: [Vec<u32>; 4],
    base: [u64; 4],
    pub total: u64,
}

impl Cubes {
    /// Finds and numbers the boundary cubes (XOR of shifted activity words;
    /// toxels on the low border are padding and so is what the shift wraps to).
    pub fn new(act: &Activity) -> Self {
        let words = act.bits.len();
        let mut bits: [Vec<u64>; 4] = Default::default();
        let mut rank: [Vec<u32>; 4] = Default::default();
        let mut base = [0u64; 4];
        let mut total = 0u64;
        for a in 0..4 {
            let st = act.grid.stride[a] as isize;
            bits[a] = (0..words)
                .into_par_iter()
                .map(|w| {
                    let q = (w * 64) as isize;
                    act.window(q) ^ act.window(q - st)
                })
                .collect();
            let mut acc = 0u64;
            rank[a] = bits[a]
                .iter()
                .map(|w| {
                    let r = acc.min(u32::MAX as u64) as u32;
                    acc += w.count_ones() as u64;
                    r
                })
                .collect();
            base[a] = total;
            total += acc;
        }
        Cubes {
            bits,
            rank,
            base,
            total,
        }
    }

    /// Id of the boundary cube on the low side of padded toxel `q` along `axis`.
    #[inline]
    pub fn id(&self, axis: usize, q: usize) -> u32 {
        let w = self.bits[axis][q >> 6];
        let below = w & ((1u64 << (q & 63)) - 1);
        debug_assert!(w >> (q & 63) & 1 == 1, "not a boundary cube");
        (self.base[axis] + self.rank[axis][q >> 6] as u64 + below.count_ones() as u64) as u32
    }
}

/// Support points of all boundary cubes in id order, index space.
pub(crate) fn support_points<T: Scalar>(
    values: &[T],
    act: &Activity,
    cubes: &Cubes,
    iso: f64,
    displace: bool,
) -> Vec<[f64; 4]> {
    let mut out = Vec::with_capacity(cubes.total as usize);
    for a in 0..4 {
        let parts: Vec<Vec<[f64; 4]>> = cubes.bits[a]
            .par_chunks(1024)
            .enumerate()
            .map(|(chunk, words)| {
                let mut v = Vec::new();
                for (k, &word) in words.iter().enumerate() {
                    let mut left = word;
                    while left != 0 {
                        let t = left.trailing_zeros() as usize;
                        left &= left - 1;
                        let q = (chunk * 1024 + k) * 64 + t;
                        v.push(support_point(values, act, a, q, iso, displace));
                    }
                }
                v
            })
            .collect();
        for p in parts {
            out.extend(p);
        }
    }
    out
}

/// Support point of the cube on the low side of padded toxel `q` along `axis`.
fn support_point<T: Scalar>(
    values: &[T],
    act: &Activity,
    axis: usize,
    q: usize,
    iso: f64,
    displace: bool,
) -> [f64; 4] {
    let g = &act.grid;
    let hi = g.coords(q);
    let mut lo = hi;
    lo[axis] -= 1;
    let centre = hi.map(|c| c as f64 - 1.0);
    let mut p = centre;
    p[axis] -= 0.5;
    if !displace {
        return p;
    }
    let (Some(vh), Some(vl)) = (g.toxel(hi), g.toxel(lo)) else {
        return p;
    };
    let (vh, vl) = (values[vh].to_f64(), values[vl].to_f64());
    let hi_active = act.get(q);
    let (va, vi) = if hi_active { (vh, vl) } else { (vl, vh) };
    let t = interpolation_fraction(va, vi, iso);
    if hi_active {
        p[axis] = centre[axis] - t;
    } else {
        p[axis] = centre[axis] - 1.0 + t;
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubes_are_numbered_densely() {
        let dims = [3, 2, 2, 3];
        let n: usize = dims.iter().product();
        let values: Vec<u8> = (0..n).map(|i| ((i * 37) % 5 == 0) as u8).collect();
        let grid = Grid::new(dims);
        let act = Activity::new(&values, grid, 1.0);
        let cubes = Cubes::new(&act);
        let mut expect = 0u32;
        for a in 0..4 {
            for q in 0..grid.len {
                if grid.coords(q)[a] == 0 {
                    assert!(!act.get(q));
                    continue;
                }
                if act.get(q) != act.get(q - grid.stride[a]) {
                    assert_eq!(cubes.id(a, q), expect);
                    expect += 1;
                }
            }
        }
        assert_eq!(cubes.total, expect as u64);
        assert_eq!(
            act.active as usize,
            values.iter().filter(|&&v| v >= 1).count()
        );
    }
}
