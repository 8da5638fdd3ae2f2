#!/usr/bin/env python3
"""Real materials (issue #68): two cues that need no white card, measured before a model uses them.

  cues.py photos                the labelled photographs of ../shared/data/photos/dev and dev2,
                                circle given: per material
  cues.py renders DIR PROBES    renders of a class file with members (`reflectance render`, PFM)
                                in DIR, under the probes of the folder PROBES: per member
  cues.py colour                the photographs again: how coloured each ball's centre is
                                against the whole picture (no white card needed either)

Both cues are log10 ratios of median linear luminances:
* against the surroundings: the ball (within 0.9 r) over the ring 1.1-1.6 r around it; for a
  render, over the probe in a ring 6-15 degrees around the direction behind the sphere, what a
  camera would see around it (the render itself has no background);
* the rim's rise: the ring 0.9-0.97 r, outside the unwrapped annulus (which stops at 0.9 r),
  over the ball. A dielectric's Fresnel term rises there; a metal's hardly does.

The colour: the mean linear RGB of the ball's centre (within 0.5 r, its brightest quarter left
out, as highlights) over the picture's mean RGB (a grey world), normalized to sum 1; its
distance from grey (L1 from a third each). A mirror ball reflects the scene it is in, so it
reads near grey; a coloured ball does not.

Needs numpy and Pillow.
"""
import collections
import csv
import os
import sys

import numpy as np
from PIL import Image, ImageOps

SCRIPTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..')
sys.path[:0] = [os.path.join(SCRIPTS, 'domain'), os.path.join(SCRIPTS, 'reference')]
import hdr  # noqa: E402  (scripts/domain: Radiance files and lat-long directions)
from alpha_contrast import read_pfm  # noqa: E402

PHOTOS = os.path.join(SCRIPTS, '..', '..', 'shared', 'data', 'photos')
SURROUND_DEGREES = (6.0, 15.0)


def cues(luminance, cx, cy, r):
    """(against the surroundings or None, rim's rise) of the ball at (cx, cy, r)."""
    h, w = luminance.shape
    yy, xx = np.mgrid[0:h, 0:w]
    d = np.hypot(xx - cx, yy - cy) / r
    ring = lambda lo, hi: luminance[(d >= lo) & (d < hi)]
    ball = np.median(ring(0.0, 0.9))
    around = ring(1.1, 1.6)
    level = np.median(around) if around.size >= 64 else 0.0
    against = np.log10(ball / level) if level > 0 else None
    return against, np.log10(np.median(ring(0.9, 0.97)) / ball)


def srgb_to_linear(u8):
    c = u8 / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def labelled_photos():
    """(manifest row, material, linear RGB, circle) of every photograph of dev and dev2."""
    for folder in ('dev', 'dev2'):
        base = os.path.join(PHOTOS, folder)
        with open(os.path.join(base, 'manifest.csv')) as f:
            for r in csv.DictReader(f):
                image = ImageOps.exif_transpose(Image.open(os.path.join(base, r['path'])))
                rgb = np.asarray(image.convert('RGB'), dtype=np.float64)
                material = r['label6'] or r['path'].split('_')[0]
                yield r, material, srgb_to_linear(rgb), tuple(float(r[k]) for k in 'cx cy r'.split())


def photos():
    table = collections.defaultdict(list)
    for r, material, rgb, circle in labelled_photos():
        against, rise = cues(hdr.luminance(rgb), *circle)
        table[material].append((against, rise))
        shown = '  none' if against is None else f'{against:6.2f}'
        print(f"{r['path']:45s} {material:12s} {shown} {rise:6.2f}", file=sys.stderr)
    print('| material | photographs | against the surroundings: median (range) | rim\'s rise: median (range) |')
    print('|---|---|---|---|')
    for material, values in sorted(table.items()):
        print(f'| {material} | {len(values)} | {summary([a for a, _ in values if a is not None])} '
              f'| {summary([b for _, b in values])} |')


def centre_colour(rgb, cx, cy, r):
    """How far from grey the ball's centre is against the picture's mean colour."""
    h, w, _ = rgb.shape
    yy, xx = np.mgrid[0:h, 0:w]
    centre = rgb[np.hypot(xx - cx, yy - cy) <= 0.5 * r]
    y = hdr.luminance(centre)
    centre = centre[y <= np.quantile(y, 0.75)]
    ratio = centre.mean(0) / rgb.reshape(-1, 3).mean(0)
    return np.abs(ratio / ratio.sum() - 1.0 / 3.0).sum()


