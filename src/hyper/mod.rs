//! STEVE iso-hypersurfaces of 4-D (time-varying) volumes, and the closed
//! surface at any time in between, after B. R. Schlei's *Space-Time-Enclosing
//! Volume Extraction*.
//!
//! [`hypersurface`] encloses the toxels (time-varying voxels) whose value is at
//! least the iso value with a closed, oriented hypersurface made of
//! tetrahedra in (x, y, z, t). It is VESTA one dimension up: one support point
//! per boundary cube (the 3-face between an active and an inactive toxel),
//! moved along its range vector to the interpolated iso value; one 2-face
//! (an N-cycle) per connected piece of the boundary around each grid edge; one
//! polyhedron per connected piece around each grid vertex, cut into
//! tetrahedra around face centres and a volume centre. [`Hypersurface::slice`]
//! cuts it at any time `T` into a closed, outward-oriented triangle surface
//! (an [`InterfaceMesh`](crate::mesh::InterfaceMesh), checked by [`crate::mesh::validate`]): the shape at
//! `T`, continuous in `T`, with no correspondence problem between frames.
//!
//! # The path table and the facts it gives
//!
//! The paper's Table I (192 vector paths: 32 boundary-cube centres × 2
//! orientations × 3 paths over 24 connectivity points) is missing from its
//! text; [`table`] derives it from the construction (the hypersurface is the
//! dual of the boundary 3-complex) and the tests verify it;
//! [`table::table_markdown`] prints it (`docs/hyper_table.md`). Cell numbering is
//! in [`cell`]; in the paper's style of global point ids, toxels are 0–15,
//! cube centres 16–47 and connectivity points 48–71 (`16 + cube`,
//! `48 + square`). The paper's examples, as counted by this implementation
//! (`tests/hyper.rs`):
//!
//! | configuration (one 2⁴ cell)                 | polyhedra | tetrahedra |
//! |---------------------------------------------|-----------|------------|
//! | one active toxel                            | tetrahedron | 1 per cell, 16 for the whole toxel |
//! | 8 active "past", 8 inactive "future" toxels | cube (six 4-cycles) | 24 |
//! | two toxels sharing a volume (a cube)        | triangular strut (two 3-, three 4-cycles) | 14 |
//! | two toxels sharing only a face, disconnect  | two tetrahedra | 2 |
//! | the same, connect                           | one: four 3-cycles, two 6-cycles | 16 |
//! | two toxels sharing only an edge or a vertex | two tetrahedra | 2 |
//!
//! Reading of the paper's counts: "a single toxel gives 16 tetrahedra" is the
//! whole toxel (one tetrahedron in each of the 16 cells around it — the
//! hypersurface is the 16-cell, the 4-D cross-polytope, as VESTA's voxel is an
//! octahedron); the other counts are per cell.
//!
//! # Topology
//!
//! Every triangle of the hypersurface lies in exactly two tetrahedra, with
//! opposite orientations, and the tetrahedra around every edge form one
//! cycle. The link of a support point or face centre is a sphere; the link
//! of a volume centre is the boundary of its polyhedron, which is a sphere
//! except in rare cells where the active toxels around the grid vertex form a
//! ring in its 3-sphere link (a toroidal polyhedron; 3,720 of them, 1,860 per
//! mode, over all 2 × 65,536 global-mode cell configurations): there the
//! hypersurface is a cone over a torus at one point, as the boundary of the
//! binary 4-D region genuinely is. [`HyperStats::higher_genus`] counts them.
//! Slices are unaffected: a cone point is one vertex, strictly between frames,
//! and a slice through it is handled like one through any vertex (below).
//!
//! # Orientation
//!
//! A tetrahedron `(p0, p1, p2, p3)` is oriented so that `det[p1 − p0, p2 − p0,
//! p3 − p0, w] > 0` for `w` pointing out of the enclosed region (from ≥ iso to
//! < iso), in index space. In physical space the spatial affine may mirror;
//! the writers swap two corners then, as the 3-D writers flip triangles.
//!
//! # Slices
//!
//! The slice at time `T` cuts every tetrahedron whose vertices lie on both
//! sides; each cut point is identified by its hypersurface edge, so the slice
//! is a closed surface over one vertex pool. **At a frame's own time the slice
//! is that frame's VESTA surface** (same mode, H decomposition): spatial cubes
//! of frame `k` have their support points at `t = k` exactly, with the same
//! positions VESTA computes; the 2-faces at `t = k` are exactly VESTA's cycles
//! of frame `k` (the cycles around the grid edges along t); every other
//! vertex lies strictly between frames. So the slice at `t = k` is VESTA's
//! surface of frame `k` with every N-cycle (N > 3) cut into a fan around its
//! mean point — `septa iso --decompose h` — vertex for vertex (face centres up
//! to rounding), provided VESTA's H does not fall back to L for a degenerate
//! fan. At any time, a hypersurface vertex within 10⁻⁶ frames of `T` is the
//! cut point itself (the edges from it to earlier vertices all meet the slice
//! there). If that pinches two sheets together — a topology change exactly
//! at `T`, where the exact level set is not a manifold — the cut points
//! around that vertex are taken 10⁻³ frames earlier instead
//! ([`TimeSlice::separated`] counts such vertices; never at frame times).
//!
//! Files of this module:
//! - `cell.rs`: numbering of the 2⁴ cell (toxels, cubes, squares, half-edges);
//! - `table.rs`: the vector-path table, the cycle tracer and the polyhedra;
//! - `grid.rs`: activity bits, boundary-cube ids, support points;
//! - `extract.rs`: the parallel march and the decomposition into tetrahedra;
//! - `slice.rs`: time slices;
//! - `check.rs`: the closed-oriented-3-manifold check of a tetrahedral mesh;
//! - `fireball.rs`: a generated 4-D example (a blob splitting in two);
//! - `ply.rs`: the hypersurface PLY writer and reader.
//!
//! ```
//! use septa::hyper::{HyperOptions, hypersurface};
//! use septa::volume::Geometry;
//! // one bright toxel in a dark 3×3×3×3 volume
//! let mut v = vec![0u8; 81];
//! v[40] = 200;
//! let h = hypersurface(&v, [3, 3, 3, 3], Geometry::identity(), 1.0, &HyperOptions::new(100.0)).unwrap();
//! assert_eq!((h.points.len(), h.tets.len()), (8, 16)); // the 16-cell
//! let s = h.slice(1.0).unwrap(); // the toxel's frame: VESTA's octahedron
//! assert_eq!((s.mesh.vertex_count(), s.mesh.triangle_count()), (6, 8));
//! ```

