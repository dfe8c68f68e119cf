//! PLY files of interface meshes: the whole mesh, one file per patch, the
//! junction curves, and a reader that turns any triangle or polygon PLY back
//! into an [`InterfaceMesh`].
//!
//! Everything goes through `ply-rs-bw` (header and body), with small element
//! structs implementing its `PropertyAccess` trait instead of its generic
//! property maps; this writes 2M triangles in about a quarter of a second.
//!
//! # Files written
//!
//! All files are `binary_little_endian 1.0` but the junction file (`ascii
//! 1.0`, which trimesh reads edge lists from), written atomically. Vertex ids in
//! lists are `int`, label values are the original label **values** of the volume
//! (not septa's dense ids). The header of the whole mesh ([`write_ply`]) is:
//!
//! ```text
//! ply
//! format binary_little_endian 1.0
//! comment septa 0.1.0
//! comment space LPS mm SPACE=LPS  (RAS when written in RAS; SPACE= as 3D Slicer reads it)
//! comment label 0 background        (one line per label: value, then name)
//! comment label 3 left hippocampus
//! element vertex 1234
//! property float x
//! property float y
//! property float z
//! element face 2460
//! property list uchar int vertex_indices
//! property int label_a
//! property int label_b
//! property uint patch
//! end_header
//! ```
//!
//! Each face is a triangle of patch `patch` (index into the patches sorted by
//! label pair) between labels `label_a < label_b`; its vertices are
//! counter-clockwise seen from `label_b`, i.e. the normal points from `label_a`
//! into `label_b`.
//!
//! Coordinates are `float`: at ±500 mm a float's spacing is 2⁻¹⁵ mm ≈ 0.00003 mm,
//! so rounding moves a vertex by at most 0.000015 mm, three hundred times less than
//! a 0.01 mm feature; `double` would double the vertex data for nothing.
//!
//! **Per-patch files** ([`write_patch_ply`], [`write_patch_plys`]) hold one
//! patch's triangles over only the vertices they use, with one more vertex
//! property, `property uint vid`: the vertex's id in the whole mesh, so the
//! shared boundaries of patches in different files can be matched. Their
//! `comment label` lines are the patch's two labels only (with thousands of
//! labels, listing all of them in every file made the headers larger than the
//! meshes), and they add a `comment patch <id> <value_a> <value_b>` line; faces
//! have the same four properties. The junction file lists the labels that
//! meet along its curves.
//!
//! **Junction files** ([`write_junctions_ply`]) hold the vertices of the junction
//! curves (`float x, y, z`, `uint vid`) and an edge element:
//!
//! ```text
//! element edge 17
//! property int vertex1
//! property int vertex2
//! property uint curve
//! property list uchar int labels
//! ```
//!
//! one edge per curve segment (closed curves include the closing edge), with the
//! curve index and the values of the labels meeting along it.
//!
//! # Reading
//!
//! [`read_ply`] reads any PLY: ascii or binary of either byte order, `float` or
//! `double` coordinates, any integer index type, faces named `vertex_indices` or
//! `vertex_index`. Polygons are fan-triangulated; faces with fewer than three
//! vertices are skipped (with a note). When faces carry `label_a` / `label_b`
//! (any numeric type holding whole numbers) the patches are rebuilt from them;
//! a face with `label_a > label_b` has its pair swapped **and its vertex order
//! reversed**, so that its normal still points from the smaller label value into
//! the larger. Without those properties every face goes into one patch between
//! `inside` (value 0) and `outside` (value 1), keeping its orientation, and the
//! returned notes say so. Names come from `comment label <value> <name>` lines.
//! A `vid` vertex property is returned as [`PlyMesh::vertex_ids`].

use std::collections::{BTreeMap, BTreeSet};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use glam::DVec3;
use ply_rs_bw::parser::{ParseError, Parser, Reader};
use ply_rs_bw::ply::{
    Addable, BeginList, ElementDef, Encoding, Header, PropertyAccess, PropertyAccessResult,
    PropertyDef, PropertyType, ScalarType,
};
use ply_rs_bw::writer::Writer;

use super::{Space, atomic_write_with, read_file};
use crate::error::{Error, Result};
use crate::mesh::{InterfaceMesh, LabelInfo, Patch};
use crate::volume::{LabelId, MAX_LABELS};

/// The `comment septa <version>` line's version.
const VERSION: &str = env!("CARGO_PKG_VERSION");

// ───────────────────────────── checks shared by writers ─────────────────────────────

/// Checks that `mesh` can be written: consistent arrays, finite positions that
/// fit `f32`, vertex ids that fit `int`, label values that fit `int`. Shared by
/// every mesh writer.
pub(crate) fn check_writable(mesh: &InterfaceMesh) -> Result<()> {
    let n = mesh.vertex_count();
    if n > i32::MAX as usize {
        return Err(Error::invalid(format!(
            "{n} vertices: too many for a mesh file"
        )));
    }
    if mesh.triangle_patch.len() != mesh.triangles.len() {
        return Err(Error::invalid(
            "mesh has a patch id count different from its triangle count",
        ));
    }
    if let Some(i) = mesh.positions.iter().position(|p| !fits_f32(*p)) {
        return Err(Error::invalid(format!(
            "vertex {i} is at {}: not a finite position that fits a float",
            crate::mesh::fmt_point(mesh.positions[i])
        )));
    }
    if let Some(t) = mesh
        .triangles
        .iter()
        .position(|t| t.iter().any(|&v| v as usize >= n))
    {
        return Err(Error::invalid(format!(
            "triangle {t} refers to a vertex beyond the {n} vertices"
        )));
    }
    if let Some(t) = mesh
        .triangle_patch
        .iter()
        .position(|&p| p as usize >= mesh.patches.len())
    {
        return Err(Error::invalid(format!(
            "triangle {t} belongs to a patch that does not exist"
        )));
    }
    patch_values(mesh).map(|_| ())
}

