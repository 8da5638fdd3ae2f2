//! The one validated input of a classification: what the command line, the service and
//! Python all build, through its constructors.

use super::Answer;
use crate::analysis::{InputError, Placement, WhiteSpec};
use crate::decode::Encoding;
use bytes::Bytes;

/// A validated classification request: [`Input::new`] is the only way to make one.
#[derive(Debug)]
pub struct Input {
    pub(super) image: Bytes,
    pub(super) white: WhiteSpec<Bytes>,
    pub(super) locate: Placement<Bytes, Bytes>,
    pub(super) encoding: Option<Encoding>,
    pub(super) answer: Answer,
}

impl Input {
    /// A request of an encoded photograph: not empty, with a prediction-set coverage (when
    /// given) in [0.5, 0.999].
    ///
    /// The request's rules are checked here, before any decoding: its parts are built by
    /// [`WhiteSpec::new`] and [`Placement::new`], which hold their own rules.
    ///
    /// ```
    /// use bytes::Bytes;
    /// use reflectance_core::analysis::{InputError, Placement, WhiteSpec};
    /// use reflectance_core::inference::{Answer, Input};
    ///
    /// let photo = Bytes::from_static(b"the bytes of a PNG, JPEG, HDR, PFM, EXR or TIFF");
    /// // White measured beside the sphere: a number, and the circle given.
    /// let white = WhiteSpec::new(Some(0.8), None, None, None)?;
    /// let locate = Placement::new(Some(120.0), Some(110.0), Some(90.0), None)?;
    /// let answer = Answer { coverage: Some(0.9), ..Answer::default() };
    /// let input = Input::new(photo, white, locate, None, answer)?;
    /// # drop(input);
    ///
    /// // The rules: an image, a coverage the prediction sets offer, one white, …
    /// let empty = Input::new(Bytes::new(), WhiteSpec::Missing, Placement::Auto, None, answer);
    /// assert_eq!(empty.unwrap_err(), InputError::EmptyImage);
    /// let loose = Answer { coverage: Some(0.3), ..Answer::default() };
    /// let photo = Bytes::from_static(b"...");
    /// let refused = Input::new(photo, WhiteSpec::Missing, Placement::Auto, None, loose);
    /// assert_eq!(refused.unwrap_err(), InputError::Coverage(0.3));
    /// let two = WhiteSpec::<Bytes>::new(Some(0.8), None, Some("10,10,20,20".parse()?), None);
    /// assert_eq!(two.unwrap_err(), InputError::SeveralWhites);
    /// let partial = Placement::<Bytes, Bytes>::new(Some(120.0), None, Some(90.0), None);
    /// assert!(matches!(partial, Err(InputError::Geometry(_))));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(
        image: Bytes,
        white: WhiteSpec<Bytes>,
        locate: Placement<Bytes, Bytes>,
        encoding: Option<Encoding>,
        answer: Answer,
    ) -> Result<Input, InputError> {
        if image.is_empty() {
            return Err(InputError::EmptyImage);
        }
        answer.checked()?;
        Ok(Input {
            image,
            white,
            locate,
            encoding,
            answer,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_input_has_an_image_and_a_coverage_the_sets_offer() {
        let input = |image: &'static [u8], coverage| {
            let answer = Answer {
                coverage,
                ..Answer::default()
            };
            let image = Bytes::from_static(image);
            Input::new(image, WhiteSpec::Missing, Placement::Auto, None, answer)
        };
        assert!(input(b"png", Some(0.9)).is_ok());
        assert!(input(b"png", None).is_ok());
        assert_eq!(input(b"", None).unwrap_err(), InputError::EmptyImage);
        for bad in [0.4, 1.0, f64::NAN] {
            assert!(matches!(
                input(b"png", Some(bad)),
                Err(InputError::Coverage(_))
            ));
        }
    }
}
