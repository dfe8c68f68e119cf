//! `septa info`: what a label volume holds, in physical terms.

use std::process::ExitCode;

use clap::Args;
use glam::DVec3;

use super::ui::{Ui, count, table};
use super::{VolumeArgs, load, show};
use septa::Result;

#[derive(Args, Debug)]
pub struct InfoArgs {
    #[command(flatten)]
    pub input: VolumeArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// What to say about a volume that looks like an intensity image.
pub fn intensity_note(work: &septa::estimate::Work) -> String {
    work.intensity_note()
}

pub fn run(args: &InfoArgs, ui: &Ui) -> Result<ExitCode> {
    let loaded = load(&args.input, ui)?;
    let v = &loaded.volume;
    let g = v.geometry();
    let d = v.dims();
    let counts = v.voxel_counts();
    let voxel_ml = g.voxel_volume_mm3() / 1000.0;
    // physical bounding box of the voxel corners
    let mut lo = DVec3::splat(f64::MAX);
    let mut hi = DVec3::splat(f64::MIN);
    for c in 0..8 {
        let idx = DVec3::new(
            if c & 1 == 1 { d.nx as f64 - 0.5 } else { -0.5 },
            if c & 2 == 2 { d.ny as f64 - 0.5 } else { -0.5 },
            if c & 4 == 4 { d.nz as f64 - 0.5 } else { -0.5 },
        );
        let p = g.index_to_physical(idx);
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let outside = loaded.resolved.outside;
    let name = |id: u16| loaded.config.display_name(v.value(id));
    let subdivision = septa::preprocess::subdivision_for(&loaded.resolved) as u64;
    let work = septa::estimate::estimate(v, subdivision);
    if args.json {
        let labels: Vec<_> = (0..v.label_count())
            .map(|i| {
                serde_json::json!({
                    "value": v.value(i as u16), "name": name(i as u16), "voxels": counts[i],
                    "volume_ml": counts[i] as f64 * voxel_ml,
                })
            })
            .collect();
        let j = serde_json::json!({
            "file": show(&args.input.volume),
            "dims": d.to_array(), "voxels": d.len(),
            "spacing_mm": g.spacing(), "origin_mm": g.origin(), "direction": g.direction(),
            "affine_lps": g.affine(), "orientation": g.orientation_code(), "space": "LPS mm",
            "extent_mm": {"min": lo.to_array(), "max": hi.to_array()},
            "outside": {"value": v.value(outside), "name": name(outside), "from_config": loaded.resolved.outside_from_config},
            "labels": labels,
            "work": work,
            "extract_memory_bytes": work.bytes(),
            "looks_like_intensity": work.looks_like_intensity(),
        });
        println!("{}", serde_json::to_string_pretty(&j).expect("json"));
        return Ok(ExitCode::SUCCESS);
    }
    let sp = g.spacing();
    let o = g.origin();
    ui.say(format!("file         {}", show(&args.input.volume)));
    ui.say(format!(
        "grid         {} × {} × {} voxels ({})",
        d.nx,
        d.ny,
        d.nz,
        count(d.len() as u64)
    ));
    ui.say(format!(
        "spacing      {:.4} × {:.4} × {:.4} mm",
        sp[0], sp[1], sp[2]
    ));
    ui.say(format!(
        "orientation  {} (the index axes point toward these directions, RAS+ convention)",
        g.orientation_code()
    ));
    ui.say(format!(
        "origin       ({:.3}, {:.3}, {:.3}) mm, LPS: centre of voxel (0, 0, 0)",
        o[0], o[1], o[2]
    ));
    ui.say(format!(
        "extent       x {:.2} .. {:.2}, y {:.2} .. {:.2}, z {:.2} .. {:.2} mm (LPS, {:.1} × {:.1} × {:.1} mm)",
        lo.x, hi.x, lo.y, hi.y, lo.z, hi.z, hi.x - lo.x, hi.y - lo.y, hi.z - lo.z
    ));
    ui.say(format!(
        "outside      label {} ({}){}",
        v.value(outside),
        name(outside),
        if loaded.resolved.outside_from_config {
            ", from the config"
        } else {
            ", the most frequent label on the border"
        }
    ));
    let rows: Vec<Vec<String>> = (0..v.label_count())
        .map(|i| {
            vec![
                v.value(i as u16).to_string(),
                name(i as u16),
                count(counts[i]),
                format!("{:.3}", counts[i] as f64 * voxel_ml),
                format!("{:.2} %", 100.0 * counts[i] as f64 / d.len() as f64),
            ]
        })
        .collect();
    ui.say(format!(
        "boundary     {} voxel faces between labels ({:.1} % of all), {} critical edges, {} critical vertices",
        count(work.boundary_faces),
        100.0 * work.boundary_share(),
        count(work.critical_edges),
        count(work.critical_vertices)
    ));
    ui.say(format!(
        "extract      needs at most about {} of memory (without remeshing)",
        septa::estimate::human_bytes(work.bytes())
    ));
    if work.looks_like_intensity() {
        ui.warn(intensity_note(&work));
    }
    ui.say(format!("labels       {}", v.label_count()));
    ui.say(table(
        &["value", "name", "voxels", "volume (mL)", "share"],
        &rows,
    ));
    Ok(ExitCode::SUCCESS)
}
