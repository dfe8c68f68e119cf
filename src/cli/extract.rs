//! `septa extract`: maps the flags to [`septa::pipeline`]'s options, writes
//! the result to the output directory and prints a summary.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, ValueEnum};

use super::VolumeArgs;
use super::ui::{Ui, count, secs, table};
use super::{read, show};
use septa::Result;
use septa::config::RemeshOptions;
use septa::extract::{Decompose, Surface};
use septa::io::Space;
use septa::io::label_files::LabelFormats;
use septa::labels::{LabelSelection, parse_label_ref};
use septa::output::{Formats, OutDir, write_outdir};
use septa::pipeline::{self, PipelineOptions, PipelineResult, Progress};

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum DecomposeArg {
    /// No extra points: each N-cycle is triangulated on its own points.
    L,
    /// One extra point (the average) per N-cycle with N > 3, and a fan around it.
    H,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum SurfaceArg {
    /// VESTA surface: dual of the voxel faces, one point per boundary face.
    Vesta,
    /// The voxel faces themselves (blocky; exact voxel volumes).
    Faces,
}

#[derive(Clone, Copy, Debug, ValueEnum, PartialEq, Eq)]
pub enum FormatArg {
    Obj,
    Vtp,
    Stl,
}

/// Formats of the per-label surfaces.
#[derive(Clone, Copy, Debug, ValueEnum, PartialEq, Eq)]
pub enum LabelFormatArg {
    Stl,
    Obj,
    Ply,
    Vtp,
}

#[derive(Clone, Copy, Debug, ValueEnum, PartialEq, Eq)]
pub enum SpaceArg {
    /// x toward patient left, y posterior, z superior (DICOM, ITK, 3D Slicer).
    Lps,
    /// x toward patient right, y anterior, z superior (NIfTI, nibabel, FreeSurfer).
    Ras,
}

#[derive(Args, Debug)]
pub struct ExtractArgs {
    #[command(flatten)]
    pub input: VolumeArgs,
    /// Output directory (interfaces.ply and .vtp, patches/, junctions.ply and .vtp, manifest.json).
    #[arg(short, long, value_name = "OUTDIR")]
    pub output: PathBuf,
    /// Replace OUTDIR if it exists.
    #[arg(long)]
    pub force: bool,
    /// How N-cycles are cut into triangles.
    #[arg(long, value_enum, default_value = "l", ignore_case = true)]
    pub decompose: DecomposeArg,
    /// Which surface to extract (`faces` is written as is, never remeshed).
    #[arg(long, value_enum, default_value = "vesta")]
    pub surface: SurfaceArg,
    /// Extra formats besides PLY and VTP (both always written): obj (all patches, one group
    /// each), stl (one closed outward surface per label, for printing: as --per-label stl);
    /// vtp is accepted and changes nothing. Repeatable or comma-separated.
    #[arg(long = "format", value_enum, value_delimiter = ',')]
    pub formats: Vec<FormatArg>,
    /// Also write each label's closed, outward-oriented surface on its own, as
    /// labels/NAME.EXT in each FORMAT (stl, obj, ply, vtp; repeatable or comma-separated);
    /// NAME is the label's name made safe for file names, label<value> without one.
    #[arg(long, value_enum, value_delimiter = ',', value_name = "FORMAT")]
    pub per_label: Vec<LabelFormatArg>,
    /// Mesh only these labels (values or names, comma-separated or repeated): every other
    /// label is merged into the outside label (or into --others) before anything else.
    #[arg(long, value_name = "LABEL,...", value_delimiter = ',')]
    pub labels: Vec<String>,
    /// With --labels: the label the unselected labels become (value or name; default: the
    /// outside label).
    #[arg(long, value_name = "LABEL", requires = "labels")]
    pub others: Option<String>,
    /// Coordinate system of the mesh files, in mm (their header comments and the manifest say
    /// which).
    #[arg(long, value_enum, default_value = "lps", ignore_case = true)]
    pub space: SpaceArg,
    /// Also check the output for self-intersections (slower; always done after remeshing).
    #[arg(long)]
    pub intersections: bool,
    /// Write the extraction as it is: no smoothing, no remeshing (config: `[remesh] enabled = false`).
    #[arg(long)]
    pub no_remesh: bool,
    /// With --no-remesh: merge the flat stretches of each patch (staircase terraces, sides of
    /// fattened blocks) into large polygons. The very same surface in fewer, longer triangles
    /// (13 % fewer on a brain tissue map); leave it off if the mesh is to be smoothed elsewhere,
    /// which needs a point on every voxel face.
    #[arg(long)]
    pub merge_flat: bool,
    /// Largest edge length of the remeshed patches, in mm: the target wherever the structures
    /// leave room for it (default: twice the mean voxel spacing). Edges get shorter where label
    /// regions are thinner (a sizing field from the volume), down to --min-edge.
    #[arg(long, value_name = "MM")]
    pub target_edge: Option<f64>,
    /// Smallest edge length of the remeshed patches, in mm, where label regions are thin
    /// (default: half the smallest voxel spacing).
    #[arg(long, value_name = "MM")]
    pub min_edge: Option<f64>,
    /// Taubin λ/μ smoothing passes that remove the voxel staircase before remeshing (default 10).
    #[arg(long, value_name = "N")]
    pub smooth_iterations: Option<u32>,
    /// How far smoothing may move a vertex, in voxels along each axis (default 0.5); keeps thin walls.
    #[arg(long, value_name = "VOXELS")]
    pub max_displacement: Option<f64>,
    /// Split/collapse/flip/relax iterations of the remesher (default 5).
    #[arg(long, value_name = "N")]
    pub remesh_iterations: Option<u32>,
    /// Do not write preview.png (the patches drawn from four sides).
    #[arg(long)]
    pub no_preview: bool,
    /// Memory the run may use (e.g. 8G, 500M; default: what the system has
    /// available). The work is estimated before preprocessing and before
    /// extracting; a run that would need more is refused.
    #[arg(long, value_name = "SIZE", value_parser = parse_size)]
    pub max_memory: Option<u64>,
}

/// `--max-memory`: bytes, with an optional K, M, G or T (powers of 1000; a
/// trailing B or iB is accepted too).
fn parse_size(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim().to_ascii_uppercase();
    let t = t
        .strip_suffix("IB")
        .or_else(|| t.strip_suffix('B'))
        .unwrap_or(&t);
    let (num, unit) = match t.char_indices().find(|(_, c)| c.is_ascii_alphabetic()) {
        Some((i, _)) => (&t[..i], &t[i..]),
        None => (t, ""),
    };
    let scale = match unit {
        "" => 1.0,
        "K" => 1e3,
        "M" => 1e6,
        "G" => 1e9,
        "T" => 1e12,
        _ => return Err(format!("`{s}`: use a size like 8G, 500M or 2000000000")),
    };
    match num.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok((x * scale) as u64),
        _ => Err(format!("`{s}`: use a size like 8G, 500M or 2000000000")),
    }
}

