//! Keeping every label's volume: the offsets along the patch normals that
//! give each label back the volume the smoothing and the chords took.
//!
//! Smoothing cuts the staircase's corners and a remeshed surface spans
//! chords; both change the volume a label encloses, most where the
//! structures are thin or small. Moving patch `p` (labels `a < b`, normal
//! from `a` into `b`) along its normal by `δ_p` moves `δ_p · A_p` of volume
//! from `b` to `a`. The offsets that give every label `L` back its deficit
//! `r_L` with the least displacement (least `Σ A_p δ_p²`) are differences of
//! one *potential* per label, `δ_p = φ_a − φ_b`, with `φ` solving the graph
//! Laplacian of the labels weighted by the patch areas, `L φ = r` — the
//! Lagrange multipliers of the volume constraints. The system is singular
//! (adding a constant to every potential changes no offset) but consistent:
//! the deficits of all labels, the unbounded outside included, add up to
//! zero, since every patch counts once for each side.

use glam::DVec3;
use rayon::prelude::*;

/// Per label: the signed volume its surface encloses (mm³; the sum over its
/// patches, each counted with the side it bounds; negative for the
/// unbounded outside). `patch_labels` gives each patch's `[a, b]`.
pub(super) fn label_volumes(
    pos: &[DVec3],
    tris: &[[u32; 3]],
    tri_patch: &[u32],
    patch_labels: &[[usize; 2]],
    labels: usize,
) -> Vec<f64> {
    // (about the box's centre: smaller terms, less rounding)
    let centre = centre_of(pos);
    let per_patch = patch_sums(tris, tri_patch, patch_labels.len(), |t| {
        let [a, b, c] = t.map(|v| pos[v as usize] - centre);
        a.dot(b.cross(c)) / 6.0
    });
    let mut volumes = vec![0.0; labels];
    for (p, &[a, b]) in patch_labels.iter().enumerate() {
        volumes[a] += per_patch[p];
        volumes[b] -= per_patch[p];
    }
    volumes
}

/// Per patch: its area (mm²).
pub(super) fn patch_areas(
    pos: &[DVec3],
    tris: &[[u32; 3]],
    tri_patch: &[u32],
    patches: usize,
) -> Vec<f64> {
    patch_sums(tris, tri_patch, patches, |t| {
        let [a, b, c] = t.map(|v| pos[v as usize]);
        0.5 * (b - a).cross(c - a).length()
    })
}

/// Per patch: the offset along its normal (mm) that gives every label its
/// `deficit` back (see the module docs), for patches of the given `areas`.
pub(super) fn volume_offsets(
    patch_labels: &[[usize; 2]],
    areas: &[f64],
    deficit: &[f64],
) -> Vec<f64> {
    let phi = potentials(patch_labels, areas, deficit);
    patch_labels.iter().map(|&[a, b]| phi[a] - phi[b]).collect()
}

