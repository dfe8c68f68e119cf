//! `septa check`: validate any mesh file against septa's invariants.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use super::show;
use super::ui::{Ui, secs};
use septa::Result;
use septa::io::mesh_ply::read_ply;
use septa::mesh::quality::{QualityOptions, quality};
use septa::mesh::validate::{Check, Options, validate, validate_label_surface, validate_patch};
use septa::volume::LabelId;

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Mesh to check: a PLY whose faces carry `label_a` and `label_b` (septa's
    /// interfaces.ply, or another tool's output). Without labels, the whole mesh
    /// is checked as one closed surface.
    pub mesh: PathBuf,
    /// Also look for self-intersections (slower).
    #[arg(long)]
    pub intersections: bool,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also measure the mesh's quality (as `septa extract` does after
    /// remeshing): edge lengths, angles, valences, and against this reference
    /// PLY (e.g. the `--no-remesh` extraction) the one-sided Hausdorff distance
    /// and the volume change per label (labels matched by value).
    #[arg(long, value_name = "PLY")]
    pub reference: Option<PathBuf>,
    /// Target edge length L in mm for the quality figures (implies them;
    /// default: the mean edge length).
    #[arg(long, value_name = "MM")]
    pub target_edge: Option<f64>,
}

/// Said of a patch file (one patch, vertices with the `vid` property).
const PATCH_FILE_NOTE: &str = "a single patch file (its vertices carry `vid`): a patch is open \
     by design, its boundary is where it meets the other patches, so it is checked as one \
     patch (a subset of an oriented 2-manifold), not as closed surfaces; check interfaces.ply \
     for the whole mesh";

/// Said when a file with `vid` vertices but several patches fails.
const MULTI_PATCH_NOTE: &str = "note: the vertices carry `vid` as in septa's patch files, but \
     the file holds several patches; if it is a part of a mesh, the closed-surface checks \
     fail on it by design: check interfaces.ply for the whole mesh";

pub fn run(args: &CheckArgs, ui: &Ui) -> Result<ExitCode> {
    let stage = ui.stage("reading");
    let ply = read_ply(&args.mesh)?;
    let t_read = stage.done();
    for note in &ply.notes {
        ui.warn(note);
    }
    let stage = ui.stage("validating");
    let options = Options {
        intersections: args.intersections,
        fidelity: None,
    };
    // a patch file (its vertices carry `vid`) is one open patch by design
    let patch_file = ply.vertex_ids.is_some() && ply.mesh.patches.len() == 1;
    // a label file (`labels/NAME.ply`) is that label's closed surface, its
    // neighbours' surfaces open by design
    let label_surface = ply.surface_of.and_then(|value| {
        let id = ply.mesh.labels.iter().position(|l| l.value == value)?;
        validate_label_surface(&ply.mesh, id as LabelId, &options).map(|r| (value, r))
    });
    let label_file = label_surface.as_ref().map(|(value, _)| *value);
    let mut report = if let Some((_, report)) = label_surface {
        report
    } else if patch_file {
        validate_patch(&ply.mesh, &options)
    } else {
        validate(&ply.mesh, &options)
    };
    let t_check = stage.done();
    // a face of 0, 1 or 2 vertices is no surface: the file fails the check
    let mut short = Check::new("faces of at least three vertices");
    for f in &ply.short_faces {
        short.fail(|| format!("face {f}"));
    }
    report.checks.insert(0, short);
    let quality = if args.reference.is_some() || args.target_edge.is_some() {
        let reference = match &args.reference {
            Some(path) => Some(read_ply(path)?.mesh),
            None => None,
        };
        let stage = ui.stage("measuring quality");
        let q = quality(
            &ply.mesh,
            reference.as_ref(),
            &QualityOptions::target(args.target_edge.unwrap_or(0.0)),
        );
        stage.done();
        Some(q)
    } else {
        None
    };
    if args.json {
        let mut j = serde_json::json!({"file": show(&args.mesh), "passed": report.passed(), "patch_file": patch_file, "surface_of_label": label_file, "report": report});
        if let Some(q) = &quality {
            j["quality"] = serde_json::to_value(q).expect("json");
        }
        println!("{}", serde_json::to_string_pretty(&j).expect("json"));
    } else {
        ui.say(format!(
            "{} (read in {}, checked in {})",
            show(&args.mesh),
            secs(t_read),
            secs(t_check)
        ));
        if patch_file {
            ui.say(PATCH_FILE_NOTE);
        }
        if let Some(value) = label_file {
            ui.say(format!(
                "the closed surface of label {value} (the file's header says so): checked as that \
                 label's surface against its neighbours taken as one, whose own surfaces are open \
                 here by design; check interfaces.ply for the whole mesh"
            ));
        }
        ui.say(report.summary().trim_end());
        if !patch_file && !report.passed() && ply.vertex_ids.is_some() {
            ui.say(MULTI_PATCH_NOTE);
        }
        if ui.verbose > 0 {
            for l in &report.labels {
                ui.say(format!(
                    "  label {:>5}: {} triangles, {} components, volume {:.1} mm³{}",
                    l.value,
                    l.triangles,
                    l.components,
                    l.volume_mm3,
                    if l.unbounded {
                        " (unbounded: the outside)"
                    } else {
                        ""
                    }
                ));
            }
        }
        if let Some(q) = &quality {
            ui.say(q.summary().trim_end());
        }
    }
    Ok(if report.passed() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
