//! The preprocessing guarantee, checked: after fattening, no label has a
//! critical edge or vertex anywhere on the mixed coarse/fine grid, and no
//! constrained pair of labels shares a face.
//!
//! Only the closures of refined voxels need a look: elsewhere the grid is
//! unchanged, and every critical element of the input touches a refined voxel.
//! Each refined voxel is checked on a local block of (s + 2)³ fine labels (its
//! subvoxels and one layer of its neighbours), in parallel.

use rayon::prelude::*;

use super::critical::{CriticalElement, CriticalSet, ElementKind, SeparationTable};
use super::refined::RefinedVolume;
use crate::star::is_critical_mask;
use crate::volume::LabelId;

/// A violation of the guarantee, at a fine grid vertex (fine coordinates).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Violation {
    /// `label` is not manifold at fine vertex `at`.
    CriticalVertex { at: [i32; 3], label: LabelId },
    /// Fine cells `a` and `b` (neighbours) hold labels that must be separated.
    ConstrainedFace {
        a: [i32; 3],
        b: [i32; 3],
        labels: [LabelId; 2],
    },
    /// A critical element of the input (lowest corner `at`, fine coordinates)
    /// touches no refined voxel: it was never fattened.
    Unresolved { at: [i32; 3], kind: ElementKind },
}

/// Result of [`check_guarantee`].
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct GuaranteeReport {
    /// Fine vertices examined.
    pub points_checked: u64,
    /// Number of violations found.
    pub violation_count: u64,
    /// The first violations, in grid order.
    pub first_violations: Vec<Violation>,
}

impl GuaranteeReport {
    /// True when the mixed grid is manifold for every label and respects every constraint.
    pub fn passed(&self) -> bool {
        self.violation_count == 0
    }
}

const KEEP: usize = 32;

/// Checks the guarantee: every critical element of the input (`critical`) must
/// touch a refined voxel, and every refined voxel's closure must be clean.
pub fn check_guarantee(
    rv: &RefinedVolume,
    separation: &SeparationTable,
    critical: &CriticalSet,
) -> GuaranteeReport {
    let mut out = check_refined(rv, separation);
    for e in &critical.elements {
        if !touches_refined(rv, e) {
            let s = rv.subdivision();
            record(
                &mut out,
                Violation::Unresolved {
                    at: e.pos.map(|p| p * s),
                    kind: e.kind,
                },
            );
        }
    }
    out
}

/// Whether some voxel of the closed element's star is refined.
fn touches_refined(rv: &RefinedVolume, e: &CriticalElement) -> bool {
    let mut hi = e.pos;
    match e.kind {
        ElementKind::Vertex => {}
        ElementKind::Edge { axis } => hi[axis as usize] += 1,
        ElementKind::Face { axis } => {
            for a in 0..3 {
                if a != axis as usize {
                    hi[a] += 1;
                }
            }
        }
    }
    for z in e.pos[2] - 1..=hi[2] {
        for y in e.pos[1] - 1..=hi[1] {
            for x in e.pos[0] - 1..=hi[0] {
                if rv.is_refined([x, y, z]) {
                    return true;
                }
            }
        }
    }
    false
}

fn check_refined(rv: &RefinedVolume, separation: &SeparationTable) -> GuaranteeReport {
    let parts: Vec<GuaranteeReport> = rv
        .refined_cells()
        .par_chunks(64)
        .map(|cells| {
            let mut rep = GuaranteeReport::default();
            let mut block = Vec::new();
            for &c in cells {
                check_cell(rv, separation, c, &mut block, &mut rep);
            }
            rep
        })
        .collect();
    let mut out = GuaranteeReport::default();
    for p in parts {
        out.points_checked += p.points_checked;
        out.violation_count += p.violation_count;
        for v in p.first_violations {
            if out.first_violations.len() < KEEP {
                out.first_violations.push(v);
            }
        }
    }
    out
}

/// Fine labels of cell `c` and a one-subvoxel border, indexed by local (u, v, w) in −1..=s.
fn fill_block(rv: &RefinedVolume, c: [i32; 3], block: &mut Vec<LabelId>) {
    let s = rv.subdivision();
    let w = (s + 2) as usize;
    block.clear();
    block.resize(w * w * w, 0);
    // The 27 coarse cells around c: subvoxels if refined, else the coarse label.
    let mut near: [(Option<&[LabelId]>, LabelId); 27] = [(None, 0); 27];
    for (i, slot) in near.iter_mut().enumerate() {
        let n = [
            c[0] + (i % 3) as i32 - 1,
            c[1] + (i / 3 % 3) as i32 - 1,
            c[2] + (i / 9) as i32 - 1,
        ];
        *slot = (
            if rv.is_refined(n) {
                rv.subvoxels(n)
            } else {
                None
            },
            rv.coarse_label(n),
        );
    }
    let split = |v: i32| -> (usize, i32) {
        if v < 0 {
            (0, v + s)
        } else if v < s {
            (1, v)
        } else {
            (2, v - s)
        }
    };
    for z in -1..=s {
        let (cz, lz) = split(z);
        for y in -1..=s {
            let (cy, ly) = split(y);
            for x in -1..=s {
                let (cx, lx) = split(x);
                let l = match near[cx + 3 * (cy + 3 * cz)] {
                    (Some(sub), _) => sub[(lx + s * (ly + s * lz)) as usize],
                    (None, l) => l,
                };
                block[(x + 1) as usize + w * ((y + 1) as usize + w * (z + 1) as usize)] = l;
            }
        }
    }
}

