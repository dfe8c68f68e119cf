//! Smoothing and remeshing: the validator's invariants (no self-intersection
//! ever), the quality figures on a noisy phantom, the shapes real
//! segmentations have (a sulcus-like fold whose banks are a voxel apart, two
//! parallel one-voxel walls, random volumes from blobs to pure noise) remeshed
//! with almost nothing left as extracted, thin walls that survive,
//! thread-count independence, and parameter errors.

mod common;

use septa::config::Resolved;
use septa::extract::{ExtractOptions, extract, label_infos};
use septa::mesh::InterfaceMesh;
use septa::mesh::quality::{QualityOptions, quality};
use septa::mesh::validate::{Options, validate};
use septa::phantom::{PhantomParams, heart};
use septa::preprocess::preprocess;
use septa::remesh::{RemeshParams, Remeshed, Sizing, remesh};
use septa::volume::{Dims, Geometry, LabelVolume};

fn extraction(vol: &LabelVolume, r: &Resolved) -> InterfaceMesh {
    let pre = preprocess(vol, r);
    extract(
        &pre.refined,
        label_infos(vol, None),
        *vol.geometry(),
        &ExtractOptions::default(),
    )
    .unwrap()
}

/// The extraction of `vol` and its remeshing with default parameters but the
/// largest target edge (mm), with the sizing field of the volume.
fn remeshed(vol: &LabelVolume, r: &Resolved, target_edge: f64) -> (InterfaceMesh, Remeshed) {
    let pre = preprocess(vol, r);
    let mesh = extract(
        &pre.refined,
        label_infos(vol, None),
        *vol.geometry(),
        &ExtractOptions::default(),
    )
    .unwrap();
    let params = RemeshParams {
        target_edge,
        ..Default::default()
    };
    let sizing = params.sizing(pre.refined.grid(), vol.geometry());
    let out = remesh(&mesh, &sizing, &params).unwrap();
    (mesh, out)
}

/// A label volume of `dims` (x fastest) on the kmeans head's anisotropic
/// 2 × 2 × 3 mm voxels.
fn on_head_voxels(dims: [usize; 3], values: &[i64]) -> LabelVolume {
    let geometry = Geometry::new(
        [2.0, 2.0, 3.0],
        [0.0; 3],
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    )
    .unwrap();
    LabelVolume::from_values(
        Dims::new(dims[0], dims[1], dims[2]).unwrap(),
        values,
        geometry,
    )
    .unwrap()
}

/// Share of the surface left as extracted where no operation could be done
/// safely.
fn stuck(out: &Remeshed) -> f64 {
    out.kept_share
}

/// Every invariant but self-intersections (counted separately).
fn assert_valid_but_intersections(name: &str, mesh: &InterfaceMesh) -> u64 {
    let report = validate(
        mesh,
        &Options {
            intersections: true,
            fidelity: None,
        },
    );
    for c in &report.checks {
        if c.name != "no self-intersections" {
            assert_eq!(c.failures, 0, "{name}: {}", report.summary());
        }
    }
    report
        .check("no self-intersections")
        .map_or(0, |c| c.failures)
}

/// Every invariant including no self-intersections, junction curves shared,
/// and at most 1 % of the surface left as extracted.
fn assert_remeshed_cleanly(name: &str, out: &Remeshed) {
    assert_eq!(assert_valid_but_intersections(name, &out.mesh), 0, "{name}");
    assert_junctions_shared(&out.mesh);
    assert!(stuck(out) <= 0.01, "{name}: {} kept", out.kept_share);
}

/// Junction vertices are shared: every junction curve vertex of the remeshed
/// mesh is used by a triangle of every patch whose labels meet there (at
/// least two patches).
fn assert_junctions_shared(mesh: &InterfaceMesh) {
    let mut patches_at: Vec<Vec<u32>> = vec![Vec::new(); mesh.vertex_count()];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for &v in tri {
            let p = mesh.triangle_patch[t];
            if !patches_at[v as usize].contains(&p) {
                patches_at[v as usize].push(p);
            }
        }
    }
    for c in &mesh.junctions {
        for &v in &c.vertices {
            assert!(
                patches_at[v as usize].len() >= 2,
                "junction vertex {v} in {} patches",
                patches_at[v as usize].len()
            );
        }
    }
}

