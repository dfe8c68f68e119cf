//! `septa check`: validate any mesh file against septa's invariants.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use super::show;
use super::ui::{Ui, secs};
use septa::Result;
use septa::io::mesh_ply::read_ply;
use septa::mesh::validate::{Options, validate};

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
}

pub fn run(args: &CheckArgs, ui: &Ui) -> Result<ExitCode> {
    let stage = ui.stage("reading");
    let ply = read_ply(&args.mesh)?;
    let t_read = stage.done();
    for note in &ply.notes {
        ui.warn(note);
    }
    let stage = ui.stage("validating");
    let report = validate(
        &ply.mesh,
        &Options {
            intersections: args.intersections,
            fidelity: None,
        },
    );
    let t_check = stage.done();
    if args.json {
        let j = serde_json::json!({"file": show(&args.mesh), "passed": report.passed(), "report": report});
        println!("{}", serde_json::to_string_pretty(&j).expect("json"));
    } else {
        ui.say(format!(
            "{} (read in {}, checked in {})",
            show(&args.mesh),
            secs(t_read),
            secs(t_check)
        ));
        ui.say(report.summary().trim_end());
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
    }
    Ok(if report.passed() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
