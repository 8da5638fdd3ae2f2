#!/usr/bin/env python3
"""Tables of docs/accuracy.md "Honest answers" from `reflectance predict` outputs.

    python3 scripts/domain/tables.py sets PREDICTIONS.csv MANIFEST.csv
        accuracy, coverage, mean set size, in-domain rate and confidently wrong answers (a wrong
        label, the truth outside the set, in domain) of labelled rows: all, the original
        renders, the captures
    python3 scripts/domain/tables.py domain PREDICTIONS.csv MANIFEST.csv
        per kind (the manifest's class; `@cap` rows apart): rows flagged out of domain and
        the checks that failed

Standard library only.
"""

import collections
import csv
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


if __name__ == "__main__":
    if len(sys.argv) != 4 or sys.argv[1] not in ("sets", "domain"):
        sys.exit(__doc__)
    {"sets": sets, "domain": domain}[sys.argv[1]](rows(sys.argv[2], sys.argv[3]))
