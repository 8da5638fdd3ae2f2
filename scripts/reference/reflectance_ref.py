#!/usr/bin/env python3
"""Independent float64 numpy reference for the feature extraction of docs/design.md §3.

Dev-only: used to generate golden fixtures under tests/fixtures/.  It is written
from the specification (docs/design.md §3 "Numeric conventions"), not from the Rust
code.  Every interpretation choice is marked with "CHOICE:" in a comment and is
listed in README.md.

Public functions
    decode_image(path, encoding=None)   -> 2-D float64 luminance (linear)
    unwrap(lum, cx, cy, r)              -> (96, 448) float64
    pyramid(u, levels=4, y_mode="reflect", x_mode="wrap") -> dict
    stats(x)                            -> dict mean,var,skew,kurt,p10,p50,p90
    band_powers(u)                      -> dict (17 entries, canonical order)
    feature_names()                     -> list of the 117 names
    features(lum, cx, cy, r, white=1.0) -> (names, values)

CLI
    python3 reflectance_ref.py IMAGE --cx X --cy Y --r R [--white W] [--encoding E]
prints {"names": [...], "values": [...]} (floats in repr precision).
"""

import argparse
import json
import math
import sys

import numpy as np

# ---------------------------------------------------------------- constants
H = 96            # rows of the unwrapped grid (radius)
W = 448           # columns (angle)
RHO_IN = 0.2      # inner radius of the annulus, in units of r
RHO_OUT = 0.9     # outer radius
R0 = 80.0         # s = max(1, ceil(r / R0))
LEVELS = 4

LO = np.array([0.02807382, -0.060944743, -0.073386624, 0.41472545, 0.7973934,
               0.41472545, -0.073386624, -0.060944743, 0.02807382], dtype=np.float64)
# HI[k] = LO[8-k] * (-1)^(4-k)
HI = np.array([LO[8 - k] * (-1.0) ** (4 - k) for k in range(9)], dtype=np.float64)

ORIENTS = ("h", "v", "d")
STATS = ("mean", "var", "skew", "kurt", "p10", "p50", "p90")
ANGLES = (0, 45, 90, 135)
LOG_FLOOR = 1e-30


# ---------------------------------------------------------------- decoding
def _srgb_to_linear(c):
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def apply_encoding(c, encoding):
    """c: float64 array of values in [0, 1] (v / (2^bits - 1))."""
    enc = (encoding or "srgb").strip().lower()
    if enc == "srgb":
        return _srgb_to_linear(c)
    if enc == "linear":
        return c
    if enc.startswith("gamma:"):
        g = float(enc[len("gamma:"):])
        return c ** g
    raise ValueError("unknown encoding %r" % encoding)


def luminance(chans):
    """chans: (h, w, n) float64 linear values; n = 1,2 (gray[+alpha]) or 3,4 (RGB[A]).
    Alpha is never used as a value."""
    n = chans.shape[2]
    if n in (1, 2):
        return chans[:, :, 0].copy()
    if n in (3, 4):
        return 0.2126 * chans[:, :, 0] + 0.7152 * chans[:, :, 1] + 0.0722 * chans[:, :, 2]
    raise ValueError("unsupported channel count %d" % n)


def read_pfm(path):
    """Returns (h, w, n) float64 array (top row first), n = 3 ('PF') or 1 ('Pf').
    Rows are stored bottom-up; negative scale = little endian, positive = big
    endian; the scale's magnitude is ignored."""
    with open(path, "rb") as f:
        data = f.read()
    # header: three whitespace-separated tokens ("PF"/"Pf", "W H", scale),
    # the raster starts after the single whitespace byte following the scale.
    pos = 0
    tokens = []
    while len(tokens) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        start = pos
        while not data[pos:pos + 1].isspace():
            pos += 1
        tokens.append(data[start:pos].decode("ascii"))
    pos += 1  # the single whitespace byte ending the header
    kind, w, h, scale = tokens[0], int(tokens[1]), int(tokens[2]), float(tokens[3])
    if kind == "PF":
        n = 3
    elif kind == "Pf":
        n = 1
    else:
        raise ValueError("not a PFM file")
    dtype = "<f4" if scale < 0 else ">f4"
    arr = np.frombuffer(data, dtype=dtype, count=w * h * n, offset=pos)
    arr = arr.reshape(h, w, n)[::-1]  # bottom-up -> top row first
    return arr.astype(np.float64)


