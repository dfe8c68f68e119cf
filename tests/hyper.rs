//! STEVE iso-hypersurfaces: the derived vector-path table and the paper's
//! facts, the closed oriented 3-manifold on random 4-D volumes, time slices
//! (closed surfaces; VESTA at frame times), files, and bad input.

mod common;

use std::collections::{HashMap, HashSet};

use common::Rng;
use proptest::prelude::*;
use septa::hyper::cell::{
    CUBES, HALF_EDGES, SQUARES, cube_id, other_axes, square_id, square_toxels,
};
use septa::hyper::table::{CONNECT_ALL, CellShape, cell_shape, vector_paths};
use septa::hyper::{
    HyperOptions, Hypersurface, check_closed_manifold, hypersurface, hypersurface_image,
    stack_frames,
};
use septa::io::{Image, Samples};
use septa::iso::{Decompose, IsoOptions, Mode, iso_surface};
use septa::mesh::InterfaceMesh;
use septa::mesh::validate::{Options, validate};
use septa::star::trace_per_edge;
use septa::volume::{Dims, Geometry};

const MODES: [Mode; 3] = [Mode::Disconnect, Mode::Connect, Mode::Mixed];

fn opts(iso: f64, mode: Mode, displace: bool) -> HyperOptions {
    HyperOptions {
        iso,
        mode,
        displace,
    }
}

fn run(values: &[f64], d: [usize; 4], o: &HyperOptions) -> Hypersurface {
    hypersurface(values, d, Geometry::identity(), 1.0, o).unwrap()
}

/// Signed 4-volume enclosed by the tetrahedra (positive when they face
/// outward): Σ det[p1 − p0, p2 − p0, p3 − p0, p0] / 24.
fn signed_volume(h: &Hypersurface) -> f64 {
    h.tets
        .iter()
        .map(|t| {
            let p = t.map(|v| h.points[v as usize]);
            let m = [sub(p[1], p[0]), sub(p[2], p[0]), sub(p[3], p[0]), p[0]];
            det4(m) / 24.0
        })
        .sum()
}

fn sub(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]]
}

/// Determinant of four column vectors.
fn det4(c: [[f64; 4]; 4]) -> f64 {
    let mut m = [[0.0; 4]; 4];
    for (j, col) in c.iter().enumerate() {
        for i in 0..4 {
            m[i][j] = col[i];
        }
    }
    let mut det = 1.0;
    for k in 0..4 {
        let p = (k..4)
            .max_by(|&a, &b| m[a][k].abs().total_cmp(&m[b][k].abs()))
            .unwrap();
        if m[p][k] == 0.0 {
            return 0.0;
        }
        if p != k {
            m.swap(p, k);
            det = -det;
        }
        det *= m[k][k];
        for i in k + 1..4 {
            let f = m[i][k] / m[k][k];
            for j in k..4 {
                m[i][j] -= f * m[k][j];
            }
        }
    }
    det
}

fn assert_slice_valid(m: &InterfaceMesh, what: &str) {
    let report = validate(m, &Options::default());
    assert!(report.passed(), "{what}: {}", report.summary());
    if m.triangle_count() > 0 {
        let v = m.signed_volume(&m.label_surface(0));
        assert!(v > 0.0, "{what}: enclosed volume {v}");
    }
}

// ───────────────────────────── the table and the paper's facts ─────────────────────────────

fn poly_summary(s: &CellShape) -> Vec<(Vec<usize>, usize)> {
    (0..s.polys as usize)
        .map(|p| (s.poly_lengths(p), s.tet_count(p)))
        .collect()
}

