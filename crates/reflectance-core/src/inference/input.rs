//! The one validated input of a classification: what the command line, the service and
//! Python all build, through its constructors.

use super::Answer;
use crate::decode::Encoding;
use crate::locate::{self, GeometryError};
use crate::white::{Rect, WhiteError};
use bytes::Bytes;

/// How white is given, before decoding.
#[derive(Debug)]
pub enum WhiteSpec {
    /// A number: the linear luminance of white at the sphere (finite, > 0).
    Value(f64),
    /// A separate photograph of a white card (its encoded bytes).
    Card {
        /// The card's encoded photograph, decoded like the image.
        bytes: Bytes,
        /// The card's reflectance, in (0, 1].
        reflectance: f64,
    },
    /// A white card inside the photograph.
    Rect {
        /// The card's rectangle, in the photograph's pixels.
        rect: Rect,
        /// The card's reflectance, in (0, 1].
        reflectance: f64,
    },
    /// No white reference: the image is taken as normalized (white = 1).
    Missing,
}

impl WhiteSpec {
    /// A white reference given as a number: finite and positive.
    pub fn value(value: f64) -> Result<WhiteSpec, WhiteError> {
        crate::white::given(value).map(|_| WhiteSpec::Value(value))
    }

    /// The white reference of a request: at most one of a value, a card's crop and a card
    /// inside the photograph; the card's reflectance (in (0, 1], default 1) only with a card.
    pub fn new(
        value: Option<f64>,
        card: Option<Bytes>,
        rect: Option<Rect>,
        reflectance: Option<f64>,
    ) -> Result<WhiteSpec, InputError> {
        let given = [value.is_some(), card.is_some(), rect.is_some()];
        if given.iter().filter(|&&g| g).count() > 1 {
            return Err(InputError::SeveralWhites);
        }
        if reflectance.is_some() && !(given[1] || given[2]) {
            return Err(InputError::ReflectanceWithoutCard);
        }
        let reflectance = reflectance.unwrap_or(1.0);
        if !(reflectance > 0.0 && reflectance <= 1.0) {
            return Err(WhiteError::BadReflectance(reflectance).into());
        }
        Ok(match (value, card, rect) {
            (Some(value), _, _) => WhiteSpec::value(value)?,
            (_, Some(bytes), _) => WhiteSpec::Card { bytes, reflectance },
            (_, _, Some(rect)) => WhiteSpec::Rect { rect, reflectance },
            (None, None, None) => WhiteSpec::Missing,
        })
    }
}

/// Where the sphere is, before decoding: a circle, a mask (`M`: the mask as the caller
/// holds it, bytes of a file or an array), or found in the image.
#[derive(Debug)]
pub enum Placement<M> {
    /// A circle given in the image's pixels.
    Circle(locate::Circle),
    /// A mask image of the sphere (its alpha, else luminance ≥ 0.5); the circle is fitted to
    /// its edge.
    Mask(M),
    /// Found by detection (or the image's alpha channel).
    Auto,
    /// An object of any shape, read as its equivalent sphere: its normal map (PNG or
    /// OpenEXR), and a mask of its pixels when the normals alone do not say.
    Normals {
        /// The normal map, the image's size.
        normals: M,
        /// The object's pixels (alpha, else luminance ≥ 0.5).
        mask: Option<M>,
    },
}

impl<M> Placement<M> {
    /// The placement of a request: `cx`, `cy` and `r` all or none (checked as far as they can
    /// be without the image), or a mask, not both.
    pub fn new(
        cx: Option<f64>,
        cy: Option<f64>,
        r: Option<f64>,
        mask: Option<M>,
    ) -> Result<Placement<M>, InputError> {
        Ok(match (locate::given(cx, cy, r)?, mask) {
            (Some(_), Some(_)) => return Err(InputError::CircleAndMask),
            (Some(given), None) => Placement::Circle(given.circle()),
            (None, Some(mask)) => Placement::Mask(mask),
            (None, None) => Placement::Auto,
        })
    }

    /// With an object's normals, the placement of an object of any shape: a mask given
    /// becomes the object's mask; a circle cannot go with normals.
    pub fn with_normals(self, normals: Option<M>) -> Result<Placement<M>, InputError> {
        let Some(normals) = normals else {
            return Ok(self);
        };
        match self {
            Placement::Circle(_) => Err(InputError::CircleAndNormals),
            Placement::Mask(mask) => Ok(Placement::Normals {
                normals,
                mask: Some(mask),
            }),
            Placement::Auto => Ok(Placement::Normals {
                normals,
                mask: None,
            }),
            normals @ Placement::Normals { .. } => Ok(normals),
        }
    }
}

/// Where the sphere is in an encoded photograph.
pub type LocateSpec = Placement<Bytes>;

/// A request's input that breaks a rule of the request itself (before any decoding).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum InputError {
    /// The image has no bytes.
    #[error("the image is empty")]
    EmptyImage,
    /// More than one white reference was given.
    #[error("give one of white, white_image and white_rect")]
    SeveralWhites,
    /// A card's reflectance without a card.
    #[error("white_reflectance applies to white_image or white_rect only")]
    ReflectanceWithoutCard,
    /// The white reference breaks its own rule (not positive, reflectance outside (0, 1]).
    #[error(transparent)]
    White(#[from] WhiteError),
    /// The circle is incomplete or not a circle (non-finite, r ≤ 0).
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// Both a circle and a mask were given.
    #[error("give cx, cy and r, or a mask, not both")]
    CircleAndMask,
    /// A circle and normals were both given.
    #[error("give cx, cy and r for a sphere, or normals for an object of any shape, not both")]
    CircleAndNormals,
    /// A prediction-set coverage outside [0.5, 0.999].
    #[error("coverage must be a number from 0.5 to 0.999, not {0}")]
    Coverage(f64),
}

