//! What a caller says about a photograph before it is measured: where the sphere is
//! ([`Placement`]) and how bright white is ([`WhiteSpec`]), each one type with its rules in
//! its constructor. A request holds them encoded (`Placement<Bytes, Bytes>`,
//! `WhiteSpec<Bytes>`: a mask, normals or a card as file bytes); [`Placement::decode`] and
//! [`WhiteSpec::decode`] turn them into the decoded forms (the defaults) that
//! [`super::analyze`] reads. The command line, the service, dataset rows and Python all
//! build them here.

use crate::decode::{self, DecodeError, DecodeOptions, Encoding, LinearImage};
use crate::image::circle::Circle;
use crate::locate::{self, GeometryError};
use crate::object::normals::{NormalMap, NormalsError};
use crate::white::{self, Rect, WhiteError};
use ndarray::Array2;

/// Where the sphere is: a circle, a mask (`M`: bytes of a file, or decoded), or found in the
/// image; or an object of any shape by its normals (`N`).
#[derive(Clone, Debug)]
pub enum Placement<M = Array2<bool>, N = NormalMap> {
    /// A circle given in the image's pixels.
    Circle(Circle),
    /// A mask image of the sphere (its alpha, else luminance ≥ 0.5); the circle is fitted to
    /// its edge.
    Mask(M),
    /// The image's alpha channel if it has one, else automatic detection.
    Auto,
    /// An object of any shape, read as its equivalent sphere (docs/design.md §9): its normal
    /// map (the image's size), and a mask of its pixels when the normals alone do not say.
    Normals {
        /// The object's normals.
        normals: N,
        /// The object's pixels (alpha, else luminance ≥ 0.5).
        mask: Option<M>,
    },
}

impl<M, N> Placement<M, N> {
    /// The placement of a request: `cx`, `cy` and `r` all or none (checked as far as they can
    /// be without the image), or a mask, not both.
    pub fn new(
        cx: Option<f64>,
        cy: Option<f64>,
        r: Option<f64>,
        mask: Option<M>,
    ) -> Result<Self, InputError> {
        Ok(match (locate::given(cx, cy, r)?, mask) {
            (Some(_), Some(_)) => return Err(InputError::CircleAndMask),
            (Some(given), None) => Placement::Circle(given.circle()),
            (None, Some(mask)) => Placement::Mask(mask),
            (None, None) => Placement::Auto,
        })
    }

    /// With an object's normals, the placement of an object of any shape: a mask given
    /// becomes the object's mask; a circle cannot go with normals.
    pub fn with_normals(self, normals: Option<N>) -> Result<Self, InputError> {
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

    /// The same placement with its mask and normals turned into other forms (decoded, say).
    pub fn try_map<M2, N2, E>(
        self,
        mut mask: impl FnMut(M) -> Result<M2, E>,
        normals: impl FnOnce(N) -> Result<N2, E>,
    ) -> Result<Placement<M2, N2>, E> {
        Ok(match self {
            Placement::Circle(circle) => Placement::Circle(circle),
            Placement::Mask(m) => Placement::Mask(mask(m)?),
            Placement::Auto => Placement::Auto,
            Placement::Normals {
                normals: n,
                mask: m,
            } => Placement::Normals {
                normals: normals(n)?,
                mask: m.map(mask).transpose()?,
            },
        })
    }
}

impl<M: AsRef<[u8]>, N: AsRef<[u8]>> Placement<M, N> {
    /// The placement with its files decoded: a mask as coverage ([`decode_mask`]), normals
    /// as a checked normal map.
    pub fn decode(self, options: &DecodeOptions) -> Result<Placement, PartError> {
        self.try_map(
            |m| decode_mask(m.as_ref(), options).map_err(PartError::Mask),
            |n| NormalMap::decode(n.as_ref(), &options.limits).map_err(PartError::Normals),
        )
    }
}

/// How white is given: a number, a white card (`C`: its photograph's bytes, or decoded), a
/// card inside the photograph, or nothing.
#[derive(Clone, Debug)]
pub enum WhiteSpec<C = LinearImage> {
    /// A number: the linear luminance of white at the sphere (finite, > 0).
    Value(f64),
    /// A separate photograph of a white card, decoded like the image.
    Card {
        /// The card's photograph.
        image: C,
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
    /// No white reference: the image is taken as normalized (white = 1), with a warning.
    Missing,
}

impl<C> WhiteSpec<C> {
    /// A white reference given as a number: finite and positive.
    pub fn value(value: f64) -> Result<Self, WhiteError> {
        white::given(value).map(|_| WhiteSpec::Value(value))
    }

    /// The white reference of a request: at most one of a value, a card's crop and a card
    /// inside the photograph; the card's reflectance (in (0, 1], default 1) only with a card.
    pub fn new(
        value: Option<f64>,
        card: Option<C>,
        rect: Option<Rect>,
        reflectance: Option<f64>,
    ) -> Result<Self, InputError> {
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
            (_, Some(image), _) => WhiteSpec::Card { image, reflectance },
            (_, _, Some(rect)) => WhiteSpec::Rect { rect, reflectance },
            (None, None, None) => WhiteSpec::Missing,
        })
    }

    /// A white card, beside the sphere or in a photograph of its own: what a colour is read
    /// against.
    pub fn is_card(&self) -> bool {
        matches!(self, WhiteSpec::Card { .. } | WhiteSpec::Rect { .. })
    }

