//! The whole extraction in one call: a label volume and its config in, the
//! interface mesh, its junctions, the quality and validation reports, the
//! [`Manifest`] and the timings out. The `septa extract` command and the
//! Python package both call [`run`]; they only differ in where the volume
//! comes from and what they do with the [`PipelineResult`].
//!
//! Stages: resolving the config against the volume, preprocessing (finding
//! and fattening critical elements), extracting the patches, smoothing and
//! remeshing them (unless disabled), validating. Each stage reports its start
//! and end through the progress callback; the work is estimated before the
//! memory-hungry stages and a run that would need more than the budget is
//! refused before it starts.
//!
//! ```
//! use septa::config::{Config, RemeshOptions};
//! use septa::phantom::{PhantomParams, heart};
//! use septa::pipeline::{PipelineOptions, Progress, run};
//! let volume = heart(&PhantomParams { size: 16, ..Default::default() }).unwrap();
//! let options = PipelineOptions {
//!     remesh: RemeshOptions { enabled: Some(false), ..Default::default() },
//!     ..Default::default()
//! };
//! let mut stages = Vec::new();
//! let progress = &mut |p: Progress<'_>| {
//!     if let Progress::Finished { stage, .. } = p {
//!         stages.push(stage.name());
//!     }
//! };
//! let result = run(volume, &Config::default(), &options, progress).unwrap();
//! assert!(result.report.passed());
//! assert_eq!(result.manifest.triangles, result.mesh.triangle_count());
//! assert_eq!(stages, ["preprocess", "extract", "validate"]);
//! ```

use std::path::PathBuf;
use std::time::{Duration, Instant};

use crate::config::{Config, RemeshOptions};
use crate::error::{Error, Result};
use crate::estimate::{Work, human_bytes};
use crate::extract::{Decompose, ExtractOptions, Surface, extract, label_infos};
use crate::io::manifest::{
    Manifest, ManifestInput, ManifestJunction, ManifestLabel, ManifestLabelSelection,
    ManifestParameters, ManifestPatch, ManifestPreprocessing, ManifestSeparation,
    ManifestValidation, MeshSize,
};
use crate::io::output::{patch_paths, rel_string};
use crate::labels::{LabelSelection, Selected};
use crate::mesh::InterfaceMesh;
use crate::mesh::quality::{QualityOptions, QualityReport, quality};
use crate::mesh::stats::patch_stats;
use crate::mesh::validate::{self, Report, validate};
use crate::preprocess::{Preprocessed, preprocess, subdivision_for};
use crate::remesh::{RemeshParams, remesh};
use crate::volume::{Geometry, LabelVolume};

/// How to run the pipeline; [`Default`] gives what `septa extract` does
/// without flags.
#[derive(Clone, Debug, Default)]
pub struct PipelineOptions {
    /// Which surface to extract ([`Surface::Faces`] is never remeshed).
    pub surface: Surface,
    /// How N-cycles are cut into triangles.
    pub decompose: Decompose,
    /// Remeshing settings; every one given here wins over the config's
    /// `[remesh]` table, every one left `None` comes from there, else from
    /// [`RemeshParams::default`]. `enabled: Some(false)` keeps the
    /// extraction as it is.
    pub remesh: RemeshOptions,
    /// Also check for self-intersections when not remeshing (always done
    /// after remeshing).
    pub intersections: bool,
    /// Memory the run may use, in bytes; `None`: what the system has
    /// available (no limit where that is unknown).
    pub max_memory: Option<u64>,
    /// The file the volume was read from: named in messages and the manifest.
    pub source_file: Option<PathBuf>,
    /// Mesh only these labels: every other label is merged into the outside
    /// label (or the selection's `others`) before anything else, as if the
    /// volume had only these (see [`LabelSelection::apply`]).
    pub labels: Option<LabelSelection>,
    /// Merge the flat stretches of each patch in the extraction (see
    /// [`ExtractOptions::merge_flat`]); only where it is kept as is
    /// (remeshing smooths the extraction, which needs its every point).
    pub merge_flat: bool,
}

/// A stage of the pipeline.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stage {
    /// Finding and fattening critical elements.
    Preprocess,
    /// Extracting the interface patches.
    Extract,
    /// Smoothing and remeshing.
    Remesh,
    /// Checking the invariants.
    Validate,
}

impl Stage {
    /// Short name, as in the manifest's `timings_s`.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Preprocess => "preprocess",
            Stage::Extract => "extract",
            Stage::Remesh => "remesh",
            Stage::Validate => "validate",
        }
    }
}

