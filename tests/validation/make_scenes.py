#!/usr/bin/env python3
"""Writes Nimbus's own validation scenes into tests/validation/<scene>/ (scene.gltf and any PNG textures).

Run from the repository root: `python3 tests/validation/make_scenes.py`. Pure Python and deterministic; the
references beside each scene come from `make_references.py` (Mitsuba 3, through ../shared/tools/gltf2mitsuba.py).

| scene | what it checks |
|---|---|
| textured-emitter | an emissive panel whose emissiveTexture (NEAREST, sRGB) is a colour pattern: the texture's orientation on an emitter, light sampling of a textured emitter, and MIS with BSDF-sampled hits on it |
| spot-cone | two KHR_lights_punctual spot lights (candela, hard cones, one tilted) over a floor and a box: cone direction, cone angle, photometric units, a spot shadow |
| light-groups | three light groups (`nimbus_light_group` on an emissive panel's node and on a point light's node, `light_group` in `nimbus_environment`) over a finite floor and two boxes, sky visible above the horizon: each group's layer, their sum, and alpha |
| thin-lens | depth of field: a glTF camera with `nimbus_camera` {aperture_radius, focus_distance} over a checkered floor, a sphere near, a box at the focus distance and a sphere far, under a sky and a sun: the lens disk, the focal plane and the blur of near and far things |
| diffuse-transmission | a single-sided leaf with KHR_materials_diffuse_transmission (factor 0.6, a colour of its own) lit from behind by a sun over a floor under a dim sky: the Lambertian transmission seen through the leaf, its glow on the floor in its shadow, both faces scattering alike |
"""
import math
import os
import struct
import sys
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "assets"))
from gltf_writer import GltfBuilder, look_rotation  # noqa: E402

GENERATOR = "nimbus tests/validation/make_scenes.py"


def write_png(path, width, height, rgb_rows):
    """8-bit RGB PNG (no filtering), rows top first, each a list of (r, g, b) bytes."""
    raw = b"".join(b"\x00" + bytes(c for px in row for c in px) for row in rgb_rows)

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) + \
        chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)


def textured_quad(b, name, corners, uvs, material):
    """a quad (corners counter-clockwise seen from the front) with TEXCOORD_0"""
    a, bb, c, d = corners
    e1 = [bb[i] - a[i] for i in range(3)]
    e2 = [d[i] - a[i] for i in range(3)]
    n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]
    ln = math.sqrt(sum(x * x for x in n))
    n = [x / ln for x in n]
    p, nn, i = b.add_geometry(corners, [n] * 4, [0, 1, 2, 0, 2, 3])
    t = b.add_accessor(uvs, 2, 5126, "VEC2", 34962)
    b.meshes.append({"name": name, "primitives": [{"attributes": {"POSITION": p, "NORMAL": nn, "TEXCOORD_0": t},
                                                    "indices": i, "material": material}]})
    return b.add_node({"name": name, "mesh": len(b.meshes) - 1})


def write(b, folder, scene_extras, extra_json=None):
    os.makedirs(folder, exist_ok=True)
    out = os.path.join(folder, "scene.gltf")
    gltf = b.to_gltf(GENERATOR, scene_extras=scene_extras)
    if extra_json:
        gltf.update(extra_json)
    import base64
    import json
    gltf["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(b.buffer)).decode()
    with open(out, "w") as f:
        f.write(json.dumps(gltf, separators=(",", ":")) + "\n")
    print("wrote", os.path.relpath(out))


def textured_emitter():
    folder = os.path.join(HERE, "textured-emitter")
    os.makedirs(folder, exist_ok=True)
    # 4 x 2 texels, top row first: red, green, blue, white / yellow, cyan, magenta, dark grey.
    rows = [[(255, 40, 40), (40, 255, 40), (40, 40, 255), (255, 255, 255)],
            [(255, 255, 40), (40, 255, 255), (255, 40, 255), (60, 60, 60)]]
    write_png(os.path.join(folder, "pattern.png"), 4, 2, rows)
    b = GltfBuilder()
    floor = b.lambert("floor", [0.6, 0.6, 0.6])
    b.quad("floor", [[-2, 0, 2], [2, 0, 2], [2, 0, -2], [-2, 0, -2]], floor)
    white = b.lambert("sphere", [0.8, 0.8, 0.8])
    b.sphere("sphere", [0.35, 0.3, -0.1], 0.3, white, rings=24, segments=48)
    panel = b.add_material("panel", pbrMetallicRoughness={"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0},
                           emissiveFactor=[1.0, 1.0, 1.0], emissiveTexture={"index": 0},
                           extensions={"KHR_materials_emissive_strength": {"emissiveStrength": 2.5},
                                       "KHR_materials_specular": {"specularFactor": 0.0}})
    # The panel stands at z = -0.8 facing +z; uv (0, 0) at its top-left as seen from the front.
    textured_quad(b, "panel", [[-0.8, 0.2, -0.8], [0.8, 0.2, -0.8], [0.8, 1.0, -0.8], [-0.8, 1.0, -0.8]],
                  [[0, 1], [1, 1], [1, 0], [0, 0]], panel)
    b.camera("camera", eye=[-0.4, 0.9, 2.0], target=[0.0, 0.4, -0.4], yfov_deg=45)
    write(b, folder, {"nimbus_environment": {"color": [0.0, 0.0, 0.0]}, "max_bounces": 8},
          {"textures": [{"source": 0, "sampler": 0}],
           "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": 33071, "wrapT": 33071}],
           "images": [{"uri": "pattern.png", "mimeType": "image/png"}]})


