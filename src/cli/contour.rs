//! `septa contour`: DICONEX contours of a 2-D image or of one slice of a
//! volume — iso-contours of gray values, or per-label-pair polylines of a
//! label image.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::{Args, ValueEnum};

use super::iso::refuse_input_as_output;
use super::show;
use super::ui::{Ui, count, secs};
use septa::contour::{
    ContourFormat, ContourOptions, Image2d, LabelContourOptions, is_image_file, iso_contours,
    label_contours, read_image2d, slice, write_contours, write_label_contours,
};
use septa::io::{ReadOptions, read_image};
use septa::iso::Mode;
use septa::{Error, Result};

/// DICONEX's points of ambiguity: two inside pixels that touch only at a
/// corner (the 2-D counterpart of `septa iso --mode`).
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ContourModeArg {
    /// Two inside pixels touching only at a corner stay apart: separate
    /// contours.
    Disconnect,
    /// They are joined: one contour passes through the corner.
    Connect,
    /// Joined where the mean of the four pixels around the corner is ≥ iso.
    Mixed,
}

#[derive(Args, Debug)]
pub struct ContourArgs {
    /// A 2-D image (.pgm, .pbm, .pnm, .png) or a volume (.nii, .nii.gz,
    /// .nrrd, .mha, ...) with --slice (a volume with one slice needs none).
    pub image: PathBuf,
    /// Iso-contours: pixels with value ≥ VALUE are inside.
    #[arg(
        long,
        value_name = "VALUE",
        allow_negative_numbers = true,
        required_unless_present = "labels",
        conflicts_with = "labels"
    )]
    pub iso: Option<f64>,
    /// Label contours: one polyline per stretch of boundary between two
    /// labels; polylines meet at shared junction points.
    #[arg(long)]
    pub labels: bool,
    /// Iso-contours: how two inside pixels that touch only at a corner are
    /// treated (label contours resolve such corners toward the smaller label).
    #[arg(long, value_enum, default_value = "mixed", ignore_case = true)]
    pub mode: ContourModeArg,
    /// Iso-contours: keep support points at the pixel edge midpoints instead of
    /// interpolating the iso value along each range vector.
    #[arg(long)]
    pub no_displace: bool,
    /// The slice of a volume: AXIS=INDEX with AXIS x, y or z and a voxel
    /// index (e.g. z=40). Its pixel axes are the other two in order: (x, y),
    /// (x, z) or (y, z).
    #[arg(long, value_name = "AXIS=K", value_parser = parse_slice)]
    pub slice: Option<(usize, usize)>,
    /// Label contours: the label of everything outside the image (default:
    /// the most frequent label on the image border).
    #[arg(
        long,
        value_name = "LABEL",
        allow_negative_numbers = true,
        requires = "labels"
    )]
    pub outside: Option<i64>,
    /// Output: .svg (a drawing over the pixel grid), .csv (one row per
    /// point) or .json (everything; with physical coordinates for slices).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

fn parse_slice(s: &str) -> std::result::Result<(usize, usize), String> {
    let (a, k) = s
        .split_once('=')
        .ok_or_else(|| format!("`{s}`: expected AXIS=INDEX, e.g. z=40"))?;
    let axis = match a.trim().to_ascii_lowercase().as_str() {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        other => return Err(format!("unknown axis `{other}` (x, y or z)")),
    };
    let k = k
        .trim()
        .parse::<usize>()
        .map_err(|_| format!("`{k}` is not a voxel index"))?;
    Ok((axis, k))
}

/// Reads the 2-D input: an image file, or a slice of a volume.
fn read_input(args: &ContourArgs) -> Result<Image2d> {
    if is_image_file(&args.image) {
        if args.slice.is_some() {
            return Err(Error::input(
                &args.image,
                "is a 2-D image: --slice is for volumes",
            ));
        }
        return read_image2d(&args.image);
    }
    let image = read_image(&args.image, &ReadOptions::default())?;
    let dims = image.dims3()?;
    let (axis, k) = match args.slice {
        Some(s) => s,
        None if dims.nz == 1 => (2, 0),
        None => {
            return Err(Error::input(
                &args.image,
                format!(
                    "is a volume of {} × {} × {} voxels: choose a slice with --slice (e.g. --slice z={})",
                    dims.nx,
                    dims.ny,
                    dims.nz,
                    dims.nz / 2
                ),
            ));
        }
    };
    slice(&image, axis, k)
}

