//! VESTA iso-surfaces of grayscale volumes (their 2-D analogue, DICONEX, is
//! [`crate::contour`]).
//!
//! [`iso_surface`] encloses the voxels whose value is at least the iso value
//! with a closed, outward-oriented triangle mesh, after B. R. Schlei's VESTA:
//! one support point per boundary voxel face, one N-cycle per connected piece
//! of the boundary around each grid vertex, each cycle cut into triangles.
//! VESTA's six surface types are the three [`Mode`]s (how two active voxels
//! that share only an edge — a *point of ambiguity* — are treated) times the
//! two [`Decompose`] modes (L: triangles on the cycle's own points; H: a fan
//! around the cycle's average point). With displacement (the default), each
//! support point moves along its range vector — from the active voxel centre
//! to the inactive one — to where linear interpolation meets the iso value.
//!
//! The result is an [`InterfaceMesh`] with two labels: `0` = inside (voxels ≥
//! iso) and `1` = outside, one patch `{0, 1}` whose normals point from inside
//! to outside, so septa's validator and writers apply unchanged. Everything
//! outside the volume counts as inactive, so every surface closes.
//!
//! Files of this module:
//! - `cpu.rs`: run-time dispatch of the hot loops to popcnt/AVX2 code;
//! - `table.rs`: the 2×2×2 cell table (cycles, L triangulations, the 14 types);
//! - `grid.rs`: activity bits, boundary-face ids (rank bitsets), support points;
//! - `surface.rs`: the parallel march over grid vertices;
//! - `stats.rs`: N-cycle statistics (the paper's Tables II–IV).
//!
//! The iso value's place between two samples, `interpolation_fraction`, is
//! shared with DICONEX ([`crate::contour`]) and STEVE ([`crate::hyper`]), so
//! their points agree with VESTA's bit for bit.
//!
//! ```
//! use septa::iso::{iso_surface, IsoOptions, Mode};
//! use septa::volume::{Dims, Geometry};
//! // one bright voxel in a dark 3×3×3 volume
//! let mut v = vec![0u8; 27];
//! v[13] = 200;
//! let opts = IsoOptions { mode: Mode::Mixed, ..IsoOptions::new(100.0) };
//! let s = iso_surface(&v, Dims::new(3, 3, 3).unwrap(), Geometry::identity(), &opts).unwrap();
//! assert_eq!((s.mesh.vertex_count(), s.mesh.triangle_count()), (6, 8)); // an octahedron
//! assert_eq!(s.stats.cycles_by_length[3], 8);
//! ```

#[cfg(target_arch = "x86_64")]
mod cpu;
mod grid;
mod stats;
mod surface;
mod table;

pub use crate::extract::Decompose;
pub(crate) use grid::interpolation_fraction;
pub use stats::IsoStats;
pub use table::{CycleType, cycle_types};

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::io::{Image, Samples};
use crate::mesh::{InterfaceMesh, LabelInfo, Patch};
use crate::volume::{Dims, Geometry};

/// How points of ambiguity are resolved (two active voxels sharing only an
/// edge, or two active pixels sharing only a corner in 2-D).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Kept apart everywhere (VESTA's global "disconnect").
    Disconnect,
    /// Joined everywhere (global "connect").
    Connect,
    /// Joined where the mean of the four voxels around the edge (pixels around
    /// the corner) is at least the iso value.
    #[default]
    Mixed,
}

impl std::str::FromStr for Mode {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "disconnect" => Ok(Mode::Disconnect),
            "connect" => Ok(Mode::Connect),
            "mixed" => Ok(Mode::Mixed),
            other => Err(Error::invalid(format!(
                "unknown mode `{other}` (disconnect, connect or mixed)"
            ))),
        }
    }
}

impl Mode {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Disconnect => "disconnect",
            Mode::Connect => "connect",
            Mode::Mixed => "mixed",
        }
    }
}

/// Options of [`iso_surface`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsoOptions {
    /// Voxels with value ≥ `iso` are inside.
    pub iso: f64,
    pub mode: Mode,
    pub decompose: Decompose,
    /// Move support points along their range vectors to the interpolated iso
    /// value (off: voxel face centres, the binary VESTA surface).
    pub displace: bool,
}

