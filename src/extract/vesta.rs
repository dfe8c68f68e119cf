//! The VESTA construction on the mixed coarse/fine grid, one grid vertex at a time.
//!
//! The surface is the dual of the labels' boundary faces: one support point per
//! boundary face (its centre), and for each grid vertex `g` and each label `l`
//! at `g`, the cycle of `l`'s boundary faces around `g` (an N-cycle). The cycle is
//! split into runs of faces with the same neighbour label `m`; a cycle with one
//! run is one polygon of patch {l, m}; a run entered through edge `e_in` and left
//! through `e_out` becomes the polygon `mid(e_in), c(f_p) … c(f_q), mid(e_out), g`,
//! whose chords `mid(e) – g` are pieces of junction curves. Each polygon is
//! emitted once, by the lower label of its pair, oriented from it to the higher.
//!
//! Two paths produce the same kind of output:
//! - the **coarse path** visits every grid vertex none of whose 8 cells is refined,
//!   in parallel over z slabs, with tables only (no allocation per vertex);
//! - the **fine path** visits every fine grid vertex in the closure of a refined
//!   voxel (each once, by the lowest refined voxel containing it); quarter-faces
//!   lying in a coarse face between unrefined voxels belong to that coarse face,
//!   and consecutive quarter-faces of one coarse face merge into one support point.

use glam::DVec3;

use super::coarse_faces::CoarseFaces;
use super::lattice::{Key, Lattice, Positions};
use super::polygon::{centroid_fan, min_area_triangulation, vertex_fan};
use super::{Decompose, Part};
use crate::geom::predicates::is_degenerate;
use crate::preprocess::RefinedVolume;
use crate::star::{
    CycleStep, MaskStar, StarTable, edge_dir, edge_star, face_axis, face_center_offset,
    face_octants,
};
use crate::volume::LabelId;

/// Tags of vertex references in [`Part`] triangles.
pub(crate) const TAG_KEY: u64 = 1 << 62;
pub(crate) const TAG_CENTROID: u64 = 2 << 62;
pub(crate) const TAG_MASK: u64 = 3 << 62;

#[inline]
fn key_ref(k: Key) -> u64 {
    TAG_KEY | k
}

/// Pair id of a label pair (a < b).
#[inline]
pub(crate) fn pair_code(a: LabelId, b: LabelId) -> u32 {
    ((a as u32) << 16) | b as u32
}

/// L triangulations of the single cycle of every manifold mask on the unit grid.
pub(crate) struct LTable {
    tris: Vec<Vec<[u8; 3]>>,
}

impl LTable {
    pub(crate) fn get() -> &'static LTable {
        static T: std::sync::OnceLock<LTable> = std::sync::OnceLock::new();
        T.get_or_init(|| {
            let table = StarTable::disconnect();
            let tris = (0..=255u8)
                .map(|m| {
                    let star = table.get(m);
                    if star.cycles != 1 {
                        return Vec::new();
                    }
                    let pts: Vec<DVec3> = star
                        .cycle(0)
                        .iter()
                        .map(|st| {
                            let o = face_center_offset(st.face as usize);
                            DVec3::new(o[0] as f64, o[1] as f64, o[2] as f64) * 0.5
                        })
                        .collect();
                    min_area_triangulation(&pts)
                        .map(|t| t.into_iter().map(|x| x.map(|v| v as u8)).collect())
                        .unwrap_or_default()
                })
                .collect();
            LTable { tris }
        })
    }
}

/// A point of a polygon: its reference and index-space position.
type Pt = (u64, DVec3);

/// One step of a cycle after merging: support point, neighbour label, edges.
#[derive(Clone, Copy)]
struct Step {
    point: Pt,
    neighbour: LabelId,
    in_edge: u8,
    out_edge: u8,
}

/// What every vertex visit needs.
pub(crate) struct Ctx<'a> {
    pub rv: &'a RefinedVolume,
    pub faces: &'a CoarseFaces,
    pub lat: Lattice,
    /// The positions of lattice coordinates, looked up.
    pub positions: Positions,
    pub decompose: Decompose,
}

/// The grid vertex being visited.
struct Vertex {
    lattice: [i32; 3],
    /// Half-length of each half-edge in lattice units (s for an unsplit coarse edge, 1 for a fine edge).
    half: [i32; 6],
}

