#!/usr/bin/env python3
"""The out-of-domain suite: inputs that are not a sphere under natural light, each with a
plausible circle (and white), for measuring the domain check (docs/accuracy.md,
"Honest answers").

    python3 scripts/domain/make_suite.py --probes ../shared/data/probes \
        --spheres data/test_6 --out data/ood

writes DIR/<kind>/*.png|jpg and DIR/manifest.csv (path,class,illumination,cx,cy,r,white;
`class` is the kind, `illumination` the source), and DIR/lights/*.hdr with DIR/lights.txt:
light probes of one small source in the dark, to render spheres under
(`reflectance render --probes DIR/lights.txt …`).

Kinds:
  photo       sample photographs of other things (scikit-image, scikit-learn, matplotlib)
  scene       perspective views of the light probes, exposed as a camera would
  pattern     synthetic patterns (rectangles, checkerboards, stripes, noise, text-like blocks)
  object      other objects than spheres (cube, cylinder, torus, disc, ellipsoid, cone),
              ray-traced mirror, matte and glossy under the probes
  moved       a sphere's capture with the circle moved by 0.6 r
  large       … with the circle 1.5 times too large
  small       … with the circle 0.6 times too small
  dark_white  … with the white 20 times too small

Dev-only (numpy, Pillow, scikit-image, scikit-learn, matplotlib); deterministic for a seed.
"""

import argparse
import csv
import glob
import os
import sys

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(__file__))
import hdr  # noqa: E402


def srgb_encode(linear):
    c = np.clip(linear, 0, 1)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)


def srgb_decode(c):
    return np.where(c <= 0.04045, c / 12.92, np.power((c + 0.055) / 1.055, 2.4))


def linear_luminance_of_8bit(rgb8):
    lin = srgb_decode(rgb8.astype(np.float64) / 255.0)
    return lin @ hdr.REC709 if lin.ndim == 3 else lin


def save8(path, linear_rgb, quality=None):
    img = np.round(srgb_encode(linear_rgb) * 255).astype(np.uint8)
    if quality is None:
        Image.fromarray(img).save(path)
    else:
        Image.fromarray(img).save(path, quality=quality)


class Suite:
    def __init__(self, out, rng):
        self.out = out
        self.rng = rng
        self.rows = []

    def add(self, kind, source, name, circle, white):
        cx, cy, r = circle
        self.rows.append(
            {
                "path": f"{kind}/{name}",
                "class": kind,
                "illumination": source,
                "cx": f"{cx:.2f}",
                "cy": f"{cy:.2f}",
                "r": f"{r:.2f}",
                "white": "" if white is None else f"{white:.6g}",
            }
        )

    def folder(self, kind):
        path = os.path.join(self.out, kind)
        os.makedirs(path, exist_ok=True)
        return path

    def circles(self, h, w, n_random):
        """The centred circle, then random ones; each keeps its annulus (0.9 r) inside."""
        side = min(h, w)
        out = [((w - 1) / 2, (h - 1) / 2, 0.45 * side)]
        for _ in range(n_random):
            r = side * self.rng.uniform(0.18, 0.4)
            cx = self.rng.uniform(0.9 * r, w - 1 - 0.9 * r)
            cy = self.rng.uniform(0.9 * r, h - 1 - 0.9 * r)
            out.append((cx, cy, r))
        return [c for c in out if c[2] >= 40]

    def white_of(self, luminance):
        """A plausible white: the 99th percentile of the image's linear luminance."""
        return max(float(np.percentile(luminance, 99)), 1e-3)

    def write(self):
        with open(os.path.join(self.out, "manifest.csv"), "w", newline="") as f:
            writer = csv.DictWriter(f, ["path", "class", "illumination", "cx", "cy", "r", "white"])
            writer.writeheader()
            writer.writerows(self.rows)


