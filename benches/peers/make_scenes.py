#!/usr/bin/env python3
"""Write the peer benchmark's own scenes (issue 15) into benches/peers/scenes/.

Run from the repository root: `python3 benches/peers/make_scenes.py`. Deterministic: a rerun gives the same bytes.

- `cornell.gltf`: a surfaces-only Cornell box (Lambert walls, two rotated boxes, one quad light under the ceiling).
- `haze.gltf`: a thin homogeneous haze (index-matched 6 x 3 x 6 m box, sigma_s 0.08, sigma_a 0.02 /m, g 0.3) lit by a
  point light inside it, over a floor just below the box.
- `plume.gltf`: a dense production-like plume: `../shared/vdb-corpus/real/mjurczyk_smoke.vdb` at density scale 40
  (sigma_t up to 229 /m, about 10x the validation scene `smoke-sun`), albedo 0.9, under a sun and a blue sky.
- `helmet.gltf` (git-ignored, because it refers to `../shared/realworld/`): DamagedHelmet's mesh with its base colour
  and emissive textures on a Lambert material (so that Mitsuba renders the same BSDF), 15,453 textured emissive
  triangles, over a floor under a dim sky. Its buffers and images are referenced in place, never copied.
- `backlit.gltf` (issue 34, path guiding): the bundled `assets/cloud.vdb` at density scale 120 (optical depth about
  60 through its middle along the view), albedo 0.99, g 0.5, with the sun behind it shining toward the camera, under
  a dim sky; no ground. Light reaches the camera's side of the cloud only after many scattering events.
- `doorgap.gltf` (issue 34): a closed 4 x 2.5 x 4 m room of thick white walls filled with haze (sigma_s 0.3,
  sigma_a 0.01 /m, g 0.3), lit only by the sun through a 0.2 m gap in one wall; the camera inside. Most of the haze
  and the walls see the sun only through the lit patch and the beam.

- `baffle.gltf` (issue 34): a glossy Cornell box lit only indirectly: a quad light facing the ceiling, lying on a
  baffle that hides it from the room, so that light reaches the room only from the lit patch of the (Lambertian)
  ceiling. Floor, back wall and the two boxes are a white rough metal (metallic 1, base colour 1, so that the glTF
  Fresnel term is exactly 1 and Mitsuba's and Cycles' GGX conductors of reflectance 1 are the same BSDF; roughness
  0.3 and 0.2); the side walls, ceiling and baffle are Lambertian.

- `mirrors.gltf` (issue 33): the Cornell box with two perfect-mirror spheres (metallic 1, roughness 0; 2,304 smooth
  triangles each) in place of the boxes.
- `glass.gltf` (issue 33): a smooth glass sphere (ior 1.5) holding a scattering, absorbing medium (nimbus_medium
  sigma_a [0.6, 0.25, 0.1], sigma_s 0.3 /m) over a checkerboard floor (`checker.png`, written here), lit by a quad
  light and a dim sky.
- `dense.gltf` + `dense.bin` (git-ignored, 24 MB; issue 33): the Cornell box with a 1,002,528-triangle bumpy sphere
  (Lambert, smooth vertex normals) in place of the boxes.

The other benchmark scenes are the bundled `assets/cloud.gltf` and `../shared/validation/smoke-sun/scene.gltf`.
"""
import base64
import json
import math
import os
import struct
import sys
import zlib

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "assets"))
from gltf_writer import GltfBuilder  # noqa: E402

SCENES = os.path.join(ROOT, "benches", "peers", "scenes")
SHARED = os.path.normpath(os.path.join(ROOT, "..", "shared"))
GENERATOR = "nimbus benches/peers/make_scenes.py"


def rotation_y(deg):
    h = math.radians(deg) / 2
    return [0.0, math.sin(h), 0.0, math.cos(h)]


