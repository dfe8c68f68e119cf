//! `septa._septa`: the Rust side of the Python package. Thin: it converts
//! numpy arrays and Python values to septa's types, calls
//! [`septa::pipeline::run`] with the GIL released, and hands the result back
//! as arrays; the Python side (`septa/__init__.py`) builds the user-facing
//! objects on top.

use std::path::PathBuf;

use numpy::{
    IntoPyArray, PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyReadonlyArrayDyn,
    PyUntypedArrayMethods,
};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;

use septa::config::{Config, RemeshOptions};
use septa::io::label_files::LabelFormats;
use septa::labels::{LabelNames, LabelSelection, parse_label_ref};
use septa::mesh::InterfaceMesh;
use septa::pipeline::{PipelineOptions, PipelineResult, Progress};
use septa::volume::{Dims, Geometry, LabelVolume};

create_exception!(
    _septa,
    SeptaError,
    PyValueError,
    "Base class of septa's errors."
);
create_exception!(
    _septa,
    InputError,
    SeptaError,
    "A file or volume septa cannot use (the message names it and the problem)."
);
create_exception!(
    _septa,
    ConfigError,
    SeptaError,
    "A wrong entry in the configuration (the message names the key)."
);
create_exception!(
    _septa,
    ParameterError,
    SeptaError,
    "A parameter out of its bounds (the message names it)."
);
create_exception!(
    _septa,
    InvariantError,
    PyException,
    "The output violates septa's invariants (please report it)."
);

/// septa's error as the Python exception of its cause, with septa's message.
fn to_py(e: septa::Error) -> PyErr {
    let message = e.to_string();
    match e {
        septa::Error::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(message)
        }
        septa::Error::Io { .. } => PyOSError::new_err(message),
        septa::Error::Input { .. } => InputError::new_err(message),
        septa::Error::Config { .. } => ConfigError::new_err(message),
        septa::Error::Parameter { .. } => ParameterError::new_err(message),
        septa::Error::Invalid(_) => SeptaError::new_err(message),
    }
}

/// A volume as the Python side takes it apart: label values (flat, x
/// fastest), `(nx, ny, nz)`, and the rows of the index → LPS mm affine.
type VolumeParts<'py> = (Bound<'py, PyArray1<i64>>, [usize; 3], [[f64; 4]; 3]);

