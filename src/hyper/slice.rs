//! Time slices: the closed surface where the hypersurface meets `t = T`.
//!
//! Every tetrahedron with vertices on both sides of `T` (below: `t < T − ε`,
//! above: the rest, ε = [`NEAR`]) is cut in a triangle (one vertex alone on
//! its side) or a quadrilateral (two and two, split along the better
//! diagonal). A cut point is named by its hypersurface edge (below end, above
//! end), so neighbouring tetrahedra share it and the slice is one closed
//! surface over one vertex pool. Where the above end lies at `T` (within ε)
//! the cut point is that vertex — the limit of slices just before `T` — and
//! pieces that shrink to fewer than three points are dropped (a vertex where
//! a component vanishes leaves nothing). That is exact at frame times (see
//! [`crate::hyper`]); elsewhere a vertex at `T` can be a saddle where two
//! sheets would touch: a merged vertex whose triangles do not form one fan is
//! *separated* — its cut points are taken [`SEPARATE`] frames earlier — and
//! the slice is cut again.
//!
//! **Orientation.** With the tetrahedron's vertices reordered below-first (a
//! permutation of parity π), the piece is listed as
//! - 1 below `[b, a1, a2, a3]`: `(b a1, b a2, b a3)`,
//! - 3 below `[b1, b2, b3, a]`: `(b1 a, b2 a, b3 a)`,
//! - 2 below `[b1, b2, a1, a2]`: `(b1 a1, b1 a2, b2 a2, b2 a1)`,
//!
//! when π is odd, reversed when π is even. Listed this way (π even) the cut
//! face is oriented as the boundary of the tetrahedron's part below `T`;
//! summed over the hypersurface that is the boundary of the part of the
//! hypersurface before `T`, which (∂∂ = 0) is the boundary of the enclosed
//! region at time `T` up to one global sign. With the tetrahedra's
//! orientation (see [`crate::hyper`]) that sign is −1, hence the reversal;
//! the tests check every slice with septa's validator (closed, oriented,
//! each component facing away from the inside).

use glam::DVec3;
use rayon::prelude::*;

use super::Hypersurface;
use crate::error::{Error, Result};
use crate::geom::predicates::is_degenerate;
use crate::iso::iso_labels;
use crate::mesh::{InterfaceMesh, Patch};

/// Hypersurface vertices closer than this (in frames) to the slice time
/// count as lying at it.
pub const NEAR: f64 = 1e-6;

/// How much earlier (in frames) the cut points around a separated vertex are
/// taken.
pub const SEPARATE: f64 = 1e-3;

/// Tetrahedra per parallel task (fixed, so the output never depends on the
/// number of threads).
const TETS_PER_TASK: usize = 1 << 14;

/// A cut point: (below vertex, above vertex), or (`u32::MAX`, vertex) for a
/// vertex lying exactly at the slice time.
type CutKey = (u32, u32);

/// The surface of a hypersurface at one time.
#[derive(Clone, Debug)]
pub struct TimeSlice {
    /// The requested time (physical units: frames × time step).
    pub time: f64,
    /// Hypersurface vertices at `time` where merging the cut points would
    /// pinch two sheets together; their cut points were kept apart, 10⁻³
    /// frames before `time` (see the module docs).
    pub separated: usize,
    /// The frame whose own time this is, if any: then the slice is that
    /// frame's VESTA surface (H decomposition).
    pub frame: Option<usize>,
    /// Labels 0 = inside, 1 = outside; one patch, normals pointing outward;
    /// positions in LPS mm.
    pub mesh: InterfaceMesh,
}

impl Hypersurface {
    /// The closed, outward-oriented surface at physical time `time`.
    pub fn slice(&self, time: f64) -> Result<TimeSlice> {
        if !time.is_finite() {
            return Err(Error::invalid(format!(
                "slice time {time} is not a finite number"
            )));
        }
        let tf = time / self.time_step;
        let k = tf.round();
        let frame = ((tf - k).abs() <= NEAR && k >= 0.0 && (k as usize) < self.frames)
            .then_some(k as usize);
        let t = match frame {
            Some(k) => k as f64,
            None => tf,
        };
        // cut with vertices at t merged; where that pinches, separate them
        let mut split: Vec<u32> = Vec::new();
        let mut mesh = self.cut(t, &split);
        for _ in 0..4 {
            let pinched = pinched_vertices(&mesh);
            if pinched.is_empty() {
                break;
            }
            split.extend(pinched);
            split.sort_unstable();
            split.dedup();
            mesh = self.cut(t, &split);
        }
        Ok(TimeSlice {
            time,
            frame,
            separated: split.len(),
            mesh: mesh.0,
        })
    }