def cornell():
    b = GltfBuilder()
    white = b.lambert("white", [0.73, 0.73, 0.73])
    red = b.lambert("red", [0.63, 0.065, 0.05])
    green = b.lambert("green", [0.14, 0.45, 0.091])
    b.cornell_walls(white, red, green)   # the box spans [-1, 1] in x and z, [0, 2] in y
    b.box("tall_box", [-0.3, 0.0, -0.3], [0.3, 1.2, 0.3], white, translation=[-0.35, 0.0, -0.3],
          rotation=rotation_y(17))
    b.box("short_box", [-0.3, 0.0, -0.3], [0.3, 0.6, 0.3], white, translation=[0.35, 0.0, 0.35],
          rotation=rotation_y(-17))
    light = b.emitter("light", [1.0, 0.85, 0.6], 20.0)
    y = 1.999
    b.quad("light", [[-0.25, y, -0.2], [0.25, y, -0.2], [0.25, y, 0.2], [-0.25, y, 0.2]], light)
    b.camera("camera", eye=[0.0, 1.0, 3.9], target=[0.0, 1.0, 0.0], yfov_deg=39, aspect=1.0)
    return b, {"max_bounces": 16}


def mirrors():
    b = GltfBuilder()
    white = b.lambert("white", [0.73, 0.73, 0.73])
    red = b.lambert("red", [0.63, 0.065, 0.05])
    green = b.lambert("green", [0.14, 0.45, 0.091])
    b.cornell_walls(white, red, green)   # the box spans [-1, 1] in x and z, [0, 2] in y
    mirror = b.mirror("mirror", [0.95, 0.95, 0.95])
    b.sphere("mirror_left", [-0.42, 0.4, -0.3], 0.4, mirror, rings=24, segments=48)
    b.sphere("mirror_right", [0.45, 0.35, 0.35], 0.35, mirror, rings=24, segments=48)
    light = b.emitter("light", [1.0, 0.85, 0.6], 20.0)
    y = 1.999
    b.quad("light", [[-0.25, y, -0.2], [0.25, y, -0.2], [0.25, y, 0.2], [-0.25, y, 0.2]], light)
    b.camera("camera", eye=[0.0, 1.0, 3.9], target=[0.0, 1.0, 0.0], yfov_deg=39, aspect=1.0)
    return b, {"max_bounces": 16}


