//! Interface meshes as OBJ, STL and VTK XML PolyData (`.vtp`) files, for tools
//! that do not read PLY properties. All writers are atomic and check the mesh
//! first (finite positions, valid ids, label values that fit 32 bits).
//!
//! # OBJ ([`write_obj`])
//!
//! ```text
//! # septa 0.1.0
//! # space LPS mm SPACE=LPS         (or RAS: the space the file is in)
//! # label <value> <name>          (one per label)
//! v <x> <y> <z>                   (every vertex, shortest exact decimal of the f64)
//! o <name_a>__<name_b>            (one group per patch, in patch order)
//! g <name_a>__<name_b>
//! f <i> <j> <k>                   (1-based ids into the shared v list)
//! ```
//!
//! Names have whitespace replaced by `_`. Faces are counter-clockwise about the
//! normal, which points from label `a` into label `b`.
//!
//! # STL (binary)
//!
//! [`write_stl`] writes every triangle with the patch id in the 16-bit
//! "attribute byte count" (saturated at 65535); [`write_stl_label_surface`]
//! writes the surface of one label: every patch touching it, oriented outward
//! (normals pointing away from the label), attribute 0 — closed whenever the
//! label does not touch the edge of the volume, the useful file for 3D printing.
//! Layout: 80-byte header (starting `septa`, never `solid`), `u32` triangle
//! count, then per triangle `f32` normal (unit, zero for degenerate triangles),
//! three `f32` vertices, `u16` attribute; little-endian.
//!
//! # VTP ([`write_vtp`])
//!
//! VTK XML PolyData, `version="1.0"`, `header_type="UInt64"`, little-endian,
//! either ascii inline data or base64 appended data (each array: the base64 of
//! its 8-byte byte count, then the base64 of its bytes; `offset` counts base64
//! characters after the `_`). Arrays: `Points` (Float32 ×3), `Polys` with
//! `connectivity` and `offsets` (Int32, Int64 past 2³¹ indices), and CellData `label_a`, `label_b`
//! (original label values) and `patch`, all Int32. Label names are in XML
//! comments `<!-- label <value> <name> -->` before the `VTKFile` element.

use std::io::{self, Write};
use std::path::Path;

use super::mesh_ply::{check_writable, one_line, patch_values};
use super::{Space, atomic_write_with};
use crate::error::{Error, Result};
use crate::mesh::InterfaceMesh;
use crate::volume::LabelId;

const VERSION: &str = env!("CARGO_PKG_VERSION");

// ───────────────────────────── OBJ ─────────────────────────────

/// A name usable as one OBJ token.
fn obj_token(name: &str) -> String {
    let s: String = one_line(name)
        .chars()
        .map(|c| if c.is_whitespace() { '_' } else { c })
        .collect();
    if s.is_empty() {
        "unnamed".to_string()
    } else {
        s
    }
}

fn write_obj_body(w: &mut dyn Write, mesh: &InterfaceMesh, space: Space) -> io::Result<()> {
    writeln!(w, "# septa {VERSION}\n# space {}", space.comment())?;
    for l in &mesh.labels {
        writeln!(w, "# label {} {}", l.value, one_line(&l.name))?;
    }
    for p in &mesh.positions {
        writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
    }
    for (patch, tris) in mesh.patches.iter().zip(mesh.patch_triangles()) {
        let [a, b] = patch.labels.map(|l| obj_token(&mesh.label_name(l)));
        writeln!(w, "o {a}__{b}\ng {a}__{b}")?;
        for t in tris {
            let [i, j, k] = mesh.triangles[t as usize].map(|v| u64::from(v) + 1);
            writeln!(w, "f {i} {j} {k}")?;
        }
    }
    Ok(())
}

/// Writes the mesh as a Wavefront OBJ file, one group per patch over a shared
/// vertex list. Atomic.
pub fn write_obj(path: &Path, mesh: &InterfaceMesh) -> Result<()> {
    write_obj_in(path, mesh, Space::Lps)
}

/// [`write_obj`] of a mesh whose positions are in `space` (the header says so).
pub fn write_obj_in(path: &Path, mesh: &InterfaceMesh, space: Space) -> Result<()> {
    check_writable(mesh)?;
    atomic_write_with(path, |w| write_obj_body(w, mesh, space))
}

// ───────────────────────────── STL ─────────────────────────────

fn stl_header(text: &str) -> [u8; 80] {
    let mut h = [b' '; 80];
    let bytes = text.as_bytes();
    let n = bytes.len().min(80);
    h[..n].copy_from_slice(&bytes[..n]);
    h
}

