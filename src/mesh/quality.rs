//! Mesh quality figures for remeshed (or any) interface meshes: edge lengths
//! relative to a target, triangle angles, vertex valences, the one-sided
//! Hausdorff distance to a reference mesh, and the volume enclosed by every
//! label (with its change against the reference).
//!
//! This file owns [`quality`] and its [`QualityReport`], and the nearest-point
//! query it needs (through [`crate::geom::nearest`]).
//!
//! Definitions used throughout:
//! - **Edges** are the distinct undirected vertex pairs of the triangles. An
//!   edge is a *boundary edge* when it is used by one triangle, by three or
//!   more, or by triangles of different patches (junction curves are made of
//!   such edges). A vertex on a boundary edge is a *boundary vertex*; every
//!   other vertex is *interior*.
//! - **Valence** of an interior vertex: its number of incident edges (all in
//!   one patch). For boundary vertices the valence is counted **per patch**:
//!   each (vertex, patch) pair contributes the number of that patch's edges at
//!   the vertex, which is what regular remeshing aims at (6 inside, 4 on a
//!   boundary).
//! - **Percentiles** use the nearest-rank rule ([`percentile`]).
//! - **Distances** are measured from samples of `mesh` (every vertex, every
//!   triangle centroid and every edge midpoint) to the nearest point of the
//!   reference triangles. In voxels they are divided by the **largest** voxel
//!   spacing of `mesh.geometry` (1 mm for meshes read from PLY files).
//! - **Volumes** are the signed volumes of each label's closed surface (the
//!   patches touching it, oriented outward), as
//!   [`InterfaceMesh::label_surface`] and [`InterfaceMesh::signed_volume`]
//!   compute them, summed in one pass about the mesh's centre for accuracy. The
//!   outside label's surface faces inward, so its volume is negative: it is
//!   marked `unbounded` and gets no relative change.
//!
//! All sums run over fixed chunks, so reports do not depend on the number of
//! threads.

use glam::DVec3;
use hashbrown::HashMap;
use rayon::prelude::*;
use serde::Serialize;

use super::InterfaceMesh;
use crate::volume::LabelId;

/// A target edge length that depends on the position (the remesher's sizing
/// field): edges are measured against the target at their midpoint.
pub trait TargetEdges: Sync {
    /// The target edge length (mm) at `p` (LPS mm).
    fn target_at(&self, p: DVec3) -> f64;
}

/// Options of [`quality`].
#[derive(Clone, Copy, Default)]
pub struct QualityOptions<'a> {
    /// Target edge length L in mm (the largest, with `local`). When not a
    /// positive finite number, the mean edge length of the mesh is used (the
    /// relative figures then measure uniformity only).
    pub target_edge_mm: f64,
    /// A local target h(x): edges are then measured against h at their
    /// midpoint ([`EdgeStats::local`]).
    pub local: Option<&'a dyn TargetEdges>,
}

impl QualityOptions<'_> {
    /// Edges measured against one target length (mm).
    pub fn target(mm: f64) -> Self {
        QualityOptions {
            target_edge_mm: mm,
            local: None,
        }
    }
}

/// Lower end of the accepted edge-length range, relative to L.
pub const EDGE_RANGE_LO: f64 = 0.8;
/// Upper end of the accepted edge-length range, relative to L (4/3 ≈ 1.33).
pub const EDGE_RANGE_HI: f64 = 4.0 / 3.0;

/// Everything [`quality`] measures.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct QualityReport {
    pub vertices: usize,
    pub triangles: usize,
    pub patches: usize,
    pub edges: EdgeStats,
    pub angles: AngleStats,
    pub valence: ValenceStats,
    /// Distance from the mesh to the reference (when one was given).
    pub distance: Option<DistanceStats>,
    /// One entry per label that has a patch, by label id.
    pub labels: Vec<LabelVolumeStats>,
}

/// Edge lengths.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct EdgeStats {
    /// Distinct edges.
    pub count: usize,
    /// Edges on a patch boundary (one triangle, three or more, or two patches).
    pub boundary: usize,
    /// The L the relative figures use (mm).
    pub target_mm: f64,
    /// True when L is the mean edge length (no valid target was given).
    pub target_is_mean: bool,
    pub min_mm: f64,
    pub max_mm: f64,
    pub mean_mm: f64,
    /// Population standard deviation.
    pub std_mm: f64,
    /// Mean / L.
    pub mean_rel: f64,
    /// Standard deviation / L.
    pub std_rel: f64,
    /// Share of edges with length in [0.8 L, 4/3 L] (0..1), L the target at
    /// the edge's midpoint when `local`.
    pub within_range: f64,
    /// True when edges were measured against a local target h(x): then
    /// `mean_rel` and `std_rel` are of length / h(midpoint).
    pub local: bool,
    /// The smallest and largest target at the edges' midpoints (mm).
    pub target_min_mm: f64,
    pub target_max_mm: f64,
}

