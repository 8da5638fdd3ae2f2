#!/usr/bin/env python3
"""Regenerate every golden fixture under tests/fixtures/ (deterministic).

    python3 scripts/reference/make_fixtures.py            # from the repository root

Writes
    tests/fixtures/pyramid/*.json        pyrtools WaveletPyramid(qmf9, reflect1) goldens
                                         (+ one reflect1-y / periodic-x golden of the reference)
    tests/fixtures/stats.json            known answers for the statistics
    tests/fixtures/features/*.{png,pfm}  synthetic sphere photographs
    tests/fixtures/features/*.json       their reference features (117 names / values)
    tests/fixtures/features/manifest.csv manifest of the images decodable with the default encoding

and asserts on the way that the reference pyramid reproduces pyrtools, that the
band powers sum to pix.var, that the circular-shift property holds, etc.
"""

import csv
import io
import json
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import reflectance_ref as R  # noqa: E402

ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
FIX = os.path.join(ROOT, "tests", "fixtures")
SEED = 20261101


def dump(path, obj):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        json.dump(obj, f, separators=(",", ":"), allow_nan=False)
        f.write("\n")


def arr_json(a):
    a = np.asarray(a, dtype=np.float64)
    return {"shape": list(a.shape), "data": [float(v) for v in a.ravel()]}


# ======================================================================= pyramids
def pyrtools_bands(img, height, edge_type):
    import pyrtools
    p = pyrtools.pyramids.WaveletPyramid(img, height=height, filter_name="qmf9", edge_type=edge_type)
    out = {}
    # (lev, 0) = corrDn(hi along axis 0, lo along axis 1) -> "h"
    # (lev, 1) = corrDn(lo along axis 0, hi along axis 1) -> "v"
    # (lev, 2) = hi along both                          -> "d"
    for lev in range(height):
        for b, o in enumerate(R.ORIENTS):
            out[(lev, o)] = p.pyr_coeffs[(lev, b)]
    out["lowpass"] = p.pyr_coeffs["residual_lowpass"]
    return out


def check_band_mapping():
    """Empirical check of the pyrtools band order, in addition to reading the source:
    an image varying only along y (horizontal stripes) has energy only in "h"
    (HI in y); one varying only along x (vertical stripes) only in "v"."""
    import pyrtools
    yy, xx = np.mgrid[0:64, 0:64].astype(float)
    horiz = np.cos(np.pi * 0.9 * yy)          # varies along y only
    vert = np.cos(np.pi * 0.9 * xx)           # varies along x only
    ph = pyrtools.pyramids.WaveletPyramid(horiz, height=1, filter_name="qmf9", edge_type="reflect1")
    pv = pyrtools.pyramids.WaveletPyramid(vert, height=1, filter_name="qmf9", edge_type="reflect1")
    e = lambda p, b: float(np.sum(p.pyr_coeffs[(0, b)] ** 2))
    # (the qmf9 HI taps sum to -7.9e-4, not 0, so "no energy" means < 1e-4 of the band's energy)
    assert e(ph, 0) > 1.0 and e(ph, 1) < 1e-4 * e(ph, 0) and e(ph, 2) < 1e-4 * e(ph, 0), "band 0 is not HI-in-y"
    assert e(pv, 1) > 1.0 and e(pv, 0) < 1e-4 * e(pv, 1) and e(pv, 2) < 1e-4 * e(pv, 1), "band 1 is not HI-in-x"
    # shapes with odd sizes: band 0 has floor(h/2) rows (HI in y), ceil(w/2) columns (LO in x)
    p = pyrtools.pyramids.WaveletPyramid(np.random.default_rng(1).standard_normal((75, 91)), height=1,
                                         filter_name="qmf9", edge_type="reflect1")
    assert p.pyr_coeffs[(0, 0)].shape == (37, 46)   # HI y, LO x
    assert p.pyr_coeffs[(0, 1)].shape == (38, 45)   # LO y, HI x
    assert p.pyr_coeffs[(0, 2)].shape == (37, 45)   # HI y, HI x
    assert p.pyr_coeffs["residual_lowpass"].shape == (38, 46)


def max_pyr_diff(a, b, height):
    err = 0.0
    for lev in range(height):
        for o in R.ORIENTS:
            x, y = a[(lev, o)], b[(lev, o)]
            assert x.shape == y.shape, (lev, o, x.shape, y.shape)
            err = max(err, float(np.abs(x - y).max()))
    assert a["lowpass"].shape == b["lowpass"].shape
    return max(err, float(np.abs(a["lowpass"] - b["lowpass"]).max()))