fn fits_f32(p: DVec3) -> bool {
    p.to_array().iter().all(|c| (*c as f32).is_finite())
}

/// Original label values `[value_a, value_b]` of every patch, as PLY `int`s.
pub(crate) fn patch_values(mesh: &InterfaceMesh) -> Result<Vec<[i32; 2]>> {
    mesh.patches
        .iter()
        .map(|p| Ok([value_i32(mesh, p.labels[0])?, value_i32(mesh, p.labels[1])?]))
        .collect()
}

fn value_i32(mesh: &InterfaceMesh, id: LabelId) -> Result<i32> {
    let v = mesh.label_value(id);
    i32::try_from(v).map_err(|_| {
        Error::invalid(format!(
            "label value {v} does not fit a 32-bit int property"
        ))
    })
}

/// A label name made safe for one header line.
pub(crate) fn one_line(name: &str) -> String {
    name.chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect::<String>()
        .trim()
        .to_string()
}

// ───────────────────────────── element structs for writing ─────────────────────────────

#[derive(Default)]
struct VertexOut {
    p: [f32; 3],
    vid: u32,
}

impl VertexOut {
    fn new_at(mesh: &InterfaceMesh, vid: u32) -> Self {
        let p = mesh.positions[vid as usize];
        VertexOut {
            p: [p.x as f32, p.y as f32, p.z as f32],
            vid,
        }
    }
}

impl PropertyAccess for VertexOut {
    fn new() -> Self {
        Self::default()
    }
    fn get_float(&self, name: &str) -> Option<f32> {
        match name {
            "x" => Some(self.p[0]),
            "y" => Some(self.p[1]),
            "z" => Some(self.p[2]),
            _ => None,
        }
    }
    fn get_uint(&self, name: &str) -> Option<u32> {
        (name == "vid").then_some(self.vid)
    }
}

#[derive(Default)]
struct FaceOut {
    v: [i32; 3],
    labels: [i32; 2],
    patch: u32,
}

impl PropertyAccess for FaceOut {
    fn new() -> Self {
        Self::default()
    }
    fn get_list_int(&self, name: &str) -> Option<&[i32]> {
        (name == "vertex_indices").then_some(&self.v[..])
    }
    fn get_int(&self, name: &str) -> Option<i32> {
        match name {
            "label_a" => Some(self.labels[0]),
            "label_b" => Some(self.labels[1]),
            _ => None,
        }
    }
    fn get_uint(&self, name: &str) -> Option<u32> {
        (name == "patch").then_some(self.patch)
    }
}

#[derive(Default)]
struct EdgeOut<'a> {
    v: [i32; 2],
    curve: u32,
    labels: &'a [i32],
}

impl PropertyAccess for EdgeOut<'_> {
    fn new() -> Self {
        Self::default()
    }
    fn get_int(&self, name: &str) -> Option<i32> {
        match name {
            "vertex1" => Some(self.v[0]),
            "vertex2" => Some(self.v[1]),
            _ => None,
        }
    }
    fn get_uint(&self, name: &str) -> Option<u32> {
        (name == "curve").then_some(self.curve)
    }
    fn get_list_int(&self, name: &str) -> Option<&[i32]> {
        (name == "labels").then_some(self.labels)
    }
}

// ───────────────────────────── headers ─────────────────────────────

fn scalar(t: ScalarType) -> PropertyType {
    PropertyType::Scalar(t)
}

fn element(name: &str, count: usize, props: &[(&str, PropertyType)]) -> ElementDef {
    let mut e = ElementDef::new(name.to_string());
    e.count = count;
    for (p, t) in props {
        e.properties.add(PropertyDef::new(p.to_string(), t.clone()));
    }
    e
}

fn vertex_element(count: usize, with_vid: bool) -> ElementDef {
    let mut props = vec![
        ("x", scalar(ScalarType::Float)),
        ("y", scalar(ScalarType::Float)),
        ("z", scalar(ScalarType::Float)),
    ];
    if with_vid {
        props.push(("vid", scalar(ScalarType::UInt)));
    }
    element("vertex", count, &props)
}

fn face_element(count: usize) -> ElementDef {
    element(
        "face",
        count,
        &[
            (
                "vertex_indices",
                PropertyType::List(ScalarType::UChar, ScalarType::Int),
            ),
            ("label_a", scalar(ScalarType::Int)),
            ("label_b", scalar(ScalarType::Int)),
            ("patch", scalar(ScalarType::UInt)),
        ],
    )
}

fn edge_element(count: usize) -> ElementDef {
    element(
        "edge",
        count,
        &[
            ("vertex1", scalar(ScalarType::Int)),
            ("vertex2", scalar(ScalarType::Int)),
            ("curve", scalar(ScalarType::UInt)),
            (
                "labels",
                PropertyType::List(ScalarType::UChar, ScalarType::Int),
            ),
        ],
    )
}

