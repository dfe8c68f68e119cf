//! Statistics of an iso-surface, as in the VESTA paper's Tables II–IV: the
//! number of N-cycles for N = 3 … 12 (and per cycle type), support points,
//! triangles and the extraction time.

use super::table::{CellEntry, NO_TYPE, cycle_types};

/// Cycles counted by type id (14 listed types, then "other") and by length.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct TypeCounts {
    pub types: [u64; 15],
    pub lengths: [u64; 13],
}

impl TypeCounts {
    /// Adds the cycles of a table entry, `n` times.
    #[inline]
    pub fn add_entry(&mut self, entry: &CellEntry, n: u64) {
        for i in 0..entry.cycles as usize {
            let ty = entry.types[i];
            let t = if ty == NO_TYPE { 14 } else { ty as usize };
            self.types[t] += n;
            self.lengths[entry.cycle(i).len()] += n;
        }
    }

    pub fn merge(&mut self, other: &TypeCounts) {
        for (a, b) in self.types.iter_mut().zip(other.types) {
            *a += b;
        }
        for (a, b) in self.lengths.iter_mut().zip(other.lengths) {
            *a += b;
        }
    }
}

/// Counts and timing of one extraction.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct IsoStats {
    /// `cycles_by_length[n]`: number of n-cycles (entries 0–2 are always 0).
    pub cycles_by_length: [u64; 13],
    /// Number of cycles of each of VESTA's 14 types, in the order of
    /// [`cycle_types`](super::cycle_types).
    pub cycles_by_type: Vec<u64>,
    /// Voxels with value ≥ iso.
    pub active_voxels: u64,
    /// Support points: one per boundary face.
    pub support_points: usize,
    /// Extra points of the H decomposition (one per N-cycle with N > 3).
    pub centroids: usize,
    /// All output points (support points + centroids).
    pub points: usize,
    pub triangles: usize,
    /// Extraction time in seconds (from the loaded volume to the finished
    /// mesh in memory, as the paper times it; reading and writing excluded).
    pub seconds: f64,
}

impl IsoStats {
    pub(crate) fn from_counts(counts: &TypeCounts) -> Self {
        IsoStats {
            cycles_by_length: counts.lengths,
            cycles_by_type: counts.types[..cycle_types().len()].to_vec(),
            ..Default::default()
        }
    }

    /// Total number of cycles.
    pub fn cycle_sum(&self) -> u64 {
        self.cycles_by_length.iter().sum()
    }

    /// Rows of the paper's table: ("3-cycles", count) … ("12-cycles", count),
    /// then the sum, points, triangles and time.
    pub fn table_rows(&self) -> Vec<(String, String)> {
        let mut rows: Vec<(String, String)> = (3..=12)
            .map(|n| (format!("{n}-cycles"), self.cycles_by_length[n].to_string()))
            .collect();
        rows.push(("cycle sum".into(), self.cycle_sum().to_string()));
        rows.push(("points".into(), self.points.to_string()));
        rows.push(("triangles".into(), self.triangles.to_string()));
        rows.push(("time".into(), format!("{:.3} s", self.seconds)));
        rows
    }
}
