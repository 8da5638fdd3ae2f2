#!/usr/bin/env python3
"""Extra cross-checks of the reference against naive / third-party implementations
(run after make_fixtures.py; needs scipy and Pillow):
  * vectorized unwrap vs a scalar loop written from the spec formulas
  * decode vs Pillow (8-bit, 16-bit gray)
  * stats vs scipy.stats (skew, Pearson kurtosis) and numpy.var
  * band powers vs a per-bin loop with exact rational radial thresholds
  * the CLI output equals the stored fixture values
"""
import json
import math
import os
import subprocess
import sys
from fractions import Fraction as Fr

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import reflectance_ref as R  # noqa: E402

F = os.path.join(HERE, "..", "..", "tests", "fixtures", "features")


def unwrap_scalar(I, cx, cy, r, rows):
    h, w = I.shape
    s = max(1, math.ceil(r / 80))
    cl = lambda v, n: min(max(v, 0), n - 1)
    out = {}
    for i in rows:
        for j in range(448):
            acc = 0.0
            for a in range(s):
                for b in range(s):
                    rho = r * (0.2 + 0.7 * (i + (a + 0.5) / s) / 96)
                    th = 2 * math.pi * (j + (b + 0.5) / s) / 448
                    x = cx + rho * math.cos(th)
                    y = cy - rho * math.sin(th)
                    x0, y0 = math.floor(x), math.floor(y)
                    fx, fy = x - x0, y - y0
                    X0, X1, Y0, Y1 = cl(x0, w), cl(x0 + 1, w), cl(y0, h), cl(y0 + 1, h)
                    acc += (1 - fy) * ((1 - fx) * I[Y0, X0] + fx * I[Y0, X1]) + fy * ((1 - fx) * I[Y1, X0] + fx * I[Y1, X1])
            out[i, j] = acc / (s * s)
    return out


def band_powers_loop(u):
    P = R.power_spectrum(u)
    H, W = u.shape
    acc = {}
    for i in range(H):
        ky = i if i < H / 2 else i - H
        for j in range(W):
            kx = j if j < W / 2 else j - W
            r2 = Fr(ky, H) ** 2 + Fr(kx, W) ** 2
            if r2 == 0:
                continue
            b = "b1" if r2 >= Fr(1, 16) else "b2" if r2 >= Fr(1, 64) else "b3" if r2 >= Fr(1, 256) \
                else "b4" if r2 >= Fr(1, 1024) else "lo"
            if b != "lo":
                ang = math.degrees(math.atan2(ky / H, kx / W)) % 180
                o = 0 if (ang < 22.5 or ang >= 157.5) else 45 if ang < 67.5 else 90 if ang < 112.5 else 135
                b += ".f%d" % o
            acc[b] = acc.get(b, 0.0) + P[i, j]
    return acc


def main():
    import scipy.stats as ss
    from PIL import Image
    for fn in sorted(os.listdir(F)):
        if not fn.endswith(".json"):
            continue
        d = json.load(open(os.path.join(F, fn)))
        img = os.path.join(F, d["image"])
        pfm = img.endswith(".pfm")
        L = R.decode_image(img, None if pfm else d["encoding"]) / d["white"]
        u = R.unwrap(L, d["cx"], d["cy"], d["r"])
        o = unwrap_scalar(L, d["cx"], d["cy"], d["r"], [0, 33, 95])
        e_u = max(abs(u[k] - v) for k, v in o.items())
        bp, bl = R.band_powers(u), band_powers_loop(u)
        e_b = max(abs(bp[k] - bl[k]) / bp[k] for k in bp)
        args = [sys.executable, os.path.join(HERE, "reflectance_ref.py"), img, "--cx", repr(d["cx"]),
                "--cy", repr(d["cy"]), "--r", repr(d["r"]), "--white", repr(d["white"])]
        if not pfm:
            args += ["--encoding", d["encoding"]]
        c = json.loads(subprocess.check_output(args))
        same = c["values"] == d["values"] and c["names"] == d["names"]
        print("%-22s unwrap vs scalar %.1e  band powers vs loop %.1e  CLI==fixture %s" % (fn, e_u, e_b, same))
        assert e_u < 1e-13 and e_b < 1e-12 and same
        # (Pillow reduces 16-bit RGB PNGs to 8 bits, so that one is not compared)
        if not pfm and not (Image.open(img).mode == "RGB" and R._read_png_ints(img)[1] == 16):
            im = Image.open(img)
            a = np.asarray(im).astype(float) / (65535.0 if im.mode == "I;16" else 255.0)
            a = R.apply_encoding(a, d["encoding"])
            ref = a if a.ndim == 2 else 0.2126 * a[..., 0] + 0.7152 * a[..., 1] + 0.0722 * a[..., 2]
            e = np.abs(ref / d["white"] - L).max()
            print("    decode vs Pillow (%s) %.1e" % (im.mode, e))
            assert e < 1e-15
    rng = np.random.default_rng(5)
    for x in [rng.standard_normal(1000), rng.exponential(size=37)]:
        s = R.stats(x)
        e = max(abs(s["var"] - np.var(x)), abs(s["skew"] - ss.skew(x)), abs(s["kurt"] - ss.kurtosis(x, fisher=False)))
        print("stats vs numpy/scipy %.1e" % e)
        assert e < 1e-12
    print("selfcheck OK")


if __name__ == "__main__":
    main()