/// A binary little-endian header with septa's comments, a `comment label`
/// line for each of `labels` (the labels the file holds: a patch file lists
/// its two, not all of the volume's), and the given elements.
fn header(
    mesh: &InterfaceMesh,
    labels: impl IntoIterator<Item = LabelId>,
    extra_comments: &[String],
    elements: Vec<ElementDef>,
    space: Space,
) -> Header {
    let mut h = Header::new();
    h.encoding = Encoding::BinaryLittleEndian;
    h.comments.push(format!("septa {VERSION}"));
    h.comments.push(format!("space {}", space.comment()));
    for id in labels {
        let Some(l) = mesh.labels.get(id as usize) else {
            continue;
        };
        h.comments.push(
            format!("label {} {}", l.value, one_line(&l.name))
                .trim_end()
                .to_string(),
        );
    }
    h.comments.extend_from_slice(extra_comments);
    for e in elements {
        h.elements.add(e);
    }
    h
}

// ───────────────────────────── writers ─────────────────────────────

/// Writes elements one by one through ply-rs-bw's binary element writer, into
/// a local buffer handed to `w` a megabyte at a time: the element writer makes
/// one small write per property, and through `dyn Write` those cost more than
/// the encoding itself.
fn write_items<E: PropertyAccess>(
    w: &mut dyn Write,
    def: &ElementDef,
    items: impl Iterator<Item = E>,
) -> io::Result<()> {
    const CHUNK: usize = 1 << 20;
    let writer = Writer::<E>::new();
    let mut buf = Vec::with_capacity(CHUNK + 256);
    for item in items {
        writer.write_little_endian_element(&mut buf, &item, def)?;
        if buf.len() >= CHUNK {
            w.write_all(&buf)?;
            buf.clear();
        }
    }
    w.write_all(&buf)
}

/// Like [`write_items`], as ascii lines (for the small junction files).
fn write_items_ascii<E: PropertyAccess>(
    w: &mut dyn Write,
    def: &ElementDef,
    items: impl Iterator<Item = E>,
) -> io::Result<()> {
    let writer = Writer::<E>::new();
    let mut buf = Vec::new();
    for item in items {
        writer.write_ascii_element(&mut buf, &item, def)?;
    }
    w.write_all(&buf)
}

fn write_header_to(mut w: &mut dyn Write, h: &Header) -> io::Result<()> {
    Writer::<VertexOut>::new()
        .write_header(&mut w, h)
        .map(|_| ())
}

/// Writes the whole mesh as one binary PLY (layout in the module docs). Atomic.
pub fn write_ply(path: &Path, mesh: &InterfaceMesh) -> Result<()> {
    write_ply_in(path, mesh, Space::Lps)
}

/// [`write_ply`] of a mesh whose positions are in `space` (the header says so).
pub fn write_ply_in(path: &Path, mesh: &InterfaceMesh, space: Space) -> Result<()> {
    write_ply_with(path, mesh, space, &[])
}

/// The comment that marks a file as one label's closed surface (see
/// [`write_label_surface_ply_in`]), before the label's value.
const SURFACE_OF: &str = "surface of label ";

/// Like [`write_ply_in`] for one label's closed surface (label 0 of
/// `surface`, as [`InterfaceMesh::label_surface_mesh`] gives it), with a
/// `comment surface of label <value>` line: [`read_ply`] reports it in
/// [`PlyMesh::surface_of`], so that `septa check` checks the file as that
/// label's surface (its neighbours' surfaces are open there by design).
pub fn write_label_surface_ply_in(
    path: &Path,
    surface: &InterfaceMesh,
    space: Space,
) -> Result<()> {
    let Some(label) = surface.labels.first() else {
        return Err(Error::invalid("a label surface needs its label"));
    };
    write_ply_with(
        path,
        surface,
        space,
        &[format!("{SURFACE_OF}{}", label.value)],
    )
}

fn write_ply_with(path: &Path, mesh: &InterfaceMesh, space: Space, extra: &[String]) -> Result<()> {
    check_writable(mesh)?;
    let values = patch_values(mesh)?;
    let h = header(
        mesh,
        0..mesh.labels.len() as LabelId,
        extra,
        vec![
            vertex_element(mesh.vertex_count(), false),
            face_element(mesh.triangle_count()),
        ],
        space,
    );
    let vertices = (0..mesh.vertex_count() as u32).map(|v| VertexOut::new_at(mesh, v));
    let faces = mesh
        .triangles
        .iter()
        .zip(&mesh.triangle_patch)
        .map(|(t, &p)| FaceOut {
            v: t.map(|v| v as i32),
            labels: values[p as usize],
            patch: p,
        });
    atomic_write_with(path, |w| {
        write_header_to(w, &h)?;
        write_items(w, &h.elements["vertex"], vertices)?;
        write_items(w, &h.elements["face"], faces)
    })
}

/// Global vertex ids used by `vertices`, sorted and unique.
fn compact(vertices: impl Iterator<Item = u32>) -> Vec<u32> {
    let mut used: Vec<u32> = vertices.collect();
    used.sort_unstable();
    used.dedup();
    used
}

/// Global → local vertex ids of one file at a time: a table over all vertices,
/// allocated once and reset after each patch (only the entries used), so that
/// writing every patch costs O(vertices + corners), not O(patches × vertices).
struct LocalIds(Vec<u32>);

impl LocalIds {
    fn new(n: usize) -> Self {
        LocalIds(vec![u32::MAX; n])
    }
    /// Numbers `used` (global ids) 0, 1, 2, …
    fn assign(&mut self, used: &[u32]) {
        for (i, &v) in used.iter().enumerate() {
            self.0[v as usize] = i as u32;
        }
    }
    fn get(&self, v: u32) -> i32 {
        self.0[v as usize] as i32
    }
    fn reset(&mut self, used: &[u32]) {
        for &v in used {
            self.0[v as usize] = u32::MAX;
        }
    }
}