/// Triangle angles, in degrees.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct AngleStats {
    /// Smallest angle of any triangle.
    pub min_deg: f64,
    /// 1st percentile of the per-triangle minimum angle.
    pub min_p1_deg: f64,
    /// Mean of the per-triangle minimum angle.
    pub min_mean_deg: f64,
    /// Share of triangles whose minimum angle is ≥ 20° (0..1).
    pub min_ge_20: f64,
    /// Share of triangles whose minimum angle is ≥ 30° (0..1).
    pub min_ge_30: f64,
    /// Largest angle of any triangle.
    pub max_deg: f64,
    /// 99th percentile of the per-triangle maximum angle.
    pub max_p99_deg: f64,
    /// Triangles with zero area (counted with angles 0° and 180°).
    pub degenerate: usize,
}

/// Valence histograms: `interior[k]` = number of interior vertices with `k`
/// edges; `boundary[k]` = number of (boundary vertex, patch) pairs with `k`
/// edges of that patch at the vertex.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ValenceStats {
    pub interior_vertices: usize,
    pub boundary_vertices: usize,
    pub interior: Vec<u64>,
    pub boundary: Vec<u64>,
    /// Share of interior vertices with valence 6 (0..1).
    pub interior_6: f64,
    /// Share of boundary (vertex, patch) pairs with valence 4 (0..1).
    pub boundary_4: f64,
}

/// One-sided distance from the mesh to the reference.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct DistanceStats {
    /// Sample points: vertices + triangle centroids + edge midpoints.
    pub samples: usize,
    /// Maximum distance (one-sided Hausdorff), mm.
    pub hausdorff_mm: f64,
    /// The same in voxels (divided by `voxel_mm`).
    pub hausdorff_voxels: f64,
    /// Mean distance over the samples, mm.
    pub mean_mm: f64,
    /// The same in voxels.
    pub mean_voxels: f64,
    /// The voxel size used: the largest spacing of the mesh's geometry.
    pub voxel_mm: f64,
    /// Where the maximum is attained (a sample of the mesh, LPS mm).
    pub hausdorff_at: [f64; 3],
}

/// Enclosed volume of one label.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LabelVolumeStats {
    /// Dense label id in the mesh.
    pub label: LabelId,
    pub value: i64,
    pub name: String,
    /// Signed volume of the label's outward surface, mm³.
    pub volume_mm3: f64,
    /// True for a label whose surface encloses a negative volume (the outside).
    pub unbounded: bool,
    /// The reference's volume of the label with the same value, mm³.
    pub reference_mm3: Option<f64>,
    /// (volume − reference) / reference, for bounded labels with a positive
    /// reference volume.
    pub change: Option<f64>,
}

/// Measures `mesh`: edge lengths against `opts.target_edge_mm`, angles,
/// valences, enclosed volumes, and with a `reference`, the one-sided
/// Hausdorff distance from `mesh` to it and the volume change per label
/// (labels matched by value). Never panics; an empty mesh gives zeros.
///
/// ```
/// use glam::DVec3;
/// use septa::mesh::{InterfaceMesh, LabelInfo, Patch};
/// use septa::mesh::quality::{QualityOptions, quality};
///
/// // A regular octahedron of circumradius 1 around label 1, inside label 0.
/// let mut m = InterfaceMesh::default();
/// m.positions = vec![
///     DVec3::X, -DVec3::X, DVec3::Y, -DVec3::Y, DVec3::Z, -DVec3::Z,
/// ];
/// // Outward (from label 1 into label 0) is the reverse of patch {0, 1}'s
/// // orientation, so these triangles wind clockwise seen from outside.
/// m.triangles = vec![
///     [0, 4, 2], [2, 4, 1], [1, 4, 3], [3, 4, 0],
///     [0, 2, 5], [2, 1, 5], [1, 3, 5], [3, 0, 5],
/// ];
/// m.triangle_patch = vec![0; 8];
/// m.patches = vec![Patch { labels: [0, 1] }];
/// m.labels = vec![
///     LabelInfo { value: 0, name: "outside".into() },
///     LabelInfo { value: 1, name: "inside".into() },
/// ];
/// let shifted = InterfaceMesh {
///     positions: m.positions.iter().map(|p| *p + DVec3::new(0.0, 0.0, 0.25)).collect(),
///     ..m.clone()
/// };
/// let r = quality(&shifted, Some(&m), &QualityOptions::target(2f64.sqrt()));
/// assert!((r.angles.min_deg - 60.0).abs() < 1e-9);
/// assert_eq!(r.valence.interior, vec![0, 0, 0, 0, 6]);
/// assert!((r.edges.mean_rel - 1.0).abs() < 1e-12);
/// assert!((r.labels[1].volume_mm3 - 4.0 / 3.0).abs() < 1e-12);
/// assert!(r.labels[0].unbounded);
/// let d = r.distance.unwrap();
/// assert!(d.hausdorff_mm > 0.0 && d.hausdorff_mm <= 0.25 + 1e-12);
/// ```
pub fn quality(
    mesh: &InterfaceMesh,
    reference: Option<&InterfaceMesh>,
    opts: &QualityOptions,
) -> QualityReport {
    let topo = Topology::new(mesh);
    let edges = edge_stats(mesh, &topo, opts.target_edge_mm, opts.local);
    let angles = angle_stats(mesh);
    let valence = valence_stats(mesh, &topo);
    let distance = reference.map(|r| distance_stats(mesh, &topo.edges, r));
    let labels = label_volumes(mesh, reference);
    QualityReport {
        vertices: mesh.positions.len(),
        triangles: mesh.triangles.len(),
        patches: mesh.patches.len(),
        edges,
        angles,
        valence,
        distance,
        labels,
    }
}