def baffle():
    b = GltfBuilder()
    white = b.lambert("white", [0.73, 0.73, 0.73])
    red = b.lambert("red", [0.63, 0.065, 0.05])
    green = b.lambert("green", [0.14, 0.45, 0.091])
    # white metals: base colour 1 makes the glTF Fresnel term (Schlick, F0 = base colour) exactly 1
    metal = b.add_material("rough_metal", pbrMetallicRoughness={"baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                                                                "metallicFactor": 1.0, "roughnessFactor": 0.3})
    glossy = b.add_material("glossy_metal", pbrMetallicRoughness={"baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                                                                  "metallicFactor": 1.0, "roughnessFactor": 0.2})
    s = 1.0   # the box spans [-1, 1] in x and z, [0, 2] in y, open toward +z (the camera)
    b.quad("floor", [[-s, 0, s], [s, 0, s], [s, 0, -s], [-s, 0, -s]], metal)
    b.quad("ceiling", [[-s, 2, -s], [s, 2, -s], [s, 2, s], [-s, 2, s]], white)
    b.quad("back", [[-s, 0, -s], [s, 0, -s], [s, 2, -s], [-s, 2, -s]], metal)
    b.quad("left", [[-s, 0, s], [-s, 0, -s], [-s, 2, -s], [-s, 2, s]], red)
    b.quad("right", [[s, 0, -s], [s, 0, s], [s, 2, s], [s, 2, -s]], green)
    b.box("tall_box", [-0.3, 0.0, -0.3], [0.3, 1.2, 0.3], glossy, translation=[-0.35, 0.0, -0.3],
          rotation=rotation_y(17))
    b.box("short_box", [-0.3, 0.0, -0.3], [0.3, 0.6, 0.3], glossy, translation=[0.35, 0.0, 0.35],
          rotation=rotation_y(-17))
    # the baffle: a white slab under the light, wider than it on every side; the light lies on its top face,
    # facing the ceiling, so that no point below the slab's top sees the light's emitting face
    b.box("baffle", [-0.4, 1.70, -0.45], [0.4, 1.74, 0.15], white)
    light = b.emitter("light", [1.0, 0.85, 0.6], 60.0)
    y = 1.741
    b.quad("light", [[-0.25, y, 0.0], [0.25, y, 0.0], [0.25, y, -0.3], [-0.25, y, -0.3]], light)
    b.camera("camera", eye=[0.0, 1.0, 3.9], target=[0.0, 1.0, 0.0], yfov_deg=39, aspect=1.0)
    return b, {"max_bounces": 16}


def checker_png(path, n=256, squares=8):
    """an n x n sRGB PNG of squares x squares light and dark squares, written with zlib alone (deterministic)"""
    light, dark = (200, 190, 170), (40, 60, 90)
    rows = b""
    for y in range(n):
        row = bytearray([0])   # filter: none
        for x in range(n):
            row += bytes(light if ((x * squares // n) + (y * squares // n)) % 2 == 0 else dark)
        rows += bytes(row)
    chunk = lambda kind, data: (struct.pack(">I", len(data)) + kind + data
                                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", n, n, 8, 2, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(rows, 9)) + chunk(b"IEND", b""))
    with open(path, "wb") as f:
        f.write(png)


def glass():
    """the glass scene; `write_gltf` embeds its buffer, and the floor's texture is `checker.png` beside it"""
    b = GltfBuilder()
    floor = b.add_material("checker_floor", pbrMetallicRoughness={"baseColorTexture": {"index": 0},
                                                                  "metallicFactor": 0.0},
                           extensions={"KHR_materials_specular": {"specularFactor": 0.0}})
    s = 4.0
    geometry = b.add_geometry([[-s, 0, s], [s, 0, s], [s, 0, -s], [-s, 0, -s]], [[0, 1, 0]] * 4, [0, 1, 2, 0, 2, 3])
    uv = b.add_accessor([[0, 0], [4, 0], [4, 4], [0, 4]], 2, 5126, "VEC2", 34962)
    b.mesh_from_accessors("floor", geometry, floor)
    b.meshes[-1]["primitives"][0]["attributes"]["TEXCOORD_0"] = uv
    glass_material = b.dielectric("glass", ior=1.5, extras={"nimbus_medium": {
        "sigma_a": [0.6, 0.25, 0.1], "sigma_s": [0.3, 0.3, 0.3], "anisotropy": 0.0}})
    b.sphere("glass_sphere", [0.0, 0.6, 0.0], 0.6, glass_material, rings=48, segments=96)
    light = b.emitter("light", [1.0, 0.9, 0.75], 12.0)
    y = 3.0
    b.quad("light", [[-0.6, y, -0.6], [0.6, y, -0.6], [0.6, y, 0.6], [-0.6, y, 0.6]], light)
    b.camera("camera", eye=[0.0, 1.5, 3.4], target=[0.0, 0.5, 0.0], yfov_deg=40, aspect=1.0)
    g = b.to_gltf(GENERATOR, scene_extras={"max_bounces": 32, "nimbus_environment": {"color": [0.05, 0.06, 0.08]}})
    g["images"] = [{"uri": "checker.png"}]
    g["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
    g["textures"] = [{"sampler": 0, "source": 0}]
    return b, g


def write_gltf(b, g, path):
    """writes glTF `g` with builder `b`'s buffer embedded as a base64 data URI"""
    g["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(b.buffer)).decode()
    with open(path, "w") as f:
        f.write(json.dumps(g, separators=(",", ":")) + "\n")
    print("wrote", os.path.relpath(path, ROOT))


def dense(out_path, rings=709, segments=708):
    """the Cornell box with a bumpy UV sphere of 2 * (rings - 1) * segments triangles (1,002,528 by default; vertex
    normals averaged from the faces), its geometry in `dense.bin` beside the glTF"""
    import numpy as np
    b = GltfBuilder()
    white = b.lambert("white", [0.73, 0.73, 0.73])
    red = b.lambert("red", [0.63, 0.065, 0.05])
    green = b.lambert("green", [0.14, 0.45, 0.091])
    b.cornell_walls(white, red, green)
    light = b.emitter("light", [1.0, 0.85, 0.6], 20.0)
    y = 1.999
    b.quad("light", [[-0.25, y, -0.2], [0.25, y, -0.2], [0.25, y, 0.2], [-0.25, y, 0.2]], light)
    b.camera("camera", eye=[0.0, 1.0, 3.9], target=[0.0, 1.0, 0.0], yfov_deg=39, aspect=1.0)
    g = b.to_gltf(GENERATOR, scene_extras={"max_bounces": 16})
    g["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(b.buffer)).decode()
    # the sphere: poles excluded, rings - 1 rows of vertices, each quad of neighbouring rows two triangles, plus
    # the caps' fans
    theta = np.pi * np.arange(1, rings) / rings
    phi = 2 * np.pi * np.arange(segments) / segments
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    bump = 1.0 + 0.06 * np.sin(7 * th) * np.sin(11 * ph) + 0.02 * np.sin(23 * th + 3 * ph)
    unit = np.stack([np.sin(th) * np.sin(ph), np.cos(th), np.sin(th) * np.cos(ph)], -1)
    center, radius = np.array([0.0, 0.7, 0.0]), 0.6
    pos = (center + radius * bump[..., None] * unit).reshape(-1, 3)
    north = center + radius * np.array([0.0, 1.0, 0.0])
    south = center - radius * np.array([0.0, 1.0, 0.0])
    pos = np.vstack([pos, north, south])
    n_north, n_south = len(pos) - 2, len(pos) - 1
    r, c = np.meshgrid(np.arange(rings - 2), np.arange(segments), indexing="ij")
    a = r * segments + c
    a1 = r * segments + (c + 1) % segments
    b0 = a + segments
    b1 = a1 + segments
    quads = np.stack([np.stack([a, b0, a1], -1), np.stack([a1, b0, b1], -1)], -2).reshape(-1, 3)
    cs = np.arange(segments)
    top = np.stack([np.full(segments, n_north), cs, (cs + 1) % segments], -1)
    last = (rings - 2) * segments
    bottom = np.stack([np.full(segments, n_south), last + (cs + 1) % segments, last + cs], -1)
    tris = np.vstack([top, quads, bottom]).astype(np.uint32)
    face = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
    nor = np.zeros_like(pos)
    for k in range(3):
        np.add.at(nor, tris[:, k], face)
    nor /= np.linalg.norm(nor, axis=1, keepdims=True)
    pos32, nor32 = pos.astype(np.float32), nor.astype(np.float32)
    blobs = [pos32.tobytes(), nor32.tobytes(), tris.tobytes()]
    bin_name = os.path.splitext(os.path.basename(out_path))[0] + ".bin"
    buffer = len(g["buffers"])
    g["buffers"].append({"uri": bin_name, "byteLength": sum(len(x) for x in blobs)})
    offset, first = 0, len(g["accessors"])
    for blob, target in zip(blobs, (34962, 34962, 34963)):
        g["bufferViews"].append({"buffer": buffer, "byteOffset": offset, "byteLength": len(blob), "target": target})
        offset += len(blob)
    view = len(g["bufferViews"]) - 3
    g["accessors"] += [
        {"bufferView": view, "componentType": 5126, "count": len(pos32), "type": "VEC3",
         "min": pos32.min(0).tolist(), "max": pos32.max(0).tolist()},
        {"bufferView": view + 1, "componentType": 5126, "count": len(nor32), "type": "VEC3"},
        {"bufferView": view + 2, "componentType": 5125, "count": tris.size, "type": "SCALAR"}]
    g["meshes"].append({"name": "bumpy_sphere", "primitives": [{
        "attributes": {"POSITION": first, "NORMAL": first + 1}, "indices": first + 2, "material": white}]})
    g["nodes"].append({"name": "bumpy_sphere", "mesh": len(g["meshes"]) - 1})
    g["scenes"][0]["nodes"].append(len(g["nodes"]) - 1)
    with open(os.path.join(os.path.dirname(out_path), bin_name), "wb") as f:
        for blob in blobs:
            f.write(blob)
    with open(out_path, "w") as f:
        f.write(json.dumps(g, separators=(",", ":")) + "\n")
    print(f"wrote {os.path.relpath(out_path, ROOT)} ({len(tris)} sphere triangles)")


def haze():
    b = GltfBuilder()
    b.quad("floor", [[-6, -0.01, 6], [6, -0.01, 6], [6, -0.01, -6], [-6, -0.01, -6]],
           b.lambert("floor", [0.5, 0.5, 0.5]))
    medium = b.medium_boundary("haze", {"sigma_a": [0.02, 0.02, 0.02], "sigma_s": [0.08, 0.08, 0.08],
                                        "anisotropy": 0.3})
    b.box("haze_box", [-3.0, 0.0, -3.0], [3.0, 3.0, 3.0], medium)
    b.lights.append({"name": "bulb", "type": "point", "color": [1.0, 0.8, 0.55], "intensity": 12.0})
    b.add_node({"name": "bulb", "translation": [0.3, 1.2, 0.0],
                "extensions": {"KHR_lights_punctual": {"light": len(b.lights) - 1}}})
    b.camera("camera", eye=[0.0, 1.6, 7.5], target=[0.0, 1.0, 0.0], yfov_deg=45, aspect=1.0)
    return b, {"max_bounces": 32, "nimbus_light_units": "radiometric"}


def plume():
    b = GltfBuilder()
    b.quad("floor", [[-4, 0, 4], [4, 0, 4], [4, 0, -4], [-4, 0, -4]], b.lambert("floor", [0.4, 0.4, 0.4]))
    vdb = os.path.relpath(os.path.join(SHARED, "vdb-corpus", "real", "mjurczyk_smoke.vdb"), SCENES)
    b.volume_node("plume", {"file": vdb, "density_grid": "density", "density_scale": 40.0,
                            "albedo": [0.9, 0.9, 0.9], "anisotropy": 0.3},
                  translation=[0.1, 0.27, 0.0], scale=[0.02, 0.02, 0.02])
    b.directional_light("sun", [-0.5, -0.6, -0.6], [1.0, 0.95, 0.85], 2000.0)
    b.camera("camera", eye=[0.0, 1.0, 3.6], target=[0.0, 0.9, 0.0], yfov_deg=45, aspect=1.0)
    return b, {"max_bounces": 64, "nimbus_environment": {"color": [0.3, 0.45, 0.7]}}


def helmet(out_path):
    """DamagedHelmet (Khronos sample, CC-BY) with a Lambert material; buffers and images stay in ../shared."""
    src_dir = os.path.join(SHARED, "realworld", "gltf", "DamagedHelmet")
    src = json.load(open(os.path.join(src_dir, "DamagedHelmet.gltf")))
    b = GltfBuilder()
    b.quad("floor", [[-4, -1.2, 4], [4, -1.2, 4], [4, -1.2, -4], [-4, -1.2, -4]], b.lambert("floor", [0.5] * 3))
    b.camera("camera", eye=[1.6, 0.4, 2.4], target=[0.0, -0.1, 0.0], yfov_deg=40, aspect=1.0)
    g = b.to_gltf(GENERATOR, scene_extras={"max_bounces": 8, "nimbus_environment": {"color": [0.03, 0.03, 0.04]}})
    g["buffers"][0]["uri"] = "data:application/octet-stream;base64," + __import__("base64").b64encode(
        bytes(b.buffer)).decode()
    rel = os.path.relpath(src_dir, os.path.dirname(out_path))
    nbuf, nview, nacc = len(g["buffers"]), len(g["bufferViews"]), len(g["accessors"])
    nmat, nmesh = len(g["materials"]), len(g["meshes"])
    g["buffers"] += [dict(buf, uri=f"{rel}/{buf['uri']}") for buf in src["buffers"]]
    g["bufferViews"] += [dict(v, buffer=v["buffer"] + nbuf) for v in src["bufferViews"]]
    g["accessors"] += [dict(a, bufferView=a["bufferView"] + nview) for a in src["accessors"]]
    g["images"] = [{"uri": f"{rel}/{img['uri']}"} for img in src["images"]]
    g["samplers"] = src.get("samplers", [{}])
    g["textures"] = src["textures"]
    mat = src["materials"][0]
    g["materials"].append({
        "name": "helmet_lambert",
        "pbrMetallicRoughness": {"baseColorTexture": mat["pbrMetallicRoughness"]["baseColorTexture"],
                                 "metallicFactor": 0.0},
        "emissiveTexture": mat["emissiveTexture"], "emissiveFactor": [1.0, 1.0, 1.0],
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}},
    })
    for mesh in src["meshes"]:
        prims = []
        for p in mesh["primitives"]:
            attrs = {k: v + nacc for k, v in p["attributes"].items() if k in ("POSITION", "NORMAL", "TEXCOORD_0")}
            prims.append({"attributes": attrs, "indices": p["indices"] + nacc, "material": nmat})
        g["meshes"].append({"name": mesh.get("name", "helmet"), "primitives": prims})
    node = dict(src["nodes"][0], mesh=src["nodes"][0]["mesh"] + nmesh)
    g["nodes"].append(node)
    g["scenes"][0]["nodes"].append(len(g["nodes"]) - 1)
    g["extensionsUsed"] = sorted(set(g.get("extensionsUsed", [])) | {"KHR_materials_specular"})
    with open(out_path, "w") as f:
        json.dump(g, f, indent=1)
    print("wrote", os.path.relpath(out_path, ROOT))


def backlit():
    b = GltfBuilder()
    vdb = os.path.relpath(os.path.join(ROOT, "assets", "cloud.vdb"), SCENES)
    b.volume_node("cloud", {"file": vdb, "density_grid": "density", "density_scale": 120.0,
                            "albedo": [0.99, 0.99, 0.99], "anisotropy": 0.5},
                  translation=[0.0, 1.0, 0.0])
    b.directional_light("sun", [0.25, -0.3, 1.0], [1.0, 0.95, 0.85], 2049.0)
    b.camera("camera", eye=[0.0, 1.45, 4.0], target=[0.0, 1.45, 0.0], yfov_deg=28, aspect=1.0)
    return b, {"max_bounces": 128, "nimbus_environment": {"color": [0.03, 0.04, 0.06]}}


def doorgap():
    b = GltfBuilder()
    white = b.lambert("wall", [0.6, 0.6, 0.6])
    t = 0.2
    b.box("floor", [-2 - t, -t, -2 - t], [2 + t, 0.0, 2 + t], white)
    b.box("ceiling", [-2 - t, 2.5, -2 - t], [2 + t, 2.5 + t, 2 + t], white)
    b.box("back", [-2 - t, 0.0, -2 - t], [2 + t, 2.5, -2.0], white)
    b.box("front", [-2 - t, 0.0, 2.0], [2 + t, 2.5, 2 + t], white)
    b.box("left", [-2 - t, 0.0, -2.0], [-2.0, 2.5, 2.0], white)
    b.box("right_a", [2.0, 0.0, -2.0], [2 + t, 2.5, -0.1], white)
    b.box("right_b", [2.0, 0.0, 0.1], [2 + t, 2.5, 2.0], white)
    b.box("lintel", [2.0, 2.0, -0.1], [2 + t, 2.5, 0.1], white)
    medium = b.medium_boundary("haze", {"sigma_a": [0.01, 0.01, 0.01], "sigma_s": [0.3, 0.3, 0.3],
                                        "anisotropy": 0.3})
    b.box("haze_box", [-1.99, 0.01, -1.99], [1.99, 2.49, 1.99], medium)
    b.directional_light("sun", [-1.0, -0.45, 0.15], [1.0, 0.95, 0.85], 20000.0)
    b.camera("camera", eye=[-1.8, 1.3, 1.8], target=[0.6, 0.7, -0.6], yfov_deg=60, aspect=1.0)
    return b, {"max_bounces": 32, "nimbus_environment": {"color": [0.0, 0.0, 0.0]}}


def main():
    os.makedirs(SCENES, exist_ok=True)
    for name, make in (("cornell", cornell), ("haze", haze), ("plume", plume), ("backlit", backlit),
                       ("doorgap", doorgap), ("mirrors", mirrors), ("baffle", baffle)):
        b, extras = make()
        out = os.path.join(SCENES, f"{name}.gltf")
        b.write(out, GENERATOR, scene_extras=extras)
        print("wrote", os.path.relpath(out, ROOT))
    checker_png(os.path.join(SCENES, "checker.png"))
    write_gltf(*glass(), os.path.join(SCENES, "glass.gltf"))
    dense(os.path.join(SCENES, "dense.gltf"))
    if os.path.isdir(os.path.join(SHARED, "realworld", "gltf", "DamagedHelmet")):
        helmet(os.path.join(SCENES, "helmet.gltf"))
    else:
        print("skipped helmet.gltf: ../shared/realworld/gltf/DamagedHelmet is missing")


if __name__ == "__main__":
    main()
