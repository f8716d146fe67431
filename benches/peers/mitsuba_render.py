#!/usr/bin/env python3
"""Render a Nimbus-convention glTF scene with Mitsuba 3 for the peer benchmark (issue 15).

    python3 benches/peers/mitsuba_render.py SCENE.gltf OUT.exr --spp N --res W [--threads T] [--seed S]
            [--integrator volpath|volpathmis] [--passes P] [--variant llvm_ad_rgb]

The translation is `../shared/tools/gltf2mitsuba.py` (imported as a module), with two additions it lacks:
- a material's `emissiveTexture` becomes a textured area emitter (radiance = emissiveFactor * texture,
  sRGB-decoded), so that scenes with textured emitters (DamagedHelmet) render the same light in both renderers;
- a rough metal (metallic 1, roughness r > 0, base colour 1, no textures) becomes a `roughconductor` of GGX
  alpha = r^2 with Fresnel 1 (`material: none`), visible-normal sampling: the glTF metal BRDF with base colour 1
  (its Schlick Fresnel is then exactly 1). Mitsuba's shadowing is the separable Smith G1(i) G1(o), glTF's and
  Nimbus's the height-correlated one: they differ only near grazing angles. A base colour other than 1 would
  need the Schlick Fresnel, which Mitsuba's conductors lack: that case stays gltf2mitsuba's (diffuse, warned);
- a camera inside a closed mesh with an interior medium gets that medium as its sensor medium (the innermost, by
  bounding-box volume, where meshes nest), as Nimbus starts camera paths in the media around the camera
  (gltf2mitsuba sets it only for a camera inside a VDB grid's box).

With `--passes P` > 1 the samples are split into P passes with independent seeds, and `OUT_se.exr` gets the per-pixel
standard error of the mean from their spread (for references). Prints one `RESULT {json}` line: `render_s` is the
time spent inside `mi.render` (JIT compilation included), `load_s` the scene translation and load.
"""
import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
TOOLS = os.path.normpath(os.path.join(HERE, "..", "..", "..", "shared", "tools"))
sys.path.insert(0, TOOLS)
os.environ.setdefault("DRJIT_LIBLLVM_PATH", "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")


def textured_emitters(translator, scene):
    """gltf2mitsuba ignores emissiveTexture; give those shapes an area emitter with the texture as radiance"""
    g = translator.G.g
    index = 0
    for _, node, _ in translator.G.walk():
        if "mesh" not in node:
            continue
        for k, prim in enumerate(g["meshes"][node["mesh"]]["primitives"]):
            if prim.get("mode", 4) != 4:
                continue
            key = f"shape{index}_{node.get('name', '')}_{k}".replace(" ", "_")
            index += 1
            mat = g["materials"][prim["material"]] if "material" in prim else {}
            if "emissiveTexture" not in mat:
                continue
            strength = mat.get("extensions", {}).get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1)
            factor = np.array(mat.get("emissiveFactor", [0, 0, 0]), float) * strength
            shape = next(v for name, v in scene.items() if name.startswith(f"shape{index - 1}_"))
            shape["emitter"] = {"type": "area", "radiance": translator.texture(mat["emissiveTexture"], factor)}


def rough_metals(translator):
    """wrap the translator's `bsdf` so that white rough metals become GGX conductors with Fresnel 1"""
    plain = translator.bsdf

    def bsdf(mat):
        pbr = mat.get("pbrMetallicRoughness", {})
        rough = pbr.get("roughnessFactor", 1.0)
        textured = "baseColorTexture" in pbr or "metallicRoughnessTexture" in pbr
        if (pbr.get("metallicFactor", 1.0) >= 1 and rough > 0 and not textured
                and np.allclose(pbr.get("baseColorFactor", [1, 1, 1, 1])[:3], 1)
                and "KHR_materials_transmission" not in mat.get("extensions", {})):
            return {"type": "roughconductor", "material": "none", "distribution": "ggx", "alpha": float(rough) ** 2,
                    "sample_visible": True}
        return plain(mat)

    translator.bsdf = bsdf


