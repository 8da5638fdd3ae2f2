#!/usr/bin/env python3
"""Four tiny synthetic lat-long light probes (64×32 Radiance .hdr, flat RGBE) for the
soak test's rendered dataset: sky gradients, a sun, windows.

    python3 scripts/soak/probes.py OUT_DIR
"""
import math
import pathlib
import sys


def rgbe(v):
    if v <= 1e-32:
        return bytes([0, 0, 0, 0])
    m, e = math.frexp(v)
    c = int(m * 256.0)
    return bytes([c, c, c, e + 128])


def probe(f, width=64, height=32):
    out = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n")
    out += f"-Y {height} +X {width}\n".encode()
    for row in range(height):
        theta = math.pi * (row + 0.5) / height
        for col in range(width):
            phi = 2 * math.pi * (col + 0.5) / width
            x, y, z = math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi)
            out += rgbe(f(x, y, z))
    return bytes(out)


PROBES = [
    lambda x, y, z: 0.3 + max(y, 0.0) + 0.2 * math.sin(6 * x),
    lambda x, y, z: 0.5 + 0.4 * x + 0.1 * math.cos(9 * z) + (30.0 if y > 0.9 else 0.0),
    lambda x, y, z: 0.2 + 0.6 * (0.5 + 0.5 * y) + (3.0 if math.sin(4 * x) > 0.8 else 0.0),
    lambda x, y, z: 0.4 + 0.3 * abs(math.cos(5 * y)) + (20.0 if z > 0.95 else 0.0),
]

if __name__ == "__main__":
    out = pathlib.Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    for k, f in enumerate(PROBES):
        (out / f"probe{k}.hdr").write_bytes(probe(f))
