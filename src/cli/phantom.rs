//! `septa phantom`: write the synthetic heart.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use super::ui::{Ui, count, secs};
use super::{parse_f64x3, show};
use septa::Result;
use septa::phantom::{LABELS, PhantomParams, heart};

#[derive(Args, Debug)]
pub struct PhantomArgs {
    /// Output file: .nii, .nii.gz or .nrrd.
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Voxels along each axis (the grid is N × N × N).
    #[arg(long, default_value_t = 64, value_name = "N")]
    pub size: usize,
    /// Voxel spacing in mm along x, y, z.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_f64x3, default_value = "1,1,1")]
    pub spacing: [f64; 3],
    /// Probability of flipping a voxel next to an interface to a neighbour's label
    /// (creates the critical configurations real segmentations have; try 0.01).
    #[arg(long, default_value_t = 0.0, value_name = "P")]
    pub noise: f64,
    /// Seed of the noise (same seed, same volume).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub fn run(args: &PhantomArgs, ui: &Ui) -> Result<ExitCode> {
    let stage = ui.stage("generating phantom");
    let v = heart(&PhantomParams {
        size: args.size,
        spacing: args.spacing,
        noise: args.noise,
        seed: args.seed,
    })?;
    let t_gen = stage.done();
    let stage = ui.stage("writing");
    septa::io::write_label_volume(&args.output, &v)?;
    let t_write = stage.done();
    let counts = v.voxel_counts();
    ui.say(format!(
        "wrote {} ({}³ voxels at {:?} mm, noise {}, seed {}) in {} + {}",
        show(&args.output),
        args.size,
        args.spacing,
        args.noise,
        args.seed,
        secs(t_gen),
        secs(t_write)
    ));
    if ui.verbose > 0 {
        for (i, &value) in v.values().iter().enumerate() {
            let name = LABELS.iter().find(|l| l.0 == value).map_or("?", |l| l.1);
            ui.say(format!(
                "  {value:>3} {name:<18} {:>12} voxels",
                count(counts[i])
            ));
        }
    }
    ui.say("label names: configs/heart.toml");
    Ok(ExitCode::SUCCESS)
}
