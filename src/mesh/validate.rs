//! The validator: checks the invariants every septa output keeps (DESIGN.md).
//!
//! 1. For every label, the patches touching it, oriented away from it, form a
//!    closed oriented 2-manifold: every edge in exactly two triangles with
//!    opposite orientation, every vertex's triangles a single fan — and each
//!    closed component faces away from the label (signed volume positive for an
//!    outer boundary, negative for a cavity; one label may be the unbounded
//!    "outside", with the opposite signs).
//! 2. Each patch {a, b} is oriented from a to b (follows from 1: a reversed
//!    patch breaks the orientation of both labels' surfaces) and is a subset of
//!    a 2-manifold (follows from 1 as well).
//! 3. One vertex pool: no two vertices at the same position, no unused vertex,
//!    no index out of range.
//! 4. No degenerate triangle; optionally no self-intersection.
//! 5. Optionally, fidelity: every vertex lies within a given distance (in
//!    voxels) of a voxel of each label of the patches that use it.
//!
//! The validator works on any [`InterfaceMesh`], including meshes read from
//! files written by other tools.

use glam::DVec3;
use rayon::prelude::*;

use super::InterfaceMesh;
use crate::extract::is_degenerate;
use crate::preprocess::RefinedVolume;
use crate::volume::LabelId;

/// How many offending elements each check keeps for the report.
const EXAMPLES: usize = 8;

/// One check of the validator: how many elements fail it and the first few.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Check {
    pub name: &'static str,
    pub failures: u64,
    pub examples: Vec<String>,
}

impl Check {
    fn new(name: &'static str) -> Self {
        Check {
            name,
            failures: 0,
            examples: Vec::new(),
        }
    }

    fn fail(&mut self, what: impl FnOnce() -> String) {
        self.failures += 1;
        if self.examples.len() < EXAMPLES {
            self.examples.push(what());
        }
    }
}

/// Per-label summary of the closed surface.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LabelSurface {
    pub label: LabelId,
    pub value: i64,
    pub triangles: usize,
    pub components: usize,
    /// Signed enclosed volume, mm³ (negative for the unbounded outside label).
    pub volume_mm3: f64,
    /// Whether the label behaves as the unbounded outside (its surface faces inward).
    pub unbounded: bool,
}

/// Result of [`validate`].
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Report {
    pub vertices: usize,
    pub triangles: usize,
    pub patches: usize,
    pub checks: Vec<Check>,
    pub labels: Vec<LabelSurface>,
}

impl Report {
    /// True when every check passed.
    pub fn passed(&self) -> bool {
        self.checks.iter().all(|c| c.failures == 0)
    }

    /// Total number of failures.
    pub fn failures(&self) -> u64 {
        self.checks.iter().map(|c| c.failures).sum()
    }

    /// The check of that name.
    pub fn check(&self, name: &str) -> Option<&Check> {
        self.checks.iter().find(|c| c.name == name)
    }

    /// A short multi-line summary.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "{} vertices, {} triangles, {} patches: {}\n",
            self.vertices,
            self.triangles,
            self.patches,
            if self.passed() {
                "all invariants hold"
            } else {
                "INVARIANTS VIOLATED"
            }
        );
        for c in &self.checks {
            s.push_str(&format!(
                "  {:<28} {}\n",
                c.name,
                if c.failures == 0 {
                    "ok".to_string()
                } else {
                    format!("{} failures", c.failures)
                }
            ));
            for e in &c.examples {
                s.push_str(&format!("      {e}\n"));
            }
        }
        s
    }
}

/// Optional, costlier checks.
#[derive(Clone, Copy, Default)]
pub struct Options<'a> {
    /// Check for self-intersections (BVH triangle–triangle test).
    pub intersections: bool,
    /// Fidelity: the volume the mesh came from and the largest allowed distance
    /// (voxels) from a vertex to a voxel of each label of its patches.
    pub fidelity: Option<(&'a RefinedVolume, f64)>,
}