/// The 50 bytes of one STL facet.
fn stl_facet(mesh: &InterfaceMesh, t: [u32; 3], attribute: u16) -> [u8; 50] {
    let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
    let n = (b - a).cross(c - a).normalize_or_zero();
    let mut out = [0u8; 50];
    for (k, p) in [n, a, b, c].iter().enumerate() {
        for (j, x) in p.to_array().iter().enumerate() {
            let at = 12 * k + 4 * j;
            out[at..at + 4].copy_from_slice(&(*x as f32).to_le_bytes());
        }
    }
    out[48..].copy_from_slice(&attribute.to_le_bytes());
    out
}

fn write_stl_facets(
    path: &Path,
    header: &str,
    mesh: &InterfaceMesh,
    facets: &[([u32; 3], u16)],
) -> Result<()> {
    let count =
        u32::try_from(facets.len()).map_err(|_| Error::invalid("too many triangles for STL"))?;
    atomic_write_with(path, |w| {
        w.write_all(&stl_header(header))?;
        w.write_all(&count.to_le_bytes())?;
        for &(t, attr) in facets {
            w.write_all(&stl_facet(mesh, t, attr))?;
        }
        Ok(())
    })
}

/// Writes every triangle as binary STL, the patch id (saturated at 65535) in
/// each facet's attribute. Atomic.
pub fn write_stl(path: &Path, mesh: &InterfaceMesh) -> Result<()> {
    check_writable(mesh)?;
    let facets: Vec<_> = mesh
        .triangles
        .iter()
        .zip(&mesh.triangle_patch)
        .map(|(&t, &p)| (t, u16::try_from(p).unwrap_or(u16::MAX)))
        .collect();
    let header = format!("septa {VERSION} interface patches, LPS mm, attribute = patch id");
    write_stl_facets(path, &header, mesh, &facets)
}

/// Writes the closed surface of `label` (dense id) as binary STL: the
/// triangles of every patch touching it, normals pointing away from it. Atomic.
pub fn write_stl_label_surface(path: &Path, mesh: &InterfaceMesh, label: LabelId) -> Result<()> {
    write_stl_label_surface_in(path, mesh, label, Space::Lps)
}

/// [`write_stl_label_surface`] of a mesh whose positions are in `space`.
pub fn write_stl_label_surface_in(
    path: &Path,
    mesh: &InterfaceMesh,
    label: LabelId,
    space: Space,
) -> Result<()> {
    check_writable(mesh)?;
    if label as usize >= mesh.labels.len() {
        return Err(Error::invalid(format!(
            "label id {label} does not exist ({} labels)",
            mesh.labels.len()
        )));
    }
    let facets: Vec<_> = mesh
        .label_surface(label)
        .into_iter()
        .map(|t| (t, 0))
        .collect();
    if facets.is_empty() {
        let name = mesh.label_name(label);
        return Err(Error::invalid(format!(
            "label {name} has no surface: it touches no other label"
        )));
    }
    let header = format!(
        "septa {VERSION} surface of label {} {}, {}",
        mesh.label_value(label),
        one_line(&mesh.label_name(label)),
        space.comment()
    );
    write_stl_facets(path, &header, mesh, &facets)
}

// ───────────────────────────── VTP ─────────────────────────────

/// How a `.vtp` file stores its arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VtpEncoding {
    /// Numbers as text inside each `DataArray`.
    Ascii,
    /// Base64 appended data: valid XML, a third bigger than raw binary.
    Base64,
}

/// Values of one type, as a `.vtp` file writes them.
trait VtpValue: Copy + std::fmt::Display {
    const TYPE: &'static str;
    const SIZE: usize;
    fn push_le(self, out: &mut Vec<u8>);
}

macro_rules! vtp_value {
    ($t:ty, $name:literal) => {
        impl VtpValue for $t {
            const TYPE: &'static str = $name;
            const SIZE: usize = std::mem::size_of::<$t>();
            fn push_le(self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes());
            }
        }
    };
}
vtp_value!(f32, "Float32");
vtp_value!(i32, "Int32");
vtp_value!(i64, "Int64");