#[test]
fn table_has_192_paths_over_32_cubes_and_24_connectivity_points() {
    let t = vector_paths();
    assert_eq!(t.len(), 32 * 2 * 3);
    let cubes: HashSet<u8> = t.iter().map(|p| p.cube).collect();
    let squares: HashSet<u8> = t.iter().flat_map(|p| [p.from, p.to]).collect();
    assert_eq!((cubes.len(), squares.len()), (CUBES, SQUARES));
    // every (square, half-edge) incidence is entered and left equally often
    let mut balance: HashMap<(u8, u8), i32> = HashMap::new();
    for p in t {
        *balance.entry((p.from, p.half_edge)).or_default() += 1;
        *balance.entry((p.to, p.half_edge)).or_default() -= 1;
    }
    assert!(balance.values().all(|&b| b == 0));
}

#[test]
fn single_toxel_is_a_tetrahedron_per_cell_and_16_in_all() {
    for o in 0..16 {
        let s = cell_shape(1 << o, 0);
        assert_eq!(poly_summary(&s), vec![(vec![3, 3, 3, 3], 1)], "toxel {o}");
        assert!(s.is_tetrahedron(0));
    }
    // the whole toxel: 16 cells, 16 tetrahedra over its 8 cube centres (the 16-cell)
    let mut v = vec![0.0; 81];
    v[40] = 1.0;
    for mode in MODES {
        let h = run(&v, [3, 3, 3, 3], &opts(0.5, mode, false));
        assert_eq!((h.points.len(), h.tets.len()), (8, 16));
        let r = check_closed_manifold(h.points.len(), &h.tets);
        assert!(r.is_manifold(), "{r:?}");
        assert_eq!(r.triangles, 32);
        // the cross-polytope of radius ½: 4-volume (2^4 / 4!) (½)^4 = 1/24
        assert!((signed_volume(&h) - 1.0 / 24.0).abs() < 1e-12);
    }
}

#[test]
fn past_active_future_inactive_is_a_cube_of_24_tetrahedra() {
    for mask in [0x00ffu16, 0xff00] {
        for connect in [0, CONNECT_ALL] {
            let s = cell_shape(mask, connect);
            assert_eq!(poly_summary(&s), vec![(vec![4; 6], 24)]);
        }
    }
}

#[test]
fn toxels_sharing_a_volume_give_a_triangular_strut_of_14_tetrahedra() {
    for a in 0..16 {
        for axis in 0..4 {
            let b = a ^ (1 << axis);
            if b < a {
                continue;
            }
            let s = cell_shape(1 << a | 1 << b, 0);
            assert_eq!(poly_summary(&s), vec![(vec![3, 3, 4, 4, 4], 14)]);
        }
    }
}

#[test]
fn toxels_sharing_only_a_face_are_a_point_of_ambiguity() {
    let mut pairs = 0;
    for a in 0..16usize {
        for b in a + 1..16usize {
            if (a ^ b).count_ones() != 2 {
                continue;
            }
            pairs += 1;
            let mask = (1u16 << a) | (1 << b);
            let amb: Vec<usize> = (0..SQUARES)
                .filter(|&s| {
                    let t = square_toxels(s);
                    (t[0] == a && t[3] == b) || (t[1] == a && t[2] == b)
                })
                .collect();
            assert_eq!(amb.len(), 1, "toxels {a} {b} share one square");
            assert_eq!(
                septa::hyper::cell::ambiguous_squares(mask),
                1 << amb[0],
                "that square is the only point of ambiguity"
            );
            // disconnect: two tetrahedra
            let s = cell_shape(mask, 0);
            assert_eq!(poly_summary(&s), vec![(vec![3; 4], 1), (vec![3; 4], 1)]);
            // connect: one element of four 3-cycles and two 6-cycles, 16 tetrahedra
            let s = cell_shape(mask, 1 << amb[0]);
            assert_eq!(poly_summary(&s), vec![(vec![3, 3, 3, 3, 6, 6], 16)]);
        }
    }
    assert_eq!(pairs, 48);
}

