//! The march: every grid vertex of the padded volume, in parallel over fixed
//! ranges, emits the N-cycles of its 2×2×2 cell as triangles over the dense
//! boundary-face ids (VESTA's "original" point economy — one point per boundary
//! face — with the "marching" memory economy: nothing but the activity bits and
//! the face ranks is held for the whole volume).
//!
//! Grid vertices are visited 64 at a time: eight 64-bit activity windows (one
//! per octant) give every vertex's mask at once, and vertices whose eight cells
//! are all active or all inactive are skipped with two bit operations. Only
//! the others look up their [`CellEntry`]; in mixed mode, a vertex with a point
//! of ambiguity reads the four voxel values around each ambiguous edge.

use glam::DVec3;
use rayon::prelude::*;

use super::grid::{Activity, Faces, Rows, WORDS_PER_TASK};
use super::stats::TypeCounts;
use super::table::{CellEntry, Table};
use super::{Mode, Scalar};
use crate::extract::{Decompose, is_degenerate};
use crate::star::{edge_star, face_axis, face_octants};

/// Marks a triangle corner that refers to a part-local centroid (H mode).
pub(crate) const CENTROID: u32 = 1 << 31;

/// Output of one task.
#[derive(Default)]
pub(crate) struct Part {
    /// Triangles over face ids, or `CENTROID | local index`.
    pub tris: Vec<[u32; 3]>,
    /// H-mode centroids (index space).
    pub centroids: Vec<DVec3>,
    pub counts: TypeCounts,
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

/// Per-quarter-face constants: normal axis and the offset of the cell on the
/// face's + side (the face is on that cell's low side).
struct FaceCells {
    axis: [usize; 12],
    hi: [usize; 12],
}

impl FaceCells {
    fn new(offsets: &[usize; 8]) -> Self {
        let mut fc = FaceCells {
            axis: [0; 12],
            hi: [0; 12],
        };
        for f in 0..12 {
            fc.axis[f] = face_axis(f);
            fc.hi[f] = offsets[face_octants(f).1];
        }
        fc
    }
}

impl<T: Scalar> March<'_, T> {
    /// Runs all tasks; parts in a fixed order.
    pub fn run(&self) -> Vec<Part> {
        let words = self.act.grid.len.div_ceil(64);
        let tasks = words.div_ceil(WORDS_PER_TASK);
        (0..tasks)
            .into_par_iter()
            .map(|t| self.task(t * WORDS_PER_TASK, ((t + 1) * WORDS_PER_TASK).min(words)))
            .collect()
    }

    /// Grid vertices whose octant-0 cell lies in words `w0..w1`.
    fn task(&self, w0: usize, w1: usize) -> Part {
        let offsets = self.act.grid.octant_offsets();
        let fc = FaceCells::new(&offsets);
        let table = Table::get();
        // a closed surface has about two triangles per point: room for them up
        // front, instead of growing by copies (untouched room costs nothing)
        let faces = (0..3)
            .map(|a| self.faces.task_count(a, w0 / WORDS_PER_TASK))
            .sum::<usize>();
        let mut part = Part {
            tris: Vec::with_capacity(2 * faces + 16),
            ..Part::default()
        };
        let mut rows = Rows::new(&self.act.grid, w0 * 64);
        let edge_octants: [[usize; 4]; 6] = std::array::from_fn(|e| edge_star(e).0);
        for w in w0..w1 {
            let q0 = (w * 64) as isize;
            let win = offsets.map(|o| self.act.window(q0 + o as isize));
            let any = win.iter().fold(0, |a, &b| a | b);
            let all = win.iter().fold(!0, |a, &b| a & b);
            let mut todo = any & !all;
            while todo != 0 {
                let t = todo.trailing_zeros() as usize;
                todo &= todo - 1;
                let mut mask = 0u8;
                for (o, wo) in win.iter().enumerate() {
                    mask |= ((wo >> t) as u8 & 1) << o;
                }
                let q = w * 64 + t;
                let connect = match self.mode {
                    Mode::Disconnect => 0,
                    Mode::Connect => 0x3f,
                    Mode::Mixed => match table.ambiguous(mask) {
                        0 => 0,
                        amb => self.mixed_connect(rows.coords(q), amb, &edge_octants),
                    },
                };
                self.emit(&mut part, table.entry(mask, connect), q, &fc);
            }
        }
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

    /// Emits the cycles of one vertex.
    fn emit(&self, part: &mut Part, entry: &CellEntry, q: usize, fc: &FaceCells) {
        let mut id = [0u32; 12];
        for &f in &entry.faces[..entry.face_count()] {
            let f = f as usize;
            id[f] = self.faces.id(fc.axis[f], q + fc.hi[f]);
        }
        for i in 0..entry.cycles as usize {
            part.counts.add(entry.types[i], entry.cycle(i).len());
        }
        match self.decompose {
            Decompose::L => {
                for t in entry.all_tris() {
                    part.tris.push(t.map(|f| id[f as usize]));
                }
            }
            Decompose::H => {
                for i in 0..entry.cycles as usize {
                    let cycle = entry.cycle(i);
                    if cycle.len() == 3 || !self.centroid_fan(part, cycle, &id) {
                        for t in entry.cycle_tris(i) {
                            part.tris.push(t.map(|f| id[f as usize]));
                        }
                    }
                }
            }
        }
    }

    /// H mode: a fan around the average of the cycle's support points. False
    /// (and nothing emitted) if a fan triangle would be degenerate.
    fn centroid_fan(&self, part: &mut Part, cycle: &[u8], id: &[u32; 12]) -> bool {
        let n = cycle.len();
        let mut pts = [DVec3::ZERO; 12];
        for (k, &f) in cycle.iter().enumerate() {
            pts[k] = self.points[id[f as usize] as usize];
        }
        let c = pts[..n].iter().copied().sum::<DVec3>() / n as f64;
        if (0..n).any(|k| is_degenerate(c, pts[k], pts[(k + 1) % n])) {
            return false;
        }
        let cref = CENTROID | part.centroids.len() as u32;
        part.centroids.push(c);
        for k in 0..n {
            part.tris
                .push([cref, id[cycle[k] as usize], id[cycle[(k + 1) % n] as usize]]);
        }
        true
    }
}