/// One array of a `.vtp` file, made value by value as it is written (so
/// that no array of a large mesh is ever held in memory whole, twice over
/// with its encoding).
trait VtpArray {
    fn name(&self) -> &'static str;
    fn vtk_type(&self) -> &'static str;
    fn components(&self) -> usize;
    /// Bytes of the raw little-endian values.
    fn byte_len(&self) -> usize;
    /// Values `range`, little-endian, appended to `out`.
    fn le_bytes(&self, range: std::ops::Range<usize>, out: &mut Vec<u8>);
    /// Every value as text, three tuples to a line.
    fn write_text(&self, w: &mut dyn Write) -> io::Result<()>;
    /// How many values.
    fn len(&self) -> usize;
}

/// A [`VtpArray`] of `len` values, value `i` being `at(i)`.
struct Column<T, F> {
    name: &'static str,
    components: usize,
    len: usize,
    at: F,
    _value: std::marker::PhantomData<T>,
}

impl<T: VtpValue, F: Fn(usize) -> T> VtpArray for Column<T, F> {
    fn name(&self) -> &'static str {
        self.name
    }
    fn vtk_type(&self) -> &'static str {
        T::TYPE
    }
    fn components(&self) -> usize {
        self.components
    }
    fn byte_len(&self) -> usize {
        self.len * T::SIZE
    }
    fn le_bytes(&self, range: std::ops::Range<usize>, out: &mut Vec<u8>) {
        out.reserve(range.len() * T::SIZE);
        for i in range {
            (self.at)(i).push_le(out);
        }
    }
    fn write_text(&self, w: &mut dyn Write) -> io::Result<()> {
        let line = 3 * self.components.max(1);
        for i in 0..self.len {
            let sep = if i % line == 0 { "\n" } else { " " };
            write!(w, "{sep}{}", (self.at)(i))?;
        }
        Ok(())
    }
    fn len(&self) -> usize {
        self.len
    }
}

/// The array `name` of `len` values, `components` to a tuple, value `i`
/// being `at(i)`.
fn column<'a, T: VtpValue + 'a>(
    name: &'static str,
    components: usize,
    len: usize,
    at: impl Fn(usize) -> T + 'a,
) -> Box<dyn VtpArray + 'a> {
    Box::new(Column {
        name,
        components,
        len,
        at,
        _value: std::marker::PhantomData,
    })
}

/// The array `name` holding `values`.
fn vtp_array<'a, T: VtpValue + 'a>(
    name: &'static str,
    components: usize,
    values: &'a [T],
) -> Box<dyn VtpArray + 'a> {
    column(name, components, values.len(), move |i| values[i])
}

fn vtp_arrays(mesh: &InterfaceMesh) -> Result<Vec<Box<dyn VtpArray + '_>>> {
    let values = patch_values(mesh)?;
    let (pos, tris, tp) = (&mesh.positions, &mesh.triangles, &mesh.triangle_patch);
    let n = tris.len();
    // Int32 wherever the offsets fit it (half the bytes of Int64; VTK reads
    // either)
    let polys = if 3 * n <= i32::MAX as usize {
        [
            column("connectivity", 1, 3 * n, move |i| tris[i / 3][i % 3] as i32),
            column("offsets", 1, n, |t| 3 * (t as i32 + 1)),
        ]
    } else {
        [
            column("connectivity", 1, 3 * n, move |i| {
                i64::from(tris[i / 3][i % 3])
            }),
            column("offsets", 1, n, |t| 3 * (t as i64 + 1)),
        ]
    };
    let [conn, offsets] = polys;
    let label = move |side: usize| {
        let values = values.clone();
        move |t: usize| values[tp[t] as usize][side]
    };
    Ok(vec![
        column("Points", 3, 3 * pos.len(), move |i| {
            pos[i / 3][i % 3] as f32
        }),
        conn,
        offsets,
        column("label_a", 1, n, label(0)),
        column("label_b", 1, n, label(1)),
        column("patch", 1, n, move |t| {
            i32::try_from(tp[t]).unwrap_or(i32::MAX)
        }),
    ])
}

/// Base64 length of `n` bytes, with padding.
fn b64_len(n: usize) -> usize {
    n.div_ceil(3) * 4
}

/// Standard base64 with padding, appended to `out`.
fn base64_into(bytes: &[u8], out: &mut Vec<u8>) {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let quad = |n: u32| [18, 12, 6, 0].map(|s| ABC[(n >> s) as usize & 63]);
    out.reserve(b64_len(bytes.len()));
    let chunks = bytes.chunks_exact(3);
    let tail = chunks.remainder();
    for c in chunks {
        out.extend_from_slice(&quad(u32::from_be_bytes([0, c[0], c[1], c[2]])));
    }
    if !tail.is_empty() {
        let mut last = [0u8; 3];
        last[..tail.len()].copy_from_slice(tail);
        let mut q = quad(u32::from_be_bytes([0, last[0], last[1], last[2]]));
        q[tail.len() + 1..].fill(b'=');
        out.extend_from_slice(&q);
    }
}