#[test]
fn toxels_sharing_only_an_edge_or_a_vertex_stay_apart() {
    for a in 0..16usize {
        for b in a + 1..16usize {
            if (a ^ b).count_ones() < 3 {
                continue;
            }
            for connect in [0, CONNECT_ALL] {
                let s = cell_shape(1 << a | 1 << b, connect);
                assert_eq!(
                    poly_summary(&s),
                    vec![(vec![3; 4], 1), (vec![3; 4], 1)],
                    "toxels {a} {b}"
                );
            }
        }
    }
}

/// Each polyhedron's cycles, with cycle `i` reversed when `flip(half_edge)`,
/// form a consistently oriented closed surface; returns its genus per
/// polyhedron, or `None` if orientation fails.
fn oriented_genus(s: &CellShape, flip: impl Fn(usize) -> bool) -> Option<Vec<i64>> {
    let mut out = Vec::new();
    for p in 0..s.polys as usize {
        let mut dir: HashMap<(u8, u8), i32> = HashMap::new();
        let mut verts = HashSet::new();
        let mut faces = 0i64;
        for i in s.poly_cycles(p) {
            faces += 1;
            let mut c = s.cycle(i).to_vec();
            if flip(s.cycle_half_edge[i] as usize) {
                c.reverse();
            }
            for k in 0..c.len() {
                verts.insert(c[k]);
                *dir.entry((c[k], c[(k + 1) % c.len()])).or_default() += 1;
            }
        }
        for (&(a, b), &n) in &dir {
            if n != 1 || dir.get(&(b, a)) != Some(&1) {
                return None;
            }
        }
        let chi = verts.len() as i64 - (dir.len() / 2) as i64 + faces;
        out.push((2 - chi) / 2);
    }
    Some(out)
}

#[test]
fn every_polyhedron_of_every_configuration_is_consistently_oriented() {
    let mut toroidal = [0usize; 2];
    for mask in 0..=u16::MAX {
        for (m, connect) in [0, CONNECT_ALL].into_iter().enumerate() {
            let s = cell_shape(mask, connect);
            let g = oriented_genus(&s, |_| false)
                .unwrap_or_else(|| panic!("mask {mask:016b} connect {m}"));
            assert!(g.iter().all(|&x| x == 0 || x == 1), "mask {mask:016b}");
            toroidal[m] += g.iter().filter(|&&x| x == 1).count();
        }
    }
    // toroidal polyhedra exist (a ring of active toxels around the vertex);
    // complementing the mask swaps the modes, so the counts agree
    assert_eq!(toroidal[0], toroidal[1]);
    assert_eq!(toroidal[0] + toroidal[1], 3720);
}

/// The determinant rule is the only rule "VESTA's direction in the 3-space
/// across the half-edge, times a sign per half-edge" (up to a global sign)
/// under which all polyhedra are oriented: search all 256 sign choices.
#[test]
fn the_orientation_rule_is_unique_up_to_sign() {
    let masks: Vec<u16> = (0..=u16::MAX).filter(|m| m.count_ones() <= 3).collect();
    let shapes: Vec<CellShape> = masks
        .iter()
        .flat_map(|&m| [cell_shape(m, 0), cell_shape(m, CONNECT_ALL)])
        .collect();
    // direction of our cycles relative to VESTA's: s (−1)^d (checked below)
    let rel = |h: usize| (h & 1 == 1) != ((h / 2) % 2 == 1);
    let mut found = Vec::new();
    for eps in 0..256u32 {
        // flip = our direction differs from "VESTA × ε"
        let ok = shapes
            .iter()
            .all(|s| oriented_genus(s, |h| rel(h) != (eps >> h & 1 == 1)).is_some());
        if ok {
            found.push(eps);
        }
    }
    let ours: u32 = (0..8).filter(|&h| rel(h)).map(|h| 1 << h).sum();
    assert_eq!(found, vec![ours.min(!ours & 0xff), ours.max(!ours & 0xff)]);
}

