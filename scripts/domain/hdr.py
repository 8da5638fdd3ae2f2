"""Radiance RGBE read/write and lat-long lookups, for the domain suite's scenes and lights.

Dev-only: numpy, no other dependency. The reader handles flat and new-style RLE scanlines
with the `-Y H +X W` orientation that the probes of ../shared use.
"""

import numpy as np

REC709 = np.array([0.2126, 0.7152, 0.0722])


def read(path):
    """Linear RGB (H, W, 3) float32 of a Radiance .hdr file."""
    data = open(path, "rb").read()
    pos = 0
    while True:
        end = data.index(b"\n", pos)
        line = data[pos:end]
        pos = end + 1
        if line.startswith(b"-Y") or line.startswith(b"+Y"):
            parts = line.split()
            h, w = int(parts[1]), int(parts[3])
            break
    out = np.zeros((h, w, 4), dtype=np.uint8)
    for y in range(h):
        if w >= 8 and w < 32768 and data[pos] == 2 and data[pos + 1] == 2 and data[pos + 2] < 128:
            pos += 4
            for c in range(4):
                x = 0
                while x < w:
                    n = data[pos]
                    pos += 1
                    if n > 128:
                        n -= 128
                        out[y, x : x + n, c] = data[pos]
                        pos += 1
                    else:
                        out[y, x : x + n, c] = np.frombuffer(data, np.uint8, n, pos)
                        pos += n
                    x += n
        else:
            out[y] = np.frombuffer(data, np.uint8, w * 4, pos).reshape(w, 4)
            pos += w * 4
    e = out[..., 3].astype(np.int32)
    scale = np.where(e > 0, np.ldexp(1.0, e - 136), 0.0)
    rgb = out[..., :3].astype(np.float64) * scale[..., None]
    if line.startswith(b"+Y"):
        rgb = rgb[::-1]
    return rgb.astype(np.float32)


def write(path, rgb):
    """Write linear RGB (H, W, 3) as a flat (uncompressed) Radiance .hdr file."""
    rgb = np.asarray(rgb, dtype=np.float64)
    h, w, _ = rgb.shape
    peak = rgb.max(axis=2)
    mantissa, exponent = np.frexp(peak)
    scale = np.where(peak > 1e-32, mantissa * 256.0 / np.maximum(peak, 1e-300), 0.0)
    rgbe = np.zeros((h, w, 4), dtype=np.uint8)
    rgbe[..., :3] = np.clip(rgb * scale[..., None], 0, 255).astype(np.uint8)
    rgbe[..., 3] = np.where(peak > 1e-32, exponent + 128, 0).astype(np.uint8)
    header = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode()
    with open(path, "wb") as f:
        f.write(header)
        f.write(rgbe.tobytes())


def luminance(rgb):
    return rgb @ REC709


def directions(h, w):
    """Unit directions (H, W, 3) of a lat-long map's pixel centres (docs/design.md §3)."""
    theta = np.pi * (np.arange(h) + 0.5) / h
    phi = 2 * np.pi * (np.arange(w) + 0.5) / w - np.pi
    t, p = np.meshgrid(theta, phi, indexing="ij")
    return np.stack([np.sin(t) * np.sin(p), np.cos(t), -np.sin(t) * np.cos(p)], axis=-1)


def solid_angles(h, w):
    edges = np.cos(np.pi * np.arange(h + 1) / h)
    return np.repeat(((edges[:-1] - edges[1:]) * 2 * np.pi / w)[:, None], w, axis=1)


def lookup(env, d):
    """Nearest-pixel lookup of env (H, W, C) along unit directions d (..., 3)."""
    h, w = env.shape[:2]
    theta = np.arccos(np.clip(d[..., 1], -1, 1))
    phi = np.arctan2(d[..., 0], -d[..., 2])
    i = np.clip((theta / np.pi * h).astype(int), 0, h - 1)
    j = (((phi + np.pi) / (2 * np.pi) * w).astype(int)) % w
    return env[i, j]


def irradiance(env, normals, size=(16, 32)):
    """Cosine-weighted irradiance E(n) of env at unit normals (..., 3), on a reduced map."""
    h, w = env.shape[:2]
    fh, fw = h // size[0], w // size[1]
    small = env[: size[0] * fh, : size[1] * fw].reshape(size[0], fh, size[1], fw, -1).mean(axis=(1, 3))
    dirs = directions(*size).reshape(-1, 3)
    omega = solid_angles(*size).reshape(-1)
    radiance = small.reshape(-1, small.shape[-1])
    cos = np.clip(normals.reshape(-1, 3) @ dirs.T, 0, None) * omega
    return (cos @ radiance).reshape(normals.shape[:-1] + (radiance.shape[-1],))