/// Runs every check.
pub fn validate(mesh: &InterfaceMesh, opts: &Options) -> Report {
    let mut report = Report {
        vertices: mesh.positions.len(),
        triangles: mesh.triangles.len(),
        patches: mesh.patches.len(),
        checks: Vec::new(),
        labels: Vec::new(),
    };
    let (indices_ok, index_check) = check_indices(mesh);
    report.checks.push(index_check);
    if !indices_ok {
        return report;
    }
    report.checks.push(check_unused(mesh));
    report.checks.push(check_duplicates(mesh));
    report.checks.push(check_degenerate(mesh));
    let edges = EdgeTable::new(mesh);
    let (edge_check, orient_check) = edges.check_label_edges(mesh);
    report.checks.push(edge_check);
    report.checks.push(orient_check);
    report.checks.push(check_fans(mesh));
    let (orientation, labels) = check_component_orientation(mesh, &edges);
    report.checks.push(orientation);
    report.labels = labels;
    if opts.intersections {
        report
            .checks
            .push(super::intersect::check_self_intersections(mesh));
    }
    if let Some((rv, tol)) = opts.fidelity {
        report.checks.push(check_fidelity(mesh, rv, tol));
    }
    report
}

fn check_indices(mesh: &InterfaceMesh) -> (bool, Check) {
    let mut c = Check::new("vertex indices in range");
    let n = mesh.positions.len() as u32;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if tri.iter().any(|&v| v >= n) || tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            c.fail(|| format!("triangle {t} {tri:?}"));
        }
    }
    if mesh.triangle_patch.len() != mesh.triangles.len() {
        c.fail(|| "triangle_patch length differs from triangle count".into());
    }
    for (t, &p) in mesh.triangle_patch.iter().enumerate() {
        if p as usize >= mesh.patches.len() {
            c.fail(|| format!("triangle {t} has patch {p}"));
        }
    }
    for (i, p) in mesh.patches.iter().enumerate() {
        if p.labels[0] >= p.labels[1] {
            c.fail(|| format!("patch {i} labels {:?} not ascending", p.labels));
        }
    }
    (c.failures == 0, c)
}

fn check_unused(mesh: &InterfaceMesh) -> Check {
    let mut c = Check::new("no unused vertices");
    let mut used = vec![false; mesh.positions.len()];
    for t in &mesh.triangles {
        for &v in t {
            used[v as usize] = true;
        }
    }
    for (v, &u) in used.iter().enumerate() {
        if !u {
            c.fail(|| format!("vertex {v} at {:?}", mesh.positions[v]));
        }
    }
    c
}

fn check_duplicates(mesh: &InterfaceMesh) -> Check {
    let mut c = Check::new("no duplicate positions");
    let mut order: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    let key = |v: u32| {
        let p = mesh.positions[v as usize];
        (p.x.to_bits(), p.y.to_bits(), p.z.to_bits())
    };
    if order.len() > 1 << 16 {
        order.par_sort_unstable_by_key(|&v| key(v))
    } else {
        order.sort_unstable_by_key(|&v| key(v))
    }
    for w in order.windows(2) {
        if mesh.positions[w[0] as usize] == mesh.positions[w[1] as usize] {
            c.fail(|| {
                format!(
                    "vertices {} and {} at {:?}",
                    w[0], w[1], mesh.positions[w[0] as usize]
                )
            });
        }
    }
    c
}

fn check_degenerate(mesh: &InterfaceMesh) -> Check {
    let mut c = Check::new("no degenerate triangles");
    let bad: Vec<usize> = (0..mesh.triangles.len())
        .into_par_iter()
        .filter(|&t| {
            let [a, b, cc] = mesh.triangles[t].map(|v| mesh.positions[v as usize]);
            is_degenerate(a, b, cc)
        })
        .collect();
    for t in bad {
        c.fail(|| format!("triangle {t} {:?}", mesh.triangles[t]));
    }
    c
}