def spot_cone():
    folder = os.path.join(HERE, "spot-cone")
    b = GltfBuilder()
    floor = b.lambert("floor", [0.7, 0.7, 0.7])
    b.quad("floor", [[-3, 0, 3], [3, 0, 3], [3, 0, -3], [-3, 0, -3]], floor)
    grey = b.lambert("box", [0.5, 0.6, 0.7])
    b.box("box", [-0.55, 0.0, -0.45], [-0.15, 0.45, -0.05], grey)
    # A wide spot tilted 30 degrees from vertical (cone half-angle 0.5 rad) and a narrow one straight down
    # (0.18 rad); glTF spots shine along the node's -Z. Intensities in candela (/683 = W/sr).
    b.lights.append({"name": "wide", "type": "spot", "color": [1.0, 0.85, 0.6], "intensity": 1500.0,
                     "spot": {"innerConeAngle": 0.5, "outerConeAngle": 0.5}})
    b.add_node({"name": "wide", "translation": [-1.2, 1.6, 0.2],
                "rotation": look_rotation([math.sin(math.radians(30)), -math.cos(math.radians(30)), -0.15]),
                "extensions": {"KHR_lights_punctual": {"light": 0}}})
    b.lights.append({"name": "narrow", "type": "spot", "color": [0.6, 0.8, 1.0], "intensity": 4000.0,
                     "spot": {"innerConeAngle": 0.18, "outerConeAngle": 0.18}})
    b.add_node({"name": "narrow", "translation": [0.9, 1.8, -0.3], "rotation": look_rotation([0.0, -1.0, 0.0]),
                "extensions": {"KHR_lights_punctual": {"light": 1}}})
    b.camera("camera", eye=[0.0, 2.2, 2.6], target=[0.0, 0.0, -0.2], yfov_deg=50)
    write(b, folder, {"nimbus_environment": {"color": [0.0, 0.0, 0.0]}, "max_bounces": 8},
          {"extensionsUsed": ["KHR_lights_punctual", "KHR_materials_specular"]})


def light_groups():
    """Three light groups, each reachable alone by gltf2mitsuba's --only-emitters word (see make_references.py):
    `panel` = the node `panel_light` (word panel_light), `bulb` = the node and light `bulb` (word bulb), `sky` = the
    constant environment (word environment). No other node, material or light name contains one of those words,
    and none of them is a substring of "environment". Units are radiometric (W/sr)."""
    folder = os.path.join(HERE, "light-groups")
    b = GltfBuilder()
    floor = b.lambert("floor", [0.6, 0.6, 0.6])
    # A finite floor: the camera sees its far edge and the sky above it (alpha 0 there).
    b.quad("floor", [[-2.5, 0, 2.5], [2.5, 0, 2.5], [2.5, 0, -2.5], [-2.5, 0, -2.5]], floor)
    b.box("box_tall", [-0.75, 0.0, -0.55], [-0.3, 0.8, -0.1], b.lambert("box_grey", [0.7, 0.7, 0.7]))
    b.box("box_low", [0.2, 0.0, -0.2], [0.7, 0.35, 0.3], b.lambert("box_red", [0.75, 0.3, 0.25]))
    # An emissive quad standing at the back right, facing the boxes and the camera (front = CCW, normal
    # (-0.5, 0, 0.87)); its group comes from the node's extras.
    panel = b.emitter("panel_emission", [1.0, 0.9, 0.75], 4.0)
    c, s_, w = math.cos(math.radians(30)), math.sin(math.radians(30)), 0.35
    x0, z0 = 0.9, -0.9
    b.quad("panel_light", [[x0 - w * c, 0.25, z0 - w * s_], [x0 + w * c, 0.25, z0 + w * s_],
                           [x0 + w * c, 0.95, z0 + w * s_], [x0 - w * c, 0.95, z0 - w * s_]], panel,
           extras={"nimbus_light_group": "panel"})
    # A point light (W/sr: the scene's units are radiometric) in front of the tall box; group on the node.
    b.lights.append({"name": "bulb", "type": "point", "color": [0.6, 0.8, 1.0], "intensity": 2.0})
    b.add_node({"name": "bulb", "translation": [-0.2, 0.9, 0.5], "extras": {"nimbus_light_group": "bulb"},
                "extensions": {"KHR_lights_punctual": {"light": 0}}})
    b.camera("camera", eye=[0.0, 1.1, 3.0], target=[0.0, 0.45, -0.3], yfov_deg=45)
    write(b, folder, {"nimbus_environment": {"color": [0.12, 0.16, 0.24], "light_group": "sky"},
                      "nimbus_light_units": "radiometric", "max_bounces": 8})


