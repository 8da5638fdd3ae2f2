//! OpenEXR through the `exr` crate: the first layer's R, G, B (or Y) and A channels.

use super::{DecodeError, DecodeOptions, FloatPlane, Format, Limits, luminance, validate_float};
use crate::image::colour::ColourCopy;
use exr::prelude::{ReadChannels, ReadLayers};
use ndarray::Array2;
use std::io::Cursor;

const FORMAT: Format = Format::Exr;

fn map_error(error: exr::error::Error) -> DecodeError {
    match error {
        exr::error::Error::NotSupported(detail) => DecodeError::Unsupported {
            format: FORMAT,
            detail: detail.to_string(),
        },
        other => DecodeError::corrupt(FORMAT, other),
    }
}

/// The first valid layer's channels (their names without a layer prefix), read as f32
/// once the header's sizes pass the limits.
pub(crate) struct Channels {
    pub width: usize,
    pub height: usize,
    list: Vec<(String, Vec<f32>)>,
}

impl Channels {
    /// The samples of channel `name` (`R`, `G`, `B`, `Y`, `A`), row-major.
    pub fn get(&self, name: &str) -> Option<&[f32]> {
        self.list
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, samples)| samples.as_slice())
    }
}

pub(crate) fn read_channels(bytes: &[u8], limits: &Limits) -> Result<Channels, DecodeError> {
    let meta =
        exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false).map_err(map_error)?;
    for header in &meta.headers {
        let size = header.layer_size;
        limits.check(size.width() as u64, size.height() as u64)?;
    }
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(map_error)?;
    let layer = image.layer_data;
    let list: Vec<(String, Vec<f32>)> = layer
        .channel_data
        .list
        .iter()
        .map(|c| {
            let name = c.name.to_string();
            let short = name.rsplit('.').next().unwrap_or_default().to_string();
            (short, c.sample_data.values_as_f32().collect())
        })
        .collect();
    let (width, height) = (layer.size.width(), layer.size.height());
    if list
        .iter()
        .any(|(_, samples): &(String, Vec<f32>)| samples.len() != width * height)
    {
        return Err(DecodeError::corrupt(
            FORMAT,
            "channel size does not match the layer",
        ));
    }
    Ok(Channels {
        width,
        height,
        list,
    })
}

pub(crate) fn decode(bytes: &[u8], options: &DecodeOptions) -> Result<FloatPlane, DecodeError> {
    let layer = read_channels(bytes, &options.limits)?;
    let (width, height) = (layer.width, layer.height);
    let channel = |name: &str| -> Option<Vec<f64>> {
        layer
            .get(name)
            .map(|c| c.iter().copied().map(f64::from).collect())
    };
    let mut colour = None;
    let values = match (channel("R"), channel("G"), channel("B"), channel("Y")) {
        (Some(r), Some(g), Some(b), _) => {
            let nonfinite = [&r, &g, &b]
                .iter()
                .flat_map(|c| c.iter())
                .filter(|v| !v.is_finite())
                .count();
            let lum = (0..r.len()).map(|i| luminance(r[i], g[i], b[i])).collect();
            let same_size = [&r, &g, &b].iter().all(|c| c.len() == width * height);
            if options.colour && same_size {
                colour = Some(ColourCopy::new(width, height, |i| [r[i], g[i], b[i]]));
            }
            (lum, nonfinite)
        }
        (_, _, _, Some(y)) => {
            let nonfinite = y.iter().filter(|v| !v.is_finite()).count();
            (y, nonfinite)
        }
        _ => {
            return Err(DecodeError::Unsupported {
                format: FORMAT,
                detail: "no R,G,B or Y channels in the first layer".into(),
            });
        }
    };
    let to_plane = |v: Vec<f64>| {
        Array2::from_shape_vec((height, width), v)
            .map_err(|_| DecodeError::corrupt(FORMAT, "channel size does not match the layer"))
    };
    let lum = to_plane(values.0)?;
    validate_float(&lum, values.1)?;
    let alpha = channel("A").map(to_plane).transpose()?;
    Ok(FloatPlane {
        luminance: lum,
        alpha,
        colour,
    })
}
