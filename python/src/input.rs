//! Images and masks as Python hands them over: a path (`str` or `os.PathLike`), or a 2-D
//! numpy array. Arrays are copied while the GIL is held, so that the computing can run
//! without it.

use crate::error;
use ndarray::Array2;
use numpy::{PyReadonlyArray2, PyReadonlyArray3, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use reflectance_core::analysis;
use reflectance_core::decode::{self, DecodeOptions, Encoding, LinearImage};
use reflectance_core::object::normals::NormalMap;
use std::path::PathBuf;

/// An image: a file to decode, or linear luminance.
pub enum ImageArg {
    Path(PathBuf),
    Luminance(Array2<f64>),
}

impl ImageArg {
    pub fn from_python(object: &Bound<'_, PyAny>) -> PyResult<ImageArg> {
        if let Ok(path) = object.extract::<PathBuf>() {
            return Ok(ImageArg::Path(path));
        }
        Ok(ImageArg::Luminance(float_array(object, "image")?))
    }

    /// Decoded as `reflectance features IMAGE` decodes it, or checked as a floating-point
    /// file is; an error names the file (as the command line does).
    pub fn decode(self) -> PyResult<LinearImage> {
        let options = DecodeOptions::default();
        match self {
            ImageArg::Path(path) => decode::decode_file(&path, &options)
                .map_err(|e| error(format!("{}: {e}", path.display()))),
            ImageArg::Luminance(luminance) => decode::from_luminance(luminance, &options.limits)
                .map_err(|e| error(format!("image: {e}"))),
        }
    }
}

/// A mask of the sphere: a file (alpha, or luminance ≥ 0.5) or an array (`True`, or ≥ 0.5).
pub enum MaskArg {
    Path(PathBuf),
    Mask(Array2<bool>),
}

impl MaskArg {
    pub fn from_python(object: &Bound<'_, PyAny>) -> PyResult<MaskArg> {
        if let Ok(path) = object.extract::<PathBuf>() {
            return Ok(MaskArg::Path(path));
        }
        if let Ok(mask) = object.extract::<PyReadonlyArray2<'_, bool>>() {
            return Ok(MaskArg::Mask(mask.as_array().to_owned()));
        }
        Ok(MaskArg::Mask(
            float_array(object, "mask")?.mapv(|v| v >= 0.5),
        ))
    }

    pub fn into_mask(self) -> PyResult<Array2<bool>> {
        match self {
            MaskArg::Mask(mask) => Ok(mask),
            MaskArg::Path(path) => {
                // A mask holds coverage, not light: its samples are read as stored.
                let options = DecodeOptions {
                    encoding: Some(Encoding::Linear),
                    ..DecodeOptions::default()
                };
                let image = decode::decode_file(&path, &options)
                    .map_err(|e| error(format!("{}: {e}", path.display())))?;
                Ok(analysis::mask_from_image(&image))
            }
        }
    }
}

/// An object's normal map: a file (PNG or OpenEXR) or an H×W×3 float array of camera-space
/// unit normals (+X right, +Y up, +Z toward the camera; the zero vector is background).
pub enum NormalsArg {
    Path(PathBuf),
    Vectors(Array2<[f32; 3]>),
}

impl NormalsArg {
    pub fn from_python(object: &Bound<'_, PyAny>) -> PyResult<NormalsArg> {
        if let Ok(path) = object.extract::<PathBuf>() {
            return Ok(NormalsArg::Path(path));
        }
        let vectors = |shape: &[usize], at: &dyn Fn(usize, usize, usize) -> f32| match shape {
            [h, w, 3] => Ok(Array2::from_shape_fn((*h, *w), |(r, c)| {
                [at(r, c, 0), at(r, c, 1), at(r, c, 2)]
            })),
            _ => Err(PyTypeError::new_err(format!(
                "normals must be an H×W×3 array, not one of shape {shape:?}"
            ))),
        };
        if let Ok(array) = object.extract::<PyReadonlyArray3<'_, f32>>() {
            let a = array.as_array();
            return Ok(NormalsArg::Vectors(vectors(a.shape(), &|r, c, k| {
                a[[r, c, k]]
            })?));
        }
        if let Ok(array) = object.extract::<PyReadonlyArray3<'_, f64>>() {
            let a = array.as_array();
            return Ok(NormalsArg::Vectors(vectors(a.shape(), &|r, c, k| {
                a[[r, c, k]] as f32
            })?));
        }
        Err(PyTypeError::new_err(format!(
            "normals must be a path or an H×W×3 numpy array of float32 or float64, not {}",
            object.get_type().name()?
        )))
    }

    pub fn into_map(self) -> PyResult<NormalMap> {
        match self {
            NormalsArg::Vectors(vectors) => {
                NormalMap::from_vectors(vectors).map_err(|e| error(format!("normals: {e}")))
            }
            NormalsArg::Path(path) => {
                let bytes = std::fs::read(&path)
                    .map_err(|e| error(format!("normals {}: {e}", path.display())))?;
                NormalMap::decode(&bytes, &DecodeOptions::default().limits)
                    .map_err(|e| error(format!("{}: {e}", path.display())))
            }
        }
    }
}

/// A 2-D array of float64 or float32, as float64; anything else is a `TypeError` that says
/// what was given.
fn float_array(object: &Bound<'_, PyAny>, what: &str) -> PyResult<Array2<f64>> {
    if let Ok(array) = object.extract::<PyReadonlyArray2<'_, f64>>() {
        return Ok(array.as_array().to_owned());
    }
    if let Ok(array) = object.extract::<PyReadonlyArray2<'_, f32>>() {
        return Ok(array.as_array().mapv(f64::from));
    }
    let given = match object.cast::<PyUntypedArray>() {
        Ok(array) => format!(
            "a {}-D array of {}",
            array.ndim(),
            array
                .dtype()
                .str()
                .map_or_else(|_| "?".to_string(), |s| s.to_string())
        ),
        Err(_) => format!("{}", object.get_type().name()?),
    };
    Err(PyTypeError::new_err(format!(
        "{what} must be a path or a 2-D numpy array of float64 or float32 (linear luminance), \
         not {given}"
    )))
}
