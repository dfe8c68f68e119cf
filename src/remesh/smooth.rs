//! Staircase smoothing that keeps shapes: Taubin λ/μ smoothing (non-shrinking)
//! of junction curves as 1-D polylines (corners fixed), then of patch interiors
//! (junction vertices fixed), every vertex confined to a box around its start
//! position (`max_displacement` voxels along each index axis), so that thin
//! walls and small structures cannot collapse or cross.
//!
//! Updates are Jacobi-style (new positions from old), in parallel, so the result
//! does not depend on the thread count.

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use super::network::{Network, VertexKind};
use crate::mesh::InterfaceMesh;
use crate::mesh::intersect::{intersections_of, self_intersections};

/// Taubin's pass factors: a shrinking step λ and an inflating step μ (|μ| > λ).
const LAMBDA: f64 = 0.5;
const MU: f64 = -0.53;

/// Vertex neighbours as compressed rows.
pub(crate) struct Adjacency {
    start: Vec<u32>,
    list: Vec<u32>,
}

impl Adjacency {
    /// Unique neighbours of every vertex over the triangles.
    pub(crate) fn new(n: usize, tris: &[[u32; 3]]) -> Self {
        let mut pairs: Vec<(u32, u32)> = tris
            .par_iter()
            .flat_map_iter(|t| {
                (0..3).flat_map(move |k| [(t[k], t[(k + 1) % 3]), (t[(k + 1) % 3], t[k])])
            })
            .collect();
        pairs.par_sort_unstable();
        pairs.dedup();
        let mut start = vec![0u32; n + 1];
        for &(a, _) in &pairs {
            start[a as usize + 1] += 1;
        }
        for v in 0..n {
            start[v + 1] += start[v];
        }
        Adjacency {
            start,
            list: pairs.into_iter().map(|p| p.1).collect(),
        }
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
    // 2-D: interior vertices over their one-rings
    let adj = Adjacency::new(pos.len(), &mesh.triangles);
    let interior: Vec<u32> = (0..pos.len() as u32)
        .filter(|&v| !net.on_junction(v))
        .collect();
    for _ in 0..iterations {
        for f in [LAMBDA, MU] {
            let new: Vec<DVec3> = interior
                .par_iter()
                .map(|&v| {
                    let nb = adj.of(v as usize);
                    let p = pos[v as usize];
                    if nb.is_empty() {
                        return p;
                    }
                    let c = nb.iter().map(|&w| pos[w as usize]).sum::<DVec3>() / nb.len() as f64;
                    conf.clamp(start[v as usize], p + (c - p) * f)
                })
                .collect();
            for (&v, p) in interior.iter().zip(new) {
                pos[v as usize] = p;
            }
        }
    }
    untangle(&mesh.triangles, start, &mut pos);
    pos
}

/// Rounds of [`untangle`] before the last, which restores start positions.
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
    let mut pairs = self_intersections(pos, tris);
    for round in 0..=UNTANGLE_ROUNDS {
        if pairs.is_empty() {
            break;
        }
        let mut verts: Vec<u32> = pairs
            .iter()
            .flat_map(|&(a, b)| tris[a as usize].into_iter().chain(tris[b as usize]))
            .collect();
        verts.sort_unstable();
        verts.dedup();
        let keep = if round == UNTANGLE_ROUNDS { 0.0 } else { 0.5 };
        let mut moved = vec![false; pos.len()];
        for &v in &verts {
            let v = v as usize;
            pos[v] = start[v] + (pos[v] - start[v]) * keep;
            moved[v] = true;
        }
        held += verts.len();
        // only triangles at moved vertices can have changed
        let touched: Vec<u32> = (0..tris.len() as u32)
            .filter(|&t| tris[t as usize].iter().any(|&v| moved[v as usize]))
            .collect();
        pairs = intersections_of(pos, tris, Some(&touched));
    }
    held
}