pub mod cell;
pub mod check;
mod extract;
pub mod fireball;
mod grid;
pub mod ply;
pub mod slice;
pub mod table;

pub use check::{ManifoldReport, check_closed_manifold};
pub use slice::TimeSlice;

use std::time::Instant;

use hashbrown::HashMap;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::io::{Image, Samples};
use crate::iso::{Mode, Scalar};
use crate::volume::Geometry;

/// Options of [`hypersurface`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HyperOptions {
    /// Toxels with value ≥ `iso` are inside.
    pub iso: f64,
    /// How points of ambiguity (two active toxels sharing only a face) are
    /// resolved; mixed joins where the mean of the four toxels is ≥ iso.
    pub mode: Mode,
    /// Move support points along their range vectors to the interpolated iso
    /// value (off: cube centres, the binary STEVE hypersurface).
    pub displace: bool,
}

impl HyperOptions {
    /// Mixed mode, displaced points.
    pub fn new(iso: f64) -> Self {
        HyperOptions {
            iso,
            mode: Mode::Mixed,
            displace: true,
        }
    }

    /// An error if the options cannot be used (a NaN iso value).
    pub fn check(&self) -> Result<()> {
        if self.iso.is_nan() {
            return Err(Error::invalid("the iso value is NaN"));
        }
        Ok(())
    }
}

