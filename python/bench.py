"""The binding's cost per call: `reflectance.features` on the 512 × 512 sphere of
`cargo bench --bench features`, as a numpy array of linear luminance and as a PNG file.
Compare the medians with the core's own benches, `features_of_an_array` and
`features_including_decode` (docs/performance.md, "Python").

    python3 python/bench.py [--runs 300]
"""

import os

# numpy's OpenBLAS threads would otherwise spin beside the timed calls on a small machine.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import struct  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import zlib  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import reflectance  # noqa: E402

SIZE = 512


def sphere_pixels() -> np.ndarray:
    """The bench's 8-bit sphere (benches/features.rs, `png_bytes`)."""
    c, r = (SIZE - 1) / 2, SIZE / 2.2
    i = np.arange(SIZE * SIZE, dtype=np.int64)
    x, y = (i % SIZE).astype(np.float64), (i // SIZE).astype(np.float64)
    dx, dy = (x - c) / r, (y - c) / r
    d2 = dx * dx + dy * dy
    shade = 0.25 + 0.5 * np.sqrt(np.clip(1 - d2, 0, None)) + 0.15 * np.sin(9 * dx) * np.cos(7 * dy)
    grain = ((i * 2_654_435_761) % 17) / 170.0
    pixels = (np.clip(shade + grain, 0, 1) * 255).astype(np.uint8)
    return np.where(d2 > 1, 0, pixels).reshape(SIZE, SIZE).astype(np.uint8)


def png(pixels: np.ndarray) -> bytes:
    """A grey 8-bit PNG, unfiltered."""
    raw = b"".join(b"\0" + row.tobytes() for row in pixels)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", SIZE, SIZE, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def srgb_to_linear(pixels: np.ndarray) -> np.ndarray:
    v = pixels / 255.0
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def median_us(call, runs: int) -> float:
    for _ in range(20):
        call()
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        call()
        times.append(time.perf_counter() - t)
    return statistics.median(times) * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=300)
    runs = parser.parse_args().runs
    pixels = sphere_pixels()
    luminance = srgb_to_linear(pixels)
    circle = dict(cx=(SIZE - 1) / 2, cy=(SIZE - 1) / 2, r=SIZE / 2.2, white=1.0)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "sphere.png"
        path.write_bytes(png(pixels))
        array_us = median_us(lambda: reflectance.features(luminance, **circle), runs)
        file_us = median_us(lambda: reflectance.features(path, **circle), runs)
    print(f"reflectance.features(512² float64 array): {array_us:7.0f} µs median of {runs}")
    print(f"reflectance.features(512² PNG file):      {file_us:7.0f} µs median of {runs}")


if __name__ == "__main__":
    main()