/// A 12³ cube (1728 voxels): remeshed to 2 voxels, closed, no intersections,
/// far fewer triangles, volume within 5 % of the extraction's (smoothing
/// rounds the edges and corners a little, within half a voxel).
#[test]
fn cube_remeshes_cleanly() {
    let n = 16;
    let values: Vec<i64> = (0..n * n * n)
        .map(|i| {
            let (x, y, z) = (i % n, i / n % n, i / (n * n));
            ((2..14).contains(&x) && (2..14).contains(&y) && (2..14).contains(&z)) as i64
        })
        .collect();
    let vol = common::volume([n, n, n], &values);
    let r = Resolved::defaults(&vol);
    let (mesh, out) = remeshed(&vol, &r, 2.0);
    assert_eq!(assert_valid_but_intersections("cube", &out.mesh), 0);
    assert!(out.mesh.triangle_count() * 3 < mesh.triangle_count());
    let q = quality(&out.mesh, Some(&mesh), &QualityOptions::target(2.0));
    assert!(q.labels[1].change.unwrap().abs() < 0.05, "{}", q.summary());
    assert!(
        q.distance.as_ref().unwrap().hausdorff_voxels <= 1.0,
        "{}",
        q.summary()
    );
}

/// A two-voxel-thick plate of label 2 between labels 1 and 3: smoothing and
/// remeshing keep it (its volume within 10 %, no intersections between the
/// two sides), where unconfined Laplacian smoothing would thin it away.
#[test]
fn thin_plate_survives() {
    let (nx, ny, nz) = (16, 16, 10);
    let values: Vec<i64> = (0..nx * ny * nz)
        .map(|i| {
            let (x, y, z) = (i % nx, i / nx % ny, i / (nx * ny));
            if !(2..nx - 2).contains(&x) || !(2..ny - 2).contains(&y) || !(1..nz - 1).contains(&z) {
                0
            } else if z < 4 {
                1
            } else if z < 6 {
                2
            } else {
                3
            }
        })
        .collect();
    let vol = common::volume([nx, ny, nz], &values);
    let r = Resolved::defaults(&vol);
    let (mesh, out) = remeshed(&vol, &r, 2.0);
    assert_eq!(assert_valid_but_intersections("plate", &out.mesh), 0);
    assert_junctions_shared(&out.mesh);
    let q = quality(&out.mesh, Some(&mesh), &QualityOptions::target(2.0));
    let plate = q.labels.iter().find(|l| l.value == 2).unwrap();
    assert!(plate.change.unwrap().abs() < 0.10, "{}", q.summary());
}