/// Reads a label volume file (the Python side reshapes the values to
/// `(nx, ny, nz)`).
#[pyfunction]
fn read_volume(py: Python<'_>, path: PathBuf) -> PyResult<VolumeParts<'_>> {
    let volume = py
        .allow_threads(|| {
            let image = septa::io::read_image(&path, &septa::io::ReadOptions::default())?;
            image.into_label_volume()
        })
        .map_err(to_py)?;
    let ids = volume.ids();
    let values = volume.values();
    let flat: Vec<i64> = ids.iter().map(|&i| values[i as usize]).collect();
    Ok((
        flat.into_pyarray(py),
        volume.dims().to_array(),
        volume.geometry().affine(),
    ))
}

/// A configuration from TOML text (`source` names it in messages) or a
/// file.
fn config(toml_text: Option<String>, path: Option<PathBuf>) -> septa::Result<Config> {
    match (toml_text, path) {
        (_, Some(path)) => Config::from_file(&path),
        (Some(text), None) => Config::from_toml_str(&text, "config".as_ref()),
        (None, None) => Ok(Config::default()),
    }
}

/// A config dict (as JSON text) as TOML text, for [`Config::from_toml_str`].
#[pyfunction]
fn config_json_to_toml(json: &str) -> PyResult<String> {
    let value: toml::Value = serde_json::from_str(json)
        .map_err(|e| ConfigError::new_err(format!("config: {e} (null values are not allowed)")))?;
    toml::to_string(&value).map_err(|e| ConfigError::new_err(format!("config: {e}")))
}

/// `"lps"` or `"ras"`.
fn parse_space(space: &str) -> PyResult<septa::io::Space> {
    match space.to_ascii_lowercase().as_str() {
        "lps" => Ok(septa::io::Space::Lps),
        "ras" => Ok(septa::io::Space::Ras),
        _ => Err(ParameterError::new_err(format!(
            "space = {space:?}: use \"ras\" or \"lps\""
        ))),
    }
}

/// The result of an extraction, as the Python side reads it.
#[pyclass(module = "septa._septa", frozen)]
struct Extraction {
    result: PipelineResult,
}

fn mesh_arrays(py: Python<'_>, mesh: &InterfaceMesh) -> PyResult<Py<PyAny>> {
    let n = mesh.positions.len();
    let positions: Vec<f64> = mesh.positions.iter().flat_map(|p| p.to_array()).collect();
    let triangles: Vec<i64> = mesh
        .triangles
        .iter()
        .flat_map(|t| t.map(i64::from))
        .collect();
    let labels: Vec<i64> = mesh
        .triangle_patch
        .iter()
        .flat_map(|&p| mesh.patches[p as usize].labels.map(|l| mesh.label_value(l)))
        .collect();
    let patch: Vec<i64> = mesh.triangle_patch.iter().map(|&p| i64::from(p)).collect();
    let m = mesh.triangles.len();
    let vertices = positions.into_pyarray(py).reshape([n, 3])?;
    let triangles = triangles.into_pyarray(py).reshape([m, 3])?;
    let labels = labels.into_pyarray(py).reshape([m, 2])?;
    let dict = pyo3::types::PyDict::new(py);
    dict.set_item("vertices", vertices)?;
    dict.set_item("triangles", triangles)?;
    dict.set_item("labels", labels)?;
    dict.set_item("patch", patch.into_pyarray(py))?;
    Ok(dict.into_any().unbind())
}

#[pymethods]
impl Extraction {
    /// `{"vertices": (N, 3) float64 LPS mm, "triangles": (M, 3) int64,
    /// "labels": (M, 2) int64 label values, "patch": (M,) int64}`.
    fn arrays(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        mesh_arrays(py, &self.result.mesh)
    }

    /// Junction curves: `[(label values, vertex ids, closed)]`.
    fn junctions<'py>(&self, py: Python<'py>) -> Vec<(Vec<i64>, Bound<'py, PyArray1<i64>>, bool)> {
        let mesh = &self.result.mesh;
        mesh.junctions
            .iter()
            .map(|c| {
                let labels = c.labels.iter().map(|&l| mesh.label_value(l)).collect();
                let ids: Vec<i64> = c.vertices.iter().map(|&v| i64::from(v)).collect();
                (labels, ids.into_pyarray(py), c.closed)
            })
            .collect()
    }

    /// Label values and names: `[(value, name)]`.
    fn label_names(&self) -> Vec<(i64, String)> {
        let mesh = &self.result.mesh;
        (0..mesh.labels.len())
            .map(|l| (mesh.label_value(l as u16), mesh.label_name(l as u16)))
            .collect()
    }

    /// The manifest as JSON text.
    fn manifest_json(&self) -> PyResult<String> {
        self.result.manifest.to_json().map_err(to_py)
    }

    /// Warnings of the run.
    fn warnings(&self) -> Vec<String> {
        self.result.warnings.clone()
    }

    /// Whether every invariant holds.
    fn passed(&self) -> bool {
        self.result.report.passed()
    }

    /// The validator's summary.
    fn validation_summary(&self) -> String {
        self.result.report.summary()
    }

    /// Writes the output directory as `septa extract` does; the list of
    /// files written (relative paths).
    #[pyo3(signature = (directory, force=false, obj=false, stl=false, space="lps", per_label=Vec::new()))]
    #[allow(clippy::too_many_arguments)] // one keyword argument per option
    fn save(
        &self,
        py: Python<'_>,
        directory: PathBuf,
        force: bool,
        obj: bool,
        stl: bool,
        space: &str,
        per_label: Vec<String>,
    ) -> PyResult<Vec<String>> {
        let space = parse_space(space)?;
        let mut labels = LabelFormats::parse(per_label.iter().map(String::as_str))
            .map_err(|e| ParameterError::new_err(format!("per_label: {e}")))?;
        labels.stl |= stl;
        let formats = septa::output::Formats {
            obj,
            per_label: labels,
            ..Default::default()
        };
        let mut manifest = self.result.manifest.clone();
        let mesh = &self.result.mesh;
        let files = py
            .allow_threads(|| {
                let outdir = septa::output::OutDir::new(&directory, force);
                outdir.check()?;
                septa::output::write_outdir(&outdir, mesh, formats, space, &mut manifest)
            })
            .map_err(to_py)?;
        Ok(files.iter().map(|f| septa::output::rel_string(f)).collect())
    }
}

