//! Merging the parts produced in parallel into one [`InterfaceMesh`].
//!
//! Parts come in a fixed order (coarse slabs by z, then refined voxels by z, y,
//! x), so the result does not depend on how many threads produced them. Vertex
//! ids: coarse face centres first (by rank), then lattice points (sorted by
//! key), then polygon centroids (in part order). Positions go from index space
//! to LPS millimetres here, and triangles are reversed if the affine mirrors, so
//! that normals still point from the lower label into the higher one.

use glam::DVec3;
use rayon::prelude::*;

use super::PackedPart;
use super::coarse_faces::CoarseFaces;
use super::lattice::Lattice;
use super::vesta::{TAG_CENTROID, TAG_KEY, TAG_MASK};
use super::{dissolve, planar};
use crate::mesh::{InterfaceMesh, JunctionCurve, LabelInfo, Patch};
use crate::volume::{Geometry, LabelId};

/// Builds the mesh from the parts; with `merge_flat`, flat stretches of
/// each patch are merged (see [`planar`]).
pub(crate) fn assemble(
    mut parts: Vec<PackedPart>,
    faces: Option<&CoarseFaces>,
    lat: Lattice,
    labels: Vec<LabelInfo>,
    geometry: Geometry,
    merge_flat: bool,
) -> InterfaceMesh {
    let n_face = faces.map_or(0, |f| f.count()) as usize;
    // Lattice keys referenced anywhere (each part names its own once).
    let is_key = |r: &&u64| **r & TAG_MASK == TAG_KEY;
    let n_local_keys: usize = parts
        .par_iter()
        .map(|p| p.refs.iter().filter(is_key).count())
        .sum();
    let mut keys: Vec<u64> = Vec::with_capacity(n_local_keys);
    for p in &parts {
        keys.extend(p.refs.iter().filter(is_key).map(|r| r & !TAG_MASK));
    }
    keys.par_sort_unstable();
    keys.dedup();
    let mut centroid_base = Vec::with_capacity(parts.len());
    let mut acc = n_face + keys.len();
    for p in &parts {
        centroid_base.push(acc);
        acc += p.centroids.len();
    }
    let total = acc;
    // every part's references as mesh vertex ids
    let ref_ids: Vec<Vec<u32>> = parts
        .par_iter_mut()
        .enumerate()
        .map(|(pi, p)| {
            std::mem::take(&mut p.refs)
                .into_iter()
                .map(|r| match r & TAG_MASK {
                    0 => r as u32,
                    TAG_KEY => {
                        let k = keys.binary_search(&(r & !TAG_MASK));
                        (n_face + k.expect("key collected")) as u32
                    }
                    TAG_CENTROID => (centroid_base[pi] + (r & !TAG_MASK) as usize) as u32,
                    _ => unreachable!("bad vertex tag"),
                })
                .collect()
        })
        .collect();

    // (positions are made at the end, for the vertices left after the
    // dissolution: until then each vertex is its face, key or centroid)
    let vertices = Vertices {
        face_centres: faces.map_or_else(Vec::new, |f| f.centres()),
        keys,
        centroids: {
            let mut c = Vec::with_capacity(total - centroid_base.first().copied().unwrap_or(total));
            for p in &mut parts {
                c.extend_from_slice(&std::mem::take(&mut p.centroids));
            }
            c
        },
        lat,
    };

    // Patches (distinct per part first: a part has a few pairs, the whole
    // output one per triangle).
    let mut pairs: Vec<u32> = parts
        .par_iter()
        .flat_map_iter(|p| {
            let mut own = p.pairs.clone();
            own.sort_unstable();
            own.dedup();
            own
        })
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    let patches: Vec<Patch> = pairs
        .iter()
        .map(|&c| Patch {
            labels: [(c >> 16) as LabelId, (c & 0xffff) as LabelId],
        })
        .collect();

    // every part's triangles go straight to their place in the output, and
    // the part's own copy is freed as soon as it is read
    let mirrored = geometry.is_mirroring();
    let n_tris: usize = parts.iter().map(|p| p.tris.len()).sum();
    let mut triangles = vec![[0u32; 3]; n_tris];
    let mut triangle_patch = vec![0u32; n_tris];
    let mut tri_rest = triangles.as_mut_slice();
    let mut patch_rest = triangle_patch.as_mut_slice();
    let mut slots = Vec::with_capacity(parts.len());
    for p in &parts {
        let (t, tr) = std::mem::take(&mut tri_rest).split_at_mut(p.tris.len());
        let (q, qr) = std::mem::take(&mut patch_rest).split_at_mut(p.tris.len());
        slots.push((t, q));
        tri_rest = tr;
        patch_rest = qr;
    }
    parts
        .par_iter_mut()
        .zip(&ref_ids)
        .zip(slots)
        .for_each(|((p, ids), (out_tris, out_patch))| {
            for (o, t) in out_tris.iter_mut().zip(std::mem::take(&mut p.tris)) {
                let t = t.map(|l| ids[l as usize]);
                *o = if mirrored { [t[0], t[2], t[1]] } else { t };
            }
            for (o, c) in out_patch.iter_mut().zip(std::mem::take(&mut p.pairs)) {
                *o = pairs.binary_search(&c).expect("pair collected") as u32;
            }
        });

    let mut chords = Vec::with_capacity(parts.iter().map(|p| p.chords.len()).sum());
    for (p, ids) in parts.iter_mut().zip(&ref_ids) {
        chords.extend(std::mem::take(&mut p.chords).iter().map(|c| ResolvedChord {
            a: ids[c.a as usize],
            b: ids[c.b as usize],
            labels: c.labels,
            count: c.count,
        }));
    }
    drop(parts);
    drop(ref_ids);
    // (thousands of part buffers were freed; the arrays made from here on
    // are large, mapped apart, and would not reuse them)
    crate::memory::release();

    let mut junctions = chain_junctions(total, chords);
    dissolve::dissolve_straight(&vertices, &mut triangles, &mut triangle_patch, &junctions);
    if merge_flat {
        planar::dissolve_flat(&vertices, &mut triangles, &mut triangle_patch, &junctions);
    }
    triangles.shrink_to_fit();
    triangle_patch.shrink_to_fit();
    let kept = compact_unused(total, &mut triangles, &mut junctions);
    let positions: Vec<DVec3> = kept
        .par_iter()
        .map(|&v| geometry.index_to_physical(vertices.position(v)))
        .collect();
    InterfaceMesh {
        positions,
        triangles,
        triangle_patch,
        patches,
        junctions,
        labels,
        geometry,
    }
}

