//! Detection of critical (non-manifold) grid elements — B-K §2.1.
//!
//! For a label `l`:
//! - a grid **edge** is critical when `l` holds exactly two diagonally opposite
//!   cells of the four around it (∂V_l has four faces at the edge);
//! - a grid **vertex** is critical when the boundary faces of `l` incident to it
//!   do not form exactly one cycle ([`crate::star`]); this covers the end vertices
//!   of critical edges and B-K's singular vertex configurations;
//! - with separation constraints, a **face** between two labels of one
//!   constraint group is critical, its dominant label being the group's separator.
//!
//! The dominant label of an edge or vertex is the critical label of smallest
//! rank (smallest value by default, or the user's priority order).
//!
//! One pass over all grid vertices, in parallel over z planes, with no
//! allocation per vertex; the result is ordered by position and does not depend
//! on the number of threads.

use rayon::prelude::*;

use crate::config::Resolved;
use crate::star::is_critical_mask;
use crate::volume::{LabelId, PaddedLabels};

/// What kind of grid element is critical.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ElementKind {
    /// A grid vertex.
    Vertex,
    /// A grid edge along `axis` from `pos` to `pos + e_axis`.
    Edge { axis: u8 },
    /// A grid face perpendicular to `axis` with its lowest corner at `pos`.
    Face { axis: u8 },
}

/// A critical element and the label its neighbourhood is given to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub struct CriticalElement {
    pub kind: ElementKind,
    /// Grid vertex coordinates (0..=n along each axis) of the element's lowest corner.
    pub pos: [i32; 3],
    /// The dominant label (dense id).
    pub dominant: LabelId,
}

/// All critical elements of a volume, with per-label statistics.
#[derive(Clone, Debug, Default)]
pub struct CriticalSet {
    /// Ordered by z plane of the lowest corner, then y, x, then kind.
    pub elements: Vec<CriticalElement>,
    /// Per dense id: number of edges critical for that label.
    pub edges_per_label: Vec<u64>,
    /// Per dense id: number of vertices critical for that label.
    pub vertices_per_label: Vec<u64>,
    /// Per dense id: number of constraint faces with that label on one side.
    pub faces_per_label: Vec<u64>,
}

impl CriticalSet {
    /// Number of elements of each kind: (vertices, edges, faces).
    pub fn counts(&self) -> (usize, usize, usize) {
        let mut c = (0, 0, 0);
        for e in &self.elements {
            match e.kind {
                ElementKind::Vertex => c.0 += 1,
                ElementKind::Edge { .. } => c.1 += 1,
                ElementKind::Face { .. } => c.2 += 1,
            }
        }
        c
    }

    /// True when nothing is critical.
    pub fn is_empty(&self) -> bool {
        self.elements.is_empty()
    }
}

/// Which pairs of labels must be separated, and by what.
#[derive(Clone, Debug)]
pub struct SeparationTable {
    n: usize,
    dense: Vec<LabelId>,
    sparse: hashbrown::HashMap<(LabelId, LabelId), LabelId>,
    any: bool,
}

/// Marker for "no constraint".
const NONE: LabelId = LabelId::MAX;

impl SeparationTable {
    /// Builds the table from resolved constraints over `n` labels.
    pub fn new(resolved: &Resolved, n: usize) -> Self {
        let use_dense = n <= 1024;
        let mut t = SeparationTable {
            n,
            dense: if use_dense {
                vec![NONE; n * n]
            } else {
                Vec::new()
            },
            sparse: hashbrown::HashMap::new(),
            any: false,
        };
        for sep in &resolved.separations {
            for (i, &a) in sep.labels.iter().enumerate() {
                for &b in &sep.labels[i + 1..] {
                    t.any = true;
                    for (p, q) in [(a, b), (b, a)] {
                        if use_dense {
                            t.dense[p as usize * n + q as usize] = sep.by;
                        } else {
                            t.sparse.insert((p, q), sep.by);
                        }
                    }
                }
            }
        }
        t
    }

    /// Whether any pair is constrained.
    #[inline]
    pub fn is_active(&self) -> bool {
        self.any
    }

    /// The separator for labels a and b, if they must not touch.
    #[inline]
    pub fn separator(&self, a: LabelId, b: LabelId) -> Option<LabelId> {
        if !self.any || a == b {
            return None;
        }
        let s = if self.dense.is_empty() {
            self.sparse.get(&(a, b)).copied().unwrap_or(NONE)
        } else {
            self.dense[a as usize * self.n + b as usize]
        };
        (s != NONE).then_some(s)
    }
}

/// Cyclic order of the four octants around the +x, +y, +z half-edges of a vertex.
const EDGE_RINGS: [[usize; 4]; 3] = [[1, 3, 7, 5], [2, 3, 7, 6], [4, 5, 7, 6]];
/// Octant pairs (lower, upper) of the faces with their lowest corner at the vertex.
const CORNER_FACES: [(usize, usize); 3] = [(6, 7), (5, 7), (3, 7)];

/// Finds all critical elements of the grid (including its boundary against the
/// outside label).
pub fn critical_elements(
    grid: &PaddedLabels,
    resolved: &Resolved,
    separation: &SeparationTable,
) -> CriticalSet {
    let dims = grid.dims();
    let n_labels = resolved.rank.len();
    let planes: Vec<PlaneResult> = (0..=dims.nz as i32)
        .into_par_iter()
        .map(|k| scan_plane(grid, k, &resolved.rank, separation, n_labels))
        .collect();
    let mut set = CriticalSet {
        elements: Vec::new(),
        edges_per_label: vec![0; n_labels],
        vertices_per_label: vec![0; n_labels],
        faces_per_label: vec![0; n_labels],
    };
    for p in planes {
        set.elements.extend(p.elements);
        for (l, c) in p.counts {
            match c {
                CountKind::Edge => set.edges_per_label[l as usize] += 1,
                CountKind::Vertex => set.vertices_per_label[l as usize] += 1,
                CountKind::Face => set.faces_per_label[l as usize] += 1,
            }
        }
    }
    set
}

