//! The march: every grid vertex of the padded 4-D grid, in parallel over fixed
//! (z, t) slabs, traces the cycles and polyhedra of its 2⁴ cell
//! ([`cell_shape`]) and decomposes each polyhedron into oriented tetrahedra as
//! the paper's section III.E does:
//!
//! - a polyhedron bounded by four 3-cycles is one tetrahedron;
//! - otherwise every N-cycle with N > 3 gets a *face centre* (the mean of its
//!   support points) and is cut into N triangles around it; 3-cycles stay
//!   whole; a *volume centre* (the mean of the face centres, a 3-cycle
//!   counting with its centroid) is joined to every triangle.
//!
//! A face centre is shared by the two cells at the ends of the grid edge its
//! cycle goes around; the cell at the lower end computes it, and both refer to
//! it by (edge, smallest cube id of the cycle). Tetrahedra list the apex (the
//! volume centre, or the fourth vertex of a lone tetrahedron) first and then
//! the triangle in the cycle's path-table direction, which makes the
//! hypersurface consistently oriented; [`crate::hyper`] documents the sign.

use glam::DVec4;
use rayon::prelude::*;

use super::cell::{
    CUBES, SQUARES, ambiguous_squares, cube_axis, cube_toxels, is_boundary, square_toxels,
};
use super::grid::{Activity, Cubes, Grid};
use super::table::{CONNECT_ALL, CellShape, cell_shape};
use crate::iso::{Mode, Scalar};

/// Tag of a tetrahedron corner that is a task-local face centre.
pub(crate) const FACE: u32 = 1 << 30;
/// Tag of a tetrahedron corner that is a task-local volume centre.
pub(crate) const VOLUME: u32 = 2 << 30;
/// Both tag bits.
pub(crate) const TAG: u32 = 3 << 30;

/// Counts gathered by the march.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Counts {
    /// 2-faces by length (each counted once, at the lower end of its edge).
    pub cycles_by_length: [u64; 13],
    pub polyhedra: u64,
    /// Polyhedra that are a single tetrahedron.
    pub tetrahedra_polyhedra: u64,
    /// Polyhedra whose boundary is a torus or of higher genus (their volume
    /// centre is a cone point of the hypersurface).
    pub higher_genus: u64,
    /// Grid vertices with at least one boundary cube.
    pub cells: u64,
    /// Points of ambiguity met (each counted once per cell).
    pub ambiguities: u64,
}

impl Counts {
    pub(crate) fn merge(&mut self, o: &Counts) {
        for (a, b) in self.cycles_by_length.iter_mut().zip(o.cycles_by_length) {
            *a += b;
        }
        self.polyhedra += o.polyhedra;
        self.tetrahedra_polyhedra += o.tetrahedra_polyhedra;
        self.higher_genus += o.higher_genus;
        self.cells += o.cells;
        self.ambiguities += o.ambiguities;
    }
}

/// Output of one task.
#[derive(Default)]
pub(crate) struct Part {
    /// Corners: cube ids, or `FACE | local face`, or `VOLUME | local volume centre`.
    pub tets: Vec<[u32; 4]>,
    /// Key (edge, smallest cube id) of each local face reference.
    pub face_keys: Vec<(u64, u32)>,
    /// Positions of the faces this task owns: (local face, position).
    pub face_pos: Vec<(u32, [f64; 4])>,
    pub volumes: Vec<[f64; 4]>,
    pub counts: Counts,
}

/// What every task needs.
pub(crate) struct March<'a, T> {
    pub values: &'a [T],
    pub act: &'a Activity,
    pub cubes: &'a Cubes,
    pub points: &'a [[f64; 4]],
    pub iso: f64,
    pub mode: Mode,
}