impl Vertex {
    fn point(&self, ctx: &Ctx) -> Pt {
        (
            key_ref(ctx.lat.key(self.lattice)),
            ctx.positions.at(self.lattice),
        )
    }

    fn mid(&self, ctx: &Ctx, e: usize) -> Pt {
        let d = edge_dir(e);
        let l = [0, 1, 2].map(|a| self.lattice[a] + d[a] * self.half[e]);
        (key_ref(ctx.lat.key(l)), ctx.positions.at(l))
    }
}

/// Emits the triangles of one polygon of patch `pair`. `apex` is the index of
/// the junction vertex in `pts`, if the polygon has one; `table` an L
/// triangulation precomputed for this exact cycle.
fn emit_polygon(
    part: &mut Part,
    pts: &[Pt],
    pair: u32,
    apex: Option<usize>,
    table: Option<&[[u8; 3]]>,
    decompose: Decompose,
) {
    let n = pts.len();
    let push = |part: &mut Part, t: [u64; 3]| {
        part.tris.push(t);
        part.pairs.push(pair);
    };
    if n == 3 {
        push(part, [pts[0].0, pts[1].0, pts[2].0]);
        return;
    }
    let mut pos = [DVec3::ZERO; 24];
    for (i, p) in pts.iter().enumerate() {
        pos[i] = p.1;
    }
    let pos = &pos[..n];
    if decompose == Decompose::H {
        if let Some((c, fan)) = centroid_fan(pos) {
            let cref = TAG_CENTROID | part.centroids.len() as u64;
            part.centroids.push(c);
            for t in fan {
                push(part, [cref, pts[t[1]].0, pts[t[2]].0]);
            }
            return;
        }
    }
    if let Some(a) = apex {
        let fan = vertex_fan(n, a);
        if fan
            .iter()
            .all(|t| !is_degenerate(pos[t[0]], pos[t[1]], pos[t[2]]))
        {
            for t in fan {
                push(part, t.map(|i| pts[i].0));
            }
            return;
        }
    }
    if let Some(tris) = table.filter(|t| !t.is_empty()) {
        for t in tris {
            push(part, t.map(|i| pts[i as usize].0));
        }
        return;
    }
    if let Some(tris) = min_area_triangulation(pos) {
        for t in tris {
            push(part, t.map(|i| pts[i].0));
        }
        return;
    }
    // Last resort (not expected on valid input): the validator will flag it.
    let (c, fan) = match centroid_fan(pos) {
        Some(f) => f,
        None => (
            pos.iter().copied().sum::<DVec3>() / n as f64,
            (0..n).map(|i| [n, i, (i + 1) % n]).collect(),
        ),
    };
    let cref = TAG_CENTROID | part.centroids.len() as u64;
    part.centroids.push(c);
    for t in fan {
        push(part, [cref, pts[t[1]].0, pts[t[2]].0]);
    }
}

/// Splits one cycle of label `l` into runs and emits the polygons owned by `l`.
fn emit_cycle(
    ctx: &Ctx,
    part: &mut Part,
    l: LabelId,
    steps: &[Step],
    v: &Vertex,
    table: Option<&[[u8; 3]]>,
) {
    let n = steps.len();
    let first = steps[0].neighbour;
    if steps.iter().all(|s| s.neighbour == first) {
        // A hanging vertex on a straight coarse edge sees only the two coarse
        // faces of the fold: a digon, no area. The dual edge between the two
        // faces comes from the edge's end vertices, as if it were not split.
        if l < first && n >= 3 {
            let mut pts = [(0u64, DVec3::ZERO); 16];
            for (i, s) in steps.iter().enumerate() {
                pts[i] = s.point;
            }
            emit_polygon(
                part,
                &pts[..n],
                pair_code(l, first),
                None,
                table,
                ctx.decompose,
            );
        }
        return;
    }
    // Start at a run boundary.
    let start = (0..n)
        .find(|&t| steps[t].neighbour != steps[(t + n - 1) % n].neighbour)
        .expect("two runs");
    let mut t = 0;
    while t < n {
        let p = (start + t) % n;
        let m = steps[p].neighbour;
        let mut q = t;
        while q + 1 < n && steps[(start + q + 1) % n].neighbour == m {
            q += 1;
        }
        if l < m {
            let mut pts = [(0u64, DVec3::ZERO); 16];
            let mut k = 0;
            pts[k] = v.mid(ctx, steps[p].in_edge as usize);
            k += 1;
            for r in t..=q {
                pts[k] = steps[(start + r) % n].point;
                k += 1;
            }
            pts[k] = v.mid(ctx, steps[(start + q) % n].out_edge as usize);
            k += 1;
            pts[k] = v.point(ctx);
            k += 1;
            emit_polygon(
                part,
                &pts[..k],
                pair_code(l, m),
                Some(k - 1),
                None,
                ctx.decompose,
            );
        }
        t = q + 1;
    }
}

