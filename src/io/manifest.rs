//! A JSON summary of an interface mesh and the files written for it, so that
//! scripts can find each patch's file and labels without parsing meshes.
//!
//! Layout (`serde_json`, pretty-printed, written atomically):
//!
//! ```json
//! {
//!   "septa": "0.1.0",
//!   "space": "LPS mm",
//!   "vertices": 1234, "triangles": 2460, "junction_curves": 3,
//!   "labels": [{"value": 0, "name": "background"}, …],
//!   "patches": [{"patch": 0, "label_a": 0, "label_b": 3,
//!                "name_a": "background", "name_b": "hippocampus",
//!                "triangles": 812, "area_mm2": 431.5}, …],
//!   "files": [{"kind": "ply", "path": "out/mesh.ply"}, …]
//! }
//! ```
//!
//! `label_a` / `label_b` are original label values; normals point from
//! `label_a` into `label_b`.

use std::path::Path;

use serde::Serialize;

use super::atomic_write;
use crate::error::{Error, Result};
use crate::mesh::InterfaceMesh;

/// One label: original value and name.
#[derive(Clone, Debug, Serialize)]
pub struct ManifestLabel {
    pub value: i64,
    pub name: String,
}

/// One patch: its labels (values and names), size and area.
#[derive(Clone, Debug, Serialize)]
pub struct ManifestPatch {
    pub patch: u32,
    pub label_a: i64,
    pub label_b: i64,
    pub name_a: String,
    pub name_b: String,
    pub triangles: usize,
    pub area_mm2: f64,
}

/// A file written for the mesh: what it is (`ply`, `patch-ply`, `obj`, …) and where.
#[derive(Clone, Debug, Serialize)]
pub struct ManifestFile {
    pub kind: String,
    pub path: String,
}

/// The whole summary.
#[derive(Clone, Debug, Serialize)]
pub struct Manifest {
    pub septa: String,
    pub space: String,
    pub vertices: usize,
    pub triangles: usize,
    pub junction_curves: usize,
    pub labels: Vec<ManifestLabel>,
    pub patches: Vec<ManifestPatch>,
    pub files: Vec<ManifestFile>,
}

impl Manifest {
    /// Summarises `mesh` (no files yet; add them with [`Manifest::add_file`]).
    pub fn new(mesh: &InterfaceMesh) -> Self {
        let labels = mesh.labels.iter().map(|l| ManifestLabel {
            value: l.value,
            name: l.name.clone(),
        });
        Manifest {
            septa: env!("CARGO_PKG_VERSION").to_string(),
            space: "LPS mm".to_string(),
            vertices: mesh.vertex_count(),
            triangles: mesh.triangle_count(),
            junction_curves: mesh.junctions.len(),
            labels: labels.collect(),
            patches: patches(mesh),
            files: Vec::new(),
        }
    }

    /// Records a written file.
    pub fn add_file(&mut self, kind: &str, path: &Path) {
        self.files.push(ManifestFile {
            kind: kind.to_string(),
            path: path.display().to_string(),
        });
    }

    /// Writes the manifest as pretty JSON. Atomic.
    pub fn write(&self, path: &Path) -> Result<()> {
        let mut json =
            serde_json::to_vec_pretty(self).map_err(|e| Error::invalid(e.to_string()))?;
        json.push(b'\n');
        atomic_write(path, &json)
    }
}

fn patches(mesh: &InterfaceMesh) -> Vec<ManifestPatch> {
    let mut count = vec![0usize; mesh.patches.len()];
    let mut area = vec![0.0f64; mesh.patches.len()];
    for (t, &p) in mesh.triangle_patch.iter().enumerate() {
        let (Some(c), Some(a)) = (count.get_mut(p as usize), area.get_mut(p as usize)) else {
            continue;
        };
        *c += 1;
        *a += mesh.triangle_area(t);
    }
    let patch = |(i, p): (usize, &crate::mesh::Patch)| {
        let [a, b] = p.labels;
        ManifestPatch {
            patch: i as u32,
            label_a: mesh.label_value(a),
            label_b: mesh.label_value(b),
            name_a: mesh.label_name(a),
            name_b: mesh.label_name(b),
            triangles: count[i],
            area_mm2: area[i],
        }
    };
    mesh.patches.iter().enumerate().map(patch).collect()
}