def sample_photographs():
    """(name, RGB uint8) of the sample photographs the Python ecosystem bundles."""
    import matplotlib
    import skimage.data
    import sklearn.datasets

    found = []
    data_dir = os.path.dirname(skimage.data.__file__)
    skip = {"lfw_subset.npy", "multipage.tif", "multipage_rgb.tif", "motorcycle_disp.npz"}
    for path in sorted(glob.glob(os.path.join(data_dir, "*"))):
        name = os.path.basename(path)
        if name in skip or not name.lower().endswith((".png", ".jpg", ".gif", ".tif")):
            continue
        found.append(("skimage_" + os.path.splitext(name)[0], path))
    for path in sorted(glob.glob(os.path.join(os.path.dirname(sklearn.datasets.__file__), "images", "*.jpg"))):
        found.append(("sklearn_" + os.path.splitext(os.path.basename(path))[0], path))
    mpl = os.path.join(os.path.dirname(matplotlib.__file__), "mpl-data", "sample_data")
    for name in ["grace_hopper.jpg", "Minduka_Present_Blue_Pack.png", "logo2.png"]:
        if os.path.exists(os.path.join(mpl, name)):
            found.append(("mpl_" + os.path.splitext(name)[0], os.path.join(mpl, name)))
    for name, path in found:
        img = np.asarray(Image.open(path).convert("RGB"))
        if min(img.shape[:2]) >= 100:
            yield name, img


def photos(suite):
    folder = suite.folder("photo")
    for name, img in sample_photographs():
        h, w = img.shape[:2]
        # Small sample images are enlarged so that a circle of r ≥ 40 px fits twice over.
        if min(h, w) < 256:
            k = int(np.ceil(256 / min(h, w)))
            img = np.asarray(Image.fromarray(img).resize((w * k, h * k), Image.BILINEAR))
            h, w = img.shape[:2]
        file = f"{name}.png"
        Image.fromarray(img).save(os.path.join(folder, file))
        lum = linear_luminance_of_8bit(img)
        for i, c in enumerate(suite.circles(h, w, 2)):
            suite.add("photo", name, file, c, suite.white_of(lum) if i != 1 else None)