/// Around every half-edge, our cycles are VESTA's cycles of the 2×2×2 toxels
/// across it (its own tracer, `septa::star`), run in direction s·(−1)^d.
#[test]
fn cycles_are_vestas_in_the_3_space_across_each_half_edge() {
    let mut rng = Rng(7);
    for mask in 0..=u16::MAX {
        let amb = septa::hyper::cell::ambiguous_squares(mask);
        let mut connects = vec![0, CONNECT_ALL];
        if amb != 0 {
            connects.push(rng.next() as u32 & amb);
        }
        for connect in connects {
            let s = cell_shape(mask, connect);
            for h in 0..HALF_EDGES {
                let (d, side) = (h / 2, h & 1);
                let t = other_axes(d);
                let toxel = |o3: usize| -> usize {
                    (0..3).map(|i| ((o3 >> i) & 1) << t[i]).sum::<usize>() | side << d
                };
                let m3: u8 = (0..8)
                    .map(|o3| (((mask >> toxel(o3)) & 1) as u8) << o3)
                    .sum();
                let face_cube = |f: usize| -> u8 {
                    let a = f / 4;
                    let (b, c) = match a {
                        0 => (1, 2),
                        1 => (0, 2),
                        _ => (0, 1),
                    };
                    let lo = ((f & 1) << t[b]) | (((f >> 1) & 1) << t[c]) | side << d;
                    cube_id(t[a], lo) as u8
                };
                let c3: u8 = (0..6)
                    .filter(|&e| connect >> square_id(d, side, t[e / 2], e & 1) & 1 == 1)
                    .map(|e| 1u8 << e)
                    .sum();
                let star = trace_per_edge(m3, c3);
                let mut vesta: Vec<Vec<u8>> = (0..star.cycles as usize)
                    .map(|i| {
                        star.cycle(i)
                            .iter()
                            .map(|st| face_cube(st.face as usize))
                            .collect()
                    })
                    .collect();
                let forward = (side == 1) == (d % 2 == 0);
                let mut ours: Vec<Vec<u8>> = (0..s.cycles as usize)
                    .filter(|&i| s.cycle_half_edge[i] as usize == h)
                    .map(|i| {
                        let mut c = s.cycle(i).to_vec();
                        if !forward {
                            c.reverse();
                        }
                        c
                    })
                    .collect();
                for c in vesta.iter_mut().chain(ours.iter_mut()) {
                    let k = c.iter().enumerate().min_by_key(|x| x.1).unwrap().0;
                    c.rotate_left(k);
                }
                vesta.sort();
                ours.sort();
                assert_eq!(ours, vesta, "mask {mask:016b} half-edge {h}");
            }
        }
    }
}

// ───────────────────────────── whole volumes ─────────────────────────────

fn random_values(d: [usize; 4], seed: u64, levels: u64) -> Vec<f64> {
    let mut rng = Rng(seed);
    let n: usize = d.iter().product();
    (0..n).map(|_| rng.below(levels) as f64).collect()
}

