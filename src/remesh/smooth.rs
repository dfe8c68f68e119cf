//! Staircase smoothing that keeps shapes: Taubin λ/μ smoothing (non-shrinking)
//! of junction curves as 1-D polylines (corners fixed), then of patch interiors
//! (junction vertices fixed), every vertex confined to a box around its start
//! position (`max_displacement` voxels along each index axis), so that thin
//! walls and small structures cannot collapse or cross. Closed junction loops
//! get their size back after the curve passes (a loop of a few vertices is all
//! high frequency, which Taubin shrinks: see `keep_loop_sizes`).
//!
//! Updates are Jacobi-style (new positions from old), in parallel, so the result
//! does not depend on the thread count.

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use super::network::{Network, VertexKind};
use crate::geom::intersect::{intersections_in, self_intersections_and_bvh, triangle_box};
use crate::mesh::InterfaceMesh;

/// Taubin's pass factors: a shrinking step λ and an inflating step μ (|μ| > λ).
const LAMBDA: f64 = 0.5;
const MU: f64 = -0.53;

/// Vertex neighbours as compressed rows.
pub(crate) struct Adjacency {
    start: Vec<u32>,
    list: Vec<u32>,
}

impl Adjacency {
    /// Unique neighbours of every vertex over the triangles, each row sorted.
    pub(crate) fn new(n: usize, tris: &[[u32; 3]]) -> Self {
        // rows with repeats by counting (each vertex gets both other corners
        // of each of its triangles), then every short row sorted and deduped
        let mut start = vec![0u32; n + 1];
        for t in tris {
            for &v in t {
                start[v as usize + 1] += 2;
            }
        }
        for v in 0..n {
            start[v + 1] += start[v];
        }
        let mut fill = start.clone();
        let mut list = vec![0u32; start[n] as usize];
        for t in tris {
            for k in 0..3 {
                let (v, a, b) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                let at = fill[v as usize] as usize;
                list[at] = a;
                list[at + 1] = b;
                fill[v as usize] += 2;
            }
        }
        let mut rows: Vec<&mut [u32]> = Vec::with_capacity(n);
        let mut rest = list.as_mut_slice();
        for v in 0..n {
            let (row, tail) = rest.split_at_mut((start[v + 1] - start[v]) as usize);
            rows.push(row);
            rest = tail;
        }
        let lens: Vec<u32> = rows
            .into_par_iter()
            .map(|row| {
                row.sort_unstable();
                let mut k = 0;
                for i in 0..row.len() {
                    if i == 0 || row[i] != row[k - 1] {
                        row[k] = row[i];
                        k += 1;
                    }
                }
                k as u32
            })
            .collect();
        // compact the rows
        let mut packed = 0usize;
        for v in 0..n {
            let (from, len) = (start[v] as usize, lens[v] as usize);
            list.copy_within(from..from + len, packed);
            start[v] = packed as u32;
            packed += len;
        }
        start[n] = packed as u32;
        list.truncate(packed);
        Adjacency { start, list }
    }

    #[inline]
    pub(crate) fn of(&self, v: usize) -> &[u32] {
        &self.list[self.start[v] as usize..self.start[v + 1] as usize]
    }
}

/// Keeps `p` within `d` voxels (per index axis) of `p0`.
pub(crate) struct Confinement {
    to_index: DMat3,
    to_mm: DMat3,
    d: f64,
}

impl Confinement {
    pub(crate) fn new(mesh: &InterfaceMesh, max_voxels: f64) -> Self {
        let to_mm = mesh.geometry.linear_matrix();
        Confinement {
            to_index: to_mm.inverse(),
            to_mm,
            d: max_voxels,
        }
    }

    #[inline]
    pub(crate) fn clamp(&self, p0: DVec3, p: DVec3) -> DVec3 {
        let off = self.to_index * (p - p0);
        p0 + self.to_mm * off.clamp(DVec3::splat(-self.d), DVec3::splat(self.d))
    }
}

/// Smoothed positions: `iterations` λ/μ pairs on the curves, then on the interiors.
pub fn smooth(
    mesh: &InterfaceMesh,
    net: &Network,
    iterations: u32,
    max_displacement: f64,
) -> Vec<DVec3> {
    let start = &mesh.positions;
    let conf = Confinement::new(mesh, max_displacement);
    let mut pos = start.clone();
    // 1-D: curve neighbours of curve vertices
    let mut curve_nb: Vec<[u32; 2]> = vec![[u32::MAX; 2]; pos.len()];
    for c in &net.curves {
        let n = c.vertices.len();
        for (i, &v) in c.vertices.iter().enumerate() {
            if net.kind[v as usize] == VertexKind::Corner {
                continue;
            }
            let prev = if i > 0 {
                c.vertices[i - 1]
            } else if c.closed {
                c.vertices[n - 1]
            } else {
                continue;
            };
            let next = if i + 1 < n {
                c.vertices[i + 1]
            } else if c.closed {
                c.vertices[0]
            } else {
                continue;
            };
            curve_nb[v as usize] = [prev, next];
        }
    }
    let curve_vertices: Vec<u32> = (0..pos.len() as u32)
        .filter(|&v| curve_nb[v as usize][0] != u32::MAX)
        .collect();
    for _ in 0..iterations {
        for f in [LAMBDA, MU] {
            let new: Vec<DVec3> = curve_vertices
                .par_iter()
                .map(|&v| {
                    let [a, b] = curve_nb[v as usize];
                    let p = pos[v as usize];
                    let lap = (pos[a as usize] + pos[b as usize]) * 0.5 - p;
                    conf.clamp(start[v as usize], p + lap * f)
                })
                .collect();
            for (&v, p) in curve_vertices.iter().zip(new) {
                pos[v as usize] = p;
            }
        }
    }
    keep_loop_sizes(net, start, &conf, &mut pos);
    // 2-D: interior vertices over their one-rings, into a second buffer
    // (Jacobi: new positions from old; no allocation per pass)
    let adj = Adjacency::new(pos.len(), &mesh.triangles);
    let mut next = pos.clone();
    for _ in 0..iterations {
        for f in [LAMBDA, MU] {
            next.par_chunks_mut(1 << 12)
                .enumerate()
                .for_each(|(ci, out)| {
                    let first = ci << 12;
                    for (k, q) in out.iter_mut().enumerate() {
                        let v = first + k;
                        let p = pos[v];
                        let nb = adj.of(v);
                        *q = if net.kind[v] != VertexKind::Interior || nb.is_empty() {
                            p
                        } else {
                            let c = nb.iter().map(|&w| pos[w as usize]).sum::<DVec3>()
                                / nb.len() as f64;
                            conf.clamp(start[v], p + (c - p) * f)
                        };
                    }
                });
            std::mem::swap(&mut pos, &mut next);
        }
    }
    untangle(&mesh.triangles, start, &mut pos);
    pos
}

