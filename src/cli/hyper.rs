//! `septa hyper`: STEVE iso-hypersurface of a 4-D volume (or of 3-D frames),
//! and the closed surface at any time.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, ValueEnum};

use super::ui::{Ui, count, secs, table};
use super::{iso::refuse_input_as_output, show};
use septa::hyper::ply::write_hypersurface_ply;
use septa::hyper::{
    HyperOptions, Hypersurface, ManifoldReport, TimeSlice, check_closed_manifold, hypersurface,
    hypersurface_image, stack_frames,
};
use septa::io::{Image, ReadOptions, read_image};
use septa::iso::Mode;
use septa::mesh::validate::{Options, Report, validate};
use septa::output::OutDir;
use septa::{Error, Result};

/// Most slices one run writes.
const MAX_SLICES: usize = 100_000;

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ModeArg {
    /// Two active toxels sharing only a face stay apart.
    Disconnect,
    /// They are joined.
    Connect,
    /// Joined where the mean of the four toxels around the face is ≥ iso.
    Mixed,
}

#[derive(Args, Debug)]
pub struct HyperArgs {
    /// 4-D volume (x, y, z, t): .nii, .nii.gz, .hdr/.img, .nrrd, .nhdr, .mha, .mhd.
    #[arg(required_unless_present = "frames", conflicts_with = "frames")]
    pub volume: Option<PathBuf>,
    /// 3-D volumes as consecutive frames (same grid), instead of one 4-D file.
    #[arg(long, num_args = 2.., value_name = "FRAME")]
    pub frames: Vec<PathBuf>,
    /// Iso value: toxels with value ≥ VALUE are inside.
    #[arg(long, value_name = "VALUE", allow_negative_numbers = true)]
    pub iso: f64,
    /// How two inside toxels that share only a face (a point of ambiguity) are treated.
    #[arg(long, value_enum, default_value = "mixed", ignore_case = true)]
    pub mode: ModeArg,
    /// Keep support points at the boundary-cube centres instead of
    /// interpolating the iso value along each range vector.
    #[arg(long)]
    pub no_displace: bool,
    /// Output directory: hypersurface.ply, slice_t<T>.ply per time, summary.json.
    #[arg(short, long, value_name = "OUTDIR")]
    pub output: PathBuf,
    /// Replace OUTDIR if it exists.
    #[arg(long)]
    pub force: bool,
    /// Write the surface at time T (physical time: frame × time step); repeatable.
    #[arg(long = "at-time", value_name = "T", allow_negative_numbers = true)]
    pub at_time: Vec<f64>,
    /// Write surfaces at START, START + STEP, … up to STOP (inclusive).
    #[arg(long, value_name = "START:STOP:STEP", value_parser = parse_times, allow_hyphen_values = true)]
    pub times: Option<TimeRange>,
    /// Time per frame (default: the file's, e.g. NIfTI pixdim[4], else 1).
    #[arg(long, value_name = "DT", allow_negative_numbers = true)]
    pub time_step: Option<f64>,
    /// Another 4-D field on the same grid (e.g. density next to temperature),
    /// interpolated onto the hypersurface's vertices: vertex property `value`.
    #[arg(long, value_name = "FIELD4D")]
    pub field: Option<PathBuf>,
    /// Do not write hypersurface.ply (only the slices and the summary).
    #[arg(long)]
    pub no_hypersurface: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The times of a `--times START:STOP:STEP` range.
#[derive(Clone, Debug)]
pub struct TimeRange(pub Vec<f64>);

/// Parses `START:STOP:STEP` into the list of times.
fn parse_times(s: &str) -> std::result::Result<TimeRange, String> {
    let parts: Vec<&str> = s.split(':').collect();
    let nums: Vec<f64> = parts
        .iter()
        .map(|p| p.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| format!("`{s}`: expected START:STOP:STEP with three numbers"))?;
    let [start, stop, step] = nums[..] else {
        return Err(format!(
            "`{s}`: expected START:STOP:STEP with three numbers"
        ));
    };
    if !(start.is_finite() && stop.is_finite() && step.is_finite()) {
        return Err(format!("`{s}`: the numbers must be finite"));
    }
    if step <= 0.0 {
        return Err(format!("`{s}`: STEP must be positive"));
    }
    if stop < start {
        return Err(format!("`{s}`: STOP must not be before START"));
    }
    let n = ((stop - start) / step + 1e-9).floor() + 1.0;
    if n > MAX_SLICES as f64 {
        return Err(format!("`{s}`: {n} times, more than {MAX_SLICES}"));
    }
    Ok(TimeRange(
        (0..n as usize).map(|i| start + i as f64 * step).collect(),
    ))
}

impl HyperArgs {
    fn options(&self) -> HyperOptions {
        HyperOptions {
            iso: self.iso,
            mode: match self.mode {
                ModeArg::Disconnect => Mode::Disconnect,
                ModeArg::Connect => Mode::Connect,
                ModeArg::Mixed => Mode::Mixed,
            },
            displace: !self.no_displace,
        }
    }

