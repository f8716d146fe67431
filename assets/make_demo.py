#!/usr/bin/env python3
"""Writes assets/demo.glb, the bundled demo scene: a Cornell-style box lit by an emissive ceiling panel, with a
rough gold sphere, a glass sphere and a white diffuse sphere. Pure Python (no dependencies).

Run from the repository root:  python3 assets/make_demo.py
"""
import json
import math
import struct
import sys

buffer = bytearray()
accessors, views, meshes, nodes, materials = [], [], [], [], []


def add_view(data, target):
    while len(buffer) % 4:
        buffer.append(0)
    views.append({"buffer": 0, "byteOffset": len(buffer), "byteLength": len(data), "target": target})
    buffer.extend(data)
    return len(views) - 1


def add_accessor(values, comps, ctype, kind, target, minmax=False):
    fmt = {5126: "f", 5125: "I"}[ctype]
    flat = [c for v in values for c in (v if comps > 1 else (v,))]
    view = add_view(struct.pack("<%d%s" % (len(flat), fmt), *flat), target)
    acc = {"bufferView": view, "componentType": ctype, "count": len(values), "type": kind}
    if minmax:
        acc["min"] = [min(v[i] for v in values) for i in range(comps)]
        acc["max"] = [max(v[i] for v in values) for i in range(comps)]
    accessors.append(acc)
    return len(accessors) - 1


def add_mesh(name, positions, normals, indices, material):
    p = add_accessor(positions, 3, 5126, "VEC3", 34962, minmax=True)
    n = add_accessor(normals, 3, 5126, "VEC3", 34962)
    i = add_accessor(indices, 1, 5125, "SCALAR", 34963)
    meshes.append({"name": name, "primitives": [{"attributes": {"POSITION": p, "NORMAL": n}, "indices": i,
                                                  "material": material}]})
    nodes.append({"name": name, "mesh": len(meshes) - 1})


def add_material(name, **kw):
    materials.append(dict(name=name, **kw))
    return len(materials) - 1


def lambert(name, rgb):
    return add_material(name, pbrMetallicRoughness={"baseColorFactor": rgb + [1.0], "metallicFactor": 0.0},
                        extensions={"KHR_materials_specular": {"specularFactor": 0.0}})


def quad(name, corners, material):
    """corners counter-clockwise seen from the front."""
    a, b, c, d = corners
    n = cross(sub(b, a), sub(d, a))
    ln = math.sqrt(sum(x * x for x in n))
    n = [x / ln for x in n]
    add_mesh(name, [a, b, c, d], [n] * 4, [0, 1, 2, 0, 2, 3], material)


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def sphere(name, center, radius, material, rings=48, segments=96):
    pos, nor, idx = [], [], []
    for r in range(rings + 1):
        theta = math.pi * r / rings
        for s in range(segments + 1):
            phi = 2 * math.pi * s / segments
            n = [math.sin(theta) * math.sin(phi), math.cos(theta), math.sin(theta) * math.cos(phi)]
            nor.append(n)
            pos.append([center[i] + radius * n[i] for i in range(3)])
    for r in range(rings):
        for s in range(segments):
            a = r * (segments + 1) + s
            b = a + segments + 1
            idx += [a, b, a + 1, a + 1, b, b + 1]
    add_mesh(name, pos, nor, idx, material)


white = lambert("white", [0.73, 0.73, 0.73])
red = lambert("red", [0.65, 0.05, 0.05])
green = lambert("green", [0.12, 0.45, 0.15])
light = add_material("light", pbrMetallicRoughness={"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0},
                     emissiveFactor=[1.0, 0.85, 0.7],
                     extensions={"KHR_materials_emissive_strength": {"emissiveStrength": 12.0},
                                 "KHR_materials_specular": {"specularFactor": 0.0}})
gold = add_material("gold", pbrMetallicRoughness={"baseColorFactor": [1.0, 0.78, 0.34, 1], "metallicFactor": 1.0,
                                                  "roughnessFactor": 0.3})
glass = add_material("glass", pbrMetallicRoughness={"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0.0,
                                                    "roughnessFactor": 0.0},
                     extensions={"KHR_materials_transmission": {"transmissionFactor": 1.0},
                                 "KHR_materials_ior": {"ior": 1.5}})

s = 1.0  # the box spans [-1, 1] in x and z, [0, 2] in y
quad("floor", [[-s, 0, s], [s, 0, s], [s, 0, -s], [-s, 0, -s]], white)
quad("ceiling", [[-s, 2, -s], [s, 2, -s], [s, 2, s], [-s, 2, s]], white)
quad("back", [[-s, 0, -s], [s, 0, -s], [s, 2, -s], [-s, 2, -s]], white)
quad("left", [[-s, 0, s], [-s, 0, -s], [-s, 2, -s], [-s, 2, s]], red)
quad("right", [[s, 0, -s], [s, 0, s], [s, 2, s], [s, 2, -s]], green)
l = 0.3
quad("light", [[-l, 1.99, -l], [l, 1.99, -l], [l, 1.99, l], [-l, 1.99, l]], light)
sphere("gold_sphere", [-0.45, 0.35, -0.3], 0.35, gold)
sphere("glass_sphere", [0.45, 0.3, 0.25], 0.3, glass)
sphere("white_sphere", [0.0, 0.2, 0.55], 0.2, white)

nodes.append({"name": "camera", "camera": 0, "translation": [0, 1, 3.9]})
gltf = {
    "asset": {"version": "2.0", "generator": "nimbus assets/make_demo.py"},
    "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular", "KHR_materials_transmission",
                       "KHR_materials_ior"],
    "scene": 0,
    "scenes": [{"nodes": list(range(len(nodes)))}],
    "nodes": nodes,
    "meshes": meshes,
    "materials": materials,
    "cameras": [{"type": "perspective", "perspective": {"yfov": math.radians(38), "aspectRatio": 1.0,
                                                         "znear": 0.01}}],
    "accessors": accessors,
    "bufferViews": views,
    "buffers": [{"byteLength": len(buffer)}],
}
while len(buffer) % 4:
    buffer.append(0)
js = json.dumps(gltf, separators=(",", ":")).encode()
while len(js) % 4:
    js += b" "
out = sys.argv[1] if len(sys.argv) > 1 else "assets/demo.glb"
with open(out, "wb") as f:
    total = 12 + 8 + len(js) + 8 + len(buffer)
    f.write(struct.pack("<III", 0x46546C67, 2, total))
    f.write(struct.pack("<II", len(js), 0x4E4F534A) + js)
    f.write(struct.pack("<II", len(buffer), 0x004E4942) + bytes(buffer))
print("wrote", out, total, "bytes")