/// The noisy 64³ phantom at L = 2 voxels (structures only 2–4 L wide): every
/// invariant including no self-intersections, junctions shared, ≥ 90 % of
/// edges within [0.8 h, 1.33 h] of the local target (89.8 % while a collapse
/// bounded its new edges by the collapsed edge's target instead of their
/// own; 90.2 % since), ≥ 97.5 % of triangles
/// with minimum angle ≥ 20°, Hausdorff ≤ 1 voxel, volume change ≤ 2 % for
/// labels over 1000 voxels (the per-patch volume offsets; 5 % before them),
/// ≤ 1 % of the surface left as extracted. (This
/// seed left 9 crossing pairs that the earlier remesher could only remove by
/// remeshing everything again, then keeping the smoothed surface there.)
#[test]
fn noisy_phantom_quality() {
    let vol = heart(&PhantomParams {
        size: 64,
        noise: 0.01,
        seed: 1,
        ..Default::default()
    })
    .unwrap();
    let r = Resolved::defaults(&vol);
    let pre = preprocess(&vol, &r);
    let mesh = extraction(&vol, &r);
    let params = RemeshParams {
        target_edge: 2.0,
        ..Default::default()
    };
    let sizing = params.sizing(pre.refined.grid(), vol.geometry());
    let out = remesh(&mesh, &sizing, &params).unwrap();
    let bad = assert_valid_but_intersections("noisy phantom", &out.mesh);
    assert_junctions_shared(&out.mesh);
    let q = quality(
        &out.mesh,
        Some(&mesh),
        &QualityOptions {
            target_edge_mm: 2.0,
            local: Some(&sizing),
        },
    );
    let s = q.summary();
    assert_eq!(bad, 0, "{s}");
    assert!(stuck(&out) <= 0.01, "{} kept: {s}", out.kept_share);
    assert!(q.edges.within_range >= 0.90, "{s}");
    assert!(q.angles.min_ge_20 >= 0.975, "{s}");
    assert!(q.distance.as_ref().unwrap().hausdorff_voxels <= 1.0, "{s}");
    let counts = vol.voxel_counts();
    for l in &q.labels {
        if let (Some(change), Some(id)) = (l.change, vol.id_of(l.value)) {
            if counts[id as usize] > 1000 {
                assert!(change.abs() <= 0.02, "label {}: {s}", l.value);
            }
        }
    }
}

/// Islands (one to three voxels of one label inside another: noise) stay
/// closed, outward and free of intersections at target edges longer than
/// they are, and are remeshed like the rest (none left as extracted): a
/// collapse or a move that would take an island's volume through zero (a
/// jump through itself that no crossing test sees, as on MNI152) is refused.
#[test]
fn islands_stay_outward() {
    let n = 20usize;
    let mut values = vec![1i64; n * n * n];
    let mut x = 99u64;
    let mut next = move |m: usize| {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x % m as u64) as usize
    };
    // islands of label 2 at random places, one to three voxels, apart
    for k in 0..40 {
        let (i, j, l) = (2 + next(n - 5), 2 + next(n - 5), 2 + next(n - 5));
        let len = 1 + k % 3;
        for d in 0..len {
            values[(l * n + j) * n + i + d] = 2;
        }
    }
    let vol = common::volume([n, n, n], &values);
    let r = Resolved::defaults(&vol);
    for target_edge in [1.5, 2.0, 4.0] {
        let (_, out) = remeshed(&vol, &r, target_edge);
        let name = format!("islands, L = {target_edge}");
        assert_eq!(
            assert_valid_but_intersections(&name, &out.mesh),
            0,
            "{name}"
        );
        assert!(out.kept_share <= 0.01, "{name}: {} kept", out.kept_share);
    }
}

/// Single voxels of a third label on the interface between two others: each
/// gives two small patches on one junction loop (a thin lens), the kind of
/// place where remeshing flattened both onto one plane on the noisy 256³
/// phantom. (These lenses come out clean even without the repair's moves
/// along the normal that fixed that case; the 256³ run is its measurement.)
#[test]
fn lenses_on_an_interface_do_not_cross() {
    let n = 24usize;
    let mut total = 0;
    for (shift, target_edge) in [(0usize, 2.0), (1, 2.0), (0, 3.0), (1, 1.5)] {
        let mut values: Vec<i64> = (0..n * n * n)
            .map(|i| if i / (n * n) < n / 2 { 4 } else { 0 })
            .collect();
        // voxels of label 7 just below the interface, some with an edge
        // neighbour (critical edges: fattened) and some alone
        for (k, (i, j)) in [(4, 4), (9, 5), (10, 6), (15, 15), (4, 17), (18, 8), (19, 9)]
            .into_iter()
            .enumerate()
        {
            let z = n / 2 - 1 - (k + shift) % 2;
            values[(z * n + j) * n + i] = 7;
        }
        let vol = common::volume([n, n, n], &values);
        let (_, out) = remeshed(&vol, &Resolved::defaults(&vol), target_edge);
        let name = format!("lenses, shift {shift}, L = {target_edge}");
        total += assert_valid_but_intersections(&name, &out.mesh);
        assert_junctions_shared(&out.mesh);
    }
    assert_eq!(total, 0);
}