/// The vertices before the dissolution, by id: coarse face centres, then
/// lattice points (by key), then polygon centroids.
struct Vertices {
    face_centres: Vec<DVec3>,
    keys: Vec<u64>,
    centroids: Vec<DVec3>,
    lat: Lattice,
}

impl Vertices {
    /// Index-space position of vertex `v`.
    fn position(&self, v: u32) -> DVec3 {
        let (v, n_face, n_key) = (v as usize, self.face_centres.len(), self.keys.len());
        if v < n_face {
            self.face_centres[v]
        } else if v < n_face + n_key {
            self.lat.key_position(self.keys[v - n_face])
        } else {
            self.centroids[v - n_face - n_key]
        }
    }
}

impl dissolve::LatticeCoords for Vertices {
    fn len(&self) -> usize {
        self.face_centres.len() + self.keys.len() + self.centroids.len()
    }
    /// Coarse face centres lie at (exact) multiples of 1 / 2s (see
    /// [`Lattice::position`]), lattice points have their keys, centroids are
    /// off the lattice.
    #[inline]
    fn at(&self, v: u32) -> Option<[i32; 3]> {
        let (v, n_face) = (v as usize, self.face_centres.len());
        if v < n_face {
            let p = (self.face_centres[v] + DVec3::splat(1.5)) * (2.0 * self.lat.s as f64);
            Some(p.round().to_array().map(|c| c as i32))
        } else {
            self.keys.get(v - n_face).map(|&k| self.lat.unpack(k))
        }
    }
}

/// A junction chord between two mesh vertices, and the labels around it.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct ResolvedChord {
    pub a: u32,
    pub b: u32,
    pub labels: [LabelId; 4],
    pub count: u8,
}

impl ResolvedChord {
    fn labels(&self) -> &[LabelId] {
        &self.labels[..self.count as usize]
    }
}