def perspective(env, yaw, pitch, fov, size):
    h, w = size
    f = 0.5 * w / np.tan(np.radians(fov) / 2)
    x = (np.arange(w) - (w - 1) / 2) / f
    y = -(np.arange(h) - (h - 1) / 2) / f
    xx, yy = np.meshgrid(x, y)
    d = np.stack([xx, yy, -np.ones_like(xx)], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    cp, sp = np.cos(pitch), np.sin(pitch)
    d = d @ np.array([[1, 0, 0], [0, cp, sp], [0, -sp, cp]])
    cy_, sy_ = np.cos(yaw), np.sin(yaw)
    d = d @ np.array([[cy_, 0, -sy_], [0, 1, 0], [sy_, 0, cy_]])
    return hdr.lookup(env, d)


def scenes(suite, probes):
    folder = suite.folder("scene")
    for path in probes:
        name = os.path.splitext(os.path.basename(path))[0]
        env = hdr.read(path)
        for k in range(2):
            yaw = suite.rng.uniform(0, 2 * np.pi)
            pitch = np.radians(suite.rng.uniform(-15, 15))
            view = perspective(env, yaw, pitch, 70, (384, 512))
            lum = hdr.luminance(view)
            exposure = 0.18 / max(np.percentile(lum, 50), 1e-9)
            file = f"{name}_{k}.jpg"
            save8(os.path.join(folder, file), view * exposure, quality=90)
            img = np.asarray(Image.open(os.path.join(folder, file)).convert("RGB"))
            white = suite.white_of(linear_luminance_of_8bit(img))
            c = suite.circles(384, 512, 1)[k % 2]
            suite.add("scene", name, file, c, white if k == 0 else None)


def pattern_images(rng, n=512):
    yy, xx = np.mgrid[0:n, 0:n] / n
    out = []
    img = np.full((n, n, 3), 0.5)
    for _ in range(12):
        x0, y0 = rng.uniform(0, 0.8, 2)
        x1, y1 = x0 + rng.uniform(0.1, 0.5), y0 + rng.uniform(0.1, 0.5)
        img[(xx >= x0) & (xx < x1) & (yy >= y0) & (yy < y1)] = rng.uniform(0.02, 1, 3)
    out.append(("rectangles", img))
    for cells in (4, 8, 16):
        board = ((np.floor(xx * cells) + np.floor(yy * cells)) % 2)[..., None]
        out.append((f"checkerboard{cells}", np.repeat(0.05 + 0.85 * board, 3, axis=2)))
    for period, angle in ((16, 0.0), (40, 1.1)):
        t = (xx * np.cos(angle) + yy * np.sin(angle)) * n / period
        out.append((f"stripes{period}", np.repeat((0.1 + 0.8 * (np.sin(2 * np.pi * t) > 0))[..., None], 3, axis=2)))
    out.append(("noise", rng.uniform(0, 1, (n, n, 3))))
    spectrum = np.fft.fft2(rng.normal(size=(n, n)))
    f = np.hypot(*np.meshgrid(np.fft.fftfreq(n), np.fft.fftfreq(n)))
    pink = np.real(np.fft.ifft2(spectrum / np.maximum(f, 1 / n)))
    pink = (pink - pink.min()) / (pink.max() - pink.min())
    out.append(("pink_noise", np.repeat(pink[..., None], 3, axis=2) ** 2))
    out.append(("gradient", np.repeat((0.05 + 0.9 * xx)[..., None], 3, axis=2)))
    r = np.hypot(xx - 0.5, yy - 0.5)
    out.append(("rings", np.repeat((0.1 + 0.8 * (np.sin(2 * np.pi * r * 20) > 0))[..., None], 3, axis=2)))
    text = np.ones((n, n))
    for row in range(20, n - 20, 24):
        x = 20
        while x < n - 30:
            wlen = rng.integers(2, 9) * 9
            for cx in range(x, min(x + wlen, n - 20), 9):
                glyph = rng.uniform(size=(14, 7)) < 0.45
                text[row : row + 14, cx : cx + 7][glyph] = 0.02
            x += wlen + 9
    out.append(("text", np.repeat(text[..., None], 3, axis=2)))
    dots = np.full((n, n), 0.8)
    for _ in range(150):
        cx, cy, rad = rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(0.005, 0.03)
        dots[np.hypot(xx - cx, yy - cy) < rad] = rng.uniform(0, 0.5)
    out.append(("dots", np.repeat(dots[..., None], 3, axis=2)))
    out.append(("flat", np.full((n, n, 3), 0.4)))
    return out


def patterns(suite):
    folder = suite.folder("pattern")
    for name, linear in pattern_images(suite.rng):
        file = f"{name}.png"
        save8(os.path.join(folder, file), linear)
        lum = linear_luminance_of_8bit(np.asarray(Image.open(os.path.join(folder, file)).convert("RGB")))
        for i, c in enumerate(suite.circles(*lum.shape, 1)):
            suite.add("pattern", name, file, c, suite.white_of(lum) if i == 0 else None)


def trace(shape, n, elevation):
    """Orthographic rays along -v onto an object of unit size at the origin: (hit mask,
    normals) of an n × n image spanning ±1.1 (as the renderer's frame)."""
    e = np.radians(elevation)
    v = np.array([0.0, np.sin(e), np.cos(e)])
    up = np.array([0.0, 1.0, 0.0]) - v * v[1]
    up /= np.linalg.norm(up)
    right = np.cross(up, v)
    s = (np.arange(n) + 0.5 - n / 2) * 2.2 / n
    xs, ys = np.meshgrid(s, -s)
    origin = xs[..., None] * right + ys[..., None] * up + 5 * v
    d = -np.broadcast_to(v, origin.shape)
    t_best = np.full(xs.shape, np.inf)
    normal = np.zeros(origin.shape)
    ts = np.linspace(0, 10, 800)
    # Sphere-traced signed distance functions: simple, general, accurate enough here.
    def sdf(p):
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        if shape == "cube":
            c, s_ = np.cos(0.6), np.sin(0.6)
            x, z = c * x - s_ * z, s_ * x + c * z
            q = np.abs(np.stack([x, y, z], -1)) - 0.6
            return np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(-1), 0)
        if shape == "cylinder":
            dxz = np.hypot(x, z) - 0.55
            dy = np.abs(y) - 0.9
            return np.minimum(np.maximum(dxz, dy), 0) + np.hypot(np.maximum(dxz, 0), np.maximum(dy, 0))
        if shape == "torus":
            q = np.hypot(np.hypot(x, y) - 0.7, z)
            return q - 0.3
        if shape == "disc":
            dxy = np.hypot(x, y) - 1.0
            dz = np.abs(z) - 0.03
            return np.minimum(np.maximum(dxy, dz), 0) + np.hypot(np.maximum(dxy, 0), np.maximum(dz, 0))
        if shape == "ellipsoid":
            k = np.array([1.0, 0.5, 0.6])
            q = p / k
            k0 = np.linalg.norm(q, axis=-1)
            k1 = np.linalg.norm(q / k, axis=-1)
            return k0 * (k0 - 1) / np.maximum(k1, 1e-9)
        if shape == "cone":
            h = y + 0.8
            rad = 0.7 * (1 - h / 1.6)
            return np.maximum(np.hypot(x, z) - np.maximum(rad, 0), np.maximum(-h, h - 1.6)) * 0.8
        raise ValueError(shape)

    t = np.zeros(xs.shape)
    for _ in range(160):
        p = origin + d * t[..., None]
        dist = sdf(p)
        t = t + np.maximum(dist, 1e-4)
    p = origin + d * t[..., None]
    hit = sdf(p) < 1e-3
    eps = 1e-4
    grad = np.stack(
        [
            sdf(p + np.array([eps, 0, 0])) - sdf(p - np.array([eps, 0, 0])),
            sdf(p + np.array([0, eps, 0])) - sdf(p - np.array([0, eps, 0])),
            sdf(p + np.array([0, 0, eps])) - sdf(p - np.array([0, 0, eps])),
        ],
        -1,
    )
    normal = grad / np.maximum(np.linalg.norm(grad, axis=-1, keepdims=True), 1e-12)
    return hit, normal, v


