//! Writing an extraction to an output directory, all or nothing.
//!
//! Layout of `OUTDIR`:
//! - `interfaces.ply` — every patch over one vertex pool (binary little-endian;
//!   vertex `x, y, z` in LPS mm, or RAS mm when asked for; face `vertex_indices`, `label_a`, `label_b`,
//!   `patch`);
//! - `patches/<name_a>__<name_b>.ply` — one file per patch, with the global vertex
//!   id as vertex property `vid`, so that boundaries match across files;
//! - `interfaces.vtp` — the same as VTK XML PolyData, with cell data
//!   `label_a`, `label_b`, `patch` (VTK's PLY reader, and so ParaView, 3D
//!   Slicer and pyvista, drops PLY face properties);
//! - `junctions.ply` — junction polylines as edges with the labels meeting there;
//! - `junctions.vtp` — the same as VTK polylines, one per curve;
//! - `manifest.json` — input, parameters, labels, patches, junctions, timings
//!   and the validator's result;
//! - `preview.png` — a picture of the patches from four sides
//!   ([`crate::render`]; unless [`Formats::preview`] is off);
//! - optionally `interfaces.obj` and `labels/<name>.{stl,obj,ply,vtp}` (the
//!   closed outward surface of each label; see [`crate::io::label_files`]).
//!
//! Everything is written into a temporary directory beside `OUTDIR` and renamed
//! into place at the end, so an interrupted run leaves no half-written output.
//! An existing `OUTDIR` is replaced only when the caller allows it, and never
//! when it contains the input file.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::Space;
use crate::io::manifest::Manifest;
use crate::io::mesh_formats::{VtpEncoding, write_junctions_vtp, write_obj_in, write_vtp_in};
use crate::io::mesh_ply::{write_junctions_ply_in, write_patch_plys_in, write_ply_in};
use crate::io::temp;
use crate::mesh::InterfaceMesh;

/// Extra files besides PLY and VTP (always written). The default is what
/// `septa extract` writes without flags: the preview, no OBJ, no STL.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Formats {
    /// `interfaces.obj`: all patches, one group each.
    pub obj: bool,
    /// `labels/<name>.<ext>`: the closed outward surface of each label, in
    /// each of these formats.
    pub per_label: crate::io::label_files::LabelFormats,
    /// `preview.png`: the patches drawn from four sides ([`crate::render`]).
    pub preview: bool,
}

impl Default for Formats {
    fn default() -> Self {
        Formats {
            obj: false,
            per_label: Default::default(),
            preview: true,
        }
    }
}

/// The picture of the patches in the output directory.
pub const PREVIEW_FILE: &str = "preview.png";

/// Longest name of a label in file names (bytes): with the other label's and
/// the suffix, a patch file name stays far below the usual 255-byte limit.
const MAX_NAME: usize = 100;

/// A name safe in file names: letters, digits, `-`, `.` and single `_`s;
/// anything else becomes `_`, runs of `_` one `_` (so that `__` separates
/// the two labels of a patch name unambiguously), no `_` or `.` at either
/// end, at most [`MAX_NAME`] bytes. Not unique: see [`label_file_names`].
pub fn file_safe(name: &str) -> String {
    let mut s = String::with_capacity(name.len());
    for c in name.chars() {
        let c = if c.is_ascii_alphanumeric() || "-.".contains(c) {
            c
        } else {
            '_'
        };
        if !(c == '_' && s.ends_with('_')) {
            s.push(c);
        }
    }
    let mut s = s.trim_matches(|c| c == '_' || c == '.').to_string();
    s.truncate(MAX_NAME);
    let s = s.trim_end_matches(['_', '.']).to_string();
    if s.is_empty() { "_".to_string() } else { s }
}

