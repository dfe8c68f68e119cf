//! Times the geometry checks of the pipeline on a volume file:
//! `cargo run --release --example time_checks -- VOLUME [REPS] [DUMP_DIR]`.
//!
//! Extracts and remeshes the volume (as `septa extract` does), then times
//! - the self-intersection check of the smoothed extraction (what the
//!   untangling after smoothing runs), of a jittered copy of it (many
//!   crossings), the subset variant on it (a BVH reused, every 7th triangle),
//! - the self-intersection check of the remeshed mesh (repair, validator),
//! - `quality()` of the remeshed mesh against the extraction.
//!
//! Each is run `REPS` times (default 3); the best time is printed. With
//! `DUMP_DIR`, the pair lists and the quality report are written there (to
//! compare two builds with `cmp`).
use glam::DVec3;
use septa::config::Resolved;
use septa::extract::{ExtractOptions, extract, label_infos};
use septa::geom::intersect::{intersections_in, self_intersections, triangle_bvh};
use septa::geom::nearest::SurfaceRef;
use septa::mesh::quality::{QualityOptions, quality};
use septa::remesh::{RemeshParams, remesh};
use std::io::Write;
use std::time::Instant;

/// CPU seconds (user + system, all threads) of this process so far (Linux).
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // fields after the command name (which is in parentheses)
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|x| x.parse::<f64>().ok()).unwrap_or(0.0);
    // utime and stime are fields 14 and 15 (11 and 12 after the name), in 1/100 s
    (ticks(11) + ticks(12)) / 100.0
}

/// Best wall time and best CPU time over `reps` runs, and the last result.
struct Timing(f64, f64);

impl std::fmt::Display for Timing {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "{:.3} s (CPU {:.2} s)", self.0, self.1)
    }
}

fn best<T>(reps: usize, mut f: impl FnMut() -> T) -> (Timing, T) {
    let mut out = None;
    let (mut wall, mut cpu) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..reps {
        let (t, c) = (Instant::now(), cpu_seconds());
        let r = f();
        wall = wall.min(t.elapsed().as_secs_f64());
        cpu = cpu.min(cpu_seconds() - c);
        out = Some(r);
    }
    (Timing(wall, cpu), out.unwrap())
}

fn dump(dir: Option<&str>, name: &str, pairs: &[(u32, u32)]) {
    let Some(dir) = dir else { return };
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(format!("{dir}/{name}.txt")).expect("dump file"),
    );
    for (a, b) in pairs {
        writeln!(f, "{a} {b}").unwrap();
    }
}

/// FNV-1a over the pair list (to compare runs at a glance).
fn hash(pairs: &[(u32, u32)]) -> u64 {
    let mut h = 0xcbf29ce484222325u64;
    for &(a, b) in pairs {
        for x in [a, b] {
            for byte in x.to_le_bytes() {
                h = (h ^ byte as u64).wrapping_mul(0x100000001b3);
            }
        }
    }
    h
}

/// Writes positions and triangles as raw little-endian arrays.
fn save(path: &str, positions: &[DVec3], triangles: &[[u32; 3]]) {
    let mut b = Vec::new();
    b.extend((positions.len() as u64).to_le_bytes());
    b.extend((triangles.len() as u64).to_le_bytes());
    for p in positions {
        for x in p.to_array() {
            b.extend(x.to_le_bytes());
        }
    }
    for t in triangles {
        for v in t {
            b.extend(v.to_le_bytes());
        }
    }
    std::fs::write(path, b).expect("save");
}

