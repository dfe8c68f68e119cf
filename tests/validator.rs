//! The validator catches what it claims to: each check fails on a mesh broken
//! in exactly that way, and passes on valid meshes with cavities and nesting.

mod common;

use common::*;
use septa::extract::ExtractOptions;
use septa::mesh::InterfaceMesh;
use septa::mesh::validate::{Options, Report, validate};

/// A 7³ volume: label 1 is a hollow 5³ shell around a cavity of label 0 that
/// holds a voxel of label 2 (nesting: 0 outside, 1, 0 inside, 2 inside that).
fn nested() -> (
    septa::volume::LabelVolume,
    InterfaceMesh,
    septa::preprocess::Preprocessed,
) {
    let n = 7;
    let mut v = vec![0i64; n * n * n];
    for z in 1..6 {
        for y in 1..6 {
            for x in 1..6 {
                let inner = (2..5).contains(&x) && (2..5).contains(&y) && (2..5).contains(&z);
                v[x + n * (y + n * z)] = if inner { 0 } else { 1 };
            }
        }
    }
    v[3 + n * (3 + n * 3)] = 2;
    let (vol, r) = resolved_outside0(volume([n, n, n], &v));
    let (pre, mesh, rep) = run(&vol, &r, ExtractOptions::default());
    assert!(rep.passed(), "{}", rep.summary());
    (vol, mesh, pre)
}

fn failing(rep: &Report) -> Vec<&'static str> {
    rep.checks
        .iter()
        .filter(|c| c.failures > 0)
        .map(|c| c.name)
        .collect()
}

fn check(mesh: &InterfaceMesh) -> Report {
    validate(mesh, &Options::default())
}

#[test]
fn nested_cavities_are_valid() {
    let (vol, mesh, _) = nested();
    let rep = check(&mesh);
    let l1 = rep.labels.iter().find(|l| l.value == 1).unwrap();
    assert_eq!(l1.components, 2, "outer boundary and cavity");
    let l0 = rep.labels.iter().find(|l| l.value == 0).unwrap();
    assert!(l0.unbounded, "the outside label faces inward");
    // outside the shell, the cavity wall, and the octahedron around the label-2 voxel
    assert_eq!(l0.components, 3);
    let l2 = rep.labels.iter().find(|l| l.value == 2).unwrap();
    assert!((l2.volume_mm3 - 1.0 / 6.0).abs() < 1e-9);
    let _ = vol;
}

#[test]
fn a_missing_triangle_opens_the_surfaces() {
    let (_, mut mesh, _) = nested();
    mesh.triangles.remove(5);
    mesh.triangle_patch.remove(5);
    assert!(failing(&check(&mesh)).contains(&"label surfaces closed"));
}

#[test]
fn a_reversed_triangle_breaks_orientation() {
    let (_, mut mesh, _) = nested();
    let t = mesh.triangles[3];
    mesh.triangles[3] = [t[0], t[2], t[1]];
    assert!(failing(&check(&mesh)).contains(&"label surfaces oriented"));
}

#[test]
fn a_reversed_closed_component_faces_the_wrong_way() {
    let (vol, mut mesh, _) = nested();
    // the patch {0, 2} is a closed octahedron around the inner voxel: reverse it
    let p = mesh
        .patch_of(vol.id_of(0).unwrap(), vol.id_of(2).unwrap())
        .unwrap();
    for (t, &tp) in mesh.triangle_patch.iter().enumerate() {
        if tp == p {
            let tri = mesh.triangles[t];
            mesh.triangles[t] = [tri[0], tri[2], tri[1]];
        }
    }
    assert_only_facing_fails(&mesh);
}

#[test]
fn a_wrong_patch_label_breaks_closure() {
    let (vol, mut mesh, _) = nested();
    // relabel one triangle of {0,1} as {1,2}: both label 0's and label 2's surfaces open
    let wrong = mesh
        .patches
        .iter()
        .position(|p| p.labels == [vol.id_of(1).unwrap(), vol.id_of(2).unwrap()]);
    let wrong = match wrong {
        Some(w) => w as u32,
        None => {
            mesh.patches.push(septa::mesh::Patch {
                labels: [vol.id_of(1).unwrap(), vol.id_of(2).unwrap()],
            });
            (mesh.patches.len() - 1) as u32
        }
    };
    mesh.triangle_patch[0] = wrong;
    assert!(failing(&check(&mesh)).contains(&"label surfaces closed"));
}

#[test]
fn duplicate_degenerate_unused_and_bad_indices() {
    let (_, mesh, _) = nested();
    let mut m = mesh.clone();
    m.positions.push(m.positions[0]);
    let f = failing(&check(&m));
    assert!(
        f.contains(&"no duplicate positions") && f.contains(&"no unused vertices"),
        "{f:?}"
    );

    let mut m = mesh.clone();
    let [a, b, _] = m.triangles[0];
    let mid = (m.positions[a as usize] + m.positions[b as usize]) * 0.5;
    m.positions[m.triangles[0][2] as usize] = mid;
    assert!(failing(&check(&m)).contains(&"no degenerate triangles"));

    let mut m = mesh.clone();
    m.triangles[0][0] = m.positions.len() as u32 + 5;
    assert_eq!(failing(&check(&m)), vec!["vertex indices in range"]);
}

