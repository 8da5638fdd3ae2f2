#!/usr/bin/env python3
"""Real-like materials drawn by another renderer: Blender's Cycles (PyPI `bpy`), issue #68.

Eight physical materials as glTF metallic-roughness assets (Principled BSDF in Blender: a
dielectric's Fresnel from its index of refraction, a metal's from its base colour, a clear coat),
each a unit sphere rendered by scripts/gltf/blender/render.py under each light probe, then
classified by each model with the white reference `reflectance render` computes for that probe
(from a small render under it). Prints, per material and model, right / n and confidently wrong (a wrong label, the truth
outside the prediction set, in domain), with and without the white. Exits 1 when, with the
white, a model gets fewer than --min-right of them right or more than --max-confident
confidently wrong.

    python3 scripts/materials/cycles.py --probes P.txt|P.hdr… --models M1 [M2 …]
        [--bin target/release/reflectance] [--size 256] [--samples 128] --work DIR
        [--min-right F] [--max-confident N]

The materials are not the training members' parameters (data/classes/classes6_real.json): they
are the issue's own description of what people photograph.
"""
import argparse
import collections
import csv
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
BLENDER = os.path.join(HERE, '..', 'gltf', 'blender')
RENDER = os.path.join(BLENDER, 'render.py')
sys.path.insert(0, BLENDER)
from check import probe_files  # noqa: E402 (the probes as the glTF check reads them)
from evaluate import verdict  # noqa: E402

# name: (class, glTF material without its name)
MATERIALS = {
    'billiard_black': ('black_shiny', {'base': 0.02, 'roughness': 0.04, 'ior': 1.5}),
    'lacquer_black': ('black_shiny', {'base': 0.01, 'roughness': 0.4, 'ior': 1.5,
                                      'clearcoat': 1.0, 'clearcoat_roughness': 0.0}),
    'cue_ball': ('white_shiny', {'base': 0.8, 'roughness': 0.05, 'ior': 1.5}),
    'glazed_ceramic': ('white_shiny', {'base': 0.75, 'roughness': 0.02, 'ior': 1.55}),
    'plastic_grey': ('gray_shiny', {'base': 0.2, 'roughness': 0.1, 'ior': 1.5}),
    'plaster': ('white_matte', {'base': 0.85, 'roughness': 1.0, 'ior': 1.5}),
    'rubber_black': ('black_matte', {'base': 0.04, 'roughness': 0.6, 'ior': 1.5}),
    'steel_polished': ('chrome', {'base': 0.55, 'roughness': 0.0, 'metal': True}),
}


def parse():
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--probes', nargs='+', required=True,
                   help='.hdr probes, or a text file listing them')
    p.add_argument('--models', nargs='+', required=True)
    p.add_argument('--bin', default='target/release/reflectance')
    p.add_argument('--size', type=int, default=256)
    p.add_argument('--samples', type=int, default=128)
    p.add_argument('--work', required=True)
    p.add_argument('--min-right', type=float, default=0.0)
    p.add_argument('--max-confident', type=int)
    return p.parse_args()


def material(name, m):
    """A glTF material from a MATERIALS entry (KHR extensions for the index and the coat)."""
    base = m['base']
    out = {'name': name, 'pbrMetallicRoughness': {
        'baseColorFactor': [base, base, base, 1.0],
        'metallicFactor': 1.0 if m.get('metal') else 0.0,
        'roughnessFactor': m['roughness']}}
    ext = {}
    if 'ior' in m:
        ext['KHR_materials_ior'] = {'ior': m['ior']}
    if 'clearcoat' in m:
        ext['KHR_materials_clearcoat'] = {'clearcoatFactor': m['clearcoat'],
                                          'clearcoatRoughnessFactor': m['clearcoat_roughness']}
    if ext:
        out['extensions'] = ext
    return out, list(ext)