pub fn run(args: &ContourArgs, ui: &Ui) -> Result<ExitCode> {
    refuse_input_as_output(&args.output, &args.image)?;
    ContourFormat::of(&args.output)?;
    let mode = match args.mode {
        ContourModeArg::Disconnect => Mode::Disconnect,
        ContourModeArg::Connect => Mode::Connect,
        ContourModeArg::Mixed => Mode::Mixed,
    };
    if args.iso.is_some_and(f64::is_nan) {
        return Err(Error::invalid("the iso value is NaN"));
    }

    let stage = ui.stage("reading");
    let img = read_input(args)?;
    let t_read = stage.done();
    let mut input = serde_json::json!({
        "file": show(&args.image),
        "width": img.width,
        "height": img.height,
        "dtype": img.dtype,
    });
    if let Some(s) = img.slice {
        let (u, v) = s.plane_axes();
        let name = |a: usize| ["x", "y", "z"][a];
        input["slice"] = serde_json::json!({
            "axis": name(s.axis),
            "index": s.index,
            "pixel_axes": [name(u), name(v)],
        });
    }
    let where_ = match img.slice {
        Some(s) => format!(" (slice {}={})", ["x", "y", "z"][s.axis], s.index),
        None => String::new(),
    };

    let start = Instant::now();
    let summary = if let Some(iso) = args.iso {
        let opts = ContourOptions {
            iso,
            mode,
            displace: !args.no_displace,
        };
        let c = iso_contours(&img.values, img.width, img.height, &opts)
            .map_err(|e| in_file(e, &img))?;
        let seconds = start.elapsed().as_secs_f64();
        let holes = c.hole_count();
        let summary = serde_json::json!({
            "septa": env!("CARGO_PKG_VERSION"),
            "input": input,
            "parameters": {
                "kind": "iso",
                "iso": iso,
                "mode": mode.name(),
                "displace": opts.displace,
            },
            "active_pixels": c.active_pixels,
            "contour_count": c.contours.len(),
            "shapes": c.contours.len() - holes,
            "holes": holes,
            "point_count": c.point_count(),
            "points_of_ambiguity": c.points_of_ambiguity,
            "joined": c.joined,
            "seconds": seconds,
        });
        let stage = ui.stage("writing");
        write_contours(&args.output, &c, &img, &summary)?;
        let t_write = stage.done();
        if !args.json {
            ui.say(format!(
                "septa contour {}{where_} --iso {iso} ({}, {}) -> {}",
                show(&args.image),
                mode.name(),
                if opts.displace {
                    "displaced"
                } else {
                    "not displaced"
                },
                show(&args.output)
            ));
            ui.say(format!(
                "  {} × {} pixels, {} inside",
                img.width,
                img.height,
                count(c.active_pixels)
            ));
            if c.contours.is_empty() {
                ui.warn(format!(
                    "no contour: no pixel has a value ≥ {iso}; wrote an empty file"
                ));
            }
            ui.say(format!(
                "  {} contours ({} shapes counter-clockwise, {} holes clockwise), {} points; {} points of ambiguity, {} joined",
                count(c.contours.len() as u64),
                count((c.contours.len() - holes) as u64),
                count(holes as u64),
                count(c.point_count() as u64),
                count(c.points_of_ambiguity),
                count(c.joined)
            ));
            ui.say(format!(
                "  read {}, contour {}, write {}",
                secs(t_read),
                secs(start.elapsed() - t_write),
                secs(t_write)
            ));
        }
        summary
    } else {
        let labels = img.labels()?;
        let opts = LabelContourOptions {
            outside: args.outside,
        };
        let lc =
            label_contours(&labels, img.width, img.height, &opts).map_err(|e| in_file(e, &img))?;
        let seconds = start.elapsed().as_secs_f64();
        let mut pairs: Vec<[i64; 2]> = lc.polylines.iter().map(|p| p.labels).collect();
        pairs.sort();
        pairs.dedup();
        let closed = lc.polylines.iter().filter(|p| p.closed).count();
        let summary = serde_json::json!({
            "septa": env!("CARGO_PKG_VERSION"),
            "input": input,
            "parameters": {
                "kind": "labels",
                "outside": lc.outside,
            },
            "polyline_count": lc.polylines.len(),
            "closed": closed,
            "label_pairs": pairs,
            "point_count": lc.points.len(),
            "junctions": lc.junction_count(),
            "checkerboards": lc.checkerboards,
            "seconds": seconds,
        });
        let stage = ui.stage("writing");
        write_label_contours(&args.output, &lc, &img, &summary)?;
        let t_write = stage.done();
        if !args.json {
            ui.say(format!(
                "septa contour {}{where_} --labels (outside {}) -> {}",
                show(&args.image),
                lc.outside,
                show(&args.output)
            ));
            ui.say(format!(
                "  {} × {} pixels; {} polylines ({} closed) between {} label pairs, {} points, {} junctions",
                img.width,
                img.height,
                count(lc.polylines.len() as u64),
                count(closed as u64),
                count(pairs.len() as u64),
                count(lc.points.len() as u64),
                count(lc.junction_count() as u64)
            ));
            ui.say(format!(
                "  read {}, contour {}, write {}",
                secs(t_read),
                secs(start.elapsed() - t_write),
                secs(t_write)
            ));
        }
        summary
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary).expect("json"));
    }
    Ok(ExitCode::SUCCESS)
}

fn in_file(e: Error, img: &Image2d) -> Error {
    match e {
        Error::Invalid(m) => Error::input(&img.path, m),
        other => other,
    }
}