/// Turns a library parameter error into one about the flag or config key.
fn blame(e: septa::Error, args: &ExtractArgs, config: &septa::config::Config) -> septa::Error {
    let (name, value, problem) = match e {
        septa::Error::Parameter {
            name,
            value,
            problem,
        } => (name, value, problem),
        // the label selection names its options as the library calls them
        septa::Error::Invalid(m) if m.starts_with("labels ") || m.starts_with("others ") => {
            return septa::Error::invalid(format!("--{m}"));
        }
        other => return other,
    };
    let (flag, given) = match name {
        "target_edge" => ("--target-edge", args.target_edge.is_some()),
        "smooth_iterations" => ("--smooth-iterations", args.smooth_iterations.is_some()),
        "max_displacement" => ("--max-displacement", args.max_displacement.is_some()),
        "iterations" => ("--remesh-iterations", args.remesh_iterations.is_some()),
        _ => {
            return septa::Error::Parameter {
                name,
                value,
                problem,
            };
        }
    };
    match (&config.path, given) {
        (_, true) => septa::Error::invalid(format!("{flag} {value}: {problem}")),
        (Some(path), false) => septa::Error::config(
            path,
            format!("remesh.{name}"),
            format!("{value}: {problem}"),
        ),
        (None, false) => {
            septa::Error::invalid(format!("the default {name} {value}: {problem}; set {flag}"))
        }
    }
}

