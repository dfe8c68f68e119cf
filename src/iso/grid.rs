//! Which voxels are active, which voxel faces are boundary faces, the dense
//! id of each boundary face, and its support point.
//!
//! Everything lives on the *padded* grid: the volume with one layer of
//! inactive cells around it, so that the outside of the volume counts as
//! inactive and every surface closes. Padded cell `p = i + P0 (j + P1 k)` is
//! voxel `(i − 1, j − 1, k − 1)`.
//!
//! - [`Activity`]: one bit per padded cell, "value ≥ iso", behind a guard of
//!   zero words so that a 64-bit window at any cell offset can be read without
//!   bounds checks.
//! - [`Faces`]: "the face on a cell's low side along an axis separates an
//!   active from an inactive cell" — a word of these bits is two activity
//!   windows XORed, so they are not stored — plus face counts per block of
//!   16 words within fixed tasks: the id of a boundary face is its rank (the
//!   passes that walk the words count the ids off as they go, and need a rank
//!   only where a task starts). Ids depend only on the volume (axis 0 faces
//!   first, then 1, then 2, each by cell index), never on the thread count.
//! - [`support_points`]: the point of each boundary face: the face centre, or
//!   with displacement the linear interpolation of the iso value along the
//!   range vector from the active voxel centre to the inactive one (VESTA's
//!   Fig. 2), in index space or mapped on to physical space. Faces on the
//!   border of the volume keep their centre (the outside has no value). The
//!   samples are asked for a few words ahead (a prefetch), as the ones near
//!   the surface are sparse in memory.
//! - [`Rows`]: padded coordinates of increasing indices without divisions.

use std::mem::MaybeUninit;

use glam::DVec3;
use rayon::prelude::*;

use super::Scalar;
#[cfg(target_arch = "x86_64")]
use super::cpu;
use crate::volume::Dims;

/// Displaced support points stay this fraction of a voxel away from the voxel
/// centres, so that no two support points coincide and no triangle degenerates
/// when a voxel value equals the iso value exactly.
pub(crate) const MIN_FRACTION: f64 = 1e-3;

/// Padded extents and strides.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Padded {
    pub dims: Dims,
    pub p: [usize; 3],
    pub stride: [usize; 3],
    pub len: usize,
}

impl Padded {
    pub fn new(dims: Dims) -> Self {
        let p = [dims.nx + 2, dims.ny + 2, dims.nz + 2];
        Padded {
            dims,
            p,
            stride: [1, p[0], p[0] * p[1]],
            len: p[0] * p[1] * p[2],
        }
    }

    /// Padded cell coordinates of a padded index.
    #[inline]
    pub fn coords(&self, q: usize) -> [usize; 3] {
        [
            q % self.p[0],
            (q / self.p[0]) % self.p[1],
            q / self.stride[2],
        ]
    }

    /// Index into the unpadded samples of padded cell coordinates, if interior.
    #[cfg(test)]
    #[inline]
    pub fn voxel(&self, c: [usize; 3]) -> Option<usize> {
        let d = self.dims;
        let inside =
            (1..=d.nx).contains(&c[0]) && (1..=d.ny).contains(&c[1]) && (1..=d.nz).contains(&c[2]);
        inside.then(|| (c[0] - 1) + d.nx * ((c[1] - 1) + d.ny * (c[2] - 1)))
    }

    /// Offsets of the 8 cells around the grid vertex whose octant-0 cell is
    /// `q` (bit 0 of the octant = +x, as in [`crate::star`]).
    pub fn octant_offsets(&self) -> [usize; 8] {
        let [sx, sy, sz] = self.stride;
        [0, sx, sy, sx + sy, sz, sz + sx, sz + sy, sz + sy + sx]
    }
}

/// Words of 64 cells per parallel task (fixed, so that face ids and the
/// output never depend on the number of threads).
pub(crate) const WORDS_PER_TASK: usize = 1024;