/// A validated classification request: [`Input::new`] is the only way to make one.
#[derive(Debug)]
pub struct Input {
    pub(super) image: Bytes,
    pub(super) white: WhiteSpec,
    pub(super) locate: LocateSpec,
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
    /// use reflectance_core::inference::{Answer, Input, InputError, LocateSpec, WhiteSpec};
    ///
    /// let photo = Bytes::from_static(b"the bytes of a PNG, JPEG, HDR, PFM, EXR or TIFF");
    /// // White measured beside the sphere: a number, and the circle given.
    /// let white = WhiteSpec::new(Some(0.8), None, None, None)?;
    /// let locate = LocateSpec::new(Some(120.0), Some(110.0), Some(90.0), None)?;
    /// let answer = Answer { coverage: Some(0.9), ..Answer::default() };
    /// let input = Input::new(photo, white, locate, None, answer)?;
    /// # drop(input);
    ///
    /// // The rules: an image, a coverage the prediction sets offer, one white, …
    /// let empty = Input::new(Bytes::new(), WhiteSpec::Missing, LocateSpec::Auto, None, answer);
    /// assert_eq!(empty.unwrap_err(), InputError::EmptyImage);
    /// let loose = Answer { coverage: Some(0.3), ..Answer::default() };
    /// let photo = Bytes::from_static(b"...");
    /// let refused = Input::new(photo, WhiteSpec::Missing, LocateSpec::Auto, None, loose);
    /// assert_eq!(refused.unwrap_err(), InputError::Coverage(0.3));
    /// let two = WhiteSpec::new(Some(0.8), None, Some("10,10,20,20".parse()?), None);
    /// assert_eq!(two.unwrap_err(), InputError::SeveralWhites);
    /// let partial = LocateSpec::new(Some(120.0), None, Some(90.0), None);
    /// assert!(matches!(partial, Err(InputError::Geometry(_))));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(
        image: Bytes,
        white: WhiteSpec,
        locate: LocateSpec,
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

    fn rect() -> Rect {
        Rect {
            x: 0.0,
            y: 0.0,
            w: 8.0,
            h: 8.0,
        }
    }

    #[test]
    fn white_is_one_of_a_value_a_card_and_a_rectangle() {
        let card = || Some(Bytes::from_static(b"card"));
        assert!(matches!(
            WhiteSpec::new(Some(0.5), None, None, None),
            Ok(WhiteSpec::Value(v)) if v == 0.5
        ));
        assert!(matches!(
            WhiteSpec::new(None, card(), None, Some(0.9)),
            Ok(WhiteSpec::Card { reflectance, .. }) if reflectance == 0.9
        ));
        assert!(matches!(
            WhiteSpec::new(None, None, Some(rect()), None),
            Ok(WhiteSpec::Rect { reflectance, .. }) if reflectance == 1.0
        ));
        assert!(matches!(
            WhiteSpec::new(None, None, None, None),
            Ok(WhiteSpec::Missing)
        ));
        assert_eq!(
            WhiteSpec::new(Some(0.5), None, Some(rect()), None).unwrap_err(),
            InputError::SeveralWhites
        );
        assert_eq!(
            WhiteSpec::new(Some(0.5), None, None, Some(0.9)).unwrap_err(),
            InputError::ReflectanceWithoutCard
        );
        assert_eq!(
            WhiteSpec::new(None, None, None, Some(0.9)).unwrap_err(),
            InputError::ReflectanceWithoutCard
        );
        assert_eq!(
            WhiteSpec::new(None, card(), None, Some(1.5)).unwrap_err(),
            InputError::White(WhiteError::BadReflectance(1.5))
        );
        assert!(matches!(
            WhiteSpec::new(Some(-1.0), None, None, None),
            Err(InputError::White(_))
        ));
    }

    #[test]
    fn the_sphere_is_a_circle_or_a_mask_not_both() {
        let circle = Placement::<()>::new(Some(50.0), Some(50.0), Some(40.0), None);
        assert!(matches!(circle, Ok(Placement::Circle(c)) if c.r == 40.0));
        assert!(matches!(
            Placement::new(None, None, None, Some(())),
            Ok(Placement::Mask(()))
        ));
        assert!(matches!(
            Placement::<()>::new(None, None, None, None),
            Ok(Placement::Auto)
        ));
        assert_eq!(
            Placement::new(Some(50.0), Some(50.0), Some(40.0), Some(())).unwrap_err(),
            InputError::CircleAndMask
        );
        assert_eq!(
            Placement::<()>::new(Some(50.0), None, Some(40.0), None).unwrap_err(),
            InputError::Geometry(GeometryError::Incomplete)
        );
    }

    #[test]
    fn normals_take_the_mask_as_the_objects_and_refuse_a_circle() {
        let auto = LocateSpec::new(None, None, None, None).unwrap();
        let n = Bytes::from_static(b"normals");
        assert!(matches!(
            auto.with_normals(Some(n.clone())),
            Ok(Placement::Normals { mask: None, .. })
        ));
        let masked = LocateSpec::new(None, None, None, Some(Bytes::from_static(b"m"))).unwrap();
        assert!(matches!(
            masked.with_normals(Some(n.clone())),
            Ok(Placement::Normals { mask: Some(_), .. })
        ));
        let circle = LocateSpec::new(Some(100.0), Some(100.0), Some(50.0), None).unwrap();
        assert_eq!(
            circle.with_normals(Some(n)).unwrap_err(),
            InputError::CircleAndNormals
        );
        let circle = LocateSpec::new(Some(100.0), Some(100.0), Some(50.0), None).unwrap();
        assert!(matches!(
            circle.with_normals(None),
            Ok(Placement::Circle(_))
        ));
    }

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