def _read_png_ints(path):
    """Exact integer samples of a PNG: returns (h, w, n) int64 array and bit depth.
    Palette images are expanded to RGB(A) 8-bit.  sBIT / gAMA / iCCP / tRNS are
    ignored (colour metadata is ignored; alpha is a mask)."""
    import png  # pypng
    reader = png.Reader(filename=path)
    w, h, rows, info = reader.read()
    rows = [np.asarray(row, dtype=np.int64) for row in rows]
    a = np.vstack(rows) if rows else np.zeros((0, 0), dtype=np.int64)
    if info.get("palette"):
        pal = np.asarray(info["palette"], dtype=np.int64)  # (ncolours, 3 or 4)
        a = pal[a.reshape(h, w)]
        return a, 8
    planes = info["planes"]
    return a.reshape(h, w, planes), info["bitdepth"]


def _exif_orientation(path):
    try:
        from PIL import Image
        with Image.open(path) as im:
            return int(im.getexif().get(0x0112, 1) or 1)
    except Exception:
        return 1


def _orient(a, o):
    """Apply EXIF orientation o to a 2-D array (as Pillow's exif_transpose)."""
    if o == 2:
        return a[:, ::-1]
    if o == 3:
        return a[::-1, ::-1]
    if o == 4:
        return a[::-1, :]
    if o == 5:
        return a.T
    if o == 6:
        return np.rot90(a, -1)
    if o == 7:
        return a[::-1, ::-1].T
    if o == 8:
        return np.rot90(a, 1)
    return a


def decode_image(path, encoding=None):
    """Linear luminance (float64, 2-D, row 0 = top) of an image file.
    encoding: None (= "srgb" for integer images), "srgb", "linear" or "gamma:<g>";
    ignored (with a warning on stderr when given) for float images (PFM)."""
    with open(path, "rb") as f:
        magic = f.read(8)
    if magic[:2] in (b"PF", b"Pf"):
        if encoding is not None:
            print("warning: encoding %r ignored for a float image" % encoding, file=sys.stderr)
        return np.ascontiguousarray(luminance(read_pfm(path)))
    if magic == b"\x89PNG\r\n\x1a\n":
        ints, bits = _read_png_ints(path)
        c = ints.astype(np.float64) / float(2 ** bits - 1)
        lum = luminance(apply_encoding(c, encoding))
        return np.ascontiguousarray(_orient(lum, _exif_orientation(path)))
    # fallback (not used by the fixtures): 8-bit images through Pillow
    from PIL import Image
    with Image.open(path) as im:
        o = int(im.getexif().get(0x0112, 1) or 1)
        if im.mode == "P":
            im = im.convert("RGBA" if "transparency" in im.info else "RGB")
        if im.mode not in ("L", "LA", "RGB", "RGBA"):
            raise ValueError("unsupported mode %s" % im.mode)
        a = np.asarray(im, dtype=np.float64)
    if a.ndim == 2:
        a = a[:, :, None]
    lum = luminance(apply_encoding(a / 255.0, encoding))
    return np.ascontiguousarray(_orient(lum, o))


# ---------------------------------------------------------------- unwrap
def supersampling(r):
    return max(1, int(math.ceil(r / R0)))


