//! The `faces` surface (B-K §2.2): every boundary face of the mixed grid as
//! triangles — two per face, or a fan from the face centre when a coarse face
//! has hanging vertices where refined voxels meet its edges. Encloses exactly
//! the (sub)voxels of each label, so it cross-checks volumes and topology of
//! the VESTA surface.

use rayon::prelude::*;

use super::lattice::Lattice;
use super::vesta::{TAG_KEY, pair_code};
use super::{Chord, PackedPart, Part};
use crate::preprocess::RefinedVolume;
use crate::star::other_axes;
use crate::volume::LabelId;

/// Output parts: coarse faces by z plane, then refined voxels in order.
pub(crate) fn primal_parts(rv: &RefinedVolume, lat: Lattice) -> Vec<PackedPart> {
    let dims = rv.dims();
    let mut parts: Vec<PackedPart> = (-1..=dims.nz as i32)
        .into_par_iter()
        .map(|z| coarse_plane(rv, lat, z).pack())
        .collect();
    parts.extend(
        rv.refined_cells()
            .par_chunks(32)
            .map_init(Part::default, |part, cells| {
                for &c in cells {
                    refined_faces(rv, lat, c, part);
                }
                part.pack()
            })
            .collect::<Vec<_>>(),
    );
    parts
}

#[inline]
fn key_ref(lat: Lattice, l: [i32; 3]) -> u64 {
    TAG_KEY | lat.key(l)
}

/// Emits polygon `pts` (lattice points, counter-clockwise about +axis) of a face
/// whose − side holds `lo` and + side `hi`: normal from the smaller label to the
/// larger; a fan around `centre` when it has more than four points.
fn emit_face(
    part: &mut Part,
    lat: Lattice,
    pts: &[[i32; 3]],
    centre: [i32; 3],
    axis: usize,
    lo: LabelId,
    hi: LabelId,
) {
    let (a, b) = (lo.min(hi), lo.max(hi));
    // the point order is counter-clockwise about e_b × e_c; flip for the wanted normal
    let (pb, pc) = other_axes(axis);
    let ccw_sign = if (pb, pc) == (0, 2) { -1 } else { 1 };
    let want = if lo < hi { 1 } else { -1 };
    let flip = ccw_sign != want;
    let refs: Vec<u64> = pts.iter().map(|&p| key_ref(lat, p)).collect();
    let mut push = |t: [u64; 3]| {
        part.tris.push(if flip { [t[0], t[2], t[1]] } else { t });
        part.pairs.push(pair_code(a, b));
    };
    if refs.len() == 4 {
        push([refs[0], refs[1], refs[2]]);
        push([refs[0], refs[2], refs[3]]);
    } else {
        let c = key_ref(lat, centre);
        for i in 0..refs.len() {
            push([c, refs[i], refs[(i + 1) % refs.len()]]);
        }
    }
}

/// Coarse faces on the low sides of the cells of plane z, and coarse junction edges.
fn coarse_plane(rv: &RefinedVolume, lat: Lattice, z: i32) -> Part {
    let dims = rv.dims();
    let s = lat.s;
    let mut part = Part::default();
    let mut pts = Vec::with_capacity(4 * s as usize);
    for y in -1..=dims.ny as i32 {
        for x in -1..=dims.nx as i32 {
            let c = [x, y, z];
            if rv.is_refined(c) {
                continue;
            }
            let here = rv.coarse_label(c);
            for axis in 0..3 {
                let mut n = c;
                n[axis] -= 1;
                let there = rv.coarse_label(n);
                if there == here || rv.is_refined(n) {
                    continue;
                }
                face_outline(rv, lat, c, axis, &mut pts);
                let mut centre = lat.of_fine_vertex(c.map(|v| v * s));
                let (b, cc) = other_axes(axis);
                centre[b] += s;
                centre[cc] += s;
                emit_face(&mut part, lat, &pts, centre, axis, there, here);
            }
            coarse_junctions(rv, lat, c, &mut part);
        }
    }
    part
}