/// Writes one patch (its triangles, over only the vertices they use, each with
/// its global id as `vid`) as a binary PLY. Atomic.
pub fn write_patch_ply(path: &Path, mesh: &InterfaceMesh, patch: u32) -> Result<()> {
    check_writable(mesh)?;
    let values = patch_values(mesh)?;
    let tris: Vec<u32> = (0..mesh.triangle_count() as u32)
        .filter(|&t| mesh.triangle_patch[t as usize] == patch)
        .collect();
    let mut local = LocalIds::new(mesh.vertex_count());
    write_patch(path, mesh, patch, &values, &tris, &mut local, Space::Lps)
}

/// Writes patch `patch` made of triangles `tris` (the mesh is checked).
fn write_patch(
    path: &Path,
    mesh: &InterfaceMesh,
    patch: u32,
    values: &[[i32; 2]],
    tris: &[u32],
    local: &mut LocalIds,
    space: Space,
) -> Result<()> {
    let Some(&[va, vb]) = values.get(patch as usize) else {
        return Err(Error::invalid(format!(
            "patch {patch} does not exist ({} patches)",
            mesh.patches.len()
        )));
    };
    let corners = |t: &u32| mesh.triangles[*t as usize];
    let used = compact(tris.iter().flat_map(corners));
    local.assign(&used);
    let comment = format!("patch {patch} {va} {vb}");
    let elements = vec![vertex_element(used.len(), true), face_element(tris.len())];
    let h = header(
        mesh,
        mesh.patches[patch as usize].labels,
        &[comment],
        elements,
        space,
    );
    let vertices = used.iter().map(|&v| VertexOut::new_at(mesh, v));
    let faces = tris.iter().map(|t| FaceOut {
        v: corners(t).map(|v| local.get(v)),
        labels: [va, vb],
        patch,
    });
    let written = atomic_write_with(path, |w| {
        write_header_to(w, &h)?;
        write_items(w, &h.elements["vertex"], vertices)?;
        write_items(w, &h.elements["face"], faces)
    });
    local.reset(&used);
    written
}

/// File name of a patch's PLY: `<prefix><value_a>_<value_b>.ply`.
pub fn patch_file_name(mesh: &InterfaceMesh, prefix: &str, patch: u32) -> String {
    let [a, b] = mesh
        .patches
        .get(patch as usize)
        .map(|p| p.labels)
        .unwrap_or([0, 0]);
    format!(
        "{prefix}{}_{}.ply",
        mesh.label_value(a),
        mesh.label_value(b)
    )
}

/// Writes every patch to `dir/<prefix><value_a>_<value_b>.ply` (see
/// [`write_patch_ply`]); returns the paths in patch order.
pub fn write_patch_plys(dir: &Path, prefix: &str, mesh: &InterfaceMesh) -> Result<Vec<PathBuf>> {
    let path_of = |p: usize| dir.join(patch_file_name(mesh, prefix, p as u32));
    write_patch_plys_to(mesh, path_of)?;
    Ok((0..mesh.patches.len()).map(path_of).collect())
}

/// Writes every patch `p` to `path_of(p)` (see [`write_patch_ply`]) in one
/// pass over the triangles; returns the number of files written.
pub fn write_patch_plys_to(
    mesh: &InterfaceMesh,
    path_of: impl Fn(usize) -> PathBuf,
) -> Result<usize> {
    write_patch_plys_in(mesh, path_of, Space::Lps)
}

/// [`write_patch_plys_to`] of a mesh whose positions are in `space`.
pub fn write_patch_plys_in(
    mesh: &InterfaceMesh,
    path_of: impl Fn(usize) -> PathBuf,
    space: Space,
) -> Result<usize> {
    check_writable(mesh)?;
    let values = patch_values(mesh)?;
    let groups = mesh.patch_triangles();
    let mut local = LocalIds::new(mesh.vertex_count());
    for (p, tris) in groups.iter().enumerate() {
        write_patch(
            &path_of(p),
            mesh,
            p as u32,
            &values,
            tris,
            &mut local,
            space,
        )?;
    }
    Ok(groups.len())
}

/// Edges (local vertex ids, curve index) of every junction curve.
fn junction_edges(mesh: &InterfaceMesh, local: &LocalIds) -> Vec<([i32; 2], u32)> {
    let mut edges = Vec::new();
    for (c, curve) in mesh.junctions.iter().enumerate() {
        let v = &curve.vertices;
        let mut pairs: Vec<(u32, u32)> = v.windows(2).map(|w| (w[0], w[1])).collect();
        if curve.closed && v.len() > 2 {
            pairs.push((v[v.len() - 1], v[0]));
        }
        edges.extend(
            pairs
                .iter()
                .map(|&(a, b)| ([local.get(a), local.get(b)], c as u32)),
        );
    }
    edges
}

/// Original label values of each junction curve.
fn junction_labels(mesh: &InterfaceMesh) -> Result<Vec<Vec<i32>>> {
    mesh.junctions
        .iter()
        .map(|c| {
            if c.labels.len() > u8::MAX as usize {
                return Err(Error::invalid("a junction curve with more than 255 labels"));
            }
            c.labels.iter().map(|&l| value_i32(mesh, l)).collect()
        })
        .collect()
}

