//! The junction network's part of the sizing field: where the curves along
//! which patches meet are finer than the target, the target comes down to
//! them.
//!
//! A patch's triangles along a junction curve have one edge on the curve.
//! Where a run of a curve (from corner to corner) is shorter than the target
//! it stays one short edge; where two runs come closer than the target (a
//! strip of patch between them) the triangles across the strip are as wide
//! as the strip. Either way a target longer than the curves allow makes
//! needles: on a low-resolution segmentation where many labels meet, most
//! runs are shorter than the target. So, on the smoothed curves:
//! - every point of a run gets the run's length as its limit (a third of it
//!   for a closed curve without corners: three edges at least);
//! - points along a run get a limit from the distance w to the nearest run
//!   that shares no corner with it (runs meeting at a corner come together
//!   there; that is the corner's angle, not a gap): the strip between them
//!   must hold a whole number of rows of triangles. One row spans it where
//!   w is below the target (the target comes down to w). A strip too wide
//!   for one row at the target (its diagonals would be longer than the
//!   remesher keeps) and too narrow for two rows of equilateral triangles
//!   has no mesh at the target whose edges are all in range: a vertex in
//!   the middle of a strip 1.5 targets wide has its edges to both curves at
//!   0.75 of the target, and no collapse can take it out (the edges across
//!   the strip would be too long again); on a noisy head most short edges
//!   were of that kind. There the target comes down to the edge of two rows
//!   of equilateral triangles across the strip (three rows, in a narrow
//!   band; wider strips always hold whole rows at the target).
//!
//! [`Sizing::limited`] takes these limits into the field and grades around
//! them, so the targets beside short or close runs match them.

use glam::DVec3;
use rayon::prelude::*;

use super::network::{Network, VertexKind};
use super::sizing::Sizing;
use crate::geom::predicates::closest_on_segment;
use crate::mesh::quality::EDGE_RANGE_HI;

/// The widest strip (in targets) that one row of triangles spans: a
/// triangle on an edge of one curve with its apex on the other, above the
/// edge's middle, has its two other edges no longer than the longest edge
/// the remesher keeps.
fn one_row() -> f64 {
    (EDGE_RANGE_HI * EDGE_RANGE_HI - 0.25).sqrt()
}

/// The height of a row of equilateral triangles, in edges.
const ROW_HEIGHT: f64 = 0.866_025_403_784_438_6;

/// The widest strip (in targets) that [`strip_limit`] can limit: three rows
/// of equilateral triangles. From four rows on, the fewest rows that fit
/// are never wider than rows of equilateral triangles at the target
/// ((k − 1) · [`one_row`] ≥ k · [`ROW_HEIGHT`] for k ≥ 4).
const STRIP_REACH: f64 = 3.0 * ROW_HEIGHT;

/// The target limit a strip of width `w` between two runs sets where the
/// target is `t` (`None`: the strip leaves room for `t`). Below `t`, the
/// strip itself (one row across). Wider, the strip holds k rows, the fewest
/// that [`one_row`] allows, and the target is at most the edge of k rows of
/// equilateral triangles across it: rows as wide as they are at `t` would
/// leave the vertices between them at w / k from the curves, which may be
/// shorter than the remesher keeps (a strip 1.5 targets wide: 0.75).
fn strip_limit(w: f64, t: f64) -> Option<f64> {
    if w < t {
        return Some(w);
    }
    let rows = (w / (one_row() * t)).ceil().max(1.0);
    let equilateral = w / (rows * ROW_HEIGHT);
    (equilateral < t).then_some(equilateral)
}

/// A run of a junction curve: its vertices from corner to corner (or a
/// whole closed curve without corners, first vertex repeated at the end).
struct Run {
    vertices: Vec<u32>,
    /// Its end corners (vertex ids); `None` for a closed curve without corners.
    ends: Option<[u32; 2]>,
}

