#!/usr/bin/env python3
"""Writes assets/demo.glb, the bundled demo scene: a Cornell-style box lit by an emissive ceiling panel, with a
rough gold sphere, a glass sphere and a white diffuse sphere. Pure Python (no dependencies); the glTF plumbing is
in assets/gltf_writer.py.

Run from the repository root:  python3 assets/make_demo.py [OUT.glb]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltf_writer import GltfBuilder  # noqa: E402

b = GltfBuilder()
white = b.lambert("white", [0.73, 0.73, 0.73])
red = b.lambert("red", [0.65, 0.05, 0.05])
green = b.lambert("green", [0.12, 0.45, 0.15])
light = b.emitter("light", [1.0, 0.85, 0.7], 12.0)
gold = b.add_material("gold", pbrMetallicRoughness={"baseColorFactor": [1.0, 0.78, 0.34, 1], "metallicFactor": 1.0,
                                                    "roughnessFactor": 0.3})
glass = b.dielectric("glass", ior=1.5)

b.cornell_walls(white, red, green)  # the box spans [-1, 1] in x and z, [0, 2] in y
l = 0.3
b.quad("light", [[-l, 1.99, -l], [l, 1.99, -l], [l, 1.99, l], [-l, 1.99, l]], light)
b.sphere("gold_sphere", [-0.45, 0.35, -0.3], 0.35, gold)
b.sphere("glass_sphere", [0.45, 0.3, 0.25], 0.3, glass)
b.sphere("white_sphere", [0.0, 0.2, 0.55], 0.2, white)
b.camera("camera", eye=[0, 1, 3.9], yfov_deg=38)

out = sys.argv[1] if len(sys.argv) > 1 else "assets/demo.glb"
total = b.write(out, "nimbus assets/make_demo.py",
                extensions_used=["KHR_materials_emissive_strength", "KHR_materials_specular",
                                 "KHR_materials_transmission", "KHR_materials_ior"])
print("wrote", out, total, "bytes")