impl IsoOptions {
    /// An error if the options cannot be used (a NaN iso value).
    pub fn check(&self) -> Result<()> {
        if self.iso.is_nan() {
            return Err(Error::invalid("the iso value is NaN"));
        }
        Ok(())
    }

    /// Mixed mode, L decomposition, displaced points.
    pub fn new(iso: f64) -> Self {
        IsoOptions {
            iso,
            mode: Mode::Mixed,
            decompose: Decompose::L,
            displace: true,
        }
    }
}

/// An iso-surface and its statistics.
#[derive(Clone, Debug)]
pub struct IsoSurface {
    /// Labels 0 = inside, 1 = outside; one patch, normals pointing outward.
    pub mesh: InterfaceMesh,
    pub stats: IsoStats,
}

/// Sample types the iso commands accept.
pub trait Scalar: Copy + Send + Sync + PartialOrd {
    fn to_f64(self) -> f64;

    /// The smallest value `c` of the type with `c.to_f64() >= iso` (`None` if
    /// there is none), so that `v >= c` ⇔ `v.to_f64() >= iso` for every `v`:
    /// the activity pass compares in the samples' own type, which vectorizes.
    fn cut(iso: f64) -> Option<Self>;
}

macro_rules! scalar_int {
    ($($t:ty),*) => {$(
        impl Scalar for $t {
            #[inline]
            fn to_f64(self) -> f64 {
                self as f64
            }

            fn cut(iso: f64) -> Option<Self> {
                if iso <= <$t>::MIN as f64 {
                    return Some(<$t>::MIN);
                }
                if iso.is_nan() || iso > <$t>::MAX as f64 {
                    return None;
                }
                // ceil(iso) is exact below 2^64 (saturating at MAX); step down
                // where 64-bit values round up to iso
                let mut c = iso.ceil() as $t;
                while c > <$t>::MIN && ((c - 1) as f64) >= iso {
                    c -= 1;
                }
                Some(c)
            }
        }
    )*};
}
scalar_int!(u8, i8, u16, i16, u32, i32, u64, i64);

impl Scalar for f64 {
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }

    fn cut(iso: f64) -> Option<Self> {
        (!iso.is_nan()).then_some(iso)
    }
}

impl Scalar for f32 {
    #[inline]
    fn to_f64(self) -> f64 {
        self as f64
    }

    fn cut(iso: f64) -> Option<Self> {
        if iso.is_nan() {
            return None;
        }
        // round to nearest, then up to the next f32 if that fell below iso
        let c = iso as f32;
        if (c as f64) >= iso {
            return Some(c);
        }
        Some(if c == 0.0 {
            f32::from_bits(1)
        } else if c > 0.0 {
            f32::from_bits(c.to_bits() + 1)
        } else {
            f32::from_bits(c.to_bits() - 1)
        })
    }
}

/// The VESTA iso-surface of a volume: samples x fastest, `geometry` maps voxel
/// indices to LPS millimetres. Deterministic for any number of threads.
pub fn iso_surface<T: Scalar>(
    values: &[T],
    dims: Dims,
    geometry: Geometry,
    opts: &IsoOptions,
) -> Result<IsoSurface> {
    let start = Instant::now();
    opts.check()?;
    if values.len() != dims.len() {
        return Err(Error::invalid(format!(
            "{} samples for {} × {} × {} voxels",
            values.len(),
            dims.nx,
            dims.ny,
            dims.nz
        )));
    }
    // the table (built once per process) is independent of the volume
    let (_, act) = rayon::join(table::Table::get, || {
        grid::Activity::new(values, dims, opts.iso)
    });
    let faces = grid::Faces::new(&act);
    if faces.total >= surface::CENTROID as u64 {
        return Err(Error::invalid(format!(
            "{} boundary faces: more than septa's limit of 2^31",
            faces.total
        )));
    }
    // L reads no point back: place them in physical space at once; H
    // averages them in index space first
    let physical = opts.decompose == Decompose::L;
    let points = if physical {
        let place = |p| geometry.index_to_physical(p);
        grid::support_points(values, &act, &faces, opts.iso, opts.displace, place)
    } else {
        grid::support_points(values, &act, &faces, opts.iso, opts.displace, |p| p)
    };
    let march = surface::March {
        values,
        act: &act,
        faces: &faces,
        points: &points,
        iso: opts.iso,
        mode: opts.mode,
        decompose: opts.decompose,
    };
    let (triangles, parts) = march.run();
    let mut s = assemble(points, physical, triangles, parts, geometry, act.active);
    s.stats.seconds = start.elapsed().as_secs_f64();
    Ok(s)
}

