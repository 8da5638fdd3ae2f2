//! The log-domain features (`log.*`, docs/design.md §8): the whole block again, on the log10
//! of the white-normalized annulus floored at [`LOG_PIXEL_FLOOR`].

use super::{Family, Kind};
use crate::features::LOG_PIXEL_FLOOR;
use ndarray::Array2;

/// Prefix of the log-domain features' names.
pub const LOG_PREFIX: &str = "log.";

/// The log-domain family.
pub const LOG: Family = Family {
    option: "log_features",
    help: "Also compute the log-domain features (`log.*`, 117 more; implied by feature sets that\n\
           name them, such as hand6+log).",
    key: "log_domain",
    recorded_when_off: true,
    prefix: LOG_PREFIX,
    addition: None,
    kind: Kind::Block(log_pixels),
};

/// log10 of the floored unwrapped values: the image of the log-domain features.
pub(crate) fn log_pixels(unwrapped: &Array2<f64>) -> Array2<f64> {
    let values = unwrapped.as_standard_layout();
    let logs = crate::features::log10::log10_floored(
        values.as_slice().expect("standard layout"),
        LOG_PIXEL_FLOOR,
    );
    Array2::from_shape_vec(unwrapped.raw_dim(), logs).expect("same number of values")
}
