//! What an extraction will cost, known before it starts.
//!
//! The work of [`crate::preprocess`] and [`crate::extract`] grows with the
//! voxel faces between different labels (each becomes a point of the
//! surface) and with the voxels around critical elements (each is refined
//! into 5³ or 7³ subvoxels, whose faces are extracted too). A label map has
//! few of either; a grayscale image taken for one (a 0–255 probability map:
//! 256 "labels", nearly every face between two of them, critical elements
//! everywhere) has them all, and would need tens of gigabytes. One pass over
//! the volume counts them ([`estimate`]); [`Work::bytes`] turns the counts into
//! memory, with per-item costs measured on septa's own runs; and
//! [`Work::looks_like_intensity`] says when the volume looks like an image
//! rather than a segmentation.

use rayon::prelude::*;

use crate::star::is_critical_mask;
use crate::volume::LabelVolume;

/// Counts that drive the cost of preprocessing and extraction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Work {
    /// Voxels.
    pub voxels: u64,
    /// Distinct labels.
    pub labels: u64,
    /// Faces between two voxels of different labels (inside the volume).
    pub boundary_faces: u64,
    /// Grid edges critical for some label (two diagonal voxels of it among four).
    pub critical_edges: u64,
    /// Inner grid vertices critical for some label.
    pub critical_vertices: u64,
    /// Subdivision of refined voxels: 5, or 7 with separation constraints.
    pub subdivision: u64,
}

/// Bytes per voxel: the label ids, their padded copy, the voxel counts and
/// the refined volume's coarse grid; and
const BYTES_PER_VOXEL: u64 = 12;
/// bytes per boundary face, through extraction and validation. Measured with
/// `--no-remesh`: a 160³ cube without critical elements (4.1 M voxels,
/// 38 k faces) peaks at 38 MB, less than these give; the 32³ to 128³
/// phantoms and the k-means head stay below the estimate too.
const BYTES_PER_FACE: u64 = 450;
/// Bytes per subvoxel of a refined voxel, its faces extracted. Measured
/// peaks of the whole `--no-remesh` command (2026-12-04), less the voxel
/// and face terms: 17 B on the k-means head (15.6 M subvoxels, 433 MB), 49
/// to 52 B on 28³ to 48³ pure noise with 6 labels (where every refined voxel
/// is cut up; 826 MB on 48³). The estimate is an upper bound: 1.3 GB for
/// that noise, 1.4 GB for the head. (It was 600 B before the parts were
/// packed and freed memory handed back, and refused the head on machines
/// with less than 9.5 GB free.)
const BYTES_PER_SUBVOXEL: u64 = 80;
/// Bytes per subvoxel while preprocessing (the sparse subvoxel labels and
/// the critical elements; measured: `inspect` on the k-means head, 125 k
/// refined voxels, peaks at 107 MB).
const PREPROCESS_BYTES_PER_SUBVOXEL: u64 = 8;
/// Bytes per triangle while remeshing (the larger of the extraction's and
/// the remeshed count): the extraction, its smoothed copy, the remeshed
/// patches and their search structures (measured peaks: 350 B on the heart
/// phantom, 550 to 590 B on the 128³ phantom and a 32³ noise volume).
const REMESH_BYTES_PER_TRIANGLE: u64 = 700;

impl Work {
    /// Voxels refined at most: each critical edge refines the 4 voxels around
    /// it, each critical vertex its 8 (no more than the volume has).
    pub fn refined_upper_bound(&self) -> u64 {
        (4 * self.critical_edges + 8 * self.critical_vertices).min(self.voxels)
    }

    fn subvoxels(&self, refined: u64) -> u64 {
        refined.saturating_mul(self.subdivision.pow(3))
    }

    /// Estimated peak memory of preprocessing, in bytes (refined voxels at
    /// their upper bound).
    pub fn preprocess_bytes(&self) -> u64 {
        self.voxels * BYTES_PER_VOXEL
            + self.subvoxels(self.refined_upper_bound()) * PREPROCESS_BYTES_PER_SUBVOXEL
    }

    /// Estimated peak memory of extracting with `refined` voxels refined (as
    /// preprocessing reports).
    pub fn extraction_bytes(&self, refined: u64) -> u64 {
        self.voxels * BYTES_PER_VOXEL
            + self.boundary_faces * BYTES_PER_FACE
            + self.subvoxels(refined) * BYTES_PER_SUBVOXEL
    }

    /// Estimated peak memory of remeshing an extraction of `triangles`
    /// triangles and `area_mm2` to edges of `target_edge` mm.
    pub fn remesh_bytes(&self, triangles: u64, area_mm2: f64, target_edge: f64) -> u64 {
        // an equilateral triangle of side L covers √3/4 L²
        let remeshed = area_mm2 / (0.433 * target_edge * target_edge);
        let remeshed = if remeshed.is_finite() {
            remeshed.min(1e15) as u64
        } else {
            u64::MAX / 1024
        };
        self.voxels * BYTES_PER_VOXEL
            + triangles
                .max(remeshed)
                .saturating_mul(REMESH_BYTES_PER_TRIANGLE)
    }