/// Chains junction chords into polylines: curves end at corners (vertices where
/// other than two chords meet, or where the set of labels changes) and the rest
/// close into loops.
pub(crate) fn chain_junctions(
    n_vertices: usize,
    mut chords: Vec<ResolvedChord>,
) -> Vec<JunctionCurve> {
    if chords.is_empty() {
        return Vec::new();
    }
    for c in &mut chords {
        (c.a, c.b) = (c.a.min(c.b), c.a.max(c.b));
        // (unused label slots must not tell equal chords apart)
        c.labels[c.count as usize..].fill(0);
    }
    chords.sort_unstable();
    chords.dedup();
    // adjacency: vertex -> chord ids (CSR)
    let mut degree = vec![0u32; n_vertices + 1];
    for c in &chords {
        degree[c.a as usize] += 1;
        degree[c.b as usize] += 1;
    }
    let mut start = vec![0usize; n_vertices + 1];
    for v in 0..n_vertices {
        start[v + 1] = start[v] + degree[v] as usize;
    }
    let mut fill = start.clone();
    let mut adj = vec![0u32; start[n_vertices]];
    for (i, c) in chords.iter().enumerate() {
        for v in [c.a, c.b] {
            adj[fill[v as usize]] = i as u32;
            fill[v as usize] += 1;
        }
    }
    let incident = |v: u32| &adj[start[v as usize]..start[v as usize + 1]];
    let is_corner = |v: u32| {
        let inc = incident(v);
        inc.len() != 2 || chords[inc[0] as usize].labels() != chords[inc[1] as usize].labels()
    };
    let mut used = vec![false; chords.len()];
    let mut curves = Vec::new();
    let walk = |from: u32, first: u32, used: &mut Vec<bool>| -> (Vec<u32>, bool) {
        let mut verts = vec![from];
        let mut v = from;
        let mut c = first;
        loop {
            used[c as usize] = true;
            let ch = &chords[c as usize];
            let next = if ch.a == v { ch.b } else { ch.a };
            verts.push(next);
            if next == from {
                // a loop back to a corner stays open, with the corner at both
                // ends, so that the corner is an end like at every other curve
                if is_corner(from) {
                    return (verts, false);
                }
                verts.pop();
                return (verts, true);
            }
            if is_corner(next) {
                return (verts, false);
            }
            let inc = incident(next);
            let n = if inc[0] == c { inc[1] } else { inc[0] };
            if used[n as usize] {
                return (verts, false);
            }
            v = next;
            c = n;
        }
    };
    let mut corners: Vec<u32> = chords
        .iter()
        .flat_map(|c| [c.a, c.b])
        .filter(|&v| is_corner(v))
        .collect();
    corners.sort_unstable();
    corners.dedup();
    for &v in &corners {
        for &c in incident(v) {
            if !used[c as usize] {
                let labels = chords[c as usize].labels().to_vec();
                let (verts, closed) = walk(v, c, &mut used);
                curves.push(JunctionCurve {
                    vertices: verts,
                    closed,
                    labels,
                });
            }
        }
    }
    for c in 0..chords.len() {
        if !used[c] {
            let labels = chords[c].labels().to_vec();
            let (verts, closed) = walk(chords[c].a, c as u32, &mut used);
            curves.push(JunctionCurve {
                vertices: verts,
                closed,
                labels,
            });
        }
    }
    curves
}

/// Renumbers the vertices that some triangle uses (those the straight-segment
/// dissolution left) in order, in the triangles and the junction curves;
/// returns the old id of each vertex kept.
fn compact_unused(
    n: usize,
    triangles: &mut [[u32; 3]],
    junctions: &mut Vec<JunctionCurve>,
) -> Vec<u32> {
    let mut used = vec![false; n];
    for t in triangles.iter() {
        for &v in t {
            used[v as usize] = true;
        }
    }
    let kept: Vec<u32> = (0..n as u32).filter(|&v| used[v as usize]).collect();
    if kept.len() == n {
        return kept;
    }
    let mut remap = vec![u32::MAX; n];
    for (new, &old) in kept.iter().enumerate() {
        remap[old as usize] = new as u32;
    }
    triangles
        .par_iter_mut()
        .for_each(|t| *t = t.map(|v| remap[v as usize]));
    for c in junctions.iter_mut() {
        c.vertices.retain(|&v| used[v as usize]);
        for v in &mut c.vertices {
            *v = remap[*v as usize];
        }
    }
    junctions.retain(|c| c.vertices.len() >= 2);
    kept
}
