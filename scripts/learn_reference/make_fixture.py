"""Generates tests/fixtures/learn/{table.csv, expected.json}: a synthetic feature table and
what scikit-learn (libsvm) and an independent numpy/scipy implementation of docs/design.md §3
"Automatic selection" compute on it. crates/reflectance-core/tests/numerics/learn_reference.rs checks the Rust `learn`
module against them.

    pip install -r scripts/learn_reference/requirements.txt
    python3 scripts/learn_reference/make_fixture.py
"""

import json
import os
import sys
import time
import warnings

import numpy as np
import scipy
import sklearn
from scipy.optimize import minimize
from scipy.special import ndtr
from sklearn.multiclass import OneVsRestClassifier
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from synthetic import CLASSES, GROUPS, HAND6, make_table, read_csv, write_csv  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
OUT = os.path.join(ROOT, "tests", "fixtures", "learn")
SEED = 2001
PER_CELL = 6
DIFFICULTY = 1.5

STD_FLOOR = 1e-6
EXHAUSTED = 1e-9


# ---------------------------------------------------------------- automatic selection

def bayes_error(means, stds, priors):
    """1 − ∫ max_k π_k N(x; μ_k, σ_k) dx, by crossing points of the weighted densities.
    (Written independently of the Rust code: absolute-x quadratics, 1 − correct mass.)"""
    keep = priors > 0
    means, stds, priors = means[keep], stds[keep], priors[keep]
    k = len(means)
    pts = []
    for a in range(k):
        for b in range(a + 1, k):
            # log π_a N_a − log π_b N_b = A x² + B x + C
            A = -0.5 / stds[a] ** 2 + 0.5 / stds[b] ** 2
            B = means[a] / stds[a] ** 2 - means[b] / stds[b] ** 2
            C = (-0.5 * means[a] ** 2 / stds[a] ** 2 + 0.5 * means[b] ** 2 / stds[b] ** 2
                 + np.log(priors[a] / stds[a]) - np.log(priors[b] / stds[b]))
            if A == 0.0:
                if B != 0.0:
                    pts.append(-C / B)
                continue
            disc = B * B - 4 * A * C
            if disc < 0:
                continue
            sq = np.sqrt(disc)
            q = -0.5 * (B + np.copysign(sq, B))
            if q != 0.0:
                pts += [q / A, C / q]
            else:
                pts.append(0.0)
    pts = sorted(p for p in pts if np.isfinite(p))
    edges = [-np.inf] + pts + [np.inf]
    correct = 0.0
    for lo, hi in zip(edges[:-1], edges[1:]):
        if not lo < hi:
            continue
        if np.isfinite(lo) and np.isfinite(hi):
            x = 0.5 * (lo + hi)
        elif np.isfinite(hi):
            x = hi - 1.0 - abs(hi)
        elif np.isfinite(lo):
            x = lo + 1.0 + abs(lo)
        else:
            x = means.mean()
        logw = np.log(priors) - np.log(stds) - 0.5 * ((x - means) / stds) ** 2
        w = int(np.argmax(logw))
        correct += priors[w] * (ndtr((hi - means[w]) / stds[w]) - ndtr((lo - means[w]) / stds[w]))
    return 1.0 - correct


def auto_select(x, y, n_classes, n):
    x = x.astype(float).copy()
    rows, cols = x.shape
    counts = np.bincount(y, minlength=n_classes)
    priors = counts / rows
    guess = 1.0 - priors.max()
    orig_std = x.std(axis=0, ddof=1)
    remaining = list(range(cols))
    chosen, errors = [], []
    for _ in range(n):
        best, best_err = None, None
        for j in remaining:
            v = x[:, j]
            s = v.std(ddof=1)
            if not s > EXHAUSTED * orig_std[j]:
                err = guess
            else:
                floor = STD_FLOOR * s
                means = np.zeros(n_classes)
                stds = np.ones(n_classes)
                for c in range(n_classes):
                    vc = v[y == c]
                    if len(vc) == 0:
                        continue
                    means[c] = vc.mean()
                    stds[c] = max(vc.std(ddof=1), floor) if len(vc) > 1 else floor
                err = bayes_error(means, stds, priors)
            if best_err is None or err < best_err:
                best, best_err = j, err
        remaining.remove(best)
        chosen.append(best)
        errors.append(best_err)
        c = x[:, best] - x[:, best].mean()
        css = c @ c
        for j in remaining:
            f = x[:, j] - x[:, j].mean()
            slope = (c @ f) / css if css > 0 else 0.0
            x[:, j] = f - slope * c
    return chosen, errors


# ---------------------------------------------------------------- Platt reference

def platt_reference(dec, positive):
    """Minimizer of the prior-corrected cross-entropy (Lin, Lin & Weng 2007) by BFGS."""
    n_pos = positive.sum()
    n_neg = len(positive) - n_pos
    t = np.where(positive, (n_pos + 1) / (n_pos + 2), 1 / (n_neg + 2))

    def f(ab):
        z = ab[0] * dec + ab[1]
        return np.sum(t * z + np.logaddexp(0, -z))

    def grad(ab):
        z = ab[0] * dec + ab[1]
        p = 1 / (1 + np.exp(z))  # P(positive) = 1 / (1 + exp(Af + B))
        d = t - p
        return np.array([np.sum(dec * d), np.sum(d)])

    res = minimize(f, [0.0, np.log((n_neg + 1) / (n_pos + 1))], jac=grad, method="BFGS",
                   options={"gtol": 1e-12, "maxiter": 10000})
    return res.x


