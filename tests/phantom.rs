//! The synthetic heart: labels, geometry, determinism, junctions, noise, and
//! the shipped config that names its labels.

use std::path::Path;

use septa::config::Config;
use septa::phantom::{LABELS, PhantomParams, heart};
use septa::volume::LabelVolume;

fn params(size: usize, noise: f64, seed: u64) -> PhantomParams {
    PhantomParams {
        size,
        noise,
        seed,
        ..Default::default()
    }
}

fn make(size: usize, noise: f64, seed: u64) -> LabelVolume {
    heart(&params(size, noise, seed)).unwrap()
}

/// Label values per voxel, x fastest.
fn values(v: &LabelVolume) -> Vec<i64> {
    v.ids().iter().map(|&i| v.value(i)).collect()
}

fn value_of(name: &str) -> i64 {
    LABELS.iter().find(|(_, n)| *n == name).unwrap().0
}

/// Calls `f` with the labels of the 2×2 voxels around every interior grid edge
/// (along each axis), in cyclic order.
fn for_each_edge(v: &LabelVolume, mut f: impl FnMut([i64; 4])) {
    let d = v.dims();
    let s = d.strides();
    let n = d.to_array();
    let vals = values(v);
    for axis in 0..3 {
        let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
        for i in 0..d.len() {
            let c = d.coords(i);
            if c[u] + 1 < n[u] && c[w] + 1 < n[w] {
                let (a, b) = (i + s[u], i + s[w]);
                f([vals[i], vals[a], vals[a + s[w]], vals[b]]);
            }
        }
    }
}

/// Grid edges around which some label occupies exactly two diagonally
/// opposite voxels of the four.
fn critical_edges(v: &LabelVolume) -> usize {
    let mut count = 0;
    for_each_edge(v, |q| {
        let diagonal =
            |a: usize, b: usize, c: usize, d: usize| q[a] == q[c] && q[b] != q[a] && q[d] != q[a];
        if diagonal(0, 1, 2, 3) || diagonal(1, 0, 3, 2) {
            count += 1;
        }
    });
    count
}

fn distinct(labels: &mut [i64]) -> usize {
    labels.sort_unstable();
    1 + labels.windows(2).filter(|w| w[0] != w[1]).count()
}

/// Grid edges around which exactly three labels meet (triple curves).
fn triple_edges(v: &LabelVolume) -> usize {
    let mut count = 0;
    for_each_edge(v, |mut q| count += (distinct(&mut q) == 3) as usize);
    count
}

/// Label sets of the 2×2×2 voxels around grid vertices where at least four
/// labels meet.
fn quadruple_vertices(v: &LabelVolume) -> Vec<Vec<i64>> {
    let d = v.dims();
    let s = d.strides();
    let vals = values(v);
    let mut found = Vec::new();
    for i in 0..d.len() {
        let c = d.coords(i);
        if (0..3).any(|a| c[a] + 1 >= d.to_array()[a]) {
            continue;
        }
        let mut cube: Vec<i64> = (0..8)
            .map(|k| vals[i + (k & 1) * s[0] + (k >> 1 & 1) * s[1] + (k >> 2) * s[2]])
            .collect();
        if distinct(&mut cube) >= 4 {
            cube.dedup();
            found.push(cube);
        }
    }
    found
}

/// Number of voxel faces between labels `a` and `b`.
fn shared_faces(v: &LabelVolume, a: i64, b: i64) -> usize {
    let d = v.dims();
    let vals = values(v);
    let mut count = 0;
    for i in 0..d.len() {
        let c = d.coords(i);
        for (axis, step) in d.strides().into_iter().enumerate() {
            if c[axis] + 1 < d.to_array()[axis] {
                let (p, q) = (vals[i], vals[i + step]);
                count += ((p, q) == (a, b) || (p, q) == (b, a)) as usize;
            }
        }
    }
    count
}

#[test]
fn every_label_occurs_from_size_16() {
    let all: Vec<i64> = LABELS.iter().map(|l| l.0).collect();
    assert_eq!(all, (0..8).collect::<Vec<_>>());
    for size in [16, 17, 33, 64] {
        let v = make(size, 0.0, 1);
        assert_eq!(v.values(), all.as_slice(), "size {size}");
        assert!(v.voxel_counts().iter().all(|&c| c > 0));
    }
}

#[test]
fn several_sizes_scale_and_centre() {
    for size in [16, 33, 64] {
        let spacing = [0.5, 1.0, 2.5];
        let v = heart(&PhantomParams {
            size,
            spacing,
            ..Default::default()
        })
        .unwrap();
        assert_eq!(v.dims().to_array(), [size; 3]);
        let g = v.geometry();
        assert_eq!(g.spacing(), spacing);
        assert_eq!(g.direction(), septa::volume::Geometry::IDENTITY_DIRECTION);
        let mid = (size as f64 - 1.0) / 2.0;
        let centre = g.index_to_physical([mid; 3].into());
        assert!(centre.length() < 1e-9, "size {size}: centre at {centre}");
        // The heart fills a similar fraction of the volume at every size.
        let background = v.voxel_counts()[0] as f64 / v.dims().len() as f64;
        assert!(
            (0.8..0.93).contains(&background),
            "size {size}: {background}"
        );
    }
}