/// Writes the junction curves: their vertices (with global `vid`) and one
/// `edge` per segment (layout in the module docs). Atomic.
pub fn write_junctions_ply(path: &Path, mesh: &InterfaceMesh) -> Result<()> {
    write_junctions_ply_in(path, mesh, Space::Lps)
}

/// [`write_junctions_ply`] of a mesh whose positions are in `space`.
pub fn write_junctions_ply_in(path: &Path, mesh: &InterfaceMesh, space: Space) -> Result<()> {
    check_writable(mesh)?;
    let n = mesh.vertex_count();
    if mesh
        .junctions
        .iter()
        .flat_map(|c| &c.vertices)
        .any(|&v| v as usize >= n)
    {
        return Err(Error::invalid(
            "a junction curve refers to a vertex that does not exist",
        ));
    }
    let labels = junction_labels(mesh)?;
    let used = compact(
        mesh.junctions
            .iter()
            .flat_map(|c| c.vertices.iter().copied()),
    );
    let mut local = LocalIds::new(n);
    local.assign(&used);
    let edges = junction_edges(mesh, &local);
    let on_curves: BTreeSet<LabelId> = mesh
        .junctions
        .iter()
        .flat_map(|c| c.labels.iter().copied())
        .collect();
    let mut h = header(
        mesh,
        on_curves,
        &[],
        vec![vertex_element(used.len(), true), edge_element(edges.len())],
        space,
    );
    // ascii: trimesh reads list properties of edges only there (and the
    // file is small: the curves' vertices only)
    h.encoding = Encoding::Ascii;
    let vertices = used.iter().map(|&v| VertexOut::new_at(mesh, v));
    let items = edges.iter().map(|&(v, curve)| EdgeOut {
        v,
        curve,
        labels: &labels[curve as usize],
    });
    atomic_write_with(path, |w| {
        write_header_to(w, &h)?;
        write_items_ascii(w, &h.elements["vertex"], vertices)?;
        write_items_ascii(w, &h.elements["edge"], items)
    })
}

// ───────────────────────────── reading ─────────────────────────────

/// A mesh read from a PLY file.
#[derive(Clone, Debug)]
pub struct PlyMesh {
    /// The mesh (no junction curves; identity geometry).
    pub mesh: InterfaceMesh,
    /// The `vid` vertex property, when the file has one (per-patch files).
    pub vertex_ids: Option<Vec<u32>>,
    /// The label (by value) whose closed surface the file holds, when its
    /// header says so (`labels/NAME.ply`: a `comment surface of label V`).
    pub surface_of: Option<i64>,
    /// What the reader had to assume or skip, for the user.
    pub notes: Vec<String>,
    /// Faces of the file with fewer than three vertices (skipped), by index.
    pub short_faces: Vec<usize>,
}

/// Implements the eight scalar setters of `PropertyAccess` through `self.scalar`.
macro_rules! scalar_setters {
    ($($f:ident: $t:ty),*) => {$(
        fn $f(&mut self, name: &str, v: $t) -> PropertyAccessResult {
            self.scalar(name, f64::from(v))
        }
    )*};
}

#[derive(Default)]
struct VertexIn {
    p: [f64; 3],
    vid: f64,
}

