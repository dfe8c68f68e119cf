//! `septa inspect`: critical configurations of a volume and what fattening does.

use std::process::ExitCode;

use clap::Args;
use glam::DVec3;

use super::ui::{Ui, count, secs, table};
use super::{VolumeArgs, load, show};
use septa::Result;
use septa::preprocess::{ElementKind, Violation, preprocess};

#[derive(Args, Debug)]
pub struct InspectArgs {
    #[command(flatten)]
    pub input: VolumeArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// How many critical elements to list with their positions.
    #[arg(long, default_value_t = 10, value_name = "N")]
    pub first: usize,
}

pub fn run(args: &InspectArgs, ui: &Ui) -> Result<ExitCode> {
    let loaded = load(&args.input, ui)?;
    let v = &loaded.volume;
    let r = &loaded.resolved;
    let stage = ui.stage("detecting and fattening critical elements");
    let pre = preprocess(v, r);
    let took = stage.done();
    let g = v.geometry();
    let name = |id: u16| loaded.config.display_name(v.value(id));
    let (nv, ne, nf) = pre.critical.counts();
    let n = v.label_count();
    let mut dominant = vec![[0u64; 3]; n];
    for e in &pre.critical.elements {
        let k = match e.kind {
            ElementKind::Vertex => 0,
            ElementKind::Edge { .. } => 1,
            ElementKind::Face { .. } => 2,
        };
        dominant[e.dominant as usize][k] += 1;
    }
    let s = pre.refined.subdivision();
    let refined = pre.refined.refined_count();
    // refined voxels include those of the one-voxel ring of the outside
    // label around the volume: the share is of the grid with that ring
    let d = v.dims();
    let padded = (d.nx + 2) * (d.ny + 2) * (d.nz + 2);
    let share = refined as f64 / padded as f64;
    let position = |kind: ElementKind, pos: [i32; 3]| -> DVec3 {
        // element centre in index space: grid vertex (i,j,k) is at index i - 0.5
        let mut c = DVec3::new(
            pos[0] as f64 - 0.5,
            pos[1] as f64 - 0.5,
            pos[2] as f64 - 0.5,
        );
        match kind {
            ElementKind::Vertex => {}
            ElementKind::Edge { axis } => c[axis as usize] += 0.5,
            ElementKind::Face { axis } => {
                for a in 0..3 {
                    if a != axis as usize {
                        c[a] += 0.5;
                    }
                }
            }
        }
        g.index_to_physical(c)
    };
    let kind_name = |k: ElementKind| match k {
        ElementKind::Vertex => "vertex",
        ElementKind::Edge { .. } => "edge",
        ElementKind::Face { .. } => "face",
    };
    let first: Vec<_> = pre.critical.elements.iter().take(args.first).collect();
    let passed = pre.guarantee.passed();
    if args.json {
        let per_label: Vec<_> = (0..n)
            .map(|i| {
                serde_json::json!({
                    "value": v.value(i as u16), "name": name(i as u16),
                    "critical_edges": pre.critical.edges_per_label[i],
                    "critical_vertices": pre.critical.vertices_per_label[i],
                    "constraint_faces": pre.critical.faces_per_label[i],
                    "dominant": {"vertices": dominant[i][0], "edges": dominant[i][1], "faces": dominant[i][2]},
                })
            })
            .collect();
        let j = serde_json::json!({
            "file": show(&args.input.volume),
            "subdivision": s,
            "critical": {"vertices": nv, "edges": ne, "faces": nf},
            "labels": per_label,
            "refined_voxels": refined, "refined_share": share,
            "first": first.iter().map(|e| serde_json::json!({
                "kind": kind_name(e.kind), "grid_vertex": e.pos, "position_mm": position(e.kind, e.pos).to_array(),
                "dominant": v.value(e.dominant), "dominant_name": name(e.dominant),
            })).collect::<Vec<_>>(),
            "guarantee": {"passed": passed, "fine_vertices_checked": pre.guarantee.points_checked,
                          "violations": pre.guarantee.violation_count, "first_violations": pre.guarantee.first_violations},
            "seconds": took.as_secs_f64(),
        });
        println!("{}", serde_json::to_string_pretty(&j).expect("json"));
        return Ok(if passed {
            ExitCode::SUCCESS
        } else {
            ExitCode::from(1)
        });
    }
    ui.say(format!(
        "volume       {} ({} × {} × {})",
        show(&args.input.volume),
        v.dims().nx,
        v.dims().ny,
        v.dims().nz
    ));
    ui.say(format!(
        "outside      label {} ({})",
        v.value(r.outside),
        name(r.outside)
    ));
    ui.say(format!(
        "subdivision  {s}³ subvoxels per refined voxel{}",
        if r.has_constraints() {
            " (separation constraints given)"
        } else {
            ""
        }
    ));
    ui.say(format!(
        "critical     {} vertices, {} edges, {} constraint faces",
        count(nv as u64),
        count(ne as u64),
        count(nf as u64)
    ));
    let rows: Vec<Vec<String>> = (0..n)
        .filter(|&i| {
            pre.critical.edges_per_label[i]
                + pre.critical.vertices_per_label[i]
                + pre.critical.faces_per_label[i]
                + dominant[i].iter().sum::<u64>()
                > 0
        })
        .map(|i| {
            vec![
                format!("{} ({})", name(i as u16), v.value(i as u16)),
                count(pre.critical.edges_per_label[i]),
                count(pre.critical.vertices_per_label[i]),
                count(pre.critical.faces_per_label[i]),
                count(dominant[i][0] + dominant[i][1] + dominant[i][2]),
            ]
        })
        .collect();
    if !rows.is_empty() {
        ui.say(table(
            &[
                "label",
                "critical edges",
                "critical vertices",
                "constraint faces",
                "dominant at",
            ],
            &rows,
        ));
    }
    ui.say(format!(
        "refined      {} voxels ({:.4} % of the volume with its outside ring) in {}",
        count(refined as u64),
        100.0 * share,
        secs(took)
    ));
    if !first.is_empty() {
        ui.say(format!("first {} critical elements (LPS mm):", first.len()));
        for e in &first {
            let p = position(e.kind, e.pos);
            ui.say(format!(
                "  {:<6} at ({:8.2}, {:8.2}, {:8.2})  dominant {}",
                kind_name(e.kind),
                p.x,
                p.y,
                p.z,
                name(e.dominant)
            ));
        }
    }
    if passed {
        ui.say(format!(
            "guarantee    passed: no label is critical on the fattened grid and no constrained pair touches ({} fine vertices checked)",
            count(pre.guarantee.points_checked)
        ));
        Ok(ExitCode::SUCCESS)
    } else {
        ui.say(format!(
            "guarantee    FAILED: {} violations",
            pre.guarantee.violation_count
        ));
        for viol in pre.guarantee.first_violations.iter().take(5) {
            ui.say(format!("  {}", describe(viol)));
        }
        Ok(ExitCode::from(1))
    }
}

fn describe(v: &Violation) -> String {
    format!("{v:?}")
}