# ---------------------------------------------------------------- LOIO with scikit-learn

def loio(x, y, groups, cols, C=100.0):
    """Predictions and decision values of OneVsRest(SVC) on StandardScaler-ed folds."""
    pred = np.zeros(len(y), dtype=int)
    dec = np.zeros((len(y), len(CLASSES)))
    fit_seconds = 0.0
    for g in sorted(set(groups)):
        tr = groups != g
        te = groups == g
        sc = StandardScaler().fit(x[tr][:, cols])
        clf = OneVsRestClassifier(SVC(kernel="rbf", C=C, gamma=1.0 / len(cols)))
        t0 = time.perf_counter()
        clf.fit(sc.transform(x[tr][:, cols]), y[tr])
        fit_seconds += time.perf_counter() - t0
        d = clf.decision_function(sc.transform(x[te][:, cols]))
        dec[te] = d
        pred[te] = d.argmax(axis=1)
    return pred, dec, fit_seconds


def loio_probabilities(x, y, groups, cols, C=100.0):
    """Calibrated LOIO probabilities: OneVsRest(SVC(probability=True)) = per class libsvm's
    5-fold internal CV + sigmoid_train, normalized across classes (our scheme)."""
    warnings.simplefilter("ignore", FutureWarning)
    proba = np.zeros((len(y), len(CLASSES)))
    for g in sorted(set(groups)):
        tr = groups != g
        te = groups == g
        sc = StandardScaler().fit(x[tr][:, cols])
        clf = OneVsRestClassifier(SVC(kernel="rbf", C=C, gamma=1.0 / len(cols),
                                      probability=True, random_state=0))
        clf.fit(sc.transform(x[tr][:, cols]), y[tr])
        proba[te] = clf.predict_proba(sc.transform(x[te][:, cols]))
    return proba


def log_loss_and_ece(proba, y):
    p_true = np.clip(proba[np.arange(len(y)), y], 1e-15, None)
    log_loss = float(-np.log(p_true).mean())
    conf = proba.max(axis=1)
    hit = proba.argmax(axis=1) == y
    bins = np.minimum((conf * 10).astype(int), 9)
    ece = 0.0
    for b in range(10):
        m = bins == b
        if m.any():
            ece += m.sum() / len(y) * abs(hit[m].mean() - conf[m].mean())
    return log_loss, float(ece)


def main():
    os.makedirs(OUT, exist_ok=True)
    names, rows = make_table(SEED, CLASSES, GROUPS, PER_CELL, DIFFICULTY)
    table = os.path.join(OUT, "table.csv")
    write_csv(table, names, rows)
    # Everything below reads the CSV back, exactly as the Rust test does.
    names, paths, classes, illums, x = read_csv(table)
    class_names = sorted(set(classes))
    y = np.array([class_names.index(c) for c in classes])
    groups = np.array(illums)
    expected = {
        "generator": {"seed": SEED, "per_cell": PER_CELL, "difficulty": DIFFICULTY},
        "versions": {"numpy": np.__version__, "scipy": scipy.__version__,
                     "sklearn": sklearn.__version__},
        "classes": class_names,
        "svm": {},
    }
    for set_name, cols in [("hand6", [names.index(n) for n in HAND6]),
                           ("all", list(range(len(names))))]:
        pred, dec, secs = loio(x, y, groups, cols)
        expected["svm"][set_name] = {
            "accuracy": float((pred == y).mean()),
            "predicted": [class_names[p] for p in pred],
            "decision_values": dec.tolist(),
            "fit_seconds_total": secs,
        }
        proba = loio_probabilities(x, y, groups, cols)
        ll, ece = log_loss_and_ece(proba, y)
        expected["svm"][set_name]["calibrated"] = {"log_loss": ll, "ece": ece}
        print(f"{set_name}: sklearn LOIO accuracy {(pred == y).mean():.4f}, fits {secs:.3f} s, "
              f"calibrated log-loss {ll:.4f}, ECE {ece:.4f}")
    chosen, errors = auto_select(x, y, len(class_names), 6)
    expected["auto6"] = {"features": [names[j] for j in chosen], "bayes_errors": errors}
    print("auto6:", [names[j] for j in chosen], np.round(errors, 4))
    per_fold = {}
    for g in sorted(set(illums)):
        tr = groups != g
        ch, _ = auto_select(x[tr], y[tr], len(class_names), 6)
        per_fold[g] = [names[j] for j in ch]
    expected["auto6"]["per_fold"] = per_fold
    # Platt: the held-out decision values of class 0 in the hand6 LOIO run.
    dec0 = np.array(expected["svm"]["hand6"]["decision_values"])[:, 0]
    pos0 = y == 0
    a, b = platt_reference(dec0, pos0)
    expected["platt"] = {"decision_values": dec0.tolist(), "positive": pos0.tolist(),
                         "a": float(a), "b": float(b)}
    print(f"platt A={a:.6f} B={b:.6f}")
    with open(os.path.join(OUT, "expected.json"), "w") as f:
        json.dump(expected, f, indent=1)
        f.write("\n")
    print("wrote", table, os.path.getsize(table), "bytes")


if __name__ == "__main__":
    main()