/// Random label volumes, from pure noise to blobs, remeshed at several
/// target edges: every invariant holds, including no self-intersections
/// (every operation is checked against every other triangle), junction
/// curves stay shared, and at most 1 % of the surface is left as extracted
/// (small islands included). (The earlier remesher, repairing crossings after
/// the fact, kept nearly everything on the noisiest of these.)
#[test]
fn random_volumes_remesh_without_crossings() {
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move |m: u64| {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x % m
    };
    for case in 0..6 {
        let n = 8 + next(5) as usize;
        let labels = 2 + next(3) as i64;
        // 0: pure noise; otherwise blobs: label of a coarse cell, flipped with p
        let cell = 1 + case % 3;
        let flip = [100, 20, 5][case % 3];
        let coarse: Vec<i64> = (0..n * n * n).map(|_| next(labels as u64) as i64).collect();
        let values: Vec<i64> = (0..n * n * n)
            .map(|i| {
                let (a, b, c) = (i % n / cell, i / n % n / cell, i / (n * n) / cell);
                if next(100) < flip {
                    next(labels as u64) as i64
                } else {
                    coarse[(c * n + b) * n + a]
                }
            })
            .collect();
        let vol = common::volume([n, n, n], &values);
        for target_edge in [1.5, 3.0] {
            let (_, out) = remeshed(&vol, &Resolved::defaults(&vol), target_edge);
            let name =
                format!("case {case}: {n}³, {labels} labels, cell {cell}, L = {target_edge}");
            assert_eq!(
                assert_valid_but_intersections(&name, &out.mesh),
                0,
                "{name}"
            );
            assert_junctions_shared(&out.mesh);
            assert!(
                stuck(&out) <= 0.01,
                "{name}: {} kept ({} islands)",
                out.kept_share,
                out.island_share
            );
        }
    }
}

/// The same output for one thread and for several.
#[test]
fn independent_of_thread_count() {
    let vol = heart(&PhantomParams {
        size: 32,
        noise: 0.01,
        seed: 3,
        ..Default::default()
    })
    .unwrap();
    let r = Resolved::defaults(&vol);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| remeshed(&vol, &r, 2.0).1)
    };
    let (a, b) = (run(1), run(3));
    assert_eq!(a.mesh.triangles, b.mesh.triangles);
    assert_eq!(a.mesh.positions, b.mesh.positions);
    assert_eq!(a.mesh.junctions.len(), b.mesh.junctions.len());
    // the shares reported are sums over the triangles: bit for bit too
    assert_eq!(a.kept_share.to_bits(), b.kept_share.to_bits());
    assert_eq!(a.island_share.to_bits(), b.island_share.to_bits());
    assert_eq!(a.kept_vertices, b.kept_vertices);
}

#[test]
fn bad_parameters_are_errors() {
    let vol = common::volume([2, 2, 2], &[0, 1, 0, 0, 0, 0, 0, 0]);
    let mesh = extraction(&vol, &Resolved::defaults(&vol));
    for p in [
        RemeshParams {
            target_edge: 0.0,
            ..Default::default()
        },
        RemeshParams {
            target_edge: f64::NAN,
            ..Default::default()
        },
        RemeshParams {
            max_displacement: -1.0,
            ..Default::default()
        },
        RemeshParams {
            min_edge: Some(-0.5),
            ..Default::default()
        },
    ] {
        let e = remesh(&mesh, &Sizing::uniform(2.0), &p)
            .err()
            .expect("an error");
        assert!(e.to_string().contains("must be"), "{e}");
    }
}

