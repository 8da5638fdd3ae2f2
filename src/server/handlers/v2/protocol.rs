//! The Open Inference Protocol apart from its transports: which tensors a model takes and
//! gives, the inputs as a classification request, and the answer as output tensors. The
//! REST handlers ([`super`]) and the gRPC service (`server::grpc`) both call these.

use super::tensor::{Datatype, Elements, Tensor};
use crate::server::error::{ApiError, Kind};
use crate::server::handlers::input::RawInput;
use base64::Engine;
use reflectance_core::estimate::Interval;
use reflectance_core::image::colour;
use reflectance_core::inference::{Classified, LoadedModel};
use reflectance_core::white::Method as WhiteMethod;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// A tensor's name, type and shape (−1: variable).
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct TensorMetadata {
    pub name: String,
    pub datatype: String,
    pub shape: Vec<i64>,
}

fn meta(name: &str, datatype: &str, shape: Vec<i64>) -> TensorMetadata {
    TensorMetadata {
        name: name.into(),
        datatype: datatype.into(),
        shape,
    }
}

/// BYTES inputs (the files, and the encoding's text).
const BYTES_INPUTS: [&str; 5] = ["image", "white_image", "mask", "normals", "encoding"];
/// Inputs of one number each.
const NUMBER_INPUTS: [&str; 6] = ["white", "white_reflectance", "cx", "cy", "r", "coverage"];

/// Every input a model takes; only `image` is required.
pub fn inputs() -> Vec<TensorMetadata> {
    let mut inputs: Vec<TensorMetadata> = BYTES_INPUTS
        .iter()
        .map(|n| meta(n, "BYTES", vec![1]))
        .collect();
    inputs.extend(NUMBER_INPUTS.iter().map(|n| meta(n, "FP64", vec![1])));
    inputs.push(meta("white_rect", "FP64", vec![4]));
    inputs
}

/// Every output of `model`, in the order an answer lists them.
pub fn outputs(model: &LoadedModel) -> Vec<TensorMetadata> {
    let k = model.file().classifier.classes().len() as i64;
    let mut outputs = vec![
        meta("label", "BYTES", vec![1]),
        meta("probabilities", "FP64", vec![k]),
        meta("classes", "BYTES", vec![k]),
        meta("prediction_set", "BYTES", vec![-1]),
        meta("in_domain", "BOOL", vec![1]),
    ];
    if model.file().estimator.is_some() {
        // `ward` only when a white reference is given.
        outputs.push(meta("ward", "FP64", vec![3, 3]));
        outputs.push(meta("specular_fraction", "FP64", vec![3]));
    }
    // Only against a white card in colour.
    outputs.push(meta("colour", "FP64", vec![3]));
    outputs
}

fn invalid(detail: String) -> ApiError {
    ApiError::new(Kind::InvalidField, detail)
}

/// The one element of an input that must hold one.
fn single<T>(name: &str, mut values: Vec<T>) -> Result<T, ApiError> {
    match values.len() {
        1 => Ok(values.remove(0)),
        n => Err(invalid(format!(
            "input {name:?} must hold exactly one element (shape [1]), not {n}"
        ))),
    }
}

/// A BYTES input's one element: raw bytes, or (from JSON) text, which for files is base64.
fn file_or_text(tensor: Tensor, base64: bool) -> Result<bytes::Bytes, ApiError> {
    let name = tensor.name;
    match tensor.elements {
        Elements::Bytes(v) => single(&name, v),
        Elements::Text(v) => {
            let text = single(&name, v)?;
            if !base64 {
                return Ok(text.into_bytes().into());
            }
            base64::engine::general_purpose::STANDARD
                .decode(text.trim())
                .map(Into::into)
                .map_err(|e| invalid(format!("input {name:?} is not base64: {e}")))
        }
        _ => Err(invalid(format!(
            "input {name:?} must be BYTES, not {}",
            tensor.datatype.name()
        ))),
    }
}

fn numbers(tensor: Tensor) -> Result<Vec<f64>, ApiError> {
    match tensor.elements {
        Elements::Numbers(v) if tensor.datatype.is_number() => Ok(v),
        _ => Err(invalid(format!(
            "input {:?} must be a number (FP64, FP32 or an integer type), not {}",
            tensor.name,
            tensor.datatype.name()
        ))),
    }
}