/// Gives every closed junction loop without corners back its size: its
/// mean distance from its centroid before smoothing, about its centroid
/// after. Taubin's passes keep a curve's low frequencies, but a loop of a
/// few vertices has none: its shape is its highest mode, which each λ/μ pair
/// scales by (1 − λκ)(1 − μκ), κ = 1 − cos(2π/n), so ten pairs left the loop
/// around one voxel face (n = 4, factor 0.765 a pair) at 7 % of its size:
/// 0.07 mm edges where the target was 0.5 mm or more, slivers on every
/// triangle at it, and no coarsening possible (a loop keeps three vertices).
/// Long loops are scaled by about 1. Positions stay within their boxes.
fn keep_loop_sizes(net: &Network, start: &[DVec3], conf: &Confinement, pos: &mut [DVec3]) {
    for c in &net.curves {
        let vs = &c.vertices;
        if !c.closed
            || vs.len() < 3
            || vs
                .iter()
                .any(|&v| net.kind[v as usize] == VertexKind::Corner)
        {
            continue;
        }
        let n = vs.len() as f64;
        let centre = |q: &[DVec3]| vs.iter().map(|&v| q[v as usize]).sum::<DVec3>() / n;
        let radius = |q: &[DVec3], c: DVec3| {
            vs.iter()
                .map(|&v| (q[v as usize] - c).length())
                .sum::<f64>()
                / n
        };
        let (c0, c1) = (centre(start), centre(pos));
        let (r0, r1) = (radius(start, c0), radius(pos, c1));
        if !(r1 > 0.0 && r0.is_finite()) {
            continue;
        }
        let k = r0 / r1;
        for &v in vs {
            let p = c1 + (pos[v as usize] - c1) * k;
            pos[v as usize] = conf.clamp(start[v as usize], p);
        }
    }
}

/// Rounds of [`untangle`] that halve displacements before those that
/// restore start positions.
const UNTANGLE_ROUNDS: usize = 6;

/// Pulls the vertices of self-intersecting triangles back toward their start
/// positions (half the displacement per round; fully in the last round), so
/// the smoothed surface is as free of self-intersections as the extraction.
///
/// Where two sheets are closer than the smoothing moves them (thin walls, small
/// gaps) smoothing alone can make them cross; only the vertices involved are
/// held back, the rest keep their smoothed positions.
pub(crate) fn untangle(tris: &[[u32; 3]], start: &[DVec3], pos: &mut [DVec3]) -> usize {
    let mut held = 0;
    let (mut pairs, mut bvh) = self_intersections_and_bvh(pos, tris);
    if pairs.is_empty() {
        return 0;
    }
    // Every vertex stays on the segment from its start to its smoothed
    // position, so boxes around both triangles hold it in every round: one
    // BVH (the first one, refitted) serves all rounds.
    let boxes: Vec<(DVec3, DVec3)> = tris
        .par_iter()
        .map(|&t| {
            let (a, b) = (triangle_box(start, t), triangle_box(pos, t));
            (a.0.min(b.0), a.1.max(b.1))
        })
        .collect();
    bvh.refit(&boxes);
    let mut moved = vec![false; pos.len()];
    // after the halving rounds, restore start positions until no pair is left:
    // a pair of triangles all at their start positions is a pair of the
    // extraction, which does not intersect, so every round restores a vertex
    // more and the loop ends
    for round in 0.. {
        if pairs.is_empty() {
            break;
        }
        let mut verts: Vec<u32> = pairs
            .iter()
            .flat_map(|&(a, b)| tris[a as usize].into_iter().chain(tris[b as usize]))
            .collect();
        verts.sort_unstable();
        verts.dedup();
        let keep = if round >= UNTANGLE_ROUNDS { 0.0 } else { 0.5 };
        moved.fill(false);
        let mut changed = false;
        for &v in &verts {
            let v = v as usize;
            changed |= pos[v] != start[v];
            pos[v] = start[v] + (pos[v] - start[v]) * keep;
            moved[v] = true;
        }
        if !changed {
            // only start positions are involved: the input itself intersects
            break;
        }
        held += verts.len();
        // only triangles at moved vertices can have changed
        let touched: Vec<u32> = (0..tris.len() as u32)
            .into_par_iter()
            .filter(|&t| tris[t as usize].iter().any(|&v| moved[v as usize]))
            .collect();
        pairs = intersections_in(pos, tris, &bvh, Some(&touched));
    }
    held
}
