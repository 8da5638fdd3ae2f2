#!/usr/bin/env python3
"""Keep each class's reference material at half of its training rows (issue #68).

  balance.py MANIFEST.csv CLASSES.json [SHARE] > BALANCED.csv

`render --classes` with members renders every member in every view, so a class with four
members holds its reference material in a fifth of its rows, and a classifier trained on all of
them learns the members at the cost of the reference (the paper's classes, which Tables 1 and 2
and every earlier figure are measured on). This keeps every row of the references and, per
illumination, deals the views among the class's members in turn: with k members, member i keeps
the views v (in the order they first appear under that illumination) with (v + p) mod k = i,
p the illumination's index. The members together then hold as many rows as the reference, and
every member is seen under every probe. With SHARE = 1/n (n a whole number; default 1), the
modulus is n k: the members hold 1/n of the reference's rows. Deterministic: the same manifest
gives the same rows.
"""
import csv
import json
import sys


def material(path):
    """(illumination, view tags, class, member or None) from a render's file name."""
    name = path.rsplit('/', 1)[-1].rsplit('.', 1)[0]
    scene, mat = name.split('__', 1)
    parts = scene.split('@')
    views = [t for t in parts[1:] if not t.startswith('cap')]
    cls, _, member = mat.partition('+')
    return parts[0], '@'.join(views), cls, member or None


def main(manifest, classes_file, per_member):
    with open(classes_file) as f:
        members = {}
        for entry in json.load(f)['classes']:
            if 'member' in entry:
                members.setdefault(entry['name'], []).append(entry['member'])
    with open(manifest, newline='') as f:
        reader = csv.reader(f)
        header = next(reader)
        rows = list(reader)
    illuminations, views = {}, {}
    for row in rows:
        illum, view, _, _ = material(row[0])
        illuminations.setdefault(illum, len(illuminations))
        views.setdefault(illum, {}).setdefault(view, len(views[illum]))
    out = csv.writer(sys.stdout, lineterminator='\n')
    out.writerow(header)
    for row in rows:
        illum, view, cls, member = material(row[0])
        if member is not None:
            k = len(members[cls]) * per_member
            v, p = views[illum][view], illuminations[illum]
            if (v + p) % k != members[cls].index(member):
                continue
        out.writerow(row)


if __name__ == '__main__':
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    share = 1 if len(sys.argv) == 3 else 1 / float(sys.argv[3])
    if share != round(share) or share < 1:
        sys.exit('SHARE must be 1/n for a whole number n (1, 0.5, 0.25, …)')
    main(sys.argv[1], sys.argv[2], int(round(share)))