/// A sulcus-like fold, as in a cortical grey-matter map: a grey sheet two
/// voxels thick over a white block, folded down into a slot so that its two
/// banks face each other across one voxel of the outside (CSF) label, at
/// several targets up to 3 voxels. No crossings, ≤ 1 % left as extracted,
/// both banks kept apart (the gap's label keeps its volume within 30 %).
/// The earlier remesher, with one uniform target, crossed the banks and had
/// to keep the smoothed extraction around them.
#[test]
fn fold_with_banks_one_voxel_apart() {
    let n = 32usize;
    let values: Vec<i64> = (0..n * n * n)
        .map(|i| {
            let (x, y, z) = (i % n, i / n % n, i / (n * n));
            let inside =
                (2..n - 2).contains(&x) && (2..n - 2).contains(&y) && (2..n - 6).contains(&z);
            if !inside {
                return 0;
            }
            // the slot x 12..19, z 6.. ; its grey lining two voxels thick, its
            // middle column x = 15 (one voxel) the outside label
            let slot = (12..19).contains(&x) && z >= 6;
            if slot {
                if x == 15 && z >= 8 { 0 } else { 1 }
            } else if z >= n - 8 {
                1
            } else {
                2
            }
        })
        .collect();
    let vol = common::volume([n, n, n], &values);
    let r = Resolved::defaults(&vol);
    for target_edge in [2.0, 3.0] {
        let (mesh, out) = remeshed(&vol, &r, target_edge);
        let name = format!("fold, L = {target_edge}");
        assert_remeshed_cleanly(&name, &out);
        let q = quality(&out.mesh, Some(&mesh), &QualityOptions::target(target_edge));
        for l in &q.labels {
            if let Some(c) = l.change {
                assert!(
                    c.abs() <= 0.3,
                    "{name}: label {} changed {c}: {}",
                    l.value,
                    q.summary()
                );
            }
        }
        assert!(
            out.mesh.triangle_count() * 2 < mesh.triangle_count(),
            "{name}: remeshed coarser"
        );
    }
}

/// Two parallel walls one voxel thick (labels 2 and 3, one voxel of label 1
/// between them), with steps in them, across a block of label 1: no
/// crossings, ≤ 1 % left as extracted, both walls keep their volume within
/// 30 %.
#[test]
fn two_parallel_one_voxel_walls() {
    let (nx, ny, nz) = (24usize, 28usize, 28usize);
    let values: Vec<i64> = (0..nx * ny * nz)
        .map(|i| {
            let (x, y, z) = (i % nx, i / nx % ny, i / (nx * ny));
            if !(2..nx - 2).contains(&x) || !(2..ny - 2).contains(&y) || !(2..nz - 2).contains(&z) {
                return 0;
            }
            let step = usize::from(y >= 14) + usize::from(z >= 10);
            let wall = 9 + step;
            if x == wall {
                2
            } else if x == wall + 2 {
                3
            } else {
                1
            }
        })
        .collect();
    let vol = common::volume([nx, ny, nz], &values);
    let r = Resolved::defaults(&vol);
    for target_edge in [2.0, 4.0] {
        let (mesh, out) = remeshed(&vol, &r, target_edge);
        let name = format!("walls, L = {target_edge}");
        assert_remeshed_cleanly(&name, &out);
        let q = quality(&out.mesh, Some(&mesh), &QualityOptions::target(target_edge));
        for value in [2, 3] {
            let l = q.labels.iter().find(|l| l.value == value).unwrap();
            let c = l.change.unwrap();
            assert!(
                c.abs() <= 0.3,
                "{name}: wall {value} changed {c}: {}",
                q.summary()
            );
        }
    }
}