/// Junction chords at a vertex: half-edges with three or more labels around them.
fn emit_chords(ctx: &Ctx, part: &mut Part, oct: &[LabelId; 8], v: &Vertex) {
    // a junction needs three labels at the vertex
    let a = oct[0];
    let Some(b) = oct.iter().copied().find(|&l| l != a) else {
        return;
    };
    if oct.iter().all(|&l| l == a || l == b) {
        return;
    }
    for e in 0..6 {
        let (octs, _) = edge_star(e);
        let mut labels = octs.map(|o| oct[o]);
        labels.sort_unstable();
        let mut distinct = 1;
        for i in 1..4 {
            if labels[i] != labels[i - 1] {
                labels[distinct] = labels[i];
                distinct += 1;
            }
        }
        if distinct >= 3 {
            part.chords.push(super::Chord {
                a: v.point(ctx).0,
                b: v.mid(ctx, e).0,
                labels,
                count: distinct as u8,
            });
        }
    }
}

/// Octant offsets in the padded buffer.
fn octant_offsets(strides: [usize; 3]) -> [usize; 8] {
    let [sx, sy, sz] = strides;
    [0, sx, sy, sx + sy, sz, sz + sx, sz + sy, sz + sy + sx]
}

/// The coarse path over grid vertex planes `k0..k1`, emitted into `part`.
pub(crate) fn coarse_slab(ctx: &Ctx, part: &mut Part, k0: i32, k1: i32) {
    let rv = ctx.rv;
    let grid = rv.grid();
    let data = grid.data();
    let offsets = octant_offsets(grid.strides());
    let table = StarTable::disconnect();
    let ltable = LTable::get();
    let s = ctx.lat.s;
    for k in k0..k1 {
        for (i, j, base) in grid.candidates_in_plane(k as usize) {
            {
                let c0 = data[base];
                let mut oct = [c0; 8];
                let mut uniform = true;
                for o in 1..8 {
                    oct[o] = data[base + offsets[o]];
                    uniform &= oct[o] == c0;
                }
                if uniform || offsets.iter().any(|&off| rv.is_refined_padded(base + off)) {
                    continue;
                }
                let v = Vertex {
                    lattice: ctx.lat.of_fine_vertex([i * s, j * s, k * s]),
                    half: [s; 6],
                };
                let mut seen = 0u8;
                for o in 0..8 {
                    if seen >> o & 1 == 1 {
                        continue;
                    }
                    let l = oct[o];
                    let mask = mask_of(&oct, l);
                    seen |= mask;
                    let star = table.get(mask);
                    let single = star.cycles == 1;
                    for cy in 0..star.cycles as usize {
                        let mut steps = [Step {
                            point: (0, DVec3::ZERO),
                            neighbour: 0,
                            in_edge: 0,
                            out_edge: 0,
                        }; 12];
                        let cycle = star.cycle(cy);
                        for (t, st) in cycle.iter().enumerate() {
                            steps[t] = coarse_step(ctx, &oct, mask, base, &offsets, st);
                        }
                        let lt = if single {
                            Some(&ltable.tris[mask as usize][..])
                        } else {
                            None
                        };
                        emit_cycle(ctx, part, l, &steps[..cycle.len()], &v, lt);
                    }
                }
                emit_chords(ctx, part, &oct, &v);
            }
        }
    }
}

#[inline]
fn mask_of(oct: &[LabelId; 8], l: LabelId) -> u8 {
    let mut mask = 0u8;
    for (p, &x) in oct.iter().enumerate() {
        if x == l {
            mask |= 1 << p;
        }
    }
    mask
}