/// Smooth-ish values: a random blob moving in time plus noise.
fn blob_values(d: [usize; 4], seed: u64) -> Vec<f64> {
    let mut rng = Rng(seed);
    let c: Vec<f64> = (0..3)
        .map(|a| rng.below(d[a] as u64 * 10) as f64 / 10.0)
        .collect();
    let v: Vec<f64> = (0..3)
        .map(|_| rng.below(100) as f64 / 100.0 - 0.5)
        .collect();
    let r = 0.5 + rng.below(20) as f64 / 10.0;
    let mut out = Vec::new();
    for t in 0..d[3] {
        for z in 0..d[2] {
            for y in 0..d[1] {
                for x in 0..d[0] {
                    let p = [x as f64, y as f64, z as f64];
                    let dist: f64 = (0..3)
                        .map(|a| (p[a] - c[a] - v[a] * t as f64).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    out.push(100.0 * (r - dist) + rng.below(30) as f64);
                }
            }
        }
    }
    out
}

/// Frame `k` of a 4-D sample array.
fn frame(values: &[f64], d: [usize; 4], k: usize) -> Vec<f64> {
    let n = d[0] * d[1] * d[2];
    values[k * n..(k + 1) * n].to_vec()
}

/// Triangles as position triples (rotated to start at the smallest, keeping
/// orientation), rounded to 1e-9.
fn triangle_set(m: &InterfaceMesh) -> Vec<[[i64; 3]; 3]> {
    let key = |p: glam::DVec3| [p.x, p.y, p.z].map(|c| (c * 1e9).round() as i64);
    let mut out: Vec<[[i64; 3]; 3]> = m
        .triangles
        .iter()
        .map(|t| {
            let mut k = t.map(|v| key(m.positions[v as usize]));
            let i = (0..3).min_by_key(|&i| k[i]).unwrap();
            k.rotate_left(i);
            k
        })
        .collect();
    out.sort();
    out
}

/// The slice at a frame's own time is VESTA's surface of that frame (same
/// mode, H decomposition): same triangles, support points bit for bit.
fn assert_frame_slices_are_vesta(
    values: &[f64],
    d: [usize; 4],
    o: &HyperOptions,
    h: &Hypersurface,
) {
    for k in 0..d[3] {
        let s = h.slice(k as f64).unwrap();
        assert_eq!((s.frame, s.separated), (Some(k), 0));
        let vesta = iso_surface(
            &frame(values, d, k),
            Dims::new(d[0], d[1], d[2]).unwrap(),
            Geometry::identity(),
            &IsoOptions {
                iso: o.iso,
                mode: o.mode,
                decompose: Decompose::H,
                displace: o.displace,
            },
        )
        .unwrap();
        assert_eq!(
            triangle_set(&s.mesh),
            triangle_set(&vesta.mesh),
            "frame {k} of {d:?} {o:?}"
        );
        // support points (not centroids) are identical, bit for bit
        let ours: HashSet<[u64; 3]> = s
            .mesh
            .positions
            .iter()
            .map(|p| [p.x, p.y, p.z].map(f64::to_bits))
            .collect();
        for p in &vesta.mesh.positions[..vesta.stats.support_points] {
            assert!(ours.contains(&[p.x, p.y, p.z].map(f64::to_bits)));
        }
    }
}

fn check_all(values: &[f64], d: [usize; 4], o: &HyperOptions, times: &[f64], what: &str) {
    let h = run(values, d, o);
    let r = check_closed_manifold(h.points.len(), &h.tets);
    assert!(r.passed(), "{what}: {r:?}");
    assert_eq!(r.cone_points, h.stats.higher_genus, "{what}");
    if !h.tets.is_empty() {
        assert!(signed_volume(&h) > 0.0, "{what}");
    }
    for &t in times {
        let s = h.slice(t).unwrap();
        assert_slice_valid(&s.mesh, &format!("{what} at t = {t}"));
    }
    assert_frame_slices_are_vesta(values, d, o, &h);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    /// Noise: every configuration occurs; all modes, with and without
    /// displacement: a closed oriented 3-manifold; slices anywhere are closed
    /// outward surfaces; frame slices are VESTA.
    #[test]
    fn noise_volumes_give_closed_oriented_hypersurfaces(
        nx in 1usize..5, ny in 1usize..5, nz in 1usize..4, nt in 2usize..5,
        seed in any::<u64>(), levels in 2u64..5, t_frac in 0.0f64..1.0,
    ) {
        let d = [nx, ny, nz, nt];
        let v = random_values(d, seed, levels);
        let iso = (levels / 2) as f64;
        let t = -0.6 + t_frac * (nt as f64 + 0.2);
        for displace in [false, true] {
            for mode in MODES {
                let o = opts(iso, mode, displace);
                let what = format!("{d:?} seed {seed} {o:?}");
                check_all(&v, d, &o, &[t, 0.5, nt as f64 - 1.5, -0.25], &what);
            }
        }
    }

    /// Smooth moving blobs with real values.
    #[test]
    fn blob_volumes_give_closed_oriented_hypersurfaces(
        nx in 2usize..6, ny in 2usize..6, nz in 2usize..5, nt in 2usize..5,
        seed in any::<u64>(), t_frac in 0.0f64..1.0,
    ) {
        let d = [nx, ny, nz, nt];
        let v = blob_values(d, seed);
        let t = t_frac * (nt as f64 - 1.0);
        for mode in MODES {
            let o = opts(50.0, mode, true);
            check_all(&v, d, &o, &[t, 0.25, 0.75], &format!("{d:?} seed {seed} {mode:?}"));
        }
    }
}

#[test]
fn output_does_not_depend_on_the_thread_count() {
    let d = [6, 5, 4, 5];
    let v = random_values(d, 3, 3);
    let o = opts(1.0, Mode::Mixed, true);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| run(&v, d, &o));
    let many = rayon::ThreadPoolBuilder::new()
        .num_threads(4)
        .build()
        .unwrap()
        .install(|| run(&v, d, &o));
    assert_eq!(one.points, many.points);
    assert_eq!(one.tets, many.tets);
    let (a, b) = (one.slice(1.3).unwrap(), many.slice(1.3).unwrap());
    assert_eq!(a.mesh.positions, b.mesh.positions);
    assert_eq!(a.mesh.triangles, b.mesh.triangles);
}