    /// The same reference with its card's photograph in another form (decoded, say).
    pub fn try_map<C2, E>(self, card: impl FnOnce(C) -> Result<C2, E>) -> Result<WhiteSpec<C2>, E> {
        Ok(match self {
            WhiteSpec::Value(v) => WhiteSpec::Value(v),
            WhiteSpec::Card { image, reflectance } => WhiteSpec::Card {
                image: card(image)?,
                reflectance,
            },
            WhiteSpec::Rect { rect, reflectance } => WhiteSpec::Rect { rect, reflectance },
            WhiteSpec::Missing => WhiteSpec::Missing,
        })
    }
}

impl<C: AsRef<[u8]>> WhiteSpec<C> {
    /// The reference with its card's photograph decoded like the image.
    pub fn decode(self, options: &DecodeOptions) -> Result<WhiteSpec, PartError> {
        self.try_map(|bytes| decode::decode(bytes.as_ref(), options).map_err(PartError::WhiteCard))
    }
}

/// A mask file: it holds coverage, not light, so its samples are read as stored.
pub fn decode_mask(bytes: &[u8], options: &DecodeOptions) -> Result<Array2<bool>, DecodeError> {
    let as_stored = DecodeOptions {
        encoding: Some(Encoding::Linear),
        colour: false,
        ..*options
    };
    Ok(mask_from_image(&decode::decode(bytes, &as_stored)?))
}

/// The mask of a decoded mask image.
pub fn mask_from_image(mask: &LinearImage) -> Array2<bool> {
    match &mask.alpha_mask {
        Some(alpha) => alpha.clone(),
        None => mask.luminance.mapv(|v| v >= 0.5),
    }
}

/// A file of the input besides the photograph that does not decode.
#[derive(Debug, thiserror::Error)]
pub enum PartError {
    /// The mask.
    #[error(transparent)]
    Mask(DecodeError),
    /// The object's normal map.
    #[error("normals: {0}")]
    Normals(NormalsError),
    /// The white card's photograph.
    #[error(transparent)]
    WhiteCard(DecodeError),
}

/// An input that breaks a rule of the request itself (before any decoding).
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

#[cfg(test)]
mod tests {
    use super::*;
    use bytes::Bytes;

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
            WhiteSpec::<Bytes>::new(Some(0.5), None, None, None),
            Ok(WhiteSpec::Value(v)) if v == 0.5
        ));
        assert!(matches!(
            WhiteSpec::<Bytes>::new(None, card(), None, Some(0.9)),
            Ok(WhiteSpec::Card { reflectance, .. }) if reflectance == 0.9
        ));
        assert!(matches!(
            WhiteSpec::<Bytes>::new(None, None, Some(rect()), None),
            Ok(WhiteSpec::Rect { reflectance, .. }) if reflectance == 1.0
        ));
        assert!(matches!(
            WhiteSpec::<Bytes>::new(None, None, None, None),
            Ok(WhiteSpec::Missing)
        ));
        assert_eq!(
            WhiteSpec::<Bytes>::new(Some(0.5), None, Some(rect()), None).unwrap_err(),
            InputError::SeveralWhites
        );
        assert_eq!(
            WhiteSpec::<Bytes>::new(Some(0.5), None, None, Some(0.9)).unwrap_err(),
            InputError::ReflectanceWithoutCard
        );
        assert_eq!(
            WhiteSpec::<Bytes>::new(None, None, None, Some(0.9)).unwrap_err(),
            InputError::ReflectanceWithoutCard
        );
        assert_eq!(
            WhiteSpec::<Bytes>::new(None, card(), None, Some(1.5)).unwrap_err(),
            InputError::White(WhiteError::BadReflectance(1.5))
        );
        assert!(matches!(
            WhiteSpec::<Bytes>::new(Some(-1.0), None, None, None),
            Err(InputError::White(_))
        ));
    }

    #[test]
    fn the_sphere_is_a_circle_or_a_mask_not_both() {
        let circle = Placement::<(), ()>::new(Some(50.0), Some(50.0), Some(40.0), None);
        assert!(matches!(circle, Ok(Placement::Circle(c)) if c.r == 40.0));
        assert!(matches!(
            Placement::<(), ()>::new(None, None, None, Some(())),
            Ok(Placement::Mask(()))
        ));
        assert!(matches!(
            Placement::<(), ()>::new(None, None, None, None),
            Ok(Placement::Auto)
        ));
        assert_eq!(
            Placement::<(), ()>::new(Some(50.0), Some(50.0), Some(40.0), Some(())).unwrap_err(),
            InputError::CircleAndMask
        );
        assert_eq!(
            Placement::<(), ()>::new(Some(50.0), None, Some(40.0), None).unwrap_err(),
            InputError::Geometry(GeometryError::Incomplete)
        );
    }

    #[test]
    fn normals_take_the_mask_as_the_objects_and_refuse_a_circle() {
        let auto = Placement::<Bytes, Bytes>::new(None, None, None, None).unwrap();
        let n = Bytes::from_static(b"normals");
        assert!(matches!(
            auto.with_normals(Some(n.clone())),
            Ok(Placement::Normals { mask: None, .. })
        ));
        let masked =
            Placement::<Bytes, Bytes>::new(None, None, None, Some(Bytes::from_static(b"m")))
                .unwrap();
        assert!(matches!(
            masked.with_normals(Some(n.clone())),
            Ok(Placement::Normals { mask: Some(_), .. })
        ));
        let circle =
            Placement::<Bytes, Bytes>::new(Some(100.0), Some(100.0), Some(50.0), None).unwrap();
        assert_eq!(
            circle.with_normals(Some(n)).unwrap_err(),
            InputError::CircleAndNormals
        );
        let circle =
            Placement::<Bytes, Bytes>::new(Some(100.0), Some(100.0), Some(50.0), None).unwrap();
        assert!(matches!(
            circle.with_normals(None),
            Ok(Placement::Circle(_))
        ));
    }
}