#[derive(Clone, Copy)]
enum CountKind {
    Edge,
    Vertex,
    Face,
}

struct PlaneResult {
    elements: Vec<CriticalElement>,
    counts: Vec<(LabelId, CountKind)>,
}

fn scan_plane(
    grid: &PaddedLabels,
    k: i32,
    rank: &[u32],
    separation: &SeparationTable,
    _n: usize,
) -> PlaneResult {
    let data = grid.data();
    let [sx, sy, sz] = grid.strides();
    let offsets = [0, sx, sy, sx + sy, sz, sz + sx, sz + sy, sz + sy + sx];
    let mut out = PlaneResult {
        elements: Vec::new(),
        counts: Vec::new(),
    };
    // vertex (i, j, k) has padded cell (i, j, k) as its octant 0
    for (i, j, base) in grid.candidates_in_plane(k as usize) {
        let c0 = data[base];
        let mut c = [c0; 8];
        let mut uniform = true;
        for o in 1..8 {
            c[o] = data[base + offsets[o]];
            uniform &= c[o] == c0;
        }
        if uniform {
            continue;
        }
        scan_vertex(&c, [i, j, k], rank, separation, &mut out);
    }
    out
}

#[inline]
fn better(rank: &[u32], cand: LabelId, best: Option<LabelId>) -> Option<LabelId> {
    match best {
        Some(b) if rank[b as usize] <= rank[cand as usize] => Some(b),
        _ => Some(cand),
    }
}

fn scan_vertex(
    c: &[LabelId; 8],
    pos: [i32; 3],
    rank: &[u32],
    separation: &SeparationTable,
    out: &mut PlaneResult,
) {
    // Vertex: every distinct label with a non-manifold mask.
    let mut dominant = None;
    let mut seen: u8 = 0;
    for o in 0..8 {
        if seen >> o & 1 == 1 {
            continue;
        }
        let l = c[o];
        let mut mask = 0u8;
        for (p, &cp) in c.iter().enumerate() {
            if cp == l {
                mask |= 1 << p;
            }
        }
        seen |= mask;
        if is_critical_mask(mask) {
            out.counts.push((l, CountKind::Vertex));
            dominant = better(rank, l, dominant);
        }
    }
    if let Some(d) = dominant {
        out.elements.push(CriticalElement {
            kind: ElementKind::Vertex,
            pos,
            dominant: d,
        });
    }
    // Edges leaving in +x, +y, +z.
    for (axis, ring) in EDGE_RINGS.iter().enumerate() {
        let [a, b, cc, d] = ring.map(|o| c[o]);
        let mut dom = None;
        if a == cc && b != a && d != a {
            out.counts.push((a, CountKind::Edge));
            dom = better(rank, a, dom);
        }
        if b == d && a != b && cc != b {
            out.counts.push((b, CountKind::Edge));
            dom = better(rank, b, dom);
        }
        if let Some(dl) = dom {
            out.elements.push(CriticalElement {
                kind: ElementKind::Edge { axis: axis as u8 },
                pos,
                dominant: dl,
            });
        }
    }
    // Faces with their lowest corner here, between constrained labels.
    if separation.is_active() {
        for (axis, &(lo, hi)) in CORNER_FACES.iter().enumerate() {
            if let Some(by) = separation.separator(c[lo], c[hi]) {
                out.counts.push((c[lo], CountKind::Face));
                out.counts.push((c[hi], CountKind::Face));
                out.elements.push(CriticalElement {
                    kind: ElementKind::Face { axis: axis as u8 },
                    pos,
                    dominant: by,
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Dims, Geometry, LabelVolume};

    fn grid(dims: [usize; 3], values: &[i64]) -> (PaddedLabels, Resolved) {
        let v = LabelVolume::from_values(
            Dims::new(dims[0], dims[1], dims[2]).unwrap(),
            values,
            Geometry::identity(),
        )
        .unwrap();
        let r = Resolved::defaults(&v);
        (PaddedLabels::new(&v, 0), r)
    }

    #[test]
    fn diagonal_pair_gives_a_critical_edge_and_its_vertices() {
        // 2×2×1: label 1 on a diagonal, 2 on the other; outside = label 0... use values 1,2
        let (g, r) = grid([2, 2, 1], &[1, 2, 2, 1]);
        let sep = SeparationTable::new(&r, 2);
        let set = critical_elements(&g, &r, &sep);
        let edges: Vec<_> = set
            .elements
            .iter()
            .filter(|e| matches!(e.kind, ElementKind::Edge { .. }))
            .collect();
        assert_eq!(edges.len(), 1, "{:?}", set.elements);
        assert_eq!(edges[0].pos, [1, 1, 0]);
        assert_eq!(edges[0].kind, ElementKind::Edge { axis: 2 });
        assert_eq!(edges[0].dominant, 0); // label value 1 is dense id 0, smallest
        let verts: Vec<_> = set
            .elements
            .iter()
            .filter(|e| e.kind == ElementKind::Vertex)
            .collect();
        assert_eq!(verts.len(), 2);
    }

    #[test]
    fn single_voxel_and_slab_are_clean() {
        let (g, r) = grid([1, 1, 1], &[5]);
        assert!(critical_elements(&g, &r, &SeparationTable::new(&r, 1)).is_empty());
        let (g, r) = grid(
            [3, 3, 2],
            &[0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1],
        );
        assert!(critical_elements(&g, &r, &SeparationTable::new(&r, 2)).is_empty());
    }
}