/// Every triangle edge, grouped by undirected edge.
struct EdgeTable {
    /// (min vertex, max vertex, triangle, forward) sorted by edge.
    entries: Vec<(u32, u32, u32, bool)>,
}

impl EdgeTable {
    fn new(mesh: &InterfaceMesh) -> Self {
        let mut entries: Vec<(u32, u32, u32, bool)> = mesh
            .triangles
            .par_iter()
            .enumerate()
            .flat_map_iter(|(t, tri)| {
                (0..3).map(move |k| {
                    let (u, v) = (tri[k], tri[(k + 1) % 3]);
                    (u.min(v), u.max(v), t as u32, u < v)
                })
            })
            .collect();
        sort(&mut entries);
        EdgeTable { entries }
    }

    /// Groups of entries sharing an undirected edge.
    fn groups(&self) -> impl Iterator<Item = &[(u32, u32, u32, bool)]> {
        self.entries.chunk_by(|a, b| a.0 == b.0 && a.1 == b.1)
    }

    /// Invariant 1 on edges: for each label at an edge, exactly two of its
    /// surface triangles, with opposite directions.
    fn check_label_edges(&self, mesh: &InterfaceMesh) -> (Check, Check) {
        let mut open = Check::new("label surfaces closed");
        let mut orient = Check::new("label surfaces oriented");
        let mut labels: Vec<(LabelId, i8)> = Vec::with_capacity(16);
        for g in self.groups() {
            labels.clear();
            for &(_, _, t, fwd) in g {
                let [a, b] = mesh.patches[mesh.triangle_patch[t as usize] as usize].labels;
                let d = if fwd { 1 } else { -1 };
                labels.push((a, d));
                labels.push((b, -d));
            }
            labels.sort_unstable();
            for run in labels.chunk_by(|x, y| x.0 == y.0) {
                let l = run[0].0;
                if run.len() != 2 {
                    open.fail(|| {
                        format!(
                            "edge {}-{} has {} triangles of label {}",
                            g[0].0,
                            g[0].1,
                            run.len(),
                            mesh.label_value(l)
                        )
                    });
                } else if run[0].1 == run[1].1 {
                    orient.fail(|| {
                        format!(
                            "edge {}-{}: two triangles of label {} run the same way",
                            g[0].0,
                            g[0].1,
                            mesh.label_value(l)
                        )
                    });
                }
            }
        }
        (open, orient)
    }
}

/// Invariant 1 at vertices: the triangles of each label around a vertex form a
/// single fan.
fn check_fans(mesh: &InterfaceMesh) -> Check {
    let mut c = Check::new("label surfaces manifold at vertices");
    // (vertex, label, prev, next) in the label's outward orientation
    let mut corners: Vec<(u32, LabelId, u32, u32)> = mesh
        .triangles
        .par_iter()
        .enumerate()
        .flat_map_iter(|(t, tri)| {
            let [a, b] = mesh.patches[mesh.triangle_patch[t] as usize].labels;
            let tri = *tri;
            (0..3).flat_map(move |k| {
                let (v, next, prev) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                [(v, a, prev, next), (v, b, next, prev)]
            })
        })
        .collect();
    sort(&mut corners);
    let bad: Vec<(u32, LabelId, usize)> = corners
        .par_chunk_by(|x, y| x.0 == y.0 && x.1 == y.1)
        .filter_map(|fan| {
            let n = fan.len();
            // walk next -> prev links; one cycle must cover every triangle
            let mut seen = 1;
            let mut cur = 0;
            loop {
                let next = fan[cur].3;
                match fan.iter().position(|x| x.2 == next) {
                    Some(0) => break,
                    Some(i) if seen < n => {
                        cur = i;
                        seen += 1;
                    }
                    _ => return Some((fan[0].0, fan[0].1, seen)),
                }
            }
            (seen != n).then_some((fan[0].0, fan[0].1, seen))
        })
        .collect();
    for (v, l, _) in bad {
        c.fail(|| {
            format!(
                "vertex {v} at {:?}: label {} has more than one fan",
                mesh.positions[v as usize],
                mesh.label_value(l)
            )
        });
    }
    c
}