impl QualityReport {
    /// A few aligned lines for the terminal.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let pct = |x: f64| format!("{:.1} %", 100.0 * x);
        s.push_str(&format!(
            "mesh       {} vertices, {} triangles, {} patches, {} edges ({} on patch boundaries)\n",
            self.vertices, self.triangles, self.patches, self.edges.count, self.edges.boundary
        ));
        let e = &self.edges;
        if e.local {
            s.push_str(&format!(
                "edges      h(x) from {:.3} to {:.3} mm (largest L = {:.3} mm): length / h mean {:.3}, std {:.3}; {} within [0.8 h, 1.33 h]; min {:.3} mm, max {:.3} mm\n",
                e.target_min_mm,
                e.target_max_mm,
                e.target_mm,
                e.mean_rel,
                e.std_rel,
                pct(e.within_range),
                e.min_mm,
                e.max_mm
            ));
        } else {
            s.push_str(&format!(
                "edges      L = {:.3} mm{}: mean {:.3} L, std {:.3} L; {} within [0.8 L, 1.33 L]; min {:.3} mm, max {:.3} mm\n",
                e.target_mm,
                if e.target_is_mean { " (mean)" } else { "" },
                e.mean_rel,
                e.std_rel,
                pct(e.within_range),
                e.min_mm,
                e.max_mm
            ));
        }
        let a = &self.angles;
        s.push_str(&format!(
            "angles     min {:.1}°, 1st percentile {:.1}°; {} ≥ 20°, {} ≥ 30°; max {:.1}°{}\n",
            a.min_deg,
            a.min_p1_deg,
            pct(a.min_ge_20),
            pct(a.min_ge_30),
            a.max_deg,
            if a.degenerate > 0 {
                format!("; {} degenerate", a.degenerate)
            } else {
                String::new()
            }
        ));
        let v = &self.valence;
        s.push_str(&format!(
            "valence    interior {}; boundary (per patch) {}\n",
            top_valences(&v.interior),
            top_valences(&v.boundary)
        ));
        if let Some(d) = &self.distance {
            s.push_str(&format!(
                "distance   Hausdorff {:.3} mm ({:.3} voxels), mean {:.3} mm, to the reference ({} samples)\n",
                d.hausdorff_mm, d.hausdorff_voxels, d.mean_mm, d.samples
            ));
        }
        let bounded: Vec<&LabelVolumeStats> = self.labels.iter().filter(|l| !l.unbounded).collect();
        if !bounded.is_empty() {
            let name_w = bounded
                .iter()
                .map(|l| l.name.chars().count())
                .max()
                .unwrap_or(0);
            let with_change = bounded.iter().any(|l| l.change.is_some());
            s.push_str(if with_change {
                "volume     label, mm³, change against the reference\n"
            } else {
                "volume     label, mm³\n"
            });
            for l in bounded {
                s.push_str(&format!(
                    "           {:<name_w$}  {:>12.1}{}\n",
                    l.name,
                    l.volume_mm3,
                    match l.change {
                        Some(c) => format!("  {:+.2} %", 100.0 * c),
                        None => String::new(),
                    }
                ));
            }
        }
        s
    }

    /// The largest |relative volume change| over bounded labels, if any.
    pub fn max_volume_change(&self) -> Option<f64> {
        self.labels
            .iter()
            .filter_map(|l| l.change.map(f64::abs))
            .fold(None, |m, c| Some(m.map_or(c, |m: f64| m.max(c))))
    }
}