/// Values per piece of an appended array: a multiple of 3, so that every
/// piece but the last is a whole number of base64 quads and the pieces
/// encode as the whole would.
const B64_PIECE: usize = 3 * 8192;

/// Writes array `a` as appended base64 data: its byte count (UInt64), then
/// its values, encoded piece by piece.
fn write_appended(w: &mut dyn Write, a: &dyn VtpArray) -> io::Result<()> {
    let mut raw = Vec::new();
    let mut text = Vec::new();
    base64_into(&(a.byte_len() as u64).to_le_bytes(), &mut text);
    w.write_all(&text)?;
    for start in (0..a.len()).step_by(B64_PIECE) {
        raw.clear();
        text.clear();
        a.le_bytes(start..(start + B64_PIECE).min(a.len()), &mut raw);
        base64_into(&raw, &mut text);
        w.write_all(&text)?;
    }
    Ok(())
}

/// The `<DataArray …>` element; `offset` is used for appended data.
fn data_array(
    w: &mut dyn Write,
    a: &dyn VtpArray,
    offset: usize,
    enc: VtpEncoding,
) -> io::Result<()> {
    let comps = if a.components() > 1 {
        format!(" NumberOfComponents=\"{}\"", a.components())
    } else {
        String::new()
    };
    write!(
        w,
        "        <DataArray type=\"{}\" Name=\"{}\"{comps}",
        a.vtk_type(),
        a.name()
    )?;
    match enc {
        VtpEncoding::Base64 => writeln!(w, " format=\"appended\" offset=\"{offset}\"/>"),
        VtpEncoding::Ascii => {
            write!(w, " format=\"ascii\">")?;
            a.write_text(w)?;
            writeln!(w, "\n        </DataArray>")
        }
    }
}

/// A label name made safe for an XML comment.
fn xml_comment_text(s: &str) -> String {
    one_line(s).replace("--", "- -")
}

/// What one `<Piece>` of a `.vtp` file holds: counts, and which arrays go
/// into which element (`Points`, `Polys`, `Lines`, `PointData`, `CellData`).
struct VtpPiece<'a> {
    space: Space,
    points: usize,
    lines: usize,
    polys: usize,
    groups: &'a [(&'a str, &'a str, std::ops::Range<usize>)],
}

