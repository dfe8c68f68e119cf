//! `septa::mesh::quality`: exact figures on hand-built meshes, the percentile
//! and histogram rules, distances against shifted copies, volumes, degenerate
//! input, and speed.

use glam::DVec3;
use septa::geom::nearest::SurfaceRef;
use septa::geom::predicates::closest_point_on_triangle;
use septa::mesh::quality::{QualityOptions, percentile, quality};
use septa::mesh::{InterfaceMesh, LabelInfo, Patch};
use septa::volume::Geometry;

/// One patch {0, 1} ("outside", "inside") over the given triangles.
fn one_patch(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> InterfaceMesh {
    InterfaceMesh {
        triangle_patch: vec![0; triangles.len()],
        positions,
        triangles,
        patches: vec![Patch { labels: [0, 1] }],
        labels: vec![
            LabelInfo {
                value: 0,
                name: "outside".into(),
            },
            LabelInfo {
                value: 1,
                name: "inside".into(),
            },
        ],
        ..Default::default()
    }
}

/// Reverses every triangle (patch {0,1} normals point from 0 into 1, so a
/// closed surface of label 1 must face inward in the patch).
fn flipped(mut tris: Vec<[u32; 3]>) -> Vec<[u32; 3]> {
    for t in &mut tris {
        t.swap(1, 2);
    }
    tris
}

fn octahedron() -> InterfaceMesh {
    let p = vec![
        DVec3::X,
        -DVec3::X,
        DVec3::Y,
        -DVec3::Y,
        DVec3::Z,
        -DVec3::Z,
    ];
    // Outward-facing (counter-clockwise seen from outside).
    let t = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [0, 5, 2],
        [2, 5, 1],
        [1, 5, 3],
        [3, 5, 0],
    ];
    one_patch(p, flipped(t))
}

fn tetrahedron() -> InterfaceMesh {
    let p = vec![
        DVec3::new(1.0, 1.0, 1.0),
        DVec3::new(1.0, -1.0, -1.0),
        DVec3::new(-1.0, 1.0, -1.0),
        DVec3::new(-1.0, -1.0, 1.0),
    ];
    let t = vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
    one_patch(p, t)
}

/// Unit cube [0,1]³, outward triangles.
fn cube_outward() -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    for i in 0..8 {
        p.push(DVec3::new(
            (i & 1) as f64,
            ((i >> 1) & 1) as f64,
            ((i >> 2) & 1) as f64,
        ));
    }
    // Quads counter-clockwise seen from outside.
    let quads = [
        [0, 2, 3, 1], // z = 0
        [4, 5, 7, 6], // z = 1
        [0, 1, 5, 4], // y = 0
        [2, 6, 7, 3], // y = 1
        [0, 4, 6, 2], // x = 0
        [1, 3, 7, 5], // x = 1
    ];
    let mut t = Vec::new();
    for q in quads {
        t.push([q[0], q[1], q[2]]);
        t.push([q[0], q[2], q[3]]);
    }
    (p, t)
}

fn cube() -> InterfaceMesh {
    let (p, t) = cube_outward();
    one_patch(p, flipped(t))
}

