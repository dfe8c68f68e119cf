//! `septa iso`: VESTA iso-surface of a grayscale volume, with the N-cycle
//! statistics of the paper's Tables II–IV.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, ValueEnum};

use super::ui::{Ui, count, secs, table};
use super::{parse_dtype, parse_f64x3, parse_usize3, show};
use septa::io::{DataType, ReadOptions, read_image};
use septa::iso::{Decompose, IsoOptions, IsoSurface, Mode, cycle_types, iso_surface_image};
use septa::mesh::validate::{Options, validate};
use septa::{Error, Result};

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ModeArg {
    /// Two active voxels sharing only an edge stay apart.
    Disconnect,
    /// They are joined.
    Connect,
    /// Joined where the mean of the four voxels around the edge is ≥ iso.
    Mixed,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum DecomposeArg {
    /// No extra points: each N-cycle is triangulated on its own points.
    L,
    /// One extra point (the average) per N-cycle with N > 3, and a fan around it.
    H,
}

#[derive(Args, Debug)]
pub struct IsoArgs {
    /// Grayscale volume (any sample type): .nii, .nii.gz, .hdr/.img, .nrrd, .nhdr,
    /// .mha, .mhd, or raw with --dims/--dtype.
    pub volume: PathBuf,
    /// Iso value: voxels with value ≥ VALUE are inside.
    #[arg(long, value_name = "VALUE", allow_negative_numbers = true)]
    pub iso: f64,
    /// How two inside voxels that share only an edge are treated.
    #[arg(long, value_enum, default_value = "mixed", ignore_case = true)]
    pub mode: ModeArg,
    /// How N-cycles are cut into triangles (VESTA's L and H).
    #[arg(long, value_enum, default_value = "l", ignore_case = true)]
    pub decompose: DecomposeArg,
    /// Keep support points at the voxel face centres (the binary VESTA surface)
    /// instead of interpolating the iso value along each range vector.
    #[arg(long)]
    pub no_displace: bool,
    /// Output mesh: .ply (with label_a = 0 inside, label_b = 1 outside), .obj,
    /// .stl or .vtp. Normals point outward (from ≥ iso to < iso).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// Validate the mesh (closed, oriented, manifold, non-degenerate); exit
    /// code 1 if it is not.
    #[arg(long)]
    pub check: bool,
    /// Print the statistics as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// For benchmarking: run the extraction N times in this process and report
    /// the fastest, like a benchmark harness would; the output is written once.
    /// The first (cold) time is reported too.
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = parse_repeat)]
    pub repeat: usize,
    /// Raw files: extents along x, y, z (e.g. 256,256,128).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_usize3, help_heading = "Raw input")]
    pub dims: Option<[usize; 3]>,
    /// Raw files: sample type (uint8, int16, float32, ...).
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

/// `--repeat`: a whole number ≥ 1.
fn parse_repeat(s: &str) -> std::result::Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(0) => Err("must be at least 1 (the number of extractions to run)".into()),
        Ok(n) => Ok(n),
        Err(_) => Err(format!("`{s}` is not a whole number ≥ 1")),
    }
}

impl IsoArgs {
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

    fn options(&self) -> IsoOptions {
        IsoOptions {
            iso: self.iso,
            mode: match self.mode {
                ModeArg::Disconnect => Mode::Disconnect,
                ModeArg::Connect => Mode::Connect,
                ModeArg::Mixed => Mode::Mixed,
            },
            decompose: match self.decompose {
                DecomposeArg::L => Decompose::L,
                DecomposeArg::H => Decompose::H,
            },
            displace: !self.no_displace,
        }
    }
}

