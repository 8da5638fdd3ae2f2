"""Shared fixtures: the repository, the command line to compare with, a sphere photograph."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SPHERE = ROOT / "tests/fixtures/features/sphere_rgb8.png"
# The README's example: the circle and white of this photograph.
CIRCLE = {"cx": 96.5, "cy": 94.25, "r": 85.0, "white": 0.8}
WARD6 = ROOT / "models/ward6"


def binary() -> Path:
    path = Path(os.environ.get("REFLECTANCE_BIN", ROOT / "target/release/reflectance"))
    if not path.is_file():
        pytest.fail(f"{path} is missing: `cargo build --release` first (or set REFLECTANCE_BIN)")
    return path


def cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([str(binary()), *map(str, args)], capture_output=True, text=True)


def cli_json(*args):
    done = cli(*args)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def circle_flags(cx, cy, r, white):
    return ["--cx", cx, "--cy", cy, "--r", r, "--white", white]


def write_pfm(path: Path, luminance: np.ndarray) -> None:
    """A grey Portable Float Map (little-endian, rows bottom to top)."""
    h, w = luminance.shape
    with open(path, "wb") as f:
        f.write(f"Pf\n{w} {h}\n-1.0\n".encode())
        f.write(np.flipud(luminance).astype("<f4").tobytes())


def shaded_sphere(size: int = 160) -> np.ndarray:
    """A glossy-looking sphere on black, float32 values (so that a PFM holds them exactly)."""
    y, x = np.mgrid[0:size, 0:size].astype(np.float64)
    c, r = (size - 1) / 2, size / 2.2
    d2 = ((x - c) ** 2 + (y - c) ** 2) / r**2
    inside = d2 < 1
    z = np.sqrt(np.clip(1 - d2, 0, 1))
    shade = 0.15 + 0.5 * z + 2.0 * np.exp(-((x - c + 0.3 * r) ** 2 + (y - c + 0.35 * r) ** 2) / (0.01 * r**2))
    stripes = 0.1 * np.sin(x / 3.0) * np.cos(y / 5.0)
    return np.where(inside, shade + stripes * z, 0.0).clip(0, None).astype(np.float32)
