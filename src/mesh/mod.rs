//! The output of septa: interface patches over one shared vertex pool.
//!
//! [`InterfaceMesh`] holds every patch of a volume: vertex positions (LPS mm),
//! triangles tagged with the patch they belong to, the patches (one per pair of
//! touching labels `{a, b}`, `a < b`, oriented so that normals point from `a`
//! into `b`), and the junction curves where three or more labels meet. Patches
//! share their boundary vertices exactly, so any label's closed surface is the
//! union of its patches ([`InterfaceMesh::label_surface`]).
//!
//! [`validate`] checks the invariants every output keeps.

pub mod quality;
pub mod stats;
pub mod validate;

use glam::DVec3;

use crate::volume::{Geometry, LabelId};

/// A point for messages: `(x, y, z)` with three decimals (mm: a micrometre).
pub fn fmt_point(p: DVec3) -> String {
    format!("({:.3}, {:.3}, {:.3})", p.x, p.y, p.z)
}

/// One interface patch: the triangles between labels `labels[0] < labels[1]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Patch {
    /// Dense label ids `[a, b]`, `a < b`; normals point from `a` into `b`.
    pub labels: [LabelId; 2],
}

/// A polyline along which three or more labels meet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JunctionCurve {
    /// Vertex ids along the curve.
    pub vertices: Vec<u32>,
    /// True when the curve is a closed loop (the last vertex connects to the first).
    pub closed: bool,
    /// The labels meeting along the curve (dense ids, ascending).
    pub labels: Vec<LabelId>,
}

/// A label known to the mesh: its original value and display name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LabelInfo {
    pub value: i64,
    pub name: String,
}

/// Interface patches of a label volume over one vertex pool.
#[derive(Clone, Debug, Default)]
pub struct InterfaceMesh {
    /// Vertex positions, LPS millimetres.
    pub positions: Vec<DVec3>,
    /// Triangles (vertex ids), counter-clockwise about the normal.
    pub triangles: Vec<[u32; 3]>,
    /// Patch id of each triangle.
    pub triangle_patch: Vec<u32>,
    /// Patches, sorted by label pair.
    pub patches: Vec<Patch>,
    /// Junction curves.
    pub junctions: Vec<JunctionCurve>,
    /// Dense label id → value and name.
    pub labels: Vec<LabelInfo>,
    /// Geometry of the volume the mesh came from (identity if unknown).
    pub geometry: Geometry,
}

impl InterfaceMesh {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Triangle ids of each patch.
    pub fn patch_triangles(&self) -> Vec<Vec<u32>> {
        let mut out = vec![Vec::new(); self.patches.len()];
        for (t, &p) in self.triangle_patch.iter().enumerate() {
            out[p as usize].push(t as u32);
        }
        out
    }

    /// The patch id of label pair {a, b}, if the labels touch.
    pub fn patch_of(&self, a: LabelId, b: LabelId) -> Option<u32> {
        let key = [a.min(b), a.max(b)];
        self.patches
            .binary_search_by(|p| p.labels.cmp(&key))
            .ok()
            .map(|i| i as u32)
    }

    /// The closed surface of `label`: the triangles of every patch touching it,
    /// oriented outward (away from `label`).
    pub fn label_surface(&self, label: LabelId) -> Vec<[u32; 3]> {
        let mut out = Vec::new();
        for (t, &p) in self.triangle_patch.iter().enumerate() {
            let [a, b] = self.patches[p as usize].labels;
            let tri = self.triangles[t];
            if a == label {
                out.push(tri);
            } else if b == label {
                out.push([tri[0], tri[2], tri[1]]);
            }
        }
        out
    }