    /// [`Work::extraction_bytes`] before preprocessing: refined voxels at
    /// their upper bound.
    pub fn bytes(&self) -> u64 {
        self.extraction_bytes(self.refined_upper_bound())
    }

    /// Share of the inner voxel faces that lie between different labels.
    pub fn boundary_share(&self) -> f64 {
        // 3 faces per voxel, less the ones on the volume's border (ignored)
        self.boundary_faces as f64 / (3 * self.voxels.max(1)) as f64
    }

    /// Whether the volume looks like an intensity image (CT, MR, a
    /// probability map) rather than a label map: many distinct values, and
    /// most faces between different ones (smooth or noisy images: 80 to
    /// 90 %). Label maps with hundreds of labels (atlases) have large
    /// regions, few of their faces are boundary; supervoxels of 3³ a third.
    pub fn looks_like_intensity(&self) -> bool {
        self.labels >= 32 && self.boundary_share() > 0.5
    }

    /// What to tell the user about a volume that
    /// [looks like an intensity image](Work::looks_like_intensity).
    pub fn intensity_note(&self) -> String {
        format!(
            "this looks like an intensity image, not a label map: {} distinct values, {:.0} % of the \
             voxel faces between different ones; for grayscale data use `septa iso VOLUME --iso VALUE`",
            self.labels,
            100.0 * self.boundary_share()
        )
    }
}

/// Counts the work of extracting `volume` (one parallel pass over it);
/// `subdivision` is 5, or 7 with separation constraints.
pub fn estimate(volume: &LabelVolume, subdivision: u64) -> Work {
    let d = volume.dims();
    let ids = volume.ids();
    let (nx, ny, nz) = (d.nx, d.ny, d.nz);
    let at = |x: usize, y: usize, z: usize| ids[x + nx * (y + ny * z)];
    let slab = |z: usize| -> [u64; 3] {
        let mut faces = 0u64;
        let mut edges = 0u64;
        let mut vertices = 0u64;
        for y in 0..ny {
            for x in 0..nx {
                let l = at(x, y, z);
                faces += u64::from(x + 1 < nx && at(x + 1, y, z) != l)
                    + u64::from(y + 1 < ny && at(x, y + 1, z) != l)
                    + u64::from(z + 1 < nz && at(x, y, z + 1) != l);
                // edges of the cell (x..x+1, y..y+1, z..z+1) through its corner
                let (ex, ey, ez) = (x + 1 < nx, y + 1 < ny, z + 1 < nz);
                if ey && ez {
                    edges += u64::from(critical_edge([
                        l,
                        at(x, y + 1, z),
                        at(x, y, z + 1),
                        at(x, y + 1, z + 1),
                    ]));
                }
                if ex && ez {
                    edges += u64::from(critical_edge([
                        l,
                        at(x + 1, y, z),
                        at(x, y, z + 1),
                        at(x + 1, y, z + 1),
                    ]));
                }
                if ex && ey {
                    edges += u64::from(critical_edge([
                        l,
                        at(x + 1, y, z),
                        at(x, y + 1, z),
                        at(x + 1, y + 1, z),
                    ]));
                }
                if ex && ey && ez {
                    let mut cell = [0; 8];
                    for (o, c) in cell.iter_mut().enumerate() {
                        *c = at(x + (o & 1), y + (o >> 1 & 1), z + (o >> 2 & 1));
                    }
                    vertices += u64::from(critical_vertex(&cell));
                }
            }
        }
        [faces, edges, vertices]
    };
    let [boundary_faces, critical_edges, critical_vertices] = (0..nz)
        .into_par_iter()
        .map(slab)
        .reduce(|| [0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]]);
    Work {
        voxels: d.len() as u64,
        labels: volume.label_count() as u64,
        boundary_faces,
        critical_edges,
        critical_vertices,
        subdivision,
    }
}

/// Four voxels around an edge, in the order (0,0), (1,0), (0,1), (1,1) of
/// the two other axes: critical when a label holds exactly one diagonal.
fn critical_edge([a, b, c, d]: [u16; 4]) -> bool {
    (a == d && b != a && c != a) || (b == c && a != b && d != b)
}