#[inline]
fn coarse_step(
    ctx: &Ctx,
    oct: &[LabelId; 8],
    mask: u8,
    base: usize,
    offsets: &[usize; 8],
    st: &CycleStep,
) -> Step {
    let f = st.face as usize;
    let (lo, hi) = face_octants(f);
    let other = if mask >> lo & 1 == 1 { hi } else { lo };
    let a = face_axis(f);
    let cell = base + offsets[hi];
    let id = ctx.faces.id(a, cell);
    Step {
        point: (id as u64, ctx.faces.centre(a, cell)),
        neighbour: oct[other],
        in_edge: st.in_edge,
        out_edge: st.out_edge,
    }
}

/// Neighbourhood of a refined voxel: the 27 coarse cells around it, and the
/// fine labels of all of them in one cube of (3s)³ fine cells (filled cell
/// by cell: the fine path reads each fine label many times, and looking one
/// up through its coarse cell, a division per axis, showed in the profile).
/// One `Near` serves every refined voxel of a task ([`Near::centre_on`]).
struct Near<'a> {
    cell: [i32; 3],
    sub: [Option<&'a [LabelId]>; 27],
    label: [LabelId; 27],
    s: i32,
    /// Fine labels, x fastest: fine cell `f` at `f − (cell − 1) s`.
    cube: Vec<LabelId>,
}

impl<'a> Near<'a> {
    fn new(s: i32) -> Self {
        Near {
            cell: [0; 3],
            sub: [None; 27],
            label: [0; 27],
            s,
            cube: vec![0; (27 * s * s * s) as usize],
        }
    }

    /// Makes this the neighbourhood of refined voxel `c`.
    fn centre_on(&mut self, rv: &'a RefinedVolume, c: [i32; 3]) {
        self.cell = c;
        for i in 0..27 {
            let n = [
                c[0] + (i % 3) as i32 - 1,
                c[1] + (i / 3 % 3) as i32 - 1,
                c[2] + (i / 9) as i32 - 1,
            ];
            self.sub[i] = if rv.is_refined(n) {
                rv.subvoxels(n)
            } else {
                None
            };
            self.label[i] = rv.coarse_label(n);
        }
        let s = self.s as usize;
        let w = 3 * s;
        for slot in 0..27 {
            let (x0, y0, z0) = (slot % 3 * s, slot / 3 % 3 * s, slot / 9 * s);
            for z in 0..s {
                for y in 0..s {
                    let at = x0 + w * (y0 + y + w * (z0 + z));
                    let row = &mut self.cube[at..at + s];
                    match self.sub[slot] {
                        Some(sub) => {
                            row.copy_from_slice(&sub[s * (y + s * z)..s * (y + s * z) + s])
                        }
                        None => row.fill(self.label[slot]),
                    }
                }
            }
        }
    }

    /// Index in [`Near::cube`] of fine cell `f`.
    #[inline]
    fn cube_index(&self, f: [i32; 3]) -> usize {
        let w = 3 * self.s;
        let r = [0, 1, 2].map(|a| f[a] - (self.cell[a] - 1) * self.s);
        debug_assert!(r.iter().all(|&x| (0..w).contains(&x)));
        (r[0] + w * (r[1] + w * r[2])) as usize
    }

    /// Coarse cell of a slot.
    #[inline]
    fn cell_at(&self, slot: usize) -> [i32; 3] {
        [
            self.cell[0] + (slot % 3) as i32 - 1,
            self.cell[1] + (slot / 3 % 3) as i32 - 1,
            self.cell[2] + (slot / 9) as i32 - 1,
        ]
    }

    /// Slot of coarse cell `n` (must be within one cell of the centre).
    #[inline]
    fn slot(&self, n: [i32; 3]) -> usize {
        let d = [0, 1, 2].map(|a| (n[a] - self.cell[a] + 1) as usize);
        d[0] + 3 * (d[1] + 3 * d[2])
    }

    #[inline]
    fn refined(&self, n: [i32; 3]) -> bool {
        self.sub[self.slot(n)].is_some()
    }

    /// Label of fine cell `f` (its coarse cell within one of the centre).
    #[inline]
    fn fine_label(&self, f: [i32; 3]) -> LabelId {
        self.cube[self.cube_index(f)]
    }
}

