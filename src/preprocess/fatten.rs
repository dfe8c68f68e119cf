//! Fattening of critical elements on virtual subvoxels — B-K §2.1.
//!
//! Every voxel touching a critical element is split into s³ subvoxels inheriting
//! its label; then the k-neighbourhood of each element is given its dominant
//! label, where N0(x) = x and N_k(x) = the subvoxels meeting N_{k−1}(x) (closed
//! sets). For an element spanning fine grid vertices `lo..=hi` along an axis,
//! N_k covers fine cells `lo − k ..= hi + k − 1` along that axis.
//!
//! Order, later wins: faces by N1, then edges by N1 (s = 5) or N2 (s = 7), then
//! vertices by N2 (s = 5) or N3 (s = 7). Elements of one stage are applied in
//! the (deterministic) order of the [`CriticalSet`].
//!
//! Voxels whose subvoxels all end up with the voxel's own label are not kept
//! refined: they are the same set as the coarse voxel.

use hashbrown::HashMap;

use super::critical::{CriticalElement, CriticalSet, ElementKind};
use super::refined::{RefinedVolume, cell_key};
use crate::volume::{LabelId, PaddedLabels};

/// Neighbourhood sizes (faces, edges, vertices) for a subdivision factor.
pub fn neighbourhoods(s: i32) -> [i32; 3] {
    if s >= 7 { [1, 2, 3] } else { [1, 1, 2] }
}

/// The fine-cell box `[lo, hi]` (inclusive, per axis) of N_k(element).
pub fn neighbourhood_box(e: &CriticalElement, s: i32, k: i32) -> ([i32; 3], [i32; 3]) {
    let lo = e.pos.map(|p| p * s);
    let mut hi = lo;
    match e.kind {
        ElementKind::Vertex => {}
        ElementKind::Edge { axis } => hi[axis as usize] += s,
        ElementKind::Face { axis } => {
            for a in 0..3 {
                if a != axis as usize {
                    hi[a] += s;
                }
            }
        }
    }
    (lo.map(|v| v - k), hi.map(|v| v + k - 1))
}

fn stage_of(kind: ElementKind) -> usize {
    match kind {
        ElementKind::Face { .. } => 0,
        ElementKind::Edge { .. } => 1,
        ElementKind::Vertex => 2,
    }
}

/// Subvoxel storage while fattening.
struct Work<'g> {
    grid: &'g PaddedLabels,
    s: i32,
    slot_of: HashMap<u64, u32>,
    cells: Vec<[i32; 3]>,
    sub: Vec<LabelId>,
}

impl Work<'_> {
    fn slot(&mut self, c: [i32; 3]) -> usize {
        let n = (self.s * self.s * self.s) as usize;
        let next = self.cells.len() as u32;
        let slot = *self.slot_of.entry(cell_key(c)).or_insert(next);
        if slot == next {
            self.cells.push(c);
            let l = self.grid.get(c[0], c[1], c[2]);
            self.sub.extend(std::iter::repeat_n(l, n));
        }
        slot as usize
    }

    /// Gives every fine cell of the box the label `l`.
    fn paint(&mut self, lo: [i32; 3], hi: [i32; 3], l: LabelId) {
        let s = self.s;
        let n = (s * s * s) as usize;
        let clo = lo.map(|v| v.div_euclid(s));
        let chi = hi.map(|v| v.div_euclid(s));
        for cz in clo[2]..=chi[2] {
            for cy in clo[1]..=chi[1] {
                for cx in clo[0]..=chi[0] {
                    let c = [cx, cy, cz];
                    let base = self.slot(c) * n;
                    let a = [0, 1, 2].map(|i| (lo[i] - c[i] * s).max(0));
                    let b = [0, 1, 2].map(|i| (hi[i] - c[i] * s).min(s - 1));
                    for z in a[2]..=b[2] {
                        for y in a[1]..=b[1] {
                            let row = base + (s * (y + s * z)) as usize;
                            self.sub[row + a[0] as usize..=row + b[0] as usize].fill(l);
                        }
                    }
                }
            }
        }
    }
}

/// Fattens all critical elements of `critical` on `s`³ subvoxels.
pub fn fatten(grid: PaddedLabels, critical: &CriticalSet, s: i32) -> RefinedVolume {
    if critical.is_empty() {
        return RefinedVolume::unrefined(grid, s);
    }
    let k = neighbourhoods(s);
    let mut work = Work {
        grid: &grid,
        s,
        slot_of: HashMap::new(),
        cells: Vec::new(),
        sub: Vec::new(),
    };
    for stage in 0..3 {
        for e in critical
            .elements
            .iter()
            .filter(|e| stage_of(e.kind) == stage)
        {
            let (lo, hi) = neighbourhood_box(e, s, k[stage]);
            work.paint(lo, hi, e.dominant);
        }
    }
    let n = (s * s * s) as usize;
    let Work { cells, sub, .. } = work;
    let mut kept: Vec<(usize, [i32; 3])> = cells
        .iter()
        .enumerate()
        .filter(|(slot, c)| {
            let own = grid.get(c[0], c[1], c[2]);
            sub[slot * n..(slot + 1) * n].iter().any(|&l| l != own)
        })
        .map(|(slot, &c)| (slot, c))
        .collect();
    kept.sort_unstable_by_key(|&(_, c)| (c[2], c[1], c[0]));
    let mut sorted_sub = Vec::with_capacity(kept.len() * n);
    for &(slot, _) in &kept {
        sorted_sub.extend_from_slice(&sub[slot * n..(slot + 1) * n]);
    }
    let cells = kept.into_iter().map(|(_, c)| c).collect();
    RefinedVolume::new(grid, s, cells, sorted_sub)
}