/// Runs the pipeline on `labels` (an `(nx, ny, nz)` int64 array, indexed
/// `[x, y, z]`) with the index → LPS mm `affine_lps` (3 × 4 rows).
#[pyfunction]
#[pyo3(signature = (
    volume, affine_lps, config_toml=None, config_path=None, remesh=None, target_edge=None,
    min_edge=None, smooth_iterations=None, max_displacement=None, iterations=None,
    surface="vesta", decompose="l", intersections=false, max_memory=None, source_file=None,
    progress=None, label_names=None, label_names_path=None, labels=None, others=None,
    merge_flat=false,
))]
#[allow(clippy::too_many_arguments)] // one keyword argument per option
fn extract(
    py: Python<'_>,
    volume: PyReadonlyArray3<'_, i64>,
    affine_lps: [[f64; 4]; 3],
    config_toml: Option<String>,
    config_path: Option<PathBuf>,
    remesh: Option<bool>,
    target_edge: Option<f64>,
    min_edge: Option<f64>,
    smooth_iterations: Option<u32>,
    max_displacement: Option<f64>,
    iterations: Option<u32>,
    surface: &str,
    decompose: &str,
    intersections: bool,
    max_memory: Option<u64>,
    source_file: Option<PathBuf>,
    progress: Option<Py<PyAny>>,
    label_names: Option<Vec<(i64, String)>>,
    label_names_path: Option<PathBuf>,
    labels: Option<Vec<String>>,
    others: Option<String>,
    merge_flat: bool,
) -> PyResult<Extraction> {
    let surface = match surface {
        "vesta" => septa::extract::Surface::Vesta,
        "faces" => septa::extract::Surface::Faces,
        other => {
            return Err(ParameterError::new_err(format!(
                "surface = {other:?}: use \"vesta\" or \"faces\""
            )));
        }
    };
    let decompose = parse_decompose(decompose)?;
    let view = volume.as_array();
    let shape = view.shape();
    let dims = Dims::new(shape[0], shape[1], shape[2]).map_err(to_py)?;
    // x fastest, as septa stores volumes
    let values: Vec<i64> = view.t().iter().copied().collect();
    let options = PipelineOptions {
        surface,
        decompose,
        remesh: RemeshOptions {
            enabled: remesh,
            target_edge,
            min_edge,
            smooth_iterations,
            max_displacement,
            iterations,
        },
        intersections,
        merge_flat,
        max_memory,
        source_file,
        labels: labels.map(|keep| LabelSelection {
            keep: keep.iter().map(|l| parse_label_ref(l)).collect(),
            others: others.as_deref().map(parse_label_ref),
        }),
    };
    let result = py.allow_threads(|| -> septa::Result<PipelineResult> {
        let geometry = Geometry::from_affine(affine_lps)?;
        let volume = LabelVolume::from_values(dims, &values, geometry)?;
        let mut config = config(config_toml, config_path)?;
        if let Some(path) = &label_names_path {
            config = config.with_label_names(&septa::labels::read_label_names(path)?)?;
        }
        if let Some(names) = label_names {
            config = config.with_label_names(&label_names_from(names)?)?;
        }
        let mut report = |p: Progress<'_>| {
            let Some(callback) = &progress else {
                return;
            };
            let (event, stage, text) = match p {
                Progress::Started { stage, message } => ("started", stage.name(), message),
                Progress::Finished { stage, .. } => ("finished", stage.name(), ""),
                Progress::Warning(text) => ("warning", "", text),
            };
            Python::with_gil(|py| {
                if let Err(e) = callback.call1(py, (event, stage, text)) {
                    e.print(py);
                }
            });
        };
        septa::pipeline::run(volume, &config, &options, &mut report)
    });
    Ok(Extraction {
        result: result.map_err(to_py)?,
    })
}