/// Coordinates of increasing padded indices without a division per index:
/// one division at the start, then rows are counted off as `q` passes them.
#[derive(Clone)]
pub(crate) struct Rows {
    p: [usize; 2],
    row_start: usize,
    j: usize,
    k: usize,
}

impl Rows {
    /// A cursor at padded index `q`.
    pub fn new(grid: &Padded, q: usize) -> Self {
        let [i, j, k] = grid.coords(q);
        Rows {
            p: [grid.p[0], grid.p[1]],
            row_start: q - i,
            j,
            k,
        }
    }

    /// Padded cell coordinates of `q`, which must not be before the last `q`.
    #[inline(always)]
    pub fn coords(&mut self, q: usize) -> [usize; 3] {
        while q >= self.row_start + self.p[0] {
            self.row_start += self.p[0];
            self.j += 1;
            if self.j == self.p[1] {
                self.j = 0;
                self.k += 1;
            }
        }
        [q - self.row_start, self.j, self.k]
    }
}

/// One bit per padded cell: is it active?
pub(crate) struct Activity {
    pub grid: Padded,
    /// Zero bits before cell 0 (a multiple of 64, at least one z stride).
    pub guard: usize,
    pub bits: Vec<u64>,
    pub active: u64,
}

impl Activity {
    /// Marks every voxel with value ≥ `iso`, in parallel over 64-cell words.
    pub fn new<T: Scalar>(values: &[T], dims: Dims, iso: f64) -> Self {
        let grid = Padded::new(dims);
        let guard_words = (grid.stride[2] + grid.stride[1] + 64) / 64 + 1;
        let cell_words = grid.len.div_ceil(64);
        let tail_words = guard_words + 2;
        let mut bits = vec![0u64; guard_words + cell_words + tail_words];
        // no sample reaches the iso value: nothing is active
        let active = if let Some(cut) = T::cut(iso) {
            bits[guard_words..guard_words + cell_words]
                .par_chunks_mut(WORDS_PER_TASK)
                .enumerate()
                .map(|(chunk, words)| activity_task(values, &grid, chunk, words, cut))
                .sum()
        } else {
            0
        };
        Activity {
            grid,
            guard: guard_words * 64,
            bits,
            active,
        }
    }

    /// 64 activity bits starting at padded cell `q` (which may lie up to the
    /// guard before cell 0 or past the end).
    #[inline(always)]
    pub fn window(&self, q: isize) -> u64 {
        let bit = (self.guard as isize + q) as usize;
        funnel(&self.bits, bit >> 6, (bit & 63) as u32)
    }

    /// Whether padded cell `q` is active.
    #[cfg(test)]
    pub fn get(&self, q: usize) -> bool {
        let bit = self.guard + q;
        self.bits[bit >> 6] >> (bit & 63) & 1 == 1
    }
}

/// Bits `s .. s + 64` of `bits[w], bits[w + 1]` (one double shift).
#[inline(always)]
pub(crate) fn funnel(bits: &[u64], w: usize, s: u32) -> u64 {
    let pair = (bits[w + 1] as u128) << 64 | bits[w] as u128;
    (pair >> s) as u64
}

/// Fills the activity words of task `chunk` (of [`WORDS_PER_TASK`] words);
/// returns the number of active cells among them.
fn activity_task<T: Scalar>(
    values: &[T],
    grid: &Padded,
    chunk: usize,
    words: &mut [u64],
    cut: T,
) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if cpu::fast() {
        // SAFETY: the CPU has the features (checked just above).
        return unsafe { activity_task_fast(values, grid, chunk, words, cut) };
    }
    activity_task_body(values, grid, chunk, words, cut)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt,bmi1,bmi2,lzcnt,avx2")]
unsafe fn activity_task_fast<T: Scalar>(
    values: &[T],
    grid: &Padded,
    chunk: usize,
    words: &mut [u64],
    cut: T,
) -> u64 {
    activity_task_body(values, grid, chunk, words, cut)
}