pub fn run(args: &IsoArgs, ui: &Ui) -> Result<ExitCode> {
    let opts = args.options();
    opts.check()?;
    refuse_input_as_output(&args.output, &args.volume)?;
    let format = MeshFormat::of(&args.output)?;
    septa::io::check_writable(&args.output)?;

    let stage = ui.stage("reading volume");
    let image = read_image(&args.volume, &args.read_options()?)?;
    let t_read = stage.done();
    let values = ValueStats::of(&image.samples);
    for w in values.warnings(opts.iso) {
        ui.warn(format!("{}: {w}", show(&args.volume)));
    }

    let stage = ui.stage("extracting the iso-surface");
    let mut s = iso_surface_image(&image, &opts)?;
    let t_extract = stage.done();
    let mut extract = Extraction::first(t_extract, s.stats.seconds);
    for i in 1..args.repeat.max(1) {
        let stage = ui.stage(&format!("extracting again ({}/{})", i + 1, args.repeat));
        // the previous mesh is dropped first, so each run allocates afresh
        // as the first did
        let before = std::mem::take(&mut s.stats);
        drop(std::mem::take(&mut s.mesh));
        s = iso_surface_image(&image, &opts)?;
        let wall = stage.done();
        if !same_counts(&before, &s.stats) {
            return Err(Error::invalid(
                "repeated extractions gave different counts; please report this with the input volume",
            ));
        }
        extract.add(wall, s.stats.seconds);
    }
    // the statistics report the fastest run
    s.stats.seconds = extract.internal_best;

    let mut passed = true;
    let mut t_check = None;
    if args.check {
        let stage = ui.stage("validating");
        let report = validate(&s.mesh, &Options::default());
        t_check = Some(stage.done());
        passed = report.passed();
        if !passed {
            eprintln!("{}", report.summary().trim_end());
        }
    }

    let stage = ui.stage("writing");
    format.write(&args.output, &s.mesh)?;
    let t_write = stage.done();

    let range = values.range;
    let timings = Timings {
        read: t_read,
        extract,
        check: t_check,
        write: t_write,
    };
    if args.json {
        println!("{}", json_report(args, &image, &opts, &s, &timings, passed));
    } else {
        summarize(ui, args, &image, &opts, &s, &timings, range);
    }
    Ok(if passed {
        ExitCode::SUCCESS
    } else {
        eprintln!(
            "error: the iso-surface violates septa's invariants; please report this with the input volume"
        );
        ExitCode::from(1)
    })
}

/// Stage times.
struct Timings {
    read: Duration,
    extract: Extraction,
    check: Option<Duration>,
    write: Duration,
}

/// Times of the extraction runs (`--repeat`): the whole stage (wall) and the
/// library's own figure (`IsoStats::seconds`), of the first run and the fastest.
struct Extraction {
    runs: usize,
    wall_first: Duration,
    wall_best: Duration,
    internal_first: f64,
    internal_best: f64,
}

impl Extraction {
    fn first(wall: Duration, internal: f64) -> Self {
        Extraction {
            runs: 1,
            wall_first: wall,
            wall_best: wall,
            internal_first: internal,
            internal_best: internal,
        }
    }

    fn add(&mut self, wall: Duration, internal: f64) {
        self.runs += 1;
        self.wall_best = self.wall_best.min(wall);
        self.internal_best = self.internal_best.min(internal);
    }
}

/// Whether two extractions counted the same (the time aside).
fn same_counts(a: &septa::iso::IsoStats, b: &septa::iso::IsoStats) -> bool {
    let strip = |s: &septa::iso::IsoStats| septa::iso::IsoStats {
        seconds: 0.0,
        ..s.clone()
    };
    strip(a) == strip(b)
}

/// Output formats by extension.
#[derive(Clone, Copy)]
enum MeshFormat {
    Ply,
    Obj,
    Stl,
    Vtp,
}

impl MeshFormat {
    fn of(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        Ok(match ext.as_str() {
            "ply" => MeshFormat::Ply,
            "obj" => MeshFormat::Obj,
            "stl" => MeshFormat::Stl,
            "vtp" => MeshFormat::Vtp,
            _ => {
                return Err(Error::input(
                    path,
                    "unknown mesh format: use .ply, .obj, .stl or .vtp",
                ));
            }
        })
    }

    fn write(self, path: &Path, mesh: &septa::mesh::InterfaceMesh) -> Result<()> {
        use septa::io::mesh_formats as f;
        match self {
            MeshFormat::Ply => septa::io::mesh_ply::write_ply(path, mesh),
            MeshFormat::Obj => f::write_obj(path, mesh),
            MeshFormat::Stl => f::write_stl_label_surface(path, mesh, 0),
            MeshFormat::Vtp => f::write_vtp(path, mesh, f::VtpEncoding::Base64),
        }
    }
}

