"""Do real renderers draw the exported materials as the classes they came from?

For each class file: every class exported with `reflectance gltf`, imported and rendered by
Blender (scripts/gltf/blender/render.py, Cycles by default) under each light probe, and the
same class rendered by the project's Ward renderer (`reflectance render`) under the same
probe and camera. Printed as Markdown:

* per class, over the probes: the disc-mean brightness of Blender's sphere over the Ward
  sphere's (mean, min, max), and the radial profile's RMS difference (10 rings of equal
  width out to 0.98 r, each ring's mean relative to the Ward disc's mean);
* the Blender renders classified by the model (`reflectance predict`, with the Ward
  render's white reference): right, and confidently wrong (wrong with the true class
  outside the 95 % prediction set).

Exits 1 when a class's mean brightness ratio leaves [1 − tol, 1 + tol] (--tolerance) or a
render is confidently wrong; --min-right sets the least fraction classified right.

    python3 scripts/gltf/blender/check.py --probes LIST_OR_FILES… --classes C.json[:MODEL] …
        [--bin target/release/reflectance] [--size 128] [--samples 256] [--work DIR]
        [--engine cycles|eevee] [--tolerance 0.05] [--min-right 0.95]
"""

import argparse
import csv
import math
import os
import struct
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
RING_COUNT = 10
RING_EDGE = 0.98


def parse():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--probes", nargs="+", required=True,
                   help=".hdr files, or text files listing them (as reflectance render reads)")
    p.add_argument("--classes", nargs="+", required=True,
                   help="CLASSES.json, or CLASSES.json:MODEL_DIR to classify the renders")
    p.add_argument("--bin", default="target/release/reflectance")
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--samples", type=int, default=256)
    p.add_argument("--engine", choices=["cycles", "eevee"], default="cycles")
    p.add_argument("--work", help="keep the renders here (default: a temporary folder)")
    p.add_argument("--tolerance", type=float, default=0.05)
    p.add_argument("--min-right", type=float, default=0.95)
    return p.parse_args()


def probe_files(entries):
    files = []
    for entry in entries:
        if entry.endswith(".hdr"):
            files.append(os.path.abspath(entry))
            continue
        base = os.path.dirname(os.path.abspath(entry))
        with open(entry) as f:
            for line in f:
                line = line.split("#")[0].strip()
                if not line:
                    continue
                for folder in (base, os.path.dirname(base)):
                    path = os.path.join(folder, line)
                    if os.path.exists(path):
                        files.append(path)
                        break
                else:
                    sys.exit(f"probe {line!r} of {entry} not found")
    return files


def read_pfm(path):
    """(width, height, luminance rows top first) of a grey or RGB PFM."""
    with open(path, "rb") as f:
        kind = f.readline().strip()
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        data = f.read()
    channels = 3 if kind == b"PF" else 1
    fmt = ("<" if scale < 0 else ">") + "f" * (width * height * channels)
    values = struct.unpack(fmt, data[: 4 * width * height * channels])
    if channels == 3:
        values = [0.2126 * values[3 * i] + 0.7152 * values[3 * i + 1] + 0.0722 * values[3 * i + 2]
                  for i in range(width * height)]
    rows = [values[y * width:(y + 1) * width] for y in range(height)]
    return width, height, rows[::-1]


def rings(path):
    """The disc's mean, and the means of RING_COUNT rings of equal width to RING_EDGE r."""
    width, height, rows = read_pfm(path)
    c, r = (width - 1) / 2.0, width / 2.2
    sums = [0.0] * RING_COUNT
    counts = [0] * RING_COUNT
    for y in range(height):
        for x in range(width):
            rho = math.hypot(x - c, y - c) / r
            if rho < RING_EDGE:
                k = int(rho / RING_EDGE * RING_COUNT)
                sums[k] += rows[y][x]
                counts[k] += 1
    disc = sum(sums) / sum(counts)
    return disc, [s / max(n, 1) for s, n in zip(sums, counts)]


def run(cmd, **kw):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, **kw)