def inside_mesh(eye, vertices, faces, direction):
    """whether `eye` is inside the closed triangle mesh: the parity of a ray's crossings (Moller-Trumbore)"""
    v0, v1, v2 = (vertices[faces[:, i]] for i in range(3))
    e1, e2 = v1 - v0, v2 - v0
    p = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    t_vec = eye - v0
    u = np.einsum("ij,ij->i", t_vec, p) * inv
    q = np.cross(t_vec, e1)
    v = (q @ direction) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hits = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return int(hits.sum()) % 2 == 1


def camera_medium(mi, scene_dict):
    """set the sensor medium to the interior medium of the innermost closed mesh around the camera"""
    sensor = scene_dict["sensor"]
    eye = np.array(sensor["to_world"].matrix, dtype=np.float64).reshape(4, 4)[:3, 3]
    direction = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    around = []
    for shape in scene_dict.values():
        if not isinstance(shape, dict) or "interior" not in shape or shape.get("type") != "ply":
            continue
        mesh = mi.load_dict({"type": "ply", "filename": shape["filename"]})
        vertices = np.array(mesh.vertex_positions_buffer(), dtype=np.float64).reshape(-1, 3)
        faces = np.array(mesh.faces_buffer(), dtype=np.int64).reshape(-1, 3)
        if inside_mesh(eye, vertices, faces, direction):
            around.append((np.prod(vertices.max(0) - vertices.min(0)), shape["interior"]["id"]))
    if around:
        medium = min(around)[1]
        sensor["medium"] = {"type": "ref", "id": medium}
        print(f"mitsuba_render: camera inside the mesh medium {medium}: sensor medium set", file=sys.stderr)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--passes", type=int, default=1)
    ap.add_argument("--integrator", default="volpath", choices=["volpath", "volpathmis", "path"])
    ap.add_argument("--variant", default="llvm_ad_rgb")
    a = ap.parse_args()
    t0 = time.perf_counter()
    import drjit as dr
    import mitsuba as mi
    import gltf2mitsuba
    mi.set_variant(a.variant)
    if a.threads:
        dr.set_thread_count(a.threads)
    if a.spp % a.passes:
        sys.exit("--spp must be a multiple of --passes")
    pass_spp = a.spp // a.passes
    translator = gltf2mitsuba.Translator(a.scene, res=a.res, spp=pass_spp, integrator=a.integrator)
    rough_metals(translator)
    scene_dict = translator.build()
    textured_emitters(translator, scene_dict)
    if "medium" not in scene_dict["sensor"]:
        camera_medium(mi, scene_dict)
    scene = mi.load_dict(scene_dict)
    t1 = time.perf_counter()
    total = total_sq = None
    for i in range(a.passes):
        img = np.array(mi.render(scene, spp=pass_spp, seed=a.seed * 100003 + i), dtype=np.float64)
        total = img if total is None else total + img
        total_sq = img * img if total_sq is None else total_sq + img * img
    t2 = time.perf_counter()
    mean = total / a.passes
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    mi.Bitmap(mean.astype(np.float32), mi.Bitmap.PixelFormat.RGB).write(a.out)
    if a.passes > 1:
        var = np.maximum(total_sq / a.passes - mean * mean, 0.0) * a.passes / (a.passes - 1)
        se = np.sqrt(var / a.passes).astype(np.float32)
        mi.Bitmap(se, mi.Bitmap.PixelFormat.RGB).write(os.path.splitext(a.out)[0] + "_se.exr")
    print("RESULT " + json.dumps({"peer": f"mitsuba-{mi.__version__}", "variant": a.variant,
                                  "integrator": a.integrator, "threads": dr.thread_count(), "spp": a.spp,
                                  "load_s": t1 - t0, "render_s": t2 - t1, "mean": float(mean.mean())}), flush=True)
    sys.stdout.flush()
    os._exit(0)   # skip Dr.Jit's slow teardown


if __name__ == "__main__":
    main()
