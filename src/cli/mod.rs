//! The `septa` command line: a thin layer over the library. Each subcommand
//! parses its arguments, calls library stages, and prints a readable summary
//! (or JSON with `--json`). Progress goes to stderr and hides when stderr is not
//! a terminal or with `-q`.

mod check;
mod contour;
mod extract;
mod hyper;
mod info;
mod inspect;
mod iso;
mod phantom;
mod ui;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

use septa::config::{Config, Resolved};
use septa::io::{DataType, ReadOptions};
use septa::volume::LabelVolume;
use septa::{Error, Result};

const ABOUT: &str = "Consistent manifold interface meshes from segmented label volumes.";

const LONG_ABOUT: &str = "\
septa turns a segmented label volume (one tissue label per voxel: a heart CT
segmentation, a brain tissue map, any multi-material voxel data) into interface
patches: one triangle mesh per pair of touching labels. Every patch is a
2-manifold, patches share their boundaries exactly along junction curves, and
each label's patches together form a closed, outward-oriented surface.

Typical use:
  septa info  segmentation.nii.gz -c labels.toml      # what is in the volume
  septa extract segmentation.nii.gz -c labels.toml -o out/
  septa check out/interfaces.ply                      # verify any mesh

Try it on the bundled example:
  septa extract data/heart_phantom_48.nii.gz -c configs/heart.toml -o out/";

/// Command line of septa.
#[derive(Parser, Debug)]
#[command(name = "septa", version, about = ABOUT, long_about = LONG_ABOUT)]
pub struct Cli {
    /// More detail in the summary (per-patch tables, per-label statistics).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
    /// Print nothing but errors.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Describe a label volume: grid, spacing, orientation, extent, labels with voxel counts and volumes.
    Info(info::InfoArgs),
    /// Generate a synthetic heart-like label volume (for trying septa and for tests).
    Phantom(phantom::PhantomArgs),
    /// Find critical (non-manifold) voxel configurations and check that fattening removes them.
    Inspect(inspect::InspectArgs),
    /// Extract interface patches: the main command.
    Extract(extract::ExtractArgs),
    /// Validate a mesh (PLY with label_a/label_b face properties) against septa's invariants.
    Check(check::CheckArgs),
    /// VESTA iso-surface of a grayscale volume (CT, MR, simulation data), with N-cycle statistics.
    Iso(iso::IsoArgs),
    /// DICONEX contours of a 2-D image or a volume slice: iso-contours, or label-pair polylines.
    Contour(contour::ContourArgs),
    /// STEVE iso-hypersurface of a 4-D volume (or of 3-D frames), and closed surfaces at any time.
    Hyper(hyper::HyperArgs),
}

/// Reading a volume: the file, an optional config, and the description of raw files.
#[derive(Args, Debug, Clone)]
pub struct VolumeArgs {
    /// Label volume: .nii, .nii.gz, .hdr/.img, .nrrd, .nhdr, .mha, .mhd, or raw with --dims/--dtype.
    pub volume: PathBuf,
    /// Configuration (TOML): label names, outside label, priority, separation constraints, remeshing.
    #[arg(short, long, value_name = "CONFIG")]
    pub config: Option<PathBuf>,
    /// Label names from a file (they win over the config's [labels]): JSON ({"1": "grey matter"}
    /// or [{"value": 1, "name": "grey matter"}]), TOML ([labels] as in the config), a 3D Slicer
    /// colour table (.ctbl/.txt: `value name r g b a`) or an ITK-SNAP label description
    /// (`IDX R G B A VIS MSH "LABEL"`); the format is found from the extension or the content.
    #[arg(long, value_name = "FILE")]
    pub label_names: Option<PathBuf>,
    /// Raw files: extents along x, y, z (e.g. 256,256,128).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_usize3, help_heading = "Raw input")]
    pub dims: Option<[usize; 3]>,
    /// Raw files: sample type (uint8, int8, uint16, int16, uint32, int32, float32, float64, ...).
    #[arg(long, value_parser = parse_dtype, help_heading = "Raw input")]
    pub dtype: Option<DataType>,
    /// Raw files: voxel spacing in mm (default 1,1,1).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_f64x3, help_heading = "Raw input")]
    pub spacing: Option<[f64; 3]>,
    /// Raw files: samples are big-endian.
    #[arg(long, help_heading = "Raw input")]
    pub big_endian: bool,
    /// Raw files: bytes to skip before the samples.
    #[arg(long, default_value_t = 0, help_heading = "Raw input")]
    pub header_bytes: u64,
}