def colour():
    table = collections.defaultdict(list)
    for r, material, rgb, circle in labelled_photos():
        distance = centre_colour(rgb, *circle)
        table[material].append(distance)
        print(f"{r['path']:45s} {material:12s} {distance:6.3f}", file=sys.stderr)
    print('| material | photographs | centre against the picture, distance from grey: median (range) |')
    print('|---|---|---|')
    for material, values in sorted(table.items()):
        print(f'| {material} | {len(values)} | {summary(values)} |')


def summary(values):
    if not values:
        return '-'
    v = np.array(values)
    return f'{np.median(v):.2f} ({v.min():.2f} to {v.max():.2f})'


def surround(luminance, elevation, azimuth):
    """Median radiance (weighted by solid angle) of the map in a ring around the direction
    behind a sphere seen from `elevation` with the map turned by `azimuth` (degrees), in the
    renderer's conventions (reflectance-render: EnvMap::direction, Camera)."""
    h, w = luminance.shape
    d, solid = hdr.directions(h, w), hdr.solid_angles(h, w)
    e, a = np.radians(elevation), np.radians(azimuth)
    behind = -np.array([0.0, np.sin(e), np.cos(e)])
    behind = np.array([np.cos(a) * behind[0] + np.sin(a) * behind[2], behind[1],
                       -np.sin(a) * behind[0] + np.cos(a) * behind[2]])
    angle = np.degrees(np.arccos(np.clip(d @ behind, -1, 1)))
    inside = (angle >= SURROUND_DEGREES[0]) & (angle < SURROUND_DEGREES[1])
    values, weights = luminance[inside], solid[inside]
    order = np.argsort(values)
    cumulative = np.cumsum(weights[order])
    return values[order][np.searchsorted(cumulative, cumulative[-1] / 2)]


def view_of(illumination):
    """(probe, elevation, azimuth) of an illumination written probe[@view]."""
    probe, _, view = illumination.partition('@')
    elevation, azimuth = 45.0, 0.0
    if view.startswith('rot'):
        azimuth = float(view[3:])
    elif view.startswith('el'):
        elevation = float(view[2:])
    elif view:
        return None
    return probe, elevation, azimuth


def renders(folder, probes):
    table = collections.defaultdict(list)
    surrounds = {}
    with open(os.path.join(folder, 'manifest.csv')) as f:
        for r in csv.DictReader(f):
            view = view_of(r['illumination'])
            if view is None:
                continue
            if view not in surrounds:
                probe, elevation, azimuth = view
                luminance = hdr.luminance(hdr.read(os.path.join(probes, probe + '.hdr')))
                surrounds[view] = surround(luminance, elevation, azimuth)
            image = read_pfm(os.path.join(folder, r['path']))
            _, rise = cues(image, *(float(r[k]) for k in 'cx cy r'.split()))
            h, w = image.shape
            yy, xx = np.mgrid[0:h, 0:w]
            inside = np.hypot(xx - float(r['cx']), yy - float(r['cy'])) < 0.9 * float(r['r'])
            against = np.log10(np.median(image[inside]) / surrounds[view])
            member = os.path.splitext(os.path.basename(r['path']))[0].split('__')[1]
            table[member].append((against, rise))
    print('| member | renders | against the surroundings: mean ± sd (10-90 %) | rim\'s rise: mean ± sd (10-90 %) |')
    print('|---|---|---|---|')
    for member, values in sorted(table.items()):
        v = np.array(values)
        cells = [f'{c.mean():.2f} ± {c.std():.2f} ({np.percentile(c, 10):.2f} to {np.percentile(c, 90):.2f})'
                 for c in v.T]
        print(f'| {member} | {len(v)} | {cells[0]} | {cells[1]} |')


if __name__ == '__main__':
    if sys.argv[1:2] == ['photos'] and len(sys.argv) == 2:
        photos()
    elif sys.argv[1:2] == ['renders'] and len(sys.argv) == 4:
        renders(sys.argv[2], sys.argv[3])
    elif sys.argv[1:2] == ['colour'] and len(sys.argv) == 2:
        colour()
    else:
        sys.exit(__doc__)