/// Whether refined voxel `c` is the lowest refined voxel containing its local
/// lattice point `u` (so that every fine vertex is visited once).
fn owns(near: &Near, u: [i32; 3], s: i32) -> bool {
    let range = |x: i32| {
        if x == 0 {
            (-1, 0)
        } else if x == s {
            (0, 1)
        } else {
            (0, 0)
        }
    };
    let (rx, ry, rz) = (range(u[0]), range(u[1]), range(u[2]));
    for dz in rz.0..=rz.1 {
        for dy in ry.0..=ry.1 {
            for dx in rx.0..=rx.1 {
                let lower = dz < 0 || (dz == 0 && (dy < 0 || (dy == 0 && dx < 0)));
                if lower && near.refined([near.cell[0] + dx, near.cell[1] + dy, near.cell[2] + dz])
                {
                    return false;
                }
            }
        }
    }
    true
}

/// The fine path over a list of refined voxels, emitted into `part`.
pub(crate) fn refined_cells(ctx: &Ctx, part: &mut Part, cells: &[[i32; 3]]) {
    let mut secs = Sections::new(ctx.lat.s);
    let mut near = Near::new(ctx.lat.s);
    for &c in cells {
        secs.reset();
        near.centre_on(ctx.rv, c);
        refined_cell(ctx, part, &mut secs, &near, c);
    }
}

/// The boundary faces of one section (the part of a fine grid plane inside one
/// coarse cell's cross-section, s × s fine faces) cut into rectangles of faces
/// with the same ordered label pair; every fine face of a rectangle has the
/// rectangle's centre as its support point. The cut depends only on the labels
/// on both sides of the section (greedy: rows of maximal runs, grown downward
/// while the whole run repeats), so every refined voxel that touches the section
/// finds the same rectangles, and the complex stays conforming: a rectangle is a
/// polygon whose boundary carries the fine vertices of its neighbours.
pub(crate) struct Sections {
    s: i32,
    /// Per slot: the generation in which it was filled.
    stamp: Vec<u32>,
    generation: u32,
    /// Per slot and fine face (u + s v): support point reference, or 0 (no face).
    refs: Vec<u64>,
    /// Per slot and fine face: whether its rectangle is that single face.
    unit: Vec<bool>,
}

impl Sections {
    pub(crate) fn new(s: i32) -> Self {
        let slots = (3 * (s + 1) * 9) as usize;
        let n = (s * s) as usize;
        Sections {
            s,
            stamp: vec![0; slots],
            generation: 0,
            refs: vec![0; slots * n],
            unit: vec![false; slots * n],
        }
    }

