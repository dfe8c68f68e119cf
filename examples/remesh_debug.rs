//! Debug: classify intersecting pairs after remeshing (development tool).
use septa::config::{Config, Resolved};
use septa::extract::{ExtractOptions, extract, label_infos};
use septa::remesh::{RemeshParams, remesh};
use septa::remesh::project::closest_on_triangle;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let vol = septa::io::read_label_volume(args[1].as_ref(), &Default::default()).unwrap();
    let (vol, r) = match args.get(2) {
        Some(c) if c != "-" => Config::from_file(c.as_ref()).unwrap().resolve(vol).unwrap(),
        _ => { let r = Resolved::defaults(&vol); (vol, r) }
    };
    let target: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(2.0);
    let pre = septa::preprocess::preprocess(&vol, &r);
    let mesh = extract(&pre.refined, label_infos(&vol, None), *vol.geometry(), &ExtractOptions::default()).unwrap();
    let out = remesh(&mesh, &RemeshParams { target_edge: target, ..Default::default() }).unwrap();
    let m = &out.mesh;
    let net = septa::remesh::network::Network::new(m);
    let pairs = septa::mesh::intersect::self_intersections(&m.positions, &m.triangles);
    let sm = &out.smoothed;
    let ref_normal = |p: glam::DVec3, patch: u32| -> glam::DVec3 {
        let mut best = (f64::INFINITY, glam::DVec3::ZERO);
        for (t, q) in sm.triangles.iter().zip(&sm.triangle_patch) {
            if *q != patch { continue; }
            let [a, b, c] = t.map(|v| sm.positions[v as usize]);
            let d = (closest_on_triangle(p, a, b, c) - p).length();
            if d < best.0 { best = (d, (b - a).cross(c - a).normalize()); }
        }
        best.1
    };
    let mut folded = 0;
    for (t, &q) in m.triangles.iter().zip(&m.triangle_patch) {
        let [a, b, c] = t.map(|v| m.positions[v as usize]);
        let n = (b - a).cross(c - a).normalize();
        if n.dot(ref_normal((a + b + c) / 3.0, q)) < 0.0 { folded += 1; }
    }
    println!("folded triangles: {folded} of {}", m.triangles.len());
    let dist = |p: glam::DVec3, patch: u32| -> f64 {
        sm.triangles.iter().zip(&sm.triangle_patch).filter(|(_, q)| **q == patch).map(|(t, _)| {
            let [a, b, c] = t.map(|v| sm.positions[v as usize]);
            (closest_on_triangle(p, a, b, c) - p).length()
        }).fold(f64::INFINITY, f64::min)
    };
    for &(a, b) in pairs.iter().take(30) {
        let (ta, tb) = (m.triangles[a as usize], m.triangles[b as usize]);
        let (pa, pb) = (m.triangle_patch[a as usize], m.triangle_patch[b as usize]);
        let shared = ta.iter().filter(|v| tb.contains(v)).count();
        let kinds = |t: [u32; 3]| t.map(|v| match net.kind[v as usize] { septa::remesh::network::VertexKind::Interior => 'i', septa::remesh::network::VertexKind::Curve(_) => 'c', _ => 'K' }).iter().collect::<String>();
        let ca = ta.iter().map(|&v| m.positions[v as usize]).sum::<glam::DVec3>() / 3.0;
        let cb = tb.iter().map(|&v| m.positions[v as usize]).sum::<glam::DVec3>() / 3.0;
        println!("{a}/{b} patches {pa:?}{:?} / {pb:?}{:?} shared {shared} kinds {} {} centroid dist to own ref {:.3} {:.3}; vtx dist {:?} {:?}", m.patches[pa as usize].labels, m.patches[pb as usize].labels, kinds(ta), kinds(tb), dist(ca, pa), dist(cb, pb),
            ta.map(|v| (dist(m.positions[v as usize], pa) * 1000.0).round() / 1000.0), tb.map(|v| (dist(m.positions[v as usize], pb) * 1000.0).round() / 1000.0));
    }
    println!("{} pairs", pairs.len());
}
