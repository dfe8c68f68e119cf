//! Extract + remesh a volume and validate (development tool).
use std::time::Instant;
use septa::config::{Config, Resolved};
use septa::extract::{ExtractOptions, extract, label_infos};
use septa::mesh::validate::{Options, validate};
use septa::remesh::{RemeshParams, remesh, triangle_quality};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let vol = septa::io::read_label_volume(args[1].as_ref(), &Default::default()).unwrap();
    let (vol, r) = match args.get(2) {
        Some(c) if c != "-" => Config::from_file(c.as_ref()).unwrap().resolve(vol).unwrap(),
        _ => { let r = Resolved::defaults(&vol); (vol, r) }
    };
    let target: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(2.0);
    let t = Instant::now();
    let pre = septa::preprocess::preprocess(&vol, &r);
    let mesh = extract(&pre.refined, label_infos(&vol, None), *vol.geometry(), &ExtractOptions::default()).unwrap();
    println!("extract {:?}: {} tris", t.elapsed(), mesh.triangle_count());
    let t = Instant::now();
    let out = remesh(&mesh, &RemeshParams { target_edge: target, ..Default::default() }).unwrap();
    println!("remesh {:?}: {} tris {} verts, {} intersections left", t.elapsed(), out.mesh.triangle_count(), out.mesh.vertex_count(), out.intersections_left);
    for (name, mm) in [("extraction", &mesh), ("smoothed", &out.smoothed)] {
        let rep = validate(mm, &Options { intersections: true, fidelity: None });
        println!("{name}: {}", rep.check("no self-intersections").map_or(0, |c| c.failures));
    }
    let m = &out.mesh;
    let mut lens: Vec<f64> = m.triangles.iter().flat_map(|t| (0..3).map(move |k| (t[k], t[(k + 1) % 3]))).map(|(a, b)| (m.positions[a as usize] - m.positions[b as usize]).length()).collect();
    lens.sort_by(f64::total_cmp);
    let within = lens.iter().filter(|&&l| l >= 0.8 * target && l <= 4.0 / 3.0 * target).count() as f64 / lens.len() as f64;
    let q: Vec<f64> = m.triangles.iter().map(|t| { let [a, b, c] = t.map(|v| m.positions[v as usize]); triangle_quality(a, b, c) }).collect();
    let angles: Vec<f64> = m.triangles.iter().map(|t| {
        let p = t.map(|v| m.positions[v as usize]);
        (0..3).map(|k| { let (u, w) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]); u.angle_between(w).to_degrees() }).fold(180.0, f64::min)
    }).collect();
    let ok20 = angles.iter().filter(|&&a| a >= 20.0).count() as f64 / angles.len() as f64;
    println!("edges within [0.8L,1.33L]: {:.1}%  median {:.3}  min angle >= 20: {:.2}%  min angle {:.2}  min quality {:.3}", 100.0 * within, lens[lens.len() / 2], 100.0 * ok20, angles.iter().cloned().fold(180.0, f64::min), q.iter().cloned().fold(1.0, f64::min));
    let t = Instant::now();
    let rep = validate(m, &Options { intersections: true, fidelity: None });
    println!("validate {:?}\n{}", t.elapsed(), rep.summary());
    if args.get(4).is_some() {
        septa::io::mesh_ply::write_ply(args[4].as_ref(), m).unwrap();
    }
}