/// `white_rect` as four numbers (x, y, w, h) or as the text `x,y,w,h`.
fn rect_text(tensor: Tensor) -> Result<String, ApiError> {
    if tensor.datatype == Datatype::Bytes {
        let bytes = file_or_text(tensor, false)?;
        return String::from_utf8(bytes.to_vec())
            .map_err(|_| invalid("input \"white_rect\" is not UTF-8 text".into()));
    }
    let values = numbers(tensor)?;
    if values.len() != 4 {
        return Err(invalid(format!(
            "input \"white_rect\" must hold x, y, w and h (shape [4]), not {} elements",
            values.len()
        )));
    }
    Ok(values
        .iter()
        .map(f64::to_string)
        .collect::<Vec<_>>()
        .join(","))
}

/// The inputs as the fields of a classification request.
pub fn raw_input(tensors: Vec<Tensor>) -> Result<RawInput, ApiError> {
    let mut raw = RawInput::default();
    for tensor in tensors {
        let name = tensor.name.clone();
        let duplicate = || invalid(format!("input {name:?} is given more than once"));
        let replaced = match name.as_str() {
            "image" => raw.image.replace(file_or_text(tensor, true)?).is_some(),
            "white_image" => raw
                .white_image
                .replace(file_or_text(tensor, true)?)
                .is_some(),
            "mask" => raw.mask.replace(file_or_text(tensor, true)?).is_some(),
            "normals" => raw.normals.replace(file_or_text(tensor, true)?).is_some(),
            "encoding" => {
                let text = String::from_utf8(file_or_text(tensor, false)?.to_vec())
                    .map_err(|_| invalid("input \"encoding\" is not UTF-8 text".into()))?;
                raw.encoding.replace(text).is_some()
            }
            "white_rect" => raw.white_rect.replace(rect_text(tensor)?).is_some(),
            n if RawInput::NUMBERS.contains(&n) => {
                let value = single(&name, numbers(tensor)?)?.to_string();
                raw.number_mut(&name).replace(value).is_some()
            }
            other => {
                let known: Vec<String> = inputs().into_iter().map(|t| t.name).collect();
                return Err(ApiError::new(
                    Kind::UnknownField,
                    format!("unknown input {other:?} (expected {})", known.join(", ")),
                ));
            }
        };
        if replaced {
            return Err(duplicate());
        }
    }
    Ok(raw)
}

/// The most images one infer request may hold (the model metadata's `max_batch_size`),
/// when the server admits as many requests at once (`--max-inflight`).
pub const MAX_BATCH: usize = 32;

/// The most images one infer request may hold on a server admitting `max_inflight`.
pub fn max_batch(max_inflight: usize) -> usize {
    MAX_BATCH.min(max_inflight)
}

/// How many images a request's `image` input holds when it is a batch: shape [N] or
/// [N, 1] with N > 1. One image (whatever its shape) is answered as today's single image.
fn batch_size(tensors: &[Tensor]) -> Option<i64> {
    let image = tensors.iter().find(|t| t.name == "image")?;
    match image.shape.as_slice() {
        &[n] | &[n, 1] if n > 1 => Some(n),
        _ => None,
    }
}

/// A request's inputs, one [`RawInput`] per image, and whether they came as a batch. In a
/// batch every other input holds one value per image, or one value for all of them.
pub fn raw_inputs(tensors: Vec<Tensor>, max: usize) -> Result<(Vec<RawInput>, bool), ApiError> {
    let Some(n) = batch_size(&tensors) else {
        return Ok((vec![raw_input(tensors)?], false));
    };
    let n = usize::try_from(n)
        .ok()
        .filter(|n| (1..=max).contains(n))
        .ok_or_else(|| {
            invalid(format!(
                "a batch holds 1 to {max} images (the model metadata's max_batch_size), not {n}"
            ))
        })?;
    let mut items: Vec<Vec<Tensor>> = vec![Vec::with_capacity(tensors.len()); n];
    for tensor in tensors {
        let per = if tensor.name == "white_rect" && tensor.datatype != Datatype::Bytes {
            4
        } else {
            1
        };
        let count = tensor.elements.len();
        let start = |i: usize| match count {
            c if c == per => Some(0),
            c if c == per * n => Some(i * per),
            _ => None,
        };
        if start(0).is_none() {
            return Err(invalid(format!(
                "input {:?} holds {count} elements; in a batch of {n} images it holds {per} \
                 (for every image) or {} (one for each)",
                tensor.name,
                per * n
            )));
        }
        for (i, item) in items.iter_mut().enumerate() {
            let from = start(i).unwrap_or(0);
            item.push(Tensor {
                name: tensor.name.clone(),
                datatype: tensor.datatype,
                shape: vec![per as i64],
                elements: tensor.elements.range(from, per),
            });
        }
    }
    items
        .into_iter()
        .enumerate()
        .map(|(i, item)| raw_input(item).map_err(|e| e.in_batch(i, n)))
        .collect::<Result<_, _>>()
        .map(|inputs| (inputs, true))
}

