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
//!
//! With separation constraints the dominant label of an edge or vertex is
//! chosen when it is painted: the best-ranked critical label that is not
//! constrained against any label its paint will touch (the labels in
//! N_{k+1}, after the earlier stages); failing that, the separator of a
//! constrained pair present there. Otherwise fattening an edge could paint
//! label A against label B that a constraint keeps apart (found by the
//! property tests: B-K do not discuss it).

use hashbrown::HashMap;

use super::critical::{CriticalElement, CriticalSet, ElementKind, SeparationTable};
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

    /// Current label of fine cell `f`.
    fn label(&self, f: [i32; 3]) -> LabelId {
        let s = self.s;
        let c = f.map(|v| v.div_euclid(s));
        match self.slot_of.get(&cell_key(c)) {
            Some(&slot) => {
                let l = [0, 1, 2].map(|a| f[a] - c[a] * s);
                self.sub
                    [slot as usize * (s * s * s) as usize + (l[0] + s * (l[1] + s * l[2])) as usize]
            }
            None => self.grid.get(c[0], c[1], c[2]),
        }
    }

    /// Distinct labels currently in the fine box.
    fn labels_in(&self, lo: [i32; 3], hi: [i32; 3], out: &mut Vec<LabelId>) {
        out.clear();
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let l = self.label([x, y, z]);
                    if !out.contains(&l) {
                        out.push(l);
                    }
                }
            }
        }
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

/// Fattens all critical elements of `critical` on `s`³ subvoxels. `rank`
/// orders labels for dominance; `separation` holds the constrained pairs.
pub fn fatten(
    grid: PaddedLabels,
    critical: &CriticalSet,
    s: i32,
    rank: &[u32],
    separation: &SeparationTable,
) -> RefinedVolume {
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
    let mut present = Vec::new();
    for stage in 0..3 {
        for e in critical
            .elements
            .iter()
            .filter(|e| stage_of(e.kind) == stage)
        {
            let (lo, hi) = neighbourhood_box(e, s, k[stage]);
            let mut dominant = e.dominant;
            if separation.is_active() && stage > 0 {
                let (tlo, thi) = neighbourhood_box(e, s, k[stage] + 1);
                work.labels_in(tlo, thi, &mut present);
                dominant = constrained_dominant(&grid, e, rank, separation, &present);
            }
            work.paint(lo, hi, dominant);
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

/// Labels critical at an edge or vertex of the coarse grid, best rank first.
fn critical_labels(grid: &PaddedLabels, e: &CriticalElement, rank: &[u32]) -> Vec<LabelId> {
    let oct = grid.vertex_octants(e.pos[0], e.pos[1], e.pos[2]);
    let mut out: Vec<LabelId> = Vec::new();
    match e.kind {
        ElementKind::Vertex => {
            for &l in &oct {
                let mask = (0..8).filter(|&o| oct[o] == l).fold(0u8, |m, o| m | 1 << o);
                if crate::star::is_critical_mask(mask) && !out.contains(&l) {
                    out.push(l);
                }
            }
        }
        ElementKind::Edge { axis } => {
            let ring = [[1, 3, 7, 5], [2, 3, 7, 6], [4, 5, 7, 6]][axis as usize].map(|o| oct[o]);
            for (p, q, r, t) in [(0, 2, 1, 3), (1, 3, 0, 2)] {
                if ring[p] == ring[q]
                    && ring[r] != ring[p]
                    && ring[t] != ring[p]
                    && !out.contains(&ring[p])
                {
                    out.push(ring[p]);
                }
            }
        }
        ElementKind::Face { .. } => {}
    }
    out.sort_by_key(|&l| rank[l as usize]);
    out
}

/// The dominant label of an edge or vertex under separation constraints: the
/// best critical label not constrained against anything it will touch, else
/// the separator of a constrained pair that is present.
fn constrained_dominant(
    grid: &PaddedLabels,
    e: &CriticalElement,
    rank: &[u32],
    sep: &SeparationTable,
    present: &[LabelId],
) -> LabelId {
    let allowed = |d: LabelId| present.iter().all(|&p| sep.separator(d, p).is_none());
    if let Some(d) = critical_labels(grid, e, rank)
        .into_iter()
        .find(|&d| allowed(d))
    {
        return d;
    }
    let mut separators: Vec<LabelId> = Vec::new();
    for (i, &a) in present.iter().enumerate() {
        for &b in &present[i + 1..] {
            if let Some(c) = sep.separator(a, b) {
                separators.push(c);
            }
        }
    }
    separators.sort_by_key(|&l| rank[l as usize]);
    separators
        .into_iter()
        .find(|&d| allowed(d))
        .unwrap_or(e.dominant)
}
