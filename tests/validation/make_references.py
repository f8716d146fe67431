#!/usr/bin/env python3
"""Renders the Mitsuba 3 reference of each scene in tests/validation/ (see make_scenes.py), as
../shared/validation/ does for its scenes: 128x128, box filter, `volpath`, in independent passes, writing
`reference_mitsuba_<spp>spp_128.exr` (the mean) and `..._se.exr` (the per-pixel standard error of that mean).

Set-up as in ../shared/tools/README.md (pip install mitsuba numpy; Debian's libllvm19, with
DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1). Run from the repository root:

    python3 tests/validation/make_references.py [SCENE ...] [--spp 4096] [--pass-spp 256]

The translation is ../shared/tools/gltf2mitsuba.py's, plus what it does not express yet:
- emissiveTexture: the area emitter's radiance becomes the texture (sRGB-decoded, NEAREST or bilinear as its
  sampler says) times emissiveFactor x emissiveStrength, baked into a linear EXR by gltf2mitsuba's own helper.
"""
import argparse
import json
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.environ.get("NIMBUS_SHARED_DIR", os.path.join(HERE, "..", "..", "..", "shared"))
sys.path.insert(0, os.path.join(SHARED, "tools"))


def patch_emissive_textures(translator, d):
    g = translator.G.g
    for mi_index, mat in enumerate(g.get("materials", [])):
        tinfo = mat.get("emissiveTexture")
        if tinfo is None:
            continue
        factor = np.array(mat.get("emissiveFactor", [0, 0, 0]), float) * \
            mat.get("extensions", {}).get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
        meshes = [i for i, m in enumerate(g["meshes"]) if any(p.get("material") == mi_index for p in m["primitives"])]
        names = [n.get("name", "") for n in g["nodes"] if n.get("mesh") in meshes]
        patched = 0
        for key, shape in d.items():
            if isinstance(shape, dict) and "emitter" in shape and any(f"_{n}_" in key for n in names):
                shape["emitter"]["radiance"] = translator.texture(tinfo, factor)
                patched += 1
        if not patched:
            raise RuntimeError(f"material {mat.get('name')}: no emitter shape found to texture")


def render(scene_dir, spp, pass_spp):
    import gltf2mitsuba as g2m
    import mitsuba as mi
    gltf = os.path.join(scene_dir, "scene.gltf")
    t = g2m.Translator(gltf, 128, None, pass_spp, "volpath", None)
    d = t.build()
    patch_emissive_textures(t, d)
    scene = mi.load_dict(d)
    npass = spp // pass_spp
    acc = acc2 = None
    for i in range(npass):
        arr = np.array(mi.render(scene, spp=pass_spp, seed=1 * 100003 + i), dtype=np.float64)
        acc = arr if acc is None else acc + arr
        acc2 = arr * arr if acc2 is None else acc2 + arr * arr
    mean = acc / npass
    var = np.maximum(acc2 / npass - mean ** 2, 0.0) * npass / (npass - 1)
    se = np.sqrt(var / npass)
    out = os.path.join(scene_dir, f"reference_mitsuba_{spp}spp_128.exr")
    mi.Bitmap(mean.astype(np.float32), mi.Bitmap.PixelFormat.RGB).write(out)
    mi.Bitmap(se.astype(np.float32), mi.Bitmap.PixelFormat.RGB).write(out.replace(".exr", "_se.exr"))
    print(f"wrote {os.path.relpath(out)}: mean {mean.reshape(-1, 3).mean(0).round(6).tolist()}", flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="*")
    ap.add_argument("--spp", type=int, default=4096)
    ap.add_argument("--pass-spp", type=int, default=256)
    a = ap.parse_args()
    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")
    scenes = a.scenes or sorted(n for n in os.listdir(HERE) if os.path.isfile(os.path.join(HERE, n, "scene.gltf")))
    for name in scenes:
        folder = os.path.join(HERE, name)
        for f in os.listdir(folder):
            if f.startswith("reference_"):
                os.remove(os.path.join(folder, f))
        render(folder, a.spp, a.pass_spp)


if __name__ == "__main__":
    main()
