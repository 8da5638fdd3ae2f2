//! `reflectance` for Python: the features of a sphere's photograph and its classification,
//! on `reflectance-core`, with the command line's numbers and messages. Images are file
//! paths or 2-D numpy arrays of linear luminance; the GIL is released while computing.

mod input;

use input::{ImageArg, MaskArg, NormalsArg};
use numpy::{IntoPyArray, PyArray2};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use reflectance_core::analysis::{self, AnalysisError, Placement, WhiteSpec};
use reflectance_core::decode::LinearImage;
use reflectance_core::features::families;
use reflectance_core::features::{Extractor, Families, FeatureConfig, Preprocessing};
use reflectance_core::inference::{self, Answer, InferenceError, LoadedModel};
use reflectance_core::locate::GeometryError;
use reflectance_core::model::registry;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};
use std::time::Instant;

create_exception!(
    reflectance,
    ReflectanceError,
    PyValueError,
    "An input the pipeline refuses: a file that does not decode, a circle outside the image, \
     a sphere that cannot be found, an invalid model file. The message is the command line's."
);

fn error(message: impl std::fmt::Display) -> PyErr {
    ReflectanceError::new_err(message.to_string())
}

/// A failure to place the sphere asks for the arguments that place it.
fn analysis_error(e: &AnalysisError) -> PyErr {
    match e {
        AnalysisError::Geometry(GeometryError::DetectionFailed { .. }) => {
            error(format!("{e}; give cx, cy and r, or mask"))
        }
        other => error(other),
    }
}

fn inference_error(e: InferenceError) -> PyErr {
    match e {
        InferenceError::Analysis(e) => analysis_error(&e),
        other => error(other),
    }
}

/// Where the sphere is: the circle, a mask, or found in the image; or an object's normals
/// (with `mask`, the object's pixels).
fn placement(
    (cx, cy, r): (Option<f64>, Option<f64>, Option<f64>),
    mask: Option<MaskArg>,
    normals: Option<NormalsArg>,
) -> PyResult<Placement> {
    Placement::new(cx, cy, r, mask)
        .and_then(|p| p.with_normals(normals))
        .map_err(error)?
        .try_map(MaskArg::into_mask, NormalsArg::into_map)
}

fn white(value: Option<f64>) -> PyResult<WhiteSpec> {
    WhiteSpec::new(value, None, None, None).map_err(error)
}

/// A sphere's photograph as the arguments give it, checked before any decoding.
struct Sphere {
    image: ImageArg,
    how: Placement,
    white: WhiteSpec,
}

impl Sphere {
    fn new(
        image: &Bound<'_, PyAny>,
        (cx, cy, r): (Option<f64>, Option<f64>, Option<f64>),
        white: Option<f64>,
        mask: Option<&Bound<'_, PyAny>>,
        normals: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Sphere> {
        Ok(Sphere {
            image: ImageArg::from_python(image)?,
            how: placement(
                (cx, cy, r),
                mask.map(MaskArg::from_python).transpose()?,
                normals.map(NormalsArg::from_python).transpose()?,
            )?,
            white: self::white(white)?,
        })
    }

    /// `f` of the decoded image, where the sphere is and its white, without the GIL.
    fn decoded<T: Send>(
        self,
        py: Python<'_>,
        f: impl FnOnce(LinearImage, &Placement, &WhiteSpec) -> PyResult<T> + Send,
    ) -> PyResult<T> {
        py.detach(move || f(self.image.decode()?, &self.how, &self.white))
    }
}

/// The extractor of `reflectance features` (with `--log-features` for `log`), made once.
fn extractor(log: bool) -> &'static Extractor {
    static PLAIN: OnceLock<Extractor> = OnceLock::new();
    static LOG: OnceLock<Extractor> = OnceLock::new();
    let cell = if log { &LOG } else { &PLAIN };
    cell.get_or_init(|| {
        let families = match log {
            true => Families::NONE.with(&families::LOG),
            false => Families::NONE,
        };
        let config = FeatureConfig::for_spec(families, "", Preprocessing::default())
            .expect("the command line's default configuration");
        Extractor::new(config).expect("the command line's default configuration")
    })
}

/// The named features of a sphere, in the canonical order, as `reflectance features`
/// computes them.
#[pyfunction]
#[pyo3(signature = (image, *, cx=None, cy=None, r=None, white=None, mask=None, log=false))]
#[allow(clippy::too_many_arguments)]
fn features<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    cx: Option<f64>,
    cy: Option<f64>,
    r: Option<f64>,
    white: Option<f64>,
    mask: Option<&Bound<'py, PyAny>>,
    log: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let extractor = extractor(log);
    let sphere = Sphere::new(image, (cx, cy, r), white, mask, None)?;
    let values = sphere.decoded(py, |decoded, how, white| {
        let analysis =
            analysis::analyze(extractor, &decoded, how, white).map_err(|e| analysis_error(&e))?;
        Ok(analysis.values)
    })?;
    let out = PyDict::new(py);
    for (name, value) in extractor.config().names().into_iter().zip(values) {
        out.set_item(name, value)?;
    }
    Ok(out)
}