/// [`iso_surface`] of an image as read by [`crate::io::read_image`], any
/// sample type; an error for 4-D images.
pub fn iso_surface_image(image: &Image, opts: &IsoOptions) -> Result<IsoSurface> {
    let dims = image.dims3()?;
    let g = image.geometry;
    let r = match &image.samples {
        Samples::U8(v) => iso_surface(v, dims, g, opts),
        Samples::I8(v) => iso_surface(v, dims, g, opts),
        Samples::U16(v) => iso_surface(v, dims, g, opts),
        Samples::I16(v) => iso_surface(v, dims, g, opts),
        Samples::U32(v) => iso_surface(v, dims, g, opts),
        Samples::I32(v) => iso_surface(v, dims, g, opts),
        Samples::U64(v) => iso_surface(v, dims, g, opts),
        Samples::I64(v) => iso_surface(v, dims, g, opts),
        Samples::F32(v) => iso_surface(v, dims, g, opts),
        Samples::F64(v) => iso_surface(v, dims, g, opts),
    };
    r.map_err(|e| match e {
        Error::Invalid(m) => Error::input(&image.path, m),
        other => other,
    })
}

/// The two labels of an iso-surface mesh.
pub fn iso_labels() -> Vec<LabelInfo> {
    vec![
        LabelInfo {
            value: 0,
            name: "inside".into(),
        },
        LabelInfo {
            value: 1,
            name: "outside".into(),
        },
    ]
}

/// Merges the parts into one mesh in physical space (`physical`: the points
/// are there already, and there are no centroids). `triangles`: of all parts,
/// in order, as the march left them.
fn assemble(
    mut points: Vec<DVec3>,
    physical: bool,
    mut triangles: Vec<[u32; 3]>,
    parts: Vec<surface::Part>,
    geometry: Geometry,
    active: u64,
) -> IsoSurface {
    let n_faces = points.len() as u32;
    let mut counts = stats::TypeCounts::default();
    let mut n_centroids = 0u32;
    let mut cbases = Vec::with_capacity(parts.len());
    for p in &parts {
        counts.merge(&p.counts);
        cbases.push(n_faces + n_centroids);
        n_centroids += p.centroids.len() as u32;
    }
    let mirrored = geometry.is_mirroring();
    if mirrored || n_centroids > 0 {
        // centroid references to point indices, orientation for mirroring
        // geometries: in place, the parts' ranges in parallel
        let mut slices = Vec::with_capacity(parts.len());
        let mut rest: &mut [[u32; 3]] = &mut triangles;
        for p in &parts {
            let (head, tail) = rest.split_at_mut(p.tris);
            slices.push(head);
            rest = tail;
        }
        slices
            .into_par_iter()
            .zip(&cbases)
            .for_each(|(tris, &cbase)| {
                for o in tris.iter_mut() {
                    let t = o.map(|v| {
                        if v & surface::CENTROID != 0 {
                            cbase + (v & !surface::CENTROID)
                        } else {
                            v
                        }
                    });
                    *o = if mirrored { [t[0], t[2], t[1]] } else { t };
                }
            });
    }
    for p in &parts {
        points.extend_from_slice(&p.centroids);
    }
    let positions: Vec<DVec3> = if physical {
        debug_assert_eq!(n_centroids, 0);
        points
    } else {
        points
            .par_iter()
            .map(|&p| geometry.index_to_physical(p))
            .collect()
    };
    let mut stats = IsoStats::from_counts(&counts);
    stats.active_voxels = active;
    stats.support_points = n_faces as usize;
    stats.centroids = n_centroids as usize;
    stats.points = positions.len();
    stats.triangles = triangles.len();
    let patches = if triangles.is_empty() {
        Vec::new()
    } else {
        vec![Patch { labels: [0, 1] }]
    };
    let mesh = InterfaceMesh {
        positions,
        triangle_patch: vec![0; triangles.len()],
        triangles,
        patches,
        junctions: Vec::new(),
        labels: iso_labels(),
        geometry,
    };
    IsoSurface { mesh, stats }
}
