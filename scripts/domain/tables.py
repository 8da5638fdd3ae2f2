#!/usr/bin/env python3
"""Tables of docs/accuracy.md "Honest answers" from `reflectance predict` outputs.

    python3 scripts/domain/tables.py sets PREDICTIONS.csv MANIFEST.csv
        accuracy, coverage, mean set size, in-domain rate and confidently wrong answers (a wrong
        label, the truth outside the set, in domain) of labelled rows: all, the original
        renders, the captures
    python3 scripts/domain/tables.py domain PREDICTIONS.csv MANIFEST.csv
        per kind (the manifest's class; `@cap` rows apart): rows flagged out of domain and
        the checks that failed
    python3 scripts/domain/tables.py ward PREDICTIONS.csv MANIFEST.csv CLASSES.json
        the Ward estimate of labelled rows (`predict` of a model with an estimator): how often
        its intervals hold the class's parameters where the label is right with p >= 0.9, how
        often all three hold the truth, the mean width of the rho_s interval, and the errors

Standard library only.
"""

import collections
import csv
import json
import math
import sys


def rows(predictions, manifest):
    with open(predictions) as p, open(manifest) as m:
        return list(zip(csv.DictReader(p), csv.DictReader(m)))


def sets(pairs):
    groups = collections.OrderedDict((("all", []), ("originals", []), ("captures", [])))
    for p, m in pairs:
        groups["all"].append((p, m))
        groups["captures" if "@cap" in m["illumination"] else "originals"].append((p, m))
    print("| images | n | accuracy | set holds the truth | mean set size | in domain | confidently wrong |")
    print("|---|---|---|---|---|---|---|")
    for name, group in groups.items():
        if not group:
            continue
        n = len(group)
        right = sum(p["label"] == m["class"] for p, m in group)
        held = sum(m["class"] in p["set"].split() for p, m in group)
        size = sum(len(p["set"].split()) for p, m in group) / n
        inside = sum(p["in_domain"] == "true" for p, m in group)
        # A wrong label, the truth outside the set, and in domain: the worst answer.
        confident = sum(
            p["label"] != m["class"] and m["class"] not in p["set"].split() and p["in_domain"] == "true"
            for p, m in group
        )
        print(
            f"| {name} | {n} | {100 * right / n:.1f} % | {100 * held / n:.1f} % | {size:.2f} "
            f"| {100 * inside / n:.1f} % | {100 * confident / n:.1f} % |"
        )


def domain(pairs):
    kinds = collections.OrderedDict()
    for p, m in pairs:
        kinds.setdefault(m["class"], []).append(p)
    print("| kind | n | flagged | failed checks |")
    print("|---|---|---|---|")
    total, flagged_total = 0, 0
    for kind, group in kinds.items():
        flagged = [p for p in group if p["in_domain"] == "false"]
        checks = collections.Counter(c for p in flagged for c in p["domain_failed"].split())
        named = ", ".join(f"{c} {k}" for c, k in checks.most_common())
        print(f"| {kind} | {len(group)} | {100 * len(flagged) / len(group):.1f} % | {named} |")
        total += len(group)
        flagged_total += len(flagged)
    print(f"| **all** | {total} | **{100 * flagged_total / total:.1f} %** | |")


def ward(pairs, classes):
    params = {c["name"]: c for c in json.load(open(classes))["classes"]}

    def holds(p, c):
        return all(
            float(p[f"{k}_low"]) <= c[k] + 1e-9 and c[k] <= float(p[f"{k}_high"]) + 1e-9
            for k in ("rho_d", "rho_s", "alpha")
        )

    estimated = [(p, params[m["class"]]) for p, m in pairs if p.get("rho_s")]
    if not estimated:
        sys.exit("no row carries an estimate with its total (a model with an estimator, with white)")
    confident = [(p, c) for p, c in estimated if p["label"] == c["name"] and float(p[f"p_{c['name']}"]) >= 0.9]
    n = len(estimated)
    # Mirror or not means something only for a sphere with a specular part.
    specular = [(p, c) for p, c in estimated if c["rho_s"] > 0]
    mirror = sum((float(p["alpha"]) == 0) == (c["alpha"] == 0) for p, c in specular)
    print("| n | label right, p >= 0.9 | there, intervals hold the class | all three hold the truth "
          "| mean rho_s width | total MAE | rho_s MAE | mirror or not (specular) |")
    print("|---|---|---|---|---|---|---|---|")
    print(
        f"| {n} | {len(confident)} | {100 * sum(holds(p, c) for p, c in confident) / max(len(confident), 1):.1f} % "
        f"| {100 * sum(holds(p, c) for p, c in estimated) / n:.1f} % "
        f"| {sum(float(p['rho_s_high']) - float(p['rho_s_low']) for p, _ in estimated) / n:.3f} "
        f"| {sum(abs(float(p['rho_d']) + float(p['rho_s']) - c['rho_d'] - c['rho_s']) for p, c in estimated) / n:.3f} "
        f"| {sum(abs(float(p['rho_s']) - c['rho_s']) for p, c in estimated) / n:.3f} "
        f"| {100 * mirror / max(len(specular), 1):.1f} % of {len(specular)} |"
    )
    # What stands without white: the specular fraction (its interval: every ratio the rho_d and
    # rho_s intervals allow) and alpha (the glossy ones called glossy).
    fractions = []
    for p, c in estimated:
        total = c["rho_d"] + c["rho_s"]
        if total <= 0:
            continue
        d_low, d_high, s_low, s_high = (float(p[k]) for k in ("rho_d_low", "rho_d_high", "rho_s_low", "rho_s_high"))
        low = s_low / (s_low + d_high) if s_low + d_high > 0 else 0.0
        high = s_high / (s_high + d_low) if s_high + d_low > 0 else 1.0
        estimate = float(p["rho_s"]) / max(float(p["rho_d"]) + float(p["rho_s"]), 1e-12)
        truth = c["rho_s"] / total
        fractions.append((abs(estimate - truth), low - 1e-9 <= truth <= high + 1e-9, high - low))
    glossy = [
        abs(math.log10(float(p["alpha"])) - math.log10(c["alpha"]))
        for p, c in estimated
        if c["alpha"] > 0 and float(p["alpha"]) > 0
    ]
    m = max(len(fractions), 1)
    print()
    print("| specular fraction MAE | its interval holds the truth | its mean width | log10 alpha MAE (glossy called glossy) |")
    print("|---|---|---|---|")
    print(
        f"| {sum(f[0] for f in fractions) / m:.3f} | {100 * sum(f[1] for f in fractions) / m:.1f} % "
        f"| {sum(f[2] for f in fractions) / m:.2f} | {sum(glossy) / max(len(glossy), 1):.3f} |"
    )


if __name__ == "__main__":
    commands = {"sets": 4, "domain": 4, "ward": 5}
    if commands.get(sys.argv[1] if len(sys.argv) > 1 else None) != len(sys.argv):
        sys.exit(__doc__)
    if sys.argv[1] == "ward":
        ward(rows(sys.argv[2], sys.argv[3]), sys.argv[4])
    else:
        {"sets": sets, "domain": domain}[sys.argv[1]](rows(sys.argv[2], sys.argv[3]))