#[test]
fn slices_through_vertices_stay_closed() {
    // undisplaced: time cubes sit exactly at k + ½, so t = 0.5 hits vertices
    let d = [4, 4, 3, 3];
    let v = random_values(d, 11, 2);
    for mode in MODES {
        let h = run(&v, d, &opts(1.0, mode, false));
        let s = h.slice(0.5).unwrap();
        assert!(s.frame.is_none());
        assert_slice_valid(&s.mesh, &format!("{mode:?}"));
        // outside the hypersurface's time range: empty
        assert_eq!(h.slice(-0.6).unwrap().mesh.triangle_count(), 0);
        assert_eq!(h.slice(2.6).unwrap().mesh.triangle_count(), 0);
    }
}

#[test]
fn physical_space_follows_the_affine_and_the_time_step() {
    let d = [3, 3, 3, 3];
    let mut v = vec![0.0; 81];
    v[40] = 1.0;
    // a mirroring affine (LPS with a flipped axis) and 0.25 s per frame
    let g = Geometry::new(
        [2.0, 1.0, 3.0],
        [10.0, -5.0, 1.0],
        [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    )
    .unwrap();
    let h = hypersurface(&v, d, g, 0.25, &opts(0.5, Mode::Mixed, false)).unwrap();
    let p = h.physical_points();
    let ts: HashSet<u64> = p.iter().map(|q| (q[3] * 1000.0).round() as u64).collect();
    assert_eq!(ts, [125u64, 250, 375].into_iter().collect()); // frames ½, 1, 1½
    let s = h.slice(0.25).unwrap();
    assert_eq!(s.frame, Some(1));
    assert_slice_valid(&s.mesh, "mirrored");
    let c = g.index_to_physical(glam::DVec3::new(1.0, 1.0, 1.0));
    for q in &s.mesh.positions {
        assert!((*q - c).length() <= 1.5 + 1e-9);
    }
}

// ───────────────────────────── files and bad input ─────────────────────────────

#[test]
fn nifti_4d_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let img = septa::hyper::fireball::fireball(6, 3, 1.5, 0.5);
    for name in ["f.nii", "f.nii.gz"] {
        let path = dir.path().join(name);
        septa::io::nifti::write_image(&path, &img).unwrap();
        let back = septa::io::read_image(&path, &Default::default()).unwrap();
        assert_eq!(back.dims, vec![6, 6, 6, 3]);
        assert_eq!(back.samples, img.samples);
        assert_eq!(back.time_step, Some(0.5));
        for (a, b) in back
            .geometry
            .affine()
            .iter()
            .flatten()
            .zip(img.geometry.affine().iter().flatten())
        {
            assert!((a - b).abs() < 1e-5);
        }
        // 3-D commands still refuse it, naming `septa hyper`
        let e = back.dims3().unwrap_err().to_string();
        assert!(e.contains("septa hyper"), "{e}");
    }
}

