"""Render glTF assets in Blender (PyPI `bpy`) as the project renders its Ward spheres.

Each asset is imported with Blender's own glTF importer and drawn alone, lit only by a
lat-long light probe, through an orthographic camera that sees what `reflectance render`
sees: the unit sphere from 45° of elevation, a frame 2.2 radii wide (so the circle is
cx = cy = (N − 1)/2, r = N/2.2), background 0. The probe's directions are the project's
(docs/rendering.md, ../shared/data/probes/PROVENANCE.md): its +Y up is Blender's +Z, its −Z
(the map's centre) Blender's +X, its +X Blender's −Y, which is a rotation, and it maps every
direction to the same pixel of the map in both conventions, so the map needs no turning.

Writes OUT/<probe>__<asset>.pfm (linear RGB, premultiplied by coverage, bottom row first as
PFM has it) and prints one line per image.

    python3 scripts/gltf/blender/render.py --probes P1.hdr [P2.hdr …] --assets A.gltf [B.glb …]
        --out DIR [--size 128] [--samples 256] [--engine cycles|eevee]
"""

import argparse
import math
import os
import struct
import sys
import time

import bpy  # before addon_utils, which bpy puts on the path
import addon_utils  # noqa: E402

ELEVATION_DEG = 45.0
HALF_WIDTH = 1.1


def parse():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--probes", nargs="+", required=True)
    p.add_argument("--assets", nargs="+", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--samples", type=int, default=256)
    p.add_argument("--engine", choices=["cycles", "eevee"], default="cycles")
    p.add_argument("--seed", type=int, default=1)
    return p.parse_args()


def empty_scene(args):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    if args.engine == "cycles":
        addon_utils.enable("cycles", default_set=True)
        scene.render.engine = "CYCLES"
        cycles = scene.cycles
        cycles.device = "CPU"
        cycles.samples = args.samples
        cycles.use_adaptive_sampling = False
        cycles.use_denoising = False
        cycles.seed = args.seed
        # A pixel is the mean over its square, as the project's renderer draws it.
        cycles.pixel_filter_type = "BOX"
        cycles.max_bounces = 4
        cycles.caustics_reflective = False
        cycles.caustics_refractive = False
    else:
        scene.render.engine = "BLENDER_EEVEE"
        scene.eevee.taa_render_samples = args.samples
    scene.render.resolution_x = args.size
    scene.render.resolution_y = args.size
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.color_mode = "RGBA"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.display_settings.display_device = "sRGB"
    scene.sequencer_colorspace_settings.name = "Linear Rec.709"

    e = math.radians(ELEVATION_DEG)
    cam_data = bpy.data.cameras.new("camera")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 2.0 * HALF_WIDTH
    cam_data.clip_start = 0.1
    cam_data.clip_end = 100.0
    camera = bpy.data.objects.new("camera", cam_data)
    # The project's viewer direction (0, sin e, cos e) in Blender's axes.
    direction = (-math.cos(e), 0.0, math.sin(e))
    camera.location = tuple(10.0 * c for c in direction)
    # Looking at the origin with +Z up: −Z local toward the sphere, +Y local up.
    camera.rotation_mode = "XYZ"
    camera.rotation_euler = (math.pi / 2 - e, 0.0, -math.pi / 2)
    scene.collection.objects.link(camera)
    scene.camera = camera

    world = bpy.data.worlds.new("probe")
    world.use_nodes = True
    scene.world = world
    return scene


def set_probe(scene, path):
    nodes = scene.world.node_tree.nodes
    links = scene.world.node_tree.links
    nodes.clear()
    texture = nodes.new("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(path, check_existing=True)
    texture.image.colorspace_settings.name = "Linear Rec.709"
    texture.interpolation = "Linear"
    texture.projection = "EQUIRECTANGULAR"
    background = nodes.new("ShaderNodeBackground")
    background.inputs["Strength"].default_value = 1.0
    output = nodes.new("ShaderNodeOutputWorld")
    links.new(texture.outputs["Color"], background.inputs["Color"])
    links.new(background.outputs["Background"], output.inputs["Surface"])


def import_asset(scene, path):
    """The asset's objects, alone in the scene (the camera stays)."""
    for obj in list(scene.collection.all_objects):
        if obj.type != "CAMERA":
            bpy.data.objects.remove(obj, do_unlink=True)
    for material in list(bpy.data.materials):
        bpy.data.materials.remove(material)
    bpy.ops.import_scene.gltf(filepath=path)


def write_pfm(path, width, height, rgba):
    """Premultiplied RGBA floats, bottom row first (Blender's order and PFM's)."""
    rgb = bytearray()
    for i in range(width * height):
        rgb += struct.pack("<fff", *rgba[4 * i : 4 * i + 3])
    with open(path + ".part", "wb") as f:
        f.write(b"PF\n%d %d\n-1.0\n" % (width, height))
        f.write(rgb)
    os.replace(path + ".part", path)


def render(scene, out_path):
    exr = out_path + ".exr"
    scene.render.filepath = exr
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(exr)
    image.colorspace_settings.name = "Non-Color"
    pixels = list(image.pixels)
    write_pfm(out_path, image.size[0], image.size[1], pixels)
    bpy.data.images.remove(image)
    os.remove(exr)


def main():
    args = parse()
    os.makedirs(args.out, exist_ok=True)
    scene = empty_scene(args)
    for probe in args.probes:
        set_probe(scene, os.path.abspath(probe))
        stem = os.path.splitext(os.path.basename(probe))[0]
        for asset in args.assets:
            name = os.path.splitext(os.path.basename(asset))[0]
            out = os.path.join(args.out, f"{stem}__{name}.pfm")
            if os.path.exists(out):
                continue
            started = time.time()
            import_asset(scene, os.path.abspath(asset))
            render(scene, out)
            print(f"{out} {time.time() - started:.1f}s", flush=True)


if __name__ == "__main__":
    sys.exit(main())