/// Refuses to write over the input file.
pub(super) fn refuse_input_as_output(output: &Path, input: &Path) -> Result<()> {
    let same = match (output.canonicalize(), input.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => output == input,
    };
    if same {
        return Err(Error::input(
            output,
            "is the input file; choose another output",
        ));
    }
    Ok(())
}

/// The range of the finite samples and the count of the others.
struct ValueStats {
    range: Option<(f64, f64)>,
    nan: u64,
    infinite: u64,
}

impl ValueStats {
    fn of(s: &septa::io::Samples) -> Self {
        use septa::io::Samples as S;
        #[allow(clippy::unnecessary_cast)] // one cast for all ten types, f64 among them
        match s {
            S::U8(v) => Self::scan(v.iter().map(|&x| x as f64)),
            S::I8(v) => Self::scan(v.iter().map(|&x| x as f64)),
            S::U16(v) => Self::scan(v.iter().map(|&x| x as f64)),
            S::I16(v) => Self::scan(v.iter().map(|&x| x as f64)),
            S::U32(v) => Self::scan(v.iter().map(|&x| x as f64)),
            S::I32(v) => Self::scan(v.iter().map(|&x| x as f64)),
            S::U64(v) => Self::scan(v.iter().map(|&x| x as f64)),
            S::I64(v) => Self::scan(v.iter().map(|&x| x as f64)),
            S::F32(v) => Self::scan(v.iter().map(|&x| x as f64)),
            S::F64(v) => Self::scan(v.iter().map(|&x| x as f64)),
        }
    }

    fn scan(values: impl Iterator<Item = f64>) -> Self {
        let mut out = ValueStats {
            range: None,
            nan: 0,
            infinite: 0,
        };
        for x in values {
            if x.is_nan() {
                out.nan += 1;
            } else if x.is_infinite() {
                out.infinite += 1;
            } else {
                out.range = Some(match out.range {
                    None => (x, x),
                    Some((lo, hi)) => (lo.min(x), hi.max(x)),
                });
            }
        }
        out
    }

    /// What the user should know before trusting the surface: values that
    /// are not numbers, and an iso value outside or at the edge of the data.
    fn warnings(&self, iso: f64) -> Vec<String> {
        let mut w = Vec::new();
        if self.nan > 0 || self.infinite > 0 {
            w.push(format!(
                "{} samples are NaN and {} infinite: NaN and -inf count as outside, +inf as inside",
                self.nan, self.infinite
            ));
        }
        let Some((lo, hi)) = self.range else {
            return w;
        };
        // within 1 % of the range from an end: the surface follows the
        // background or the peak, not a structure
        let edge = 0.01 * (hi - lo);
        if iso <= lo {
            w.push(format!(
                "the iso value {iso} is at or below the smallest value {lo} (values {lo} to {hi}): \
                 every voxel is inside"
            ));
        } else if iso > hi {
            // (the summary says so: an empty surface)
        } else if iso - lo <= edge {
            w.push(format!(
                "the iso value {iso} is at the bottom of the values ({lo} to {hi}): the surface \
                 encloses every voxel above the minimum"
            ));
        } else if hi - iso <= edge {
            w.push(format!(
                "the iso value {iso} is at the top of the values ({lo} to {hi}): only the largest \
                 values are inside"
            ));
        }
        w
    }
}

fn describe(opts: &IsoOptions) -> String {
    format!(
        "{}, {:?}, {}",
        opts.mode.name(),
        opts.decompose,
        if opts.displace {
            "displaced"
        } else {
            "not displaced"
        }
    )
}