/// What a hypersurface vertex is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[repr(u8)]
pub enum PointKind {
    /// A boundary cube's (displaced) centre.
    Support = 0,
    /// The mean point of an N-cycle with N > 3.
    FaceCentre = 1,
    /// The volume centre of a polyhedron.
    VolumeCentre = 2,
}

/// Counts and timing of one extraction.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct HyperStats {
    /// Toxels with value ≥ iso.
    pub active_toxels: u64,
    /// Support points: one per boundary cube.
    pub support_points: usize,
    pub face_centres: usize,
    pub volume_centres: usize,
    /// All vertices.
    pub points: usize,
    pub tetrahedra: usize,
    /// Grid vertices whose cell has boundary cubes.
    pub cells: u64,
    /// Polyhedra (3-cells), and how many of them are single tetrahedra.
    pub polyhedra: u64,
    pub tetrahedron_polyhedra: u64,
    /// Polyhedra bounded by a torus or higher genus (see the module docs).
    pub higher_genus: u64,
    /// Points of ambiguity, counted per cell.
    pub ambiguities: u64,
    /// `cycles_by_length[n]`: number of 2-faces with n support points.
    pub cycles_by_length: [u64; 13],
    /// Extraction time in seconds (volume in memory to tetrahedra in memory).
    pub seconds: f64,
}

/// An iso-hypersurface in index space (x, y, z voxel indices, t frame index).
#[derive(Clone, Debug)]
pub struct Hypersurface {
    /// Vertices: support points, then face centres, then volume centres.
    pub points: Vec<[f64; 4]>,
    /// Kind of each vertex.
    pub kinds: Vec<PointKind>,
    /// Oriented tetrahedra (see the module docs for the sign), in index space.
    pub tets: Vec<[u32; 4]>,
    /// Spatial geometry (index → LPS mm).
    pub geometry: Geometry,
    /// Physical time per frame (1 when the input gives none).
    pub time_step: f64,
    /// Number of frames.
    pub frames: usize,
    pub stats: HyperStats,
}

impl Hypersurface {
    /// Vertices in physical space: x, y, z in LPS mm, t = frame × time step.
    pub fn physical_points(&self) -> Vec<[f64; 4]> {
        self.points
            .par_iter()
            .map(|p| {
                let x = self
                    .geometry
                    .index_to_physical(glam::DVec3::new(p[0], p[1], p[2]));
                [x.x, x.y, x.z, p[3] * self.time_step]
            })
            .collect()
    }

    /// Tetrahedra oriented in physical space (two corners swapped when the
    /// spatial affine mirrors).
    pub fn physical_tets(&self) -> Vec<[u32; 4]> {
        if self.geometry.is_mirroring() {
            self.tets.iter().map(|t| [t[0], t[1], t[3], t[2]]).collect()
        } else {
            self.tets.clone()
        }
    }

    /// Physical time range the hypersurface spans (frame −½ to last + ½ at
    /// most: outside the frames everything is inactive).
    pub fn time_range(&self) -> Option<(f64, f64)> {
        let (lo, hi) = self
            .points
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p[3]), hi.max(p[3]))
            });
        (lo <= hi).then_some((lo * self.time_step, hi * self.time_step))
    }
}