#[test]
fn two_fans_at_a_vertex_are_not_manifold() {
    // the mesh and a translated copy glued at one vertex: every edge is still
    // fine, the glued vertex has two fans per label
    let (_, mut mesh, _) = nested();
    let n = mesh.positions.len() as u32;
    let shift = mesh.positions[0] - mesh.positions[1];
    let copy: Vec<_> = mesh.positions.iter().map(|&p| p + shift).collect();
    mesh.positions.extend(copy);
    let tris: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| if v == 1 { 0 } else { v + n }))
        .collect();
    let patches = mesh.triangle_patch.clone();
    mesh.triangles.extend(tris);
    mesh.triangle_patch.extend(patches);
    let f = failing(&check(&mesh));
    assert!(f.contains(&"label surfaces manifold at vertices"), "{f:?}");
    assert!(!f.contains(&"label surfaces closed"), "{f:?}");
}

#[test]
fn fidelity_catches_a_moved_vertex() {
    let (_, mut mesh, pre) = nested();
    // a vertex of the octahedron around the label-2 voxel at (3,3,3), moved 3 voxels away
    let v = mesh
        .positions
        .iter()
        .position(|p| (*p - glam::DVec3::new(3.5, 3.0, 3.0)).length() < 1e-9)
        .unwrap();
    mesh.positions[v].x += 3.0;
    let rep = validate(
        &mesh,
        &Options {
            intersections: false,
            fidelity: Some((&pre.refined, 0.5)),
        },
    );
    assert!(failing(&rep).contains(&"vertices near their labels"));
}

#[test]
fn intersections_are_found() {
    let (_, mut mesh, _) = nested();
    assert!(
        validate(
            &mesh,
            &Options {
                intersections: true,
                fidelity: None
            }
        )
        .passed()
    );
    // push the centre of the shell's -x face through the cavity wall and the inner octahedron
    let v = mesh
        .positions
        .iter()
        .position(|p| (*p - glam::DVec3::new(0.5, 3.0, 3.0)).length() < 1e-9)
        .unwrap();
    mesh.positions[v].x += 2.5;
    let rep = validate(
        &mesh,
        &Options {
            intersections: true,
            fidelity: None,
        },
    );
    assert!(
        failing(&rep).contains(&"no self-intersections"),
        "{}",
        rep.summary()
    );
}

/// A block of label 1 holding 343 one-voxel cavities of label 0, more than
/// the nesting check tests one ray at a time: it finds every cavity inside
/// the block through its grid of triangles, and a cavity turned inside out
/// among them.
#[test]
fn many_cavities_are_found_nested() {
    let n = 24;
    let mut v = vec![0i64; n * n * n];
    for z in 1..n - 1 {
        for y in 1..n - 1 {
            for x in 1..n - 1 {
                let cavity = [x, y, z].iter().all(|&c| c % 3 == 2 && c < 22);
                v[x + n * (y + n * z)] = if cavity { 0 } else { 1 };
            }
        }
    }
    let (vol, r) = resolved_outside0(volume([n, n, n], &v));
    let (_, mut mesh, rep) = run(&vol, &r, ExtractOptions::default());
    assert!(rep.passed(), "{}", rep.summary());
    let l1 = rep.labels.iter().find(|l| l.value == 1).unwrap();
    assert_eq!(l1.components, 1 + 343, "outer boundary and cavities");
    let l0 = rep.labels.iter().find(|l| l.value == 0).unwrap();
    assert!(l0.unbounded);

    // turn one cavity (the smallest component) inside out
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    fn root(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for t in &mesh.triangles {
        for k in 1..3 {
            let (a, b) = (root(&mut parent, t[0]), root(&mut parent, t[k]));
            parent[a as usize] = b;
        }
    }
    let mut size = vec![0usize; mesh.positions.len()];
    for t in &mesh.triangles {
        size[root(&mut parent, t[0]) as usize] += 1;
    }
    let last = (0..size.len() as u32)
        .filter(|&r| size[r as usize] > 0)
        .min_by_key(|&r| size[r as usize])
        .unwrap();
    let mut turned = 0;
    for t in 0..mesh.triangles.len() {
        let tri = mesh.triangles[t];
        if root(&mut parent, tri[0]) == last {
            mesh.triangles[t] = [tri[0], tri[2], tri[1]];
            turned += 1;
        }
    }
    assert!(
        turned < mesh.triangles.len() / 100,
        "one small cavity turned"
    );
    assert_only_facing_fails(&mesh);
}

/// The validator finds `mesh` wrong in one check only: a surface facing
/// its own label.
fn assert_only_facing_fails(mesh: &InterfaceMesh) {
    let rep = check(mesh);
    assert_eq!(
        failing(&rep),
        vec!["surfaces face away from their label"],
        "{}",
        rep.summary()
    );
}