fn summarize(
    ui: &Ui,
    args: &IsoArgs,
    image: &septa::io::Image,
    opts: &IsoOptions,
    s: &IsoSurface,
    t: &Timings,
    range: Option<(f64, f64)>,
) {
    let st = &s.stats;
    let n: usize = image.dims.iter().take(3).product();
    ui.say(format!(
        "septa iso {} --iso {} ({}) -> {}",
        show(&args.volume),
        opts.iso,
        describe(opts),
        show(&args.output)
    ));
    ui.say(format!(
        "  {} × {} × {} voxels ({}), {} inside ({:.2} %)",
        image.dims[0],
        image.dims[1],
        image.dims[2],
        image.samples.dtype().name(),
        count(st.active_voxels),
        100.0 * st.active_voxels as f64 / n.max(1) as f64
    ));
    if s.mesh.triangle_count() == 0 {
        let why = match range {
            Some((lo, hi)) => format!("the values range from {lo} to {hi}"),
            None => "the volume holds no finite value".into(),
        };
        ui.warn(format!(
            "empty surface: no voxel has a value ≥ {} ({why}); wrote an empty mesh",
            opts.iso
        ));
        return;
    }
    if st.active_voxels as usize == n {
        ui.say("  every voxel is inside: the surface is the volume's box");
    }
    let rows: Vec<Vec<String>> = st
        .table_rows()
        .into_iter()
        .map(|(k, v)| {
            let v = v.parse::<u64>().map(count).unwrap_or(v);
            vec![k, v]
        })
        .collect();
    ui.say(table(&["", "count"], &rows));
    if ui.verbose > 0 {
        let types: Vec<Vec<String>> = cycle_types()
            .iter()
            .zip(&st.cycles_by_type)
            .map(|(ty, &c)| {
                vec![
                    ty.name.clone(),
                    count(c),
                    if ty.planar { "planar" } else { "" }.into(),
                    if ty.global { "" } else { "mixed only" }.into(),
                ]
            })
            .collect();
        ui.say(table(&["type", "cycles", "", ""], &types));
    }
    let extract = if t.extract.runs > 1 {
        format!(
            "{} (fastest of {}; first {})",
            secs(t.extract.wall_best),
            t.extract.runs,
            secs(t.extract.wall_first)
        )
    } else {
        secs(t.extract.wall_best)
    };
    ui.say(format!(
        "  read {}, extract {}{}, write {}",
        secs(t.read),
        extract,
        t.check
            .map(|d| format!(", check {}", secs(d)))
            .unwrap_or_default(),
        secs(t.write)
    ));
}

fn json_report(
    args: &IsoArgs,
    image: &septa::io::Image,
    opts: &IsoOptions,
    s: &IsoSurface,
    t: &Timings,
    passed: bool,
) -> String {
    let st = &s.stats;
    let j = serde_json::json!({
        "septa": env!("CARGO_PKG_VERSION"),
        "input": {
            "file": show(&args.volume),
            "dims": &image.dims[..3],
            "dtype": image.samples.dtype().name(),
            "spacing_mm": image.geometry.spacing(),
            "affine_lps": image.geometry.affine(),
        },
        "output": show(&args.output),
        "parameters": {
            "iso": opts.iso,
            "mode": opts.mode.name(),
            "decompose": format!("{:?}", opts.decompose),
            "displace": opts.displace,
        },
        "empty": s.mesh.triangle_count() == 0,
        "active_voxels": st.active_voxels,
        "cycles": (3..=12).map(|n| (n.to_string(), serde_json::json!(st.cycles_by_length[n])))
            .collect::<serde_json::Map<_, _>>(),
        "cycle_sum": st.cycle_sum(),
        "cycle_types": cycle_types().iter().zip(&st.cycles_by_type).map(|(ty, &c)| serde_json::json!({
            "type": ty.name, "length": ty.length, "planar": ty.planar,
            "global": ty.global, "cycles": c,
        })).collect::<Vec<_>>(),
        "points": st.points,
        "support_points": st.support_points,
        "centroids": st.centroids,
        "triangles": st.triangles,
        "valid": if args.check { serde_json::json!(passed) } else { serde_json::Value::Null },
        "repeat": t.extract.runs,
        "timings_s": {
            "read": t.read.as_secs_f64(),
            "extract": t.extract.wall_best.as_secs_f64(),
            "extract_first": t.extract.wall_first.as_secs_f64(),
            "extract_internal": t.extract.internal_best,
            "extract_internal_first": t.extract.internal_first,
            "check": t.check.map(|d| d.as_secs_f64()),
            "write": t.write.as_secs_f64(),
        },
    });
    serde_json::to_string_pretty(&j).expect("json")
}