#[test]
fn hypersurface_ply_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let img = septa::hyper::fireball::fireball(8, 3, 2.0, 0.5);
    let o = opts(50.0, Mode::Mixed, true);
    let h = hypersurface_image(&img, None, &o).unwrap();
    let path = dir.path().join("h.ply");
    let Samples::F32(v) = &img.samples else {
        panic!("float samples")
    };
    let values = h.field_values(v, [8, 8, 8, 3]).unwrap();
    septa::hyper::ply::write_hypersurface_ply(&path, &h, &o, Some(&values)).unwrap();
    let back = septa::hyper::ply::read_hypersurface_ply(&path).unwrap();
    let bv = back.values.clone().unwrap();
    assert!(bv.iter().zip(&values).all(|(a, b)| *a == *b as f32 as f64));
    assert_eq!(back.tets, h.physical_tets());
    let p = h.physical_points();
    assert_eq!(back.points.len(), p.len());
    for (a, b) in back.points.iter().zip(&p) {
        for k in 0..4 {
            assert_eq!(a[k], b[k] as f32 as f64);
        }
    }
    assert_eq!(
        back.kinds.iter().filter(|&&k| k == 0).count(),
        h.stats.support_points
    );
    assert!(back.comments.iter().any(|c| c.contains("STEVE")));
    let r = check_closed_manifold(back.points.len(), &back.tets);
    assert!(r.passed());
}

/// A field interpolated onto the hypersurface: the iso field itself gives the
/// iso value at (unclamped) support points; a field linear in space is
/// reproduced exactly at every vertex (all the averages are of points).
#[test]
fn field_values_interpolate_along_range_vectors() {
    let img = septa::hyper::fireball::fireball(12, 4, 1.0, 1.0);
    let o = opts(50.0, Mode::Mixed, true);
    let h = hypersurface_image(&img, None, &o).unwrap();
    let d = [12, 12, 12, 4];
    let Samples::F32(v) = &img.samples else {
        panic!("float samples")
    };
    let own = h.field_values(v, d).unwrap();
    // support points between two toxels of the volume (not the lids before
    // the first and after the last frame, which keep the inside toxel's value)
    let inner: Vec<f64> = (0..h.stats.support_points)
        .filter(|&i| h.points[i][3] > -0.5 && h.points[i][3] < 3.5)
        .map(|i| own[i])
        .collect();
    let near = inner.iter().filter(|x| (*x - 50.0).abs() < 1e-6).count();
    assert!(near * 100 >= inner.len() * 95, "{near} of {}", inner.len());
    let linear: Vec<f64> = (0..d.iter().product::<usize>())
        .map(|i| {
            let (x, y, z) = (i % 12, (i / 12) % 12, (i / 144) % 12);
            x as f64 + 2.0 * y as f64 - 3.0 * z as f64
        })
        .collect();
    let lv = h.field_values(&linear, d).unwrap();
    for (p, val) in h.points.iter().zip(&lv) {
        let expect = p[0] + 2.0 * p[1] - 3.0 * p[2];
        assert!((val - expect).abs() < 1e-9, "{p:?}: {val} vs {expect}");
    }
    assert!(h.field_values(&linear[1..], d).is_err());
}

