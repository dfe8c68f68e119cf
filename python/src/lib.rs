//! `septa._septa`: the Rust side of the Python package. Thin: it converts
//! numpy arrays and Python values to septa's types, calls
//! [`septa::pipeline::run`] with the GIL released, and hands the result back
//! as arrays; the Python side (`septa/__init__.py`) builds the user-facing
//! objects on top.

use std::path::PathBuf;

use numpy::{IntoPyArray, PyArray1, PyArrayMethods, PyReadonlyArray3};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;

use septa::config::{Config, RemeshOptions};
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
    #[pyo3(signature = (directory, force=false, obj=false, stl=false, space="lps"))]
    fn save(
        &self,
        py: Python<'_>,
        directory: PathBuf,
        force: bool,
        obj: bool,
        stl: bool,
        space: &str,
    ) -> PyResult<Vec<String>> {
        let space = parse_space(space)?;
        let formats = septa::output::Formats {
            obj,
            stl,
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
    labels, affine_lps, config_toml=None, config_path=None, remesh=None, target_edge=None,
    min_edge=None, smooth_iterations=None, max_displacement=None, iterations=None,
    surface="vesta", decompose="l", intersections=false, max_memory=None, source_file=None,
    progress=None,
))]
#[allow(clippy::too_many_arguments)] // one keyword argument per option
fn extract(
    py: Python<'_>,
    labels: PyReadonlyArray3<'_, i64>,
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
    let decompose = match decompose.to_ascii_lowercase().as_str() {
        "l" => septa::extract::Decompose::L,
        "h" => septa::extract::Decompose::H,
        _ => {
            return Err(ParameterError::new_err(format!(
                "decompose = {decompose:?}: use \"l\" or \"h\""
            )));
        }
    };
    let view = labels.as_array();
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
        max_memory,
        source_file,
    };
    let result = py.allow_threads(|| -> septa::Result<PipelineResult> {
        let geometry = Geometry::from_affine(affine_lps)?;
        let volume = LabelVolume::from_values(dims, &values, geometry)?;
        let config = config(config_toml, config_path)?;
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
    m.add_function(wrap_pyfunction!(read_volume, m)?)?;
    m.add_function(wrap_pyfunction!(extract, m)?)?;
    m.add_function(wrap_pyfunction!(config_json_to_toml, m)?)?;
    m.add_function(wrap_pyfunction!(read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(check, m)?)?;
    m.add_function(wrap_pyfunction!(spacing_affine_lps, m)?)?;
    Ok(())
}