/// Union-find over triangles.
struct Dsu(Vec<u32>);

impl Dsu {
    fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let p = self.0[x as usize];
            self.0[x as usize] = self.0[p as usize];
            x = p;
        }
        x
    }
    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.0[ra.max(rb) as usize] = ra.min(rb);
        }
    }
}

/// Connected components of each label's surface, and their orientation.
///
/// Every triangle has two sides, one per label of its patch; side `2t` belongs
/// to the lower label (as oriented), side `2t + 1` to the higher (reversed).
/// Sides of one label that share an edge are in the same component.
fn check_component_orientation(
    mesh: &InterfaceMesh,
    edges: &EdgeTable,
) -> (Check, Vec<LabelSurface>) {
    let mut check = Check::new("surfaces face away from their label");
    let side_label = |side: u32| -> LabelId {
        let p = mesh.patches[mesh.triangle_patch[(side / 2) as usize] as usize];
        p.labels[(side % 2) as usize]
    };
    let mut dsu = Dsu((0..2 * mesh.triangles.len() as u32).collect());
    let mut sides: Vec<(LabelId, u32)> = Vec::with_capacity(8);
    for g in edges.groups() {
        sides.clear();
        for &(_, _, t, _) in g {
            sides.push((side_label(2 * t), 2 * t));
            sides.push((side_label(2 * t + 1), 2 * t + 1));
        }
        sides.sort_unstable();
        for run in sides.chunk_by(|a, b| a.0 == b.0) {
            for w in run.windows(2) {
                dsu.union(w[0].1, w[1].1);
            }
        }
    }
    let centre = bbox_centre(&mesh.positions);
    let oriented = |side: u32| -> [DVec3; 3] {
        let tri = mesh.triangles[(side / 2) as usize];
        let tri = if side % 2 == 1 {
            [tri[0], tri[2], tri[1]]
        } else {
            tri
        };
        tri.map(|v| mesh.positions[v as usize] - centre)
    };
    // per label: its sides, grouped by component root
    let mut by_label: Vec<(LabelId, u32, u32)> = (0..2 * mesh.triangles.len() as u32)
        .map(|sd| (side_label(sd), dsu.find(sd), sd))
        .collect();
    sort(&mut by_label);
    let labels: Vec<&[(LabelId, u32, u32)]> = by_label.chunk_by(|a, b| a.0 == b.0).collect();
    let results: Vec<(LabelSurface, Vec<String>)> = labels
        .par_iter()
        .map(|sides| label_orientation(mesh, sides, &oriented))
        .collect();
    let mut out = Vec::new();
    let mut unbounded = Vec::new();
    for (surf, errors) in results {
        for e in errors {
            check.fail(|| e);
        }
        if surf.unbounded {
            unbounded.push(surf.value);
        }
        out.push(surf);
    }
    if unbounded.len() > 1 {
        check.fail(|| format!("labels {unbounded:?} all face inward; only the outside label may"));
    }
    (check, out)
}

/// Sorts small slices sequentially and large ones in parallel (the validator
/// often runs inside an already parallel loop of tests).
fn sort<T: Ord + Send>(v: &mut [T]) {
    if v.len() > 1 << 16 {
        v.par_sort_unstable()
    } else {
        v.sort_unstable()
    }
}

fn bbox_centre(p: &[DVec3]) -> DVec3 {
    if p.is_empty() {
        return DVec3::ZERO;
    }
    let (lo, hi) = p.iter().fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(lo, hi), &q| (lo.min(q), hi.max(q)),
    );
    (lo + hi) * 0.5
}