impl VertexIn {
    fn scalar(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        match name {
            "x" => self.p[0] = v,
            "y" => self.p[1] = v,
            "z" => self.p[2] = v,
            "vid" => self.vid = v,
            _ => return PropertyAccessResult::Ignored,
        }
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for VertexIn {
    fn new() -> Self {
        Self::default()
    }
    scalar_setters!(set_char: i8, set_uchar: u8, set_short: i16, set_ushort: u16,
        set_int: i32, set_uint: u32, set_float: f32, set_double: f64);
}

/// The vertex list of a face, in whatever integer type the file uses.
#[derive(Default)]
enum Indices {
    #[default]
    None,
    I8(Vec<i8>),
    U8(Vec<u8>),
    I16(Vec<i16>),
    U16(Vec<u16>),
    I32(Vec<i32>),
    U32(Vec<u32>),
}

impl Indices {
    /// Appends the indices to `out` as i64.
    fn extend_into(&self, out: &mut Vec<i64>) {
        match self {
            Indices::None => {}
            Indices::I8(v) => out.extend(v.iter().map(|&x| i64::from(x))),
            Indices::U8(v) => out.extend(v.iter().map(|&x| i64::from(x))),
            Indices::I16(v) => out.extend(v.iter().map(|&x| i64::from(x))),
            Indices::U16(v) => out.extend(v.iter().map(|&x| i64::from(x))),
            Indices::I32(v) => out.extend(v.iter().map(|&x| i64::from(x))),
            Indices::U32(v) => out.extend(v.iter().map(|&x| i64::from(x))),
        }
    }
}

#[derive(Default)]
struct FaceIn {
    indices: Indices,
    labels: [f64; 2],
}

fn is_index_list(name: &str) -> bool {
    name == "vertex_indices" || name == "vertex_index"
}

/// `begin_list_*` for an index type: the parser fills the face's own vector.
macro_rules! index_list {
    ($f:ident, $variant:ident, $t:ty) => {
        fn $f(&mut self, name: &str, _len: usize) -> BeginList<'_, $t> {
            if !is_index_list(name) {
                return BeginList::UseSetter;
            }
            self.indices = Indices::$variant(Vec::new());
            match &mut self.indices {
                Indices::$variant(v) => BeginList::Fill(v),
                _ => BeginList::UnsupportedType,
            }
        }
    };
}

impl FaceIn {
    fn scalar(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        match name {
            "label_a" => self.labels[0] = v,
            "label_b" => self.labels[1] = v,
            _ => return PropertyAccessResult::Ignored,
        }
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for FaceIn {
    fn new() -> Self {
        Self::default()
    }
    scalar_setters!(set_char: i8, set_uchar: u8, set_short: i16, set_ushort: u16,
        set_int: i32, set_uint: u32, set_float: f32, set_double: f64);
    index_list!(begin_list_char, I8, i8);
    index_list!(begin_list_uchar, U8, u8);
    index_list!(begin_list_short, I16, i16);
    index_list!(begin_list_ushort, U16, u16);
    index_list!(begin_list_int, I32, i32);
    index_list!(begin_list_uint, U32, u32);
}

/// Element of no interest: everything is read and dropped.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

/// What the header says about the parts we read.
struct Layout {
    labelled: bool,
    has_vid: bool,
}

fn prop_type<'a>(e: &'a ElementDef, name: &str) -> Option<&'a PropertyType> {
    e.properties.get(name).map(|p| &p.data_type)
}

fn is_scalar(t: Option<&PropertyType>) -> bool {
    matches!(t, Some(PropertyType::Scalar(_)))
}

fn is_int(t: &ScalarType) -> bool {
    !matches!(t, ScalarType::Float | ScalarType::Double)
}

/// Checks the vertex and face elements and finds the optional properties.
fn layout(path: &Path, h: &Header) -> Result<Layout> {
    let Some(v) = h.elements.get("vertex") else {
        return Err(Error::input(path, "has no 'vertex' element"));
    };
    if let Some(c) = ["x", "y", "z"].iter().find(|c| !is_scalar(prop_type(v, c))) {
        return Err(Error::input(
            path,
            format!("its vertex element has no scalar property '{c}'"),
        ));
    }
    let Some(f) = h.elements.get("face") else {
        return Err(Error::input(
            path,
            "has no 'face' element (is it a point cloud?)",
        ));
    };
    let lists: Vec<_> = f
        .properties
        .values()
        .filter(|p| is_index_list(&p.name))
        .collect();
    match lists.as_slice() {
        [p] if matches!(&p.data_type, PropertyType::List(_, t) if is_int(t)) => {}
        [_] => {
            return Err(Error::input(
                path,
                "its face vertex list is not a list of integers",
            ));
        }
        [] => {
            return Err(Error::input(
                path,
                "its face element has no 'vertex_indices' list",
            ));
        }
        _ => {
            return Err(Error::input(
                path,
                "its faces have both 'vertex_indices' and 'vertex_index'",
            ));
        }
    }
    let (a, b) = (
        is_scalar(prop_type(f, "label_a")),
        is_scalar(prop_type(f, "label_b")),
    );
    if a != b {
        return Err(Error::input(
            path,
            "its faces have only one of the scalar properties 'label_a' and 'label_b'",
        ));
    }
    Ok(Layout {
        labelled: a,
        has_vid: is_scalar(prop_type(v, "vid")),
    })
}

fn scalar_size(t: &ScalarType) -> u64 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// The fewest bytes an element can take in a binary file (lists empty).
fn min_size(e: &ElementDef) -> u64 {
    e.properties
        .values()
        .map(|p| match &p.data_type {
            PropertyType::Scalar(t) | PropertyType::List(t, _) => scalar_size(t),
        })
        .sum()
}

/// Rejects headers whose counts cannot fit in the bytes left (a truncated file, or
/// a corrupt count that would make the parser loop for ever).
fn check_counts(path: &Path, h: &Header, remaining: usize) -> Result<()> {
    let mut need: u64 = 0;
    for e in h.elements.values() {
        let per = if h.encoding == Encoding::Ascii {
            1
        } else {
            min_size(e)
        };
        need = need.saturating_add((e.count as u64).saturating_mul(per));
    }
    if need > remaining as u64 {
        return Err(Error::input(
            path,
            format!(
                "is truncated: its header declares at least {need} bytes of data but only {remaining} follow"
            ),
        ));
    }
    Ok(())
}

/// ply-rs-bw keeps only the last of two elements (or properties) with the same
/// name, which would shift every later value; count the declarations ourselves.
fn check_unique_names(path: &Path, header_text: &[u8], h: &Header) -> Result<()> {
    let text = String::from_utf8_lossy(header_text);
    let count = |kw: &str| {
        let first = |l: &str| l.split_whitespace().next() == Some(kw);
        text.lines().filter(|l| first(l)).count()
    };
    let props: usize = h.elements.values().map(|e| e.properties.len()).sum();
    if count("element") != h.elements.len() || count("property") != props {
        return Err(Error::input(
            path,
            "declares the same element or property name twice",
        ));
    }
    Ok(())
}

fn parse_error(path: &Path, element: &str, e: ParseError) -> Error {
    let what = if e.kind() == io::ErrorKind::UnexpectedEof {
        "is truncated"
    } else {
        "has bad data"
    };
    Error::input(path, format!("{what} in element '{element}': {e}"))
}

/// Reads the payload of one element with element type `E`.
fn read_element<E: PropertyAccess>(
    path: &Path,
    reader: &mut Reader<&[u8]>,
    e: &ElementDef,
    h: &Header,
) -> Result<Vec<E>> {
    Parser::<E>::new()
        .read_payload_for_element(reader, e, h)
        .map_err(|err| parse_error(path, &e.name, err))
}

/// `comment label <value> <name>` lines → names by value.
fn label_names(h: &Header) -> BTreeMap<i64, String> {
    let mut names = BTreeMap::new();
    for c in &h.comments {
        let Some(rest) = c.trim().strip_prefix("label ") else {
            continue;
        };
        let rest = rest.trim_start();
        let (value, name) = rest.split_once(char::is_whitespace).unwrap_or((rest, ""));
        if let Ok(v) = value.parse::<i64>() {
            names.insert(v, name.trim().to_string());
        }
    }
    names
}

/// Reads a PLY file into an [`InterfaceMesh`] (see the module docs).
pub fn read_ply(path: &Path) -> Result<PlyMesh> {
    parse_ply(path, &read_file(path)?)
}

/// Like [`read_ply`], from bytes already in memory (`path` is for messages).
pub fn parse_ply(path: &Path, bytes: &[u8]) -> Result<PlyMesh> {
    if !bytes.starts_with(b"ply") {
        return Err(Error::input(
            path,
            "is not a PLY file (it does not start with 'ply')",
        ));
    }
    let mut reader = Reader::new(bytes);
    let h = Parser::<Skip>::new()
        .read_header(&mut reader)
        .map_err(|e| Error::input(path, format!("has a bad PLY header: {e}")))?;
    let remaining = reader.get_ref().len();
    check_unique_names(path, &bytes[..bytes.len() - remaining], &h)?;
    let layout = layout(path, &h)?;
    check_counts(path, &h, remaining)?;
    let (mut vertices, mut faces) = (Vec::new(), Vec::new());
    for e in h.elements.values() {
        match e.name.as_str() {
            "vertex" => vertices = read_element::<VertexIn>(path, &mut reader, e, &h)?,
            "face" => faces = read_element::<FaceIn>(path, &mut reader, e, &h)?,
            // binary elements without properties take no bytes: nothing to read
            _ if e.properties.is_empty() && h.encoding != Encoding::Ascii => {}
            _ => drop(read_element::<Skip>(path, &mut reader, e, &h)?),
        }
    }
    build(path, &layout, &h, &vertices, &faces)
}

fn positions(path: &Path, vertices: &[VertexIn]) -> Result<Vec<DVec3>> {
    let mut out = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        let p = DVec3::from(v.p);
        if !p.is_finite() {
            return Err(Error::input(
                path,
                format!(
                    "vertex {i} has a non-finite coordinate: {}",
                    crate::mesh::fmt_point(p)
                ),
            ));
        }
        out.push(p);
    }
    Ok(out)
}