/// The runs of every curve of `net`.
fn runs(net: &Network) -> Vec<Run> {
    let corner = |v: u32| net.kind[v as usize] == VertexKind::Corner;
    let mut runs = Vec::new();
    for c in &net.curves {
        let vs = &c.vertices;
        if vs.len() < 2 {
            continue;
        }
        let first_corner = vs.iter().position(|&v| corner(v));
        let ring: Vec<u32> = match (c.closed, first_corner) {
            (true, None) => {
                let mut ring = vs.clone();
                ring.push(vs[0]);
                runs.push(Run {
                    vertices: ring,
                    ends: None,
                });
                continue;
            }
            // a closed curve through corners: its runs from a corner round
            (true, Some(k)) => vs[k..].iter().chain(&vs[..=k]).copied().collect(),
            (false, _) => vs.clone(),
        };
        let mut start = 0;
        for i in 1..ring.len() {
            if corner(ring[i]) || i + 1 == ring.len() {
                let run = ring[start..=i].to_vec();
                let ends = Some([run[0], run[run.len() - 1]]);
                runs.push(Run {
                    vertices: run,
                    ends,
                });
                start = i;
            }
        }
    }
    runs
}

/// Points along a polyline about `step` apart: a vertex where it is at
/// least `step` from the last point taken (with points between on a long
/// stretch), and the last vertex.
fn samples(points: impl Iterator<Item = DVec3>, step: f64) -> Vec<DVec3> {
    let mut out: Vec<DVec3> = Vec::new();
    let mut end = None;
    for p in points {
        end = Some(p);
        let Some(&last) = out.last() else {
            out.push(p);
            continue;
        };
        let d = (p - last).length();
        if d >= step {
            let n = (d / step).floor().max(1.0) as usize;
            out.extend((1..=n).map(|k| last + (p - last) * (k as f64 / n as f64)));
        }
    }
    if let Some(p) = end {
        if out.last() != Some(&p) {
            out.push(p);
        }
    }
    out
}

/// The limits (point, largest target there in mm) the junction network of
/// `net` (at positions `pos`) sets on `sizing`; none where it leaves room
/// for the target.
pub(super) fn limits(net: &Network, pos: &[DVec3], sizing: &Sizing) -> Vec<(DVec3, f64)> {
    let max = sizing.max();
    let runs = runs(net);
    let length = |r: &Run| -> f64 {
        r.vertices
            .windows(2)
            .map(|w| (pos[w[1] as usize] - pos[w[0] as usize]).length())
            .sum()
    };
    let by_length: Vec<f64> = runs
        .par_iter()
        .map(|r| {
            let l = length(r);
            if r.ends.is_none() { l / 3.0 } else { l }
        })
        .collect();
    let mut limits: Vec<(DVec3, f64)> = Vec::new();
    for (r, &t) in runs.iter().zip(&by_length) {
        if t < max {
            limits.extend(r.vertices.iter().map(|&v| (pos[v as usize], t)));
        }
    }
    limits.extend(gap_limits(&runs, pos, &by_length, sizing));
    limits
}

/// The limits that the strips between runs set at points along each run
/// (see [`strip_limit`]): from the distance to the nearest run that shares
/// no corner with it, where that is below the target there (the field's, or
/// the run's other limit).
fn gap_limits(
    runs: &[Run],
    pos: &[DVec3],
    by_length: &[f64],
    sizing: &Sizing,
) -> Vec<(DVec3, f64)> {
    let max = sizing.max();
    // the runs resampled at a fraction of the smallest target: fewer
    // segments than the extraction's fine chords, as close to the curves
    // as the field can tell
    let step = 0.5 * sizing.min();
    let sampled: Vec<Vec<DVec3>> = runs
        .par_iter()
        .map(|r| samples(r.vertices.iter().map(|&v| pos[v as usize]), step))
        .collect();
    // segments binned by midpoint in cells of the largest query reach
    let mut segs: Vec<(u32, DVec3, DVec3)> = Vec::new();
    let mut longest = 0.0f64;
    for (r, pts) in sampled.iter().enumerate() {
        for w in pts.windows(2) {
            segs.push((r as u32, w[0], w[1]));
            longest = longest.max((w[1] - w[0]).length());
        }
    }
    if segs.is_empty() {
        return Vec::new();
    }
    // (strips up to STRIP_REACH targets wide set limits)
    let grid = SegmentGrid::new(&segs, 0.5 * (STRIP_REACH * max + 0.5 * longest));
    let related = |r: usize, s: usize| {
        r == s
            || match (runs[r].ends, runs[s].ends) {
                (Some(a), Some(b)) => a.iter().any(|x| b.contains(x)),
                _ => false,
            }
    };
    sampled
        .par_iter()
        .enumerate()
        .flat_map_iter(|(r, pts)| {
            let run_limit = by_length[r].min(max);
            let (segs, grid, related) = (&segs, &grid, &related);
            pts.iter().filter_map(move |&p| {
                let target = sizing.at(p).min(run_limit);
                let reach = STRIP_REACH * target;
                // (a segment within `reach` of p has its midpoint within
                // reach + longest / 2 of it)
                let mut nearest2 = f64::INFINITY;
                grid.for_each_near(p, reach + 0.5 * longest, |i| {
                    let (s, a, b) = segs[i as usize];
                    if !related(r, s as usize) {
                        nearest2 = nearest2.min((closest_on_segment(p, a, b) - p).length_squared());
                    }
                });
                strip_limit(reach.min(nearest2.sqrt()), target).map(|t| (p, t))
            })
        })
        .collect()
}