/// Orientation of one label's surface components; `sides` are (label, root,
/// side) sorted by root.
fn label_orientation(
    mesh: &InterfaceMesh,
    sides: &[(LabelId, u32, u32)],
    oriented: &(dyn Fn(u32) -> [DVec3; 3] + Sync),
) -> (LabelSurface, Vec<String>) {
    let l = sides[0].0;
    let value = mesh.label_value(l);
    // components: (root, volume, first side, bbox lo, bbox hi)
    let mut list: Vec<(u32, f64, u32, DVec3, DVec3)> = Vec::new();
    for comp in sides.chunk_by(|a, b| a.1 == b.1) {
        let mut vol = 0.0;
        let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
        for &(_, _, sd) in comp {
            let [a, b, c] = oriented(sd);
            vol += a.dot(b.cross(c)) / 6.0;
            lo = lo.min(a).min(b).min(c);
            hi = hi.max(a).max(b).max(c);
        }
        list.push((
            comp[0].1,
            vol,
            comp.iter().map(|x| x.2).min().unwrap_or(0),
            lo,
            hi,
        ));
    }
    list.sort_unstable_by_key(|c| c.2);
    let total: f64 = list.iter().map(|c| c.1).sum();
    let depths: Vec<usize> = if list.len() == 1 {
        vec![0]
    } else {
        let roots: Vec<u32> = sides.iter().map(|x| x.1).collect();
        let tri_pts: Vec<[DVec3; 3]> = sides.iter().map(|x| oriented(x.2)).collect();
        let firsts: Vec<usize> = list
            .iter()
            .map(|c| sides.iter().position(|x| x.2 == c.2).unwrap_or(0))
            .collect();
        nesting_depths(&list, &firsts, &roots, &tri_pts)
    };
    let mut bounded_ok = true;
    let mut unbounded_ok = true;
    let mut wrong_bounded = 0;
    for (c, &d) in list.iter().zip(&depths) {
        let positive = c.1 > 0.0;
        let even = d % 2 == 0;
        bounded_ok &= positive == even;
        unbounded_ok &= positive != even;
        wrong_bounded += usize::from(positive != even);
    }
    let mut errors = Vec::new();
    let unbounded = !bounded_ok && unbounded_ok;
    if !bounded_ok && !unbounded_ok {
        errors.push(format!(
            "label {value}: {} of {} surface components face the wrong way",
            wrong_bounded.min(list.len() - wrong_bounded),
            list.len()
        ));
    }
    (
        LabelSurface {
            label: l,
            value,
            triangles: sides.len(),
            components: list.len(),
            volume_mm3: total,
            unbounded,
        },
        errors,
    )
}