/// Reads what [`save`] wrote.
fn load(path: &str) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let b = std::fs::read(path).expect("load");
    let u64_at = |o: usize| u64::from_le_bytes(b[o..o + 8].try_into().unwrap()) as usize;
    let f64_at = |o: usize| f64::from_le_bytes(b[o..o + 8].try_into().unwrap());
    let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let (nv, nt) = (u64_at(0), u64_at(8));
    let positions = (0..nv)
        .map(|i| {
            DVec3::new(
                f64_at(16 + 24 * i),
                f64_at(24 + 24 * i),
                f64_at(32 + 24 * i),
            )
        })
        .collect();
    let base = 16 + 24 * nv;
    let triangles = (0..nt)
        .map(|i| [0, 1, 2].map(|k| u32_at(base + 12 * i + 4 * k)))
        .collect();
    (positions, triangles)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("volume");
    // `time_checks --saved FILE REPS`: only the self-check of a mesh saved
    // with TIME_CHECKS_SAVE=FILE (for profiling)
    if path == "--saved" {
        let file = args.next().expect("saved mesh");
        let reps: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(3);
        let (p, t) = load(&file);
        let (s, pairs) = best(reps, || self_intersections(&p, &t));
        println!(
            "{} tris: self-check {s}, {} pairs, hash {:016x}",
            t.len(),
            pairs.len(),
            hash(&pairs)
        );
        return;
    }
    let reps: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(3);
    let dir = args.next();
    let dir = dir.as_deref();
    let vol = septa::io::read_label_volume(path.as_ref(), &Default::default()).unwrap();
    let pre = septa::preprocess::preprocess(&vol, &Resolved::defaults(&vol));
    let mesh = extract(
        &pre.refined,
        label_infos(&vol, None),
        *vol.geometry(),
        &ExtractOptions::default(),
    )
    .unwrap();
    let params = RemeshParams {
        target_edge: RemeshParams::default_target(vol.geometry()),
        ..Default::default()
    };
    let sizing = params.sizing(pre.refined.grid(), vol.geometry());
    let t = Instant::now();
    let out = remesh(&mesh, &sizing, &params).unwrap();
    println!(
        "threads {}; remesh {:.2} s; {:?}",
        rayon::current_num_threads(),
        t.elapsed().as_secs_f64(),
        out.timings
    );

    let sm = &out.smoothed;
    if let Ok(cache) = std::env::var("TIME_CHECKS_SAVE") {
        save(&cache, &sm.positions, &sm.triangles);
    }
    let (s, pairs) = best(reps, || self_intersections(&sm.positions, &sm.triangles));
    println!(
        "smoothed    {:>8} tris: self-check {}, {} pairs, hash {:016x}",
        sm.triangles.len(),
        s,
        pairs.len(),
        hash(&pairs)
    );
    dump(dir, "smoothed", &pairs);

    let (s, bvh) = best(reps, || triangle_bvh(&sm.positions, &sm.triangles));
    println!("  of which the BVH build {s}");
    let (s, _) = best(reps, || {
        intersections_in(&sm.positions, &sm.triangles, &bvh, None)
    });
    println!("  and the check with a built BVH {s}");
    // jittered copy: many crossings
    let mut x = 0x9e3779b97f4a7c15u64;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let jit: Vec<DVec3> = sm
        .positions
        .iter()
        .map(|p| *p + DVec3::new(next(), next(), next()) * 0.3)
        .collect();
    let (s, pairs) = best(reps, || self_intersections(&jit, &sm.triangles));
    println!(
        "jittered    {:>8} tris: self-check {}, {} pairs, hash {:016x}",
        sm.triangles.len(),
        s,
        pairs.len(),
        hash(&pairs)
    );
    dump(dir, "jittered", &pairs);
    let bvh = triangle_bvh(&jit, &sm.triangles);
    let subset: Vec<u32> = (0..sm.triangles.len() as u32).step_by(7).collect();
    let (s, pairs) = best(reps, || {
        intersections_in(&jit, &sm.triangles, &bvh, Some(&subset))
    });
    println!(
        "jit. subset {:>8} tris: check {}, {} pairs, hash {:016x}",
        subset.len(),
        s,
        pairs.len(),
        hash(&pairs)
    );
    dump(dir, "jittered_subset", &pairs);

    let m = &out.mesh;
    let (s, pairs) = best(reps, || self_intersections(&m.positions, &m.triangles));
    println!(
        "remeshed    {:>8} tris: self-check {}, {} pairs, hash {:016x}",
        m.triangles.len(),
        s,
        pairs.len(),
        hash(&pairs)
    );
    dump(dir, "remeshed", &pairs);

    let opts = QualityOptions::target(params.target_edge);
    let (s, q) = best(reps, || quality(m, Some(&mesh), &opts));
    println!("quality(): {s}");
    let (s, _) = best(reps, || quality(m, None, &opts));
    println!("  of which without distances {s}");
    let (s, _) = best(reps, || {
        SurfaceRef::new(
            mesh.triangles
                .iter()
                .map(|t| t.map(|v| mesh.positions[v as usize]))
                .collect(),
        )
        .is_empty()
    });
    println!("  and the nearest-point tree {s}");
    let json = serde_json::to_string_pretty(&q).unwrap();
    if let Some(dir) = dir {
        std::fs::write(format!("{dir}/quality.json"), &json).unwrap();
    }
}