/// Islands made where the preprocessing fattens (voxels of one label that
/// touch only along an edge or at a corner, inside another, and between
/// two labels), as noise in real segmentations leaves them: remeshed, none
/// turns inside out.
#[test]
fn fattened_islands_stay_outward() {
    let n = 22usize;
    let mut x = 7u64;
    let mut next = move |m: usize| {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x % m as u64) as usize
    };
    for case in 0..6 {
        let mut values: Vec<i64> = (0..n * n * n)
            .map(|i| {
                if case % 2 == 1 && i / (n * n) < n / 2 {
                    3
                } else {
                    1
                }
            })
            .collect();
        for k in 0..30 {
            let (i, j, l) = (2 + next(n - 6), 2 + next(n - 6), 2 + next(n - 6));
            let d = [(1, 1, 0), (1, 0, 1), (0, 1, 1), (1, 1, 1), (1, 0, 0)][k % 5];
            values[(l * n + j) * n + i] = 2;
            values[((l + d.2) * n + j + d.1) * n + i + d.0] = 2;
        }
        let vol = common::volume([n, n, n], &values);
        for target_edge in [1.0, 2.0, 3.0] {
            let (_, out) = remeshed(&vol, &Resolved::defaults(&vol), target_edge);
            let name = format!("fattened islands, case {case}, L = {target_edge}");
            assert_eq!(
                assert_valid_but_intersections(&name, &out.mesh),
                0,
                "{name}"
            );
            assert!(out.kept_share <= 0.01, "{name}: {} kept", out.kept_share);
        }
    }
}