impl Hypersurface {
    /// Another field given on the same toxels (x fastest, then y, z, t; the
    /// extents of the volume the hypersurface came from) interpolated onto
    /// every vertex, as the paper's section IV.B suggests: at a support point
    /// linearly between the two toxels of its range vector (the toxel inside
    /// the volume where the other is outside), at a face centre the mean of its
    /// cycle's support points, at a volume centre the mean over its faces (a
    /// 3-cycle by the mean of its points) — the same averages that place them.
    /// Face and volume centres are found through the tetrahedra around them.
    pub fn field_values<T: Scalar>(&self, field: &[T], dims: [usize; 4]) -> Result<Vec<f64>> {
        let n = dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
        if n != Some(field.len()) {
            return Err(Error::invalid(format!(
                "the field holds {} samples for extents {dims:?}",
                field.len()
            )));
        }
        let at = |c: [i64; 4]| -> Option<f64> {
            let inside = (0..4).all(|a| c[a] >= 0 && (c[a] as usize) < dims[a]);
            inside.then(|| {
                let i = c[0] as usize
                    + dims[0]
                        * (c[1] as usize + dims[1] * (c[2] as usize + dims[2] * c[3] as usize));
                field[i].to_f64()
            })
        };
        let mut values = vec![f64::NAN; self.points.len()];
        for (i, p) in self.points.iter().enumerate() {
            if self.kinds[i] != PointKind::Support {
                continue;
            }
            // the range-vector axis is the one coordinate that is not whole
            let Some(a) = (0..4).find(|&a| p[a].fract() != 0.0) else {
                continue;
            };
            let lo = p[a].floor();
            let s = p[a] - lo;
            let mut c: [i64; 4] = p.map(|x| x.round() as i64);
            c[a] = lo as i64;
            let vlo = at(c);
            c[a] += 1;
            let vhi = at(c);
            values[i] = match (vlo, vhi) {
                (Some(x), Some(y)) => x + (y - x) * s,
                (Some(x), None) | (None, Some(x)) => x,
                (None, None) => f64::NAN,
            };
        }
        // tetrahedra around each face and volume centre
        let mut around: Vec<Vec<u32>> = vec![Vec::new(); self.points.len()];
        for (t, tet) in self.tets.iter().enumerate() {
            for &v in tet {
                if self.kinds[v as usize] != PointKind::Support {
                    around[v as usize].push(t as u32);
                }
            }
        }
        let kind = |v: u32| self.kinds[v as usize];
        for (v, ts) in around.iter().enumerate() {
            if kind(v as u32) != PointKind::FaceCentre {
                continue;
            }
            let mut members: Vec<u32> = ts
                .iter()
                .flat_map(|&t| self.tets[t as usize])
                .filter(|&u| kind(u) == PointKind::Support)
                .collect();
            members.sort_unstable();
            members.dedup();
            values[v] =
                members.iter().map(|&u| values[u as usize]).sum::<f64>() / members.len() as f64;
        }
        for (v, ts) in around.iter().enumerate() {
            if kind(v as u32) != PointKind::VolumeCentre {
                continue;
            }
            let mut faces: Vec<u32> = Vec::new();
            let mut sum = 0.0;
            let mut count = 0usize;
            for &t in ts {
                let tet = self.tets[t as usize];
                match tet.iter().find(|&&u| kind(u) == PointKind::FaceCentre) {
                    Some(&f) => faces.push(f),
                    None => {
                        let tri: Vec<u32> =
                            tet.iter().copied().filter(|&u| u as usize != v).collect();
                        sum += tri.iter().map(|&u| values[u as usize]).sum::<f64>() / 3.0;
                        count += 1;
                    }
                }
            }
            faces.sort_unstable();
            faces.dedup();
            sum += faces.iter().map(|&f| values[f as usize]).sum::<f64>();
            count += faces.len();
            values[v] = sum / count as f64;
        }
        Ok(values)
    }
}