impl<T: Scalar> March<'_, T> {
    /// Runs all tasks; parts in a fixed order.
    pub fn run(&self) -> Vec<Part> {
        let g = self.act.grid;
        let (nz, nt) = (g.p[2] - 1, g.p[3] - 1);
        (0..nz * nt)
            .into_par_iter()
            .map(|k| self.task(k % nz, k / nz))
            .collect()
    }

    /// All cells whose lowest toxel has coordinates (·, ·, z, t). Cells are
    /// visited 64 at a time along x: the OR and AND of the 16 activity
    /// windows skip cells whose toxels are all active or all inactive.
    fn task(&self, z: usize, t: usize) -> Part {
        let g: &Grid = &self.act.grid;
        let off = g.cell_offsets();
        let nx = g.p[0] - 1;
        let mut part = Part::default();
        for y in 0..g.p[1] - 1 {
            let row = y * g.stride[1] + z * g.stride[2] + t * g.stride[3];
            for x0 in (0..nx).step_by(64) {
                let (mut any, mut all) = (0u64, !0u64);
                for &d in &off {
                    let w = self.act.window((row + x0 + d) as isize);
                    any |= w;
                    all &= w;
                }
                let mut todo = any & !all;
                if nx - x0 < 64 {
                    todo &= (1u64 << (nx - x0)) - 1;
                }
                while todo != 0 {
                    let b = todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    self.cell(&mut part, row + x0 + b, &off);
                }
            }
        }
        part
    }

    /// One cell with at least one boundary cube.
    fn cell(&self, part: &mut Part, q: usize, off: &[usize; 16]) {
        let mut mask = 0u16;
        for (o, &d) in off.iter().enumerate() {
            mask |= (self.act.get(q + d) as u16) << o;
        }
        let amb = ambiguous_squares(mask);
        let connect = match self.mode {
            Mode::Disconnect => 0,
            Mode::Connect => CONNECT_ALL,
            Mode::Mixed => self.mixed_connect(q, amb, off),
        };
        part.counts.cells += 1;
        part.counts.ambiguities += amb.count_ones() as u64;
        let shape = cell_shape(mask, connect);
        self.emit(part, &shape, mask, q, off);
    }

    /// Mixed mode: join at a point of ambiguity iff the mean of its four
    /// toxels is at least the iso value.
    fn mixed_connect(&self, q: usize, amb: u32, off: &[usize; 16]) -> u32 {
        let g = &self.act.grid;
        let mut connect = 0;
        for s in 0..SQUARES {
            if amb >> s & 1 == 0 {
                continue;
            }
            let mut sum = 0.0;
            for o in square_toxels(s) {
                // two diagonal active toxels put all four inside the volume
                sum += match g.toxel(g.coords(q + off[o])) {
                    Some(v) => self.values[v].to_f64(),
                    None => f64::NEG_INFINITY,
                };
            }
            if sum / 4.0 >= self.iso {
                connect |= 1 << s;
            }
        }
        connect
    }

    /// Decomposes the polyhedra of one cell into tetrahedra.
    fn emit(&self, part: &mut Part, shape: &CellShape, mask: u16, q: usize, off: &[usize; 16]) {
        let g = &self.act.grid;
        let mut id = [u32::MAX; CUBES];
        for (c, slot) in id.iter_mut().enumerate() {
            if is_boundary(mask, c) {
                let (_, hi) = cube_toxels(c);
                *slot = self.cubes.id(cube_axis(c), q + off[hi]);
            }
        }
        let pos = |c: u8| DVec4::from_array(self.points[id[c as usize] as usize]);
        // cycle counts, once per face: at the lower end of its edge (+ half-edge)
        for i in 0..shape.cycles as usize {
            if shape.cycle_half_edge[i] & 1 == 1 {
                part.counts.cycles_by_length[shape.cycle(i).len().min(12)] += 1;
            }
        }
        for p in 0..shape.polys as usize {
            part.counts.polyhedra += 1;
            if genus_above_zero(shape, p) {
                part.counts.higher_genus += 1;
            }
            if shape.is_tetrahedron(p) {
                part.counts.tetrahedra_polyhedra += 1;
                let first = shape.poly_cycles(p).next().expect("four cycles");
                let tri = shape.cycle(first);
                let apex = shape
                    .poly_cycles(p)
                    .flat_map(|i| shape.cycle(i).iter().copied())
                    .find(|c| !tri.contains(c))
                    .expect("a tetrahedron has four vertices");
                part.tets.push([
                    id[apex as usize],
                    id[tri[0] as usize],
                    id[tri[1] as usize],
                    id[tri[2] as usize],
                ]);
                continue;
            }
            let vol = VOLUME | part.volumes.len() as u32;
            let mut centre_sum = DVec4::ZERO;
            let mut faces = 0usize;
            for i in shape.poly_cycles(p) {
                let cyc = shape.cycle(i);
                faces += 1;
                if cyc.len() == 3 {
                    centre_sum += (pos(cyc[0]) + pos(cyc[1]) + pos(cyc[2])) / 3.0;
                    part.tets.push([
                        vol,
                        id[cyc[0] as usize],
                        id[cyc[1] as usize],
                        id[cyc[2] as usize],
                    ]);
                    continue;
                }
                // face centre: sum in ascending cube-id order (canonical)
                let mut ids: [u32; 12] = [u32::MAX; 12];
                for (k, &c) in cyc.iter().enumerate() {
                    ids[k] = id[c as usize];
                }
                let ids = &mut ids[..cyc.len()];
                ids.sort_unstable();
                let mut sum = DVec4::ZERO;
                for &v in ids.iter() {
                    sum += DVec4::from_array(self.points[v as usize]);
                }
                let centre = sum / cyc.len() as f64;
                centre_sum += centre;
                let h = shape.cycle_half_edge[i] as usize;
                let (d, side) = (h / 2, h & 1);
                let lower = if side == 1 { q } else { q - g.stride[d] };
                let local = part.face_keys.len() as u32;
                part.face_keys
                    .push(((lower as u64) << 2 | d as u64, ids[0]));
                if side == 1 {
                    part.face_pos.push((local, centre.to_array()));
                }
                let fc = FACE | local;
                for k in 0..cyc.len() {
                    let (a, b) = (cyc[k], cyc[(k + 1) % cyc.len()]);
                    part.tets.push([vol, fc, id[a as usize], id[b as usize]]);
                }
            }
            part.volumes.push((centre_sum / faces as f64).to_array());
        }
    }
}

/// Whether polyhedron `p`'s boundary has genus > 0 (V − E + F < 2).
fn genus_above_zero(shape: &CellShape, p: usize) -> bool {
    let mut seen = 0u32;
    let (mut e2, mut f) = (0usize, 0i64);
    for i in shape.poly_cycles(p) {
        let c = shape.cycle(i);
        e2 += c.len();
        f += 1;
        for &x in c {
            seen |= 1 << x;
        }
    }
    (seen.count_ones() as i64 - (e2 / 2) as i64 + f) < 2
}
