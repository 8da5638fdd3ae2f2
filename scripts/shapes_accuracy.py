#!/usr/bin/env python3
"""Classify rendered objects of every shape from their normal maps (issue #44).

Renders each shape under the probes given with `reflectance render --shape` (shaded from its
normals), or with `--renderer cycles` path-traces Blender's objects with the classes' exported
glTF materials (scripts/gltf/blender/objects.py: self-shadowing and interreflection included,
the normals from Blender), classifies every image with `reflectance classify --normals`, and
prints accuracy, confident errors and the observed fraction per shape. Usage:

    python3 scripts/shapes_accuracy.py --model models/ward6 --classes data/classes/classes6.json \
        --probes data/probes [--shapes torus,superquadric,capsule,blob,sphere] [--size 256] \
        [--out /tmp/shapes] [--binary target/release/reflectance] [--keep left|top|centre]
        [--perturb noise:DEG|blur:PX|rotate:DEG] [--capture SEED] [--renderer ward|cycles]
        [--samples 256]
        [--min-right 0.9] [--max-confident 0]

With --renderer cycles the shapes are torus, suzanne, blob and capsule (the default then) and
the white reference is the one `reflectance render` gives under the same probe. A render with
no normal map beside it (`reflectance render`'s sphere) is classified by its manifest's circle.

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
    if args.renderer == "cycles":
        return render_cycles(binary, args, shape, out)
    subprocess.run(
        [binary, "render", "--probes", args.probes, "--classes", args.classes, "--out", out,
         "--size", str(args.size), "--seed", str(args.seed), "--shape", shape],
        check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def render_cycles(binary, args, shape, out):
    """Blender's `shape` with each class's glTF material under each probe, and a manifest in
    `reflectance render`'s columns (the white from a small Ward sphere under the same probe)."""
    quiet = dict(check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    gltf = os.path.join(args.out, "gltf")
    whites = os.path.join(args.out, "whites")
    if not os.path.isdir(gltf):
        subprocess.run([binary, "gltf", "--classes", args.classes, "--out", gltf], **quiet)
    probes = sorted(probe_paths(args.probes))
    if not os.path.exists(os.path.join(whites, "manifest.csv")):
        listed = os.path.join(args.out, "probes.txt")
        with open(listed, "w") as f:
            f.write("\n".join(probes) + "\n")
        subprocess.run([binary, "render", "--probes", listed, "--classes", args.classes,
                        "--out", whites, "--size", "96"], **quiet)
    with open(os.path.join(whites, "manifest.csv")) as f:
        white = {row["illumination"]: row["white"] for row in csv.DictReader(f)}
    here = os.path.dirname(os.path.abspath(__file__))
    assets = sorted(os.path.join(gltf, a) for a in os.listdir(gltf))
    subprocess.run([sys.executable, os.path.join(here, "gltf", "blender", "objects.py"),
                    "--shape", shape, "--probes", *probes, "--assets", *assets, "--out", out,
                    "--size", str(args.size), "--samples", str(args.samples),
                    "--seed", str(args.seed)], **quiet)
    with open(os.path.join(out, "manifest.csv.part"), "w", newline="") as f:
        rows = csv.writer(f)
        rows.writerow(["path", "class", "illumination", "cx", "cy", "r", "white", "normals"])
        for probe in probes:
            light = os.path.splitext(os.path.basename(probe))[0]
            for asset in assets:
                cls = os.path.splitext(os.path.basename(asset))[0]
                name = f"{light}__{cls}"
                rows.writerow([f"{name}.pfm", cls, light, "", "", "", white[light],
                               f"{name}.normals.png"])
    os.replace(os.path.join(out, "manifest.csv.part"), os.path.join(out, "manifest.csv"))


def probe_paths(probes):
    """The .hdr files `--probes` names: a folder, one file, or a list file (as render reads)."""
    if os.path.isdir(probes):
        return {os.path.join(probes, p) for p in os.listdir(probes) if p.endswith(".hdr")}
    if probes.endswith(".hdr"):
        return {os.path.abspath(probes)}
    base = os.path.dirname(os.path.abspath(probes))
    with open(probes) as f:
        names = [line.split("#")[0].strip() for line in f]
    return {n if os.path.isabs(n) else os.path.join(base, n) for n in names if n}


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


def read_pfm(path):
    """A PFM's samples as a float array (rows top to bottom; H×W or H×W×3)."""
    import numpy as np
    with open(path, "rb") as f:
        kind = f.readline().strip()
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        samples = np.fromfile(f, dtype="<f4" if scale < 0 else ">f4")
    shape = (height, width, 3) if kind == b"PF" else (height, width)
    return samples.reshape(shape)[::-1].astype(float)


def captured(image, white, seed):
    """`image` (a linear render whose white reference is `white`) as the capture model of
    docs/design.md ("Capture model") takes a photograph of it, the geometry kept (no resampling,
    so the normal map still lines up): lens blur σ 0–1 px, exposure e 0.2–0.8 of full scale,
    noise n 0–0.025 (shot share 0.5–1), clipped, then ¼ 8-bit sRGB PNG, ¼ 16-bit linear PNG,
    ½ JPEG quality 70–98; the reported white e·(1 ± 5 %). Drawn per image from `seed` and its
    name. Returns (path, reported white, encoding)."""
    import zlib
    import numpy as np
    from PIL import Image
    rng = np.random.default_rng([seed, zlib.crc32(os.path.basename(image).encode())])
    blur, e = rng.uniform(0.0, 1.0), rng.uniform(0.2, 0.8)
    n, share = rng.uniform(0.0, 0.025), rng.uniform(0.5, 1.0)
    signal = read_pfm(image)
    if blur > 0.05:
        radius = int(np.ceil(3 * blur))
        taps = np.exp(-0.5 * (np.arange(-radius, radius + 1) / blur) ** 2)
        taps /= taps.sum()
        for axis in (0, 1):
            padded = np.pad(signal, [(radius, radius) if a == axis else (0, 0)
                                     for a in range(signal.ndim)], mode="edge")
            signal = sum(t * np.take(padded, range(k, k + signal.shape[axis]), axis=axis)
                         for k, t in enumerate(taps))
    x = signal / white * e
    variance = n * n * share * e * x + n * n * (1.0 - share) * e * e
    x = np.clip(x + rng.normal(size=x.shape) * np.sqrt(np.maximum(variance, 0.0)), 0.0, 1.0)
    reported = e * (1.0 + rng.uniform(-0.05, 0.05))
    encode = lambda v: np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)
    stem = os.path.splitext(image)[0] + f".cap{seed}"
    draw = rng.uniform()
    if draw < 0.25:
        path, encoding = stem + ".png", "srgb"
        Image.fromarray(np.round(encode(x) * 255).astype(np.uint8)).save(path)
    elif draw < 0.5:
        import png
        path, encoding = stem + ".png", "linear"
        codes = np.round(x * 65535).astype(np.uint16)
        planes = 3 if codes.ndim == 3 else 1
        png.Writer(codes.shape[1], codes.shape[0], greyscale=planes == 1, bitdepth=16).write(
            open(path, "wb"), codes.reshape(codes.shape[0], -1).tolist())
    else:
        path, encoding = stem + ".jpg", "srgb"
        Image.fromarray(np.round(encode(x) * 255).astype(np.uint8)).save(
            path, quality=int(rng.integers(70, 99)))
    return path, reported, encoding


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


