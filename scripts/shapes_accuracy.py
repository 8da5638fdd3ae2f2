#!/usr/bin/env python3
"""Classify rendered objects of every shape from their normal maps (issue #44).

Renders each shape under the probes given with `reflectance render --shape`, classifies
every image with `reflectance classify --normals`, and prints accuracy, confident errors and
the observed fraction per shape. Usage:

    python3 scripts/shapes_accuracy.py --model models/ward6 --classes data/classes/classes6.json \
        --probes data/probes [--shapes torus,superquadric,capsule,blob,sphere] [--size 256] \
        [--out /tmp/shapes] [--binary target/release/reflectance] [--keep left|top|centre]
        [--perturb noise:DEG|blur:PX|rotate:DEG]

A confident error is a wrong label whose prediction set holds that label alone while the
domain check calls the input in domain.
"""

import argparse
import csv
import json
import os
import subprocess
import sys
from collections import defaultdict


def render(binary, args, shape, out):
    if os.path.exists(os.path.join(out, "manifest.csv")):
        return
    subprocess.run(
        [binary, "render", "--probes", args.probes, "--classes", args.classes, "--out", out,
         "--size", str(args.size), "--seed", str(args.seed), "--shape", shape],
        check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def perturbed(normals, how, seed=7):
    """`normals` (a 16-bit PNG) perturbed as `how` says, written beside it: noise:DEG (each
    normal turned by a random tangent offset of DEG degrees per axis), blur:PX (a Gaussian of PX
    pixels over the object's normals) or rotate:DEG (every normal turned DEG degrees about the
    image's x axis: the pose is off by that)."""
    import numpy as np
    import png
    kind, amount = how.split(":")
    amount = float(amount)
    width, height, rows, info = png.Reader(filename=normals).read()
    planes = info["planes"]
    v = np.array([list(r) for r in rows], dtype=float).reshape(height, width, planes)
    object_ = v[..., :3].sum(-1) > 0
    n = 2.0 * v[..., :3] / 65535.0 - 1.0
    if kind == "noise":
        rng = np.random.default_rng(seed)
        offset = rng.normal(0.0, np.radians(amount), n.shape)
        offset -= (offset * n).sum(-1, keepdims=True) * n
        n = n + offset
    elif kind == "blur":
        radius = int(np.ceil(3 * amount))
        taps = np.exp(-0.5 * (np.arange(-radius, radius + 1) / amount) ** 2)
        weight = object_.astype(float)
        def smooth(a):
            for axis in (0, 1):
                a = sum(np.roll(a, k, axis=axis) * t for k, t in zip(range(-radius, radius + 1), taps))
            return a
        n = smooth(n * weight[..., None]) / np.maximum(smooth(weight), 1e-9)[..., None]
    elif kind == "rotate":
        a = np.radians(amount)
        turn = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        n = n @ turn.T
    else:
        raise SystemExit(f"unknown perturbation {how!r}")
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-9)
    object_ &= n[..., 2] >= 0
    out = np.where(object_[..., None], np.round((n + 1.0) / 2.0 * 65535.0), 0).astype(np.uint16)
    path = normals.replace(".normals.png", f".{kind}{amount:g}.normals.png")
    png.Writer(width, height, greyscale=False, bitdepth=16).write(
        open(path, "wb"), out.reshape(height, width * 3).tolist())
    return path


def half_mask(normals, keep):
    """A mask of the part of the image `keep` names (left, top, centre), beside `normals`."""
    from PIL import Image
    import numpy as np
    size = Image.open(normals).size
    rows, cols = np.mgrid[0:size[1], 0:size[0]]
    inside = {"left": cols < size[0] // 2, "top": rows < size[1] // 2,
              "centre": (abs(cols - size[0] / 2) < size[0] / 4) & (abs(rows - size[1] / 2) < size[1] / 4)}[keep]
    path = normals.replace(".normals.png", f".{keep}.mask.png")
    Image.fromarray((inside * 255).astype("uint8")).save(path)
    return path


def classify(binary, model, image, normals, white, keep=None, perturb=None):
    command = [binary, "classify", image, "--model", model, "--json", "--white", str(white)]
    if normals and perturb:
        normals = perturbed(normals, perturb)
    if normals:
        command += ["--normals", normals]
        if keep:
            command += ["--mask", half_mask(normals, keep)]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        return None, done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "failed"
    return json.loads(done.stdout), None


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--model", required=True)
    p.add_argument("--classes", required=True)
    p.add_argument("--probes", required=True)
    p.add_argument("--shapes", default="torus,superquadric,capsule,blob,sphere")
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", default="/tmp/shapes")
    p.add_argument("--binary", default="target/release/reflectance")
    p.add_argument("--perturb", metavar="noise:DEG|blur:PX|rotate:DEG",
                   help="classify with the normal maps perturbed (needs numpy and pypng)")
    p.add_argument("--keep", choices=["left", "top", "centre"],
                   help="classify only this part of each object (a mask beside the normals)")
    args = p.parse_args()
    rows = []
    for shape in args.shapes.split(","):
        out = os.path.join(args.out, shape.replace(":", "_").replace("/", "_"))
        render(args.binary, args, shape, out)
        with open(os.path.join(out, "manifest.csv")) as f:
            for entry in csv.DictReader(f):
                image = os.path.join(out, entry["path"])
                normals = os.path.splitext(image)[0] + ".normals.png"
                white = float(entry.get("white") or 1.0)
                answer, why = classify(args.binary, args.model, image,
                                       normals if os.path.exists(normals) else None, white,
                                       args.keep, args.perturb)
                rows.append((shape, entry["class"], entry.get("illumination", ""), answer, why))
    print(f"{'shape':<14}{'n':>4}{'right':>7}{'refused':>9}{'conf. wrong':>13}"
          f"{'out of dom.':>13}{'in set':>8}{'mean set':>10}{'observed':>10}{'scatter':>9}")
    per = defaultdict(list)
    for row in rows:
        per[row[0]].append(row)
    for shape, group in per.items():
        answered = [r for r in group if r[3]]
        right = sum(r[3]["label"] == r[1] for r in answered)
        confident = sum(
            r[3]["label"] != r[1] and r[3]["domain"]["in_domain"]
            and len((r[3].get("prediction_set") or {}).get("labels", [r[3]["label"]])) == 1
            for r in answered)
        outside = sum(not r[3]["domain"]["in_domain"] for r in answered)
        sets = [len((r[3].get("prediction_set") or {}).get("labels", [])) for r in answered]
        held = sum(r[1] in (r[3].get("prediction_set") or {}).get("labels", []) for r in answered)
        scatter = [r[3].get("normal_scatter_deg") or 0.0 for r in answered]
        observed = [r[3].get("observed_fraction") or 1.0 for r in answered]
        mean = lambda v: sum(v) / len(v) if v else float("nan")
        print(f"{shape:<14}{len(group):>4}{right:>7}{len(group) - len(answered):>9}"
              f"{confident:>13}{outside:>13}{held:>8}{mean(sets):>10.2f}{mean(observed):>10.2f}"
              f"{mean(scatter):>9.1f}")
    for shape, cls, light, answer, why in rows:
        if answer is None:
            print(f"refused {shape} {cls} {light}: {why}", file=sys.stderr)


if __name__ == "__main__":
    main()