    /// Forgets every section (a new refined voxel: slots are relative to it).
    fn reset(&mut self) {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.stamp.fill(0);
            self.generation = 1;
        }
    }

    /// Support point of the fine face on plane `plane` (global fine coordinate)
    /// normal to `a`, whose fine cells have in-plane coordinates `fb`, `fc`
    /// along axes `(a + 1) % 3`, `(a + 2) % 3`; and whether it is one face alone.
    fn support(
        &mut self,
        ctx: &Ctx,
        near: &Near,
        a: usize,
        plane: i32,
        fb: i32,
        fc: i32,
    ) -> (Pt, bool) {
        let s = self.s;
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        let (sb, sc) = (fb.div_euclid(s), fc.div_euclid(s));
        let off = plane - near.cell[a] * s;
        debug_assert!((0..=s).contains(&off));
        let db = sb - near.cell[b] + 1;
        let dc = sc - near.cell[c] + 1;
        debug_assert!((0..3).contains(&db) && (0..3).contains(&dc));
        let slot = (((a as i32 * (s + 1) + off) * 3 + db) * 3 + dc) as usize;
        let n = (s * s) as usize;
        if self.stamp[slot] != self.generation {
            self.stamp[slot] = self.generation;
            self.fill(ctx, near, slot * n, [a, b, c], plane, sb, sc);
        }
        let i = slot * n + ((fb - sb * s) + s * (fc - sc * s)) as usize;
        let r = self.refs[i];
        debug_assert!(r != 0, "a boundary face has a rectangle");
        let l = ctx.lat.unpack(r & !TAG_MASK);
        ((r, ctx.positions.at(l)), self.unit[i])
    }

    #[allow(clippy::too_many_arguments)]
    fn fill(
        &mut self,
        ctx: &Ctx,
        near: &Near,
        at: usize,
        axes: [usize; 3],
        plane: i32,
        sb: i32,
        sc: i32,
    ) {
        let s = self.s;
        let n = (s * s) as usize;
        let [a, b, c] = axes;
        // ordered pair per fine face (lo side, hi side), None where equal
        let mut code = [u32::MAX; 49];
        for v in 0..s {
            for u in 0..s {
                let mut f = [0i32; 3];
                f[a] = plane;
                f[b] = sb * s + u;
                f[c] = sc * s + v;
                let hi = near.fine_label(f);
                f[a] = plane - 1;
                let lo = near.fine_label(f);
                if lo != hi {
                    code[(u + s * v) as usize] = pair_code(lo, hi);
                }
            }
        }
        let refs = &mut self.refs[at..at + n];
        let unit = &mut self.unit[at..at + n];
        refs.fill(0);
        let merge = s == 5;
        let mut done = [false; 49];
        for v0 in 0..s {
            for u0 in 0..s {
                let i0 = (u0 + s * v0) as usize;
                if done[i0] || code[i0] == u32::MAX {
                    continue;
                }
                let k = code[i0];
                let mut u1 = u0;
                // 7³ (separation constraints): single fine faces only; merged
                // rectangles there gave self-intersecting extractions (the
                // heart phantom with its constraints), not understood yet
                while merge
                    && u1 + 1 < s
                    && !done[(u1 + 1 + s * v0) as usize]
                    && code[(u1 + 1 + s * v0) as usize] == k
                {
                    u1 += 1;
                }
                let mut v1 = v0;
                while merge
                    && v1 + 1 < s
                    && (u0..=u1).all(|u| {
                        let i = (u + s * (v1 + 1)) as usize;
                        !done[i] && code[i] == k
                    })
                {
                    v1 += 1;
                }
                let mut l = [0i32; 3];
                l[a] = 2 * (plane + s);
                l[b] = 2 * sb * s + u0 + u1 + 1 + 2 * s;
                l[c] = 2 * sc * s + v0 + v1 + 1 + 2 * s;
                let r = key_ref(ctx.lat.key(l));
                let single = u0 == u1 && v0 == v1;
                for v in v0..=v1 {
                    for u in u0..=u1 {
                        let i = (u + s * v) as usize;
                        done[i] = true;
                        refs[i] = r;
                        unit[i] = single;
                    }
                }
            }
        }
    }
}

fn refined_cell(ctx: &Ctx, part: &mut Part, secs: &mut Sections, near: &Near, c: [i32; 3]) {
    let s = ctx.lat.s;
    let table = StarTable::disconnect();
    let ltable = LTable::get();
    let w = (3 * s) as usize;
    let offsets = octant_offsets([1, w, w * w]);
    for lw in 0..=s {
        for lv in 0..=s {
            for lu in 0..=s {
                // octant 0 of local lattice point (lu, lv, lw) is fine cell (lu-1, lv-1, lw-1) of the voxel
                let base =
                    near.cube_index([c[0] * s + lu - 1, c[1] * s + lv - 1, c[2] * s + lw - 1]);
                let c0 = near.cube[base];
                let mut oct = [c0; 8];
                let mut uniform = true;
                for o in 1..8 {
                    oct[o] = near.cube[base + offsets[o]];
                    uniform &= oct[o] == c0;
                }
                if uniform || !owns(near, [lu, lv, lw], s) {
                    continue;
                }
                let p = [c[0] * s + lu, c[1] * s + lv, c[2] * s + lw];
                fine_vertex(ctx, part, secs, near, &oct, p, table, ltable);
            }
        }
    }
}