/// An m × m grid of unit squares in z = 0, each split along the (i,j)–(i+1,j+1) diagonal.
fn grid(m: u32) -> InterfaceMesh {
    let mut p = Vec::new();
    for j in 0..=m {
        for i in 0..=m {
            p.push(DVec3::new(i as f64, j as f64, 0.0));
        }
    }
    let id = |i: u32, j: u32| j * (m + 1) + i;
    let mut t = Vec::new();
    for j in 0..m {
        for i in 0..m {
            t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    one_patch(p, t)
}

fn shifted(m: &InterfaceMesh, d: DVec3) -> InterfaceMesh {
    InterfaceMesh {
        positions: m.positions.iter().map(|p| *p + d).collect(),
        ..m.clone()
    }
}

/// A latitude–longitude sphere of radius `r` with about 2·n_lat·n_lon triangles.
fn sphere(n_lat: u32, n_lon: u32, r: f64, rotate: f64) -> InterfaceMesh {
    let mut p = vec![DVec3::new(0.0, 0.0, r), DVec3::new(0.0, 0.0, -r)];
    for i in 1..n_lat {
        let th = std::f64::consts::PI * i as f64 / n_lat as f64;
        for j in 0..n_lon {
            let ph = 2.0 * std::f64::consts::PI * j as f64 / n_lon as f64 + rotate;
            p.push(r * DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()));
        }
    }
    let id = |i: u32, j: u32| 2 + (i - 1) * n_lon + (j % n_lon);
    let mut t = Vec::new();
    for j in 0..n_lon {
        t.push([0, id(1, j), id(1, j + 1)]);
        t.push([1, id(n_lat - 1, j + 1), id(n_lat - 1, j)]);
    }
    for i in 1..n_lat - 1 {
        for j in 0..n_lon {
            t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    one_patch(p, flipped(t))
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn octahedron_exact() {
    let m = octahedron();
    let r = quality(&m, None, &QualityOptions::target(2f64.sqrt()));
    assert_eq!((r.vertices, r.triangles, r.patches), (6, 8, 1));
    assert_eq!(r.edges.count, 12);
    assert_eq!(r.edges.boundary, 0);
    assert!(close(r.edges.mean_mm, 2f64.sqrt(), 1e-12));
    assert!(close(r.edges.mean_rel, 1.0, 1e-12));
    assert!(close(r.edges.std_rel, 0.0, 1e-12));
    assert_eq!(r.edges.within_range, 1.0);
    assert!(close(r.angles.min_deg, 60.0, 1e-9));
    assert!(close(r.angles.max_deg, 60.0, 1e-9));
    assert!(close(r.angles.min_p1_deg, 60.0, 1e-9));
    assert_eq!((r.angles.min_ge_20, r.angles.min_ge_30), (1.0, 1.0));
    assert_eq!(r.angles.degenerate, 0);
    assert_eq!(r.valence.interior, vec![0, 0, 0, 0, 6]);
    assert_eq!(r.valence.interior_vertices, 6);
    assert_eq!(r.valence.boundary_vertices, 0);
    assert!(r.valence.boundary.is_empty());
    assert!(r.distance.is_none());
    assert_eq!(r.labels.len(), 2);
    assert!(r.labels[0].unbounded);
    assert!(close(r.labels[0].volume_mm3, -4.0 / 3.0, 1e-12));
    assert!(!r.labels[1].unbounded);
    assert!(close(r.labels[1].volume_mm3, 4.0 / 3.0, 1e-12));
    assert_eq!(r.labels[1].name, "inside");
    // Against itself: distance zero, no volume change.
    let r = quality(&m, Some(&m), &QualityOptions::default());
    let d = r.distance.unwrap();
    assert_eq!(d.samples, 6 + 8 + 12);
    assert!(d.hausdorff_mm < 1e-12, "{}", d.hausdorff_mm);
    assert!(r.labels[1].change.unwrap().abs() < 1e-12);
    assert_eq!(
        r.labels[0].change, None,
        "the outside has no relative change"
    );
    assert!(r.edges.target_is_mean);
    assert!(close(r.edges.target_mm, 2f64.sqrt(), 1e-12));
}

#[test]
fn tetrahedron_exact() {
    let r = quality(&tetrahedron(), None, &QualityOptions::default());
    assert!(close(r.angles.min_deg, 60.0, 1e-9));
    assert!(close(r.angles.max_deg, 60.0, 1e-9));
    assert_eq!(r.valence.interior, vec![0, 0, 0, 4]);
    assert!(close(r.labels[1].volume_mm3.abs(), 8.0 / 3.0, 1e-12));
}

#[test]
fn unit_cube_volume_and_angles() {
    let m = cube();
    let r = quality(&m, None, &QualityOptions::target(1.0));
    assert!(close(r.labels[1].volume_mm3, 1.0, 1e-12));
    assert!(r.labels[0].unbounded);
    assert!(close(r.angles.min_deg, 45.0, 1e-9));
    assert!(close(r.angles.max_deg, 90.0, 1e-9));
    assert_eq!(r.angles.min_ge_20, 1.0);
    assert_eq!(r.angles.min_ge_30, 1.0);
    assert_eq!(r.edges.count, 18);
    // 12 cube edges of length 1 in range, 6 diagonals of √2 outside it.
    assert!(close(r.edges.within_range, 12.0 / 18.0, 1e-12));
    assert_eq!(r.valence.interior.iter().sum::<u64>(), 8);
    // Volumes do not depend on where the cube is.
    let far = shifted(&m, DVec3::new(1e6, -2e6, 3e6));
    let r = quality(&far, Some(&m), &QualityOptions::default());
    assert!(close(r.labels[1].volume_mm3, 1.0, 1e-6));
    assert!(close(r.labels[1].change.unwrap(), 0.0, 1e-6));
}

#[test]
fn shifted_copy_hausdorff_is_the_shift() {
    // A plane shifted along its normal: every sample is exactly `s` away.
    let g = grid(6);
    for s in [0.3, 1.7] {
        let r = quality(
            &shifted(&g, DVec3::new(0.0, 0.0, s)),
            Some(&g),
            &QualityOptions::default(),
        );
        let d = r.distance.unwrap();
        assert!(close(d.hausdorff_mm, s, 1e-12), "{d:?}");
        assert!(close(d.mean_mm, s, 1e-12), "{d:?}");
        assert_eq!(d.voxel_mm, 1.0);
        assert!(close(d.hausdorff_at[2], s, 1e-12));
    }
    // A closed cube shifted along z: the top face is `s` away, nothing farther.
    let c = cube();
    let s = 0.25;
    let r = quality(
        &shifted(&c, DVec3::new(0.0, 0.0, s)),
        Some(&c),
        &QualityOptions::default(),
    );
    let d = r.distance.unwrap();
    assert!(close(d.hausdorff_mm, s, 1e-12), "{d:?}");
    assert!(d.mean_mm < s);
    // Volume: same size, so no change.
    assert!(close(r.labels[1].change.unwrap(), 0.0, 1e-12));
    // Voxels: divided by the largest spacing.
    let mut m = shifted(&g, DVec3::new(0.0, 0.0, 1.0));
    m.geometry = Geometry::new([0.5, 2.0, 1.0], [0.0; 3], Geometry::IDENTITY_DIRECTION).unwrap();
    let d = quality(&m, Some(&g), &QualityOptions::default())
        .distance
        .unwrap();
    assert!(close(d.hausdorff_voxels, 0.5, 1e-12));
    assert_eq!(d.voxel_mm, 2.0);
}

#[test]
fn distance_matches_brute_force() {
    // A coarse sphere against a finer, rotated one: the nearest-point answer
    // (the one the report uses) equals the minimum over all triangles.
    let q = sphere(9, 13, 10.0, 0.0);
    let r = sphere(23, 31, 10.3, 0.1);
    let reference = SurfaceRef::new(
        r.triangles
            .iter()
            .map(|t| t.map(|v| r.positions[v as usize]))
            .collect(),
    );
    let mut samples = q.positions.clone();
    for t in &q.triangles {
        let [a, b, c] = t.map(|v| q.positions[v as usize]);
        samples.push((a + b + c) / 3.0);
        samples.push(0.5 * (a + b));
    }
    samples.push(DVec3::new(100.0, -50.0, 3.0));
    samples.push(DVec3::ZERO);
    let mut worst: f64 = 0.0;
    for (k, &x) in samples.iter().enumerate() {
        let brute = r
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| r.positions[v as usize]);
                x.distance_squared(closest_point_on_triangle(x, a, b, c))
            })
            .fold(f64::INFINITY, f64::min);
        let hint = if k % 2 == 0 {
            u32::MAX
        } else {
            (k * 7 % r.triangles.len()) as u32
        };
        let (point, _) = reference.project_from(x, hint);
        assert_eq!(x.distance_squared(point), brute, "sample {k}");
        worst = worst.max(brute.sqrt());
    }
    assert!(worst > 0.0);
    // The report's Hausdorff over the same kind of samples.
    let d = quality(&q, Some(&r), &QualityOptions::default())
        .distance
        .unwrap();
    assert!(d.hausdorff_mm > 0.25 && d.hausdorff_mm < 1.0, "{d:?}");
}

#[test]
fn closest_point_regions_and_degenerate_triangles() {
    let (a, b, c) = (
        DVec3::ZERO,
        DVec3::new(2.0, 0.0, 0.0),
        DVec3::new(0.0, 2.0, 0.0),
    );
    let cp = |p: DVec3| closest_point_on_triangle(p, a, b, c);
    assert_eq!(cp(DVec3::new(0.5, 0.5, 1.0)), DVec3::new(0.5, 0.5, 0.0));
    assert_eq!(cp(DVec3::new(3.0, -1.0, 0.0)), b);
    assert_eq!(cp(DVec3::new(-1.0, 3.0, 0.0)), c);
    assert_eq!(cp(DVec3::new(1.0, -1.0, 5.0)), DVec3::new(1.0, 0.0, 0.0));
    assert_eq!(cp(DVec3::new(-1.0, 1.0, 0.0)), DVec3::new(0.0, 1.0, 0.0));
    assert_eq!(cp(DVec3::new(2.0, 2.0, 0.0)), DVec3::new(1.0, 1.0, 0.0));
    // Collinear and coincident corners: the nearest point of the segment.
    let q = closest_point_on_triangle(DVec3::new(1.0, 1.0, 0.0), a, b, 0.5 * b);
    assert_eq!(q, DVec3::new(1.0, 0.0, 0.0));
    let q = closest_point_on_triangle(DVec3::new(1.0, 1.0, 0.0), a, a, a);
    assert_eq!(q, a);
    let q = closest_point_on_triangle(DVec3::new(5.0, 1.0, 0.0), a, b, b);
    assert_eq!(q, b);
}

#[test]
fn percentile_nearest_rank() {
    assert_eq!(percentile(&[], 50.0), None);
    assert_eq!(percentile(&[7.0], 1.0), Some(7.0));
    let v: Vec<f64> = (1..=200).rev().map(|x| x as f64).collect();
    assert_eq!(percentile(&v, 1.0), Some(2.0)); // rank ⌈2⌉ = 2
    assert_eq!(percentile(&v, 0.5), Some(1.0));
    assert_eq!(percentile(&v, 0.6), Some(2.0)); // rank ⌈1.2⌉ = 2
    assert_eq!(percentile(&v, 50.0), Some(100.0));
    assert_eq!(percentile(&v, 99.0), Some(198.0));
    assert_eq!(percentile(&v, 150.0), Some(200.0));
    assert_eq!(percentile(&v, -3.0), Some(1.0));
}

#[test]
fn first_percentile_of_min_angles() {
    // 100 squares = 200 right isosceles triangles (45°); make the first
    // triangle thin by moving a corner: p1 is the 2nd smallest minimum angle.
    let mut g = grid(10);
    g.positions[0] = DVec3::new(0.9, 0.0, 0.0);
    let r = quality(&g, None, &QualityOptions::default());
    let mut mins: Vec<f64> = g
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| g.positions[v as usize]);
            let ang = |u: DVec3, v: DVec3| u.angle_between(v).to_degrees();
            ang(b - a, c - a)
                .min(ang(a - b, c - b))
                .min(ang(a - c, b - c))
        })
        .collect();
    mins.sort_by(f64::total_cmp);
    assert!(close(r.angles.min_deg, mins[0], 1e-9));
    assert!(close(r.angles.min_p1_deg, mins[1], 1e-9));
    let ge30 = mins.iter().filter(|&&m| m >= 30.0).count();
    assert!(ge30 < 200);
    assert_eq!(r.angles.min_ge_30, ge30 as f64 / 200.0);
}