#[inline(always)]
fn activity_task_body<T: Scalar>(
    values: &[T],
    grid: &Padded,
    chunk: usize,
    words: &mut [u64],
    cut: T,
) -> u64 {
    let start = chunk * WORDS_PER_TASK * 64;
    let mut at = grid.coords(start.min(grid.len - 1));
    let mut n = 0;
    for (k, word) in words.iter_mut().enumerate() {
        *word = active_word(values, grid, start + k * 64, &mut at, cut);
        n += word.count_ones() as u64;
    }
    n
}

/// Activity bits of padded cells `start .. start + 64`; `at` holds the
/// coordinates of `start` and is advanced past the word.
#[inline(always)]
fn active_word<T: Scalar>(
    values: &[T],
    grid: &Padded,
    start: usize,
    at: &mut [usize; 3],
    cut: T,
) -> u64 {
    let mut word = 0u64;
    if start >= grid.len {
        return word;
    }
    let [mut i, mut j, mut k] = *at;
    let d = grid.dims;
    let end = (start + 64).min(grid.len);
    let mut t = 0;
    while start + t < end {
        // run of interior cells along x in this row
        let row_interior = (1..=d.ny).contains(&j) && (1..=d.nz).contains(&k);
        let run = (grid.p[0] - i).min(end - start - t);
        if row_interior {
            let lo = i.max(1);
            let hi = (i + run).min(d.nx + 1);
            if lo < hi {
                let row = d.nx * ((j - 1) + d.ny * (k - 1));
                word |= at_least_bits(&values[row + lo - 1..row + hi - 1], cut) << (t + lo - i);
            }
        }
        t += run;
        i += run;
        if i == grid.p[0] {
            i = 0;
            j += 1;
            if j == grid.p[1] {
                j = 0;
                k += 1;
            }
        }
    }
    *at = [i, j, k];
    word
}

/// Bit `x`: `values[x] >= cut`, for at most 64 values. The comparisons go to
/// bytes first (a vectorizable loop), then eight bytes at a time into bits
/// with one multiplication.
#[inline(always)]
fn at_least_bits<T: Scalar>(values: &[T], cut: T) -> u64 {
    let mut bytes = [0u8; 64];
    for (b, v) in bytes.iter_mut().zip(values) {
        *b = (*v >= cut) as u8;
    }
    let mut word = 0u64;
    for (k, eight) in bytes.chunks_exact(8).enumerate() {
        let x = u64::from_le_bytes(eight.try_into().expect("eight bytes"));
        // byte b (0 or 1) lands on bit 56 + b; no two products overlap there
        word |= (x.wrapping_mul(0x0102_0408_1020_4080) >> 56) << (8 * k);
    }
    word
}

/// Words of 64 cells per rank block: [`Faces`] keeps the number of boundary
/// faces before each block of its task; a rank adds the words in between.
const BLOCK_WORDS: usize = 16;

/// Dense ids of the boundary faces. The face bits themselves are not stored:
/// a word of them is two activity windows XORed, cheaper than the memory a
/// stored copy would take (three more bits per cell to write and fault in).
/// Nothing per face or per word is stored either: the march and the support
/// points go through the words in order and count the ids off themselves, and
/// only need a [`rank`](Faces::rank) where a task starts.
pub(crate) struct Faces<'a> {
    act: &'a Activity,
    /// Padded strides, signed for windows before a word.
    stride: [isize; 3],
    /// Boundary faces in the task's earlier blocks of [`BLOCK_WORDS`] words.
    block_rank: [Vec<u32>; 3],
    /// Boundary faces of the axis in earlier tasks, one more entry at the end.
    task_base: [Vec<u32>; 3],
    base: [u32; 3],
    words: usize,
    pub total: u64,
}