def main():
    args = parse()
    work = args.work or tempfile.mkdtemp(prefix="blender-check.")
    os.makedirs(work, exist_ok=True)
    probes = probe_files(args.probes)
    probe_list = os.path.join(work, "probes.txt")
    with open(probe_list, "w") as f:
        f.write("\n".join(probes) + "\n")
    failed = False
    print(f"Blender ({args.engine}, {args.samples} samples, {args.size}²) against the Ward "
          f"renderer, {len(probes)} probes\n")
    for spec in args.classes:
        classes, _, model = spec.partition(":")
        name = os.path.splitext(os.path.basename(classes))[0]
        gltf_dir = os.path.join(work, f"gltf_{name}")
        ward_dir = os.path.join(work, f"ward_{name}")
        blender_dir = os.path.join(work, f"blender_{name}_{args.engine}")
        run([args.bin, "gltf", "--classes", classes, "--out", gltf_dir])
        run([args.bin, "render", "--probes", probe_list, "--classes", classes, "--out", ward_dir,
             "--size", str(args.size)])
        assets = sorted(os.path.join(gltf_dir, a) for a in os.listdir(gltf_dir))
        subprocess.run([sys.executable, os.path.join(HERE, "render.py"), "--probes", *probes,
                        "--assets", *assets, "--out", blender_dir, "--size", str(args.size),
                        "--samples", str(args.samples), "--engine", args.engine],
                       check=True, stdout=subprocess.DEVNULL)
        with open(os.path.join(ward_dir, "manifest.csv")) as f:
            ward_rows = list(csv.DictReader(f))
        per_class = {}
        manifest = [["path", "class", "illumination", "cx", "cy", "r", "white"]]
        for row in ward_rows:
            stem = os.path.splitext(os.path.basename(row["path"]))[0]
            blender = os.path.join(blender_dir, f"{stem}.pfm")
            ward_disc, ward_rings = rings(os.path.join(ward_dir, row["path"]))
            disc, profile = rings(blender)
            rms = math.sqrt(sum((a - b) ** 2 for a, b in zip(profile, ward_rings)) / RING_COUNT)
            per_class.setdefault(row["class"], []).append((disc / ward_disc, rms / ward_disc))
            manifest.append([blender, row["class"], row["illumination"], row["cx"], row["cy"],
                             row["r"], row["white"]])
        print(f"### {classes}\n")
        print("| class | brightness, Blender / Ward: mean | min | max | radial profile RMS |")
        print("|---|---|---|---|---|")
        for cls, values in sorted(per_class.items()):
            ratios = [v[0] for v in values]
            mean = sum(ratios) / len(ratios)
            profile = sum(v[1] for v in values) / len(values)
            if abs(mean - 1.0) > args.tolerance:
                failed = True
            print(f"| {cls} | {mean:.3f} | {min(ratios):.3f} | {max(ratios):.3f} | {profile:.3f} |")
        if model:
            failed |= classify(args, work, name, model, manifest)
        print()
    sys.exit(1 if failed else 0)


def classify(args, work, name, model, manifest):
    manifest_path = os.path.join(work, f"blender_{name}.csv")
    with open(manifest_path, "w", newline="") as f:
        csv.writer(f).writerows(manifest)
    predictions = os.path.join(work, f"predictions_{name}.csv")
    run([args.bin, "predict", "--model", model, "--manifest", manifest_path, "--out", predictions])
    truth = {row[0]: row[1] for row in manifest[1:]}
    with open(predictions) as f:
        rows = list(csv.DictReader(f))
    right = sum(truth[r["path"]] == r["label"] for r in rows)
    confident = [r for r in rows
                 if truth[r["path"]] != r["label"] and truth[r["path"]] not in r["set"].split()]
    print(f"\nClassified by {model}: **{right} of {len(rows)} right**, "
          f"{len(confident)} confidently wrong (the truth outside the 95 % set)")
    for r in confident:
        p = r.get(f"p_{r['label']}", "?")
        print(f"- {os.path.basename(r['path'])}: {r['label']} (p {p}), set {{{r['set']}}}")
    return len(confident) > 0 or right < args.min_right * len(rows)


if __name__ == "__main__":
    main()