def classify(binary, model, image, normals, white, keep=None, perturb=None, capture=None,
             circle=None):
    encoding = None
    if capture is not None:
        image, white, encoding = captured(image, white, capture)
    command = [binary, "classify", image, "--model", model, "--json", "--white", str(white)]
    if encoding:
        command += ["--encoding", encoding]
    if normals and perturb:
        normals = perturbed(normals, perturb)
    if normals:
        command += ["--normals", normals]
        if keep:
            command += ["--mask", half_mask(normals, keep)]
    elif circle:
        command += ["--cx", circle[0], "--cy", circle[1], "--r", circle[2]]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        return None, done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "failed"
    return json.loads(done.stdout), None


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--model", required=True)
    p.add_argument("--classes", required=True)
    p.add_argument("--probes", required=True)
    p.add_argument("--shapes", help="default: torus,superquadric,capsule,blob,sphere "
                   "(ward), torus,suzanne,blob,capsule (cycles)")
    p.add_argument("--renderer", choices=["ward", "cycles"], default="ward")
    p.add_argument("--samples", type=int, default=256, help="Cycles' samples per pixel")
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", default="/tmp/shapes")
    p.add_argument("--binary", default="target/release/reflectance")
    p.add_argument("--perturb", metavar="noise:DEG|blur:PX|rotate:DEG",
                   help="classify with the normal maps perturbed (needs numpy and pypng)")
    p.add_argument("--min-right", type=float, default=0.0,
                   help="exit 1 when a shape has fewer right than this share")
    p.add_argument("--max-confident", type=int,
                   help="exit 1 when a shape has more confident errors than this")
    p.add_argument("--capture", type=int, metavar="SEED",
                   help="classify each render as the capture model photographs it, its geometry "
                   "kept (exposure, noise, blur, 8/16-bit PNG or JPEG; needs numpy, pypng, Pillow)")
    p.add_argument("--keep", choices=["left", "top", "centre"],
                   help="classify only this part of each object (a mask beside the normals)")
    args = p.parse_args()
    args.shapes = args.shapes or ("torus,suzanne,blob,capsule" if args.renderer == "cycles"
                                  else "torus,superquadric,capsule,blob,sphere")
    rows = []
    for shape in args.shapes.split(","):
        out = os.path.join(args.out, shape.replace(":", "_").replace("/", "_"))
        render(args.binary, args, shape, out)
        with open(os.path.join(out, "manifest.csv")) as f:
            for entry in csv.DictReader(f):
                image = os.path.join(out, entry["path"])
                normals = entry.get("normals") and os.path.join(out, entry["normals"])
                white = float(entry.get("white") or 1.0)
                answer, why = classify(args.binary, args.model, image, normals, white,
                                       args.keep, args.perturb, args.capture,
                                       (entry["cx"], entry["cy"], entry["r"]))
                rows.append((shape, entry["class"], entry.get("illumination", ""), answer, why))
    print(f"{'shape':<14}{'n':>4}{'right':>7}{'refused':>9}{'conf. wrong':>13}"
          f"{'out of dom.':>13}{'in set':>8}{'mean set':>10}{'observed':>10}{'scatter':>9}"
          f"{'not convex':>12}{'shadowed':>10}")
    per = defaultdict(list)
    failed = False
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
        hollow = [r[3].get("not_convex_fraction") or 0.0 for r in answered]
        shadowed = [r[3].get("shadowed_fraction") or 0.0 for r in answered]
        mean = lambda v: sum(v) / len(v) if v else float("nan")
        failed |= right < args.min_right * len(group)
        failed |= args.max_confident is not None and confident > args.max_confident
        print(f"{shape:<14}{len(group):>4}{right:>7}{len(group) - len(answered):>9}"
              f"{confident:>13}{outside:>13}{held:>8}{mean(sets):>10.2f}{mean(observed):>10.2f}"
              f"{mean(scatter):>9.1f}{mean(hollow):>12.2f}{mean(shadowed):>10.2f}")
    for shape, cls, light, answer, why in rows:
        if answer is None:
            print(f"refused {shape} {cls} {light}: {why}", file=sys.stderr)
        elif answer["label"] != cls:
            labels = (answer.get("prediction_set") or {}).get("labels", [])
            print(f"wrong {shape} {cls} {light}: {answer['label']}, set {labels}", file=sys.stderr)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