/// For each component, how many other components of the same label contain it
/// (ray parity along +x from a generic point of its first triangle).
fn nesting_depths(
    list: &[(u32, f64, u32, DVec3, DVec3)],
    firsts: &[usize],
    roots: &[u32],
    tris: &[[DVec3; 3]],
) -> Vec<usize> {
    // 2-D bucket grid over (y, z) of all surface triangles
    let (lo, hi) = list.iter().fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(lo, hi), c| (lo.min(c.3), hi.max(c.4)),
    );
    let n = ((tris.len() as f64).sqrt().ceil() as usize).clamp(1, 1024);
    let cell = DVec3::new(
        1.0,
        ((hi.y - lo.y) / n as f64).max(1e-9),
        ((hi.z - lo.z) / n as f64).max(1e-9),
    );
    let bucket = |y: f64, z: f64| -> (usize, usize) {
        (
            (((y - lo.y) / cell.y) as isize).clamp(0, n as isize - 1) as usize,
            (((z - lo.z) / cell.z) as isize).clamp(0, n as isize - 1) as usize,
        )
    };
    let mut grid: Vec<Vec<u32>> = vec![Vec::new(); n * n];
    for (i, t) in tris.iter().enumerate() {
        let tlo = t[0].min(t[1]).min(t[2]);
        let thi = t[0].max(t[1]).max(t[2]);
        let (y0, z0) = bucket(tlo.y, tlo.z);
        let (y1, z1) = bucket(thi.y, thi.z);
        for z in z0..=z1 {
            for y in y0..=y1 {
                grid[y + n * z].push(i as u32);
            }
        }
    }
    list.iter()
        .zip(firsts)
        .map(|(c, &first)| {
            let t = tris[first];
            // a generic point next to the triangle: irrational-ish barycentric
            // weights, nudged off its plane so that it is off any lattice plane
            let normal = (t[1] - t[0]).cross(t[2] - t[0]);
            let size = (t[1] - t[0]).length().max((t[2] - t[0]).length());
            let nudge = normal.normalize_or_zero() * size * 1.37e-6
                + DVec3::new(0.0, 0.71e-7, 0.43e-7) * size;
            let mut p = t[0] * 0.2134 + t[1] * 0.3712 + t[2] * 0.4154 + nudge;
            let mut crossings: hashbrown::HashMap<u32, u32> = hashbrown::HashMap::new();
            for attempt in 0..3 {
                let (by, bz) = bucket(p.y, p.z);
                crossings.clear();
                let mut ambiguous = false;
                for &i in &grid[by + n * bz] {
                    if roots[i as usize] == c.0 {
                        continue;
                    }
                    match ray_crosses(p, &tris[i as usize]) {
                        Some(true) => *crossings.entry(roots[i as usize]).or_insert(0) += 1,
                        Some(false) => {}
                        None => ambiguous = true,
                    }
                }
                if !ambiguous {
                    break;
                }
                let k = 1.0 + attempt as f64;
                p = t[0] * 0.3191
                    + t[1] * 0.2473
                    + t[2] * 0.4336
                    + nudge * (1.0 + 0.61 * k)
                    + DVec3::new(0.0, 0.29e-7, -0.53e-7) * size * k;
            }
            crossings.values().filter(|&&k| k % 2 == 1).count()
        })
        .collect()
}

/// Whether the ray from `p` along +x crosses triangle `t`; `None` when it
/// passes too close to an edge to decide.
fn ray_crosses(p: DVec3, t: &[DVec3; 3]) -> Option<bool> {
    let (a, b, c) = (t[0], t[1], t[2]);
    let d = |u: DVec3, v: DVec3| (u.y - p.y) * (v.z - p.z) - (u.z - p.z) * (v.y - p.y);
    let (w0, w1, w2) = (d(b, c), d(c, a), d(a, b));
    let area = w0 + w1 + w2;
    if area.abs() < 1e-300 {
        return Some(false);
    }
    let eps = 1e-12 * ((b - a).length_squared() + (c - a).length_squared());
    if w0.abs() < eps || w1.abs() < eps || w2.abs() < eps {
        let inside_loose =
            (w0 >= -eps && w1 >= -eps && w2 >= -eps) || (w0 <= eps && w1 <= eps && w2 <= eps);
        return if inside_loose { None } else { Some(false) };
    }
    let inside = (w0 > 0.0 && w1 > 0.0 && w2 > 0.0) || (w0 < 0.0 && w1 < 0.0 && w2 < 0.0);
    if !inside {
        return Some(false);
    }
    let x = (w0 * a.x + w1 * b.x + w2 * c.x) / area;
    Some(x > p.x)
}