/// What the pipeline reports while it works.
#[derive(Clone, Copy, Debug)]
pub enum Progress<'a> {
    /// A stage starts; `message` says what it does.
    Started { stage: Stage, message: &'a str },
    /// A stage has ended after `elapsed`.
    Finished { stage: Stage, elapsed: Duration },
    /// A finding that may change the result (also in [`PipelineResult::warnings`]).
    Warning(&'a str),
}

/// Everything a run produced.
#[derive(Clone, Debug)]
pub struct PipelineResult {
    /// The interface mesh (LPS mm), with its patches and junction curves.
    pub mesh: InterfaceMesh,
    /// The validator's report on `mesh`.
    pub report: Report,
    /// The remeshed mesh against the extraction (`None` without remeshing).
    pub quality: Option<QualityReport>,
    /// The manifest, without the `files` an output directory adds.
    pub manifest: Manifest,
    /// How long each stage took, in order.
    pub timings: Vec<(Stage, Duration)>,
    /// Findings that may change the result, in the order they came.
    pub warnings: Vec<String>,
}

/// Runs the pipeline on `volume` with `config` (see the module docs).
///
/// Errors: [`Error::Parameter`] for a remeshing parameter out of its bounds
/// (named as the library calls it, so a caller can name its own flag or key);
/// [`Error::Input`] (naming [`PipelineOptions::source_file`]) for a volume
/// that cannot be meshed or would need more memory than the budget;
/// [`Error::Config`] for a config that does not fit the volume.
pub fn run(
    volume: LabelVolume,
    config: &Config,
    options: &PipelineOptions,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<PipelineResult> {
    let mut warnings: Vec<String> = Vec::new();
    let mut warn = |text: String, progress: &mut dyn FnMut(Progress<'_>)| {
        progress(Progress::Warning(&text));
        warnings.push(text);
    };
    // the selection first: what follows sees only the chosen labels
    let selected;
    let (volume, config) = match &options.labels {
        Some(selection) => {
            let (volume, s) = selection.apply(volume, config, ("labels", "others"))?;
            // the outside label stays the one of the whole volume, even where
            // merging changed which label is most frequent on the border
            let mut c = config.clone();
            if c.outside.is_none() {
                c.outside = Some(crate::config::LabelRef::Value(s.outside));
            }
            selected = Some(s);
            (volume, std::borrow::Cow::Owned(c))
        }
        None => {
            selected = None;
            (volume, std::borrow::Cow::Borrowed(config))
        }
    };
    let config: &Config = &config;
    let (volume, resolved) = config.resolve(volume)?;
    for w in &resolved.warnings {
        warn(w.clone(), progress);
    }
    let v = &volume;
    let params = remesh_params(options, &config.remesh, v);
    if let Some(p) = &params {
        check_remesh_scale(p, v)?;
        if options.merge_flat {
            return Err(Error::parameter(
                "merge_flat",
                true,
                "merging flat stretches (--merge-flat) applies to the extraction written as is, \
                 and remeshing smooths the extraction, which needs every point of it: add \
                 --no-remesh (config: [remesh] enabled = false) or leave merging off",
            ));
        }
    }
    check_label_values(options, v)?;
    let work = crate::estimate::estimate(v, subdivision_for(&resolved) as u64);
    if work.looks_like_intensity() {
        warn(work.intensity_note(), progress);
    }
    let budget = Budget::new(options);
    budget.check(options, &work, "preprocessing", work.preprocess_bytes(), "")?;

    let mut timings = Vec::new();
    let mut timer = Timer::start(
        Stage::Preprocess,
        "finding and fattening critical elements",
        progress,
    );
    let pre = preprocess(v, &resolved);
    timings.push(timer.done(progress));
    let refined = pre.refined.refined_count() as u64;
    budget.check(
        options,
        &work,
        "extracting",
        work.extraction_bytes(refined),
        "",
    )?;
    if !pre.guarantee.passed() {
        warn(
            format!(
                "preprocessing left {} critical configurations; the patches will not all be manifold (first: {:?})",
                pre.guarantee.violation_count,
                pre.guarantee.first_violations.first()
            ),
            progress,
        );
    }

    let extract_options = ExtractOptions {
        surface: options.surface,
        decompose: options.decompose,
        merge_flat: options.merge_flat,
    };
    timer = Timer::start(Stage::Extract, "extracting interface patches", progress);
    let extracted = extract(
        &pre.refined,
        label_infos(v, Some(config)),
        *v.geometry(),
        &extract_options,
    )?;
    timings.push(timer.done(progress));
    let extraction = MeshSize {
        triangles: extracted.triangle_count(),
        vertices: extracted.vertex_count(),
    };
    let facts = InputFacts::new(v, resolved.outside, &pre);

    let mut remeshed = None;
    let mut pre = Some(pre);
    let mut volume = Some(volume);
    let mesh = match params {
        Some(params) => {
            let area = crate::estimate::surface_area(&extracted);
            let needed =
                work.remesh_bytes(extracted.triangle_count() as u64, area, params.target_edge);
            let remedy = format!(
                "a longer target edge than {} mm makes fewer triangles; ",
                params.target_edge
            );
            budget.check(options, &work, "remeshing", needed, &remedy)?;
            let message = format!(
                "smoothing and remeshing to {:.2} mm edges",
                params.target_edge
            );
            timer = Timer::start(Stage::Remesh, &message, progress);
            let debug_clock = std::time::Instant::now();
            let refined = &pre.as_ref().expect("not yet dropped").refined;
            let sizing = params.sizing(refined.grid(), &facts.geometry);
            let sizing_s = debug_clock.elapsed().as_secs_f64();
            // the voxels are not needed any more (the manifest keeps its
            // facts): on a 512³ volume they are half a gigabyte less at the
            // remesher's peak
            drop(pre.take());
            drop(volume.take());
            let out = remesh(&extracted, &sizing, &params)?;
            let remesh_s = debug_clock.elapsed().as_secs_f64();
            let q = quality(
                &out.mesh,
                Some(&extracted),
                &QualityOptions {
                    target_edge_mm: params.target_edge,
                    local: Some(&out.sizing),
                },
            );
            if std::env::var_os("SEPTA_DEBUG_ITER").is_some() {
                let all = debug_clock.elapsed().as_secs_f64();
                eprintln!(
                    "sizing {sizing_s:.3} s, remesh {:.3} s, quality {:.3} s",
                    remesh_s - sizing_s,
                    all - remesh_s
                );
            }
            timings.push(timer.done(progress));
            remeshed = Some(Remeshed {
                params,
                quality: q,
                steps: out.timings,
                kept_share: out.kept_share,
                kept_islands_share: out.island_share,
                kept_vertices: out.kept_vertices,
            });
            out.mesh
        }
        None => extracted,
    };

    timer = Timer::start(Stage::Validate, "validating", progress);
    let report = validate(
        &mesh,
        &validate::Options {
            intersections: options.intersections || remeshed.is_some(),
            // remeshed vertices leave the voxel grid by design; their distance
            // to the extraction is in the quality report instead (and the
            // voxels were dropped before remeshing: `pre` is gone exactly then)
            fidelity: pre.as_ref().map(|pre| (&pre.refined, 0.5)),
        },
    );
    timings.push(timer.done(progress));

    let manifest = manifest(ManifestParts {
        options,
        config,
        facts: &facts,
        extract_options,
        mesh: &mesh,
        extraction,
        remeshed: remeshed.as_ref(),
        report: &report,
        timings: &timings,
        selected: selected.as_ref(),
    });
    Ok(PipelineResult {
        mesh,
        report,
        quality: remeshed.map(|r| r.quality),
        manifest,
        timings,
        warnings,
    })
}

/// What remeshing gave, for the manifest.
struct Remeshed {
    params: RemeshParams,
    quality: QualityReport,
    steps: crate::remesh::RemeshTimings,
    kept_share: f64,
    kept_islands_share: f64,
    kept_vertices: usize,
}

/// A running stage: reported as started, timed, reported as finished.
struct Timer {
    stage: Stage,
    start: Instant,
}

impl Timer {
    fn start(stage: Stage, message: &str, progress: &mut dyn FnMut(Progress<'_>)) -> Timer {
        progress(Progress::Started { stage, message });
        crate::memory::set_activity(match stage {
            Stage::Preprocess => &"preprocessing",
            Stage::Extract => &"extracting",
            Stage::Remesh => &"remeshing",
            Stage::Validate => &"validating",
        });
        Timer {
            stage,
            start: Instant::now(),
        }
    }

    fn done(&self, progress: &mut dyn FnMut(Progress<'_>)) -> (Stage, Duration) {
        let elapsed = self.start.elapsed();
        // what the stage freed goes back to the system before the next one
        crate::memory::release();
        progress(Progress::Finished {
            stage: self.stage,
            elapsed,
        });
        (self.stage, elapsed)
    }
}

/// Remeshing parameters from the options, else the config, else the
/// defaults; `None` when the extraction is to be kept as it is.
fn remesh_params(
    options: &PipelineOptions,
    config: &RemeshOptions,
    volume: &LabelVolume,
) -> Option<RemeshParams> {
    let given = &options.remesh;
    // the primal faces are the exact voxel boundary, asked for as such
    let enabled = given.enabled.or(config.enabled).unwrap_or(true);
    if !enabled || matches!(options.surface, Surface::Faces) {
        return None;
    }
    let d = RemeshParams::default();
    Some(RemeshParams {
        target_edge: given
            .target_edge
            .or(config.target_edge)
            .unwrap_or_else(|| RemeshParams::default_target(volume.geometry())),
        min_edge: given.min_edge.or(config.min_edge),
        smooth_iterations: given
            .smooth_iterations
            .or(config.smooth_iterations)
            .unwrap_or(d.smooth_iterations),
        max_displacement: given
            .max_displacement
            .or(config.max_displacement)
            .unwrap_or(d.max_displacement),
        iterations: given
            .iterations
            .or(config.iterations)
            .unwrap_or(d.iterations),
    })
}

/// Checks the remeshing parameters against the volume's size and spacing.
fn check_remesh_scale(params: &RemeshParams, v: &LabelVolume) -> Result<()> {
    let g = v.geometry();
    let d = v.dims();
    let n = glam::DVec3::new(d.nx as f64, d.ny as f64, d.nz as f64);
    let half = glam::DVec3::splat(0.5);
    let extent = (g.index_to_physical(n - half) - g.index_to_physical(-half)).length();
    params.validate_scale(g, extent)
}

/// An error about the volume: naming its file when there is one.
fn volume_error(options: &PipelineOptions, problem: String) -> Error {
    match &options.source_file {
        Some(path) => Error::input(path, problem),
        None => Error::invalid(format!("the volume: {problem}")),
    }
}

/// The outputs store label values as 32-bit ints: refuse larger ones now,
/// not after the extraction.
fn check_label_values(options: &PipelineOptions, v: &LabelVolume) -> Result<()> {
    match v.values().iter().find(|&&x| i32::try_from(x).is_err()) {
        Some(x) => Err(volume_error(
            options,
            format!(
                "label value {x} does not fit the 32-bit label_a/label_b properties of the PLY \
                 output (−2147483648 to 2147483647): renumber the labels"
            ),
        )),
        None => Ok(()),
    }
}

/// The memory a run may use, and where the limit came from.
struct Budget(Option<(u64, &'static str)>);

impl Budget {
    fn new(options: &PipelineOptions) -> Budget {
        Budget(match options.max_memory {
            Some(m) => Some((m, "the memory limit")),
            None => crate::estimate::available_memory().map(|m| (m, "the memory available")),
        })
    }

    /// Refuses a stage that would need more memory than the budget, before
    /// it starts, with what it needs and what to change.
    fn check(
        &self,
        options: &PipelineOptions,
        work: &Work,
        stage: &str,
        needed: u64,
        remedy: &str,
    ) -> Result<()> {
        let Some((budget, what)) = self.0 else {
            return Ok(());
        };
        if needed <= budget {
            return Ok(());
        }
        let hint = if work.looks_like_intensity() {
            format!("; {}", work.intensity_note())
        } else {
            String::new()
        };
        Err(volume_error(
            options,
            format!(
                "{stage} would need about {} of memory ({} labels, {} boundary faces, {} critical \
                 elements), more than {what} ({}){hint}; {remedy}to try anyway, raise the memory \
                 limit (--max-memory, or max_memory in Python)",
                human_bytes(needed),
                work.labels,
                work.boundary_faces,
                work.critical_edges + work.critical_vertices,
                human_bytes(budget),
            ),
        ))
    }
}

/// What the manifest is made of.
struct ManifestParts<'a> {
    options: &'a PipelineOptions,
    config: &'a Config,
    facts: &'a InputFacts,
    extract_options: ExtractOptions,
    mesh: &'a InterfaceMesh,
    extraction: MeshSize,
    remeshed: Option<&'a Remeshed>,
    report: &'a Report,
    timings: &'a [(Stage, Duration)],
    selected: Option<&'a Selected>,
}

/// What the manifest reads of the volume and its preprocessing, taken
/// before remeshing so that their voxel arrays can go.
struct InputFacts {
    dims: [usize; 3],
    geometry: Geometry,
    /// Per label id: its value and voxel count.
    values: Vec<i64>,
    counts: Vec<u64>,
    outside: i64,
    critical: (usize, usize, usize),
    subdivision: usize,
    refined_voxels: usize,
    guarantee_passed: bool,
}

impl InputFacts {
    fn new(v: &LabelVolume, outside: u16, pre: &Preprocessed) -> Self {
        InputFacts {
            dims: v.dims().to_array(),
            geometry: *v.geometry(),
            values: (0..v.label_count()).map(|i| v.value(i as u16)).collect(),
            counts: v.voxel_counts(),
            outside: v.value(outside),
            critical: pre.critical.counts(),
            subdivision: pre.refined.subdivision() as usize,
            refined_voxels: pre.refined.refined_count(),
            guarantee_passed: pre.guarantee.passed(),
        }
    }
}

fn manifest(p: ManifestParts<'_>) -> Manifest {
    let (f, mesh, g) = (p.facts, p.mesh, &p.facts.geometry);
    let counts = &f.counts;
    let voxel_ml = g.voxel_volume_mm3() / 1000.0;
    let (nv, ne, nf) = f.critical;
    let stats = patch_stats(mesh);
    let files = patch_paths(mesh);
    Manifest {
        septa: env!("CARGO_PKG_VERSION").to_string(),
        command: Vec::new(),
        input: ManifestInput {
            file: p
                .options
                .source_file
                .as_ref()
                .map(|f| f.display().to_string()),
            config: p.config.path.as_ref().map(|f| f.display().to_string()),
            dims: f.dims,
            spacing_mm: g.spacing(),
            origin_mm: g.origin(),
            direction: g.direction(),
            affine_lps: g.affine(),
            orientation: g.orientation_code(),
        },
        space: crate::io::output::space_description(crate::io::Space::Lps).to_string(),
        orientation: "patch {label_a, label_b}, label_a < label_b: triangle normals point from \
                      label_a into label_b"
            .to_string(),
        parameters: ManifestParameters {
            surface: format!("{:?}", p.extract_options.surface).to_lowercase(),
            decompose: format!("{:?}", p.extract_options.decompose),
            merge_flat: p.extract_options.merge_flat,
            subdivision: f.subdivision,
            remesh: p.remeshed.map(|r| r.params),
            outside: f.outside,
            priority: p.config.priority.iter().map(|l| l.to_string()).collect(),
            separate: p
                .config
                .separate
                .iter()
                .map(|s| ManifestSeparation {
                    labels: s.labels.iter().map(|l| l.to_string()).collect(),
                    by: s.by.to_string(),
                })
                .collect(),
            label_selection: p.selected.map(|s| ManifestLabelSelection {
                kept: s.kept.clone(),
                merged: s.merged.clone(),
                into: s.target,
            }),
        },
        labels: (0..f.values.len())
            .map(|i| ManifestLabel {
                value: f.values[i],
                name: mesh.label_name(i as u16),
                voxels: counts[i],
                volume_ml: counts[i] as f64 * voxel_ml,
            })
            .collect(),
        preprocessing: ManifestPreprocessing {
            critical_vertices: nv,
            critical_edges: ne,
            constraint_faces: nf,
            refined_voxels: f.refined_voxels,
            guarantee_passed: f.guarantee_passed,
        },
        vertices: mesh.vertex_count(),
        triangles: mesh.triangle_count(),
        patches: mesh
            .patches
            .iter()
            .zip(stats)
            .enumerate()
            .map(|(i, (patch, stats))| ManifestPatch {
                patch: i as u32,
                label_a: mesh.label_value(patch.labels[0]),
                label_b: mesh.label_value(patch.labels[1]),
                name_a: mesh.label_name(patch.labels[0]),
                name_b: mesh.label_name(patch.labels[1]),
                file: rel_string(&files[i]),
                stats,
            })
            .collect(),
        junction_curves: mesh
            .junctions
            .iter()
            .map(|c| ManifestJunction {
                labels: c.labels.iter().map(|&l| mesh.label_value(l)).collect(),
                vertices: c.vertices.len(),
                closed: c.closed,
            })
            .collect(),
        extraction: p.extraction,
        quality: p.remeshed.map(|r| r.quality.clone()),
        remesh_steps_s: p.remeshed.map(|r| r.steps),
        remesh_kept_share: p.remeshed.map(|r| r.kept_share),
        remesh_kept_vertices: p.remeshed.map(|r| r.kept_vertices as u64),
        remesh_kept_islands_share: p.remeshed.map(|r| r.kept_islands_share),
        validation: ManifestValidation {
            passed: p.report.passed(),
            checks: p.report.checks.clone(),
        },
        timings_s: p
            .timings
            .iter()
            .map(|(s, d)| (s.name().to_string(), d.as_secs_f64()))
            .collect(),
        peak_memory_mb: crate::memory::peak_resident_bytes().map(|b| b as f64 / 1e6),
        files: Vec::new(),
    }
}