    /// The closed surface of `label` as a mesh of its own: the triangles of
    /// every patch touching it over only the vertices they use, oriented
    /// outward (away from `label`). Its labels are `label` (dense id 0) and
    /// its neighbours (ids 1, 2, … in the order of this mesh's ids), one
    /// patch `{0, k}` per neighbour, so that every writer puts `label` as
    /// `label_a` and the neighbour across each triangle as `label_b` (normals
    /// from `label_a` into `label_b`, as everywhere). The junction curves on
    /// it come along. Empty when `label` has no patch.
    pub fn label_surface_mesh(&self, label: LabelId) -> InterfaceMesh {
        // neighbours in ascending id order: patch k (k ≥ 1) is {label, neighbour k}
        let mut local_label = vec![u16::MAX; self.labels.len().max(label as usize + 1)];
        local_label[label as usize] = 0;
        let mut labels = vec![LabelInfo {
            value: self.label_value(label),
            name: self.label_name(label),
        }];
        let mut patch_of = vec![u32::MAX; self.patches.len()];
        let mut patches = Vec::new();
        for (i, p) in self.patches.iter().enumerate() {
            let other = match p.labels {
                [a, b] if a == label => b,
                [a, b] if b == label => a,
                _ => continue,
            };
            local_label[other as usize] = labels.len() as LabelId;
            labels.push(LabelInfo {
                value: self.label_value(other),
                name: self.label_name(other),
            });
            patch_of[i] = patches.len() as u32;
            patches.push(Patch {
                labels: [0, local_label[other as usize]],
            });
        }
        let mut local = vec![u32::MAX; self.positions.len()];
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        let mut triangle_patch = Vec::new();
        for (t, &p) in self.triangle_patch.iter().enumerate() {
            let Some(&q) = patch_of.get(p as usize) else {
                continue;
            };
            if q == u32::MAX {
                continue;
            }
            let mut tri = self.triangles[t];
            if self.patches[p as usize].labels[1] == label {
                tri.swap(1, 2);
            }
            triangles.push(tri.map(|v| {
                let slot = &mut local[v as usize];
                if *slot == u32::MAX {
                    *slot = positions.len() as u32;
                    positions.push(self.positions[v as usize]);
                }
                *slot
            }));
            triangle_patch.push(q);
        }
        let junctions = self
            .junctions
            .iter()
            .filter(|c| c.labels.contains(&label))
            .filter(|c| c.vertices.iter().all(|&v| local[v as usize] != u32::MAX))
            .map(|c| {
                let mut ls: Vec<LabelId> = c
                    .labels
                    .iter()
                    .filter_map(|&l| local_label.get(l as usize).copied())
                    .filter(|&l| l != u16::MAX)
                    .collect();
                ls.sort_unstable();
                JunctionCurve {
                    vertices: c.vertices.iter().map(|&v| local[v as usize]).collect(),
                    closed: c.closed,
                    labels: ls,
                }
            })
            .collect();
        InterfaceMesh {
            positions,
            triangles,
            triangle_patch,
            patches,
            junctions,
            labels,
            geometry: self.geometry,
        }
    }

    /// Labels that have at least one patch.
    pub fn labels_with_patches(&self) -> Vec<LabelId> {
        let mut v: Vec<LabelId> = self.patches.iter().flat_map(|p| p.labels).collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// Display name of a dense label id.
    pub fn label_name(&self, id: LabelId) -> String {
        self.labels
            .get(id as usize)
            .map(|l| l.name.clone())
            .unwrap_or_else(|| format!("label{id}"))
    }

    /// Original value of a dense label id.
    pub fn label_value(&self, id: LabelId) -> i64 {
        self.labels
            .get(id as usize)
            .map(|l| l.value)
            .unwrap_or(id as i64)
    }

    /// Area of a triangle in mm².
    pub fn triangle_area(&self, t: usize) -> f64 {
        let [a, b, c] = self.triangles[t].map(|i| self.positions[i as usize]);
        0.5 * (b - a).cross(c - a).length()
    }

    /// Signed volume enclosed by a set of oriented triangles (mm³; positive when
    /// they enclose a region and face away from it).
    pub fn signed_volume(&self, triangles: &[[u32; 3]]) -> f64 {
        triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }
}
