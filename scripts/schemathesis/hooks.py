"""What the OpenAPI document cannot say, for Schemathesis's positive cases (loaded with
SCHEMATHESIS_HOOKS; scripts/schemathesis.sh).

A schema can say that `image` is bytes, not that they must be a photograph, nor that a
circle must lie inside it, that at most one white reference is given, or that ρd + ρs ≤ 1.
For a case generated as valid (positive), these hooks make the parts that only a real
photograph can fill real: the committed fixture sphere, its circle, a white card. Negative
cases are left as generated, and the server must refuse them.
"""

import base64
import pathlib

import schemathesis

ROOT = pathlib.Path(__file__).resolve().parents[2]
IMAGE = (ROOT / "tests/fixtures/features/sphere_rgb8.png").read_bytes()
CIRCLE = {"cx": "96.5", "cy": "94.25", "r": "85"}
WHITES = ("white", "white_image", "white_rect")
# The fixture is 196 × 191: a white card in its top-left corner.
WHITE_RECT = "0,0,16,16"


def positive(case):
    """Generated valid in every part (the coverage phase marks invalid parts one by one)."""
    meta = case.meta
    return (meta is not None and not meta.generation.mode.is_negative
            and not any(c.mode.is_negative for c in meta.components.values()))


def fill_form(form):
    """A multipart classification or location form: the fixture, its circle, one white."""
    if "image" in form:
        form["image"] = IMAGE
    form.pop("mask", None)
    if any(k in form for k in CIRCLE):
        form.update(CIRCLE)
    given = [k for k in WHITES if k in form]
    for extra in given[1:]:
        del form[extra]
    if "white_image" in form:
        form["white_image"] = IMAGE
    if "white_rect" in form:
        form["white_rect"] = WHITE_RECT
    if "white_reflectance" in form and not ({"white_image", "white_rect"} & set(form)):
        del form["white_reflectance"]
    if "white" in form and not usable_white(form["white"]):
        form["white"] = "0.8"


def usable_white(value):
    """A white the image can be divided by within f32's range (generated forms may hold none)."""
    try:
        return float(value) >= 1e-6
    except (TypeError, ValueError):
        return False


def fill_inference(body):
    """A V2 request: the fixture as its image, the inputs and outputs it names real ones."""
    inputs = [{"name": "image", "datatype": "BYTES", "shape": [1],
               "data": [base64.b64encode(IMAGE).decode()]}]
    inputs += [{"name": k, "datatype": "FP64", "shape": [1], "data": [float(v)]}
               for k, v in CIRCLE.items()]
    body["inputs"] = inputs
    body.pop("parameters", None)
    outputs = list(body.get("outputs") or [])
    if "outputs" in body:
        names = {"label", "probabilities", "classes", "prediction_set", "in_domain"}
        body["outputs"] = [o for o in outputs if isinstance(o, dict) and o.get("name") in names
                           and "parameters" not in o]


@schemathesis.hook
def before_call(ctx, case, **kwargs):
    if not positive(case):
        return
    path = case.operation.path
    # Copies: generated values may be shared with other cases, negative ones among them.
    if isinstance(case.query, dict):
        case.query = dict(case.query)
    if isinstance(case.body, dict):
        case.body = dict(case.body)
    query = case.query if isinstance(case.query, dict) else {}
    if {"rho_d", "rho_s"} <= set(query):
        # ρd + ρs ≤ 1: energy.
        if float(query["rho_d"]) + float(query["rho_s"]) > 1:
            query["rho_s"] = max(0.0, 1.0 - float(query["rho_d"]))
    if "colour" in query and not any(c.strip("0. ") for c in str(query["colour"]).split(",")):
        # A colour of luminance 0 has no hue to scale to luminance 1.
        query["colour"] = "1,1,1"
    if isinstance(case.body, dict):
        if path.endswith("/infer"):
            fill_inference(case.body)
        elif "multipart" in str(case.media_type):
            # Only forms: a JSON body (a job's) may hold an `image` key of its own.
            fill_form(case.body)