/// "6: 71.2 %, 5: 14.0 %, 7: 12.1 %" — the three most frequent valences.
fn top_valences(h: &[u64]) -> String {
    let total: u64 = h.iter().sum();
    if total == 0 {
        return "none".into();
    }
    let mut v: Vec<(usize, u64)> = h.iter().copied().enumerate().filter(|e| e.1 > 0).collect();
    v.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    v.iter()
        .take(3)
        .map(|(k, n)| format!("{k}: {:.1} %", 100.0 * *n as f64 / total as f64))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The `p`-th percentile (0..=100) of `values` by the nearest-rank rule: the
/// value at 1-based rank ⌈p/100 · n⌉ (at least 1) in ascending order. `None`
/// for an empty slice. NaNs sort last.
///
/// ```
/// use septa::mesh::quality::percentile;
/// let v = [5.0, 1.0, 4.0, 2.0, 3.0];
/// assert_eq!(percentile(&v, 0.0), Some(1.0));
/// assert_eq!(percentile(&v, 20.0), Some(1.0));
/// assert_eq!(percentile(&v, 21.0), Some(2.0));
/// assert_eq!(percentile(&v, 100.0), Some(5.0));
/// ```
pub fn percentile(values: &[f64], p: f64) -> Option<f64> {
    let mut v = values.to_vec();
    percentile_in_place(&mut v, p)
}

fn percentile_in_place(v: &mut [f64], p: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let n = v.len();
    let p = if p.is_nan() { 0.0 } else { p.clamp(0.0, 100.0) };
    let rank = ((p / 100.0 * n as f64).ceil() as usize).clamp(1, n);
    let (_, x, _) = v.select_nth_unstable_by(rank - 1, |a, b| a.total_cmp(b));
    Some(*x)
}

// ───────────────────────────── topology ─────────────────────────────

const CHUNK: usize = 1 << 14;

/// Distinct edges with their boundary flags, and boundary vertices.
struct Topology {
    /// Distinct edges (lower id first), ascending.
    edges: Vec<[u32; 2]>,
    /// Per edge: on a patch boundary.
    edge_boundary: Vec<bool>,
    /// (edge index, patch) of every distinct edge-in-patch, ascending.
    edge_patches: Vec<(u32, u32)>,
    /// Per vertex: on a boundary edge.
    vertex_boundary: Vec<bool>,
    /// Per vertex: used by a triangle.
    vertex_used: Vec<bool>,
}

impl Topology {
    fn new(mesh: &InterfaceMesh) -> Self {
        let nv = mesh.positions.len();
        let valid = |t: &[u32; 3]| t.iter().all(|&v| (v as usize) < nv);
        let mut keys: Vec<(u64, u32)> = mesh
            .triangles
            .par_iter()
            .enumerate()
            .filter(|(_, t)| valid(t))
            .flat_map_iter(|(i, t)| {
                let p = mesh.triangle_patch.get(i).copied().unwrap_or(0);
                (0..3).filter_map(move |k| {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    (a != b).then(|| (((a.min(b) as u64) << 32) | a.max(b) as u64, p))
                })
            })
            .collect();
        keys.par_sort_unstable();
        let mut edges = Vec::with_capacity(keys.len() / 2 + 1);
        let mut edge_boundary = Vec::with_capacity(keys.len() / 2 + 1);
        let mut edge_patches = Vec::with_capacity(keys.len() / 2 + 1);
        let mut vertex_boundary = vec![false; nv];
        let mut i = 0;
        while i < keys.len() {
            let key = keys[i].0;
            let mut j = i;
            let e = edges.len() as u32;
            while j < keys.len() && keys[j].0 == key {
                if j == i || keys[j].1 != keys[j - 1].1 {
                    edge_patches.push((e, keys[j].1));
                }
                j += 1;
            }
            let uses = j - i;
            let boundary = uses != 2 || keys[i].1 != keys[j - 1].1;
            let (a, b) = ((key >> 32) as u32, key as u32);
            if boundary {
                vertex_boundary[a as usize] = true;
                vertex_boundary[b as usize] = true;
            }
            edges.push([a, b]);
            edge_boundary.push(boundary);
            i = j;
        }
        let mut vertex_used = vec![false; nv];
        for t in mesh.triangles.iter().filter(|t| valid(t)) {
            for &v in t {
                vertex_used[v as usize] = true;
            }
        }
        Topology {
            edges,
            edge_boundary,
            edge_patches,
            vertex_boundary,
            vertex_used,
        }
    }
}

fn edge_stats(
    mesh: &InterfaceMesh,
    topo: &Topology,
    target: f64,
    local: Option<&dyn TargetEdges>,
) -> EdgeStats {
    let p = &mesh.positions;
    let lengths: Vec<f64> = topo
        .edges
        .par_iter()
        .map(|&[a, b]| p[a as usize].distance(p[b as usize]))
        .collect();
    let valid = target.is_finite() && target > 0.0;
    let n = lengths.len();
    if n == 0 {
        return EdgeStats {
            target_mm: if valid { target } else { 0.0 },
            target_is_mean: !valid,
            local: local.is_some() && valid,
            ..Default::default()
        };
    }
    let sum = chunked_sum(&lengths, |&l| l);
    let mean = sum / n as f64;
    let var = chunked_sum(&lengths, |&l| (l - mean) * (l - mean)) / n as f64;
    let std = var.max(0.0).sqrt();
    let (l, is_mean) = if valid { (target, false) } else { (mean, true) };
    // the target of each edge: the local one at its midpoint, or L
    let targets: Vec<f64> = match local.filter(|_| valid) {
        Some(field) => topo
            .edges
            .par_iter()
            .map(|&[a, b]| field.target_at(0.5 * (p[a as usize] + p[b as usize])))
            .collect(),
        None => vec![l; n],
    };
    let rel: Vec<f64> = lengths
        .iter()
        .zip(&targets)
        .map(|(&x, &h)| if h > 0.0 { x / h } else { 0.0 })
        .collect();
    let within = rel
        .par_iter()
        .filter(|&&r| (EDGE_RANGE_LO..=EDGE_RANGE_HI).contains(&r))
        .count();
    let (min, max) = lengths
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    let (tmin, tmax) = targets
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    let local_used = local.is_some() && valid;
    let (mean_rel, std_rel) = if local_used {
        let m = chunked_sum(&rel, |&r| r) / n as f64;
        let v = chunked_sum(&rel, |&r| (r - m) * (r - m)) / n as f64;
        (m, v.max(0.0).sqrt())
    } else if l > 0.0 {
        (mean / l, std / l)
    } else {
        (0.0, 0.0)
    };
    EdgeStats {
        count: n,
        boundary: topo.edge_boundary.iter().filter(|&&b| b).count(),
        target_mm: l,
        target_is_mean: is_mean,
        min_mm: min,
        max_mm: max,
        mean_mm: mean,
        std_mm: std,
        mean_rel,
        std_rel,
        within_range: if l > 0.0 {
            within as f64 / n as f64
        } else {
            0.0
        },
        local: local_used,
        target_min_mm: tmin,
        target_max_mm: tmax,
    }
}

/// Sum of `f` over `v` in fixed chunks (independent of the thread count).
fn chunked_sum<T: Sync>(v: &[T], f: impl Fn(&T) -> f64 + Sync) -> f64 {
    let parts: Vec<f64> = v
        .par_chunks(CHUNK)
        .map(|c| c.iter().map(&f).sum::<f64>())
        .collect();
    parts.iter().sum()
}

/// Minimum and maximum angle of a triangle in degrees, and whether its area is
/// zero (then the angles are reported as 0° and 180°). Scale-free: the edge
/// vectors are normalised by their largest component first.
fn triangle_angles(a: DVec3, b: DVec3, c: DVec3) -> (f64, f64, bool) {
    let (ab, bc, ca) = (b - a, c - b, a - c);
    let s = ab.abs().max(bc.abs()).max(ca.abs()).max_element();
    if !(s > 0.0 && s.is_finite()) {
        return (0.0, 180.0, true);
    }
    let (ab, bc, ca) = (ab / s, bc / s, ca / s);
    if !(ab.cross(-ca).length() > 0.0) {
        return (0.0, 180.0, true);
    }
    let angle = |u: DVec3, v: DVec3| u.cross(v).length().atan2(u.dot(v)).to_degrees();
    let x = angle(ab, -ca);
    let y = angle(bc, -ab);
    let z = angle(ca, -bc);
    (x.min(y).min(z), x.max(y).max(z), false)
}

fn angle_stats(mesh: &InterfaceMesh) -> AngleStats {
    let p = &mesh.positions;
    let nv = p.len();
    let per: Vec<(f64, f64, bool)> = mesh
        .triangles
        .par_iter()
        .map(|t| {
            if t.iter().any(|&v| v as usize >= nv) {
                return (0.0, 180.0, true);
            }
            let [a, b, c] = t.map(|v| p[v as usize]);
            triangle_angles(a, b, c)
        })
        .collect();
    let n = per.len();
    if n == 0 {
        return AngleStats::default();
    }
    let mut mins: Vec<f64> = per.iter().map(|x| x.0).collect();
    let mut maxs: Vec<f64> = per.iter().map(|x| x.1).collect();
    let min_deg = mins.iter().copied().fold(f64::INFINITY, f64::min);
    let max_deg = maxs.iter().copied().fold(0.0, f64::max);
    let ge20 = mins.iter().filter(|&&m| m >= 20.0).count();
    let ge30 = mins.iter().filter(|&&m| m >= 30.0).count();
    let mean = chunked_sum(&mins, |&m| m) / n as f64;
    AngleStats {
        min_deg,
        min_p1_deg: percentile_in_place(&mut mins, 1.0).unwrap_or(0.0),
        min_mean_deg: mean,
        min_ge_20: ge20 as f64 / n as f64,
        min_ge_30: ge30 as f64 / n as f64,
        max_deg,
        max_p99_deg: percentile_in_place(&mut maxs, 99.0).unwrap_or(0.0),
        degenerate: per.iter().filter(|x| x.2).count(),
    }
}

fn valence_stats(mesh: &InterfaceMesh, topo: &Topology) -> ValenceStats {
    let nv = mesh.positions.len();
    let mut degree = vec![0u32; nv];
    for &[a, b] in &topo.edges {
        degree[a as usize] += 1;
        degree[b as usize] += 1;
    }
    let mut interior: Vec<u64> = Vec::new();
    let mut interior_vertices = 0;
    let mut boundary_vertices = 0;
    for v in 0..nv {
        if !topo.vertex_used[v] {
            continue;
        }
        if topo.vertex_boundary[v] {
            boundary_vertices += 1;
        } else {
            interior_vertices += 1;
            bump(&mut interior, degree[v] as usize);
        }
    }
    // Per-patch valence of boundary vertices.
    let mut per_patch: HashMap<u64, u32> = HashMap::new();
    for &(e, patch) in &topo.edge_patches {
        for v in topo.edges[e as usize] {
            if topo.vertex_boundary[v as usize] {
                *per_patch
                    .entry(((v as u64) << 32) | patch as u64)
                    .or_insert(0) += 1;
            }
        }
    }
    let mut boundary: Vec<u64> = Vec::new();
    for &k in per_patch.values() {
        bump(&mut boundary, k as usize);
    }
    let share = |h: &[u64], k: usize| {
        let total: u64 = h.iter().sum();
        if total == 0 {
            0.0
        } else {
            h.get(k).copied().unwrap_or(0) as f64 / total as f64
        }
    };
    ValenceStats {
        interior_vertices,
        boundary_vertices,
        interior_6: share(&interior, 6),
        boundary_4: share(&boundary, 4),
        interior,
        boundary,
    }
}

fn bump(h: &mut Vec<u64>, k: usize) {
    if h.len() <= k {
        h.resize(k + 1, 0);
    }
    h[k] += 1;
}

// ───────────────────────────── volumes ─────────────────────────────

/// Signed volume per dense label id (outward surfaces), about the bbox centre.
fn volumes(mesh: &InterfaceMesh) -> Vec<f64> {
    let nl = mesh
        .patches
        .iter()
        .map(|p| p.labels[1] as usize + 1)
        .max()
        .unwrap_or(0);
    let p = &mesh.positions;
    if nl == 0 || p.is_empty() {
        return vec![0.0; nl];
    }
    let (lo, hi) = p.iter().fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(l, h), &x| (l.min(x), h.max(x)),
    );
    let o = 0.5 * lo + 0.5 * hi;
    let nv = p.len();
    let np = mesh.patches.len();
    let tris: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
    let parts: Vec<Vec<f64>> = tris
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut acc = vec![0.0; nl];
            for &t in chunk {
                let tri = mesh.triangles[t as usize];
                let Some(&patch) = mesh.triangle_patch.get(t as usize) else {
                    continue;
                };
                if patch as usize >= np || tri.iter().any(|&v| v as usize >= nv) {
                    continue;
                }
                let [a, b, c] = tri.map(|v| p[v as usize] - o);
                let v = a.dot(b.cross(c)) / 6.0;
                let [la, lb] = mesh.patches[patch as usize].labels;
                acc[la as usize] += v;
                acc[lb as usize] -= v;
            }
            acc
        })
        .collect();
    let mut out = vec![0.0; nl];
    for part in parts {
        for (o, x) in out.iter_mut().zip(part) {
            *o += x;
        }
    }
    out
}

