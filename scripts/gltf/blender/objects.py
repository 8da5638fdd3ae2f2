"""Path-trace objects of other shapes in Blender (PyPI `bpy`), with their camera-space normals.

Each class's material is taken from its exported glTF asset (`reflectance gltf`: a sphere
with it) and put on an object built in Blender: a torus tilted to show its hole, Suzanne
(subdivided, smooth: concave, with creases), a three-ball metaball blob (crevices) or a
capsule; or the unit sphere itself, as a control. Cycles draws it under each light probe through render.py's camera and light, so
self-shadowing and interreflection are in the photograph, as in a real one, and writes its
normal pass beside it:

    OUT/<probe>__<class>.pfm           linear RGB, premultiplied by coverage, bottom row first
    OUT/normals.png                    16-bit RGBA, n = 2v/65535 − 1 in the camera's axes
                                       (+X right, +Y up, +Z toward the camera), alpha 0 off
                                       the object (coverage under one half)
    OUT/<probe>__<class>.normals.png   the same file, linked beside each photograph

The normal pass is world space and filtered over each pixel like the colour; the normals are
turned into the camera's axes and renormalized (an edge pixel averages normals across the
silhouette, as any renderer's pass does).

    python3 scripts/gltf/blender/objects.py --shape torus|suzanne|blob|capsule|sphere \
        --probes P1.hdr [P2.hdr …] --assets A.gltf [B.glb …] --out DIR \
        [--size 256] [--samples 256] [--seed 1]
"""

import argparse
import math
import os
import struct
import sys
import time
import zlib

import bpy
from mathutils import Matrix, Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import render  # noqa: E402  (render.py beside this file: the scene, the probe, PFM)

SHAPES = ("torus", "suzanne", "blob", "capsule", "sphere")


def parse():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--shape", choices=SHAPES, required=True)
    p.add_argument("--probes", nargs="+", required=True)
    p.add_argument("--assets", nargs="+", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--samples", type=int, default=256)
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    args.engine = "cycles"
    return args


def build(shape):
    """The object, about the unit sphere's place (the frame is 2.2 wide), smooth-shaded."""
    if shape == "torus":
        bpy.ops.mesh.primitive_torus_add(major_radius=0.68, minor_radius=0.3,
                                         major_segments=96, minor_segments=48,
                                         rotation=(math.radians(35), math.radians(20), 0.0))
    elif shape == "suzanne":
        # Her face (−Y) turned to the camera (+X) and tipped 30° up: the eyes' hollows show.
        bpy.ops.mesh.primitive_monkey_add(size=1.5, rotation=(math.radians(-30), 0.0, math.radians(90)))
        modifier = bpy.context.object.modifiers.new("subdivision", "SUBSURF")
        modifier.levels = modifier.render_levels = 2
    elif shape == "blob":
        bpy.ops.object.metaball_add(type="BALL", radius=0.62, location=(0.0, -0.3, -0.2))
        ball = bpy.context.object
        ball.data.resolution = ball.data.render_resolution = 0.02
        for location, radius in (((0.0, 0.35, -0.15), 0.55), ((0.1, 0.0, 0.4), 0.5)):
            element = ball.data.elements.new()
            element.co = location
            element.radius = radius
    elif shape == "sphere":
        bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=128, ring_count=64)
    elif shape == "capsule":
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, segments=96, ring_count=48)
        capsule = bpy.context.object
        for vertex in capsule.data.vertices:
            vertex.co.z += 0.4 if vertex.co.z > 0 else -0.4 if vertex.co.z < 0 else 0.0
        capsule.rotation_euler = (math.radians(50), math.radians(30), 0.0)
    obj = bpy.context.object
    if obj.type == "MESH":
        bpy.ops.object.shade_smooth()
    return obj


def material_of(path):
    """The material of the class's glTF asset; the asset's own objects removed."""
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=path)
    imported = [o for o in bpy.data.objects if o not in before]
    material = next(slot.material for o in imported if o.type == "MESH"
                    for slot in o.material_slots if slot.material)
    for obj in imported:
        bpy.data.objects.remove(obj, do_unlink=True)
    return material