impl VolumeArgs {
    fn read_options(&self) -> Result<ReadOptions> {
        if self.dims.is_some() != self.dtype.is_some() {
            return Err(Error::invalid("raw input needs both --dims and --dtype"));
        }
        Ok(ReadOptions {
            dims: self.dims,
            dtype: self.dtype,
            spacing: self.spacing,
            big_endian: self.big_endian,
            header_bytes: self.header_bytes,
        })
    }

    fn config(&self) -> Result<Config> {
        let config = match &self.config {
            Some(p) => Config::from_file(p)?,
            None => Config::default(),
        };
        match &self.label_names {
            Some(p) => config.with_label_names(&septa::labels::read_label_names(p)?),
            None => Ok(config),
        }
    }
}

/// A volume ready for the pipeline.
pub struct Loaded {
    pub volume: LabelVolume,
    pub config: Config,
    pub resolved: Resolved,
}

/// Reads the config and the volume (not yet resolved against each other);
/// also every file read (the volume's header and data files, the config).
fn read(args: &VolumeArgs) -> Result<(LabelVolume, Config, Vec<PathBuf>)> {
    let config = args.config()?;
    let image = septa::io::read_image(&args.volume, &args.read_options()?)?;
    let mut sources = image.sources.clone();
    sources.extend(args.config.iter().cloned());
    sources.extend(args.label_names.iter().cloned());
    Ok((image.into_label_volume()?, config, sources))
}

/// Reads the volume and the config and resolves one against the other.
fn load(args: &VolumeArgs, ui: &ui::Ui) -> Result<Loaded> {
    let (volume, config, _) = read(args)?;
    let (volume, resolved) = config.resolve(volume)?;
    for w in &resolved.warnings {
        ui.warn(w);
    }
    Ok(Loaded {
        volume,
        config,
        resolved,
    })
}

fn parse_list<T: std::str::FromStr>(s: &str, n: usize) -> std::result::Result<Vec<T>, String> {
    let v: Vec<T> = s
        .split(',')
        .map(|x| x.trim().parse::<T>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| format!("`{s}` is not a list of {n} numbers"))?;
    if v.len() != n {
        return Err(format!("`{s}`: expected {n} comma-separated numbers"));
    }
    Ok(v)
}

fn parse_usize3(s: &str) -> std::result::Result<[usize; 3], String> {
    let v = parse_list::<usize>(s, 3)?;
    Ok([v[0], v[1], v[2]])
}

fn parse_f64x3(s: &str) -> std::result::Result<[f64; 3], String> {
    let v = parse_list::<f64>(s, 3)?;
    Ok([v[0], v[1], v[2]])
}

fn parse_dtype(s: &str) -> std::result::Result<DataType, String> {
    DataType::parse(s).ok_or_else(|| format!("unknown sample type `{s}` (uint8, int8, uint16, int16, uint32, int32, uint64, int64, float32, float64)"))
}

/// Runs the command line; the process exit code.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let ui = ui::Ui::new(cli.verbose, cli.quiet);
    // the worker threads now, so that a limit that forbids them is an
    // error message (rayon would panic at its first use)
    if let Err(e) = rayon::ThreadPoolBuilder::new().build_global() {
        eprintln!(
            "error: could not start the worker threads ({e}): the process is at a limit of \
             memory or threads (a container's, `ulimit -v` or `ulimit -u`)"
        );
        return ExitCode::from(2);
    }
    // temporary output is removed when the run is stopped (Ctrl-C, kill)
    if let Err(e) = septa::io::temp::install_signal_cleanup() {
        ui.warn(e.to_string());
    }
    let result = match &cli.command {
        Command::Info(a) => info::run(a, &ui),
        Command::Phantom(a) => phantom::run(a, &ui),
        Command::Inspect(a) => inspect::run(a, &ui),
        Command::Extract(a) => extract::run(a, &ui),
        Command::Check(a) => check::run(a, &ui),
        Command::Iso(a) => iso::run(a, &ui),
        Command::Hyper(a) => hyper::run(a, &ui),
        Command::Contour(a) => contour::run(a, &ui),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

/// A path for messages.
fn show(p: &Path) -> String {
    p.display().to_string()
}