/// A mesh file (PLY as septa writes it) read back: the arrays of
/// [`Extraction::arrays`].
#[pyfunction]
fn read_mesh(py: Python<'_>, path: PathBuf) -> PyResult<Py<PyAny>> {
    let mesh = py
        .allow_threads(|| septa::io::mesh_ply::read_ply(&path).map(|p| p.mesh))
        .map_err(to_py)?;
    mesh_arrays(py, &mesh)
}

/// Whether a mesh file keeps septa's invariants: `(passed, summary)`.
#[pyfunction]
fn check(py: Python<'_>, path: PathBuf) -> PyResult<(bool, String)> {
    let report = py
        .allow_threads(|| -> septa::Result<_> {
            let mesh = septa::io::mesh_ply::read_ply(&path)?.mesh;
            let options = septa::mesh::validate::Options {
                intersections: true,
                fidelity: None,
            };
            Ok(septa::mesh::validate::validate(&mesh, &options))
        })
        .map_err(to_py)?;
    Ok((report.passed(), report.summary()))
}

/// Label names given as `(value, name)` pairs, checked as a file's are.
fn label_names_from(names: Vec<(i64, String)>) -> septa::Result<LabelNames> {
    let json = serde_json::Value::Array(
        names
            .into_iter()
            .map(|(value, name)| serde_json::json!({"value": value, "name": name}))
            .collect(),
    );
    septa::labels::parse_label_names(
        &json.to_string(),
        "label_names".as_ref(),
        Some(septa::labels::LabelNameFormat::Json),
    )
}

/// A validator report as JSON text (the Python side turns it into a dict).
fn report_json(report: &septa::mesh::validate::Report) -> PyResult<String> {
    let j = serde_json::json!({
        "passed": report.passed(),
        "failures": report.failures(),
        "summary": report.summary(),
        "vertices": report.vertices,
        "triangles": report.triangles,
        "patches": report.patches,
        "checks": report.checks,
        "labels": report.labels,
    });
    serde_json::to_string(&j).map_err(|e| SeptaError::new_err(e.to_string()))
}