#[test]
fn grid_valence_histograms_and_edge_range() {
    let m = 4;
    let g = grid(m);
    let r = quality(&g, None, &QualityOptions::target(1.0));
    // Interior: (m−1)² vertices of valence 6.
    assert_eq!(r.valence.interior, vec![0, 0, 0, 0, 0, 0, 9]);
    assert_eq!(r.valence.interior_6, 1.0);
    // Boundary: two corners of valence 2, two of 3, 4(m−1) sides of 4.
    assert_eq!(r.valence.boundary, vec![0, 0, 2, 2, 12]);
    assert_eq!(r.valence.boundary_vertices, 16);
    assert!(close(r.valence.boundary_4, 12.0 / 16.0, 1e-12));
    // 2m(m+1) unit edges in range, m² diagonals (√2 > 4/3) not.
    assert_eq!(r.edges.count, 40 + 16);
    assert_eq!(r.edges.boundary, 16);
    assert!(close(r.edges.within_range, 40.0 / 56.0, 1e-12));
    let mean = (40.0 + 16.0 * 2f64.sqrt()) / 56.0;
    assert!(close(r.edges.mean_rel, mean, 1e-12));
}

#[test]
fn junction_vertices_counted_per_patch() {
    // Two unit cubes side by side: labels 1 (x in [0,1]) and 2 (x in [1,2]) in
    // outside 0. Patches {0,1}, {0,2}, {1,2}; the shared square is patch {1,2}.
    let (p1, t1) = cube_outward();
    let mut positions = p1.clone();
    for i in 0..8 {
        if i & 1 == 1 {
            positions.push(p1[i] + DVec3::X);
        }
    }
    // Vertex ids of the second cube: x=1 corners are 1,3,5,7; x=2 corners 8..12.
    let map2 = |v: u32| if v & 1 == 0 { v + 1 } else { 8 + v / 2 };
    let mut tris = Vec::new();
    let mut patch = Vec::new();
    let faces_x1 = |t: &[u32; 3]| t.iter().all(|&v| v & 1 == 1);
    let faces_x0 = |t: &[u32; 3]| t.iter().all(|&v| v & 1 == 0);
    for t in &t1 {
        if faces_x1(t) {
            // Shared face, outward from label 1: normal from 1 into 2 = patch {1,2} as is.
            tris.push(*t);
            patch.push(2);
        } else {
            tris.push([t[0], t[2], t[1]]); // patch {0,1}: from 0 into 1
            patch.push(0);
        }
    }
    for t in &t1 {
        if faces_x0(t) {
            continue; // the shared face, already there
        }
        let t2 = t.map(map2);
        tris.push([t2[0], t2[2], t2[1]]); // patch {0,2}: from 0 into 2
        patch.push(1);
    }
    let mesh = InterfaceMesh {
        positions,
        triangles: tris,
        triangle_patch: patch,
        patches: vec![
            Patch { labels: [0, 1] },
            Patch { labels: [0, 2] },
            Patch { labels: [1, 2] },
        ],
        ..Default::default()
    };
    let r = quality(&mesh, None, &QualityOptions::default());
    assert_eq!((r.vertices, r.triangles, r.patches), (12, 22, 3));
    let vols: Vec<f64> = r.labels.iter().map(|l| l.volume_mm3).collect();
    assert!(
        close(vols[0], -2.0, 1e-12) && close(vols[1], 1.0, 1e-12) && close(vols[2], 1.0, 1e-12)
    );
    assert_eq!(r.labels[0].name, "label0");
    // The 4 corners of the shared square are junction vertices (the square's
    // edges are used by 3 triangles; its diagonal is inside patch {1,2}).
    assert_eq!(r.valence.boundary_vertices, 4);
    assert_eq!(r.edges.boundary, 4);
    // Each junction vertex appears once per patch: 4 × 3 pairs.
    assert_eq!(r.valence.boundary.iter().sum::<u64>(), 12);
    assert_eq!(r.valence.interior_vertices, 8);
    let s = r.summary();
    assert!(s.contains("12 vertices, 22 triangles, 3 patches"), "{s}");
}