def write_assets(args, work):
    """The sphere `reflectance gltf` writes, with each material in turn."""
    template = os.path.join(work, 'template')
    os.makedirs(template, exist_ok=True)
    subprocess.run([args.bin, 'gltf', '--rho-d', '0.5', '--rho-s', '0', '--alpha', '0',
                    '--out', os.path.join(template, 'sphere.gltf')], check=True,
                   stdout=subprocess.DEVNULL)
    with open(os.path.join(template, 'sphere.gltf')) as f:
        sphere = json.load(f)
    paths = []
    for name, (_, m) in MATERIALS.items():
        asset = json.loads(json.dumps(sphere))
        gltf_material, used = material(name, m)
        asset['materials'] = [gltf_material]
        asset.pop('extensionsUsed', None)
        if used:
            asset['extensionsUsed'] = used
        path = os.path.join(work, f'{name}.gltf')
        with open(path, 'w') as f:
            json.dump(asset, f)
        paths.append(path)
    return paths


def whites(args, probes, work):
    """Each probe's white, as the manifest of a small render of one class under it gives it."""
    classes = os.path.join(work, 'white.json')
    with open(classes, 'w') as f:
        json.dump({'classes': [{'name': 'white', 'rho_d': 0.9, 'rho_s': 0.0, 'alpha': 0.0}]}, f)
    listed = os.path.join(work, 'probes.txt')
    with open(listed, 'w') as f:
        f.write(''.join(f'{p}\n' for p in probes))
    out = os.path.join(work, 'white')
    subprocess.run([args.bin, 'render', '--probes', listed, '--classes', classes, '--out', out,
                    '--size', '72'], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    with open(os.path.join(out, 'manifest.csv')) as f:
        return {row['illumination']: row['white'] for row in csv.DictReader(f)}


def main():
    args = parse()
    work = os.path.abspath(args.work)
    renders = os.path.join(work, 'renders')
    os.makedirs(renders, exist_ok=True)
    assets = write_assets(args, work)
    probes = probe_files(args.probes)
    subprocess.run([sys.executable, RENDER, '--probes', *probes, '--assets', *assets,
                    '--out', renders, '--size', str(args.size), '--samples', str(args.samples)],
                   check=True, stdout=subprocess.DEVNULL)
    white = whites(args, probes, work)
    centre, r = (args.size - 1) / 2, args.size / 2.2
    rows, failed = [], False
    for probe in probes:
        illum = os.path.splitext(os.path.basename(probe))[0]
        for name, (cls, _) in MATERIALS.items():
            rows.append([os.path.join(renders, f'{illum}__{name}.pfm'), cls, illum, centre,
                         centre, r, white[illum]])
    for with_white in (True, False):
        manifest = os.path.join(work, f'manifest{"" if with_white else "_nowhite"}.csv')
        with open(manifest, 'w', newline='') as f:
            out = csv.writer(f)
            out.writerow(['path', 'class', 'illumination', 'cx', 'cy', 'r', 'white'])
            out.writerows(r[:6] + [r[6] if with_white else ''] for r in rows)
        for model in args.models:
            right, n, confident = report(args, manifest, model, with_white)
            if with_white and (right < args.min_right * n or (
                    args.max_confident is not None and confident > args.max_confident)):
                failed = True
    sys.exit(1 if failed else 0)


def report(args, manifest, model, with_white):
    """Print the model's answers on the manifest; (right, n, confidently wrong)."""
    out = manifest.replace('.csv', f'_{model.strip("/").replace("/", "_")}.csv')
    subprocess.run([args.bin, 'predict', '--model', model, '--manifest', manifest, '--out', out],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    tally = collections.defaultdict(lambda: [0, 0, 0])
    with open(out) as f:
        for row in csv.DictReader(f):
            name = os.path.basename(row['path']).split('__')[1].rsplit('.', 1)[0]
            truth = MATERIALS[name][0]
            v = verdict(row['label'], truth, row['set'].split(), row['in_domain'] == 'true')
            t = tally[name]
            t[1] += 1
            t[0] += v == 'right'
            t[2] += v == 'confidently wrong'
    print(f'## {model}, {"with" if with_white else "without"} white')
    total = [sum(t[i] for t in tally.values()) for i in range(3)]
    print(f'all: {total[0]}/{total[1]} right, {total[2]} confidently wrong')
    for name in MATERIALS:
        t = tally[name]
        print(f'{name} ({MATERIALS[name][0]}): {t[0]}/{t[1]} right, {t[2]} confidently wrong')
    return total


if __name__ == '__main__':
    main()
