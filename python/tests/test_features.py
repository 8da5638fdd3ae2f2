"""`reflectance.features` and `reflectance.unwrap` against the command line, numpy input,
and the errors a researcher will meet."""

import numpy as np
import pytest

import reflectance
from conftest import CIRCLE, SPHERE, circle_flags, cli, cli_json, shaded_sphere, write_pfm


def test_features_equal_the_command_lines_bit_for_bit():
    ours = reflectance.features(SPHERE, **CIRCLE)
    theirs = cli_json("features", SPHERE, *circle_flags(**CIRCLE))
    assert list(ours) == theirs["names"]
    assert len(ours) == 117
    assert [v.hex() for v in ours.values()] == [v.hex() for v in theirs["values"]]


def test_log_features_and_detection_equal_the_command_lines():
    ours = reflectance.features(str(SPHERE), white=0.8, log=True)
    theirs = cli_json("features", SPHERE, "--white", 0.8, "--log-features")
    assert len(ours) == 234
    assert list(ours) == theirs["names"]
    assert list(ours.values()) == theirs["values"]


def test_an_array_gives_what_the_same_samples_in_a_file_give(tmp_path):
    luminance = shaded_sphere()
    pfm = tmp_path / "sphere.pfm"
    write_pfm(pfm, luminance)
    c = (luminance.shape[0] - 1) / 2
    circle = {"cx": c, "cy": c, "r": luminance.shape[0] / 2.2, "white": 1.3}
    from_file = reflectance.features(pfm, **circle)
    from_float32 = reflectance.features(luminance, **circle)
    from_float64 = reflectance.features(luminance.astype(np.float64), **circle)
    # A transposed view (not C-contiguous) holds the same values as its copy.
    from_view = reflectance.features(np.ascontiguousarray(luminance.T).T, **circle)
    assert from_file == from_float32 == from_float64 == from_view
    theirs = cli_json("features", pfm, *circle_flags(**circle))
    assert list(from_file.values()) == theirs["values"]


def test_a_mask_array_places_the_sphere_as_the_mask_file_does(tmp_path):
    luminance = shaded_sphere()
    mask = luminance > 0
    from_bool = reflectance.features(luminance, mask=mask, white=1.3)
    from_float = reflectance.features(luminance, mask=mask.astype(np.float64), white=1.3)
    assert from_bool == from_float
    pfm = tmp_path / "mask.pfm"
    write_pfm(pfm, mask.astype(np.float32))
    assert reflectance.features(luminance, mask=pfm, white=1.3) == from_bool


def test_unwrap_is_what_the_features_read():
    annulus = reflectance.unwrap(SPHERE, **CIRCLE)
    assert annulus.shape == (96, 448) and annulus.dtype == np.float64
    f = reflectance.features(SPHERE, **CIRCLE)
    assert annulus.mean() == pytest.approx(f["pix.mean"], rel=1e-12)
    assert np.log10(annulus.var()) == pytest.approx(f["pix.var"], rel=1e-12)


@pytest.mark.parametrize(
    "image, kwargs, error, words",
    [
        (np.zeros((64, 64), dtype=np.int64), {}, TypeError, "not a 2-D array of int64"),
        (np.zeros((64, 64, 3)), {}, TypeError, "not a 3-D array of float64"),
        ([[0.5] * 64] * 64, {}, TypeError, "not list"),
        (np.full((100, 100), np.nan), CIRCLE, reflectance.ReflectanceError, "non-finite"),
        (-np.ones((100, 100)), CIRCLE, reflectance.ReflectanceError, "negative luminance"),
        (np.ones((100, 100)), {"cx": 50, "cy": 50, "r": 80}, reflectance.ReflectanceError, "outside the 100×100 image"),
        (np.ones((100, 100)), {"cx": 50, "cy": 50}, reflectance.ReflectanceError, "cx, cy and r"),
        (np.ones((100, 100)), {"cx": 50, "cy": 50, "r": 10}, reflectance.ReflectanceError, "below the minimum of 32 px"),
        (np.ones((100, 100)), {"white": 0.0}, reflectance.ReflectanceError, "white"),
        (np.zeros((100, 100)), {}, reflectance.ReflectanceError, "give cx, cy and r, or mask"),
        ("no/such/photo.png", {}, reflectance.ReflectanceError, "no/such/photo.png: "),
    ],
)
def test_bad_input_is_a_clear_python_error(image, kwargs, error, words):
    with pytest.raises(error) as raised:
        reflectance.features(image, **kwargs)
    assert words in str(raised.value)


def test_errors_carry_the_command_lines_messages(tmp_path):
    text = tmp_path / "notes.png"
    text.write_bytes(b"not an image at all")
    with pytest.raises(reflectance.ReflectanceError) as raised:
        reflectance.features(text, **CIRCLE)
    done = cli("features", text, *circle_flags(**CIRCLE))
    assert done.returncode != 0
    assert str(raised.value) in done.stderr