/// A batch's answers as one answer: every output with the batch's dimension in front of one
/// image's shape. `prediction_set`s are padded with empty names to the longest; an output
/// some images lack (`ward` without their white, `colour`) holds NaN for them.
pub fn stack(model: &LoadedModel, answers: &[Vec<Tensor>]) -> Vec<Tensor> {
    let n = answers.len() as i64;
    let mut stacked = Vec::new();
    for meta in outputs(model) {
        let parts: Vec<Option<&Tensor>> = answers
            .iter()
            .map(|a| a.iter().find(|t| t.name == meta.name))
            .collect();
        let Some(first) = parts.iter().flatten().next() else {
            continue;
        };
        let width = parts.iter().flatten().map(|t| t.elements.len()).max();
        let width = width.unwrap_or(0);
        let mut shape = vec![n];
        if meta.name == "prediction_set" {
            shape.push(width as i64);
        } else {
            shape.extend(&first.shape);
        }
        let padded = |t: &Option<&Tensor>| -> Elements {
            let mut e = t.map_or_else(|| first.elements.range(0, 0), |t| t.elements.clone());
            match &mut e {
                Elements::Text(v) => v.resize(width, String::new()),
                Elements::Bytes(v) => v.resize(width, bytes::Bytes::new()),
                Elements::Numbers(v) => v.resize(width, f64::NAN),
                Elements::Bool(v) => v.resize(width, false),
            }
            e
        };
        let mut elements = padded(&parts[0]);
        for part in &parts[1..] {
            elements.append(padded(part));
        }
        stacked.push(Tensor {
            name: meta.name,
            datatype: first.datatype,
            shape,
            elements,
        });
    }
    stacked
}

/// The answer as output tensors, in the order of [`outputs`].
pub fn answer(c: &Classified) -> Vec<Tensor> {
    let classes = c.model.file().classifier.classes();
    let k = classes.len() as i64;
    let mut tensors = vec![
        Tensor::bytes("label", vec![classes[c.decision.class].clone()]),
        Tensor::fp64("probabilities", vec![k], c.decision.probabilities.clone()),
        Tensor::bytes("classes", classes.to_vec()),
    ];
    if let Some(set) = &c.decision.set {
        let names = set.iter().map(|&i| classes[i].clone()).collect();
        tensors.push(Tensor::bytes("prediction_set", names));
    }
    tensors.push(Tensor::bool("in_domain", c.decision.in_domain()));
    if let Some(w) = &c.ward {
        let rows = |intervals: &[Interval]| -> Vec<f64> {
            intervals
                .iter()
                .flat_map(|i| [i.value, i.low, i.high])
                .collect()
        };
        // Rows ρd, ρs, α; columns value, low, high. Only with a white reference: without
        // one the total reflectance is unknown.
        if c.analysis.white.method != WhiteMethod::None {
            tensors.push(Tensor::fp64(
                "ward",
                vec![3, 3],
                rows(&[w.rho_d, w.rho_s, w.alpha]),
            ));
        }
        // Value, low, high.
        tensors.push(Tensor::fp64(
            "specular_fraction",
            vec![3],
            rows(&[w.specular_fraction()]),
        ));
    }
    // Linear RGB relative to white, luminance 1.
    if let Some(rgb) = c.analysis.appearance.and_then(colour::surface_colour) {
        tensors.push(Tensor::fp64("colour", vec![3], rgb.to_vec()));
    }
    tensors
}

/// The outputs a request asked for, in its order (all when it names none). An output the
/// model has but this answer lacks (`ward` without a white reference) is left out.
pub fn select(
    model: &LoadedModel,
    answer: Vec<Tensor>,
    requested: &[String],
) -> Result<Vec<Tensor>, ApiError> {
    if requested.is_empty() {
        return Ok(answer);
    }
    let known = outputs(model);
    let mut selected = Vec::with_capacity(requested.len());
    for name in requested {
        if !known.iter().any(|t| &t.name == name) {
            let names: Vec<String> = known.into_iter().map(|t| t.name).collect();
            return Err(ApiError::new(
                Kind::UnknownField,
                format!("unknown output {name:?} (expected {})", names.join(", ")),
            ));
        }
        if selected.iter().any(|t: &Tensor| &t.name == name) {
            return Err(invalid(format!(
                "output {name:?} is requested more than once"
            )));
        }
        if let Some(t) = answer.iter().find(|t| &t.name == name) {
            selected.push(t.clone());
        }
    }
    Ok(selected)
}
