//! The hypersurface as a PLY file, and a reader for it.
//!
//! Binary little-endian, written atomically through `ply-rs-bw`:
//!
//! ```text
//! ply
//! format binary_little_endian 1.0
//! comment septa 0.1.0
//! comment STEVE iso-hypersurface
//! comment space LPS mm, t = frame × time step
//! comment iso 50 mode mixed displace true time_step 0.5
//! element vertex 1234
//! property float x
//! property float y
//! property float z
//! property float t
//! property uchar kind
//! element tetra 5678
//! property list uchar int vertex_indices
//! end_header
//! ```
//!
//! With a field (`septa hyper --field`), vertices have one more property,
//! `property float value`: the field interpolated onto the vertex.
//!
//! `kind` is 0 for a support point (a displaced boundary-cube centre), 1 for a
//! face centre, 2 for a volume centre. Each tetra `(p0, p1, p2, p3)` is
//! oriented so that `det[p1 − p0, p2 − p0, p3 − p0, w] > 0` for `w` pointing
//! out of the enclosed region (from ≥ iso to < iso) in (x, y, z, t).

use std::path::Path;

use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{
    Addable, DefaultElement, ElementDef, Encoding, Header, Property, PropertyAccess, PropertyDef,
    PropertyType, ScalarType,
};
use ply_rs_bw::writer::Writer;

use super::{HyperOptions, Hypersurface};
use crate::error::{Error, Result};
use crate::io::{atomic_write_with, read_file};

#[derive(Default)]
struct VertexOut {
    p: [f32; 4],
    kind: u8,
    value: f32,
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
            "t" => Some(self.p[3]),
            "value" => Some(self.value),
            _ => None,
        }
    }
    fn get_uchar(&self, name: &str) -> Option<u8> {
        (name == "kind").then_some(self.kind)
    }
}

#[derive(Default)]
struct TetraOut {
    v: [i32; 4],
}

impl PropertyAccess for TetraOut {
    fn new() -> Self {
        Self::default()
    }
    fn get_list_int(&self, name: &str) -> Option<&[i32]> {
        (name == "vertex_indices").then_some(&self.v[..])
    }
}

fn element(name: &str, count: usize, props: &[(&str, PropertyType)]) -> ElementDef {
    let mut e = ElementDef::new(name.to_string());
    e.count = count;
    for (p, t) in props {
        e.properties.add(PropertyDef::new(p.to_string(), t.clone()));
    }
    e
}

/// Writes the hypersurface in physical space (layout in the module docs),
/// with a vertex property `float value` when `values` (one per vertex, e.g.
/// from [`Hypersurface::field_values`]) are given.
pub fn write_hypersurface_ply(
    path: &Path,
    h: &Hypersurface,
    opts: &HyperOptions,
    values: Option<&[f64]>,
) -> Result<()> {
    if values.is_some_and(|v| v.len() != h.points.len()) {
        return Err(Error::invalid(
            "one field value per hypersurface vertex needed",
        ));
    }
    let points = h.physical_points();
    if let Some(i) = points
        .iter()
        .position(|p| p.iter().any(|c| !(*c as f32).is_finite()))
    {
        return Err(Error::invalid(format!(
            "vertex {i} at ({}) does not fit a float",
            points[i].map(|c| format!("{c:.3}")).join(", ")
        )));
    }
    if points.len() > i32::MAX as usize {
        return Err(Error::invalid("too many vertices for a PLY file"));
    }
    let tets = h.physical_tets();
    let f = ScalarType::Float;
    let mut header = Header::new();
    header.encoding = Encoding::BinaryLittleEndian;
    header
        .comments
        .push(format!("septa {}", env!("CARGO_PKG_VERSION")));
    header.comments.push("STEVE iso-hypersurface".into());
    header
        .comments
        .push("space LPS mm, t = frame × time step".into());
    header.comments.push(format!(
        "iso {} mode {} displace {} time_step {}",
        opts.iso,
        opts.mode.name(),
        opts.displace,
        h.time_step
    ));
    let mut vprops = vec![
        ("x", PropertyType::Scalar(f.clone())),
        ("y", PropertyType::Scalar(f.clone())),
        ("z", PropertyType::Scalar(f.clone())),
        ("t", PropertyType::Scalar(f.clone())),
        ("kind", PropertyType::Scalar(ScalarType::UChar)),
    ];
    if values.is_some() {
        vprops.push(("value", PropertyType::Scalar(f)));
    }
    header
        .elements
        .add(element("vertex", points.len(), &vprops));
    header.elements.add(element(
        "tetra",
        tets.len(),
        &[(
            "vertex_indices",
            PropertyType::List(ScalarType::UChar, ScalarType::Int),
        )],
    ));
    atomic_write_with(path, |w| {
        let mut w = w;
        Writer::<VertexOut>::new().write_header(&mut w, &header)?;
        let mut buf = Vec::with_capacity(1 << 20);
        let vw = Writer::<VertexOut>::new();
        let vdef = &header.elements["vertex"];
        for (i, (p, &k)) in points.iter().zip(&h.kinds).enumerate() {
            let item = VertexOut {
                p: p.map(|c| c as f32),
                kind: k as u8,
                value: values.map_or(0.0, |v| v[i] as f32),
            };
            vw.write_little_endian_element(&mut buf, &item, vdef)?;
            if buf.len() >= 1 << 20 {
                w.write_all(&buf)?;
                buf.clear();
            }
        }
        let tw = Writer::<TetraOut>::new();
        let tdef = &header.elements["tetra"];
        for t in &tets {
            let item = TetraOut {
                v: t.map(|v| v as i32),
            };
            tw.write_little_endian_element(&mut buf, &item, tdef)?;
            if buf.len() >= 1 << 20 {
                w.write_all(&buf)?;
                buf.clear();
            }
        }
        w.write_all(&buf)
    })
}