def objects(suite, probes):
    folder = suite.folder("object")
    n = 256
    shapes = ["cube", "cylinder", "torus", "disc", "ellipsoid", "cone"]
    materials = {"mirror": (0.0, 0.75), "matte": (0.8, 0.0), "glossy": (0.3, 0.15)}
    for shape in shapes:
        hit, normal, v = trace(shape, n, 45)
        for k, (material, (rho_d, rho_s)) in enumerate(materials.items()):
            path = probes[(shapes.index(shape) * 3 + k) % len(probes)]
            env = hdr.luminance(hdr.read(path))[..., None]
            white = float(hdr.irradiance(env, v[None])[0, 0]) / np.pi
            lum = np.zeros((n, n))
            diffuse = hdr.irradiance(env, normal[hit])[:, 0] / np.pi
            nv = (normal[hit] * v).sum(-1, keepdims=True)
            reflected = 2 * nv * normal[hit] - v
            specular = hdr.lookup(env, reflected)[:, 0]
            lum[hit] = rho_d * diffuse + rho_s * specular
            background = suite.rng.uniform(0.1, 0.9) * white
            lum[~hit] = background
            exposure = 0.5
            image = lum / white * exposure
            file = f"{shape}_{material}.png"
            save8(os.path.join(folder, file), np.repeat(image[..., None], 3, axis=2))
            ys, xs = np.nonzero(hit)
            cx, cy = (xs.min() + xs.max()) / 2, (ys.min() + ys.max()) / 2
            r = 0.5 * max(xs.max() - xs.min(), ys.max() - ys.min())
            r = min(r, (n - 1) / 0.9 / 2 - 1)
            suite.add("object", os.path.basename(path), file, (cx, cy, r), exposure)