/// Emits the polygons and junction chords of fine grid vertex `p`.
#[allow(clippy::too_many_arguments)]
fn fine_vertex(
    ctx: &Ctx,
    part: &mut Part,
    secs: &mut Sections,
    near: &Near,
    oct: &[LabelId; 8],
    p: [i32; 3],
    table: &StarTable,
    ltable: &LTable,
) {
    let s = ctx.lat.s;
    let vert = Vertex {
        lattice: ctx.lat.of_fine_vertex(p),
        half: half_edges(near, p, s),
    };
    // slot in `near` of the coarse cell holding each octant's fine cell
    let local = [0, 1, 2].map(|ax| p[ax] - near.cell[ax] * s);
    let side = |q: i32| {
        if q < 0 {
            0
        } else if q >= s {
            2
        } else {
            1
        }
    };
    let lo_hi = local.map(|l| [side(l - 1), side(l)]);
    let slots: [usize; 8] = std::array::from_fn(|o| {
        lo_hi[0][o & 1] + 3 * (lo_hi[1][(o >> 1) & 1] + 3 * lo_hi[2][(o >> 2) & 1])
    });
    let mut seen = 0u8;
    for o in 0..8 {
        if seen >> o & 1 == 1 {
            continue;
        }
        let l = oct[o];
        let mask = mask_of(oct, l);
        seen |= mask;
        let star: &MaskStar = table.get(mask);
        for cy in 0..star.cycles as usize {
            let mut steps = [Step {
                point: (0, DVec3::ZERO),
                neighbour: 0,
                in_edge: 0,
                out_edge: 0,
            }; 12];
            let mut n = 0;
            let mut all_fine = true;
            for st in star.cycle(cy) {
                let (step, unit) = fine_step(ctx, secs, near, oct, mask, p, &slots, st);
                all_fine &= unit;
                // consecutive quarter-faces of one coarse face: one support point
                if n > 0 && steps[n - 1].point.0 == step.point.0 {
                    steps[n - 1].out_edge = step.out_edge;
                } else {
                    steps[n] = step;
                    n += 1;
                }
            }
            if n > 1 && steps[n - 1].point.0 == steps[0].point.0 {
                steps[0].in_edge = steps[n - 1].in_edge;
                n -= 1;
            }
            // only single fine faces: the cycle has the unit geometry of its mask, scaled
            let lt = (all_fine && star.cycles == 1).then(|| &ltable.tris[mask as usize][..]);
            emit_cycle(ctx, part, l, &steps[..n], &vert, lt);
        }
    }
    emit_chords(ctx, part, oct, &vert);
}

/// Half-lengths (lattice units) of the six half-edges at fine vertex `p`: an
/// unsplit coarse edge (coarse vertex, no refined cell around the edge) has s,
/// every other edge is a fine edge of half-length 1.
fn half_edges(near: &Near, p: [i32; 3], s: i32) -> [i32; 6] {
    let mut half = [1; 6];
    if p.iter().any(|&x| x.rem_euclid(s) != 0) {
        return half;
    }
    let q = p.map(|x| x / s);
    for (e, h) in half.iter_mut().enumerate() {
        let axis = e / 2;
        let along = if e & 1 == 1 { q[axis] } else { q[axis] - 1 };
        let mut any_refined = false;
        for db in -1..=0 {
            for dc in -1..=0 {
                let mut cell = q;
                cell[axis] = along;
                let (b, cax) = crate::star::other_axes(axis);
                cell[b] += db;
                cell[cax] += dc;
                any_refined |= near.refined(cell);
            }
        }
        if !any_refined {
            *h = s;
        }
    }
    half
}

/// Support point and neighbour label of quarter-face `st.face` at fine vertex
/// `p`, and whether the support point is that of the single fine face.
#[allow(clippy::too_many_arguments)]
fn fine_step(
    ctx: &Ctx,
    secs: &mut Sections,
    near: &Near,
    oct: &[LabelId; 8],
    mask: u8,
    p: [i32; 3],
    slots: &[usize; 8],
    st: &CycleStep,
) -> (Step, bool) {
    let f = st.face as usize;
    let (lo, hi) = face_octants(f);
    let other = if mask >> lo & 1 == 1 { hi } else { lo };
    let a = face_axis(f);
    let (sa, sb) = (slots[lo], slots[hi]);
    let fb = [0, 1, 2].map(|ax| p[ax] - 1 + ((hi >> ax) & 1) as i32);
    let (point, unit) = if sa != sb && near.sub[sa].is_none() && near.sub[sb].is_none() {
        let cb = near.cell_at(sb);
        let grid = ctx.rv.grid();
        let i = grid.padded_index(
            (cb[0] + 1) as usize,
            (cb[1] + 1) as usize,
            (cb[2] + 1) as usize,
        );
        ((ctx.faces.id(a, i) as u64, ctx.faces.centre(a, i)), false)
    } else {
        secs.support(ctx, near, a, fb[a], fb[(a + 1) % 3], fb[(a + 2) % 3])
    };
    (
        Step {
            point,
            neighbour: oct[other],
            in_edge: st.in_edge,
            out_edge: st.out_edge,
        },
        unit,
    )
}