/// The STEVE iso-hypersurface of a 4-D volume: samples x fastest, then y, z,
/// t; `dims` = (x, y, z, frames); `geometry` maps voxel indices to LPS mm and
/// `time_step` frames to physical time. Deterministic for any thread count.
pub fn hypersurface<T: Scalar>(
    values: &[T],
    dims: [usize; 4],
    geometry: Geometry,
    time_step: f64,
    opts: &HyperOptions,
) -> Result<Hypersurface> {
    let start = Instant::now();
    opts.check()?;
    if dims.contains(&0) {
        return Err(Error::invalid(format!(
            "extents {dims:?}: every extent must be at least 1"
        )));
    }
    if !(time_step.is_finite() && time_step > 0.0) {
        return Err(Error::invalid(format!(
            "time step {time_step}: it must be a positive number"
        )));
    }
    let n = dims
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .filter(|&n| n == values.len());
    if n.is_none() {
        return Err(Error::invalid(format!(
            "{} samples for {} × {} × {} voxels × {} frames",
            values.len(),
            dims[0],
            dims[1],
            dims[2],
            dims[3]
        )));
    }
    let padded = dims
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d + 2));
    if padded.is_none_or(|p| p >= 1 << 40) {
        return Err(Error::invalid("the 4-D volume is too large"));
    }
    let grid = grid::Grid::new(dims);
    let act = grid::Activity::new(values, grid, opts.iso);
    let cubes = grid::Cubes::new(&act);
    if cubes.total >= extract::FACE as u64 {
        return Err(Error::invalid(format!(
            "{} boundary cubes: more than septa's limit of 2^30",
            cubes.total
        )));
    }
    let points = grid::support_points(values, &act, &cubes, opts.iso, opts.displace);
    let march = extract::March {
        values,
        act: &act,
        cubes: &cubes,
        points: &points,
        iso: opts.iso,
        mode: opts.mode,
    };
    let parts = march.run();
    let mut h = assemble(points, parts, act.active)?;
    h.geometry = geometry;
    h.time_step = time_step;
    h.frames = dims[3];
    h.stats.seconds = start.elapsed().as_secs_f64();
    Ok(h)
}

/// Merges the parts: dense ids for face centres (in the order their owners
/// appear) and volume centres, then the tetrahedra over them.
fn assemble(
    mut points: Vec<[f64; 4]>,
    parts: Vec<extract::Part>,
    active: u64,
) -> Result<Hypersurface> {
    let n_support = points.len();
    let mut counts = extract::Counts::default();
    let mut face_ids: HashMap<(u64, u32), u32> = HashMap::new();
    for p in &parts {
        counts.merge(&p.counts);
        for &(local, pos) in &p.face_pos {
            let key = p.face_keys[local as usize];
            let next = points.len() as u32;
            face_ids.entry(key).or_insert_with(|| {
                points.push(pos);
                next
            });
        }
    }
    let n_faces = points.len() - n_support;
    let mut vol_base = Vec::with_capacity(parts.len());
    for p in &parts {
        vol_base.push(points.len() as u32);
        points.extend_from_slice(&p.volumes);
    }
    if points.len() >= extract::FACE as usize {
        return Err(Error::invalid("more than 2^30 hypersurface vertices"));
    }
    let mut tets = Vec::with_capacity(parts.iter().map(|p| p.tets.len()).sum());
    for (p, &vb) in parts.iter().zip(&vol_base) {
        let faces: Vec<u32> = p
            .face_keys
            .iter()
            .map(|k| {
                face_ids.get(k).copied().ok_or_else(|| {
                    Error::invalid("internal error: a face centre without its owner cell")
                })
            })
            .collect::<Result<_>>()?;
        for t in &p.tets {
            tets.push(t.map(|v| match v & extract::TAG {
                0 => v,
                extract::FACE => faces[(v & !extract::TAG) as usize],
                _ => vb + (v & !extract::TAG),
            }));
        }
    }
    let n_vol = points.len() - n_support - n_faces;
    let mut kinds = vec![PointKind::Support; n_support];
    kinds.extend(std::iter::repeat_n(PointKind::FaceCentre, n_faces));
    kinds.extend(std::iter::repeat_n(PointKind::VolumeCentre, n_vol));
    let stats = HyperStats {
        active_toxels: active,
        support_points: n_support,
        face_centres: n_faces,
        volume_centres: n_vol,
        points: points.len(),
        tetrahedra: tets.len(),
        cells: counts.cells,
        polyhedra: counts.polyhedra,
        tetrahedron_polyhedra: counts.tetrahedra_polyhedra,
        higher_genus: counts.higher_genus,
        ambiguities: counts.ambiguities,
        cycles_by_length: counts.cycles_by_length,
        seconds: 0.0,
    };
    Ok(Hypersurface {
        points,
        kinds,
        tets,
        geometry: Geometry::identity(),
        time_step: 1.0,
        frames: 0,
        stats,
    })
}

