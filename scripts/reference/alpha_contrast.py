"""How much fine detail a glossy lobe removes, per probe.

For each probe of a rendered 11-class data set (`render --classes classes11.json`), the
variance of horizontal differences of log10 luminance in the annulus 0.4 r–0.9 r of the
α = 0.02 sphere (class K) over that of the mirror (class D). Small: the glossy lobe removes
much detail the map has; near 1: the map has little detail finer than α, and the two
spheres look alike. Dev-only (numpy), for the README's account of the α mistakes.

    python3 scripts/reference/alpha_contrast.py data/all_11
"""

import csv
import sys
from pathlib import Path

import numpy as np


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    channels = 3 if kind == b"PF" else 1
    return data.reshape(height, width, channels)[::-1].mean(axis=2)


def fine_detail(image, annulus):
    log = np.log10(np.maximum(image, 1e-4))
    steps = log[:, 1:] - log[:, :-1]
    return float(np.var(steps[annulus[:, 1:]]))


def main(folder):
    folder = Path(folder)
    rows = {r["path"]: r for r in csv.DictReader(open(folder / "manifest.csv"))}
    ratios = []
    for path, row in rows.items():
        if "@" in row["illumination"] or not path.endswith("__D.pfm"):
            continue
        mirror = read_pfm(folder / path)
        glossy = read_pfm(folder / path.replace("__D.pfm", "__K.pfm"))
        cx, cy, r = (float(row[k]) for k in ("cx", "cy", "r"))
        y, x = np.mgrid[: mirror.shape[0], : mirror.shape[1]]
        radius = np.hypot(x - cx, y - cy) / r
        annulus = (radius > 0.4) & (radius < 0.9)
        ratios.append((fine_detail(glossy, annulus) / fine_detail(mirror, annulus), row["illumination"]))
    ratios.sort()
    for ratio, name in ratios:
        print(f"{ratio:.3f}  {name}")
    print(f"median {np.median([r for r, _ in ratios]):.3f} over {len(ratios)} probes")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "data/all_11")
