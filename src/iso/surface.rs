//! The march: every grid vertex of the padded volume, in parallel over fixed
//! ranges, emits the N-cycles of its 2×2×2 cell as triangles over the dense
//! boundary-face ids (VESTA's "original" point economy — one point per boundary
//! face — with the "marching" memory economy: nothing but the activity bits and
//! a few face counts is held for the whole volume).
//!
//! Grid vertices are visited 64 at a time: eight 64-bit activity windows (one
//! per octant) give every vertex's mask at once, and vertices whose eight cells
//! are all active or all inactive are skipped with two bit operations. Only
//! the others look up their [`CellEntry`]; in mixed mode, a vertex with a point
//! of ambiguity reads the four voxel values around each ambiguous edge. The
//! face ids come from the same windows: a word of the faces on one side of
//! the vertices is two octant windows XORed, and an id is the stream's count
//! at the word plus a popcount below the vertex's bit.

use std::mem::MaybeUninit;

use glam::DVec3;
use rayon::prelude::*;

#[cfg(target_arch = "x86_64")]
use super::cpu;
use super::grid::{Activity, Faces, Rows, WORDS_PER_TASK, funnel};
use super::stats::TypeCounts;
use super::table::{CellEntry, Table};
use super::{Mode, Scalar};
use crate::extract::Decompose;
use crate::geom::predicates::is_degenerate;
use crate::star::{edge_star, face_axis, face_octants};

/// Marks a triangle corner that refers to a part-local centroid (H mode).
pub(crate) const CENTROID: u32 = 1 << 31;

/// Output of one task besides its triangles.
#[derive(Default)]
pub(crate) struct Part {
    /// Number of triangles.
    pub tris: usize,
    /// H-mode centroids (index space).
    pub centroids: Vec<DVec3>,
    pub counts: TypeCounts,
}

/// Where a task puts its triangles (over face ids, or `CENTROID | local
/// index`): its slot of the output's spare capacity, and if that is full, a
/// vector of its own.
struct Tris<'o> {
    slot: &'o mut [MaybeUninit<[u32; 3]>],
    /// Triangles written to the slot.
    len: usize,
    spill: Vec<[u32; 3]>,
}

impl Tris<'_> {
    #[inline(always)]
    fn push(&mut self, t: [u32; 3]) {
        match self.slot.get_mut(self.len) {
            Some(s) => {
                s.write(t);
                self.len += 1;
            }
            None => self.spill.push(t),
        }
    }
}

/// What every task needs.
pub(crate) struct March<'a, T> {
    pub values: &'a [T],
    pub act: &'a Activity,
    pub faces: &'a Faces<'a>,
    /// Support points in index space (H mode reads them for the centroids).
    pub points: &'a [DVec3],
    pub iso: f64,
    pub mode: Mode,
    pub decompose: Decompose,
}

/// Per-quarter-face constants: normal axis and the octants on the face's −
/// and + sides (the face is on the low side of the + cell).
struct FaceCells {
    axis: [usize; 12],
    lo: [usize; 12],
    hi: [usize; 12],
}

impl FaceCells {
    fn new() -> Self {
        let mut fc = FaceCells {
            axis: [0; 12],
            lo: [0; 12],
            hi: [0; 12],
        };
        for f in 0..12 {
            fc.axis[f] = face_axis(f);
            (fc.lo[f], fc.hi[f]) = face_octants(f);
        }
        fc
    }
}