def thin_lens():
    """Depth of field: the camera stands 1.1 m above a checkered floor looking slightly down the -z axis; the view
    axis is focused at 3.5 m (the box), the near sphere (about 1.6 m away) and the far sphere (about 7 m) are
    out of focus. With an aperture radius of 0.08 m the circle of confusion, 2 r |1/z - 1/f| radians across, is
    about 10 pixels wide for the near sphere and 4 for the far one (a pixel is 2 tan(20 deg) / 128 = 0.0057 rad)."""
    folder = os.path.join(HERE, "thin-lens")
    b = GltfBuilder()
    light, dark = b.lambert("tile_light", [0.75, 0.75, 0.7]), b.lambert("tile_dark", [0.12, 0.12, 0.15])
    tiles = ([], [])
    size = 0.5
    for i in range(-5, 5):
        for k in range(-18, 6):
            x0, z0 = i * size, k * size
            tiles[(i + k) % 2].append([[x0, 0, z0 + size], [x0 + size, 0, z0 + size], [x0 + size, 0, z0],
                                       [x0, 0, z0]])
    b.quads("floor_light", tiles[0], light)
    b.quads("floor_dark", tiles[1], dark)
    b.sphere("sphere_near", [-0.35, 0.25, 1.45], 0.25, b.lambert("sphere_red", [0.8, 0.2, 0.15]),
             rings=24, segments=48)
    b.box("box_focus", [0.05, 0.0, -0.65], [0.65, 0.6, -0.25], b.lambert("box_green", [0.25, 0.7, 0.3]))
    b.sphere("sphere_far", [-0.9, 0.6, -3.9], 0.6, b.lambert("sphere_blue", [0.2, 0.35, 0.85]),
             rings=24, segments=48)
    b.directional_light("sun", [0.4, -1.0, -0.5], [1.0, 0.95, 0.85], 683.0 * 2.0)
    node = b.camera("camera", eye=[0.0, 1.1, 3.0], target=[0.0, 0.45, -1.0], yfov_deg=40)
    b.nodes[node]["extras"] = {"nimbus_camera": {"aperture_radius": 0.08, "focus_distance": 3.5}}
    write(b, folder, {"nimbus_environment": {"color": [0.35, 0.42, 0.55]}, "max_bounces": 8},
          {"extensionsUsed": ["KHR_lights_punctual"]})


def diffuse_transmission():
    """A leaf (a single-sided quad tilted 37 degrees toward the camera, normal (0, 0.8, 0.6)) with
    KHR_materials_diffuse_transmission: diffuse reflection (1 - 0.6) x green, Lambertian transmission 0.6 x yellow,
    no specular layer (specularFactor 0). The sun shines along (0.25, -0.4, 1), onto the leaf's back and toward
    the camera, so the camera sees the transmitted light; the leaf's shadow on the floor, in front of it, is lit
    by the light it transmits."""
    folder = os.path.join(HERE, "diffuse-transmission")
    b = GltfBuilder()
    floor = b.lambert("floor", [0.7, 0.7, 0.7])
    b.quad("floor", [[-2.5, 0, 2.5], [2.5, 0, 2.5], [2.5, 0, -2.5], [-2.5, 0, -2.5]], floor)
    leaf = b.add_material("leaf", pbrMetallicRoughness={"baseColorFactor": [0.25, 0.6, 0.2, 1.0],
                                                         "metallicFactor": 0.0, "roughnessFactor": 1.0},
                          extensions={"KHR_materials_specular": {"specularFactor": 0.0},
                                      "KHR_materials_diffuse_transmission": {
                                          "diffuseTransmissionFactor": 0.6,
                                          "diffuseTransmissionColorFactor": [0.9, 0.85, 0.3]}})
    c, a = [0.0, 0.55, 0.0], 0.45
    u, v = [1.0, 0.0, 0.0], [0.0, 0.6, -0.8]          # u x v = (0, 0.8, 0.6), the leaf's front normal
    corner = [[c[i] + su * a * u[i] + sv * a * v[i] for i in range(3)]
              for su, sv in [(-1, -1), (1, -1), (1, 1), (-1, 1)]]
    b.quad("leaf", corner, leaf)
    b.directional_light("sun", [0.25, -0.4, 1.0], [1.0, 0.95, 0.85], 683.0 * 3.0)
    b.camera("camera", eye=[0.0, 1.6, 2.8], target=[0.0, 0.35, 0.0], yfov_deg=45)
    write(b, folder, {"nimbus_environment": {"color": [0.08, 0.1, 0.14]}, "max_bounces": 8},
          {"extensionsUsed": ["KHR_lights_punctual", "KHR_materials_specular",
                              "KHR_materials_diffuse_transmission"]})


if __name__ == "__main__":
    textured_emitter()
    spot_cone()
    light_groups()
    thin_lens()
    diffuse_transmission()