    /// The slice at index time `t` (frames), and for every slice vertex that
    /// is a hypersurface vertex at `t` (merged cut points) the pair (slice
    /// vertex, hypersurface vertex). Vertices in `split` (sorted) are not merged.
    fn cut(&self, t: f64, split: &[u32]) -> (InterfaceMesh, Vec<(u32, u32)>) {
        let pts = &self.points;
        let tasks = self.tets.len().div_ceil(TETS_PER_TASK);
        let polys: Vec<Vec<[CutKey; 4]>> = (0..tasks)
            .into_par_iter()
            .map(|k| {
                let lo = k * TETS_PER_TASK;
                let hi = (lo + TETS_PER_TASK).min(self.tets.len());
                let mut out = Vec::new();
                for tet in &self.tets[lo..hi] {
                    if let Some(p) = cut_tet(pts, tet, t, split) {
                        out.push(p);
                    }
                }
                out
            })
            .collect();
        // one vertex per distinct cut key, in key order
        let mut keys: Vec<CutKey> = polys
            .par_iter()
            .flat_map_iter(|v| v.iter().flat_map(|p| p.iter().copied()))
            .filter(|k| k.1 != u32::MAX)
            .collect();
        keys.par_sort_unstable();
        keys.dedup();
        let positions: Vec<DVec3> = keys
            .par_iter()
            .map(|&(i, j)| {
                let b = pts[j as usize];
                let pb = DVec3::new(b[0], b[1], b[2]);
                let p = if i == u32::MAX {
                    pb
                } else {
                    let a = pts[i as usize];
                    let pa = DVec3::new(a[0], a[1], a[2]);
                    // a separated vertex at t: its cut points a little earlier
                    let at = if (b[3] - t).abs() <= NEAR {
                        b[3] - SEPARATE.min((b[3] - a[3]) / 2.0)
                    } else {
                        t
                    };
                    let f = (at - a[3]) / (b[3] - a[3]);
                    pa + (pb - pa) * f
                };
                self.geometry.index_to_physical(p)
            })
            .collect();
        let merged: Vec<(u32, u32)> = keys
            .iter()
            .enumerate()
            .filter(|(_, k)| k.0 == u32::MAX)
            .map(|(i, k)| (i as u32, k.1))
            .collect();
        let id = |k: CutKey| keys.binary_search(&k).expect("cut key listed") as u32;
        let mirrored = self.geometry.is_mirroring();
        let mut triangles = Vec::new();
        for p in polys.iter().flatten() {
            let n = if p[3].1 == u32::MAX { 3 } else { 4 };
            let v: Vec<u32> = p[..n].iter().map(|&k| id(k)).collect();
            let tris: Vec<[u32; 3]> = if n == 3 {
                vec![[v[0], v[1], v[2]]]
            } else {
                split_quad(&positions, [v[0], v[1], v[2], v[3]])
            };
            for tri in tris {
                triangles.push(if mirrored {
                    [tri[0], tri[2], tri[1]]
                } else {
                    tri
                });
            }
        }
        let patches = if triangles.is_empty() {
            Vec::new()
        } else {
            vec![Patch { labels: [0, 1] }]
        };
        let mesh = InterfaceMesh {
            positions,
            triangle_patch: vec![0; triangles.len()],
            triangles,
            patches,
            junctions: Vec::new(),
            labels: iso_labels(),
            geometry: self.geometry,
        };
        (mesh, merged)
    }
}

/// Merged vertices whose triangles do not form a single closed fan.
fn pinched_vertices(cut: &(InterfaceMesh, Vec<(u32, u32)>)) -> Vec<u32> {
    let (mesh, merged) = cut;
    if merged.is_empty() {
        return Vec::new();
    }
    let mut slot = vec![u32::MAX; mesh.positions.len()];
    for (k, &(v, _)) in merged.iter().enumerate() {
        slot[v as usize] = k as u32;
    }
    // opposite edges of each merged vertex's triangles
    let mut rims: Vec<Vec<[u32; 2]>> = vec![Vec::new(); merged.len()];
    for t in &mesh.triangles {
        for k in 0..3 {
            let s = slot[t[k] as usize];
            if s != u32::MAX {
                rims[s as usize].push([t[(k + 1) % 3], t[(k + 2) % 3]]);
            }
        }
    }
    merged
        .iter()
        .zip(&rims)
        .filter(|(_, rim)| !rim.is_empty() && !is_one_fan(rim))
        .map(|(&(_, h), _)| h)
        .collect()
}