/// Validates a mesh given as arrays: `vertices` (N, 3), `triangles` (M, 3)
/// and optionally `labels` (M, 2) label values per triangle (without them
/// the mesh is checked as one closed surface). The report as JSON text.
#[pyfunction]
#[pyo3(signature = (vertices, triangles, labels=None, intersections=true))]
fn check_arrays(
    py: Python<'_>,
    vertices: PyReadonlyArray2<'_, f64>,
    triangles: PyReadonlyArray2<'_, i64>,
    labels: Option<PyReadonlyArray2<'_, i64>>,
    intersections: bool,
) -> PyResult<String> {
    let shape_error = |what: &str, shape: &[usize], cols: usize| {
        ParameterError::new_err(format!(
            "{what}: expected an array of shape (n, {cols}), got {shape:?}"
        ))
    };
    let v = vertices.as_array();
    if v.ndim() != 2 || v.shape()[1] != 3 {
        return Err(shape_error("vertices", v.shape(), 3));
    }
    let positions: Vec<glam::DVec3> = v
        .rows()
        .into_iter()
        .map(|r| glam::DVec3::new(r[0], r[1], r[2]))
        .collect();
    let t = triangles.as_array();
    if t.shape()[1] != 3 {
        return Err(shape_error("triangles", t.shape(), 3));
    }
    let tris: Vec<[i64; 3]> = t.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect();
    let pairs: Option<Vec<[i64; 2]>> = match &labels {
        Some(l) => {
            let l = l.as_array();
            if l.shape()[1] != 2 {
                return Err(shape_error("labels", l.shape(), 2));
            }
            Some(l.rows().into_iter().map(|r| [r[0], r[1]]).collect())
        }
        None => None,
    };
    let report = py
        .allow_threads(|| -> septa::Result<_> {
            let mesh = septa::io::mesh_ply::mesh_from_arrays(
                positions,
                &tris,
                pairs.as_deref(),
                &Default::default(),
            )?;
            let options = septa::mesh::validate::Options {
                intersections,
                fidelity: None,
            };
            Ok(septa::mesh::validate::validate(&mesh, &options))
        })
        .map_err(to_py)?;
    report_json(&report)
}

/// `"disconnect"`, `"connect"` or `"mixed"`.
fn parse_mode(mode: &str) -> PyResult<septa::iso::Mode> {
    mode.parse()
        .map_err(|e: septa::Error| ParameterError::new_err(format!("mode: {e}")))
}