fn record(rep: &mut GuaranteeReport, v: Violation) {
    rep.violation_count += 1;
    if rep.first_violations.len() < KEEP {
        rep.first_violations.push(v);
    }
}

fn check_cell(
    rv: &RefinedVolume,
    separation: &SeparationTable,
    c: [i32; 3],
    block: &mut Vec<LabelId>,
    rep: &mut GuaranteeReport,
) {
    let s = rv.subdivision();
    fill_block(rv, c, block);
    let w = (s + 2) as usize;
    let at = |x: i32, y: i32, z: i32| {
        block[(x + 1) as usize + w * ((y + 1) as usize + w * (z + 1) as usize)]
    };
    for vz in 0..=s {
        for vy in 0..=s {
            for vx in 0..=s {
                rep.points_checked += 1;
                let mut oct = [0 as LabelId; 8];
                for (o, slot) in oct.iter_mut().enumerate() {
                    *slot = at(
                        vx - 1 + (o & 1) as i32,
                        vy - 1 + ((o >> 1) & 1) as i32,
                        vz - 1 + ((o >> 2) & 1) as i32,
                    );
                }
                if oct.iter().all(|&l| l == oct[0]) {
                    continue;
                }
                let mut seen = 0u8;
                for o in 0..8 {
                    if seen >> o & 1 == 1 {
                        continue;
                    }
                    let mut mask = 0u8;
                    for (p, &l) in oct.iter().enumerate() {
                        if l == oct[o] {
                            mask |= 1 << p;
                        }
                    }
                    seen |= mask;
                    if mask != 255 && is_critical_mask(mask) {
                        let at = [c[0] * s + vx, c[1] * s + vy, c[2] * s + vz];
                        record(rep, Violation::CriticalVertex { at, label: oct[o] });
                    }
                }
            }
        }
    }
    if separation.is_active() {
        for z in 0..s {
            for y in 0..s {
                for x in 0..s {
                    let l = at(x, y, z);
                    for d in [
                        [1, 0, 0],
                        [0, 1, 0],
                        [0, 0, 1],
                        [-1, 0, 0],
                        [0, -1, 0],
                        [0, 0, -1],
                    ] {
                        let m = at(x + d[0], y + d[1], z + d[2]);
                        if separation.separator(l, m).is_some() {
                            let a = [c[0] * s + x, c[1] * s + y, c[2] * s + z];
                            let b = [a[0] + d[0], a[1] + d[1], a[2] + d[2]];
                            record(
                                rep,
                                Violation::ConstrainedFace {
                                    a,
                                    b,
                                    labels: [l, m],
                                },
                            );
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Resolved;
    use crate::preprocess::critical_elements;
    use crate::volume::{Dims, Geometry, LabelVolume, PaddedLabels};

    #[test]
    fn an_unfattened_volume_fails_the_check() {
        let mut v = vec![0i64; 8];
        v[0] = 1;
        v[7] = 1; // two voxels sharing only a vertex
        let vol = LabelVolume::from_values(Dims::new(2, 2, 2).unwrap(), &v, Geometry::identity())
            .unwrap();
        let r = Resolved::defaults(&vol);
        let grid = PaddedLabels::new(&vol, 0);
        let sep = SeparationTable::new(&r, 2);
        let crit = critical_elements(&grid, &r, &sep);
        assert_eq!(crit.counts(), (1, 0, 0));
        let unrefined = RefinedVolume::unrefined(grid.clone(), 5);
        let rep = check_guarantee(&unrefined, &sep, &crit);
        assert!(!rep.passed());
        // refined but not repainted: the fine check finds the vertex
        let cells: Vec<[i32; 3]> = (0..8)
            .map(|o| [o & 1, (o >> 1) & 1, (o >> 2) & 1])
            .collect();
        let mut sorted = cells.clone();
        sorted.sort_by_key(|c| (c[2], c[1], c[0]));
        let sub: Vec<LabelId> = sorted
            .iter()
            .flat_map(|c| std::iter::repeat_n(grid.get(c[0], c[1], c[2]), 125))
            .collect();
        let plain = RefinedVolume::new(grid.clone(), 5, sorted, sub);
        let rep = check_guarantee(&plain, &sep, &crit);
        assert!(
            rep.first_violations
                .iter()
                .any(|v| matches!(v, Violation::CriticalVertex { at: [5, 5, 5], .. })),
            "{rep:?}"
        );
        let fat = crate::preprocess::fatten(grid, &crit, 5, &r.rank, &sep);
        assert!(check_guarantee(&fat, &sep, &crit).passed());
    }
}