/// The 8 voxels around a grid vertex (octant `o`: +x, +y, +z by bits):
/// critical when some label's octant mask is.
fn critical_vertex(cell: &[u16; 8]) -> bool {
    if cell.iter().all(|&l| l == cell[0]) {
        return false;
    }
    for (i, &l) in cell.iter().enumerate() {
        if cell[..i].contains(&l) {
            continue;
        }
        let mask = cell
            .iter()
            .enumerate()
            .filter(|&(_, &m)| m == l)
            .fold(0u8, |m, (o, _)| m | 1 << o);
        if is_critical_mask(mask) {
            return true;
        }
    }
    false
}

/// The total area of a mesh's triangles, in mm².
pub fn surface_area(mesh: &crate::mesh::InterfaceMesh) -> f64 {
    mesh.triangles
        .par_iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
            0.5 * (b - a).cross(c - a).length()
        })
        .sum()
}

/// A byte count for people: `1.2 GB`, `350 MB`.
pub fn human_bytes(b: u64) -> String {
    let gb = b as f64 / 1e9;
    if gb >= 1.0 {
        format!("{gb:.1} GB")
    } else {
        format!("{:.0} MB", (b as f64 / 1e6).max(1.0))
    }
}

/// Memory this process may still use, in bytes, when the system says: the
/// smaller of the kernel's available memory and what the address-space limit
/// (`ulimit -v`) leaves. `None` where neither can be read.
pub fn available_memory() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok();
    let available = meminfo
        .as_deref()
        .and_then(|m| kib_field(m, "MemAvailable:"));
    let limits = std::fs::read_to_string("/proc/self/limits").ok();
    let status = std::fs::read_to_string("/proc/self/status").ok();
    let address_space = limits
        .as_deref()
        .and_then(address_space_limit)
        .map(|limit| {
            let used = status
                .as_deref()
                .and_then(|s| kib_field(s, "VmSize:"))
                .unwrap_or(0);
            limit.saturating_sub(used)
        });
    match (available, address_space) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// A `Name:   123 kB` field of /proc/meminfo or /proc/self/status, in bytes.
fn kib_field(text: &str, name: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let kib: u64 = line[name.len()..].split_whitespace().next()?.parse().ok()?;
    Some(kib * 1024)
}

/// The soft "Max address space" of /proc/self/limits, in bytes.
fn address_space_limit(limits: &str) -> Option<u64> {
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    line["Max address space".len()..]
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Dims, Geometry};

    fn vol(n: usize, f: impl Fn(usize, usize, usize) -> i64) -> LabelVolume {
        let v: Vec<i64> = (0..n * n * n)
            .map(|i| f(i % n, i / n % n, i / (n * n)))
            .collect();
        LabelVolume::from_values(Dims::new(n, n, n).unwrap(), &v, Geometry::identity()).unwrap()
    }

    #[test]
    fn counts_of_small_configurations() {
        // one voxel of 1 in a 3³ block of 0: 6 faces, nothing critical
        let w = estimate(&vol(3, |x, y, z| i64::from(x == 1 && y == 1 && z == 1)), 5);
        assert_eq!(
            (w.boundary_faces, w.critical_edges, w.critical_vertices),
            (6, 0, 0)
        );
        // two voxels sharing only an edge: a critical edge
        let w = estimate(&vol(2, |x, y, z| i64::from(x == y && z == 0)), 5);
        assert_eq!(w.critical_edges, 1);
        // two voxels sharing only a vertex: a critical vertex
        let w = estimate(&vol(2, |x, y, z| i64::from(x == y && y == z)), 5);
        assert_eq!((w.critical_edges, w.critical_vertices), (0, 1));
    }

    #[test]
    fn intensity_images_are_told_from_label_maps() {
        let gray = estimate(
            &vol(16, |x, y, z| ((x * 7 + y * 13 + z * 5) % 200) as i64),
            5,
        );
        assert!(gray.looks_like_intensity(), "{gray:?}");
        // an atlas-like map: 64 labels in 4³ blocks
        let atlas = estimate(
            &vol(16, |x, y, z| (x / 4 + 4 * (y / 4) + 16 * (z / 4)) as i64),
            5,
        );
        assert!(!atlas.looks_like_intensity(), "{atlas:?}");
        assert!(gray.bytes() > atlas.bytes());
        // remeshing to a hundredth of a voxel: ten thousand times the triangles
        assert!(atlas.remesh_bytes(1000, 1e4, 0.01) > 100 * atlas.remesh_bytes(1000, 1e4, 2.0));
    }

    #[test]
    fn proc_fields() {
        assert_eq!(
            kib_field("MemAvailable:   2048 kB\n", "MemAvailable:"),
            Some(2 << 20)
        );
        let limits = "Limit                     Soft Limit           Hard Limit           Units\n\
                      Max address space         unlimited            unlimited            bytes\n";
        assert_eq!(address_space_limit(limits), None);
        let limits = "Max address space         1073741824           unlimited            bytes\n";
        assert_eq!(address_space_limit(limits), Some(1 << 30));
    }
}
