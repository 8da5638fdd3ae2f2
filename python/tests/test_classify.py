"""`reflectance.classify` and `reflectance.Model` against `reflectance classify --json`,
and from several threads at once."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import reflectance
from conftest import CIRCLE, ROOT, SPHERE, WARD6, circle_flags, cli, cli_json, shaded_sphere

# What differs between two runs of the same classification.
VOLATILE = ("timing_ms", "request_id")


def stable(answer):
    return {k: v for k, v in answer.items() if k not in VOLATILE}


@pytest.mark.parametrize("model", ["ward6", "ward11"])
def test_the_answer_equals_the_command_lines(model):
    ours = reflectance.classify(SPHERE, model=ROOT / "models" / model, **CIRCLE)
    theirs = cli_json("classify", SPHERE, "--model", ROOT / "models" / model, *circle_flags(**CIRCLE), "--json")
    assert stable(ours) == stable(theirs)
    assert ours["label"] == ours["probabilities"][0]["label"]
    assert ours["label"] in ours["prediction_set"]["labels"]


def test_a_loaded_model_answers_as_a_path_does():
    model = reflectance.Model(WARD6)
    assert (model.name, model.version) == ("ward6", 3)
    assert model.classes == ["black_matte", "black_shiny", "chrome", "gray_shiny", "white_matte", "white_shiny"]
    assert repr(model) == 'Model(name="ward6", version=3)'
    by_model = reflectance.classify(SPHERE, model=model, **CIRCLE)
    assert stable(model.classify(SPHERE, **CIRCLE)) == stable(by_model)
    assert stable(reflectance.classify(SPHERE, model=str(WARD6), **CIRCLE)) == stable(by_model)
    wide = model.classify(SPHERE, coverage=0.999, **CIRCLE)
    assert wide["prediction_set"]["coverage"] == 0.999
    assert set(by_model["prediction_set"]["labels"]) <= set(wide["prediction_set"]["labels"])


def test_an_array_is_classified_and_a_picture_of_nothing_is_out_of_domain():
    model = reflectance.Model(WARD6)
    sphere = shaded_sphere(256)
    c = (256 - 1) / 2
    answer = model.classify(sphere, cx=c, cy=c, r=256 / 2.2, white=1.3)
    assert answer["label"] in model.classes
    assert answer["geometry"]["method"] == "given"
    noise = np.random.default_rng(3).random((256, 256))
    odd = model.classify(noise, cx=c, cy=c, r=100, white=1.0)
    # Flagged by the domain check alone (outline and typicality), not the capture envelope:
    # the verdict the model's one source gives, as on every other surface.
    assert odd["domain"]["in_domain"] is False, odd["domain"]
    assert len(odd["domain"]["reasons"]) == 2, odd["domain"]
    assert not any("noise" in reason for reason in odd["domain"]["reasons"]), odd["domain"]


def sphere_normals(size: int) -> np.ndarray:
    """The camera-space normals of `shaded_sphere(size)`'s sphere, zero outside it."""
    y, x = np.mgrid[0:size, 0:size].astype(np.float64)
    c, r = (size - 1) / 2, size / 2.2
    nx, ny = (x - c) / r, (c - y) / r
    z2 = 1 - nx**2 - ny**2
    normals = np.stack([nx, ny, np.sqrt(np.clip(z2, 0, 1))], axis=-1)
    return np.where((z2 > 0)[..., None], normals, 0.0).astype(np.float32)


def test_an_object_is_classified_from_its_normals_as_the_command_line_does(tmp_path):
    model = reflectance.Model(WARD6)
    size = 256
    sphere, normals = shaded_sphere(size), sphere_normals(size)
    c = (size - 1) / 2
    by_circle = model.classify(sphere, cx=c, cy=c, r=size / 2.2, white=1.3)
    by_normals = model.classify(sphere, normals=normals, white=1.3)
    assert by_normals["geometry"]["method"] == "normals"
    assert by_normals["observed_fraction"] > 0.95
    assert by_normals["label"] == by_circle["label"]
    # Half the object: less of the sphere, and the widest prediction set.
    left = np.zeros((size, size), dtype=bool)
    left[:, : size // 2] = True
    half = model.classify(sphere, normals=normals, mask=left, white=1.3)
    assert 0.2 < half["observed_fraction"] < 0.95
    assert half["prediction_set"]["coverage"] == 0.999
    # The files the command line reads give the command line's answer.
    render = cli("render", "--probes", ROOT / "data/probes", "--classes", ROOT / "data/classes/classes6.json",
                 "--out", tmp_path, "--size", "96", "--shape", "torus")
    assert render.returncode == 0, render.stderr
    image = tmp_path / "polyhaven_dresden_square__chrome.pfm"
    normals_png = tmp_path / "polyhaven_dresden_square__chrome.normals.png"
    ours = reflectance.classify(image, model=WARD6, normals=normals_png, white=2.0)
    theirs = cli_json("classify", image, "--model", WARD6, "--normals", normals_png, "--white", 2.0, "--json")
    assert stable(ours) == stable(theirs)
    with pytest.raises(reflectance.ReflectanceError, match="not both"):
        model.classify(sphere, normals=normals, cx=c, cy=c, r=100)
    with pytest.raises(TypeError, match="H×W×3"):
        model.classify(sphere, normals=normals[..., :2])


def test_bad_models_and_arguments_are_python_errors(tmp_path):
    with pytest.raises(reflectance.ReflectanceError, match="unknown model|no such|not found|No such"):
        reflectance.Model(tmp_path / "nothing")
    with pytest.raises(reflectance.ReflectanceError, match="coverage"):
        reflectance.classify(SPHERE, model=WARD6, coverage=1.5, **CIRCLE)
    with pytest.raises(TypeError):
        reflectance.classify(SPHERE, model=3, **CIRCLE)


def test_one_model_serves_many_threads_with_the_same_answers():
    model = reflectance.Model(WARD6)
    expected = stable(model.classify(SPHERE, **CIRCLE))
    features = reflectance.features(SPHERE, **CIRCLE)
    with ThreadPoolExecutor(max_workers=4) as pool:
        answers = list(pool.map(lambda _: stable(model.classify(SPHERE, **CIRCLE)), range(16)))
        rows = list(pool.map(lambda _: reflectance.features(SPHERE, **CIRCLE), range(16)))
    assert all(a == expected for a in answers)
    assert all(r == features for r in rows)