/// The white-normalized annulus the features read, 96 × 448 (rows: radius from 0.2 r to
/// 0.9 r, columns: angle), as a float64 array.
#[pyfunction]
#[pyo3(signature = (image, *, cx=None, cy=None, r=None, white=None, mask=None))]
#[allow(clippy::too_many_arguments)]
fn unwrap<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    cx: Option<f64>,
    cy: Option<f64>,
    r: Option<f64>,
    white: Option<f64>,
    mask: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let sphere = Sphere::new(image, (cx, cy, r), white, mask, None)?;
    let annulus = sphere.decoded(py, |decoded, how, white| {
        analysis::unwrapped(extractor(false), &decoded, how, white).map_err(|e| analysis_error(&e))
    })?;
    Ok(annulus.into_pyarray(py))
}

/// A trained model, loaded and verified once, for many classifications (thread-safe).
#[pyclass(frozen, module = "reflectance")]
struct Model {
    loaded: Arc<LoadedModel>,
}

#[pymethods]
impl Model {
    /// `path`: a model version's folder, or a model's folder (its active version), e.g.
    /// `models/ward6`.
    #[new]
    fn new(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
        let loaded = py.detach(|| -> PyResult<LoadedModel> {
            let file = registry::load_path(&path).map_err(error)?;
            LoadedModel::new(file).map_err(error)
        })?;
        Ok(Model {
            loaded: Arc::new(loaded),
        })
    }

    #[getter]
    fn name(&self) -> &str {
        self.loaded.name()
    }

    #[getter]
    fn version(&self) -> u32 {
        self.loaded.version()
    }

    /// The class names, in the model's order.
    #[getter]
    fn classes(&self) -> Vec<String> {
        self.loaded.file().classifier.classes().to_vec()
    }

    /// [`classify`] with this model.
    #[pyo3(signature = (image, *, cx=None, cy=None, r=None, white=None, coverage=None, mask=None, normals=None))]
    #[allow(clippy::too_many_arguments)]
    fn classify<'py>(
        &self,
        py: Python<'py>,
        image: &Bound<'py, PyAny>,
        cx: Option<f64>,
        cy: Option<f64>,
        r: Option<f64>,
        white: Option<f64>,
        coverage: Option<f64>,
        mask: Option<&Bound<'py, PyAny>>,
        normals: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let sphere = Sphere::new(image, (cx, cy, r), white, mask, normals)?;
        classify_with(py, &self.loaded, sphere, coverage)
    }

    fn __repr__(&self) -> String {
        format!(
            "Model(name={:?}, version={})",
            self.loaded.name(),
            self.loaded.version()
        )
    }
}

/// The service's JSON answer (`POST /v1/classify`, `reflectance classify --json`) for one
/// photograph, as Python objects. `model`: a [`Model`] or a model's path.
#[pyfunction]
#[pyo3(signature = (image, *, model, cx=None, cy=None, r=None, white=None, coverage=None, mask=None, normals=None))]
#[allow(clippy::too_many_arguments)]
fn classify<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    model: &Bound<'py, PyAny>,
    cx: Option<f64>,
    cy: Option<f64>,
    r: Option<f64>,
    white: Option<f64>,
    coverage: Option<f64>,
    mask: Option<&Bound<'py, PyAny>>,
    normals: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let loaded = match model.cast::<Model>() {
        Ok(model) => model.get().loaded.clone(),
        Err(_) => Model::new(py, model.extract::<PathBuf>()?)?.loaded,
    };
    let sphere = Sphere::new(image, (cx, cy, r), white, mask, normals)?;
    classify_with(py, &loaded, sphere, coverage)
}

fn classify_with<'py>(
    py: Python<'py>,
    model: &Arc<LoadedModel>,
    sphere: Sphere,
    coverage: Option<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let started = Instant::now();
    let answer = Answer {
        coverage,
        ..Answer::default()
    }
    .checked()
    .map_err(error)?;
    let model = model.clone();
    let decoding = Instant::now();
    let json = sphere.decoded(py, |decoded, how, white| {
        let decode_ms = decoding.elapsed().as_secs_f64() * 1e3;
        let classified =
            inference::classify_decoded(model, decoded, how, white, &answer, decode_ms)
                .map_err(inference_error)?;
        let response = classified.response(String::new(), started.elapsed().as_secs_f64() * 1e3);
        serde_json::to_string(&response).map_err(error)
    })?;
    py.import("json")?.call_method1("loads", (json,))
}

/// The extension module.
#[pymodule(name = "reflectance")]
fn reflectance_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(features, m)?)?;
    m.add_function(wrap_pyfunction!(unwrap, m)?)?;
    m.add_function(wrap_pyfunction!(classify, m)?)?;
    m.add_class::<Model>()?;
    m.add("ReflectanceError", m.py().get_type::<ReflectanceError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