fn label_volumes(mesh: &InterfaceMesh, reference: Option<&InterfaceMesh>) -> Vec<LabelVolumeStats> {
    let vol = volumes(mesh);
    let reference = reference.map(|r| {
        let v = volumes(r);
        let by_value: HashMap<i64, f64> = r
            .labels_with_patches()
            .into_iter()
            .map(|l| (r.label_value(l), v[l as usize]))
            .collect();
        by_value
    });
    mesh.labels_with_patches()
        .into_iter()
        .map(|l| {
            let value = mesh.label_value(l);
            let volume = vol[l as usize];
            let unbounded = volume < 0.0;
            let reference_mm3 = reference.as_ref().and_then(|r| r.get(&value).copied());
            let change = match reference_mm3 {
                Some(r) if !unbounded && r > 0.0 => Some((volume - r) / r),
                _ => None,
            };
            LabelVolumeStats {
                label: l,
                value,
                name: mesh.label_name(l),
                volume_mm3: volume,
                unbounded,
                reference_mm3,
                change,
            }
        })
        .collect()
}

// ───────────────────────────── distances ─────────────────────────────

fn distance_stats(
    mesh: &InterfaceMesh,
    edges: &[[u32; 2]],
    reference: &InterfaceMesh,
) -> DistanceStats {
    let voxel_mm = mesh.geometry.spacing().into_iter().fold(0.0f64, f64::max);
    let voxel_mm = if voxel_mm.is_finite() && voxel_mm > 0.0 {
        voxel_mm
    } else {
        1.0
    };
    // exact nearest triangles from a cell grid (cheaper to build and, from a
    // hint near the answer, to query than a tree over 1-2 M triangles)
    let bvh = NearestGrid(crate::geom::nearest::SurfaceRef::new(
        reference
            .triangles
            .par_iter()
            .filter(|t| t.iter().all(|&v| (v as usize) < reference.positions.len()))
            .map(|t| t.map(|v| reference.positions[v as usize]))
            .collect(),
    ));
    let p = &mesh.positions;
    let nv = p.len();
    if bvh.is_empty() {
        return DistanceStats {
            voxel_mm,
            ..Default::default()
        };
    }
    // Per chunk: (max d², where, sum of d, count).
    type Part = (f64, DVec3, f64, usize);
    let combine = |parts: Vec<Part>| -> Part {
        parts
            .into_iter()
            .fold((-1.0, DVec3::ZERO, 0.0, 0), |acc, x| {
                (
                    if x.0 > acc.0 { x.0 } else { acc.0 },
                    if x.0 > acc.0 { x.1 } else { acc.1 },
                    acc.2 + x.2,
                    acc.3 + x.3,
                )
            })
    };
    // The samples (vertices, triangle centroids, edge midpoints) in
    // Z-order of voxel-sized cells, so that consecutive queries read the
    // same reference triangles (in mesh order they jumped across the
    // reference, a cache miss per triangle read); each query starts from
    // the triangle the one before it found. Samples are numbered vertices
    // first, then triangles, then edges; all lie in the vertices' box.
    let tris: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .copied()
        .filter(|t| t.iter().all(|&v| (v as usize) < nv))
        .collect();
    let (nt, ne) = (tris.len(), edges.len());
    let sample = |i: usize| -> DVec3 {
        if i < nv {
            p[i]
        } else if i < nv + nt {
            let t = tris[i - nv];
            (p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0
        } else {
            let [a, b] = edges[i - nv - nt];
            0.5 * (p[a as usize] + p[b as usize])
        }
    };
    let (lo, inv) = z_order_frame(p, voxel_mm);
    let mut order: Vec<(u64, u32)> = (0..nv + nt + ne)
        .into_par_iter()
        .map(|i| (z_order_key(sample(i), lo, inv), i as u32))
        .collect();
    // (keys with their sample's number are distinct: one order whatever the threads)
    order.par_sort_unstable();
    let parts: Vec<Part> = order
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut part: Part = (-1.0, DVec3::ZERO, 0.0, 0);
            let mut hint = u32::MAX;
            for &(_, i) in chunk {
                let x = sample(i as usize);
                if let Some(n) = bvh.nearest(x, hint) {
                    hint = n.triangle;
                    add(&mut part, x, n.distance_squared);
                }
            }
            part
        })
        .collect();
    let all = combine(parts);
    let (max2, at, sum, count) = all;
    let h = max2.max(0.0).sqrt();
    let mean = if count > 0 { sum / count as f64 } else { 0.0 };
    DistanceStats {
        samples: count,
        hausdorff_mm: h,
        hausdorff_voxels: h / voxel_mm,
        mean_mm: mean,
        mean_voxels: mean / voxel_mm,
        voxel_mm,
        hausdorff_at: at.to_array(),
    }
}

