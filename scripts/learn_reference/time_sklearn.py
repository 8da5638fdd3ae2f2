"""Times scikit-learn (libsvm) on the table that `cargo bench --bench learn` writes, for
comparison with the Rust `learn` module (single thread; minimum and median of repeats).

    cargo bench --bench learn            # writes $TMPDIR/reflectance_learn_bench.csv
    python3 scripts/learn_reference/time_sklearn.py [$TMPDIR/reflectance_learn_bench.csv]
"""

import os
import statistics
import sys
import tempfile
import time
import warnings

import numpy as np
from sklearn.multiclass import OneVsRestClassifier
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from synthetic import HAND6, read_csv  # noqa: E402


def timed(f, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times), statistics.median(times)


def main():
    # SVC(probability=True) is deprecated in 1.9 but is exactly libsvm's Platt procedure.
    warnings.simplefilter("ignore", FutureWarning)
    path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        tempfile.gettempdir(), "reflectance_learn_bench.csv")
    names, paths, classes, illums, x = read_csv(path)
    class_names = sorted(set(classes))
    y = np.array([class_names.index(c) for c in classes])
    groups = np.array(illums)
    print(f"{path}: {x.shape[0]} rows, {len(class_names)} classes, "
          f"{len(set(illums))} illuminations")
    for set_name, cols in [("hand6", [names.index(n) for n in HAND6]),
                           ("all", list(range(len(names))))]:
        z = StandardScaler().fit_transform(x[:, cols])
        gamma = 1.0 / len(cols)

        def ova(probability=False):
            return OneVsRestClassifier(
                SVC(kernel="rbf", C=100, gamma=gamma, probability=probability,
                    random_state=0)).fit(z, y)

        mn, md = timed(ova, 10)
        print(f"{set_name:6} OvR SVC fit (bare):          min {mn * 1e3:8.1f} ms  median {md * 1e3:8.1f} ms")
        mn, md = timed(lambda: ova(True), 3)
        print(f"{set_name:6} OvR SVC fit (probability):   min {mn * 1e3:8.1f} ms  median {md * 1e3:8.1f} ms")

        def loio():
            correct = 0
            for g in sorted(set(illums)):
                tr, te = groups != g, groups == g
                sc = StandardScaler().fit(x[tr][:, cols])
                clf = OneVsRestClassifier(SVC(kernel="rbf", C=100, gamma=gamma))
                clf.fit(sc.transform(x[tr][:, cols]), y[tr])
                correct += (clf.predict(sc.transform(x[te][:, cols])) == y[te]).sum()
            return correct / len(y)

        acc = loio()
        mn, md = timed(loio, 3)
        print(f"{set_name:6} LOIO CV (bare, acc {acc:.4f}):  min {mn * 1e3:8.1f} ms  median {md * 1e3:8.1f} ms")
        clf = ova()
        sc = StandardScaler().fit(x[:, cols])
        row = x[:1, cols]
        mn, md = timed(lambda: clf.decision_function(sc.transform(row)), 200)
        print(f"{set_name:6} predict one (decision):      min {mn * 1e6:8.1f} µs  median {md * 1e6:8.1f} µs")


if __name__ == "__main__":
    main()