/// The pipeline's options from the flags.
fn pipeline_options(args: &ExtractArgs) -> PipelineOptions {
    PipelineOptions {
        surface: match args.surface {
            SurfaceArg::Vesta => Surface::Vesta,
            SurfaceArg::Faces => Surface::Faces,
        },
        decompose: match args.decompose {
            DecomposeArg::L => Decompose::L,
            DecomposeArg::H => Decompose::H,
        },
        remesh: RemeshOptions {
            enabled: args.no_remesh.then_some(false),
            target_edge: args.target_edge,
            min_edge: args.min_edge,
            smooth_iterations: args.smooth_iterations,
            max_displacement: args.max_displacement,
            iterations: args.remesh_iterations,
        },
        intersections: args.intersections,
        merge_flat: args.merge_flat,
        max_memory: args.max_memory,
        source_file: Some(args.input.volume.clone()),
        labels: (!args.labels.is_empty()).then(|| LabelSelection {
            keep: args
                .labels
                .iter()
                .filter(|l| !l.trim().is_empty())
                .map(|l| parse_label_ref(l))
                .collect(),
            others: args.others.as_deref().map(parse_label_ref),
        }),
    }
}

pub fn run(args: &ExtractArgs, ui: &Ui) -> Result<ExitCode> {
    // the destination is checked before any work, and again with every file
    // the volume's header named (detached data) once it is read
    let mut outdir = OutDir::new(&args.output, args.force);
    outdir.protect(&args.input.volume);
    if let Some(c) = &args.input.config {
        outdir.protect(c);
    }
    outdir.check()?;

    let stage = ui.stage("reading volume");
    septa::memory::set_activity(&"reading the volume");
    let (volume, config, sources) = read(&args.input)?;
    let read_time = stage.done();
    for s in &sources {
        outdir.protect(s);
    }
    outdir.check()?;

    let mut running: Option<super::ui::Stage> = None;
    let mut progress = |p: Progress<'_>| match p {
        Progress::Started { message, .. } => running = Some(ui.stage(message)),
        Progress::Finished { .. } => {
            if let Some(stage) = running.take() {
                stage.done();
            }
        }
        Progress::Warning(w) => ui.warn(w),
    };
    let mut result = pipeline::run(volume, &config, &pipeline_options(args), &mut progress)
        .map_err(|e| blame(e, args, &config))?;

    let stage = ui.stage("writing");
    septa::memory::set_activity(&"writing the output");
    let manifest = &mut result.manifest;
    manifest.command = std::env::args().collect();
    manifest
        .timings_s
        .insert("read".into(), read_time.as_secs_f64());
    let has = |f: LabelFormatArg| args.per_label.contains(&f);
    let formats = Formats {
        obj: args.formats.contains(&FormatArg::Obj),
        per_label: LabelFormats {
            stl: has(LabelFormatArg::Stl) || args.formats.contains(&FormatArg::Stl),
            obj: has(LabelFormatArg::Obj),
            ply: has(LabelFormatArg::Ply),
            vtp: has(LabelFormatArg::Vtp),
        },
        preview: !args.no_preview,
    };
    let space = match args.space {
        SpaceArg::Lps => Space::Lps,
        SpaceArg::Ras => Space::Ras,
    };
    let files = write_outdir(&outdir, &result.mesh, formats, space, manifest)?;
    let write_time = stage.done();

    let mut timings = vec![("read", read_time)];
    timings.extend(result.timings.iter().map(|(s, d)| (s.name(), *d)));
    timings.push(("write", write_time));
    summarize(ui, args, &result, &timings, files.len());
    if let Some(q) = &result.quality {
        ui.say("remeshing quality (distance and volume change against the unsmoothed extraction):");
        ui.say(q.summary().trim_end());
    }
    if let (Some(share), Some(islands)) = (
        result.manifest.remesh_kept_share,
        result.manifest.remesh_kept_islands_share,
    ) {
        report_kept(ui, share, islands);
    }
    if result.report.passed() {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!(
            "error: the output violates septa's invariants (see above and manifest.json); please report this with the input volume"
        );
        Ok(ExitCode::from(1))
    }
}

/// How much of the surface the remesher left as extracted (shares of the area).
fn report_kept(ui: &Ui, share: f64, islands: f64) {
    ui.say(format!(
        "kept       {:.2} % of the surface as extracted ({:.2} % on small islands), where no \
         operation could be done without two sheets crossing or a label region turning inside out",
        100.0 * share,
        100.0 * islands
    ));
    // much of it kept: structures thinner than the smallest edge
    if share > 0.1 {
        ui.warn(format!(
            "{:.0} % of the surface stayed at the extraction's resolution: structures there are \
             thinner than the smallest edge (a smaller --min-edge remeshes them)",
            100.0 * share
        ));
    }
}