/// `φ` with `L φ = r` for the area-weighted Laplacian of the label graph,
/// by conjugate gradients with a Jacobi preconditioner (a label graph has
/// at most a few thousand nodes; this takes microseconds to milliseconds).
fn potentials(patch_labels: &[[usize; 2]], areas: &[f64], r: &[f64]) -> Vec<f64> {
    let n = r.len();
    let apply = |x: &[f64], out: &mut [f64]| {
        out.iter_mut().for_each(|o| *o = 0.0);
        for (&[a, b], &w) in patch_labels.iter().zip(areas) {
            let f = w * (x[a] - x[b]);
            out[a] += f;
            out[b] -= f;
        }
    };
    let mut diag = vec![0.0; n];
    for (&[a, b], &w) in patch_labels.iter().zip(areas) {
        diag[a] += w;
        diag[b] += w;
    }
    // labels without area (absent) get no potential and give no deficit
    let r: Vec<f64> = (0..n)
        .map(|i| if diag[i] > 0.0 { r[i] } else { 0.0 })
        .collect();
    let precondition = |x: &[f64]| -> Vec<f64> {
        x.iter()
            .zip(&diag)
            .map(|(v, &d)| if d > 0.0 { v / d } else { 0.0 })
            .collect()
    };
    let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(a, b)| a * b).sum::<f64>();
    let mut x = vec![0.0; n];
    let mut res = r.clone();
    let mut z = precondition(&res);
    let mut dir = z.clone();
    let mut rz = dot(&res, &z);
    let scale = dot(&r, &r).sqrt();
    let mut ad = vec![0.0; n];
    for _ in 0..4 * n + 20 {
        if !(dot(&res, &res).sqrt() > 1e-12 * scale) {
            break;
        }
        apply(&dir, &mut ad);
        let dad = dot(&dir, &ad);
        if !(dad > 0.0) {
            break;
        }
        let alpha = rz / dad;
        for i in 0..n {
            x[i] += alpha * dir[i];
            res[i] -= alpha * ad[i];
        }
        z = precondition(&res);
        let rz_next = dot(&res, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        for i in 0..n {
            dir[i] = z[i] + beta * dir[i];
        }
    }
    x
}

/// The centre of the points' bounding box.
fn centre_of(pos: &[DVec3]) -> DVec3 {
    let Some(&first) = pos.first() else {
        return DVec3::ZERO;
    };
    let (lo, hi) = pos
        .iter()
        .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    0.5 * (lo + hi)
}

/// Per patch: the sum of `term` over its triangles (in parallel, in a fixed
/// order of chunks: the same sums for any number of threads).
fn patch_sums(
    tris: &[[u32; 3]],
    tri_patch: &[u32],
    patches: usize,
    term: impl Fn(&[u32; 3]) -> f64 + Sync,
) -> Vec<f64> {
    const CHUNK: usize = 1 << 14;
    let parts: Vec<Vec<f64>> = tris
        .par_chunks(CHUNK)
        .zip(tri_patch.par_chunks(CHUNK))
        .map(|(ts, ps)| {
            let mut sums = vec![0.0; patches];
            for (t, &p) in ts.iter().zip(ps) {
                sums[p as usize] += term(t);
            }
            sums
        })
        .collect();
    let mut sums = vec![0.0; patches];
    for part in parts {
        for (s, v) in sums.iter_mut().zip(part) {
            *s += v;
        }
    }
    sums
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_give_each_label_its_deficit() {
        // labels 0 (outside), 1, 2, 3; patches 0-1, 0-2, 1-2, 2-3
        let patches = [[0, 1], [0, 2], [1, 2], [2, 3]];
        let areas = [10.0, 20.0, 5.0, 2.0];
        let deficit = [-7.0, 3.0, 1.5, 2.5];
        let off = volume_offsets(&patches, &areas, &deficit);
        let mut gained = [0.0; 4];
        for ((&[a, b], &w), &d) in patches.iter().zip(&areas).zip(&off) {
            gained[a] += w * d;
            gained[b] -= w * d;
        }
        for (g, d) in gained.iter().zip(&deficit) {
            assert!((g - d).abs() < 1e-9, "{gained:?} vs {deficit:?}");
        }
    }

    #[test]
    fn a_unit_cube_encloses_its_volume() {
        // the 12 triangles of the unit cube, outward, as label 1 in label 0
        let pos: Vec<DVec3> = (0..8)
            .map(|i| DVec3::new((i & 1) as f64, (i >> 1 & 1) as f64, (i >> 2) as f64))
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let tris: Vec<[u32; 3]> = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        // normals point from label 1 (inside) into label 2 (outside)
        let v = label_volumes(&pos, &tris, &[0; 12], &[[1, 2]], 3);
        assert!(
            (v[1] - 1.0).abs() < 1e-12 && (v[2] + 1.0).abs() < 1e-12,
            "{v:?}"
        );
        let a = patch_areas(&pos, &tris, &[0; 12], 1);
        assert!((a[0] - 6.0).abs() < 1e-12);
    }
}
