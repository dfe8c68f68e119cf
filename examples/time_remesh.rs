//! Times the remeshing steps on a volume file (for profiling):
//! `cargo run --release --example time_remesh -- VOLUME [TARGET_EDGE_MM]`.
use septa::config::Resolved;
use septa::extract::{ExtractOptions, extract, label_infos};
use septa::remesh::{RemeshParams, remesh};
use std::time::Instant;
fn main() {
    let path = std::env::args().nth(1).expect("volume");
    let vol = septa::io::read_label_volume(path.as_ref(), &Default::default()).unwrap();
    let target_edge = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| RemeshParams::default_target(vol.geometry()));
    let pre = septa::preprocess::preprocess(&vol, &Resolved::defaults(&vol));
    let mesh = extract(
        &pre.refined,
        label_infos(&vol, None),
        *vol.geometry(),
        &ExtractOptions::default(),
    )
    .unwrap();
    let t = Instant::now();
    let params = RemeshParams {
        target_edge,
        ..Default::default()
    };
    let sizing = params.sizing(pre.refined.grid(), vol.geometry());
    let out = remesh(&mesh, &sizing, &params).unwrap();
    println!(
        "{} -> {} triangles in {:.3} s, {:.2} % of the surface left as extracted; {:?}",
        mesh.triangle_count(),
        out.mesh.triangle_count(),
        t.elapsed().as_secs_f64(),
        100.0 * out.kept_share,
        out.timings
    );
}