impl<'a> Faces<'a> {
    /// Counts the boundary faces (word-parallel XOR of shifted activity, all
    /// three axes in one sweep; counts within fixed tasks, so that only the
    /// short list of task totals is summed in sequence).
    pub fn new(act: &'a Activity) -> Self {
        let words = act.grid.len.div_ceil(64);
        let tasks = words.div_ceil(WORDS_PER_TASK);
        let blocks = words.div_ceil(BLOCK_WORDS);
        let stride = act.grid.stride.map(|s| s as isize);
        let mut block_rank: [Vec<u32>; 3] = std::array::from_fn(|_| vec![0u32; blocks]);
        let [r0, r1, r2] = &mut block_rank;
        const TASK_BLOCKS: usize = WORDS_PER_TASK / BLOCK_WORDS;
        let counts: Vec<[u32; 3]> = (
            r0.par_chunks_mut(TASK_BLOCKS),
            r1.par_chunks_mut(TASK_BLOCKS),
            r2.par_chunks_mut(TASK_BLOCKS),
        )
            .into_par_iter()
            .enumerate()
            .map(|(task, ranks)| count_task(act, stride, words, task, ranks.into()))
            .collect();
        let mut task_base: [Vec<u32>; 3] = Default::default();
        let mut base = [0u32; 3];
        let mut total = 0u64;
        for a in 0..3 {
            let mut acc = 0u64;
            task_base[a] = Vec::with_capacity(tasks + 1);
            for c in &counts {
                task_base[a].push(acc.min(u32::MAX as u64) as u32);
                acc += c[a] as u64;
            }
            task_base[a].push(acc.min(u32::MAX as u64) as u32);
            base[a] = total.min(u32::MAX as u64) as u32;
            total += acc;
        }
        Faces {
            act,
            stride,
            block_rank,
            task_base,
            base,
            words,
            total,
        }
    }

    /// Number of parallel tasks (of [`WORDS_PER_TASK`] words).
    pub fn tasks(&self) -> usize {
        self.task_base[0].len() - 1
    }

    /// Number of words of 64 cells.
    pub fn words(&self) -> usize {
        self.words
    }

    /// Bit `t`: whether the face on the low side of padded cell `64 w + t`
    /// along `axis` is a boundary face.
    #[inline(always)]
    pub fn word(&self, axis: usize, w: usize) -> u64 {
        let q = (w * 64) as isize;
        self.act.window(q) ^ self.act.window(q - self.stride[axis])
    }

    /// Number of boundary faces before padded cell `q` along `axis`, counting
    /// the faces of the earlier axes: the id of the face on the low side of
    /// `q` if that is a boundary face, else of the next one. `q` may lie past
    /// the last cell (no faces there).
    pub fn rank(&self, axis: usize, q: usize) -> u32 {
        let w = q >> 6;
        if w >= self.words {
            return self.base[axis] + self.task_base[axis][self.tasks()];
        }
        let block = w / BLOCK_WORDS;
        let mut r = self.base[axis]
            + self.task_base[axis][w / WORDS_PER_TASK]
            + self.block_rank[axis][block];
        for v in block * BLOCK_WORDS..w {
            r += self.word(axis, v).count_ones();
        }
        r + (self.word(axis, w) & ((1u64 << (q & 63)) - 1)).count_ones()
    }

    /// Id of the boundary face on the low side of padded cell `q` along `axis`.
    #[cfg(test)]
    pub fn id(&self, axis: usize, q: usize) -> u32 {
        debug_assert!(
            self.word(axis, q >> 6) >> (q & 63) & 1 == 1,
            "not a boundary face"
        );
        self.rank(axis, q)
    }

    /// Number of boundary faces along `axis` in task `task`.
    pub fn task_count(&self, axis: usize, task: usize) -> usize {
        (self.task_base[axis][task + 1] - self.task_base[axis][task]) as usize
    }
}