/// Makes `names` unique, ignoring case (file systems that do): every name
/// that occurs more than once gets its `suffixes` entry appended (the
/// suffixes differ from one another), until none repeats; a last resort puts
/// the (unique) index in front.
fn make_unique(mut names: Vec<String>, suffixes: &[String]) -> Vec<String> {
    use std::collections::HashMap;
    for _ in 0..4 {
        let mut seen: HashMap<String, usize> = HashMap::new();
        for n in &names {
            *seen.entry(n.to_lowercase()).or_default() += 1;
        }
        let mut changed = false;
        for (n, suffix) in names.iter_mut().zip(suffixes) {
            if seen[&n.to_lowercase()] > 1 {
                n.push_str(suffix);
                changed = true;
            }
        }
        if !changed {
            return names;
        }
    }
    names
        .into_iter()
        .enumerate()
        .map(|(i, n)| format!("{i}-{n}"))
        .collect()
}

/// File names of the labels (by dense id), unique: the file-safe name, and
/// where two labels' names collide (`a/b` and `a_b`; a label named `label3`
/// and label 3 without a name; `LV` and `lv`), `-<value>` appended.
pub fn label_file_names(mesh: &InterfaceMesh) -> Vec<String> {
    let names = (0..mesh.labels.len())
        .map(|l| file_safe(&mesh.label_name(l as u16)))
        .collect();
    let values: Vec<String> = mesh
        .labels
        .iter()
        .map(|l| format!("-{}", l.value))
        .collect();
    make_unique(names, &values)
}

/// Relative paths of the patches' files, unique:
/// `patches/<name_a>__<name_b>.ply` with the names of [`label_file_names`]
/// (which hold no `__`, so no two label pairs give the same name).
pub fn patch_paths(mesh: &InterfaceMesh) -> Vec<PathBuf> {
    let labels = label_file_names(mesh);
    let names: Vec<String> = mesh
        .patches
        .iter()
        .map(|p| {
            format!(
                "{}__{}",
                labels[p.labels[0] as usize], labels[p.labels[1] as usize]
            )
        })
        .collect();
    // unique already; the suffixes only guard against what the argument missed
    let suffixes: Vec<String> = mesh
        .patches
        .iter()
        .map(|p| {
            format!(
                "-{}_{}",
                mesh.label_value(p.labels[0]),
                mesh.label_value(p.labels[1])
            )
        })
        .collect();
    make_unique(names, &suffixes)
        .into_iter()
        .map(|n| PathBuf::from("patches").join(format!("{n}.ply")))
        .collect()
}

/// Relative path of one patch's file (see [`patch_paths`]; computing all of
/// them once is cheaper when there are many).
pub fn patch_path(mesh: &InterfaceMesh, patch: usize) -> PathBuf {
    patch_paths(mesh).swap_remove(patch)
}

/// The files of the run's output directory that mark it as septa's: one of
/// them, with a `septa` version and the `files` septa wrote there, must be in
/// any directory that `--force` replaces.
const MARKERS: [&str; 2] = ["manifest.json", "summary.json"];

/// The longest file name most file systems take (bytes).
const NAME_MAX: usize = 255;

/// An output directory: checked before the work starts, written all at once
/// at the end (see the module docs).
#[derive(Clone, Debug)]
pub struct OutDir {
    path: PathBuf,
    force: bool,
    inputs: Vec<PathBuf>,
}

impl OutDir {
    /// `path`, to be replaced if it exists only with `force` (and only if
    /// septa wrote it).
    pub fn new(path: impl Into<PathBuf>, force: bool) -> Self {
        OutDir {
            path: path.into(),
            force,
            inputs: Vec::new(),
        }
    }

    /// A file the run reads: an existing OUTDIR that holds it is never
    /// replaced.
    pub fn protect(&mut self, input: impl Into<PathBuf>) {
        self.inputs.push(input.into());
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn parent(&self) -> PathBuf {
        match self.path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        }
    }

    /// Everything that can be checked before the work starts: the name, an
    /// existing directory (only replaced with `force`, only if septa wrote
    /// it, never if it holds a file the run reads), and that a directory can
    /// be created beside it (permissions, read-only file systems, names).
    pub fn check(&self) -> Result<()> {
        let name = self
            .path
            .file_name()
            .ok_or_else(|| Error::input(&self.path, "is not a directory name"))?;
        if name.len() > NAME_MAX {
            return Err(Error::input(
                &self.path,
                format!(
                    "the name is {} bytes long: file systems take at most {NAME_MAX}",
                    name.len()
                ),
            ));
        }
        if std::fs::symlink_metadata(&self.path).is_ok() {
            self.check_replaceable()?;
        }
        self.probe()
    }

