//! Times preprocess and extract on a volume file (for profiling).
use septa::config::Resolved;
use septa::extract::{ExtractOptions, extract, label_infos};
use std::time::Instant;
fn main() {
    let path = std::env::args().nth(1).expect("volume");
    let reps: usize = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let vol = septa::io::read_label_volume(path.as_ref(), &Default::default()).unwrap();
    let r = Resolved::defaults(&vol);
    for _ in 0..reps {
        let t = Instant::now();
        let pre = septa::preprocess::preprocess(&vol, &r);
        let t1 = t.elapsed();
        let mesh = extract(
            &pre.refined,
            label_infos(&vol, None),
            *vol.geometry(),
            &ExtractOptions::default(),
        )
        .unwrap();
        let t2 = t.elapsed();
        println!(
            "preprocess {:?} extract {:?} ({} refined, {} tris, {} verts)",
            t1,
            t2 - t1,
            pre.refined.refined_count(),
            mesh.triangle_count(),
            mesh.vertex_count()
        );
    }
}