/// [`hypersurface`] of a 4-D image as read by [`crate::io::read_image`] (any
/// sample type); an error naming the file for a 3-D one. The time step is the
/// file's (NIfTI `pixdim[4]`), else 1, unless `time_step` overrides it.
pub fn hypersurface_image(
    image: &Image,
    time_step: Option<f64>,
    opts: &HyperOptions,
) -> Result<Hypersurface> {
    let d = &image.dims;
    if d.len() < 4 || d[3] < 2 || d[4..].iter().any(|&n| n > 1) {
        let what = if d.len() > 4 && d[4..].iter().any(|&n| n > 1) {
            format!("has {} axes {d:?}", d.len())
        } else {
            format!("is 3-D ({} × {} × {})", d[0], d[1], d[2])
        };
        return Err(Error::input(
            &image.path,
            format!(
                "{what}: `septa hyper` needs a 4-D volume (x, y, z, t) with at least 2 frames, or several 3-D volumes given with --frames"
            ),
        ));
    }
    let dt = time_step.or(image.time_step.map(f64::abs)).unwrap_or(1.0);
    let dims = [d[0], d[1], d[2], d[3]];
    let g = image.geometry;
    let r = match &image.samples {
        Samples::U8(v) => hypersurface(v, dims, g, dt, opts),
        Samples::I8(v) => hypersurface(v, dims, g, dt, opts),
        Samples::U16(v) => hypersurface(v, dims, g, dt, opts),
        Samples::I16(v) => hypersurface(v, dims, g, dt, opts),
        Samples::U32(v) => hypersurface(v, dims, g, dt, opts),
        Samples::I32(v) => hypersurface(v, dims, g, dt, opts),
        Samples::U64(v) => hypersurface(v, dims, g, dt, opts),
        Samples::I64(v) => hypersurface(v, dims, g, dt, opts),
        Samples::F32(v) => hypersurface(v, dims, g, dt, opts),
        Samples::F64(v) => hypersurface(v, dims, g, dt, opts),
    };
    r.map_err(|e| match e {
        Error::Invalid(m) => Error::input(&image.path, m),
        other => other,
    })
}

/// Stacks 3-D images (one per frame, in order) into one 4-D sample array:
/// every frame must have the same grid; the geometry is the first frame's
/// (an error if another frame's affine differs by more than 10⁻⁶, relative).
pub fn stack_frames(frames: &[Image]) -> Result<(Vec<f64>, [usize; 4], Geometry)> {
    let Some(first) = frames.first() else {
        return Err(Error::invalid("no frames given"));
    };
    if frames.len() < 2 {
        return Err(Error::input(
            &first.path,
            "is the only frame: a hypersurface needs at least 2 frames",
        ));
    }
    let d0 = first.dims3()?;
    let mut values = Vec::with_capacity(d0.len() * frames.len());
    for f in frames {
        let d = f.dims3()?;
        if d != d0 {
            return Err(Error::input(
                &f.path,
                format!(
                    "has {} × {} × {} voxels but the first frame {} has {} × {} × {}: all frames must have the same grid",
                    d.nx,
                    d.ny,
                    d.nz,
                    first.path.display(),
                    d0.nx,
                    d0.ny,
                    d0.nz
                ),
            ));
        }
        let a = f.geometry.affine();
        let b = first.geometry.affine();
        let differs = a
            .iter()
            .flatten()
            .zip(b.iter().flatten())
            .any(|(x, y)| (x - y).abs() > 1e-6 * (1.0 + y.abs()));
        if differs {
            return Err(Error::input(
                &f.path,
                format!(
                    "has a different geometry (affine) than the first frame {}: frames must be on the same grid in space",
                    first.path.display()
                ),
            ));
        }
        if f.samples.len() != d.len() {
            return Err(Error::input(
                &f.path,
                format!("holds {} samples for {} voxels", f.samples.len(), d.len()),
            ));
        }
        values.extend(f.to_f64());
    }
    Ok((values, [d0.nx, d0.ny, d0.nz, frames.len()], first.geometry))
}
