"""Synthetic feature tables that look like the real ones: 117 canonically named columns,
class- and illumination-dependent, correlated, with the exact linear dependencies of the
real bank (ratio.b.sk_sk+1 = wav.sk.b.var − wav.sk+1.b.var, all log10)."""

import numpy as np

STATS = ["mean", "var", "skew", "kurt", "p10", "p50", "p90"]
BANDS = ["h", "v", "d"]
ORIENT = ["f0", "f45", "f90", "f135"]

CLASSES = ["black_matte", "black_shiny", "chrome", "gray_shiny", "white_matte", "white_shiny"]
HAND6 = ["pix.mean", "pix.p10", "wav.s1.v.var", "wav.s2.v.var", "ratio.v.s1_s2", "wav.s2.v.kurt"]
GROUPS = ["beach", "building", "campus", "eucalyptus", "galileo", "grace",
          "kitchen", "pisa", "rnl", "stpeters", "uffizi", "ennis"]


def feature_names(levels=4):
    names = [f"pix.{s}" for s in STATS]
    for k in range(1, levels + 1):
        for b in BANDS:
            names += [f"wav.s{k}.{b}.{s}" for s in STATS]
    for b in BANDS:
        names += [f"ratio.{b}.s{k}_s{k + 1}" for k in range(1, levels)]
    for band in range(1, 5):
        names += [f"fft.b{band}.{o}.pow" for o in ORIENT]
    names.append("fft.lo.pow")
    return names


def make_table(seed, classes, groups, per_cell, difficulty=1.0):
    """Rows: for each group, each class, `per_cell` views. Returns (names, rows) with rows
    (path, class, illumination, values[117])."""
    rng = np.random.default_rng(seed)
    names = feature_names()
    m = len(names)
    # Latent class properties (diffuse, specular, roughness, sharpness) and illumination
    # properties (brightness, contrast, dynamic range), both standardized-ish.
    theta = rng.normal(size=(len(classes), 4))
    phi = rng.normal(size=(len(groups), 3))
    w_class = rng.normal(size=(m, 4)) * 0.9
    # The paper's hand-picked features are the informative ones.
    for n in HAND6:
        w_class[names.index(n)] *= 2.5
    w_group = rng.normal(size=(m, 3)) * 1.1
    w_inter = rng.normal(size=(m, 4, 3)) * 0.25
    w_view = rng.normal(size=(m, 3)) * 0.5
    noise = 0.35 + 0.5 * rng.random(m)
    # Per-column affine scale: means near 0.1–1, log-variances near −4…−1, etc.
    scale = 0.1 + rng.random(m)
    offset = rng.normal(size=m) * 2.0
    rows = []
    for g, group in enumerate(groups):
        for c, cls in enumerate(classes):
            for v in range(per_cell):
                view = rng.normal(size=3)
                f = (w_class @ theta[c] + w_group @ phi[g]
                     + np.einsum("mij,i,j->m", w_inter, theta[c], phi[g])
                     + w_view @ view + difficulty * noise * rng.normal(size=m))
                f = offset + scale * f
                values = dict(zip(names, f))
                for b in BANDS:
                    for k in range(1, 4):
                        values[f"ratio.{b}.s{k}_s{k + 1}"] = (
                            values[f"wav.s{k}.{b}.var"] - values[f"wav.s{k + 1}.{b}.var"])
                rows.append((f"{group}/{cls}_{v}.png", cls, group,
                             [float(values[n]) for n in names]))
    return names, rows


def write_csv(path, names, rows):
    with open(path, "w") as out:
        out.write(",".join(["path", "class", "illumination"] + names) + "\n")
        for p, c, i, values in rows:
            out.write(",".join([p, c, i] + [repr(v) for v in values]) + "\n")


def read_csv(path):
    with open(path) as f:
        header = f.readline().strip().split(",")
        names = header[3:]
        paths, classes, illums, x = [], [], [], []
        for line in f:
            parts = line.rstrip("\n").split(",")
            paths.append(parts[0])
            classes.append(parts[1])
            illums.append(parts[2])
            x.append([float(v) for v in parts[3:]])
    return names, paths, classes, illums, np.array(x)