#[test]
fn bad_input_gets_clear_errors() {
    let three_d = Image {
        dims: vec![4, 4, 4],
        samples: Samples::U8(vec![0; 64]),
        geometry: Geometry::identity(),
        time_step: None,
        path: "vol.nii".into(),
        sources: Vec::new(),
    };
    let o = HyperOptions::new(1.0);
    let e = hypersurface_image(&three_d, None, &o)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("vol.nii") && e.contains("3-D") && e.contains("--frames"),
        "{e}"
    );
    let mut other = three_d.clone();
    other.dims = vec![4, 4, 5];
    other.samples = Samples::U8(vec![0; 80]);
    other.path = "b.nii".into();
    let e = stack_frames(&[three_d.clone(), other])
        .unwrap_err()
        .to_string();
    assert!(e.contains("b.nii") && e.contains("same grid"), "{e}");
    let e = stack_frames(std::slice::from_ref(&three_d))
        .unwrap_err()
        .to_string();
    assert!(e.contains("at least 2 frames"), "{e}");
    let mut moved = three_d.clone();
    moved.geometry =
        Geometry::new([1.0; 3], [5.0, 0.0, 0.0], Geometry::IDENTITY_DIRECTION).unwrap();
    let e = stack_frames(&[three_d.clone(), moved])
        .unwrap_err()
        .to_string();
    assert!(e.contains("geometry"), "{e}");
    let v = vec![0.0; 16];
    assert!(
        hypersurface(
            &v,
            [2, 2, 2, 2],
            Geometry::identity(),
            1.0,
            &HyperOptions::new(f64::NAN)
        )
        .is_err()
    );
    assert!(hypersurface(&v, [2, 2, 2, 3], Geometry::identity(), 1.0, &o).is_err());
    assert!(hypersurface(&v, [2, 2, 2, 2], Geometry::identity(), 0.0, &o).is_err());
    assert!(hypersurface(&v, [2, 2, 0, 2], Geometry::identity(), 1.0, &o).is_err());
    let h = hypersurface(&v, [2, 2, 2, 2], Geometry::identity(), 1.0, &o).unwrap();
    assert!(h.tets.is_empty());
    assert!(h.slice(f64::NAN).is_err());
    assert_eq!(h.slice(0.5).unwrap().mesh.triangle_count(), 0);
}

/// Larger noise volumes, all options, slices at frame, half-frame and random
/// times (about 3 minutes; run with `--ignored`).
#[test]
#[ignore]
fn stress_bigger_noise() {
    let mut fails = 0;
    for seed in 0..60u64 {
        let d = [9, 8, 7, 6];
        let levels = 2 + seed % 3;
        let v = random_values(d, seed * 7919, levels);
        let iso = (levels / 2) as f64;
        for displace in [false, true] {
            for mode in MODES {
                let o = opts(iso, mode, displace);
                let h = run(&v, d, &o);
                let r = check_closed_manifold(h.points.len(), &h.tets);
                if !r.passed() {
                    eprintln!("manifold {seed} {o:?} {r:?}");
                    fails += 1;
                }
                let mut rng = Rng(seed);
                for k in 0..12 {
                    let t = if k < 4 {
                        k as f64 * 0.5 + 0.5
                    } else {
                        rng.below(6000) as f64 / 1000.0 - 0.5
                    };
                    let s = h.slice(t).unwrap();
                    let rep = validate(&s.mesh, &Options::default());
                    if !rep.passed() {
                        eprintln!(
                            "slice {seed} {o:?} t {t} sep {}: {}",
                            s.separated,
                            rep.summary()
                        );
                        fails += 1;
                    }
                }
            }
        }
    }
    assert_eq!(fails, 0);
}

/// `docs/hyper_table.md` is the derived table (regenerate with
/// `SEPTA_WRITE_TABLE=1 cargo test --test hyper table_document`).
#[test]
fn table_document_is_current() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/hyper_table.md");
    let text = septa::hyper::table::table_markdown();
    if std::env::var_os("SEPTA_WRITE_TABLE").is_some() {
        std::fs::write(&path, &text).unwrap();
    }
    assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
    assert_eq!(
        text.lines()
            .filter(|l| l.starts_with("| ") && l.contains(" → "))
            .count(),
        32
    );
}