def ref_bands(img, height, y_mode, x_mode):
    p = R.pyramid(img, height, y_mode, x_mode)
    out = {(lev, o): p["s%d" % (lev + 1)][o] for lev in range(height) for o in R.ORIENTS}
    out["lowpass"] = p["lowpass"]
    return out


def pyramid_json(img, height, bands, edge_y, edge_x, source):
    return {
        "source": source,
        "filter": "qmf9",
        "edge_type_y": edge_y,
        "edge_type_x": edge_x,
        "input": arr_json(img),
        "height": height,
        "bands": [dict(level=lev, band=o, **arr_json(bands[(lev, o)]))
                  for lev in range(height) for o in R.ORIENTS],
        "lowpass": arr_json(bands["lowpass"]),
    }


def make_pyramids(rng):
    check_band_mapping()
    d = os.path.join(FIX, "pyramid")
    os.makedirs(d, exist_ok=True)

    # inputs rounded to 6 decimals: exact decimal inputs, short JSON
    random = np.round(rng.standard_normal((40, 56)), 6)
    yy, xx = np.mgrid[0:80, 0:96].astype(float)
    smooth = (np.sin(2 * np.pi * xx / 37.0 + 0.3) * np.cos(2 * np.pi * yy / 23.0)
              + 0.5 * np.exp(-((xx - 60) ** 2 + (yy - 30) ** 2) / 200.0)
              + 0.05 * rng.standard_normal((80, 96)))
    smooth = np.round(smooth, 6)
    yy, xx = np.mgrid[0:75, 0:90].astype(float)
    odd = np.round(np.cos(xx * 0.31) * np.sin(yy * 0.17) + 0.3 * rng.standard_normal((75, 90)), 6)

    cases = [("random_40x56_h3", random, 3), ("smooth_80x96_h4", smooth, 4), ("odd_75x90_h3", odd, 3)]
    for name, img, height in cases:
        gold = pyrtools_bands(img, height, "reflect1")
        mine = ref_bands(img, height, "reflect", "reflect")
        err = max_pyr_diff(gold, mine, height)
        assert err < 1e-12, (name, err)
        # the periodic extension of the reference against pyrtools 'circular'
        err_c = max_pyr_diff(pyrtools_bands(img, height, "circular"), ref_bands(img, height, "wrap", "wrap"), height)
        assert err_c < 1e-12, (name, "circular", err_c)
        print("pyramid %-18s reference vs pyrtools: reflect1 %.2e, circular %.2e" % (name, err, err_c))
        dump(os.path.join(d, name + ".json"), pyramid_json(img, height, gold, "reflect1", "reflect1", "pyrtools 1.1.1 WaveletPyramid"))

    # the feature pyramid: reflect1 in y, periodic in x.  Cross-check against pyrtools
    # reflect1 on the image tiled 3x along x (the middle third is unaffected by the x borders).
    mixed = np.round(rng.standard_normal((40, 64)) + np.cos(np.arange(64) * 2 * np.pi / 64 * 3)[None, :], 6)
    for img, height in [(mixed, 3), (rng.standard_normal((96, 448)), 4)]:
        w = img.shape[1]
        tiled = pyrtools_bands(np.tile(img, (1, 3)), height, "reflect1")
        mine = ref_bands(img, height, "reflect", "wrap")
        err = 0.0
        for key, v in mine.items():
            lev = height - 1 if key == "lowpass" else key[0]
            step = 2 ** (lev + 1)
            mid = tiled[key][:, w // step: 2 * w // step]
            assert mid.shape == v.shape, (key, mid.shape, v.shape)
            err = max(err, float(np.abs(mid - v).max()))
        assert err < 1e-12, err
        print("pyramid mixed %s reference vs pyrtools-on-tiled: %.2e" % (img.shape, err))
    dump(os.path.join(d, "mixed_40x64_h3.json"),
         pyramid_json(mixed, 3, ref_bands(mixed, 3, "reflect", "wrap"), "reflect1", "circular",
                      "reference (reflect1 along y, periodic along x), checked against pyrtools on the x-tiled image"))


# ======================================================================= statistics
def make_stats(rng):
    cases = [
        ("constant", [2.5] * 5),
        ("zeros", [0.0, 0.0, 0.0]),
        ("single", [3.7]),
        ("two", [1.0, 4.0]),
        ("eleven", [3.1, -0.4, 7.25, 0.0, 2.2, 9.9, -3.3, 1.1, 4.4, 0.5, 6.0]),
        ("interp4", [10.0, 0.0, 3.0, 7.0]),
        ("interp7", [5.0, 1.0, 4.0, 1.5, 9.0, 2.6, 5.3]),
        ("near_constant", [1000000.0, 1000000.0000001, 1000000.0, 1000000.0]),
        ("exp50", [float(v) for v in np.round(rng.exponential(2.0, 50), 4)]),
    ]
    out = []
    for name, x in cases:
        st = R.stats(x)
        out.append(dict(name=name, x=[float(v) for v in x], **st))
    # hand checks of a few of them
    by = {c["name"]: c for c in out}
    assert by["constant"]["skew"] == 0.0 and by["constant"]["kurt"] == 3.0 and by["constant"]["var"] == 0.0
    assert by["near_constant"]["kurt"] == 3.0 and by["near_constant"]["var"] > 0.0
    assert by["two"]["var"] == 2.25 and by["two"]["kurt"] == 1.0 and by["two"]["skew"] == 0.0
    assert abs(by["two"]["p10"] - 1.3) < 1e-15 and abs(by["two"]["p90"] - 3.7) < 1e-15
    assert abs(by["interp4"]["p10"] - 0.9) < 1e-15 and by["interp4"]["p50"] == 5.0
    assert abs(by["interp4"]["p90"] - 9.1) < 1e-14
    assert by["single"]["p10"] == 3.7 and by["single"]["kurt"] == 3.0
    dump(os.path.join(FIX, "stats.json"), {
        "description": "population moments (two-pass), skew m3/m2^1.5, kurt m4/m2^2 (constant rule: "
                       "min==max or m2 <= (1e-12*max|x|)^2 -> skew 0, kurt 3), percentiles numpy 'linear' "
                       "(h=(N-1)p/100). Raw values, no log10.",
        "cases": out})


# ======================================================================= spheres
def sh_basis(d):
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([np.ones_like(x), x, y, z, x * y, y * z, x * z, x * x - y * y, 3 * z * z - 1], -1)


def random_unit(rng, n):
    v = rng.standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


class Environment:
    """A random smooth environment: low-order spherical harmonics + light blobs +
    a multi-scale sinusoidal texture, with per-channel tints."""

    def __init__(self, rng, channels):
        self.channels = channels
        self.sh = 0.1 * rng.standard_normal((channels, 9))
        self.sh[:, 0] = 0.35
        nb = 4
        self.bc = random_unit(rng, nb)
        self.bc[0] = [0.3, 0.6, 0.74]                    # one light roughly towards the viewer
        self.bc[0] /= np.linalg.norm(self.bc[0])
        self.bw = rng.uniform(0.12, 0.45, nb)
        self.ba = rng.uniform(0.4, 1.6, (channels, nb))
        nt = 8
        self.tu = random_unit(rng, nt)
        self.tf = np.exp(rng.uniform(np.log(4.0), np.log(70.0), nt))
        self.tp = rng.uniform(0, 2 * np.pi, nt)
        self.ta = 0.06 * rng.uniform(0.5, 1.0, (channels, nt))

    def low(self, d):
        return np.einsum("...k,ck->...c", sh_basis(d), self.sh)

    def __call__(self, d):
        out = self.low(d)
        blobs = np.exp((d @ self.bc.T - 1.0) / self.bw ** 2)          # (..., nb)
        out = out + np.einsum("...b,cb->...c", blobs, self.ba)
        tex = np.sin((d @ self.tu.T) * self.tf + self.tp)             # (..., nt)
        out = out + np.einsum("...t,ct->...c", tex, self.ta)
        return out


def sphere_image(rng, w, h, cx, cy, r, channels, peak, background, clip):
    """Linear radiance (h, w, channels) of a shiny sphere + the disc mask."""
    env = Environment(rng, channels)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    nx = (xx - cx) / r
    ny = -(yy - cy) / r
    q = nx * nx + ny * ny
    inside = q < 1.0
    nz = np.sqrt(np.clip(1.0 - q, 0.0, None))
    n = np.stack([nx, ny, nz], -1)
    refl = np.stack([2 * nz * nx, 2 * nz * ny, 2 * nz * nz - 1.0], -1)  # mirror of the view (0,0,1)
    rad = 0.6 * env(refl) + 0.4 * env.low(n) * (0.5 + 0.5 * nz)[..., None]
    rad = np.clip(rad, 0.0, None)
    # fine surface texture / sensor noise, so that the finest subbands are not trivial
    rad = rad * (1.0 + 0.04 * rng.standard_normal(rad.shape))
    rad = np.clip(rad, 0.0, None)
    scale = peak / np.percentile(rad[inside], 99.5)
    rad = rad * scale
    if clip:
        rad = np.clip(rad, 0.0, 1.0)
    rad[~inside] = background
    return rad, inside


def encode(lin, encoding):
    if encoding == "srgb":
        return np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    if encoding == "linear":
        return lin
    if encoding.startswith("gamma:"):
        return lin ** (1.0 / float(encoding[6:]))
    raise ValueError(encoding)


def write_png(path, ints, bits, alpha=None):
    import png
    h, w, c = ints.shape
    if alpha is not None:
        ints = np.concatenate([ints, alpha[..., None].astype(ints.dtype)], -1)
    planes = ints.shape[2]
    wr = png.Writer(width=w, height=h, greyscale=(c == 1), alpha=alpha is not None, bitdepth=bits,
                    compression=9)
    with open(path, "wb") as f:
        wr.write(f, ints.reshape(h, w * planes).astype(np.uint16 if bits == 16 else np.uint8).tolist())


def write_pfm(path, lin, little_endian, scale_magnitude=1.0):
    h, w, c = lin.shape
    kind = b"PF" if c == 3 else b"Pf"
    scale = -scale_magnitude if little_endian else scale_magnitude
    data = np.ascontiguousarray(lin[::-1].astype("<f4" if little_endian else ">f4"))  # bottom-up
    with open(path, "wb") as f:
        f.write(kind + b"\n%d %d\n%s\n" % (w, h, repr(float(scale)).encode()))
        f.write(data.tobytes())


# name, kind, channels, bits, alpha, w, h, cx, cy, r, white, encoding, class, illumination
SPHERES = [
    ("sphere_gray8", "png", 1, 8, False, 106, 99, 52.35, 48.7, 40.3, 1.0, "srgb", "shiny", "env1"),
    ("sphere_rgb8", "png", 3, 8, False, 196, 191, 96.5, 94.25, 85.0, 0.8, "srgb", "matte", "env2"),
    ("sphere_rgba8", "png", 3, 8, True, 124, 118, 61.2, 58.9, 50.5, 2.5, "linear", "shiny", "env3"),
    ("sphere_gray16", "png", 1, 16, False, 262, 258, 131.75, 128.4, 120.0, 1.7, "srgb", "chrome", "env1"),
    ("sphere_rgb16", "png", 3, 16, False, 142, 140, 71.0, 69.6, 60.25, 0.8, "gamma:2.2", "matte", "env3"),
    ("sphere_rgb_le", "pfm", 3, None, False, 161, 158, 80.3, 79.8, 70.0, 2.5, "linear", "chrome", "env2"),
    ("sphere_gray_be", "pfm", 1, None, False, 362, 360, 181.6, 180.2, 170.4, 1.0, "linear", "shiny", "env2"),
    # circle partly outside the frame: exercises the index clamping of the bilinear sampler
    ("sphere_clamp8", "png", 1, 8, False, 90, 100, 30.4, 52.6, 45.0, 1.0, "srgb", "matte", "env1"),
]

PROBES = [(0, 0), (0, 447), (17, 101), (48, 224), (60, 333), (95, 0), (95, 447)]


def make_spheres(rng):
    d = os.path.join(FIX, "features")
    os.makedirs(d, exist_ok=True)
    manifest = []
    summary = []
    for (name, kind, ch, bits, alpha, w, h, cx, cy, r, white, enc, cls, illum) in SPHERES:
        if kind == "png":
            lin, inside = sphere_image(rng, w, h, cx, cy, r, ch, peak=0.92, background=0.004, clip=True)
            maxv = 2 ** bits - 1
            ints = np.rint(encode(lin, enc) * maxv).astype(np.int64)
            fname = name + ".png"
            write_png(os.path.join(d, fname), ints, bits, (inside * 255).astype(np.int64) if alpha else None)
        else:
            lin, inside = sphere_image(rng, w, h, cx, cy, r, ch, peak=4.0, background=0.0, clip=False)
            fname = name + ".pfm"
            write_pfm(os.path.join(d, fname), lin, little_endian=name.endswith("_le"),
                      scale_magnitude=1.0 if name.endswith("_le") else 2.0)
        path = os.path.join(d, fname)
        lum = R.decode_image(path, None if kind == "pfm" else enc)
        assert lum.shape == (h, w)
        names, values = R.features(lum, cx, cy, r, white)
        u = R.unwrap(lum / white, cx, cy, r)
        check_features(names, values, u, name)
        s = R.supersampling(r)
        dump(os.path.join(d, name + ".json"), {
            "image": fname, "cx": cx, "cy": cy, "r": r, "s": s, "white": white, "encoding": enc,
            "image_size": [w, h],
            "unwrap_probe": {"ij": [list(p) for p in PROBES], "values": [float(u[i, j]) for i, j in PROBES]},
            "names": names, "values": values})
        if kind == "pfm" or enc == "srgb":
            manifest.append((fname, cls, illum, cx, cy, r, white))
        summary.append((fname, cx, cy, r, s, white, enc))
        print("features %-20s r=%-6g s=%d white=%-4g %-9s pix.mean=%.4f s1.v.var=%.3f s4.d.var=%.3f"
              % (fname, r, s, white, enc, values[0], values[names.index("wav.s1.v.var")],
                 values[names.index("wav.s4.d.var")]))
    with open(os.path.join(d, "manifest.csv"), "w", newline="") as f:
        wr = csv.writer(f, lineterminator="\n")
        wr.writerow(["path", "class", "illumination", "cx", "cy", "r", "white"])
        for row in manifest:
            wr.writerow([row[0], row[1], row[2]] + [repr(float(v)) for v in row[3:]])
    return summary


def check_features(names, values, u, label):
    assert len(names) == 117 and len(set(names)) == 117, label
    assert names == R.feature_names()
    assert all(math.isfinite(v) for v in values), label
    # band powers (before the log) sum to pix.var: all non-DC bins are in exactly one band
    bp = R.band_powers(u)
    masks = R.band_masks(*u.shape)
    cover = sum(m.astype(int) for m in masks.values())
    assert cover[0, 0] == 0 and (cover.ravel()[1:] == 1).all(), label
    var = R.stats(u)["var"]
    tot = sum(bp.values())
    assert abs(tot - var) <= 1e-12 * var, (label, tot, var)
    # every subband non-trivial
    pyr = R.pyramid(u)
    for k in range(1, 5):
        for o in R.ORIENTS:
            assert R.stats(pyr["s%d" % k][o])["var"] > 1e-10, (label, k, o)
    # circular shift: rolling u by 16 columns rolls level-k subbands by 16 / 2^k columns
    pyr2 = R.pyramid(np.roll(u, 16, axis=1))
    for k in range(1, 5):
        for o in R.ORIENTS:
            a = np.roll(pyr["s%d" % k][o], 16 // 2 ** k, axis=1)
            b = pyr2["s%d" % k][o]
            assert np.allclose(a, b, rtol=0, atol=1e-12 * np.abs(a).max()), (label, k, o)
    # ... and leaves the pixel statistics and band powers unchanged
    n2, v2 = R.features_from_unwrapped(np.roll(u, 16, axis=1))
    for nm, x, y in zip(names, values, v2):
        if nm.startswith("pix.") or nm.startswith("fft.") or nm.startswith("wav.") or nm.startswith("ratio."):
            assert abs(x - y) <= 1e-9 * max(1.0, abs(x)), (label, nm, x, y)


def main():
    rng = np.random.default_rng(SEED)
    make_pyramids(rng)
    make_stats(rng)
    summary = make_spheres(rng)
    total = 0
    for dp, _, fs in os.walk(FIX):
        for f in fs:
            total += os.path.getsize(os.path.join(dp, f))
    print("fixtures: %d files, %.2f MB" % (sum(len(fs) for _, _, fs in os.walk(FIX)), total / 1e6))
    print("image,cx,cy,r,s,white,encoding")
    for row in summary:
        print(",".join(str(v) for v in row))


if __name__ == "__main__":
    main()