/// Segments binned by midpoint in a uniform grid (one array, cell by cell),
/// for the gap queries of [`gap_limits`]: a query reads the cells within its
/// own reach, which is the target there, not the largest one.
struct SegmentGrid {
    lo: DVec3,
    inv: f64,
    dims: [usize; 3],
    /// Per cell: where its segments start in `ids` (one more entry at the end).
    start: Vec<u32>,
    ids: Vec<u32>,
}

impl SegmentGrid {
    /// Most cells the grid may have (the cell grows beyond this).
    const MAX_CELLS: usize = 1 << 22;

    fn new(segs: &[(u32, DVec3, DVec3)], cell: f64) -> Self {
        let mid = |s: &(u32, DVec3, DVec3)| (s.1 + s.2) * 0.5;
        let (lo, hi) = segs.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), s| (lo.min(mid(s)), hi.max(mid(s))),
        );
        let ext = (hi - lo).max(DVec3::ZERO);
        let mut cell = cell.max(ext.max_element() * 1e-6).max(1e-9);
        let dims_for = |c: f64| ext.to_array().map(|e| (e / c).floor() as usize + 1);
        while dims_for(cell).iter().product::<usize>() > Self::MAX_CELLS {
            cell *= 1.26;
        }
        let dims = dims_for(cell);
        let mut grid = SegmentGrid {
            lo,
            inv: 1.0 / cell,
            dims,
            start: vec![0; dims.iter().product::<usize>() + 1],
            ids: vec![0; segs.len()],
        };
        let cells: Vec<usize> = segs
            .iter()
            .map(|s| grid.index(grid.cell_of(mid(s))))
            .collect();
        for &c in &cells {
            grid.start[c + 1] += 1;
        }
        for c in 1..grid.start.len() {
            grid.start[c] += grid.start[c - 1];
        }
        let mut fill = grid.start.clone();
        for (i, &c) in cells.iter().enumerate() {
            grid.ids[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
        grid
    }

    /// The cell holding `p` (clamped to the grid).
    #[inline]
    fn cell_of(&self, p: DVec3) -> [usize; 3] {
        let q = (p - self.lo) * self.inv;
        [0, 1, 2].map(|a| {
            let x = q[a];
            if x.is_nan() || x <= 0.0 {
                0
            } else {
                (x as usize).min(self.dims[a] - 1)
            }
        })
    }

    #[inline]
    fn index(&self, c: [usize; 3]) -> usize {
        c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])
    }

    /// Calls `f` with every segment whose midpoint lies in a cell within `r`
    /// of `p` (so every one whose midpoint is within `r`).
    fn for_each_near(&self, p: DVec3, r: f64, mut f: impl FnMut(u32)) {
        let (a, b) = (
            self.cell_of(p - DVec3::splat(r)),
            self.cell_of(p + DVec3::splat(r)),
        );
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                let row = self.index([0, y, z]);
                let (s, e) = (self.start[row + a[0]], self.start[row + b[0] + 1]);
                for &i in &self.ids[s as usize..e as usize] {
                    f(i);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::remesh::network::Curve;

    /// A network of open curves given as point lists (their ends corners).
    fn network(curves: &[Vec<DVec3>]) -> (Network, Vec<DVec3>) {
        let mut pos = Vec::new();
        let mut kind = Vec::new();
        let mut out = Vec::new();
        for c in curves {
            let first = pos.len() as u32;
            for (i, &p) in c.iter().enumerate() {
                pos.push(p);
                let end = i == 0 || i + 1 == c.len();
                kind.push(if end {
                    VertexKind::Corner
                } else {
                    VertexKind::Curve(out.len() as u32)
                });
            }
            out.push(Curve {
                vertices: (first..pos.len() as u32).collect(),
                closed: false,
            });
        }
        (Network { kind, curves: out }, pos)
    }

    fn line(from: DVec3, to: DVec3, n: usize) -> Vec<DVec3> {
        (0..=n)
            .map(|k| from + (to - from) * (k as f64 / n as f64))
            .collect()
    }

    #[test]
    fn a_short_run_limits_the_target_to_its_length() {
        let (net, pos) = network(&[line(DVec3::ZERO, DVec3::X * 1.5, 3)]);
        let l = limits(&net, &pos, &Sizing::uniform(4.0));
        assert_eq!(l.len(), 4);
        assert!(l.iter().all(|&(_, t)| (t - 1.5).abs() < 1e-12), "{l:?}");
        // a long run sets no limit
        let (net, pos) = network(&[line(DVec3::ZERO, DVec3::X * 30.0, 30)]);
        assert!(limits(&net, &pos, &Sizing::uniform(4.0)).is_empty());
    }

    #[test]
    fn two_runs_a_gap_apart_limit_the_target_to_the_gap() {
        // two long parallel runs 1.2 mm apart, and a third 12 mm away (room
        // for four rows)
        let (net, pos) = network(&[
            line(DVec3::ZERO, DVec3::X * 30.0, 30),
            line(DVec3::Y * 1.2, DVec3::new(30.0, 1.2, 0.0), 30),
            line(DVec3::Z * 12.0, DVec3::new(30.0, 0.0, 12.0), 30),
        ]);
        let l = limits(&net, &pos, &Sizing::uniform(4.0).limited(&[]));
        assert!(!l.is_empty());
        for &(p, t) in &l {
            assert!(p.z < 1.0, "the far run has room: {p:?}");
            assert!((t - 1.2).abs() < 1e-9, "{p:?} {t}");
        }
    }

    #[test]
    fn a_strip_between_one_row_and_two_gets_two_rows() {
        // two long parallel runs 1.5 targets apart: one row across would have
        // edges over 1.5 targets, two rows as wide as the target edges of
        // 0.75 to the curves; the target comes down to two rows of
        // equilateral triangles. 1.8 targets apart leave room for two rows.
        let two_rows = |w: f64| w / (2.0 * ROW_HEIGHT);
        for (gap, want) in [(1.5 * 4.0, Some(two_rows(6.0))), (1.8 * 4.0, None)] {
            let (net, pos) = network(&[
                line(DVec3::ZERO, DVec3::X * 60.0, 60),
                line(DVec3::Y * gap, DVec3::new(60.0, gap, 0.0), 60),
            ]);
            let l = limits(&net, &pos, &Sizing::uniform(4.0).limited(&[]));
            match want {
                Some(t) => {
                    assert!(l.iter().any(|&(p, _)| p.y == 0.0), "{l:?}");
                    assert!(l.iter().any(|&(p, _)| p.y == gap), "{l:?}");
                    assert!(l.iter().all(|&(_, x)| (x - t).abs() < 1e-9), "{l:?}");
                }
                None => assert!(l.is_empty(), "{l:?}"),
            }
        }
        assert_eq!(
            strip_limit(3.0, 4.0),
            Some(3.0),
            "one row, the strip's width"
        );
        assert_eq!(strip_limit(4.5, 4.0), None, "one row spans it");
        assert_eq!(strip_limit(6.0, 4.0), Some(two_rows(6.0)));
        // three rows fit at the target from 2.6 targets on
        assert!(strip_limit(10.0, 4.0).is_some_and(|x| x < 4.0));
        assert_eq!(strip_limit(10.6, 4.0), None);
    }

    #[test]
    fn runs_meeting_at_a_corner_are_no_gap() {
        // a V: two runs from one corner, at 30°
        let c = DVec3::ZERO;
        let (a, b) = (DVec3::X * 20.0, DVec3::new(20.0 * 0.866, 10.0, 0.0));
        let (mut net, pos) = network(&[line(c, a, 20), line(c, b, 20)]);
        // (one corner shared: the second run starts at the first's start)
        let shared = net.curves[0].vertices[0];
        net.curves[1].vertices[0] = shared;
        assert!(limits(&net, &pos, &Sizing::uniform(4.0)).is_empty());
    }
}