fn write_vtp_body(
    w: &mut dyn Write,
    mesh: &InterfaceMesh,
    piece: &VtpPiece<'_>,
    arrays: &[Box<dyn VtpArray + '_>],
    enc: VtpEncoding,
) -> io::Result<()> {
    writeln!(
        w,
        "<?xml version=\"1.0\"?>\n<!-- septa {VERSION}, space {} -->",
        piece.space.comment()
    )?;
    for l in &mesh.labels {
        writeln!(
            w,
            "<!-- label {} {} -->",
            l.value,
            xml_comment_text(&l.name)
        )?;
    }
    writeln!(
        w,
        "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">"
    )?;
    writeln!(w, "  <PolyData>")?;
    let (n, l, t) = (piece.points, piece.lines, piece.polys);
    writeln!(
        w,
        "    <Piece NumberOfPoints=\"{n}\" NumberOfVerts=\"0\" NumberOfLines=\"{l}\" NumberOfStrips=\"0\" NumberOfPolys=\"{t}\">"
    )?;
    let mut offsets = Vec::with_capacity(arrays.len());
    let mut at = 0;
    for a in arrays {
        offsets.push(at);
        at += b64_len(8) + b64_len(a.byte_len());
    }
    for (tag, attrs, range) in piece.groups {
        writeln!(w, "      <{tag}{attrs}>")?;
        for i in range.clone() {
            data_array(w, arrays[i].as_ref(), offsets[i], enc)?;
        }
        writeln!(w, "      </{tag}>")?;
    }
    writeln!(w, "    </Piece>\n  </PolyData>")?;
    if enc == VtpEncoding::Base64 {
        write!(w, "  <AppendedData encoding=\"base64\">\n   _")?;
        for a in arrays {
            write_appended(w, a.as_ref())?;
        }
        writeln!(w, "\n  </AppendedData>")?;
    }
    writeln!(w, "</VTKFile>")
}

/// Writes the mesh as VTK XML PolyData (layout in the module docs). Atomic.
pub fn write_vtp(path: &Path, mesh: &InterfaceMesh, encoding: VtpEncoding) -> Result<()> {
    write_vtp_in(path, mesh, encoding, Space::Lps)
}

/// [`write_vtp`] of a mesh whose positions are in `space` (the header says so).
pub fn write_vtp_in(
    path: &Path,
    mesh: &InterfaceMesh,
    encoding: VtpEncoding,
    space: Space,
) -> Result<()> {
    check_writable(mesh)?;
    let arrays = vtp_arrays(mesh)?;
    let piece = VtpPiece {
        space,
        points: mesh.vertex_count(),
        lines: 0,
        polys: mesh.triangle_count(),
        groups: &[
            ("Points", "", 0..1),
            ("Polys", "", 1..3),
            ("CellData", " Scalars=\"patch\"", 3..6),
        ],
    };
    atomic_write_with(path, |w| write_vtp_body(w, mesh, &piece, &arrays, encoding))
}

/// Label slots of a junction curve in `labels` that it does not fill.
pub const NO_LABEL: i32 = i32::MIN;

/// Writes the junction curves as VTK XML PolyData: one polyline (`Lines`
/// cell) per curve over the curves' vertices (a closed curve ends where it
/// starts); point data `vid` (the vertex's id in the whole mesh), cell data
/// `curve` (its index in the manifest's `junction_curves`), `label_count`
/// and `labels` (the values of the labels meeting there, ascending, as many
/// components as the most labels any curve has, the rest [`NO_LABEL`]).
/// Atomic.
pub fn write_junctions_vtp(
    path: &Path,
    mesh: &InterfaceMesh,
    encoding: VtpEncoding,
    space: Space,
) -> Result<()> {
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
    let values = |c: &crate::mesh::JunctionCurve| -> Result<Vec<i32>> {
        c.labels
            .iter()
            .map(|&l| {
                i32::try_from(mesh.label_value(l))
                    .map_err(|_| Error::invalid("a label value does not fit 32 bits"))
            })
            .collect()
    };
    let width = mesh
        .junctions
        .iter()
        .map(|c| c.labels.len())
        .max()
        .unwrap_or(1)
        .max(1);
    let mut local = vec![u32::MAX; n];
    let mut vid: Vec<i64> = Vec::new();
    let (mut conn, mut offsets) = (Vec::<i64>::new(), Vec::<i64>::new());
    let (mut curve, mut label_count, mut labels) = (Vec::new(), Vec::new(), Vec::new());
    for (c, j) in mesh.junctions.iter().enumerate() {
        let mut ids: Vec<u32> = j.vertices.clone();
        if j.closed && ids.len() > 2 {
            ids.push(ids[0]);
        }
        for v in ids {
            if local[v as usize] == u32::MAX {
                local[v as usize] = vid.len() as u32;
                vid.push(i64::from(v));
            }
            conn.push(i64::from(local[v as usize]));
        }
        offsets.push(conn.len() as i64);
        curve.push(c as i32);
        let mut l = values(j)?;
        label_count.push(l.len() as i32);
        l.resize(width, NO_LABEL);
        labels.extend(l);
    }
    let points: Vec<f32> = vid
        .iter()
        .flat_map(|&v| mesh.positions[v as usize].to_array().map(|c| c as f32))
        .collect();
    let vid: Vec<i64> = vid;
    let arrays = vec![
        vtp_array("Points", 3, &points),
        vtp_array("connectivity", 1, &conn),
        vtp_array("offsets", 1, &offsets),
        vtp_array("vid", 1, &vid),
        vtp_array("curve", 1, &curve),
        vtp_array("label_count", 1, &label_count),
        vtp_array("labels", width, &labels),
    ];
    let piece = VtpPiece {
        space,
        points: points.len() / 3,
        lines: offsets.len(),
        polys: 0,
        groups: &[
            ("Points", "", 0..1),
            ("Lines", "", 1..3),
            ("PointData", "", 3..4),
            ("CellData", " Scalars=\"curve\"", 4..7),
        ],
    };
    atomic_write_with(path, |w| write_vtp_body(w, mesh, &piece, &arrays, encoding))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (raw, enc) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            let mut out = Vec::new();
            base64_into(raw.as_bytes(), &mut out);
            assert_eq!(out, enc.as_bytes(), "{raw}");
            assert_eq!(b64_len(raw.len()), enc.len());
        }
    }
}