def write_png16(path, width, height, rows):
    """`rows` (top first) of RGBA 16-bit samples as a PNG, written whole or not at all."""
    raw = b"".join(b"\x00" + struct.pack(">%dH" % len(row), *row) for row in rows)

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 16, 6, 0, 0, 0)
    with open(path + ".part", "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
                + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))
    os.replace(path + ".part", path)


def camera_normals(camera, normal, width, height):
    """World-space pass (RGBA floats, bottom row first) → 16-bit RGBA rows, top first."""
    to_camera = camera.matrix_world.to_3x3().normalized().transposed()
    rows = []
    for y in reversed(range(height)):
        row = []
        for x in range(width):
            i = y * width + x
            n = to_camera @ Vector(normal[4 * i: 4 * i + 3])
            if normal[4 * i + 3] < 0.5 or n.length < 1e-6:
                row += (0, 0, 0, 0)
                continue
            n.normalize()
            row += [round((c + 1.0) * 0.5 * 65535) for c in n] + [65535]
        rows.append(row)
    return rows


def normal_material():
    """An emission of the world-space shading normal, encoded (n + 1) / 2 (no negative light)."""
    material = bpy.data.materials.new("normal pass")
    material.use_nodes = True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    nodes.clear()
    geometry = nodes.new("ShaderNodeNewGeometry")
    encode = nodes.new("ShaderNodeVectorMath")
    encode.operation = "MULTIPLY_ADD"
    encode.inputs[1].default_value = (0.5, 0.5, 0.5)
    encode.inputs[2].default_value = (0.5, 0.5, 0.5)
    emission = nodes.new("ShaderNodeEmission")
    output = nodes.new("ShaderNodeOutputMaterial")
    links.new(geometry.outputs["Normal"], encode.inputs[0])
    links.new(encode.outputs["Vector"], emission.inputs["Color"])
    links.new(emission.outputs["Emission"], output.inputs["Surface"])
    return material


def rendered(scene, path):
    """(width, height, RGBA floats bottom row first) of one render."""
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(path)
    image.colorspace_settings.name = "Non-Color"
    width, height = image.size
    pixels = list(image.pixels)
    bpy.data.images.remove(image)
    os.remove(path)
    return width, height, pixels


def render_with_normals(scene, out_path, normals_path, normal_pass):
    """The photograph as PFM; once per object, its normals as a 16-bit PNG (a second render
    with every material overridden by the normal's emission)."""
    width, height, colour = rendered(scene, out_path + ".exr")
    render.write_pfm(out_path, width, height, colour)
    if os.path.exists(normals_path):
        return
    layer = scene.view_layers[0]
    samples = scene.cycles.samples
    layer.material_override, scene.cycles.samples = normal_pass, 64
    _, _, encoded = rendered(scene, normals_path + ".exr")
    layer.material_override, scene.cycles.samples = None, samples
    normal = []
    for i in range(width * height):
        a = max(encoded[4 * i + 3], 1e-6)
        normal += [2.0 * encoded[4 * i + c] / a - 1.0 for c in range(3)] + [encoded[4 * i + 3]]
    rows = camera_normals(scene.camera, normal, width, height)
    write_png16(normals_path, width, height, rows)


def main():
    args = parse()
    os.makedirs(args.out, exist_ok=True)
    scene = render.empty_scene(args)
    normal_pass = normal_material()
    materials = {os.path.splitext(os.path.basename(a))[0]: material_of(os.path.abspath(a))
                 for a in args.assets}
    obj = build(args.shape)
    if obj.type == "MESH" or obj.type == "META":
        obj.data.materials.clear()
    for probe in args.probes:
        render.set_probe(scene, os.path.abspath(probe))
        stem = os.path.splitext(os.path.basename(probe))[0]
        for name, material in materials.items():
            out = os.path.join(args.out, f"{stem}__{name}.pfm")
            if os.path.exists(out):
                continue
            started = time.time()
            obj.data.materials.clear()
            obj.data.materials.append(material)
            shared = os.path.join(args.out, "normals.png")
            render_with_normals(scene, out, shared, normal_pass)
            beside = os.path.splitext(out)[0] + ".normals.png"
            if not os.path.exists(beside):
                os.link(shared, beside)
            print(f"{out} {time.time() - started:.1f}s", flush=True)


if __name__ == "__main__":
    sys.exit(main())
