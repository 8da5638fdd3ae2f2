#!/usr/bin/env python3
"""Real materials (issue #68): how models answer, by material.

  evaluate.py photos BIN MODEL...         the labelled real photographs of ../shared/data/photos/dev
                                          and dev2, circle given, no white: by kind of material
  evaluate.py renders BIN MANIFEST MODEL...
                                          renders of a class file with members, with and without
                                          white: right and confidently wrong per member

Confidently wrong: the label wrong, the truth outside the prediction set, and in domain.
"""
import collections
import csv
import json
import os
import subprocess
import sys

PHOTOS = os.path.join(os.path.dirname(__file__), '..', '..', '..', 'shared', 'data', 'photos')


def kind(path, label):
    if label == 'chrome':
        return 'mirror'
    if label:
        return label.replace('_shiny', ' glossy').replace('_matte', ' matte')
    return 'coloured / other (no label)'


def verdict(label, truth, labels, in_domain):
    if label == truth:
        return 'right'
    return 'confidently wrong' if truth not in labels and in_domain else 'wrong'


def photos(binary, models):
    rows = []
    for folder in ('dev', 'dev2'):
        base = os.path.join(PHOTOS, folder)
        with open(os.path.join(base, 'manifest.csv')) as f:
            rows += [(base, r) for r in csv.DictReader(f)]
    for model in models:
        table = collections.defaultdict(collections.Counter)
        for base, r in rows:
            args = [binary, 'classify', '--model', model, os.path.join(base, r['path']), '--json',
                    '--cx', r['cx'], '--cy', r['cy'], '--r', r['r']]
            answer = json.loads(subprocess.run(args, capture_output=True, text=True, check=True).stdout)
            labels = answer['prediction_set']['labels']
            k = kind(r['path'], r['label6'])
            table[k]['photographs'] += 1
            if r['label6']:
                table[k][verdict(answer['label'], r['label6'], labels, answer['domain']['in_domain'])] += 1
            else:
                table[k]['answered ' + answer['label']] += 1
            print(f"{model}\t{r['path']}\t{r['label6'] or '-'}\t{answer['label']}\t"
                  f"{max(p['p'] for p in answer['probabilities']):.2f}\t{','.join(labels)}\t"
                  f"{answer['domain']['in_domain']}", file=sys.stderr)
        print(f'## {model}')
        for k, counts in sorted(table.items()):
            print(f"{k}: " + ', '.join(f'{v} {n}' for n, v in sorted(counts.items())))


def renders(binary, manifest, models):
    with open(manifest) as f:
        rows = list(csv.DictReader(f))
    nowhite = os.path.join(os.path.dirname(manifest), 'manifest_nowhite.csv')
    with open(nowhite, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows({**r, 'white': ''} for r in rows)
    truth = {r['path']: (r['class'], r['path'].split('__')[1].rsplit('.', 1)[0]) for r in rows}
    for model in models:
        for tag, m in (('with white', manifest), ('without white', nowhite)):
            out = nowhite.replace('manifest_nowhite.csv', 'predictions.csv')
            subprocess.run([binary, 'predict', '--model', model, '--manifest', m, '--out', out],
                           capture_output=True, check=True)
            per = collections.defaultdict(collections.Counter)
            with open(out) as f:
                for p in csv.DictReader(f):
                    cls, member = truth[p['path']]
                    v = verdict(p['label'], cls, p['set'].split(), p['in_domain'] == 'true')
                    for key in (member, 'all'):
                        per[key]['n'] += 1
                        per[key][v] += 1
            print(f'## {model}, {tag}')
            for key, c in sorted(per.items()):
                print(f"{key}: {c['right']}/{c['n']} right, {c['confidently wrong']} confidently wrong")


if __name__ == '__main__':
    if len(sys.argv) < 4 or sys.argv[1] not in ('photos', 'renders'):
        sys.exit(__doc__)
    if sys.argv[1] == 'photos':
        photos(sys.argv[2], sys.argv[3:])
    else:
        renders(sys.argv[2], sys.argv[3], sys.argv[4:])