/// A hypersurface read back: vertices (x, y, z, t), kinds, tetrahedra.
#[derive(Clone, Debug, Default)]
pub struct HyperPly {
    pub points: Vec<[f64; 4]>,
    /// The `value` property, if present.
    pub values: Option<Vec<f64>>,
    pub kinds: Vec<u8>,
    pub tets: Vec<[u32; 4]>,
    pub comments: Vec<String>,
}

/// Reads a file written by [`write_hypersurface_ply`] (any PLY with vertex
/// x, y, z, t and a `tetra` element with 4-vertex `vertex_indices`).
pub fn read_hypersurface_ply(path: &Path) -> Result<HyperPly> {
    let bytes = read_file(path)?;
    let mut reader = std::io::BufReader::new(&bytes[..]);
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut reader)
        .map_err(|e| Error::input(path, format!("is not a readable PLY file: {e}")))?;
    let num = |p: Option<&Property>| -> Option<f64> {
        Some(match p? {
            Property::Float(v) => *v as f64,
            Property::Double(v) => *v,
            Property::UChar(v) => *v as f64,
            Property::Int(v) => *v as f64,
            Property::UInt(v) => *v as f64,
            _ => return None,
        })
    };
    let mut out = HyperPly {
        comments: ply.header.comments.clone(),
        ..Default::default()
    };
    let vertices = ply
        .payload
        .get("vertex")
        .ok_or_else(|| Error::input(path, "has no vertex element"))?;
    for v in vertices {
        let c = ["x", "y", "z", "t"].map(|k| num(v.get(k)));
        let [Some(x), Some(y), Some(z), Some(t)] = c else {
            return Err(Error::input(path, "vertices need x, y, z and t"));
        };
        out.points.push([x, y, z, t]);
        out.kinds.push(num(v.get("kind")).unwrap_or(0.0) as u8);
        if let Some(x) = num(v.get("value")) {
            out.values.get_or_insert_with(Vec::new).push(x);
        }
    }
    let n = out.points.len();
    for (i, e) in ply.payload.get("tetra").into_iter().flatten().enumerate() {
        let idx: Vec<i64> = match e.get("vertex_indices") {
            Some(Property::ListInt(v)) => v.iter().map(|&x| x as i64).collect(),
            Some(Property::ListUInt(v)) => v.iter().map(|&x| x as i64).collect(),
            _ => {
                return Err(Error::input(
                    path,
                    format!("tetra {i} has no vertex_indices"),
                ));
            }
        };
        if idx.len() != 4 || idx.iter().any(|&x| x < 0 || x as usize >= n) {
            return Err(Error::input(
                path,
                format!("tetra {i} is not 4 vertex indices in range"),
            ));
        }
        out.tets
            .push([idx[0] as u32, idx[1] as u32, idx[2] as u32, idx[3] as u32]);
    }
    Ok(out)
}