/// Boundary points (lattice coordinates) of the coarse face on the low side of
/// cell `c` along `axis`, counter-clockwise about e_b × e_c, with the hanging
/// vertices of edges that touch refined voxels.
fn face_outline(
    rv: &RefinedVolume,
    lat: Lattice,
    c: [i32; 3],
    axis: usize,
    pts: &mut Vec<[i32; 3]>,
) {
    let s = lat.s;
    let (b, cc) = other_axes(axis);
    pts.clear();
    let corner = |u: i32, v: i32| {
        let mut f = c.map(|x| x * s);
        f[b] += u;
        f[cc] += v;
        lat.of_fine_vertex(f)
    };
    // edges in order: (0,0)->(s,0) along b at c-low, (s,0)->(s,s) along c at b-high, ...
    type Side = ((i32, i32), (i32, i32), usize, i32);
    let sides: [Side; 4] = [
        ((0, 0), (1, 0), cc, 0),
        ((s, 0), (0, 1), b, 1),
        ((s, s), (-1, 0), cc, 1),
        ((0, s), (0, -1), b, 0),
    ];
    for ((u0, v0), (du, dv), across, high) in sides {
        // the edge is split when a cell around it is refined
        let mut split = false;
        for da in -1..=0 {
            for dx in -1..=0 {
                let mut n = c;
                n[axis] += da;
                n[across] += if high == 1 { dx + 1 } else { dx };
                split |= rv.is_refined(n);
            }
        }
        let steps = if split { s } else { 1 };
        let stride = s / steps;
        for k in 0..steps {
            pts.push(corner(u0 + du * k * stride, v0 + dv * k * stride));
        }
    }
}

/// Junction edges (three or more labels around) along the +axes of coarse
/// vertex `c`, when no refined voxel touches them.
fn coarse_junctions(rv: &RefinedVolume, lat: Lattice, c: [i32; 3], part: &mut Part) {
    let s = lat.s;
    for axis in 0..3 {
        let (b, cc) = other_axes(axis);
        let mut labels = [0 as LabelId; 4];
        let mut refined = false;
        for (i, (db, dc)) in [(-1, -1), (0, -1), (0, 0), (-1, 0)].into_iter().enumerate() {
            let mut n = c;
            n[b] += db;
            n[cc] += dc;
            refined |= rv.is_refined(n);
            labels[i] = rv.coarse_label(n);
        }
        if refined {
            continue;
        }
        let mut end = c;
        end[axis] += 1;
        push_chord(part, lat, c.map(|v| v * s), end.map(|v| v * s), labels);
    }
}

fn push_chord(part: &mut Part, lat: Lattice, p: [i32; 3], q: [i32; 3], mut labels: [LabelId; 4]) {
    labels.sort_unstable();
    let mut distinct = 1;
    for i in 1..4 {
        if labels[i] != labels[i - 1] {
            labels[distinct] = labels[i];
            distinct += 1;
        }
    }
    if distinct >= 3 {
        part.chords.push(Chord {
            a: key_ref(lat, lat.of_fine_vertex(p)),
            b: key_ref(lat, lat.of_fine_vertex(q)),
            labels,
            count: distinct as u8,
        });
    }
}

/// Fine faces and fine junction edges owned by refined voxel `c`.
fn refined_faces(rv: &RefinedVolume, lat: Lattice, c: [i32; 3], part: &mut Part) {
    let s = lat.s;
    let base = c.map(|v| v * s);
    let mut pts = Vec::with_capacity(4);
    for w in 0..s {
        for v in 0..s {
            for u in 0..s {
                let f = [base[0] + u, base[1] + v, base[2] + w];
                for axis in 0..3 {
                    let local = [u, v, w][axis];
                    // low side always; high side on the voxel border when the neighbour is unrefined
                    let mut sides = vec![(f, axis)];
                    if local == s - 1 {
                        let mut nc = c;
                        nc[axis] += 1;
                        if !rv.is_refined(nc) {
                            let mut g = f;
                            g[axis] += 1;
                            sides.push((g, axis));
                        }
                    }
                    for (hi_cell, a) in sides {
                        let mut lo_cell = hi_cell;
                        lo_cell[a] -= 1;
                        let (l_lo, l_hi) = (rv.fine_label(lo_cell), rv.fine_label(hi_cell));
                        if l_lo == l_hi {
                            continue;
                        }
                        let (b, cc) = other_axes(a);
                        pts.clear();
                        for (du, dv) in [(0, 0), (1, 0), (1, 1), (0, 1)] {
                            let mut p = hi_cell;
                            p[b] += du;
                            p[cc] += dv;
                            pts.push(lat.of_fine_vertex(p));
                        }
                        emit_face(part, lat, &pts, [0; 3], a, l_lo, l_hi);
                    }
                }
            }
        }
    }
    // fine junction edges in the closure of c
    for w in 0..=s {
        for v in 0..=s {
            for u in 0..=s {
                let p = [base[0] + u, base[1] + v, base[2] + w];
                for axis in 0..3 {
                    if [u, v, w][axis] == s {
                        continue;
                    }
                    let (b, cc) = other_axes(axis);
                    let mut labels = [0 as LabelId; 4];
                    for (i, (db, dc)) in
                        [(-1, -1), (0, -1), (0, 0), (-1, 0)].into_iter().enumerate()
                    {
                        let mut f = p;
                        f[b] += db;
                        f[cc] += dc;
                        labels[i] = rv.fine_label(f);
                    }
                    let mut q = p;
                    q[axis] += 1;
                    push_chord(part, lat, p, q, labels);
                }
            }
        }
    }
}