#[test]
fn tiny_sizes_work() {
    for size in 4..16 {
        let v = make(size, 0.1, 3);
        assert_eq!(v.dims().len(), size * size * size);
        assert!(v.values().windows(2).all(|w| w[0] < w[1]));
        assert!(v.voxel_counts().iter().all(|&c| c > 0));
    }
}

#[test]
fn bad_parameters_are_errors() {
    let cases = [
        (params(3, 0.0, 1), "size"),
        (params(2049, 0.0, 1), "size"),
        (params(16, -0.1, 1), "noise"),
        (params(16, 1.5, 1), "noise"),
        (params(16, f64::NAN, 1), "noise"),
    ];
    for (p, needle) in cases {
        let e = heart(&p).unwrap_err();
        assert!(matches!(e, septa::Error::Invalid(_)), "{e:?}");
        assert!(
            e.to_string().contains(needle),
            "{e} should mention {needle}"
        );
    }
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let p = PhantomParams {
            size: 16,
            spacing: [1.0, bad, 1.0],
            ..Default::default()
        };
        let e = heart(&p).unwrap_err().to_string();
        assert!(e.contains("spacing"), "{e}");
    }
}

#[test]
fn same_seed_same_volume_other_seed_other_noise() {
    assert_eq!(
        make(40, 0.0, 1),
        make(40, 0.0, 2),
        "the clean phantom ignores the seed"
    );
    let a = make(40, 0.05, 7);
    assert_eq!(a, make(40, 0.05, 7));
    let b = make(40, 0.05, 8);
    assert_ne!(a, b);
    assert_ne!(a, make(40, 0.0, 7));
    assert_eq!(make(40, 0.0, 7), heart(&params(40, 0.0, 7)).unwrap());
}

#[test]
fn independent_of_the_number_of_threads() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| make(48, 0.05, 11))
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
}

#[test]
fn lv_and_rv_blood_never_touch_when_clean() {
    let (lv, rv) = (value_of("lv_blood"), value_of("rv_blood"));
    for size in [16, 33, 48, 64, 100, 128] {
        let v = make(size, 0.0, 1);
        assert_eq!(shared_faces(&v, lv, rv), 0, "size {size}");
    }
}

#[test]
fn arteries_touch_each_other_and_the_atria() {
    let [la, ra, ao, pa] = ["la_blood", "ra_blood", "aorta", "pulmonary_artery"].map(value_of);
    for size in [33, 64, 128] {
        let v = make(size, 0.0, 1);
        assert!(shared_faces(&v, ao, pa) > 0, "size {size}");
        for artery in [ao, pa] {
            assert!(
                shared_faces(&v, artery, la) + shared_faces(&v, artery, ra) > 0,
                "size {size}"
            );
        }
    }
}

#[test]
fn triple_and_quadruple_junctions_exist() {
    let [la, ra, ao, pa] = ["la_blood", "ra_blood", "aorta", "pulmonary_artery"].map(value_of);
    for size in [33, 64, 128] {
        let v = make(size, 0.0, 1);
        assert!(triple_edges(&v) > 100, "size {size}: {}", triple_edges(&v));
        let quads = quadruple_vertices(&v);
        assert!(quads.len() >= 5, "size {size}: {quads:?}");
        // Where the two arteries touch an atrium.
        let meeting = |q: &Vec<i64>| {
            q.contains(&ao) && q.contains(&pa) && (q.contains(&la) || q.contains(&ra))
        };
        assert!(quads.iter().any(meeting), "size {size}: {quads:?}");
    }
}

#[test]
fn artery_walls_are_thin() {
    let v = make(64, 0.0, 1);
    let d = v.dims();
    let vals = values(&v);
    for artery in ["aorta", "pulmonary_artery"].map(value_of) {
        let (mut wall, mut surface) = (0, 0);
        for i in 0..d.len() {
            if vals[i] != artery {
                continue;
            }
            wall += 1;
            let c = d.coords(i);
            let s = d.strides();
            let other = (0..3).any(|a| {
                (c[a] > 0 && vals[i - s[a]] != artery)
                    || (c[a] + 1 < d.to_array()[a] && vals[i + s[a]] != artery)
            });
            surface += other as usize;
        }
        assert!(
            surface as f64 > 0.97 * wall as f64,
            "label {artery}: {surface} of {wall} on the surface"
        );
    }
}