/// A digitised ball (radius 5 voxels) keeps its volume through remeshing at
/// the default target edge: an interpolating mesh on a curved surface spans
/// chords that lie inside it (about h²/(8 r) on average, 5 % of this ball's
/// volume at h = 2 voxels); the last iterations move vertices off the
/// reference so that the triangles lie on it on average.
#[test]
fn a_ball_keeps_its_volume() {
    let n = 16usize;
    let c = (n as f64 - 1.0) / 2.0;
    let values: Vec<i64> = (0..n * n * n)
        .map(|i| {
            let (x, y, z) = (i % n, (i / n) % n, i / (n * n));
            let d = [x, y, z].map(|k| k as f64 - c);
            i64::from((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() < 5.0)
        })
        .collect();
    let vol = common::volume([n, n, n], &values);
    let r = Resolved::defaults(&vol);
    let (extracted, out) = remeshed(&vol, &r, 2.0);
    let ball = vol.id_of(1).unwrap();
    let before = extracted.signed_volume(&extracted.label_surface(ball));
    let after = out.mesh.signed_volume(&out.mesh.label_surface(ball));
    let change = after / before - 1.0;
    assert!(
        change.abs() < 0.025,
        "volume {before} -> {after} ({change:+.4})"
    );
    assert_eq!(assert_valid_but_intersections("ball", &out.mesh), 0);
}

/// Where two regions touch across a voxel face or two inside a third (the
/// kmeans head has thousands of such contacts), their junction curve is a
/// small closed loop of three to five edges. Relaxed by straight-line
/// midpoints and projection, such a loop bunched its vertices together (a
/// 3-loop's median shortest/longest edge on the head was 0.36, and over half
/// of the head's triangles under 20° sat on these loops); relaxed along the
/// curve by arc length, its vertices spread evenly.
#[test]
fn small_junction_loops_spread_their_vertices() {
    // blobs of three labels in a fourth, on the head's 2 × 2 × 3 mm voxels
    let n = 28usize;
    let mut rng = common::Rng(7);
    let blobs: Vec<([f64; 3], f64, i64)> = (0..400)
        .map(|_| {
            let c = [0, 1, 2].map(|_| 2.0 + rng.below(24 * 16) as f64 / 16.0);
            (
                c,
                0.8 + rng.below(16) as f64 / 16.0,
                1 + rng.below(3) as i64,
            )
        })
        .collect();
    let values: Vec<i64> = (0..n * n * n)
        .map(|i| {
            let p = [i % n, (i / n) % n, i / (n * n)].map(|k| k as f64);
            blobs
                .iter()
                .find(|(c, r, _)| (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>() < r * r)
                .map_or(0, |b| b.2)
        })
        .collect();
    let vol = on_head_voxels([n, n, n], &values);
    let r = Resolved::defaults(&vol);
    let (_, out) = remeshed(&vol, &r, RemeshParams::default_target(vol.geometry()));
    assert_remeshed_cleanly("contacts", &out);
    let mesh = &out.mesh;
    let (mut loops, mut even) = (0, 0);
    for c in mesh
        .junctions
        .iter()
        .filter(|c| c.closed && c.vertices.len() <= 5)
    {
        let n = c.vertices.len();
        let edges: Vec<f64> = (0..n)
            .map(|i| {
                let (u, v) = (c.vertices[i], c.vertices[(i + 1) % n]);
                (mesh.positions[u as usize] - mesh.positions[v as usize]).length()
            })
            .collect();
        let (lo, hi) = edges.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &e| {
            (lo.min(e), hi.max(e))
        });
        loops += 1;
        even += usize::from(lo >= 0.5 * hi);
    }
    assert!(loops >= 10, "only {loops} small loops to test");
    assert!(even * 10 >= loops * 9, "{even} of {loops} small loops even");
}

/// A voxel of a third label on an interface, with one face on the far side,
/// makes a junction loop of four vertices around that face. Taubin's λ/μ
/// passes keep a curve's low frequencies, but such a loop is all high
/// frequency: ten passes left it at 7 % of its size (its edges 0.07 mm on
/// 1 mm voxels, so below any target that the loop could never be coarsened
/// and every triangle at it was a sliver: 69 % of the triangles under 20° on
/// a 117-label parcellation-like volume). Smoothing gives closed loops their
/// size back, and the remeshed loop has edges near the target.
#[test]
fn a_small_junction_loop_keeps_its_size() {
    let n = 8;
    let values: Vec<i64> = (0..n * n * n)
        .map(|i| {
            let (x, y, z) = (i % n, (i / n) % n, i / (n * n));
            if (x, y, z) == (4, 4, 4) {
                2
            } else if z >= 4 {
                1
            } else {
                0
            }
        })
        .collect();
    let vol = common::volume([n, n, n], &values);
    let r = Resolved::defaults(&vol);
    let mesh = extraction(&vol, &r);
    let net = septa::remesh::network::Network::new(&mesh);
    let loops: Vec<&Vec<u32>> = net
        .curves
        .iter()
        .filter(|c| c.closed)
        .map(|c| &c.vertices)
        .collect();
    assert_eq!(loops.len(), 1, "one loop around the voxel's lower face");
    let perimeter = |pos: &[glam::DVec3], vs: &[u32]| -> f64 {
        (0..vs.len())
            .map(|i| (pos[vs[i] as usize] - pos[vs[(i + 1) % vs.len()] as usize]).length())
            .sum()
    };
    let before = perimeter(&mesh.positions, loops[0]);
    let smoothed = septa::remesh::smooth::smooth(&mesh, &net, 10, 0.5);
    let after = perimeter(&smoothed, loops[0]);
    assert!(
        after >= 0.9 * before,
        "loop perimeter {before} -> {after} after smoothing"
    );
    // remeshed at the default target (2 voxels, down to 0.5 where needed)
    let (_, out) = remeshed(&vol, &r, 2.0);
    assert_eq!(assert_valid_but_intersections("loop", &out.mesh), 0);
    let shortest = out
        .mesh
        .triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| (t[k], t[(k + 1) % 3])))
        .map(|(a, b)| (out.mesh.positions[a as usize] - out.mesh.positions[b as usize]).length())
        .fold(f64::INFINITY, f64::min);
    assert!(shortest > 0.3, "shortest edge {shortest} mm");
}

/// Labels 1 below and 2 above an interface, on the head's voxels (36 × 36
/// × 8), with a third label on `percent` % of the voxels of the two layers
/// at the interface: a web of junction loops.
fn noisy_interface(percent: u64) -> LabelVolume {
    let (nx, ny, nz) = (36usize, 36usize, 8usize);
    let mut rng = common::Rng(11);
    let values: Vec<i64> = (0..nx * ny * nz)
        .map(|i| {
            let z = i / (nx * ny);
            let noise = (3..5).contains(&z) && rng.below(100) < percent;
            if noise {
                3
            } else if z < 4 {
                1
            } else {
                2
            }
        })
        .collect();
    on_head_voxels([nx, ny, nz], &values)
}