/// Boundary faces of task `task` per axis; the counts before each of its
/// blocks go to `ranks`.
fn count_task(
    act: &Activity,
    stride: [isize; 3],
    words: usize,
    task: usize,
    ranks: [&mut [u32]; 3],
) -> [u32; 3] {
    #[cfg(target_arch = "x86_64")]
    if cpu::fast() {
        // SAFETY: the CPU has the features (checked just above).
        return unsafe { count_task_fast(act, stride, words, task, ranks) };
    }
    count_task_body(act, stride, words, task, ranks)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt,bmi1,bmi2,lzcnt,avx2")]
unsafe fn count_task_fast(
    act: &Activity,
    stride: [isize; 3],
    words: usize,
    task: usize,
    ranks: [&mut [u32]; 3],
) -> [u32; 3] {
    count_task_body(act, stride, words, task, ranks)
}

#[inline(always)]
fn count_task_body(
    act: &Activity,
    stride: [isize; 3],
    words: usize,
    task: usize,
    ranks: [&mut [u32]; 3],
) -> [u32; 3] {
    let w0 = task * WORDS_PER_TASK;
    let w1 = (w0 + WORDS_PER_TASK).min(words);
    // the windows of word w start at bit guard + 64 w (aligned) and at
    // guard + 64 w − stride (a fixed shift per axis)
    let g = act.guard / 64;
    let below: [(usize, u32); 3] = std::array::from_fn(|a| {
        let bit = act.guard - stride[a] as usize;
        (bit >> 6, (bit & 63) as u32)
    });
    let bits = &act.bits[..];
    let mut acc = [0u32; 3];
    for w in w0..w1 {
        if (w - w0) % BLOCK_WORDS == 0 {
            for a in 0..3 {
                ranks[a][(w - w0) / BLOCK_WORDS] = acc[a];
            }
        }
        let here = bits[g + w];
        for a in 0..3 {
            acc[a] += (here ^ funnel(bits, below[a].0 + w, below[a].1)).count_ones();
        }
    }
    acc
}

/// Support points of all boundary faces in id order, each passed through
/// `place` (index space → output space; voxel centres at integer
/// coordinates). Written straight into the output, in parallel over (axis,
/// task) ranges whose place in the output the face ranks give.
pub(crate) fn support_points<T: Scalar, P: Fn(DVec3) -> DVec3 + Sync>(
    values: &[T],
    act: &Activity,
    faces: &Faces,
    iso: f64,
    displace: bool,
    place: P,
) -> Vec<DVec3> {
    // written by the tasks straight into the spare capacity: no zeroing
    // first, and the new memory is touched by both threads
    let total = faces.total as usize;
    let mut out: Vec<DVec3> = Vec::with_capacity(total);
    // one task does the three axes of its cells, so that the samples it
    // reads are still in cache for the second and third axis
    let mut ranges: Vec<[&mut [MaybeUninit<DVec3>]; 3]> = Vec::with_capacity(faces.tasks());
    let mut rest = &mut out.spare_capacity_mut()[..total];
    for a in 0..3 {
        for task in 0..faces.tasks() {
            let (head, tail) = rest.split_at_mut(faces.task_count(a, task));
            if a == 0 {
                ranges.push([head, &mut [], &mut []]);
            } else {
                ranges[task][a] = head;
            }
            rest = tail;
        }
    }
    ranges.into_par_iter().enumerate().for_each(|(task, outs)| {
        task_points(values, act, faces, task, iso, displace, &place, outs);
    });
    // SAFETY: the ranges cover the first `total` elements, and every task
    // wrote every element of its ranges (`task_points_body` asserts it).
    unsafe { out.set_len(total) };
    out
}

/// Support points of the faces of task `task`, each axis into its range.
#[allow(clippy::too_many_arguments)]
fn task_points<T: Scalar, P: Fn(DVec3) -> DVec3>(
    values: &[T],
    act: &Activity,
    faces: &Faces,
    task: usize,
    iso: f64,
    displace: bool,
    place: &P,
    outs: [&mut [MaybeUninit<DVec3>]; 3],
) {
    #[cfg(target_arch = "x86_64")]
    if cpu::fast() {
        // SAFETY: the CPU has the features (checked just above).
        return unsafe { task_points_fast(values, act, faces, task, iso, displace, place, outs) };
    }
    task_points_body(values, act, faces, task, iso, displace, place, outs)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt,bmi1,bmi2,lzcnt,avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn task_points_fast<T: Scalar, P: Fn(DVec3) -> DVec3>(
    values: &[T],
    act: &Activity,
    faces: &Faces,
    task: usize,
    iso: f64,
    displace: bool,
    place: &P,
    outs: [&mut [MaybeUninit<DVec3>]; 3],
) {
    task_points_body(values, act, faces, task, iso, displace, place, outs)
}

/// The three axes word by word, so that the samples one word needs are read
/// from memory once.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn task_points_body<T: Scalar, P: Fn(DVec3) -> DVec3>(
    values: &[T],
    act: &Activity,
    faces: &Faces,
    task: usize,
    iso: f64,
    displace: bool,
    place: &P,
    outs: [&mut [MaybeUninit<DVec3>]; 3],
) {
    let words = faces.words();
    let (w0, w1) = (
        task * WORDS_PER_TASK,
        ((task + 1) * WORDS_PER_TASK).min(words),
    );
    let mut rows = Rows::new(&act.grid, w0 * 64);
    let mut n = [0usize; 3];
    let g = act.guard / 64;
    // the face words PREFETCH words ahead, whose samples are asked for early:
    // the samples near the surface are sparse in memory, and each one read
    // only when its point is made would wait for memory
    let mut ahead_rows = rows.clone();
    let mut ring = [[0u64; 3]; PREFETCH];
    let d = act.grid.dims;
    let slice = d.nx * d.ny;
    for w in w0..(w0 + PREFETCH).min(w1) {
        ring[w % PREFETCH] = [faces.word(0, w), faces.word(1, w), faces.word(2, w)];
    }
    for w in w0..w1 {
        let fw = ring[w % PREFETCH];
        let wa = w + PREFETCH;
        if wa < w1 {
            let fa = [faces.word(0, wa), faces.word(1, wa), faces.word(2, wa)];
            ring[wa % PREFETCH] = fa;
            let any = fa[0] | fa[1] | fa[2];
            if any != 0 {
                // the samples of the first and last cells with a face, and
                // the lines between; for faces along z the slice below too
                let c0 = ahead_rows.coords(wa * 64 + any.trailing_zeros() as usize);
                let c1 = ahead_rows
                    .clone()
                    .coords(wa * 64 + 63 - any.leading_zeros() as usize);
                if let (Some(v0), Some(v1)) = (voxel_near(&d, c0), voxel_near(&d, c1)) {
                    prefetch_range(values, v0, v1);
                    if fa[2] != 0 && v0 >= slice {
                        prefetch_range(values, v0 - slice, v1 - slice);
                    }
                }
            }
        }
        if fw[0] | fw[1] | fw[2] == 0 {
            continue;
        }
        // the cursor at the word's first cell, for each axis from there
        rows.coords(w * 64);
        let here = act.bits[g + w];
        for a in 0..3 {
            let mut r = rows.clone();
            let mut left = fw[a];
            let out = &mut *outs[a];
            while left != 0 {
                let t = left.trailing_zeros();
                left &= left - 1;
                let q = w * 64 + t as usize;
                let hi = r.coords(q);
                let hi_active = here >> t & 1 == 1;
                out[n[a]].write(place(support_point(
                    values, act, a, hi, hi_active, iso, displace,
                )));
                n[a] += 1;
            }
        }
    }
    // every element written (what makes the output initialised)
    assert!(
        (0..3).all(|a| n[a] == outs[a].len()),
        "support points missing"
    );
}

/// Words of face bits between asking for samples and using them.
const PREFETCH: usize = 8;

/// Index of the voxel at padded coordinates `c`, or of the nearest voxel of
/// its row (`None` for rows of padding).
#[inline(always)]
fn voxel_near(d: &Dims, c: [usize; 3]) -> Option<usize> {
    let row_inside = (1..=d.ny).contains(&c[1]) && (1..=d.nz).contains(&c[2]);
    row_inside.then(|| c[0].clamp(1, d.nx) - 1 + d.nx * ((c[1] - 1) + d.ny * (c[2] - 1)))
}

/// Asks the CPU to bring `values[v0..=v1]` into the cache (a hint: nothing is
/// read, no address need be valid; nothing on other architectures).
#[inline(always)]
fn prefetch_range<T>(values: &[T], v0: usize, v1: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let start = values.as_ptr().wrapping_add(v0) as usize & !63;
        let end = values.as_ptr().wrapping_add(v1) as usize;
        let mut line = start;
        while line <= end {
            // SAFETY: a prefetch reads nothing and cannot fault, whatever the address
            #[allow(unused_unsafe)]
            unsafe {
                _mm_prefetch::<_MM_HINT_T0>(line as *const i8)
            };
            line += 64;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (values, v0, v1);
}

/// Support point of the face on the low side of the padded cell at padded
/// coordinates `hi` along `axis` (`hi_active`: whether that cell is active),
/// in index space.
#[inline(always)]
fn support_point<T: Scalar>(
    values: &[T],
    act: &Activity,
    axis: usize,
    hi: [usize; 3],
    hi_active: bool,
    iso: f64,
    displace: bool,
) -> DVec3 {
    // index space of the high cell's voxel; the face centre is half a voxel below
    let centre = DVec3::new(hi[0] as f64 - 1.0, hi[1] as f64 - 1.0, hi[2] as f64 - 1.0);
    let mut p = centre;
    p[axis] -= 0.5;
    if !displace {
        return p;
    }
    // both cells must be voxels: the high one inside, the low one too
    let d = act.grid.dims;
    let inside = (1..=d.nx).contains(&hi[0])
        && (1..=d.ny).contains(&hi[1])
        && (1..=d.nz).contains(&hi[2])
        && hi[axis] >= 2;
    if !inside {
        return p;
    }
    let vh = (hi[0] - 1) + d.nx * ((hi[1] - 1) + d.ny * (hi[2] - 1));
    let vl = vh - [1, d.nx, d.nx * d.ny][axis];
    let (vh, vl) = (values[vh].to_f64(), values[vl].to_f64());
    let (va, vi) = if hi_active { (vh, vl) } else { (vl, vh) };
    let t = interpolation_fraction(va, vi, iso);
    // t: fraction of the way from the active centre to the inactive one
    if hi_active {
        p[axis] = centre[axis] - t;
    } else {
        p[axis] = centre[axis] - 1.0 + t;
    }
    p
}

/// Where the iso value lies between an active value `va` (≥ iso) and an
/// inactive one `vi` (< iso), as a fraction from the active end, kept within
/// [`MIN_FRACTION`], 1 − [`MIN_FRACTION`]; ½ if it is not a number (NaN or
/// infinite voxel values).
#[inline(always)]
pub(crate) fn interpolation_fraction(va: f64, vi: f64, iso: f64) -> f64 {
    let t = (va - iso) / (va - vi);
    if t.is_finite() {
        t.clamp(MIN_FRACTION, 1.0 - MIN_FRACTION)
    } else {
        0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn activity_matches_values_and_padding() {
        let dims = Dims::new(5, 3, 2).unwrap();
        let values: Vec<f64> = (0..30).map(|i| ((i * 7) % 11) as f64).collect();
        let act = Activity::new(&values, dims, 5.0);
        let g = act.grid;
        let mut n = 0;
        for q in 0..g.len {
            let expect = g.voxel(g.coords(q)).is_some_and(|v| values[v] >= 5.0);
            assert_eq!(act.get(q), expect, "cell {q}");
            n += expect as u64;
        }
        assert_eq!(act.active, n);
        // windows read across word boundaries and into the guard
        for q in -70isize..(g.len as isize + 10) {
            let w = act.window(q);
            for t in 0..64isize {
                let c = q + t;
                let expect = c >= 0 && (c as usize) < g.len && act.get(c as usize);
                assert_eq!(w >> t & 1 == 1, expect);
            }
        }
    }

    #[test]
    fn faces_are_numbered_densely() {
        let dims = Dims::new(4, 4, 4).unwrap();
        let values: Vec<u8> = (0..64).map(|i| ((i * 37) % 5 == 0) as u8).collect();
        let act = Activity::new(&values, dims, 1.0);
        let faces = Faces::new(&act);
        let g = act.grid;
        let mut expect = 0u32;
        for a in 0..3 {
            for q in g.stride[a]..g.len {
                if act.get(q) != act.get(q - g.stride[a]) {
                    assert_eq!(faces.id(a, q), expect);
                    expect += 1;
                }
            }
        }
        assert_eq!(faces.total, expect as u64);
        let pts = support_points(&values, &act, &faces, 1.0, false, |p| p);
        assert_eq!(pts.len(), expect as usize);
    }

    #[test]
    fn comparison_bits_pack_every_pattern() {
        for pattern in 0..=255u64 {
            for shift in [0, 8, 56] {
                let word = pattern << shift;
                let values: Vec<i16> = (0..64).map(|x| (word >> x & 1) as i16 * 7).collect();
                assert_eq!(at_least_bits(&values, 5), word);
                assert_eq!(
                    at_least_bits(&values[..shift + 3], 5),
                    word & ((1 << (shift + 3)) - 1)
                );
            }
        }
    }

    #[test]
    fn cuts_agree_with_comparing_as_f64() {
        fn check<T: Scalar>(values: &[T], isos: &[f64]) {
            for &iso in isos {
                let cut = T::cut(iso);
                for &v in values {
                    let expect = v.to_f64() >= iso;
                    assert_eq!(
                        cut.is_some_and(|c| v >= c),
                        expect,
                        "{} vs {iso}",
                        v.to_f64()
                    );
                }
            }
        }
        let isos = [
            -1e300,
            -129.0,
            -128.5,
            -128.0,
            -0.5,
            0.0,
            0.25,
            1.0,
            127.0,
            127.5,
            200.0,
            255.5,
            256.0,
            1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        check(&(i8::MIN..=i8::MAX).collect::<Vec<_>>(), &isos);
        check(&(u8::MIN..=u8::MAX).collect::<Vec<_>>(), &isos);
        let big = 2f64.powi(60);
        let around: Vec<i64> = (-3000..3000).map(|d| (1i64 << 60) + d).collect();
        check(&around, &[big, big + 256.0, big - 256.0, big - 1.0, 9.3e18]);
        let around: Vec<u64> = (0..3000).map(|d| u64::MAX - d).collect();
        check(&around, &[2f64.powi(64), 2f64.powi(64) - 2048.0, 1.8e19]);
        let floats = [
            f32::NEG_INFINITY,
            -f32::MAX,
            -1.0,
            -0.0,
            0.0,
            1e-45,
            0.1,
            0.2,
            1.0,
            f32::MAX,
            f32::INFINITY,
            f32::NAN,
        ];
        check(
            &floats,
            &[0.1, 0.2, -0.1, 1e-300, 0.0, -1e300, 1e300, f64::INFINITY],
        );
        check(&[f64::NAN, 0.1, 0.2, -5.0], &[0.1, 0.15, f64::NEG_INFINITY]);
    }

    #[test]
    fn interpolation_is_linear_and_clamped() {
        assert_eq!(interpolation_fraction(133.0, 0.0, 100.0), 33.0 / 133.0);
        assert_eq!(interpolation_fraction(100.0, 0.0, 100.0), MIN_FRACTION);
        assert_eq!(interpolation_fraction(f64::NAN, 0.0, 1.0), 0.5);
        assert_eq!(interpolation_fraction(f64::INFINITY, 0.0, 1.0), 0.5);
    }
}