#[test]
fn noise_multiplies_critical_edges() {
    let clean = critical_edges(&make(64, 0.0, 1));
    let noisy = critical_edges(&make(64, 0.01, 1));
    assert!(clean < 120, "clean phantom at 64³: {clean} critical edges");
    assert!(
        noisy > 2 * clean + 50,
        "noise 0.01: {noisy} vs clean {clean}"
    );
    let noisier = critical_edges(&make(64, 0.05, 1));
    assert!(
        noisier > 3 * noisy,
        "noise 0.05: {noisier} vs 0.01: {noisy}"
    );
}

#[test]
fn noise_only_takes_labels_of_neighbours_at_interfaces() {
    let size = 33;
    let clean = values(&make(size, 0.0, 1));
    let noisy_volume = make(size, 0.2, 5);
    let noisy = values(&noisy_volume);
    let d = noisy_volume.dims();
    let n = size as i64;
    let (mut interface, mut flipped) = (0, 0);
    for i in 0..d.len() {
        let c = d.coords(i).map(|x| x as i64);
        let mut face_other = false;
        let mut neighbours = Vec::new();
        for dz in -1..=1i64 {
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    let p = [c[0] + dx, c[1] + dy, c[2] + dz];
                    if (dx, dy, dz) == (0, 0, 0) || p.iter().any(|&x| x < 0 || x >= n) {
                        continue;
                    }
                    let l = clean[d.index(p[0] as usize, p[1] as usize, p[2] as usize)];
                    neighbours.push(l);
                    face_other |= dx.abs() + dy.abs() + dz.abs() == 1 && l != clean[i];
                }
            }
        }
        interface += face_other as usize;
        if noisy[i] != clean[i] {
            flipped += 1;
            assert!(face_other, "voxel {c:?} flipped away from interfaces");
            assert!(
                neighbours.contains(&noisy[i]),
                "voxel {c:?} took a label not around it"
            );
        }
    }
    let rate = flipped as f64 / interface as f64;
    assert!(
        (rate - 0.2).abs() < 0.03,
        "{flipped} of {interface} interface voxels flipped"
    );
}

#[test]
fn shipped_config_names_the_phantom_labels() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/heart.toml");
    let config = Config::from_file(&path).unwrap();
    let names: Vec<(i64, &str)> = config.names.iter().map(|(v, n)| (*v, n.as_str())).collect();
    assert_eq!(names, LABELS.to_vec());
    assert_eq!(config.remesh.target_edge, Some(3.0));
    let volume = make(32, 0.0, 1);
    let (resolved_volume, resolved) = config.resolve(volume.clone()).unwrap();
    assert_eq!(resolved_volume, volume, "the config adds no labels");
    assert!(resolved.warnings.is_empty(), "{:?}", resolved.warnings);
    let id = |name: &str| volume.id_of(value_of(name)).unwrap();
    assert_eq!(resolved.outside, id("background"));
    assert_eq!(resolved.rank[id("myocardium") as usize], 0);
    assert_eq!(resolved.separations.len(), 1);
    assert_eq!(
        resolved.separations[0].labels,
        vec![id("lv_blood"), id("rv_blood")]
    );
    assert_eq!(resolved.separations[0].by, id("myocardium"));
}

#[test]
fn shipped_phantom_is_what_the_generator_makes() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/heart_phantom_48.nii.gz");
    let read = septa::io::read_label_volume(&path, &Default::default()).unwrap();
    let made = heart(&PhantomParams {
        size: 48,
        spacing: [2.0; 3],
        noise: 0.005,
        seed: 1,
    })
    .unwrap();
    assert_eq!(read.dims(), made.dims());
    assert_eq!(read.values(), made.values());
    assert_eq!(read.ids(), made.ids());
    let (g, h) = (read.geometry(), made.geometry());
    assert_eq!(g.spacing(), h.spacing());
    assert_eq!(g.origin(), h.origin());
    assert_eq!(g.direction(), h.direction());
}

/// Numbers for the documentation: `cargo test --release --test phantom -- --ignored --nocapture`.
#[test]
#[ignore]
fn report() {
    for size in [64, 256] {
        for noise in [0.0, 0.01] {
            let p = params(size, noise, 1);
            heart(&p).unwrap();
            let start = std::time::Instant::now();
            let runs = 5;
            for _ in 0..runs {
                heart(&p).unwrap();
            }
            let time = start.elapsed() / runs;
            let v = heart(&p).unwrap();
            println!(
                "size {size} noise {noise}: {time:?} per volume, {} critical edges, {} triple edges, {} quadruple vertices",
                critical_edges(&v),
                triple_edges(&v),
                quadruple_vertices(&v).len()
            );
            if size == 64 && noise == 0.0 {
                for (&(value, name), count) in LABELS.iter().zip(v.voxel_counts()) {
                    println!("  {value} {name}: {count}");
                }
            }
        }
    }
}