/// Noise voxels of a third label on an interface, on the head's 2 × 2 × 3
/// mm voxels: the interface between their junction loops is a web of
/// strips. A strip 1.5 targets wide is too wide for one row of triangles
/// (edges over 1.5 targets, which the remesher splits) and too narrow for
/// two rows as wide as the target (edges of 0.75 to both curves, which no
/// collapse can take out: the edges across would be too long again); on
/// the noisy head most short edges were edges from a junction vertex into
/// its patch, in such strips. The target comes down where a strip holds
/// whole rows of equilateral triangles. Measured here: edges from junction
/// vertices into patches short 24 % before, 16 % after; all edges in range
/// 87.2 % before, 88.4 % after (the rest: caps of four-vertex loops, whose
/// centre vertex has edges of 0.73 targets to the loop and without which
/// the cap's diagonal would be 1.4).
#[test]
fn strips_between_noise_loops_hold_whole_rows() {
    let vol = noisy_interface(6);
    let r = Resolved::defaults(&vol);
    let (_, out) = remeshed(&vol, &r, RemeshParams::default_target(vol.geometry()));
    assert_remeshed_cleanly("noisy interface", &out);
    let m = &out.mesh;
    let mut on_curve = vec![false; m.vertex_count()];
    for c in &m.junctions {
        for &v in &c.vertices {
            on_curve[v as usize] = true;
        }
    }
    // edges in a patch (once per patch) with one end on a junction curve and
    // the other inside the patch
    let mut uses: std::collections::HashMap<(u32, u32, u32), u32> = Default::default();
    for (t, tri) in m.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k].min(tri[(k + 1) % 3]), tri[k].max(tri[(k + 1) % 3]));
            *uses.entry((a, b, m.triangle_patch[t])).or_default() += 1;
        }
    }
    let (mut edges, mut short) = (0, 0);
    for (&(a, b, _), &n) in &uses {
        if n != 2 || on_curve[a as usize] == on_curve[b as usize] {
            continue;
        }
        let (pa, pb) = (m.positions[a as usize], m.positions[b as usize]);
        edges += 1;
        short += usize::from((pa - pb).length() < 0.8 * out.sizing.at((pa + pb) * 0.5));
    }
    assert!(edges >= 1000, "only {edges} edges from junction vertices");
    assert!(
        short * 5 <= edges,
        "{short} of {edges} edges from junction vertices into patches short"
    );
}

/// A third label on 30 % of the voxels of two layers at an interface, on
/// the head's 2 × 2 × 3 mm voxels: a web of junction curves with narrow
/// strips of patch between them. A vertex inside such a strip has edges
/// to three, four or five junction vertices; every collapse that removes it
/// makes an edge between junction vertices inside the patch, or a triangle
/// on three of them. Those are made where no other patch has the same edge
/// and no label region turns inside out (every label surface component
/// keeps the sign of its volume); refused outright, they left vertices
/// squeezed between curves, most of the short edges on the noisy head
/// (90.7 % of its edges in range then, 92.0 % now). Measured here: 89.1 %
/// of edges in range before, 90.1 % after.
#[test]
fn squeezed_vertices_between_junction_curves_collapse() {
    let vol = noisy_interface(30);
    let r = Resolved::defaults(&vol);
    let (_, out) = remeshed(&vol, &r, RemeshParams::default_target(vol.geometry()));
    assert_remeshed_cleanly("dense noise on an interface", &out);
    let q = quality(
        &out.mesh,
        None,
        &QualityOptions {
            target_edge_mm: RemeshParams::default_target(vol.geometry()),
            local: Some(&out.sizing),
        },
    );
    assert!(
        q.edges.within_range >= 0.895,
        "{:.4} of edges in range",
        q.edges.within_range
    );
}