    fn times(&self) -> Result<Vec<f64>> {
        let mut t = self.at_time.clone();
        t.extend(self.times.iter().flat_map(|r| r.0.iter()));
        if let Some(bad) = t.iter().find(|x| !x.is_finite()) {
            return Err(Error::invalid(format!(
                "--at-time {bad}: not a finite time"
            )));
        }
        if t.len() > MAX_SLICES {
            return Err(Error::invalid(format!(
                "{} slice times: more than {MAX_SLICES}",
                t.len()
            )));
        }
        t.sort_by(f64::total_cmp);
        t.dedup();
        Ok(t)
    }

    fn inputs(&self) -> Vec<&Path> {
        match &self.volume {
            Some(v) => vec![v.as_path()],
            None => self.frames.iter().map(|p| p.as_path()).collect(),
        }
    }
}

/// The input: one 4-D image, or frames.
enum Input {
    Volume(Image),
    Frames(Vec<Image>),
}

impl Input {
    fn describe(&self) -> (Vec<usize>, String, Option<f64>) {
        match self {
            Input::Volume(i) => (
                i.dims.clone(),
                i.samples.dtype().name().to_string(),
                i.time_step,
            ),
            Input::Frames(f) => {
                let mut d = f[0].dims.clone();
                d.truncate(3);
                d.push(f.len());
                (d, f[0].samples.dtype().name().to_string(), None)
            }
        }
    }
}

/// Stage times.
struct Timings {
    read: Duration,
    extract: Duration,
    check: Duration,
    slice: Duration,
    write: Duration,
}

/// One written slice.
struct SliceOut {
    slice: TimeSlice,
    file: String,
    report: Report,
}

pub fn run(args: &HyperArgs, ui: &Ui) -> Result<ExitCode> {
    let opts = args.options();
    opts.check()?;
    if let Some(dt) = args.time_step {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid(format!(
                "--time-step {dt}: it must be a positive number"
            )));
        }
    }
    let times = args.times()?;
    for input in args.inputs() {
        refuse_input_as_output(&args.output, input)?;
    }
    let mut outdir = OutDir::new(&args.output, args.force);
    for input in args.inputs().into_iter().chain(args.field.as_deref()) {
        outdir.protect(input);
    }
    outdir.check()?;

    let stage = ui.stage("reading");
    let input = match &args.volume {
        Some(v) => Input::Volume(read_image(v, &ReadOptions::default())?),
        None => Input::Frames(
            args.frames
                .iter()
                .map(|f| read_image(f, &ReadOptions::default()))
                .collect::<Result<_>>()?,
        ),
    };
    let t_read = stage.done();
    let read: Vec<&Image> = match &input {
        Input::Volume(i) => vec![i],
        Input::Frames(f) => f.iter().collect(),
    };
    for s in read.iter().flat_map(|i| &i.sources) {
        outdir.protect(s);
    }
    outdir.check()?;
    check_times(args, &input, &times)?;

    let stage = ui.stage("extracting the hypersurface");
    let h = match &input {
        Input::Volume(img) => hypersurface_image(img, args.time_step, &opts)?,
        Input::Frames(frames) => {
            let (values, dims, geometry) = stack_frames(frames)?;
            hypersurface(
                &values,
                dims,
                geometry,
                args.time_step.unwrap_or(1.0),
                &opts,
            )?
        }
    };
    let values = match &args.field {
        Some(f) => Some(field_values(f, &h, &input)?),
        None => None,
    };
    let t_extract = stage.done();

    let stage = ui.stage("checking the hypersurface");
    let manifold = check_closed_manifold(h.points.len(), &h.tets);
    let t_check = stage.done();

    let stage = ui.stage("slicing");
    let names = slice_names(&times);
    let mut slices = Vec::with_capacity(times.len());
    for (&t, name) in times.iter().zip(&names) {
        let slice = h.slice(t)?;
        let report = validate(&slice.mesh, &Options::default());
        slices.push(SliceOut {
            slice,
            file: name.clone(),
            report,
        });
    }
    let t_slice = stage.done();

    let stage = ui.stage("writing");
    let timings_so_far = Timings {
        read: t_read,
        extract: t_extract,
        check: t_check,
        slice: t_slice,
        write: Duration::ZERO,
    };
    let summary = summary_json(args, &input, &opts, &h, &manifold, &slices, &timings_so_far);
    write_outdir(
        &outdir,
        args,
        &h,
        &opts,
        values.as_deref(),
        &slices,
        &summary,
    )?;
    let t_write = stage.done();
    let timings = Timings {
        write: t_write,
        ..timings_so_far
    };

    let slices_ok = slices.iter().all(|s| s.report.passed());
    if args.json {
        let mut j = summary_json(args, &input, &opts, &h, &manifold, &slices, &timings);
        j["output"] = serde_json::json!(show(&args.output));
        println!("{}", serde_json::to_string_pretty(&j).expect("json"));
    } else {
        summarize(ui, args, &input, &opts, &h, &manifold, &slices, &timings);
    }
    if !manifold.passed() || !slices_ok {
        for s in slices.iter().filter(|s| !s.report.passed()) {
            eprintln!("{}: {}", s.file, s.report.summary().trim_end());
        }
        eprintln!(
            "error: the output violates septa's invariants; please report this with the input volume"
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// Slice times must lie between the first frame and the last: beyond them
/// there is no data, and a slice would be empty.
fn check_times(args: &HyperArgs, input: &Input, times: &[f64]) -> Result<()> {
    let (dims, _, file_dt) = input.describe();
    let frames = dims.get(3).copied().unwrap_or(1);
    let dt = args.time_step.or(file_dt).unwrap_or(1.0);
    let last = (frames.saturating_sub(1)) as f64 * dt;
    let (lo, hi) = (last.min(0.0), last.max(0.0));
    match times.iter().find(|&&t| t < lo || t > hi) {
        Some(t) => Err(Error::invalid(format!(
            "slice time {t} lies outside the data: {frames} frames {dt} apart span {lo} to {hi} \
             (--at-time and --times take times, not frame numbers)"
        ))),
        None => Ok(()),
    }
}

/// Reads `--field` and interpolates it onto the hypersurface.
fn field_values(path: &Path, h: &Hypersurface, input: &Input) -> Result<Vec<f64>> {
    let (dims, _, _) = input.describe();
    let img = read_image(path, &ReadOptions::default())?;
    if img.dims != dims {
        return Err(Error::input(
            path,
            format!(
                "has extents {:?} but the iso field has {dims:?}: --field needs the same grid and frames",
                img.dims
            ),
        ));
    }
    let d = [dims[0], dims[1], dims[2], dims[3]];
    h.field_values(&img.to_f64(), d)
        .map_err(|e| Error::input(path, e.to_string()))
}

/// `slice_t<T>.ply` names, zero-padded to one width with the decimals the
/// times need (at most 6), so that they sort in time order.
fn slice_names(times: &[f64]) -> Vec<String> {
    let decimals = times
        .iter()
        .map(|&t| {
            (0..=6)
                .find(|&p| {
                    let s = 10f64.powi(p);
                    ((t * s).round() / s - t).abs() <= 1e-9 * t.abs().max(1.0)
                })
                .unwrap_or(6) as usize
        })
        .max()
        .unwrap_or(0);
    let int_digits = times
        .iter()
        .map(|t| format!("{:.0}", t.abs().trunc()).len())
        .max()
        .unwrap_or(1);
    let negative = times.iter().any(|&t| t < 0.0) as usize;
    let width = negative + int_digits + if decimals > 0 { decimals + 1 } else { 0 };
    let mut names: Vec<String> = times
        .iter()
        .map(|t| format!("slice_t{t:0width$.decimals$}.ply"))
        .collect();
    // times closer than the decimals shown would collide: number them instead
    let mut sorted = names.clone();
    sorted.sort();
    sorted.dedup();
    if sorted.len() != names.len() {
        let w = times.len().to_string().len();
        names = (0..times.len())
            .map(|i| format!("slice_{i:0w$}.ply"))
            .collect();
    }
    names
}

/// Writes everything into a temporary directory beside OUTDIR, then renames it
/// into place (replacing an old OUTDIR only with --force, checked before).
fn write_outdir(
    outdir: &OutDir,
    args: &HyperArgs,
    h: &Hypersurface,
    opts: &HyperOptions,
    values: Option<&[f64]>,
    slices: &[SliceOut],
    summary: &serde_json::Value,
) -> Result<()> {
    outdir.write(|tmp| {
        let mut files = Vec::new();
        if !args.no_hypersurface {
            write_hypersurface_ply(&tmp.join("hypersurface.ply"), h, opts, values)?;
            files.push("hypersurface.ply".to_string());
        }
        for s in slices {
            septa::io::mesh_ply::write_ply(&tmp.join(&s.file), &s.slice.mesh)?;
            files.push(s.file.clone());
        }
        files.push("summary.json".to_string());
        // the list marks the directory as septa's, for a later --force
        let mut summary = summary.clone();
        summary["files"] = serde_json::json!(files);
        let mut json =
            serde_json::to_vec_pretty(&summary).map_err(|e| Error::invalid(e.to_string()))?;
        json.push(b'\n');
        septa::io::atomic_write(&tmp.join("summary.json"), &json)
    })
}

fn summary_json(
    args: &HyperArgs,
    input: &Input,
    opts: &HyperOptions,
    h: &Hypersurface,
    manifold: &ManifoldReport,
    slices: &[SliceOut],
    t: &Timings,
) -> serde_json::Value {
    let (dims, dtype, file_dt) = input.describe();
    let st = &h.stats;
    serde_json::json!({
        "septa": env!("CARGO_PKG_VERSION"),
        "input": {
            "files": args.inputs().iter().map(|p| show(p)).collect::<Vec<_>>(),
            "dims": dims,
            "dtype": dtype,
            "spacing_mm": h.geometry.spacing(),
            "affine_lps": h.geometry.affine(),
            "file_time_step": file_dt,
        },
        "parameters": {
            "iso": opts.iso,
            "mode": opts.mode.name(),
            "displace": opts.displace,
            "time_step": h.time_step,
        },
        "hypersurface": {
            "file": if args.no_hypersurface { None } else { Some("hypersurface.ply") },
            "field": args.field.as_ref().map(|f| show(f)),
            "active_toxels": st.active_toxels,
            "support_points": st.support_points,
            "face_centres": st.face_centres,
            "volume_centres": st.volume_centres,
            "points": st.points,
            "tetrahedra": st.tetrahedra,
            "cells": st.cells,
            "polyhedra": st.polyhedra,
            "tetrahedron_polyhedra": st.tetrahedron_polyhedra,
            "toroidal_polyhedra": st.higher_genus,
            "points_of_ambiguity": st.ambiguities,
            "cycles": (3..=12).map(|n| (n.to_string(), serde_json::json!(st.cycles_by_length[n])))
                .collect::<serde_json::Map<_, _>>(),
            "time_range": h.time_range(),
            "check": manifold,
            "closed_oriented": manifold.passed(),
        },
        "slices": slices.iter().map(|s| {
            let surf = s.report.labels.iter().find(|l| l.value == 0);
            serde_json::json!({
                "time": s.slice.time,
                "frame": s.slice.frame,
                "file": s.file,
                "vertices": s.slice.mesh.vertex_count(),
                "triangles": s.slice.mesh.triangle_count(),
                "components": surf.map_or(0, |l| l.components),
                "volume_mm3": surf.map_or(0.0, |l| l.volume_mm3),
                "separated_vertices": s.slice.separated,
                "valid": s.report.passed(),
            })
        }).collect::<Vec<_>>(),
        "timings_s": {
            "read": t.read.as_secs_f64(),
            "extract": t.extract.as_secs_f64(),
            "extract_internal": st.seconds,
            "check": t.check.as_secs_f64(),
            "slice_and_validate": t.slice.as_secs_f64(),
            "write": t.write.as_secs_f64(),
        },
    })
}

#[allow(clippy::too_many_arguments)]
fn summarize(
    ui: &Ui,
    args: &HyperArgs,
    input: &Input,
    opts: &HyperOptions,
    h: &Hypersurface,
    manifold: &ManifoldReport,
    slices: &[SliceOut],
    t: &Timings,
) {
    let (dims, dtype, _) = input.describe();
    let st = &h.stats;
    let inputs = args.inputs();
    let what = if inputs.len() == 1 {
        show(inputs[0])
    } else {
        format!("{} frames ({} …)", inputs.len(), show(inputs[0]))
    };
    ui.say(format!(
        "septa hyper {what} --iso {} ({}, {}) -> {}",
        opts.iso,
        opts.mode.name(),
        if opts.displace {
            "displaced"
        } else {
            "not displaced"
        },
        show(&args.output)
    ));
    let n: usize = dims.iter().product();
    ui.say(format!(
        "  {} × {} × {} voxels × {} frames ({dtype}), time step {}, {} inside ({:.2} %)",
        dims[0],
        dims[1],
        dims[2],
        dims.get(3).copied().unwrap_or(1),
        h.time_step,
        count(st.active_toxels),
        100.0 * st.active_toxels as f64 / n.max(1) as f64
    ));
    if h.tets.is_empty() {
        ui.warn(format!(
            "empty hypersurface: no toxel has a value ≥ {}",
            opts.iso
        ));
    }
    let rows = vec![
        vec!["support points".into(), count(st.support_points as u64)],
        vec!["face centres".into(), count(st.face_centres as u64)],
        vec!["volume centres".into(), count(st.volume_centres as u64)],
        vec!["tetrahedra".into(), count(st.tetrahedra as u64)],
        vec![
            "polyhedra".into(),
            format!(
                "{} ({} tetrahedra, {} toroidal)",
                count(st.polyhedra),
                count(st.tetrahedron_polyhedra),
                count(st.higher_genus)
            ),
        ],
        vec![
            "closed oriented".into(),
            if manifold.passed() { "yes" } else { "NO" }.into(),
        ],
    ];
    ui.say(table(&["hypersurface", ""], &rows));
    if !slices.is_empty() {
        let rows: Vec<Vec<String>> = slices
            .iter()
            .map(|s| {
                let surf = s.report.labels.iter().find(|l| l.value == 0);
                vec![
                    format!("{}", s.slice.time),
                    s.file.clone(),
                    count(s.slice.mesh.triangle_count() as u64),
                    surf.map_or(0, |l| l.components).to_string(),
                    if s.report.passed() { "ok" } else { "INVALID" }.into(),
                ]
            })
            .collect();
        ui.say(table(
            &["time", "file", "triangles", "components", "check"],
            &rows,
        ));
    }
    ui.say(format!(
        "  read {}, extract {}, check {}, slice {}, write {}",
        secs(t.read),
        secs(t.extract),
        secs(t.check),
        secs(t.slice),
        secs(t.write)
    ));
}