/// Whether directed rim edges (b, c) of the triangles around a vertex chain
/// into one closed cycle.
fn is_one_fan(rim: &[[u32; 2]]) -> bool {
    let n = rim.len();
    let mut seen = vec![false; n];
    let mut at = 0;
    for _ in 0..n {
        if seen[at] {
            return false;
        }
        seen[at] = true;
        let end = rim[at][1];
        let next: Vec<usize> = (0..n).filter(|&k| rim[k][0] == end).collect();
        if next.len() != 1 {
            return false;
        }
        at = next[0];
    }
    at == 0 && seen.iter().all(|&s| s)
}

/// The oriented cut polygon of one tetrahedron at time `t` (a triangle has a
/// fourth key `(·, u32::MAX)`), or `None` if it is not cut or shrinks to
/// fewer than three points. Vertices within [`NEAR`] of `t` count as above
/// it and, unless listed in `split`, are the cut point themselves.
fn cut_tet(pts: &[[f64; 4]], tet: &[u32; 4], t: f64, split: &[u32]) -> Option<[CutKey; 4]> {
    let below = tet.map(|v| pts[v as usize][3] < t - NEAR);
    let nb = below.iter().filter(|&&b| b).count();
    if nb == 0 || nb == 4 {
        return None;
    }
    // below-first order and its parity
    let mut order = [0usize; 4];
    let mut k = 0;
    for want in [true, false] {
        for i in 0..4 {
            if below[i] == want {
                order[k] = i;
                k += 1;
            }
        }
    }
    let mut inversions = 0;
    for i in 0..4 {
        for j in i + 1..4 {
            inversions += (order[i] > order[j]) as usize;
        }
    }
    let v = order.map(|i| tet[i]);
    let cut = |b: u32, a: u32| -> CutKey {
        if (pts[a as usize][3] - t).abs() <= NEAR && split.binary_search(&a).is_err() {
            (u32::MAX, a)
        } else {
            (b, a)
        }
    };
    let mut poly: Vec<CutKey> = match nb {
        1 => vec![cut(v[0], v[1]), cut(v[0], v[2]), cut(v[0], v[3])],
        3 => vec![cut(v[0], v[3]), cut(v[1], v[3]), cut(v[2], v[3])],
        _ => vec![
            cut(v[0], v[2]),
            cut(v[0], v[3]),
            cut(v[1], v[3]),
            cut(v[1], v[2]),
        ],
    };
    // the boundary of the part below t, reversed: outward (see the module docs)
    if inversions % 2 == 0 {
        poly.reverse();
    }
    // merge points that coincide (vertices exactly at t)
    let mut merged: Vec<CutKey> = Vec::with_capacity(4);
    for k in poly {
        if merged.last() != Some(&k) {
            merged.push(k);
        }
    }
    while merged.len() > 1 && merged.first() == merged.last() {
        merged.pop();
    }
    if merged.len() < 3 || (merged.len() == 4 && (merged[0] == merged[2] || merged[1] == merged[3]))
    {
        return None;
    }
    Some(match merged.len() {
        3 => [merged[0], merged[1], merged[2], (0, u32::MAX)],
        _ => [merged[0], merged[1], merged[2], merged[3]],
    })
}

/// Splits a quadrilateral along the diagonal whose worse triangle is better
/// (the first diagonal on ties).
fn split_quad(pos: &[DVec3], q: [u32; 4]) -> Vec<[u32; 3]> {
    let p = q.map(|v| pos[v as usize]);
    let quality = |a: DVec3, b: DVec3, c: DVec3| {
        let cross = (b - a).cross(c - a).length();
        let l = (b - a)
            .length_squared()
            .max((c - a).length_squared())
            .max((c - b).length_squared());
        if l > 0.0 { cross / l } else { 0.0 }
    };
    let d02 = quality(p[0], p[1], p[2]).min(quality(p[0], p[2], p[3]));
    let d13 = quality(p[0], p[1], p[3]).min(quality(p[1], p[2], p[3]));
    let first = d02 >= d13 || is_degenerate(p[0], p[1], p[3]) || is_degenerate(p[1], p[2], p[3]);
    if first {
        vec![[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
    } else {
        vec![[q[0], q[1], q[3]], [q[1], q[2], q[3]]]
    }
}