/// Invariant 5: each vertex lies within `tol` voxels of a (sub)voxel of every
/// label of the patches that use it.
fn check_fidelity(mesh: &InterfaceMesh, rv: &RefinedVolume, tol: f64) -> Check {
    let mut c = Check::new("vertices near their labels");
    let mut vertex_labels: Vec<(u32, LabelId)> = Vec::with_capacity(mesh.triangles.len() * 6);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let [a, b] = mesh.patches[mesh.triangle_patch[t] as usize].labels;
        for &v in tri {
            vertex_labels.push((v, a));
            vertex_labels.push((v, b));
        }
    }
    sort(&mut vertex_labels);
    vertex_labels.dedup();
    let geometry = mesh.geometry;
    let bad: Vec<(u32, LabelId, f64)> = vertex_labels
        .par_iter()
        .filter_map(|&(v, l)| {
            let p = geometry.physical_to_index(mesh.positions[v as usize]);
            let d = distance_to_label(rv, p, l, tol);
            (d > tol + 1e-9).then_some((v, l, d))
        })
        .collect();
    for (v, l, d) in bad {
        c.fail(|| {
            format!(
                "vertex {v} is {d:.3} voxels from label {}",
                mesh.label_value(l)
            )
        });
    }
    c
}

/// Distance (voxels, index space) from `p` to the nearest (sub)voxel of label
/// `l`, searched up to `max` (returns something larger when none is that close).
fn distance_to_label(rv: &RefinedVolume, p: DVec3, l: LabelId, max: f64) -> f64 {
    let s = rv.subdivision();
    // fast path: a (sub)voxel of label l touches p (vertices on the boundary)
    let q = (p + DVec3::splat(0.5)) * s as f64;
    let range = |v: f64| {
        let f = v.floor();
        if (v - f).abs() < 1e-9 {
            (f as i32 - 1, f as i32)
        } else {
            (f as i32, f as i32)
        }
    };
    let (rx, ry, rz) = (range(q.x), range(q.y), range(q.z));
    for z in rz.0..=rz.1 {
        for y in ry.0..=ry.1 {
            for x in rx.0..=rx.1 {
                if rv.fine_label([x, y, z]) == l {
                    return 0.0;
                }
            }
        }
    }
    let r = max.ceil().max(1.0) as i32;
    // voxel (x,y,z) spans [x - 0.5, x + 0.5]
    let centre = [p.x.round() as i32, p.y.round() as i32, p.z.round() as i32];
    let box_dist = |lo: DVec3, hi: DVec3| -> f64 { (lo - p).max(p - hi).max(DVec3::ZERO).length() };
    // candidate cells nearest first, so that the search stops early
    let mut cells: Vec<(f64, [i32; 3])> =
        Vec::with_capacity(((2 * r + 1) * (2 * r + 1) * (2 * r + 1)) as usize);
    for z in centre[2] - r..=centre[2] + r {
        for y in centre[1] - r..=centre[1] + r {
            for x in centre[0] - r..=centre[0] + r {
                let lo = DVec3::new(x as f64 - 0.5, y as f64 - 0.5, z as f64 - 0.5);
                let d = box_dist(lo, lo + DVec3::ONE);
                if d <= max + 1e-9 {
                    cells.push((d, [x, y, z]));
                }
            }
        }
    }
    cells.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best = f64::MAX;
    for (d, c) in cells {
        if d >= best {
            break;
        }
        match rv.subvoxels(c).filter(|_| rv.is_refined(c)) {
            None => {
                if rv.coarse_label(c) == l {
                    best = d;
                }
            }
            Some(sub) => {
                let h = 1.0 / s as f64;
                let lo = DVec3::new(c[0] as f64 - 0.5, c[1] as f64 - 0.5, c[2] as f64 - 0.5);
                for (i, &sl) in sub.iter().enumerate() {
                    if sl != l {
                        continue;
                    }
                    let q = [i as i32 % s, i as i32 / s % s, i as i32 / (s * s)];
                    let flo = lo + DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64) * h;
                    best = best.min(box_dist(flo, flo + DVec3::splat(h)));
                    if best == 0.0 {
                        return 0.0;
                    }
                }
            }
        }
    }
    best
}