/// The corner and the inverse cell size of the Z-order over `points`, cells
/// of `cell` mm (grown until 21 bits per axis hold the points' box).
fn z_order_frame(points: &[DVec3], cell: f64) -> (DVec3, f64) {
    let (lo, hi) = points.iter().fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(lo, hi), &x| (lo.min(x), hi.max(x)),
    );
    if points.is_empty() || !(lo.is_finite() && hi.is_finite()) {
        return (DVec3::ZERO, 1.0);
    }
    let ext = (hi - lo).max_element();
    let cell = cell
        .max(ext / f64::from((1u32 << 21) - 1))
        .max(f64::MIN_POSITIVE);
    (lo, 1.0 / cell)
}

/// The Z-order (Morton) key of `x`'s cell: 21 bits per axis, interleaved.
fn z_order_key(x: DVec3, lo: DVec3, inv: f64) -> u64 {
    let spread = |v: f64| -> u64 {
        // (NaN and points outside the frame go to its border cells)
        let mut b = (((v * inv).max(0.0)) as u64).min((1 << 21) - 1);
        b = (b | (b << 32)) & 0x001f_0000_0000_ffff;
        b = (b | (b << 16)) & 0x001f_0000_ff00_00ff;
        b = (b | (b << 8)) & 0x100f_00f0_0f00_f00f;
        b = (b | (b << 4)) & 0x10c3_0c30_c30c_30c3;
        (b | (b << 2)) & 0x1249_2492_4924_9249
    };
    let d = x - lo;
    spread(d.x) | (spread(d.y) << 1) | (spread(d.z) << 2)
}