/// A numpy array of any real dtype as the samples septa takes: the common
/// ones without a copy, anything else as float64 (the Python side converts).
enum Samples<'py> {
    U8(PyReadonlyArrayDyn<'py, u8>),
    I16(PyReadonlyArrayDyn<'py, i16>),
    U16(PyReadonlyArrayDyn<'py, u16>),
    I32(PyReadonlyArrayDyn<'py, i32>),
    F32(PyReadonlyArrayDyn<'py, f32>),
    F64(PyReadonlyArrayDyn<'py, f64>),
}

impl<'py> Samples<'py> {
    fn from(a: &Bound<'py, PyAny>) -> PyResult<Self> {
        if let Ok(x) = a.extract() {
            return Ok(Samples::U8(x));
        }
        if let Ok(x) = a.extract() {
            return Ok(Samples::I16(x));
        }
        if let Ok(x) = a.extract() {
            return Ok(Samples::U16(x));
        }
        if let Ok(x) = a.extract() {
            return Ok(Samples::I32(x));
        }
        if let Ok(x) = a.extract() {
            return Ok(Samples::F32(x));
        }
        Ok(Samples::F64(a.extract()?))
    }

    fn shape(&self) -> Vec<usize> {
        match self {
            Samples::U8(a) => a.shape().to_vec(),
            Samples::I16(a) => a.shape().to_vec(),
            Samples::U16(a) => a.shape().to_vec(),
            Samples::I32(a) => a.shape().to_vec(),
            Samples::F32(a) => a.shape().to_vec(),
            Samples::F64(a) => a.shape().to_vec(),
        }
    }
}

/// The values of an array indexed `[x, y, z(, t)]`, x fastest.
fn x_fastest<T: Copy + numpy::Element>(a: &PyReadonlyArrayDyn<'_, T>) -> Vec<T> {
    a.as_array().t().iter().copied().collect()
}

/// The VESTA iso-surface of `values` (an `(nx, ny, nz)` array of any real
/// dtype) with the index → LPS mm `affine_lps`: the arrays of
/// [`Extraction::arrays`] and the N-cycle statistics as JSON text.
#[pyfunction]
#[pyo3(signature = (values, affine_lps, iso, mode="mixed", decompose="l", displace=true))]
fn iso<'py>(
    py: Python<'py>,
    values: &Bound<'py, PyAny>,
    affine_lps: [[f64; 4]; 3],
    iso: f64,
    mode: &str,
    decompose: &str,
    displace: bool,
) -> PyResult<(Py<PyAny>, String)> {
    let samples = Samples::from(values)?;
    let shape = samples.shape();
    if shape.len() != 3 {
        return Err(InputError::new_err(format!(
            "values: expected a 3-D array (nx, ny, nz), got shape {shape:?}"
        )));
    }
    let dims = Dims::new(shape[0], shape[1], shape[2]).map_err(to_py)?;
    let opts = septa::iso::IsoOptions {
        iso,
        mode: parse_mode(mode)?,
        decompose: parse_decompose(decompose)?,
        displace,
    };
    let geometry = Geometry::from_affine(affine_lps).map_err(to_py)?;
    macro_rules! run {
        ($a:expr) => {{
            let v = x_fastest($a);
            py.allow_threads(|| septa::iso::iso_surface(&v, dims, geometry, &opts))
        }};
    }
    let surface = match &samples {
        Samples::U8(a) => run!(a),
        Samples::I16(a) => run!(a),
        Samples::U16(a) => run!(a),
        Samples::I32(a) => run!(a),
        Samples::F32(a) => run!(a),
        Samples::F64(a) => run!(a),
    }
    .map_err(to_py)?;
    let stats =
        serde_json::to_string(&surface.stats).map_err(|e| SeptaError::new_err(e.to_string()))?;
    Ok((mesh_arrays(py, &surface.mesh)?, stats))
}

/// A STEVE iso-hypersurface, as the Python side reads it.
#[pyclass(module = "septa._septa", frozen)]
struct Hyper {
    h: septa::hyper::Hypersurface,
}

#[pymethods]
impl Hyper {
    /// `(points (N, 4) x, y, z LPS mm and t, tets (M, 4) int64, kinds (N,) uint8)`.
    #[allow(clippy::type_complexity)]
    fn arrays<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(
        Bound<'py, PyAny>,
        Bound<'py, PyAny>,
        Bound<'py, PyArray1<u8>>,
    )> {
        let points: Vec<f64> = self.h.physical_points().into_iter().flatten().collect();
        let n = points.len() / 4;
        let tets: Vec<i64> = self
            .h
            .physical_tets()
            .into_iter()
            .flat_map(|t| t.map(i64::from))
            .collect();
        let m = tets.len() / 4;
        let kinds: Vec<u8> = self.h.kinds.iter().map(|&k| k as u8).collect();
        Ok((
            points.into_pyarray(py).reshape([n, 4])?.into_any(),
            tets.into_pyarray(py).reshape([m, 4])?.into_any(),
            kinds.into_pyarray(py),
        ))
    }

    /// Counts and timing as JSON text.
    fn stats_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.h.stats).map_err(|e| SeptaError::new_err(e.to_string()))
    }

    /// The physical time range, if the hypersurface is not empty.
    fn time_range(&self) -> Option<(f64, f64)> {
        self.h.time_range()
    }

    /// The closed surface at physical time `time`: the arrays of
    /// [`Extraction::arrays`], the frame whose own time it is (if any), and
    /// the validator's report as JSON text.
    fn slice(&self, py: Python<'_>, time: f64) -> PyResult<(Py<PyAny>, Option<usize>, String)> {
        let (s, report) = py
            .allow_threads(|| -> septa::Result<_> {
                let s = self.h.slice(time)?;
                let report = septa::mesh::validate::validate(
                    &s.mesh,
                    &septa::mesh::validate::Options::default(),
                );
                Ok((s, report))
            })
            .map_err(to_py)?;
        Ok((mesh_arrays(py, &s.mesh)?, s.frame, report_json(&report)?))
    }

    /// The closed-3-manifold check of the tetrahedra, as JSON text.
    fn check_json(&self, py: Python<'_>) -> PyResult<String> {
        let r = py.allow_threads(|| {
            septa::hyper::check_closed_manifold(self.h.points.len(), &self.h.tets)
        });
        let mut j = serde_json::to_value(&r).map_err(|e| SeptaError::new_err(e.to_string()))?;
        j["passed"] = r.passed().into();
        j["manifold"] = r.is_manifold().into();
        Ok(j.to_string())
    }
}

/// The STEVE iso-hypersurface of `values` (an `(nx, ny, nz, nt)` array of
/// any real dtype, frames `time_step` apart) with the spatial index → LPS
/// mm `affine_lps`.
#[pyfunction]
#[pyo3(signature = (values, affine_lps, iso, time_step=1.0, mode="mixed", displace=true))]
fn hyper<'py>(
    py: Python<'py>,
    values: &Bound<'py, PyAny>,
    affine_lps: [[f64; 4]; 3],
    iso: f64,
    time_step: f64,
    mode: &str,
    displace: bool,
) -> PyResult<Hyper> {
    let samples = Samples::from(values)?;
    let shape = samples.shape();
    if shape.len() != 4 {
        return Err(InputError::new_err(format!(
            "values: expected a 4-D array (nx, ny, nz, nt), got shape {shape:?}"
        )));
    }
    let dims = [shape[0], shape[1], shape[2], shape[3]];
    let opts = septa::hyper::HyperOptions {
        iso,
        mode: parse_mode(mode)?,
        displace,
    };
    let geometry = Geometry::from_affine(affine_lps).map_err(to_py)?;
    macro_rules! run {
        ($a:expr) => {{
            let v = x_fastest($a);
            py.allow_threads(|| septa::hyper::hypersurface(&v, dims, geometry, time_step, &opts))
        }};
    }
    let h = match &samples {
        Samples::U8(a) => run!(a),
        Samples::I16(a) => run!(a),
        Samples::U16(a) => run!(a),
        Samples::I32(a) => run!(a),
        Samples::F32(a) => run!(a),
        Samples::F64(a) => run!(a),
    }
    .map_err(to_py)?;
    Ok(Hyper { h })
}

/// `"l"` or `"h"`.
fn parse_decompose(decompose: &str) -> PyResult<septa::extract::Decompose> {
    match decompose.to_ascii_lowercase().as_str() {
        "l" => Ok(septa::extract::Decompose::L),
        "h" => Ok(septa::extract::Decompose::H),
        _ => Err(ParameterError::new_err(format!(
            "decompose = {decompose:?}: use \"l\" or \"h\""
        ))),
    }
}

/// The affine of a volume with `spacing` (mm) and its first voxel's centre
/// at `origin` (LPS mm), axes along L, P, S.
#[pyfunction]
fn spacing_affine_lps(spacing: [f64; 3], origin: [f64; 3]) -> PyResult<[[f64; 4]; 3]> {
    let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    Ok(Geometry::new(spacing, origin, identity)
        .map_err(to_py)?
        .affine())
}

#[pymodule]
fn _septa(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("SeptaError", py.get_type::<SeptaError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    m.add("ParameterError", py.get_type::<ParameterError>())?;
    m.add("InvariantError", py.get_type::<InvariantError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<Extraction>()?;
    m.add_class::<Hyper>()?;
    m.add_function(wrap_pyfunction!(check_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(iso, m)?)?;
    m.add_function(wrap_pyfunction!(hyper, m)?)?;
    m.add_function(wrap_pyfunction!(read_volume, m)?)?;
    m.add_function(wrap_pyfunction!(extract, m)?)?;
    m.add_function(wrap_pyfunction!(config_json_to_toml, m)?)?;
    m.add_function(wrap_pyfunction!(read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(check, m)?)?;
    m.add_function(wrap_pyfunction!(spacing_affine_lps, m)?)?;
    Ok(())
}