    /// The rules for replacing an existing OUTDIR.
    fn check_replaceable(&self) -> Result<()> {
        let meta = std::fs::symlink_metadata(&self.path).map_err(|e| Error::io(&self.path, e))?;
        if meta.file_type().is_symlink() {
            return Err(Error::input(
                &self.path,
                "exists and is a symbolic link: give a directory septa may create, or the directory itself",
            ));
        }
        if !meta.is_dir() {
            return Err(Error::input(&self.path, "exists and is not a directory"));
        }
        if !self.force {
            return Err(Error::input(
                &self.path,
                "exists already: choose another output directory, or pass --force to replace \
                 it (only an output directory septa wrote is replaced)",
            ));
        }
        let tree = walk(&self.path)?;
        self.check_no_input_inside(&tree)?;
        check_written_by_septa(&self.path, &tree)
    }

    /// No file the run reads may be inside the directory to be replaced
    /// (by path, through symbolic links, or as a hard link).
    fn check_no_input_inside(&self, tree: &[Entry]) -> Result<()> {
        let Ok(dir) = self.path.canonicalize() else {
            return Ok(());
        };
        for input in &self.inputs {
            let inside = input.canonicalize().is_ok_and(|i| i.starts_with(&dir))
                || same_file_in(tree, input);
            if inside {
                return Err(Error::input(
                    &self.path,
                    format!(
                        "holds {}, which this run reads: refusing to replace it (choose another output directory)",
                        input.display()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Creates and removes a temporary directory where OUTDIR will be
    /// created (or in the nearest existing folder above), so that a
    /// read-only or missing destination fails now, not after the work.
    fn probe(&self) -> Result<()> {
        let parent = self.parent();
        let mut at = parent.as_path();
        while std::fs::symlink_metadata(at).is_err() {
            match at.parent() {
                Some(p) if !p.as_os_str().is_empty() => at = p,
                _ => {
                    at = Path::new(".");
                    break;
                }
            }
        }
        if !at.is_dir() {
            return Err(Error::input(
                &self.path,
                format!("cannot be created: {} is not a directory", at.display()),
            ));
        }
        let probe = temp::create_dir(at).map_err(|e| match e {
            Error::Io { source, .. } => Error::input(
                &self.path,
                format!(
                    "cannot be written: creating a directory in {} fails: {source}",
                    at.display()
                ),
            ),
            other => other,
        })?;
        probe.remove();
        Ok(())
    }

    /// Fills a temporary directory beside OUTDIR with `fill`, syncs it, and
    /// puts it in place of OUTDIR (replacing an old one only as
    /// [`OutDir::check`] allows, checked again now). On any error, or when
    /// the process is stopped by a signal, the temporary directory is
    /// removed and OUTDIR is left as it was.
    pub fn write<T>(&self, fill: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
        let parent = self.parent();
        std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        temp::sweep_stale(&parent);
        let tmp = temp::create_dir(&parent)?;
        let filled = fill(tmp.path()).and_then(|v| crate::io::sync_tree(tmp.path()).map(|()| v));
        let value = match filled {
            Ok(v) => v,
            Err(e) => {
                tmp.remove();
                return Err(e);
            }
        };
        let old = if std::fs::symlink_metadata(&self.path).is_ok() {
            if let Err(e) = self.check_replaceable() {
                tmp.remove();
                return Err(e);
            }
            Some(temp::temp_path(&parent, temp::Kind::Old))
        } else {
            None
        };
        if let Some(old) = temp::replace_with(tmp, &self.path, old.as_deref())? {
            old.remove();
        }
        crate::io::sync_dir(&parent)?;
        Ok(value)
    }
}

/// One file or directory below an output directory.
struct Entry {
    /// Relative path, `/`-separated (as in the manifest's `files`).
    rel: String,
    kind: EntryKind,
    meta: std::fs::Metadata,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum EntryKind {
    File,
    Dir,
    Other,
}

/// Everything below `dir` (symbolic links not followed).
fn walk(dir: &Path) -> Result<Vec<Entry>> {
    let mut out = Vec::new();
    let mut stack = vec![(dir.to_path_buf(), String::new())];
    while let Some((d, prefix)) = stack.pop() {
        for e in std::fs::read_dir(&d).map_err(|e| Error::io(&d, e))? {
            let e = e.map_err(|e| Error::io(&d, e))?;
            let meta =
                std::fs::symlink_metadata(e.path()).map_err(|err| Error::io(e.path(), err))?;
            let rel = format!("{prefix}{}", e.file_name().to_string_lossy());
            let kind = if meta.is_dir() {
                stack.push((e.path(), format!("{rel}/")));
                EntryKind::Dir
            } else if meta.is_file() {
                EntryKind::File
            } else {
                EntryKind::Other
            };
            out.push(Entry { rel, kind, meta });
        }
    }
    Ok(out)
}

/// Whether `input` is the same file (device and inode) as a file of `tree`.
#[cfg(unix)]
fn same_file_in(tree: &[Entry], input: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    let Ok(m) = std::fs::metadata(input) else {
        return false;
    };
    tree.iter()
        .any(|e| e.kind == EntryKind::File && e.meta.dev() == m.dev() && e.meta.ino() == m.ino())
}

#[cfg(not(unix))]
fn same_file_in(_tree: &[Entry], _input: &Path) -> bool {
    false
}

/// The `files` list of a septa marker file in `dir`, if there is one.
fn septa_files(dir: &Path) -> Option<(String, Vec<String>)> {
    /// What the check reads of a marker (the rest, which can be tens of
    /// megabytes of junction curves, is skipped as it is parsed).
    #[derive(serde::Deserialize)]
    struct Listing {
        #[allow(dead_code)]
        septa: String,
        files: Vec<String>,
    }
    MARKERS.iter().find_map(|m| {
        let file = std::fs::File::open(dir.join(m)).ok()?;
        let listing: Listing = serde_json::from_reader(std::io::BufReader::new(file)).ok()?;
        Some((m.to_string(), listing.files))
    })
}

/// Only a directory that septa wrote is replaced, and only when it holds
/// nothing else: every file in it must be listed in its marker.
fn check_written_by_septa(dir: &Path, tree: &[Entry]) -> Result<()> {
    let Some((marker, files)) = septa_files(dir) else {
        return Err(Error::input(
            dir,
            "was not written by septa (it has no manifest.json or summary.json of septa's listing \
             its files): --force replaces only septa's own output directories; choose another \
             output directory or remove it yourself",
        ));
    };
    let listed: std::collections::HashSet<&str> = files.iter().map(String::as_str).collect();
    for e in tree {
        let ours = match e.kind {
            EntryKind::Dir => true,
            EntryKind::File => e.rel == marker || listed.contains(e.rel.as_str()),
            EntryKind::Other => false,
        };
        if !ours {
            return Err(Error::input(
                dir,
                format!(
                    "holds {}, which septa did not write (it is not in {marker}): --force will not \
                     delete it; move it away or choose another output directory",
                    e.rel
                ),
            ));
        }
    }
    Ok(())
}

/// Checks that `outdir` may be written (see [`OutDir::check`]); `input` is
/// a file the run reads.
pub fn check_outdir(outdir: &Path, input: Option<&Path>, force: bool) -> Result<()> {
    let mut o = OutDir::new(outdir, force);
    if let Some(i) = input {
        o.protect(i);
    }
    o.check()
}

/// Writes all files of an extraction; `manifest` is completed with the list of
/// files (its `files`) and written last. Returns the relative paths written.
///
/// The files are in `space`: `mesh` (in LPS, as the pipeline makes it) is
/// converted, and the manifest's `space` and every file's header say which.
pub fn write_outdir(
    outdir: &OutDir,
    mesh: &InterfaceMesh,
    formats: Formats,
    space: Space,
    manifest: &mut Manifest,
) -> Result<Vec<PathBuf>> {
    // drawn in LPS whatever the files' space, so the views keep their meaning
    let lps = mesh;
    let render = || -> Result<Option<Vec<u8>>> {
        if !formats.preview {
            return Ok(None);
        }
        let opts = crate::render::PreviewOptions::default();
        Ok(Some(crate::render::render_preview(lps, &opts)?.to_png()?))
    };
    let converted;
    let mesh = if space == Space::Lps {
        mesh
    } else {
        converted = space.mesh_from_lps(mesh);
        &converted
    };
    manifest.space = space_description(space).to_string();
    outdir.write(|tmp| write_files(tmp, mesh, formats, space, render, manifest))
}

/// The manifest's `space`.
pub fn space_description(space: Space) -> &'static str {
    match space {
        Space::Lps => {
            "LPS mm (x toward patient left, y posterior, z superior; as DICOM/ITK/3D Slicer)"
        }
        Space::Ras => "RAS mm (x toward patient right, y anterior, z superior; as NIfTI/nibabel)",
    }
}

/// Fills a temporary directory beside `outdir` with `fill`, then moves it to
/// `outdir`, which must not exist (see [`OutDir::write`] to replace one).
pub fn write_dir_atomically<T>(outdir: &Path, fill: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
    OutDir::new(outdir, false).write(fill)
}

fn write_files(
    dir: &Path,
    mesh: &InterfaceMesh,
    formats: Formats,
    space: Space,
    render_preview: impl FnOnce() -> Result<Option<Vec<u8>>> + Send,
    manifest: &mut Manifest,
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir.join("patches")).map_err(|e| Error::io(dir, e))?;
    let paths = patch_paths(mesh);
    // the files (and the preview) are independent: made side by side (the
    // first error wins, in this order)
    let (preview, ((ply, patches), (vtp, junctions))) = rayon::join(render_preview, || {
        rayon::join(
            || {
                rayon::join(
                    || write_ply_in(&dir.join("interfaces.ply"), mesh, space),
                    || write_patch_plys_in(mesh, |p| dir.join(&paths[p]), space),
                )
            },
            || {
                rayon::join(
                    // VTK, ParaView, 3D Slicer and pyvista read labels from VTP only
                    || {
                        write_vtp_in(
                            &dir.join("interfaces.vtp"),
                            mesh,
                            VtpEncoding::Base64,
                            space,
                        )
                    },
                    || {
                        write_junctions_ply_in(&dir.join("junctions.ply"), mesh, space)?;
                        write_junctions_vtp(
                            &dir.join("junctions.vtp"),
                            mesh,
                            VtpEncoding::Base64,
                            space,
                        )
                    },
                )
            },
        )
    });
    ply?;
    let written = patches?;
    vtp?;
    junctions?;
    debug_assert_eq!(written, paths.len());
    let mut files = vec![PathBuf::from("interfaces.ply")];
    files.extend(paths);
    files.push("interfaces.vtp".into());
    files.push("junctions.ply".into());
    files.push("junctions.vtp".into());
    if formats.obj {
        write_obj_in(&dir.join("interfaces.obj"), mesh, space)?;
        files.push("interfaces.obj".into());
    }

    files.extend(crate::io::label_files::write_label_surfaces_in(
        dir,
        mesh,
        formats.per_label,
        space,
    )?);
    if let Some(png) = preview? {
        crate::io::atomic_write(&dir.join(PREVIEW_FILE), &png)?;
        files.push(PREVIEW_FILE.into());
    }
    files.push("manifest.json".into());
    manifest.files = files.iter().map(|f| rel_string(f)).collect();
    manifest.write(&dir.join("manifest.json"))?;
    Ok(files)
}

/// A relative path as the manifest lists it: `/`-separated on every system.
pub fn rel_string(p: &Path) -> String {
    p.components()
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}