/// One summary of everything the run did.
fn summarize(
    ui: &Ui,
    args: &ExtractArgs,
    result: &PipelineResult,
    timings: &[(&str, Duration)],
    files: usize,
) {
    let (m, mesh, report) = (&result.manifest, &result.mesh, &result.report);
    let d = m.input.dims;
    let pre = &m.preprocessing;
    let detail = |stage: &str| -> String {
        match stage {
            "read" => format!(
                "{} × {} × {} voxels, {} labels",
                d[0],
                d[1],
                d[2],
                m.labels.len()
            ),
            "preprocess" => format!(
                "{} critical vertices, {} edges, {} constraint faces; {} voxels refined ({}³){}",
                count(pre.critical_vertices as u64),
                count(pre.critical_edges as u64),
                count(pre.constraint_faces as u64),
                count(pre.refined_voxels as u64),
                m.parameters.subdivision,
                if pre.guarantee_passed {
                    ""
                } else {
                    "; GUARANTEE FAILED"
                }
            ),
            "extract" => format!(
                "{} patches, {} triangles, {} vertices, {} junction curves",
                mesh.patches.len(),
                count(m.extraction.triangles as u64),
                count(m.extraction.vertices as u64),
                mesh.junctions.len()
            ),
            "remesh" => format!(
                "{} triangles, {} vertices",
                count(mesh.triangle_count() as u64),
                count(mesh.vertex_count() as u64)
            ),
            "validate" => {
                if report.passed() {
                    "all invariants hold".into()
                } else {
                    format!("{} VIOLATIONS", report.failures())
                }
            }
            "write" => format!("{files} files"),
            _ => String::new(),
        }
    };
    ui.say(format!(
        "septa extract {} -> {}",
        show(&args.input.volume),
        show(&args.output)
    ));
    let mut rows: Vec<Vec<String>> = timings
        .iter()
        .map(|(k, t)| vec![k.to_string(), secs(*t), detail(k)])
        .collect();
    let total: Duration = timings.iter().map(|t| t.1).sum();
    let peak = septa::memory::peak_resident_bytes().map_or_else(String::new, |b| {
        format!(
            "peak memory {} MB ({} bytes per extracted triangle)",
            count(b / 1_000_000),
            b / m.extraction.triangles.max(1) as u64
        )
    });
    rows.push(vec!["total".into(), secs(total), peak]);
    ui.say(table(&["stage", "time", ""], &rows));
    if let Some(sel) = &m.parameters.label_selection {
        let name = |v: i64| {
            m.labels
                .iter()
                .find(|l| l.value == v)
                .map_or_else(|| format!("label{v}"), |l| l.name.clone())
        };
        let list = |vs: &[i64]| vs.iter().map(|&v| name(v)).collect::<Vec<_>>().join(", ");
        ui.say(format!(
            "  labels meshed: {}; merged into {}: {}",
            list(&sel.kept),
            name(sel.into),
            if sel.merged.is_empty() {
                "none".to_string()
            } else {
                sel.merged
                    .iter()
                    .map(i64::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        ));
    }
    if !report.passed() {
        ui.say(report.summary().trim_end());
    }
    if ui.verbose > 0 || mesh.patches.len() <= 12 {
        let rows: Vec<Vec<String>> = mesh
            .patches
            .iter()
            .zip(&m.patches)
            .map(|(p, mp)| {
                let stats = &mp.stats;
                vec![
                    format!(
                        "{} | {}",
                        mesh.label_name(p.labels[0]),
                        mesh.label_name(p.labels[1])
                    ),
                    count(stats.triangles as u64),
                    format!("{:.1}", stats.area_mm2),
                    stats.boundary_loops.to_string(),
                    stats.euler_characteristic.to_string(),
                ]
            })
            .collect();
        ui.say(table(
            &["patch", "triangles", "area (mm²)", "boundary loops", "χ"],
            &rows,
        ));
    } else {
        ui.say(format!(
            "  {} patches (use -v for the table, or see manifest.json)",
            mesh.patches.len()
        ));
    }
}