def unwrap(lum, cx, cy, r):
    """Canonical unwrap of the annulus [0.2 r, 0.9 r] into an H x W grid."""
    lum = np.asarray(lum, dtype=np.float64)
    ih, iw = lum.shape
    s = supersampling(r)
    i = np.arange(H, dtype=np.float64)
    j = np.arange(W, dtype=np.float64)
    off = (np.arange(s, dtype=np.float64) + 0.5) / s          # (a + 0.5)/s
    # rho[i, a], theta[j, b] exactly as the spec writes them
    rho = r * (RHO_IN + (RHO_OUT - RHO_IN) * (i[:, None] + off[None, :]) / H)
    theta = 2.0 * np.pi * (j[:, None] + off[None, :]) / W
    # sample positions, shape (H, s, W, s) = (i, a, j, b)
    rr = rho[:, :, None, None]
    x = cx + rr * np.cos(theta)[None, None, :, :]
    y = cy - rr * np.sin(theta)[None, None, :, :]
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = x - x0
    fy = y - y0
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    # clamp the indices AFTER the weights are taken
    x0c = np.clip(x0, 0, iw - 1)
    x1c = np.clip(x0 + 1, 0, iw - 1)
    y0c = np.clip(y0, 0, ih - 1)
    y1c = np.clip(y0 + 1, 0, ih - 1)
    top = lum[y0c, x0c] * (1.0 - fx) + lum[y0c, x1c] * fx
    bot = lum[y1c, x0c] * (1.0 - fx) + lum[y1c, x1c] * fx
    val = top * (1.0 - fy) + bot * fy
    return val.sum(axis=(1, 3)) / float(s * s)


# ---------------------------------------------------------------- pyramid
def corr_dn(x, f, start, axis, mode):
    """corrDn(x, f, start)[m] = sum_k f[k] * xe[start + 2m + k - 4] along `axis`,
    m = 0 .. len(range(start, n, 2)) - 1; xe = x extended by numpy.pad(mode)
    ('reflect' = reflect1, 'wrap' = periodic)."""
    x = np.moveaxis(np.asarray(x, dtype=np.float64), axis, 0)
    n = x.shape[0]
    pad = [(4, 4)] + [(0, 0)] * (x.ndim - 1)
    xe = np.pad(x, pad, mode=mode)            # xe[p] = x_ext[p - 4]
    nout = len(range(start, n, 2))
    out = np.zeros((nout,) + x.shape[1:], dtype=np.float64)
    for k in range(9):
        # x_ext[start + 2m + k - 4] = xe[start + 2m + k]
        out += f[k] * xe[start + k: start + k + 2 * (nout - 1) + 1: 2]
    return np.moveaxis(out, 0, axis)


def pyramid(u, levels=LEVELS, y_mode="reflect", x_mode="wrap"):
    """QMF (qmf9) wavelet pyramid.  Returns {"s1": {"h","v","d"}, ..., "lowpass": array}.
    s1 is the finest level.  Filtering along axis 0 (y) first, then axis 1 (x)."""
    out = {}
    im = np.asarray(u, dtype=np.float64)
    for lev in range(levels):
        lo_y = corr_dn(im, LO, 0, 0, y_mode)
        hi_y = corr_dn(im, HI, 1, 0, y_mode)
        out["s%d" % (lev + 1)] = {
            "h": corr_dn(hi_y, LO, 0, 1, x_mode),   # HI in y, LO in x
            "v": corr_dn(lo_y, HI, 1, 1, x_mode),   # LO in y, HI in x
            "d": corr_dn(hi_y, HI, 1, 1, x_mode),   # HI in both
        }
        im = corr_dn(lo_y, LO, 0, 1, x_mode)
    out["lowpass"] = im
    return out


# ---------------------------------------------------------------- statistics
def stats(x):
    x = np.asarray(x, dtype=np.float64).ravel()
    n = x.size
    mean = x.sum() / n
    d = x - mean
    m2 = (d * d).sum() / n
    m3 = (d * d * d).sum() / n
    m4 = ((d * d) * (d * d)).sum() / n
    amax = np.abs(x).max()
    if x.min() == x.max() or m2 <= (1e-12 * amax) ** 2:
        skew, kurt = 0.0, 3.0
    else:
        skew = m3 / m2 ** 1.5
        kurt = m4 / (m2 * m2)
    p10, p50, p90 = np.percentile(x, [10.0, 50.0, 90.0])  # numpy default 'linear'
    return {"mean": float(mean), "var": float(m2), "skew": float(skew), "kurt": float(kurt),
            "p10": float(p10), "p50": float(p50), "p90": float(p90)}