def spheres(suite, manifest_path, per_kind):
    """Captures of real renders with a wrong circle or white, padded onto their own
    background so that every circle stays inside the image."""
    base = os.path.dirname(manifest_path)
    with open(manifest_path) as f:
        rows = [r for r in csv.DictReader(f) if "@cap" in r["illumination"] and r["path"].endswith(".png")]
    rows = [r for r in rows if not r.get("encoding") or r["encoding"] == "srgb"]
    picked = [rows[i] for i in suite.rng.choice(len(rows), size=min(per_kind * 4, len(rows)), replace=False)]
    kinds = ["moved", "large", "small", "dark_white"]
    for kind in kinds:
        suite.folder(kind)
    for i, row in enumerate(picked):
        kind = kinds[i % 4]
        img = np.asarray(Image.open(os.path.join(base, row["path"])).convert("RGB"))
        h, w = img.shape[:2]
        cx, cy, r, white = (float(row[k]) for k in ("cx", "cy", "r", "white"))
        pad = int(np.ceil(0.9 * r))
        canvas = np.empty((h + 2 * pad, w + 2 * pad, 3), dtype=np.uint8)
        canvas[:] = img[0, 0]
        canvas[pad : pad + h, pad : pad + w] = img
        cx, cy = cx + pad, cy + pad
        if kind == "moved":
            a = suite.rng.uniform(0, 2 * np.pi)
            circle = (cx + 0.6 * r * np.cos(a), cy + 0.6 * r * np.sin(a), r)
        elif kind == "large":
            circle = (cx, cy, 1.5 * r)
        elif kind == "small":
            circle = (cx, cy, max(0.6 * r, 40))
        else:
            circle = (cx, cy, r)
            white = white / 20
        file = os.path.basename(row["path"])
        Image.fromarray(canvas).save(os.path.join(suite.out, kind, file))
        suite.add(kind, row["illumination"], file, circle, white)


def lights(out, rng, count):
    """Lat-long maps of one small bright source in the dark, with a faint ambient."""
    folder = os.path.join(out, "lights")
    os.makedirs(folder, exist_ok=True)
    h, w = 256, 512
    dirs = hdr.directions(h, w)
    names = []
    for k in range(count):
        size = np.radians(rng.uniform(1.0, 4.0))
        elevation = np.radians(rng.uniform(5, 60))
        azimuth = rng.uniform(-np.pi, np.pi)
        source = np.array([np.cos(elevation) * np.sin(azimuth), np.sin(elevation), -np.cos(elevation) * np.cos(azimuth)])
        # Put most sources in front of the sphere, where a lamp usually is.
        if k % 3 != 2:
            source[2] = abs(source[2])
        cos = dirs @ source
        env = np.where(cos > np.cos(size), 1000.0, 0.0)
        ambient = [0.001, 0.01, 0.05, 0.2][k % 4]
        env = env + ambient
        name = f"light{k:02d}"
        hdr.write(os.path.join(folder, name + ".hdr"), np.repeat(env[..., None], 3, axis=2))
        names.append(os.path.abspath(os.path.join(folder, name + ".hdr")))
    with open(os.path.join(out, "lights.txt"), "w") as f:
        f.write("\n".join(names) + "\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--probes", required=True, help="folder of lat-long .hdr probes")
    parser.add_argument("--spheres", required=True, help="a rendered data set with captures (render --captures)")
    parser.add_argument("--out", required=True)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--per-kind", type=int, default=40, help="spheres per wrong-circle or wrong-white kind")
    parser.add_argument("--lights", type=int, default=12)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    os.makedirs(args.out, exist_ok=True)
    suite = Suite(args.out, rng)
    probes = sorted(glob.glob(os.path.join(args.probes, "*.hdr")))
    photos(suite)
    scenes(suite, probes)
    patterns(suite)
    objects(suite, probes)
    spheres(suite, os.path.join(args.spheres, "manifest.csv"), args.per_kind)
    suite.write()
    lights(args.out, rng, args.lights)
    kinds = {}
    for row in suite.rows:
        kinds[row["class"]] = kinds.get(row["class"], 0) + 1
    print(f"{len(suite.rows)} inputs: " + ", ".join(f"{k} {v}" for k, v in kinds.items()))


if __name__ == "__main__":
    main()