fn add(part: &mut (f64, DVec3, f64, usize), x: DVec3, d2: f64) {
    if d2 > part.0 {
        part.0 = d2;
        part.1 = x;
    }
    part.2 += d2.sqrt();
    part.3 += 1;
}

/// The quality report's nearest-triangle queries.
struct NearestGrid(crate::geom::nearest::SurfaceRef);

impl NearestGrid {
    fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    fn nearest(&self, p: DVec3, hint: u32) -> Option<Nearest> {
        if self.is_empty() {
            return None;
        }
        let (point, triangle) = self.0.project_from(p, hint);
        Some(Nearest {
            triangle,
            distance_squared: (point - p).length_squared(),
        })
    }
}

/// A nearest point on the reference: its triangle, the point and its
/// squared distance.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Nearest {
    triangle: u32,
    distance_squared: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn z_order_keys_interleave_the_cells_coordinates() {
        let points = [DVec3::ZERO, DVec3::new(7.5, 3.2, 9.9)];
        let (lo, inv) = z_order_frame(&points, 1.0);
        let key = |x: f64, y: f64, z: f64| z_order_key(DVec3::new(x, y, z), lo, inv);
        // one bit per axis, x lowest
        assert_eq!(key(0.5, 0.5, 0.5), 0);
        assert_eq!(key(1.5, 0.5, 0.5), 0b001);
        assert_eq!(key(0.5, 1.5, 0.5), 0b010);
        assert_eq!(key(0.5, 0.5, 1.5), 0b100);
        assert_eq!(key(3.5, 0.5, 0.5), 0b001_001);
        assert_eq!(key(7.5, 3.2, 9.9), {
            // x 7 = 111, y 3 = 011, z 9 = 1001
            let (x, y, z) = (7u64, 3u64, 9u64);
            (0..4).fold(0, |k, b| {
                k | ((x >> b) & 1) << (3 * b)
                    | ((y >> b) & 1) << (3 * b + 1)
                    | ((z >> b) & 1) << (3 * b + 2)
            })
        });
        // points off the frame (and NaN) go to its border cells
        assert_eq!(key(-5.0, 0.5, f64::NAN), 0);
        // a huge extent grows the cells so that 21 bits per axis hold it
        let far = [DVec3::ZERO, DVec3::splat(1e9)];
        let (lo, inv) = z_order_frame(&far, 1.0);
        assert!(z_order_key(far[1], lo, inv) < 1 << 63);
        assert!(z_order_key(far[1], lo, inv) > z_order_key(DVec3::splat(5e8), lo, inv));
    }
}