#[test]
fn empty_degenerate_and_huge_inputs_do_not_panic() {
    let empty = InterfaceMesh::default();
    let r = quality(&empty, Some(&empty), &QualityOptions::default());
    assert_eq!((r.vertices, r.triangles, r.edges.count), (0, 0, 0));
    assert_eq!(r.distance.as_ref().unwrap().samples, 0);
    assert!(r.labels.is_empty());
    assert!(!r.summary().is_empty());
    let oct = octahedron();
    quality(&oct, Some(&empty), &QualityOptions::default());
    quality(&empty, Some(&oct), &QualityOptions::default());

    // Zero-area triangles: coincident and collinear corners.
    let m = one_patch(
        vec![DVec3::ZERO, DVec3::X, 2.0 * DVec3::X, DVec3::ZERO],
        vec![[0, 1, 2], [0, 1, 3], [0, 0, 0]],
    );
    let r = quality(&m, Some(&m), &QualityOptions::target(f64::NAN));
    assert_eq!(r.angles.degenerate, 3);
    assert_eq!(r.angles.min_deg, 0.0);
    assert_eq!(r.angles.max_deg, 180.0);
    assert_eq!(r.distance.as_ref().unwrap().hausdorff_mm, 0.0);
    serde_json::to_string(&r).unwrap();

    // Out-of-range vertex ids and patch ids are skipped.
    let mut bad = octahedron();
    bad.triangles.push([0, 1, 99]);
    bad.triangle_patch.push(7);
    quality(&bad, Some(&bad), &QualityOptions::default());

    // Huge coordinates.
    for scale in [1e30, 1e200] {
        let big = InterfaceMesh {
            positions: oct.positions.iter().map(|p| *p * scale).collect(),
            ..oct.clone()
        };
        let r = quality(&big, Some(&oct), &QualityOptions::default());
        assert!(close(r.angles.min_deg, 60.0, 1e-6));
        let d = r.distance.unwrap();
        assert!(d.hausdorff_mm > 0.0 && !d.hausdorff_mm.is_nan());
    }
}

#[test]
fn deterministic_across_thread_counts() {
    let q = sphere(120, 160, 20.0, 0.0);
    let r = sphere(150, 170, 20.2, 0.05);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| quality(&q, Some(&r), &QualityOptions::target(0.8)))
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a, b);
    assert!(a.distance.unwrap().hausdorff_mm > 0.1);
}

/// A finely tessellated sphere against a slightly larger, finer one: the
/// Hausdorff distance is the radius difference plus chord sagitta. (Speed is
/// measured by `benches/`, not here.)
#[test]
fn sphere_against_finer_sphere() {
    let m = sphere(50, 100, 50.0, 0.0);
    let r = quality(&m, Some(&m), &QualityOptions::target(3.0));
    assert!(r.distance.as_ref().unwrap().hausdorff_mm < 1e-9);
    let reference = sphere(100, 100, 50.05, 0.001);
    let r = quality(&m, Some(&reference), &QualityOptions::target(3.0));
    let d = r.distance.unwrap();
    assert!(
        d.hausdorff_mm > 0.04 && d.hausdorff_mm < 1.0,
        "{}",
        d.hausdorff_mm
    );
}