# ---------------------------------------------------------------- band powers
def band_masks(h, w):
    fy = np.fft.fftfreq(h)[:, None]
    fx = np.fft.fftfreq(w)[None, :]
    rho2 = fx * fx + fy * fy
    ang = np.mod(np.degrees(np.arctan2(fy, fx)), 180.0)   # floored modulo, in [0, 180]
    orient = {
        0: (ang < 22.5) | (ang >= 157.5),
        45: (ang >= 22.5) & (ang < 67.5),
        90: (ang >= 67.5) & (ang < 112.5),
        135: (ang >= 112.5) & (ang < 157.5),
    }
    radial = {
        1: rho2 >= 1.0 / 16,
        2: (rho2 >= 1.0 / 64) & (rho2 < 1.0 / 16),
        3: (rho2 >= 1.0 / 256) & (rho2 < 1.0 / 64),
        4: (rho2 >= 1.0 / 1024) & (rho2 < 1.0 / 256),
    }
    masks = {}
    for b in (1, 2, 3, 4):
        for a in ANGLES:
            masks["b%d.f%d" % (b, a)] = radial[b] & orient[a]
    masks["lo"] = (rho2 > 0) & (rho2 < 1.0 / 1024)
    return masks


def power_spectrum(u):
    u = np.asarray(u, dtype=np.float64)
    h, w = u.shape
    F = np.fft.fft2(u - u.mean())
    return (F.real ** 2 + F.imag ** 2) / float(h * w) ** 2


def band_powers(u):
    P = power_spectrum(u)
    masks = band_masks(*P.shape)
    return {k: float(P[m].sum()) for k, m in masks.items()}


# ---------------------------------------------------------------- features
def feature_names(levels=LEVELS):
    names = ["pix." + s for s in STATS]
    for k in range(1, levels + 1):
        for o in ORIENTS:
            for s in STATS:
                names.append("wav.s%d.%s.%s" % (k, o, s))
    for o in ORIENTS:
        for k in range(1, levels):
            names.append("ratio.%s.s%d_s%d" % (o, k, k + 1))
    for b in (1, 2, 3, 4):
        for a in ANGLES:
            names.append("fft.b%d.f%d.pow" % (b, a))
    names.append("fft.lo.pow")
    return names


def _log(v):
    return math.log10(max(v, LOG_FLOOR))


def features_from_unwrapped(u, levels=LEVELS):
    raw = {}
    for s, v in stats(u).items():
        raw["pix." + s] = v
    pyr = pyramid(u, levels)
    for k in range(1, levels + 1):
        for o in ORIENTS:
            for s, v in stats(pyr["s%d" % k][o]).items():
                raw["wav.s%d.%s.%s" % (k, o, s)] = v
    bp = band_powers(u)
    names = feature_names(levels)
    values = []
    for nm in names:
        if nm.startswith("ratio."):
            _, o, ks = nm.split(".")
            k1, k2 = ks.split("_")
            v = _log(raw["wav.%s.%s.var" % (k1, o)]) - _log(raw["wav.%s.%s.var" % (k2, o)])
        elif nm.startswith("fft."):
            key = nm[len("fft."):-len(".pow")]
            v = _log(bp[key])
        else:
            v = raw[nm]
            if nm.endswith(".var") or nm.endswith(".kurt"):
                v = _log(v)
        values.append(float(v))
    return names, values


def features(lum, cx, cy, r, white=1.0):
    lum = np.asarray(lum, dtype=np.float64) / float(white)
    u = unwrap(lum, cx, cy, r)
    return features_from_unwrapped(u)


# ---------------------------------------------------------------- CLI
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("image")
    ap.add_argument("--cx", type=float, required=True)
    ap.add_argument("--cy", type=float, required=True)
    ap.add_argument("--r", type=float, required=True)
    ap.add_argument("--white", type=float, default=1.0)
    ap.add_argument("--encoding", default=None)
    a = ap.parse_args(argv)
    lum = decode_image(a.image, a.encoding)
    names, values = features(lum, a.cx, a.cy, a.r, a.white)
    json.dump({"names": names, "values": values}, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
