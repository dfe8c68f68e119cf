//! Writing an extraction to an output directory, all or nothing.
//!
//! Layout of `OUTDIR`:
//! - `interfaces.ply` — every patch over one vertex pool (binary little-endian;
//!   vertex `x, y, z` in LPS mm; face `vertex_indices`, `label_a`, `label_b`,
//!   `patch`);
//! - `patches/<name_a>__<name_b>.ply` — one file per patch, with the global vertex
//!   id as vertex property `vid`, so that boundaries match across files;
//! - `junctions.ply` — junction polylines as edges with the labels meeting there;
//! - `manifest.json` — input, parameters, labels, patches, junctions, timings
//!   and the validator's result;
//! - optionally `interfaces.obj`, `interfaces.vtp` and `labels/<name>.stl` (the
//!   closed outward surface of each label, for printing).
//!
//! Everything is written into a temporary directory beside `OUTDIR` and renamed
//! into place at the end, so an interrupted run leaves no half-written output.
//! An existing `OUTDIR` is replaced only when the caller allows it, and never
//! when it contains the input file.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::mesh_formats::{VtpEncoding, write_obj, write_stl_label_surface, write_vtp};
use crate::io::mesh_ply::{write_junctions_ply, write_patch_ply, write_ply};
use crate::mesh::InterfaceMesh;

/// Extra file formats besides PLY.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Formats {
    pub obj: bool,
    pub vtp: bool,
    pub stl: bool,
}

/// A name safe in file names: letters, digits, `-`, `_`, `.`; others become `_`.
pub fn file_safe(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() || s.starts_with('.') {
        format!("_{s}")
    } else {
        s
    }
}

/// Relative path of a patch's file: `patches/<name_a>__<name_b>.ply`.
pub fn patch_path(mesh: &InterfaceMesh, patch: usize) -> PathBuf {
    let [a, b] = mesh.patches[patch].labels;
    PathBuf::from("patches").join(format!(
        "{}__{}.ply",
        file_safe(&mesh.label_name(a)),
        file_safe(&mesh.label_name(b))
    ))
}

/// Checks that `outdir` may be written: it must not exist (unless `force`) and
/// must not contain `input`.
pub fn check_outdir(outdir: &Path, input: Option<&Path>, force: bool) -> Result<()> {
    if outdir.exists() {
        if !outdir.is_dir() {
            return Err(Error::input(outdir, "exists and is not a directory"));
        }
        if !force {
            return Err(Error::input(
                outdir,
                "exists already: choose another output directory or pass --force to replace it",
            ));
        }
        if let Some(input) = input {
            let (o, i) = (outdir.canonicalize(), input.canonicalize());
            if let (Ok(o), Ok(i)) = (o, i) {
                if i.starts_with(&o) {
                    return Err(Error::input(
                        outdir,
                        format!(
                            "contains the input file {}: refusing to replace it",
                            input.display()
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Writes all files of an extraction; `manifest` is completed with the list of
/// files and written last. Returns the relative paths written.
pub fn write_outdir(
    outdir: &Path,
    mesh: &InterfaceMesh,
    formats: Formats,
    mut manifest: serde_json::Value,
) -> Result<Vec<PathBuf>> {
    write_dir_atomically(outdir, |tmp| write_files(tmp, mesh, formats, &mut manifest))
}

/// Fills a temporary directory beside `outdir` with `fill`, then moves it to
/// `outdir` (replacing an old one); on any error the temporary directory is
/// removed and `outdir` is left as it was.
pub fn write_dir_atomically<T>(outdir: &Path, fill: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
    let parent = match outdir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
    let name = outdir
        .file_name()
        .ok_or_else(|| Error::input(outdir, "is not a directory name"))?
        .to_string_lossy()
        .into_owned();
    let tmp = parent.join(format!(".{name}.tmp-septa-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let result = std::fs::create_dir_all(&tmp)
        .map_err(|e| Error::io(&tmp, e))
        .and_then(|_| fill(&tmp))
        .and_then(|value| {
            swap_into_place(&tmp, outdir, &parent, &name)?;
            Ok(value)
        });
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}

fn write_files(
    dir: &Path,
    mesh: &InterfaceMesh,
    formats: Formats,
    manifest: &mut serde_json::Value,
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir.join("patches")).map_err(|e| Error::io(dir, e))?;
    let mut files = vec![PathBuf::from("interfaces.ply")];
    write_ply(&dir.join("interfaces.ply"), mesh)?;
    for p in 0..mesh.patches.len() {
        let rel = patch_path(mesh, p);
        write_patch_ply(&dir.join(&rel), mesh, p as u32)?;
        files.push(rel);
    }
    write_junctions_ply(&dir.join("junctions.ply"), mesh)?;
    files.push("junctions.ply".into());
    if formats.obj {
        write_obj(&dir.join("interfaces.obj"), mesh)?;
        files.push("interfaces.obj".into());
    }
    if formats.vtp {
        write_vtp(&dir.join("interfaces.vtp"), mesh, VtpEncoding::Base64)?;
        files.push("interfaces.vtp".into());
    }
    if formats.stl {
        std::fs::create_dir_all(dir.join("labels")).map_err(|e| Error::io(dir, e))?;
        for l in mesh.labels_with_patches() {
            let rel =
                PathBuf::from("labels").join(format!("{}.stl", file_safe(&mesh.label_name(l))));
            write_stl_label_surface(&dir.join(&rel), mesh, l)?;
            files.push(rel);
        }
    }
    files.push("manifest.json".into());
    manifest["files"] = serde_json::json!(
        files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>()
    );
    let mut json =
        serde_json::to_vec_pretty(manifest).map_err(|e| Error::invalid(e.to_string()))?;
    json.push(b'\n');
    crate::io::atomic_write(&dir.join("manifest.json"), &json)?;
    Ok(files)
}

/// Moves the finished temporary directory to `outdir`, replacing an old one.
fn swap_into_place(tmp: &Path, outdir: &Path, parent: &Path, name: &str) -> Result<()> {
    if outdir.exists() {
        let old = parent.join(format!(".{name}.old-septa-{}", std::process::id()));
        std::fs::rename(outdir, &old).map_err(|e| Error::io(outdir, e))?;
        std::fs::rename(tmp, outdir).map_err(|e| Error::io(outdir, e))?;
        std::fs::remove_dir_all(&old).map_err(|e| Error::io(&old, e))?;
    } else {
        std::fs::rename(tmp, outdir).map_err(|e| Error::io(outdir, e))?;
    }
    Ok(())
}
