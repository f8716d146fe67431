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

The other benchmark scenes are the bundled `assets/cloud.gltf` and `../shared/validation/smoke-sun/scene.gltf`.
"""
import json
import math
import os
import sys

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
                       ("doorgap", doorgap)):
        b, extras = make()
        out = os.path.join(SCENES, f"{name}.gltf")
        b.write(out, GENERATOR, scene_extras=extras)
        print("wrote", os.path.relpath(out, ROOT))
    if os.path.isdir(os.path.join(SHARED, "realworld", "gltf", "DamagedHelmet")):
        helmet(os.path.join(SCENES, "helmet.gltf"))
    else:
        print("skipped helmet.gltf: ../shared/realworld/gltf/DamagedHelmet is missing")


if __name__ == "__main__":
    main()