fn vertex_ids(path: &Path, vertices: &[VertexIn]) -> Result<Vec<u32>> {
    let mut out = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        if !(v.vid >= 0.0 && v.vid <= f64::from(u32::MAX) && v.vid.fract() == 0.0) {
            return Err(Error::input(
                path,
                format!("vertex {i} has vid {}, not a vertex id", v.vid),
            ));
        }
        out.push(v.vid as u32);
    }
    Ok(out)
}

/// A face's label values `[a, b]` as whole numbers.
fn face_labels(path: &Path, f: usize, face: &FaceIn) -> Result<[i64; 2]> {
    let [a, b] = face.labels;
    let whole = |x: f64| x.is_finite() && x.fract() == 0.0 && x.abs() <= 9.0e15;
    if !whole(a) || !whole(b) {
        return Err(Error::input(
            path,
            format!("face {f} has labels {a} / {b}: label values must be whole numbers"),
        ));
    }
    if a == b {
        return Err(Error::input(
            path,
            format!("face {f} lies between label {a} and itself"),
        ));
    }
    Ok([a as i64, b as i64])
}

/// Triangles (fan-triangulated, oriented from the smaller label value into the
/// larger) and their label values.
struct Triangles {
    triangles: Vec<[u32; 3]>,
    values: Vec<[i64; 2]>,
    skipped: Vec<usize>,
    swapped: usize,
}

fn triangulate(path: &Path, faces: &[FaceIn], n: usize, labelled: bool) -> Result<Triangles> {
    let mut out = Triangles {
        triangles: Vec::with_capacity(faces.len()),
        values: Vec::new(),
        skipped: Vec::new(),
        swapped: 0,
    };
    out.values.reserve(faces.len());
    let mut idx = Vec::new();
    for (f, face) in faces.iter().enumerate() {
        idx.clear();
        face.indices.extend_into(&mut idx);
        if let Some(&bad) = idx.iter().find(|&&i| i < 0 || i as u64 >= n as u64) {
            return Err(Error::input(
                path,
                format!("face {f} refers to vertex {bad}, but there are {n} vertices"),
            ));
        }
        if idx.len() < 3 {
            out.skipped.push(f);
            continue;
        }
        let mut labels = if labelled {
            face_labels(path, f, face)?
        } else {
            [0, 1]
        };
        let swap = labels[0] > labels[1];
        if swap {
            labels.swap(0, 1);
            out.swapped += 1;
        }
        for k in 1..idx.len() - 1 {
            let t = [idx[0] as u32, idx[k] as u32, idx[k + 1] as u32];
            out.triangles
                .push(if swap { [t[0], t[2], t[1]] } else { t });
            out.values.push(labels);
        }
    }
    Ok(out)
}

/// The label table (every value seen on a face or in a `comment label` line,
/// ascending) and a value → dense id lookup.
fn label_table(
    path: &Path,
    values: &[[i64; 2]],
    names: &BTreeMap<i64, String>,
) -> Result<Vec<LabelInfo>> {
    let mut set: BTreeSet<i64> = names.keys().copied().collect();
    set.extend(values.iter().flatten());
    if set.len() > MAX_LABELS {
        return Err(Error::input(
            path,
            format!(
                "has {} distinct labels; at most {MAX_LABELS} are supported",
                set.len()
            ),
        ));
    }
    let name = |v: i64| {
        names
            .get(&v)
            .filter(|n| !n.is_empty())
            .cloned()
            .unwrap_or_else(|| format!("label{v}"))
    };
    Ok(set
        .into_iter()
        .map(|v| LabelInfo {
            value: v,
            name: name(v),
        })
        .collect())
}

