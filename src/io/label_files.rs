//! Each label's closed surface in a file of its own: `labels/<name>.<ext>`
//! in any of septa's mesh formats ([`LabelFormats`]).
//!
//! A label's file holds the triangles of every patch touching it, over only
//! the vertices they use, oriented outward (normals pointing away from the
//! label): a closed, oriented 2-manifold (septa's first invariant), the file
//! to print, to fill with a volume mesher or to measure. PLY and VTP faces
//! carry `label_a` = the label and `label_b` = the label across the
//! triangle (so normals still point from `label_a` into `label_b`), and
//! `patch`, the index of that neighbour among the file's patches; OBJ has one
//! group per neighbour (`<name>__<neighbour>`); STL only the triangles. The
//! headers (`comment label` lines, XML and OBJ comments) name the label and
//! its neighbours. File names are the labels' names made safe for file
//! systems ([`crate::output::label_file_names`]: `label<value>` for a label
//! without a name, unique ignoring case).

use std::path::{Path, PathBuf};

use super::Space;
use super::mesh_formats::{VtpEncoding, write_obj_in, write_stl_label_surface_in, write_vtp_in};
use super::mesh_ply::write_label_surface_ply_in;
use crate::error::{Error, Result};
use crate::mesh::InterfaceMesh;
use crate::volume::LabelId;

/// The formats of the per-label files (any number of them).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LabelFormats {
    pub stl: bool,
    pub obj: bool,
    pub ply: bool,
    pub vtp: bool,
}

impl LabelFormats {
    /// Whether any per-label file is to be written.
    pub fn any(self) -> bool {
        self.stl || self.obj || self.ply || self.vtp
    }

    /// The extensions chosen, in the order the files are written.
    pub fn extensions(self) -> Vec<&'static str> {
        [
            (self.ply, "ply"),
            (self.vtp, "vtp"),
            (self.obj, "obj"),
            (self.stl, "stl"),
        ]
        .into_iter()
        .filter_map(|(on, ext)| on.then_some(ext))
        .collect()
    }

    /// From names (`stl`, `obj`, `ply`, `vtp`; any case); an error naming
    /// the unknown one.
    pub fn parse<'a>(names: impl IntoIterator<Item = &'a str>) -> Result<LabelFormats> {
        let mut f = LabelFormats::default();
        for n in names {
            match n.trim().to_ascii_lowercase().as_str() {
                "stl" => f.stl = true,
                "obj" => f.obj = true,
                "ply" => f.ply = true,
                "vtp" => f.vtp = true,
                other => {
                    return Err(Error::invalid(format!(
                        "unknown per-label format `{other}` (stl, obj, ply, vtp)"
                    )));
                }
            }
        }
        Ok(f)
    }
}

/// Writes `labels/<name>.<ext>` below `dir` for every label with a patch and
/// every format chosen; the relative paths written, label by label.
pub fn write_label_surfaces_in(
    dir: &Path,
    mesh: &InterfaceMesh,
    formats: LabelFormats,
    space: Space,
) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    if !formats.any() {
        return Ok(files);
    }
    std::fs::create_dir_all(dir.join("labels")).map_err(|e| Error::io(dir, e))?;
    let names = crate::output::label_file_names(mesh);
    for l in mesh.labels_with_patches() {
        let surface = mesh.label_surface_mesh(l);
        for ext in formats.extensions() {
            let rel = PathBuf::from("labels").join(format!("{}.{ext}", names[l as usize]));
            write_one(&dir.join(&rel), &surface, ext, space)?;
            files.push(rel);
        }
    }
    Ok(files)
}

/// Writes one label's surface mesh (label 0 of `surface`) as `ext`.
fn write_one(path: &Path, surface: &InterfaceMesh, ext: &str, space: Space) -> Result<()> {
    match ext {
        "ply" => write_label_surface_ply_in(path, surface, space),
        "vtp" => write_vtp_in(path, surface, VtpEncoding::Base64, space),
        "obj" => write_obj_in(path, surface, space),
        _ => write_stl_label_surface_in(path, surface, 0 as LabelId, space),
    }
}
