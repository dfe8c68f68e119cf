//! `septa extract`: volume → interface patches on disk, with a summary.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, ValueEnum};

use super::ui::{Ui, count, secs, table};
use super::{VolumeArgs, load, show};
use septa::Result;
use septa::extract::{Decompose, ExtractOptions, Surface, extract, label_infos};
use septa::mesh::quality::{QualityOptions, quality};
use septa::mesh::stats::patch_stats;
use septa::mesh::validate::{Options, validate};
use septa::output::{Formats, OutDir, patch_paths, rel_string, write_outdir};
use septa::preprocess::preprocess;
use septa::remesh::{RemeshParams, remesh};

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

#[derive(Args, Debug)]
pub struct ExtractArgs {
    #[command(flatten)]
    pub input: VolumeArgs,
    /// Output directory (interfaces.ply, patches/, junctions.ply, manifest.json).
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
    /// Extra formats besides PLY: obj (all patches, one group each), vtp (ParaView),
    /// stl (one closed outward surface per label, for printing). Repeatable or comma-separated.
    #[arg(long = "format", value_enum, value_delimiter = ',')]
    pub formats: Vec<FormatArg>,
    /// Also check the output for self-intersections (slower; always done after remeshing).
    #[arg(long)]
    pub intersections: bool,
    /// Write the extraction as it is: no smoothing, no remeshing (config: `[remesh] enabled = false`).
    #[arg(long)]
    pub no_remesh: bool,
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
    /// Split/collapse/flip/relax iterations of the remesher (default 8).
    #[arg(long, value_name = "N")]
    pub remesh_iterations: Option<u32>,
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

/// The memory budget: `--max-memory`, else what the system has available.
fn budget(args: &ExtractArgs) -> Option<(u64, &'static str)> {
    match args.max_memory {
        Some(m) => Some((m, "the --max-memory limit")),
        None => septa::estimate::available_memory().map(|m| (m, "the memory available")),
    }
}

/// Refuses a stage that would need more memory than the budget, before it
/// starts, with what it needs and what to change.
fn check_memory(
    args: &ExtractArgs,
    work: &septa::estimate::Work,
    stage: &str,
    needed: u64,
    remedy: &str,
) -> Result<()> {
    use septa::estimate::human_bytes;
    let Some((budget, what)) = budget(args) else {
        return Ok(());
    };
    if needed <= budget {
        return Ok(());
    }
    let hint = if work.looks_like_intensity() {
        format!("; {}", super::info::intensity_note(work))
    } else {
        String::new()
    };
    Err(septa::Error::input(
        &args.input.volume,
        format!(
            "{stage} would need about {} of memory ({} labels, {} boundary faces, {} critical \
             elements), more than {what} ({}){hint}; {remedy}to try anyway, raise --max-memory",
            human_bytes(needed),
            work.labels,
            count(work.boundary_faces),
            count(work.critical_edges + work.critical_vertices),
            human_bytes(budget),
        ),
    ))
}

/// Remeshing parameters from the command line, else the config, else the defaults.
fn remesh_params(
    args: &ExtractArgs,
    cfg: &septa::config::RemeshOptions,
    geometry: &septa::volume::Geometry,
) -> Option<RemeshParams> {
    // the primal faces are the exact voxel boundary, asked for as such
    if args.no_remesh || cfg.enabled == Some(false) || matches!(args.surface, SurfaceArg::Faces) {
        return None;
    }
    let d = RemeshParams::default();
    Some(RemeshParams {
        target_edge: args
            .target_edge
            .or(cfg.target_edge)
            .unwrap_or_else(|| RemeshParams::default_target(geometry)),
        min_edge: args.min_edge.or(cfg.min_edge),
        smooth_iterations: args
            .smooth_iterations
            .or(cfg.smooth_iterations)
            .unwrap_or(d.smooth_iterations),
        max_displacement: args
            .max_displacement
            .or(cfg.max_displacement)
            .unwrap_or(d.max_displacement),
        iterations: args
            .remesh_iterations
            .or(cfg.iterations)
            .unwrap_or(d.iterations),
    })
}

/// Checks the remeshing parameters against the volume; an error names the
/// flag, or the config file and key, the bad value came from.
fn check_remesh(
    params: &RemeshParams,
    args: &ExtractArgs,
    config: &septa::config::Config,
    v: &septa::volume::LabelVolume,
) -> Result<()> {
    let g = v.geometry();
    let d = v.dims();
    let n = glam::DVec3::new(d.nx as f64, d.ny as f64, d.nz as f64);
    let half = glam::DVec3::splat(0.5);
    let extent = (g.index_to_physical(n - half) - g.index_to_physical(-half)).length();
    params
        .validate_scale(g, extent)
        .map_err(|e| blame(e, args, config))
}

/// The PLY files store label values as 32-bit ints: refuse larger ones
/// now, not after the extraction.
fn check_label_values(args: &ExtractArgs, v: &septa::volume::LabelVolume) -> Result<()> {
    match v.values().iter().find(|&&x| i32::try_from(x).is_err()) {
        Some(x) => Err(septa::Error::input(
            &args.input.volume,
            format!(
                "label value {x} does not fit the 32-bit label_a/label_b properties of the PLY \
                 output (−2147483648 to 2147483647): renumber the labels"
            ),
        )),
        None => Ok(()),
    }
}

/// Turns a library parameter error into one about the flag or config key.
fn blame(e: septa::Error, args: &ExtractArgs, config: &septa::config::Config) -> septa::Error {
    let septa::Error::Parameter {
        name,
        value,
        problem,
    } = e
    else {
        return e;
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

pub fn run(args: &ExtractArgs, ui: &Ui) -> Result<ExitCode> {
    // the destination is checked before any work, and again with every file
    // the volume's header named (detached data) once it is read
    let mut outdir = OutDir::new(&args.output, args.force);
    outdir.protect(&args.input.volume);
    if let Some(c) = &args.input.config {
        outdir.protect(c);
    }
    outdir.check()?;
    let mut timings: Vec<(&str, Duration)> = Vec::new();

    let stage = ui.stage("reading volume");
    let loaded = load(&args.input, ui)?;
    timings.push(("read", stage.done()));
    for s in &loaded.sources {
        outdir.protect(s);
    }
    outdir.check()?;
    let v = &loaded.volume;
    let r = &loaded.resolved;
    let params = remesh_params(args, &loaded.config.remesh, v.geometry());
    if let Some(p) = &params {
        check_remesh(p, args, &loaded.config, v)?;
    }
    check_label_values(args, v)?;
    let work = septa::estimate::estimate(v, septa::preprocess::subdivision_for(r) as u64);
    if work.looks_like_intensity() {
        ui.warn(super::info::intensity_note(&work));
    }
    check_memory(args, &work, "preprocessing", work.preprocess_bytes(), "")?;

    let stage = ui.stage("finding and fattening critical elements");
    let pre = preprocess(v, r);
    timings.push(("preprocess", stage.done()));
    check_memory(
        args,
        &work,
        "extracting",
        work.extraction_bytes(pre.refined.refined_count() as u64),
        "",
    )?;
    if !pre.guarantee.passed() {
        ui.warn(format!(
            "preprocessing left {} critical configurations; the patches will not all be manifold (first: {:?})",
            pre.guarantee.violation_count,
            pre.guarantee.first_violations.first()
        ));
    }

    let opts = ExtractOptions {
        surface: match args.surface {
            SurfaceArg::Vesta => Surface::Vesta,
            SurfaceArg::Faces => Surface::Faces,
        },
        decompose: match args.decompose {
            DecomposeArg::L => Decompose::L,
            DecomposeArg::H => Decompose::H,
        },
    };
    let stage = ui.stage("extracting interface patches");
    let mesh = extract(
        &pre.refined,
        label_infos(v, Some(&loaded.config)),
        *v.geometry(),
        &opts,
    )?;
    timings.push(("extract", stage.done()));
    let extraction_size = (mesh.triangle_count(), mesh.vertex_count());

    let (mesh, remeshed) = match params {
        Some(params) => {
            let area = septa::estimate::surface_area(&mesh);
            let needed = work.remesh_bytes(mesh.triangle_count() as u64, area, params.target_edge);
            let remedy = format!(
                "a longer --target-edge than {} mm makes fewer triangles; ",
                params.target_edge
            );
            check_memory(args, &work, "remeshing", needed, &remedy)?;
            let stage = ui.stage(&format!(
                "smoothing and remeshing to {:.2} mm edges",
                params.target_edge
            ));
            let sizing = params.sizing(pre.refined.grid(), v.geometry());
            let out = remesh(&mesh, &sizing, &params)?;
            let q = quality(
                &out.mesh,
                Some(&mesh),
                &QualityOptions {
                    target_edge_mm: params.target_edge,
                    local: Some(&sizing),
                },
            );
            timings.push(("remesh", stage.done()));
            let kept = Kept {
                share: out.kept_share,
                islands: out.island_share,
            };
            (out.mesh, Some((params, q, out.timings, kept)))
        }
        None => (mesh, None),
    };

    let stage = ui.stage("validating");
    let report = validate(
        &mesh,
        &Options {
            intersections: args.intersections || remeshed.is_some(),
            // remeshed vertices leave the voxel grid by design; their distance
            // to the extraction is in the quality report instead
            fidelity: if remeshed.is_some() {
                None
            } else {
                Some((&pre.refined, 0.5))
            },
        },
    );
    timings.push(("validate", stage.done()));

    let stage = ui.stage("writing");
    let stats = patch_stats(&mesh);
    let patch_files = patch_paths(&mesh);
    let counts = v.voxel_counts();
    let voxel_ml = v.geometry().voxel_volume_mm3() / 1000.0;
    let (nv, ne, nf) = pre.critical.counts();
    let manifest = serde_json::json!({
        "septa": env!("CARGO_PKG_VERSION"),
        "command": std::env::args().collect::<Vec<_>>(),
        "input": {
            "file": show(&args.input.volume),
            "config": args.input.config.as_ref().map(|p| show(p)),
            "dims": v.dims().to_array(),
            "spacing_mm": v.geometry().spacing(),
            "origin_mm": v.geometry().origin(),
            "direction": v.geometry().direction(),
            "affine_lps": v.geometry().affine(),
            "orientation": v.geometry().orientation_code(),
        },
        "space": "LPS mm (x toward patient left, y posterior, z superior; as DICOM/ITK/3D Slicer)",
        "orientation": "patch {label_a, label_b}, label_a < label_b: triangle normals point from label_a into label_b",
        "parameters": {
            "surface": format!("{:?}", opts.surface).to_lowercase(),
            "decompose": format!("{:?}", opts.decompose),
            "subdivision": pre.refined.subdivision(),
            "remesh": remeshed.as_ref().map(|r| r.0),
            "outside": v.value(r.outside),
            "priority": loaded.config.priority.iter().map(|p| p.to_string()).collect::<Vec<_>>(),
            "separate": loaded.config.separate.iter().map(|s| serde_json::json!({
                "labels": s.labels.iter().map(|l| l.to_string()).collect::<Vec<_>>(), "by": s.by.to_string()})).collect::<Vec<_>>(),
        },
        "labels": (0..v.label_count()).map(|i| serde_json::json!({
            "value": v.value(i as u16), "name": mesh.label_name(i as u16),
            "voxels": counts[i], "volume_ml": counts[i] as f64 * voxel_ml,
        })).collect::<Vec<_>>(),
        "preprocessing": {
            "critical_vertices": nv, "critical_edges": ne, "constraint_faces": nf,
            "refined_voxels": pre.refined.refined_count(),
            "guarantee_passed": pre.guarantee.passed(),
        },
        "vertices": mesh.vertex_count(),
        "triangles": mesh.triangle_count(),
        "patches": mesh.patches.iter().enumerate().map(|(i, p)| serde_json::json!({
            "patch": i,
            "label_a": mesh.label_value(p.labels[0]), "label_b": mesh.label_value(p.labels[1]),
            "name_a": mesh.label_name(p.labels[0]), "name_b": mesh.label_name(p.labels[1]),
            "file": rel_string(&patch_files[i]),
            "stats": stats[i],
        })).collect::<Vec<_>>(),
        "junction_curves": mesh.junctions.iter().map(|c| serde_json::json!({
            "labels": c.labels.iter().map(|&l| mesh.label_value(l)).collect::<Vec<_>>(),
            "vertices": c.vertices.len(), "closed": c.closed,
        })).collect::<Vec<_>>(),
        "extraction": {"triangles": extraction_size.0, "vertices": extraction_size.1},
        "quality": remeshed.as_ref().map(|r| &r.1),
        "remesh_steps_s": remeshed.as_ref().map(|r| r.2),
        "remesh_kept_share": remeshed.as_ref().map(|r| r.3.share),
        "remesh_kept_islands_share": remeshed.as_ref().map(|r| r.3.islands),
        "validation": {"passed": report.passed(), "checks": report.checks},
        "timings_s": timings.iter().map(|(k, d)| ((*k).to_string(), serde_json::json!(d.as_secs_f64()))).collect::<serde_json::Map<_, _>>(),
    });
    let formats = Formats {
        obj: args.formats.contains(&FormatArg::Obj),
        vtp: args.formats.contains(&FormatArg::Vtp),
        stl: args.formats.contains(&FormatArg::Stl),
    };
    let files = write_outdir(&outdir, &mesh, formats, manifest)?;
    timings.push(("write", stage.done()));

    summarize(
        ui,
        args,
        &loaded,
        &pre,
        &mesh,
        &report,
        &stats,
        &timings,
        files.len(),
        extraction_size,
    );
    if let Some((_, q, _, kept)) = &remeshed {
        ui.say("remeshing quality (distance and volume change against the unsmoothed extraction):");
        ui.say(q.summary().trim_end());
        kept.report(ui);
    }
    if report.passed() {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!(
            "error: the output violates septa's invariants (see above and manifest.json); please report this with the input volume"
        );
        Ok(ExitCode::from(1))
    }
}

/// How much of the surface the remesher left as extracted.
struct Kept {
    share: f64,
    islands: f64,
}

impl Kept {
    fn report(&self, ui: &Ui) {
        ui.say(format!(
            "kept       {:.2} % of the surface as extracted ({:.2} % on small islands), where no \
             operation could be done without two sheets crossing or an island turning inside out",
            100.0 * self.share,
            100.0 * self.islands
        ));
        // much of it kept: structures thinner than the smallest edge
        if self.share - self.islands > 0.1 {
            ui.warn(format!(
                "{:.0} % of the surface stayed at the extraction's resolution: structures there are \
                 thinner than the smallest edge (a smaller --min-edge remeshes them)",
                100.0 * (self.share - self.islands)
            ));
        }
    }
}

#[allow(clippy::too_many_arguments)] // one summary of everything the run did
fn summarize(
    ui: &Ui,
    args: &ExtractArgs,
    loaded: &super::Loaded,
    pre: &septa::preprocess::Preprocessed,
    mesh: &septa::mesh::InterfaceMesh,
    report: &septa::mesh::validate::Report,
    stats: &[septa::mesh::stats::PatchStats],
    timings: &[(&str, Duration)],
    files: usize,
    extraction_size: (usize, usize),
) {
    let v = &loaded.volume;
    let d = v.dims();
    let (nv, ne, nf) = pre.critical.counts();
    let detail = |stage: &str| -> String {
        match stage {
            "read" => format!(
                "{} × {} × {} voxels, {} labels",
                d.nx,
                d.ny,
                d.nz,
                v.label_count()
            ),
            "preprocess" => format!(
                "{} critical vertices, {} edges, {} constraint faces; {} voxels refined ({}³){}",
                count(nv as u64),
                count(ne as u64),
                count(nf as u64),
                count(pre.refined.refined_count() as u64),
                pre.refined.subdivision(),
                if pre.guarantee.passed() {
                    ""
                } else {
                    "; GUARANTEE FAILED"
                }
            ),
            "extract" => format!(
                "{} patches, {} triangles, {} vertices, {} junction curves",
                mesh.patches.len(),
                count(extraction_size.0 as u64),
                count(extraction_size.1 as u64),
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
    rows.push(vec!["total".into(), secs(total), String::new()]);
    ui.say(table(&["stage", "time", ""], &rows));
    if !report.passed() {
        ui.say(report.summary().trim_end());
    }
    if ui.verbose > 0 || mesh.patches.len() <= 12 {
        let rows: Vec<Vec<String>> = mesh
            .patches
            .iter()
            .enumerate()
            .map(|(i, p)| {
                vec![
                    format!(
                        "{} | {}",
                        mesh.label_name(p.labels[0]),
                        mesh.label_name(p.labels[1])
                    ),
                    count(stats[i].triangles as u64),
                    format!("{:.1}", stats[i].area_mm2),
                    stats[i].boundary_loops.to_string(),
                    stats[i].euler_characteristic.to_string(),
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
