//! `manifest.json`: what a run of the pipeline read, did and wrote, so that
//! scripts can find each patch's file and labels without parsing meshes.
//!
//! [`Manifest`] is the one manifest type: [`crate::pipeline`] fills it, the
//! output directory writer ([`crate::io::output::write_outdir`]) adds the list of
//! files and serialises it with serde (pretty JSON, written atomically).
//!
//! ```json
//! {
//!   "septa": "0.1.0",
//!   "command": ["septa", "extract", "…"],
//!   "input": {"file": "seg.nii.gz", "config": "labels.toml", "dims": [48, 48, 48], …},
//!   "space": "LPS mm (…)",
//!   "labels": [{"value": 0, "name": "background", "voxels": 1234, "volume_ml": 1.2}, …],
//!   "patches": [{"patch": 0, "label_a": 0, "label_b": 3, "name_a": "background",
//!                "name_b": "hippocampus", "file": "patches/background__hippocampus.ply",
//!                "stats": {"triangles": 812, "area_mm2": 431.5, …}}, …],
//!   "junction_curves": [{"labels": [0, 1, 2], "vertices": 40, "closed": true}, …],
//!   "remesh_kept_share": 0.001, "remesh_steps_s": {"smooth": 0.1, "setup": 0.0, "iterations": 0.4},
//!   "validation": {"passed": true, "checks": […]},
//!   "timings_s": {"read": 0.01, "preprocess": 0.02, …}, "peak_memory_mb": 420.5,
//!   "files": ["interfaces.ply", …, "manifest.json"]
//! }
//! ```
//!
//! `label_a` / `label_b` are original label values; normals point from
//! `label_a` into `label_b`.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;

use super::atomic_write;
use crate::error::{Error, Result};
use crate::mesh::quality::QualityReport;
use crate::mesh::stats::PatchStats;
use crate::mesh::validate::Check;
use crate::remesh::{RemeshParams, RemeshTimings};

/// The volume the run read.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ManifestInput {
    /// The volume's file, when it came from one.
    pub file: Option<String>,
    /// The config file, when there was one.
    pub config: Option<String>,
    pub dims: [usize; 3],
    pub spacing_mm: [f64; 3],
    pub origin_mm: [f64; 3],
    pub direction: [[f64; 3]; 3],
    /// Rows of the 3×4 index → LPS mm affine.
    pub affine_lps: [[f64; 4]; 3],
    /// Three letters (e.g. `LPS`, `RAS`): where each index axis points.
    pub orientation: String,
}

/// One separation constraint as the config gave it.
#[derive(Clone, Debug, Serialize)]
pub struct ManifestSeparation {
    pub labels: Vec<String>,
    pub by: String,
}

/// The parameters the run used.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ManifestParameters {
    /// `vesta` or `faces`.
    pub surface: String,
    /// `L` or `H`.
    pub decompose: String,
    /// Whether flat stretches of the extraction were merged into large
    /// polygons (`--merge-flat`).
    pub merge_flat: bool,
    /// Subvoxels per voxel edge used to fatten critical elements (5 or 7).
    pub subdivision: usize,
    /// The remeshing parameters, `null` when the extraction was kept as is.
    pub remesh: Option<RemeshParams>,
    /// Value of the label outside the volume.
    pub outside: i64,
    pub priority: Vec<String>,
    pub separate: Vec<ManifestSeparation>,
    /// The labels meshed when only some were chosen (`--labels`); `null`:
    /// all of them.
    pub label_selection: Option<ManifestLabelSelection>,
}

/// Which labels were meshed, and what became of the others.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ManifestLabelSelection {
    /// Values of the labels kept (the chosen ones, the outside label and
    /// the one the others were merged into).
    pub kept: Vec<i64>,
    /// Values of the labels merged into `into`.
    pub merged: Vec<i64>,
    /// The label they became.
    pub into: i64,
}

/// One label: original value, name, size.
#[derive(Clone, Debug, Serialize)]
pub struct ManifestLabel {
    pub value: i64,
    pub name: String,
    pub voxels: u64,
    pub volume_ml: f64,
}

/// What preprocessing found and did.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ManifestPreprocessing {
    pub critical_vertices: usize,
    pub critical_edges: usize,
    pub constraint_faces: usize,
    pub refined_voxels: usize,
    /// Whether no critical configuration is left after fattening.
    pub guarantee_passed: bool,
}

/// One patch: its labels (values and names), its file and statistics.
#[derive(Clone, Debug, Serialize)]
pub struct ManifestPatch {
    pub patch: u32,
    pub label_a: i64,
    pub label_b: i64,
    pub name_a: String,
    pub name_b: String,
    /// Relative path of the patch's own file (`/`-separated).
    pub file: String,
    pub stats: PatchStats,
}

/// One junction curve: the labels meeting there (values), its size.
#[derive(Clone, Debug, Serialize)]
pub struct ManifestJunction {
    pub labels: Vec<i64>,
    pub vertices: usize,
    pub closed: bool,
}

/// Size of a mesh.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct MeshSize {
    pub triangles: usize,
    pub vertices: usize,
}

/// The validator's verdict.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ManifestValidation {
    pub passed: bool,
    pub checks: Vec<Check>,
}

/// The whole manifest (see the module docs).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Manifest {
    /// Version of septa that wrote it (also marks an output directory as septa's).
    pub septa: String,
    /// The command line, when the run came from one.
    pub command: Vec<String>,
    pub input: ManifestInput,
    /// The coordinate system of every vertex.
    pub space: String,
    /// How triangles are oriented.
    pub orientation: String,
    pub parameters: ManifestParameters,
    pub labels: Vec<ManifestLabel>,
    pub preprocessing: ManifestPreprocessing,
    pub vertices: usize,
    pub triangles: usize,
    pub patches: Vec<ManifestPatch>,
    pub junction_curves: Vec<ManifestJunction>,
    /// Size of the mesh as extracted, before remeshing.
    pub extraction: MeshSize,
    /// The remeshed mesh against the extraction; `null` without remeshing.
    pub quality: Option<QualityReport>,
    /// Seconds of each step of remeshing (`smooth`, `setup`, `iterations`).
    pub remesh_steps_s: Option<RemeshTimings>,
    /// Share of the surface (by area) the remesher left as extracted.
    pub remesh_kept_share: Option<f64>,
    /// Output vertices all of whose triangles stayed as extracted.
    pub remesh_kept_vertices: Option<u64>,
    /// Part of that share in small islands, kept by design.
    pub remesh_kept_islands_share: Option<f64>,
    pub validation: ManifestValidation,
    /// Seconds of each stage.
    pub timings_s: BTreeMap<String, f64>,
    /// Peak resident memory of the process up to the end of validation, in
    /// MB (10⁶ bytes; `null` where the system does not report it).
    pub peak_memory_mb: Option<f64>,
    /// Relative paths of every file written (`/`-separated), `manifest.json` last.
    pub files: Vec<String>,
}

impl Manifest {
    /// The manifest as pretty-printed JSON text (with a final newline).
    pub fn to_json(&self) -> Result<String> {
        let mut json =
            serde_json::to_string_pretty(self).map_err(|e| Error::invalid(e.to_string()))?;
        json.push('\n');
        Ok(json)
    }

    /// The manifest as a JSON value.
    pub fn to_value(&self) -> Result<serde_json::Value> {
        serde_json::to_value(self).map_err(|e| Error::invalid(e.to_string()))
    }

    /// Writes the manifest as pretty JSON. Atomic.
    pub fn write(&self, path: &Path) -> Result<()> {
        atomic_write(path, self.to_json()?.as_bytes())
    }
}