impl<T: Scalar> March<'_, T> {
    /// Runs all tasks: the triangles of all, in task order, and the other
    /// output of each task.
    ///
    /// The triangles go straight into the output: each task gets a slot of
    /// its spare capacity, room for two triangles per boundary face of its
    /// own cells and of the next task's (its vertices reach one slice
    /// further; a closed surface has about two triangles per point), and the
    /// slots are then moved together. Room never written costs nothing (its
    /// memory is never touched). If a slot overflows (not seen in practice),
    /// the march runs again with vectors of each task's own, concatenated.
    pub fn run(&self) -> (Vec<[u32; 3]>, Vec<Part>) {
        let words = self.act.grid.len.div_ceil(64);
        let tasks = words.div_ceil(WORDS_PER_TASK);
        let range = |t: usize| (t * WORDS_PER_TASK, ((t + 1) * WORDS_PER_TASK).min(words));
        let faces = |t: usize| {
            (0..3)
                .map(|a| {
                    if t < tasks {
                        self.faces.task_count(a, t)
                    } else {
                        0
                    }
                })
                .sum::<usize>()
        };
        let room: Vec<usize> = (0..tasks)
            .map(|t| 2 * (faces(t) + faces(t + 1)) + 64)
            .collect();
        let mut tris: Vec<[u32; 3]> = Vec::with_capacity(room.iter().sum());
        let mut slots = Vec::with_capacity(tasks);
        let mut rest = tris.spare_capacity_mut();
        for &r in &room {
            let (head, tail) = rest.split_at_mut(r);
            slots.push(head);
            rest = tail;
        }
        let done: Vec<(Part, usize, bool)> = slots
            .into_par_iter()
            .enumerate()
            .map(|(t, slot)| {
                let (w0, w1) = range(t);
                let mut out = Tris {
                    slot,
                    len: 0,
                    spill: Vec::new(),
                };
                let part = self.task(w0, w1, &mut out);
                (part, out.len, !out.spill.is_empty())
            })
            .collect();
        if done.iter().any(|d| d.2) {
            return self.run_spilled();
        }
        let spare = tris.spare_capacity_mut();
        let (mut at, mut start) = (0, 0);
        for (d, &r) in done.iter().zip(&room) {
            spare.copy_within(start..start + d.1, at);
            at += d.1;
            start += r;
        }
        // SAFETY: the first `at` elements of the spare capacity are
        // initialised: each task wrote the first `len` elements of its slot
        // (`Tris::push`), and the slots were moved down in task order, each
        // to the end of the previous one, before any later slot was touched.
        unsafe { tris.set_len(at) };
        (tris, done.into_iter().map(|d| d.0).collect())
    }

    /// [`run`](Self::run) with every task's triangles in a vector of its own.
    #[cold]
    fn run_spilled(&self) -> (Vec<[u32; 3]>, Vec<Part>) {
        let words = self.act.grid.len.div_ceil(64);
        let tasks = words.div_ceil(WORDS_PER_TASK);
        let done: Vec<(Part, Vec<[u32; 3]>)> = (0..tasks)
            .into_par_iter()
            .map(|t| {
                let faces = (0..3).map(|a| self.faces.task_count(a, t)).sum::<usize>();
                let mut out = Tris {
                    slot: &mut [],
                    len: 0,
                    spill: Vec::with_capacity(2 * faces + 16),
                };
                let w0 = t * WORDS_PER_TASK;
                let part = self.task(w0, (w0 + WORDS_PER_TASK).min(words), &mut out);
                (part, out.spill)
            })
            .collect();
        let mut tris = Vec::with_capacity(done.iter().map(|d| d.1.len()).sum());
        for d in &done {
            tris.extend_from_slice(&d.1);
        }
        (tris, done.into_iter().map(|d| d.0).collect())
    }

    /// Grid vertices whose octant-0 cell lies in words `w0..w1`.
    fn task(&self, w0: usize, w1: usize, out: &mut Tris) -> Part {
        #[cfg(target_arch = "x86_64")]
        if cpu::fast() {
            // SAFETY: the CPU has the features (checked just above).
            return unsafe { self.task_fast(w0, w1, out) };
        }
        self.task_body(w0, w1, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "popcnt,bmi1,bmi2,lzcnt,avx2")]
    unsafe fn task_fast(&self, w0: usize, w1: usize, out: &mut Tris) -> Part {
        self.task_body(w0, w1, out)
    }

    /// The march over words `w0..w1`. Face ids are counted off along the words:
    /// the quarter-face `f` of the vertex at cell `q` is the face on the low side
    /// of cell `q + offset(hi(f))`, and a word of those faces is the XOR of the
    /// octant windows `hi(f)` and `lo(f)`; `next[f]` is the id of the first face
    /// of the stream at or after the current word (a [`Faces::rank`] at the
    /// task's start, then advanced by each word's count). Words where all eight
    /// windows agree everywhere have no boundary faces and are skipped.
    /// Cycles are counted per mask where the vertex has the mode's usual
    /// connect set (always in the global modes), and added up by entry at the
    /// end.
    #[inline(always)]
    fn task_body(&self, w0: usize, w1: usize, out: &mut Tris) -> Part {
        let grid = &self.act.grid;
        let offsets = grid.octant_offsets();
        let fc = FaceCells::new();
        let table = Table::get();
        let mut part = Part::default();
        let usual = if self.mode == Mode::Connect { 0x3f } else { 0 };
        let mut by_mask = [0u32; 256];
        let mut rows = Rows::new(grid, w0 * 64);
        let edge_octants: [[usize; 4]; 6] = std::array::from_fn(|e| edge_star(e).0);
        let mut next: [u32; 12] =
            std::array::from_fn(|f| self.faces.rank(fc.axis[f], w0 * 64 + offsets[fc.hi[f]]));
        // window of octant o at word w: bits[w + word[o]] and the next, shifted
        let word_shift: [(usize, u32); 8] = offsets.map(|o| {
            let bit = self.act.guard + o;
            (bit >> 6, (bit & 63) as u32)
        });
        let bits = &self.act.bits[..];
        let mut win = [0u64; 8];
        let mut fw = [0u64; 12];
        for w in w0..w1 {
            let (mut any, mut all) = (0, !0);
            for o in 0..8 {
                let (d, s) = word_shift[o];
                win[o] = funnel(bits, w + d, s);
                any |= win[o];
                all &= win[o];
            }
            let mut todo = any & !all;
            if todo == 0 {
                continue;
            }
            for f in 0..12 {
                fw[f] = win[fc.hi[f]] ^ win[fc.lo[f]];
            }
            while todo != 0 {
                let t = todo.trailing_zeros() as usize;
                todo &= todo - 1;
                let mut mask = 0u8;
                for (o, wo) in win.iter().enumerate() {
                    mask |= ((wo >> t) as u8 & 1) << o;
                }
                let connect = match self.mode {
                    Mode::Disconnect => 0,
                    Mode::Connect => 0x3f,
                    Mode::Mixed => match table.ambiguous(mask) {
                        0 => 0,
                        amb => self.mixed_connect(rows.coords(w * 64 + t), amb, &edge_octants),
                    },
                };
                let entry = table.entry(mask, connect);
                if connect == usual {
                    by_mask[mask as usize] += 1;
                } else {
                    part.counts.add_entry(entry, 1);
                }
                // ids of all twelve quarter-faces (those that are no boundary
                // faces are never read): cheaper than a loop over the entry's
                let below = (1u64 << t) - 1;
                let mut id = [0u32; 16];
                for f in 0..12 {
                    id[f] = next[f] + (fw[f] & below).count_ones();
                }
                self.emit(&mut part, out, entry, &id);
            }
            for f in 0..12 {
                next[f] += fw[f].count_ones();
            }
        }
        for (mask, &n) in by_mask.iter().enumerate() {
            if n > 0 {
                part.counts
                    .add_entry(table.entry(mask as u8, usual), n as u64);
            }
        }
        part.tris = out.len + out.spill.len();
        part
    }

    /// Mixed mode: join at an ambiguous edge iff the mean of its four voxels
    /// is at least the iso value. `c`: padded coordinates of the octant-0
    /// cell; `amb`: the ambiguous half-edges; `edge_octants`: of each half-edge.
    fn mixed_connect(&self, c: [usize; 3], amb: u8, edge_octants: &[[usize; 4]; 6]) -> u8 {
        let d = self.act.grid.dims;
        let mut connect = 0;
        for (e, octants) in edge_octants.iter().enumerate() {
            if amb >> e & 1 == 0 {
                continue;
            }
            let mut sum = 0.0;
            for &o in octants {
                // cells at an ambiguous edge are never padding (two of them would
                // have to be active outside cells); treat it as −∞ regardless
                let [i, j, k] = [c[0] + (o & 1), c[1] + (o >> 1 & 1), c[2] + (o >> 2 & 1)];
                let inside =
                    (1..=d.nx).contains(&i) && (1..=d.ny).contains(&j) && (1..=d.nz).contains(&k);
                sum += if inside {
                    self.values[(i - 1) + d.nx * ((j - 1) + d.ny * (k - 1))].to_f64()
                } else {
                    f64::NEG_INFINITY
                };
            }
            if sum / 4.0 >= self.iso {
                connect |= 1 << e;
            }
        }
        connect
    }

    /// Emits the triangles of one vertex (`id`: of its quarter-faces).
    #[inline(always)]
    fn emit(&self, part: &mut Part, out: &mut Tris, entry: &CellEntry, id: &[u32; 16]) {
        match self.decompose {
            Decompose::L => {
                for t in entry.all_tris() {
                    out.push(t.map(|f| id[f as usize & 15]));
                }
            }
            Decompose::H => {
                for i in 0..entry.cycles as usize {
                    let cycle = entry.cycle(i);
                    if cycle.len() == 3 || !self.centroid_fan(part, out, cycle, id) {
                        for t in entry.cycle_tris(i) {
                            out.push(t.map(|f| id[f as usize & 15]));
                        }
                    }
                }
            }
        }
    }

    /// H mode: a fan around the average of the cycle's support points. False
    /// (and nothing emitted) if a fan triangle would be degenerate.
    fn centroid_fan(&self, part: &mut Part, out: &mut Tris, cycle: &[u8], id: &[u32; 16]) -> bool {
        let n = cycle.len();
        let mut pts = [DVec3::ZERO; 12];
        for (k, &f) in cycle.iter().enumerate() {
            pts[k] = self.points[id[f as usize & 15] as usize];
        }
        let c = pts[..n].iter().copied().sum::<DVec3>() / n as f64;
        if (0..n).any(|k| is_degenerate(c, pts[k], pts[(k + 1) % n])) {
            return false;
        }
        let cref = CENTROID | part.centroids.len() as u32;
        part.centroids.push(c);
        for k in 0..n {
            out.push([
                cref,
                id[cycle[k] as usize & 15],
                id[cycle[(k + 1) % n] as usize & 15],
            ]);
        }
        true
    }
}
