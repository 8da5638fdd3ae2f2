"""What a sphere is made of, from one photograph (Dror, Adelson & Willsky 2001): the
features of a sphere's photograph and its classification, on the Rust core of
`reflectance`, with the command line's numbers and messages."""

import os
from typing import Any, Optional, Union

import numpy as np
import numpy.typing as npt

__version__: str

Image = Union[str, os.PathLike[str], npt.NDArray[np.float64], npt.NDArray[np.float32]]
"""A file (PNG, JPEG, TIFF, PNM, Radiance HDR, PFM, OpenEXR; integer samples read as sRGB)
or a 2-D array of linear luminance (rows: y, downwards)."""

Mask = Union[str, os.PathLike[str], npt.NDArray[np.bool_], npt.NDArray[np.float64], npt.NDArray[np.float32]]
"""A mask of the sphere, the image's size: a file (alpha, or luminance >= 0.5), or an
array (True, or >= 0.5). A circle is fitted to its edge."""

Normals = Union[str, os.PathLike[str], npt.NDArray[np.float32], npt.NDArray[np.float64]]
"""An object's camera-space unit normals, the image's size: a file (PNG with n = 2v/max - 1
and a black or transparent background, or OpenEXR with float R, G, B = X, Y, Z), or an
H x W x 3 float array (+X right, +Y up, +Z toward the camera; the zero vector is
background)."""

class ReflectanceError(ValueError):
    """An input the pipeline refuses: a file that does not decode, a circle outside the
    image, a sphere that cannot be found, an invalid model file."""

def features(
    image: Image,
    *,
    cx: Optional[float] = None,
    cy: Optional[float] = None,
    r: Optional[float] = None,
    white: Optional[float] = None,
    mask: Optional[Mask] = None,
    log: bool = False,
) -> dict[str, float]:
    """The 117 named features (234 with `log`), in the canonical order, as
    `reflectance features IMAGE` (`--log-features`) computes them. Give the circle
    (`cx`, `cy`, `r` in pixels, pixel centres at integers) or a `mask`, or neither to find
    the sphere; `white` is the linear luminance of a white surface at the sphere (none:
    the image is taken as normalized already)."""

def unwrap(
    image: Image,
    *,
    cx: Optional[float] = None,
    cy: Optional[float] = None,
    r: Optional[float] = None,
    white: Optional[float] = None,
    mask: Optional[Mask] = None,
) -> npt.NDArray[np.float64]:
    """The white-normalized annulus the features read: 96 x 448 (rows: radius from 0.2 r
    to 0.9 r, columns: angle)."""

class Model:
    """A trained model, loaded and verified once, for many classifications; safe to share
    between threads."""

    def __init__(self, path: Union[str, os.PathLike[str]]) -> None:
        """A model version's folder, or a model's folder (its active version), e.g.
        `models/ward6`."""
    @property
    def name(self) -> str: ...
    @property
    def version(self) -> int: ...
    @property
    def classes(self) -> list[str]: ...
    def classify(
        self,
        image: Image,
        *,
        cx: Optional[float] = None,
        cy: Optional[float] = None,
        r: Optional[float] = None,
        white: Optional[float] = None,
        coverage: Optional[float] = None,
        mask: Optional[Mask] = None,
        normals: Optional[Normals] = None,
    ) -> dict[str, Any]:
        """`classify` with this model."""

def classify(
    image: Image,
    *,
    model: Union[Model, str, os.PathLike[str]],
    cx: Optional[float] = None,
    cy: Optional[float] = None,
    r: Optional[float] = None,
    white: Optional[float] = None,
    coverage: Optional[float] = None,
    mask: Optional[Mask] = None,
    normals: Optional[Normals] = None,
) -> dict[str, Any]:
    """The service's JSON answer (`POST /v1/classify`, `reflectance classify --json`) as
    Python objects: `label`, `probabilities`, `prediction_set` (at `coverage`, default
    0.95), `domain`, `geometry`, `white`, `ward`, `warnings`, `timing_ms`. The sphere is the
    circle, a `mask`, or found; an object of any shape is given by its `normals` (with
    `mask` naming its pixels), read as its equivalent sphere (`observed_fraction`,
    `normal_scatter_deg`, `not_convex_fraction`, `shadowed_fraction` in the answer)."""