/// Patches (sorted by dense label pair) and the patch of every triangle.
fn patches(labels: &[LabelInfo], values: &[[i64; 2]]) -> (Vec<Patch>, Vec<u32>) {
    let id = |v: i64| {
        labels
            .binary_search_by_key(&v, |l| l.value)
            .map_or(0, |i| i as LabelId)
    };
    let pairs: Vec<[LabelId; 2]> = values.iter().map(|[a, b]| [id(*a), id(*b)]).collect();
    let set: BTreeSet<[LabelId; 2]> = pairs.iter().copied().collect();
    let patches: Vec<Patch> = set.into_iter().map(|labels| Patch { labels }).collect();
    let patch_of = |p: &[LabelId; 2]| {
        patches
            .binary_search_by(|q| q.labels.cmp(p))
            .map_or(0, |i| i as u32)
    };
    let triangle_patch = pairs.iter().map(patch_of).collect();
    (patches, triangle_patch)
}

fn build(
    path: &Path,
    layout: &Layout,
    h: &Header,
    vertices: &[VertexIn],
    faces: &[FaceIn],
) -> Result<PlyMesh> {
    let mut notes = Vec::new();
    let positions = positions(path, vertices)?;
    let vertex_ids = if layout.has_vid {
        Some(vertex_ids(path, vertices)?)
    } else {
        None
    };
    let tris = triangulate(path, faces, positions.len(), layout.labelled)?;
    let names = if layout.labelled {
        label_names(h)
    } else {
        notes.push("faces have no label_a/label_b: all of them form one patch from 'inside' (0) to 'outside' (1)".into());
        BTreeMap::from([(0, "inside".to_string()), (1, "outside".to_string())])
    };
    if !tris.skipped.is_empty() {
        notes.push(format!(
            "skipped {} faces with fewer than 3 vertices",
            tris.skipped.len()
        ));
    }
    let surface_of = h.comments.iter().find_map(|c| {
        c.trim()
            .strip_prefix(SURFACE_OF)
            .and_then(|v| v.trim().parse::<i64>().ok())
    });
    // a label's surface has that label first on every face, by design
    if tris.swapped > 0 && surface_of.is_none() {
        notes.push(format!(
            "{} faces had label_a > label_b: swapped the labels and reversed the faces",
            tris.swapped
        ));
    }
    let labels = label_table(path, &tris.values, &names)?;
    let (patches, triangle_patch) = patches(&labels, &tris.values);
    let mesh = InterfaceMesh {
        positions,
        triangles: tris.triangles,
        triangle_patch,
        patches,
        labels,
        ..Default::default()
    };
    Ok(PlyMesh {
        mesh,
        vertex_ids,
        surface_of,
        notes,
        short_faces: tris.skipped,
    })
}

/// An [`InterfaceMesh`] from arrays, the way [`read_ply`] builds one from a
/// file: `values` holds each triangle's `[label_a, label_b]` (a triangle with
/// `label_a > label_b` has the pair swapped and its corners reversed, so its
/// normal still points from the smaller value into the larger); without it
/// every triangle is in one patch from `inside` (0) to `outside` (1).
/// `names` names label values. Errors name `what` (e.g. "triangles") and the
/// first bad entry.
pub fn mesh_from_arrays(
    positions: Vec<DVec3>,
    triangles: &[[i64; 3]],
    values: Option<&[[i64; 2]]>,
    names: &BTreeMap<i64, String>,
) -> Result<InterfaceMesh> {
    let n = positions.len();
    if n > u32::MAX as usize {
        return Err(Error::invalid(format!("{n} vertices: too many")));
    }
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::invalid(format!(
            "vertex {i} has a non-finite coordinate ({})",
            crate::mesh::fmt_point(positions[i])
        )));
    }
    if let Some(v) = values {
        if v.len() != triangles.len() {
            return Err(Error::invalid(format!(
                "{} label pairs for {} triangles",
                v.len(),
                triangles.len()
            )));
        }
    }
    let mut tris = Vec::with_capacity(triangles.len());
    let mut pairs = Vec::with_capacity(triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&bad) = tri.iter().find(|&&i| i < 0 || i as u64 >= n as u64) {
            return Err(Error::invalid(format!(
                "triangle {t} refers to vertex {bad}, but there are {n} vertices"
            )));
        }
        let t3 = tri.map(|i| i as u32);
        let mut pair = values.map_or([0, 1], |v| v[t]);
        if pair[0] > pair[1] {
            pair.swap(0, 1);
            tris.push([t3[0], t3[2], t3[1]]);
        } else {
            tris.push(t3);
        }
        pairs.push(pair);
    }
    let names = if values.is_some() {
        names.clone()
    } else {
        BTreeMap::from([(0, "inside".to_string()), (1, "outside".to_string())])
    };
    let labels = label_table(Path::new("mesh"), &pairs, &names)?;
    let (patches, triangle_patch) = patches(&labels, &pairs);
    Ok(InterfaceMesh {
        positions,
        triangles: tris,
        triangle_patch,
        patches,
        labels,
        ..Default::default()
    })
}
