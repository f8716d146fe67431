#!/usr/bin/env python3
"""Renders the Mitsuba 3 references of Nimbus's validation scenes (see make_scenes.py), as ../shared/validation/
does for its scenes: 128x128, box filter, `volpath`, llvm_ad_rgb, in independent passes, writing the mean and
`..._se.exr`, the per-pixel standard error of that mean (from the spread of the passes).

Set-up as in ../shared/tools/README.md (pip install mitsuba numpy OpenEXR; Debian's libllvm19 and python3-openvdb,
with DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1). Run from the repository root:

    python3 tests/validation/make_references.py [SCENE ...] [--kind beauty|direct|group|alpha]
            [--spp N] [--pass-spp P] [--bounces B] [--group NAME] [--only-emitters W1,W2] [--seed S]
            [--threads T] [--check]

Kinds (a SCENE is a folder name under tests/validation/ or, for direct and alpha, under ../shared/validation/):

| kind | default scenes | default spp | seed | writes |
|---|---|---|---|---|
| beauty (default) | our own scenes | 4096 | 1 | `<scene>/reference_mitsuba_<spp>spp_128.exr` (+ `_se`) |
| direct | the 8 shared scenes and our own | 2048 (point-in-medium 65536) | 2 | `direct/<scene>/reference_mitsuba_direct_<spp>spp_128.exr` (+ `_se`): `--bounces 1` (max_depth 2), emission plus one scattering event |
| group | our own scenes with light groups | 2048 | 10 + k | `groups/<scene>/reference_mitsuba_group_<group>_<spp>spp_128.exr` (+ `_se`): only that group's emitters |
| alpha | light-groups, scattering-box, smoke-sun | 1024 | 3 | `alpha/<scene>/reference_mitsuba_alpha_<spp>spp_128.exr` (+ `_se`): one channel `A`, the mean coverage |

Every kind keeps the scene's `max_bounces` unless `--bounces` says otherwise (direct: 1). Each kind uses its own
seed (pass i of a render uses `seed * 100003 + i`, as gltf2mitsuba does), so that references of different kinds
are statistically independent of one another: a sum of group references can be compared with the beauty.
Regenerating replaces only the files of that kind (and group) in the output folder.

The translation is ../shared/tools/gltf2mitsuba.py's, plus what it does not express (patched here):
- emissiveTexture: the area emitter's radiance becomes the texture (sRGB-decoded, NEAREST or bilinear as its
  sampler says) times emissiveFactor x emissiveStrength, baked into a linear EXR by gltf2mitsuba's own helper.
- light groups: a group's emitters are read from the glTF (`extras.nimbus_light_group` on the node, else on the
  emissive material; `light_group` in the scene extras' `nimbus_environment`) and turned into the words that
  gltf2mitsuba's `--only-emitters` takes (the emitters' node names, `environment` for the environment); the script
  checks that those words keep exactly that group's emitters and nothing else.
- depth of field: a camera node whose extras hold `nimbus_camera` with `aperture_radius` and `focus_distance` becomes
  Mitsuba's `thinlens` sensor with the same two values (`fov` and `fov_axis` 'y' kept from the perspective sensor:
  glTF's yfov is vertical; Mitsuba's focus distance, like Nimbus's, is measured along the view axis). `f_stop` is
  not translated (it needs Nimbus's focal-length convention): a scene using it is refused here.
- diffuse transmission (KHR_materials_diffuse_transmission, on a material that gltf2mitsuba reads as Lambertian:
  metallic 0, specularFactor 0, no textures): Mitsuba 3 has no plain diffuse transmitter, but its `principledthin`
  with `diff_trans` 2 (all of its diffuse transmitted), `eta` 1.0001 (no specular) and `roughness` 1 is exactly a
  Lambertian transmission of its `base_color` (checked here, at several angles, before rendering). The material
  becomes `blendbsdf` (weight diffuseTransmissionFactor) of `twosided(diffuse(baseColor))` and that transmitter
  (base_color diffuseTransmissionColorFactor): both faces scatter alike, as Nimbus's thin wall does.
- alpha: Mitsuba's volpath marks every camera ray valid (alpha 1) as soon as the scene has an environment emitter,
  so the alpha render drops the environment (alpha does not depend on lighting); the alpha of a sample is then 1
  when its camera ray hits a non-null surface or scatters in a medium, so its mean is 1 - transmittance. In a
  chromatic medium Mitsuba picks the tracking channel uniformly, so the mean is the average over R, G, B of
  1 - T_channel.
- images are written with the OpenEXR module (ZIP, float32): Mitsuba's own EXR writer deadlocks when Dr.Jit's
  thread pool is set to 1 thread (`--threads 1`).

`--check` renders nothing: it compares what is on disk (group references summed against the beauty, per channel
image mean and 8x8 blocks; alpha against a ray-cast classification of the pixels that see only the environment or
only opaque surfaces) and prints the figures.
"""
import argparse
import json
import os
import re
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.environ.get("NIMBUS_SHARED_DIR", os.path.join(HERE, "..", "..", "..", "shared"))
sys.path.insert(0, os.path.join(SHARED, "tools"))

RES = 128
KINDS = ("beauty", "direct", "group", "alpha")
DEFAULT_SPP = {"beauty": 4096, "direct": 2048, "group": 2048, "alpha": 1024}
# heavy-tailed scenes: more samples for the direct reference (a point light inside a scattering medium)
DIRECT_SPP = {"point-in-medium": 65536}
SEED = {"beauty": 1, "direct": 2, "alpha": 3}          # group k (sorted by name) uses 10 + k
FOLDER = {"direct": "direct", "group": "groups", "alpha": "alpha"}
ALPHA_SCENES = ["light-groups", "scattering-box", "smoke-sun"]
PASSES = 16                                  # default pass_spp = min(256, spp / 16): 16 passes at least


# ----------------------------------------------------------------------------------------------- scenes
def own_scenes():
    return sorted(n for n in os.listdir(HERE) if os.path.isfile(os.path.join(HERE, n, "scene.gltf")))


def shared_scenes():
    root = os.path.join(SHARED, "validation")
    return sorted(n for n in os.listdir(root) if os.path.isfile(os.path.join(root, n, "scene.gltf")))


def scene_gltf(name):
    """our own tests/validation/<name>/scene.gltf, else ../shared/validation/<name>/scene.gltf"""
    for root in (HERE, os.path.join(SHARED, "validation")):
        path = os.path.join(root, name, "scene.gltf")
        if os.path.isfile(path):
            return os.path.abspath(path)
    raise SystemExit(f"no scene {name!r} in {HERE} or {os.path.join(SHARED, 'validation')}")


def out_folder(kind, name):
    return os.path.join(HERE, name) if kind == "beauty" else os.path.join(HERE, FOLDER[kind], name)


def out_name(kind, spp, group=None):
    tag = {"beauty": "", "direct": "direct_", "alpha": "alpha_", "group": f"group_{group}_"}[kind]
    return f"reference_mitsuba_{tag}{spp}spp_{RES}.exr"


def remove_old(folder, kind, group=None):
    """the earlier references of this kind (and group) in folder, not those of other kinds"""
    tag = {"beauty": "", "direct": "direct_", "alpha": "alpha_", "group": f"group_{re.escape(str(group))}_"}[kind]
    pat = re.compile(rf"^reference_mitsuba_{tag}\d+spp_{RES}(_se)?\.exr$")
    if os.path.isdir(folder):
        for f in os.listdir(folder):
            if pat.match(f):
                os.remove(os.path.join(folder, f))


# ----------------------------------------------------------------------------------------------- light groups
def light_groups(gltf_path):
    """{group: [(node index or None for the environment, name)]} from the glTF's extras, and the ungrouped emitters"""
    g = json.load(open(gltf_path))
    mats = g.get("materials", [])
    groups, ungrouped = {}, []

    def emissive(m):
        em = np.array(m.get("emissiveFactor", [0, 0, 0]), float) * \
            m.get("extensions", {}).get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
        return em.max() > 0

    for ni, node in enumerate(g.get("nodes", [])):
        name = node.get("name", f"node{ni}")
        own = node.get("extras", {}).get("nimbus_light_group")
        found = set()
        if "mesh" in node:
            for prim in g["meshes"][node["mesh"]]["primitives"]:
                if prim.get("material") is not None and emissive(mats[prim["material"]]):
                    found.add(own or mats[prim["material"]].get("extras", {}).get("nimbus_light_group"))
        if "KHR_lights_punctual" in node.get("extensions", {}):
            found.add(own)
        for group in found:
            (groups.setdefault(group, []) if group else ungrouped).append((ni, name))
    scene = g["scenes"][g.get("scene", 0)].get("extras", {})
    env = scene.get("nimbus_environment")
    if env and ("map" in env or max(env.get("color", [0, 0, 0])) > 0):
        group = env.get("light_group")
        (groups.setdefault(group, []) if group else ungrouped).append((None, "environment"))
    return groups, ungrouped


def emitter_keys(d):
    """the keys of the emitters in a translated scene dict"""
    return sorted(k for k, v in d.items() if k == "environment" or re.match(r"light_\d+$", k)
                  or (isinstance(v, dict) and "emitter" in v))


# ----------------------------------------------------------------------------------------------- rendering
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
        if not patched and translator.only_emitters is None:
            raise RuntimeError(f"material {mat.get('name')}: no emitter shape found to texture")


def patch_thin_lens(translator, d):
    """the first camera node in walk order (the one gltf2mitsuba translates) with extras.nimbus_camera: the sensor
    becomes a thinlens with its aperture_radius and focus_distance"""
    g = translator.G.g
    for _, node, _ in translator.G.walk():
        if "camera" in node and g["cameras"][node["camera"]]["type"] == "perspective":
            lens = node.get("extras", {}).get("nimbus_camera")
            if lens is None:
                return
            if set(lens) != {"aperture_radius", "focus_distance"}:
                raise SystemExit(f"nimbus_camera {lens}: only aperture_radius and focus_distance are translated")
            d["sensor"]["type"] = "thinlens"
            d["sensor"]["aperture_radius"] = float(lens["aperture_radius"])
            d["sensor"]["focus_distance"] = float(lens["focus_distance"])
            assert d["sensor"]["fov_axis"] == "y"
            return


def thin_diffuse_transmitter(color):
    """Mitsuba's principledthin reduced to a Lambertian transmission of `color` (see the module docstring)"""
    return {"type": "principledthin", "base_color": {"type": "rgb", "value": list(color)}, "diff_trans": 2.0,
            "eta": 1.0001, "roughness": 1.0}


def check_thin_diffuse_transmitter():
    """f(wi, wo) |cos| = color/pi |cos| across the surface and 0 on the same side, at several angles"""
    import math
    import mitsuba as mi
    color = [0.9, 0.5, 0.2]
    bsdf = mi.load_dict(thin_diffuse_transmitter(color))
    si = mi.SurfaceInteraction3f()
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    for ti in (0.0, 0.7, 1.4):
        si.wi = mi.Vector3f(math.sin(ti), 0, math.cos(ti))
        for to, phi in ((0.0, 0.0), (0.6, 1.0), (1.2, 2.5), (1.5, 0.3)):
            for side in (-1, 1):
                wo = mi.Vector3f(math.sin(to) * math.cos(phi), math.sin(to) * math.sin(phi), side * math.cos(to))
                f = np.array(bsdf.eval(mi.BSDFContext(), si, wo), float).reshape(-1)[:3] / math.cos(to)
                want = np.array(color) / math.pi if side < 0 else np.zeros(3)
                if np.abs(f - want).max() > 1e-4:
                    raise SystemExit(f"principledthin is not a Lambertian transmitter at {ti}, {to}, {side}: {f}")


def patch_diffuse_transmission(translator, d):
    g = translator.G.g
    for mi_index, mat in enumerate(g.get("materials", [])):
        ext = mat.get("extensions", {}).get("KHR_materials_diffuse_transmission")
        if ext is None:
            continue
        pbr = mat.get("pbrMetallicRoughness", {})
        lambert = pbr.get("metallicFactor", 1.0) == 0.0 and \
            mat.get("extensions", {}).get("KHR_materials_specular", {}).get("specularFactor", 1.0) == 0.0
        if not lambert or "baseColorTexture" in pbr or "diffuseTransmissionTexture" in ext \
                or "diffuseTransmissionColorTexture" in ext:
            raise SystemExit(f"material {mat.get('name')}: diffuse transmission is translated on an untextured "
                             "Lambertian material only")
        base = pbr.get("baseColorFactor", [1, 1, 1, 1])[:3]
        meshes = [i for i, m in enumerate(g["meshes"]) if any(p.get("material") == mi_index for p in m["primitives"])]
        names = [n.get("name", "") for n in g["nodes"] if n.get("mesh") in meshes]
        patched = 0
        for key, shape in d.items():
            if isinstance(shape, dict) and "bsdf" in shape and any(f"_{n}_" in key for n in names):
                shape["bsdf"] = {
                    "type": "blendbsdf",
                    "weight": float(ext.get("diffuseTransmissionFactor", 0.0)),
                    "reflection": {"type": "twosided",
                                   "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": base}}},
                    "transmission": thin_diffuse_transmitter(ext.get("diffuseTransmissionColorFactor", [1, 1, 1])),
                }
                patched += 1
        if not patched:
            raise RuntimeError(f"material {mat.get('name')}: no shape found")
        check_thin_diffuse_transmitter()


def write_exr(path, img):
    """float32, ZIP; img HxWx3 -> R, G, B; HxW -> A"""
    import OpenEXR
    os.makedirs(os.path.dirname(path), exist_ok=True)
    chans = {"RGB": np.ascontiguousarray(img, np.float32)} if img.ndim == 3 else \
        {"A": np.ascontiguousarray(img, np.float32)}
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, chans).write(path)


def read_exr(path):
    import OpenEXR
    ch = OpenEXR.File(path).channels()
    if "RGB" in ch:
        return np.array(ch["RGB"].pixels, np.float64)
    if "A" in ch:
        return np.array(ch["A"].pixels, np.float64)
    raise ValueError(f"{path}: channels {list(ch)}")


def render(gltf, out, spp, pass_spp, seed, threads, bounces=None, only_emitters=None, alpha=False):
    """renders spp samples in spp / pass_spp passes (pass i with seed * 100003 + i) and writes the mean and its
    per-pixel standard error; returns (mean, se, render seconds)"""
    import drjit as dr
    import gltf2mitsuba as g2m
    import mitsuba as mi
    if spp % pass_spp or spp // pass_spp < 2:
        raise SystemExit(f"--spp {spp} must be a multiple of --pass-spp {pass_spp}, with 2 passes at least")
    dr.set_thread_count(max(2, threads))     # building bakes textures with Mitsuba's EXR writer: not with 1 thread
    t = g2m.Translator(gltf, RES, None, pass_spp, "volpath", bounces, only_emitters, alpha)
    d = t.build()
    patch_emissive_textures(t, d)
    patch_thin_lens(t, d)
    patch_diffuse_transmission(t, d)
    if alpha:
        d.pop("environment", None)           # else volpath reports every ray valid (alpha 1 everywhere)
    scene = mi.load_dict(d)
    dr.set_thread_count(threads)
    npass = spp // pass_spp
    acc = acc2 = None
    t0 = time.perf_counter()
    for i in range(npass):
        arr = np.array(mi.render(scene, spp=pass_spp, seed=seed * 100003 + i), dtype=np.float64)
        arr = arr[..., 3] if alpha else arr[..., :3]
        acc = arr if acc is None else acc + arr
        acc2 = arr * arr if acc2 is None else acc2 + arr * arr
    seconds = time.perf_counter() - t0
    mean = acc / npass
    var = np.maximum(acc2 / npass - mean ** 2, 0.0) * npass / (npass - 1)
    se = np.sqrt(var / npass)
    write_exr(out, mean)
    write_exr(out.replace(".exr", "_se.exr"), se)
    m = mean.reshape(mean.shape[0] * mean.shape[1], -1).mean(0)
    print(f"wrote {os.path.relpath(out)}: spp {spp} ({npass} x {pass_spp}), seed {seed}, max_depth "
          f"{d['integrator']['max_depth']}, emitters {emitter_keys(d)}, mean {m.round(6).tolist()}, "
          f"render {seconds:.1f} s, mitsuba {mi.__version__}", flush=True)
    return mean, se, seconds


def group_words(gltf, group, members):
    """--only-emitters words for one group (its emitters' node names, `environment`), checked: they must keep
    exactly the group's emitters (by node index) of the translated scene"""
    import gltf2mitsuba as g2m
    words = sorted({name for _, name in members})
    full = g2m.Translator(gltf, RES, None, 1, "volpath", None, None, False)
    kept = g2m.Translator(gltf, RES, None, 1, "volpath", None, words, False).build()
    d = full.build()
    shape_node, idx = {}, 0                     # gltf2mitsuba's shape numbering: walk order, triangle primitives
    for ni, node, _ in full.G.walk():
        for prim in full.G.g["meshes"][node["mesh"]]["primitives"] if "mesh" in node else []:
            if prim.get("mode", 4) == 4:
                shape_node[idx] = ni
                idx += 1

    def node_of(key):
        if key == "environment":
            return None
        m = re.match(r"light_(\d+)$", key)
        return int(m.group(1)) if m else shape_node[int(re.match(r"shape(\d+)_", key).group(1))]

    nodes = {ni for ni, _ in members}
    expected = sorted(k for k in emitter_keys(d) if node_of(k) in nodes)
    if emitter_keys(kept) != expected or not expected:
        raise SystemExit(f"group {group}: --only-emitters {','.join(words)} keeps {emitter_keys(kept)}, "
                         f"the group is {expected}")
    return words


# ----------------------------------------------------------------------------------------------- checks
def block_z(img, se, ref, ref_se, n=8):
    """8x8 block z values of img - ref (block se = sqrt(sum se^2) / 64), per channel"""
    h, w = img.shape[:2]
    def blocks(a):
        return a.reshape(h // n, n, w // n, n, -1).sum((1, 3))
    diff = blocks(img - ref) / n ** 2
    s = np.sqrt(blocks(se ** 2) + blocks(ref_se ** 2)) / n ** 2
    equal = np.abs(diff) <= 1e-5 * np.abs(blocks(ref)) / n ** 2     # up to float32 film rounding
    with np.errstate(divide="ignore", invalid="ignore"):   # noiseless blocks (e.g. only sky): nan if equal
        return np.where(s > 0, diff / s, np.where(equal, np.nan, np.inf))


def check_groups(name, spp_groups=None):
    folder = os.path.join(HERE, name)
    beauty = [f for f in os.listdir(folder) if re.match(rf"reference_mitsuba_\d+spp_{RES}\.exr$", f)]
    gfolder = os.path.join(HERE, FOLDER["group"], name)
    gfiles = sorted(f for f in os.listdir(gfolder) if re.match(rf"reference_mitsuba_group_.*_\d+spp_{RES}\.exr$", f))
    ref = read_exr(os.path.join(folder, beauty[0]))
    ref_se = read_exr(os.path.join(folder, beauty[0].replace(".exr", "_se.exr")))
    tot = np.zeros_like(ref)
    tot_var = np.zeros_like(ref)
    npx = ref.shape[0] * ref.shape[1]
    print(f"{name}: beauty {beauty[0]}: mean {ref.reshape(-1, 3).mean(0).round(5).tolist()} "
          f"+- {(np.sqrt((ref_se ** 2).reshape(-1, 3).sum(0)) / npx).round(5).tolist()}")
    for f in gfiles:
        img = read_exr(os.path.join(gfolder, f))
        se = read_exr(os.path.join(gfolder, f.replace(".exr", "_se.exr")))
        tot += img
        tot_var += se ** 2
        print(f"  {f}: mean {img.reshape(-1, 3).mean(0).round(5).tolist()} "
              f"+- {(np.sqrt((se ** 2).reshape(-1, 3).sum(0)) / npx).round(5).tolist()}")
    tot_se = np.sqrt(tot_var)
    m, mr = tot.reshape(-1, 3).mean(0), ref.reshape(-1, 3).mean(0)
    s = np.sqrt((tot_se ** 2).reshape(-1, 3).sum(0) + (ref_se ** 2).reshape(-1, 3).sum(0)) / npx
    print(f"  sum of groups: mean {m.round(5).tolist()} vs beauty {mr.round(5).tolist()}: "
          f"rel diff {((m - mr) / mr).round(5).tolist()}, z {((m - mr) / s).round(2).tolist()}")
    z = block_z(tot, tot_se, ref, ref_se).reshape(-1, 3)
    noisy = ~np.isnan(z)
    print(f"  8x8 blocks: {z.shape[0]} x 3, of which {(~noisy).sum()} noiseless and equal (only sky); of the "
          f"{noisy.sum()} others: |z| > 4: {(np.abs(z[noisy]) > 4).mean():.4f}, |z| > 3: "
          f"{(np.abs(z[noisy]) > 3).mean():.4f}, max |z| {np.abs(z[noisy]).max():.2f}, z per channel: mean "
          f"{np.nanmean(z, 0).round(3).tolist()}, std {np.nanstd(z, 0).round(3).tolist()}")
    return z


def coverage_classes(gltf, k=8):
    """per pixel, from k x k stratified camera rays: the fraction that hit nothing at all (only the environment)
    and the fraction that end on an opaque (non-null-BSDF) surface, passing null-BSDF boundaries"""
    import drjit as dr
    import gltf2mitsuba as g2m
    import mitsuba as mi
    dr.set_thread_count(max(2, dr.thread_count()))
    d = g2m.Translator(gltf, RES, None, 1, "volpath", None, None, False).build()
    scene_all = mi.load_dict(d)
    opaque = {key: v for key, v in d.items()
              if not (isinstance(v, dict) and v.get("bsdf", {}).get("type") == "null")}
    scene_opaque = mi.load_dict(opaque)
    sensor = scene_all.sensors()[0]
    w, h = RES, RES
    iy, ix, sy, sx = np.meshgrid(np.arange(h), np.arange(w), np.arange(k), np.arange(k), indexing="ij")
    u = ((ix + (sx + 0.5) / k) / w).ravel()
    v = ((iy + (sy + 0.5) / k) / h).ravel()
    ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(u, v), mi.Point2f(0.5, 0.5))
    hit_any = np.array(scene_all.ray_test(ray)).reshape(h, w, k * k)
    hit_opaque = np.array(scene_opaque.ray_test(ray)).reshape(h, w, k * k)
    return (~hit_any).mean(-1), hit_opaque.mean(-1)


def check_alpha(name):
    folder = os.path.join(HERE, FOLDER["alpha"], name)
    f = [f for f in os.listdir(folder) if re.match(rf"reference_mitsuba_alpha_\d+spp_{RES}\.exr$", f)][0]
    a = read_exr(os.path.join(folder, f))
    se = read_exr(os.path.join(folder, f.replace(".exr", "_se.exr")))
    env_only, opaque = coverage_classes(scene_gltf(name))

    def interior(mask):   # the pixel and its 8 neighbours: k x k rays can miss a sliver of an edge pixel
        p = np.pad(mask, 1, constant_values=False)
        return np.all([p[1 + dy:p.shape[0] - 1 + dy, 1 + dx:p.shape[1] - 1 + dx]
                       for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=0)
    pure_env, pure_opaque = interior(env_only == 1), interior(opaque == 1)
    mixed = ~pure_env & ~pure_opaque
    print(f"{name}: {f}: mean alpha {a.mean():.5f}; {pure_env.sum()} pixels see only the environment: alpha "
          f"max {a[pure_env].max() if pure_env.any() else float('nan'):.5f}; {pure_opaque.sum()} pixels see only "
          f"opaque surfaces: alpha min {a[pure_opaque].min() if pure_opaque.any() else float('nan'):.5f}; "
          f"{mixed.sum()} others (edges, media): alpha {a[mixed].min() if mixed.any() else 0:.4f}.."
          f"{a[mixed].max() if mixed.any() else 0:.4f}, mean se {se[mixed].mean() if mixed.any() else 0:.5f}")


# ----------------------------------------------------------------------------------------------- main
def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*")
    ap.add_argument("--kind", choices=KINDS, default="beauty")
    ap.add_argument("--spp", type=int, default=None, help="default: 4096 beauty, 2048 direct and group, 1024 alpha "
                    "(direct point-in-medium: 65536)")
    ap.add_argument("--pass-spp", type=int, default=None, help=f"default: min(256, spp / {PASSES})")
    ap.add_argument("--bounces", type=int, default=None, help="default: 1 for direct, else the scene's max_bounces")
    ap.add_argument("--group", action="append", default=None, help="group kind: only this group (repeatable)")
    ap.add_argument("--only-emitters", default=None,
                    help="group kind, with one --group: these words instead of the ones read from the glTF")
    ap.add_argument("--seed", type=int, default=None, help="default: 1 beauty, 2 direct, 3 alpha, 10 + k group k")
    ap.add_argument("--threads", type=int, default=1, help="Dr.Jit threads while rendering (default 1)")
    ap.add_argument("--check", action="store_true", help="render nothing; check the group and alpha references")
    a = ap.parse_args()
    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")

    if a.check:
        for name in a.scenes or [n for n in own_scenes() if light_groups(scene_gltf(n))[0]]:
            if os.path.isdir(os.path.join(HERE, FOLDER["group"], name)):
                check_groups(name)
        for name in a.scenes or ALPHA_SCENES:
            if os.path.isdir(os.path.join(HERE, FOLDER["alpha"], name)):
                check_alpha(name)
        return

    if a.scenes:
        scenes = a.scenes
    elif a.kind == "beauty":
        scenes = own_scenes()
    elif a.kind == "direct":
        scenes = shared_scenes() + own_scenes()
    elif a.kind == "group":
        scenes = [n for n in own_scenes() if light_groups(scene_gltf(n))[0]]
    else:
        scenes = ALPHA_SCENES
    for name in scenes:
        gltf = scene_gltf(name)
        if a.kind == "beauty" and not gltf.startswith(HERE):
            raise SystemExit(f"{name}: the beauty references of ../shared/validation/ are its own")
        spp = a.spp or (DIRECT_SPP.get(name, DEFAULT_SPP["direct"]) if a.kind == "direct" else DEFAULT_SPP[a.kind])
        pass_spp = a.pass_spp or max(1, min(256, spp // PASSES))
        folder = out_folder(a.kind, name)
        if a.kind == "group":
            groups, ungrouped = light_groups(gltf)
            if ungrouped:
                print(f"{name}: emitters in no group (not rendered): {ungrouped}", flush=True)
            names = sorted(groups)
            for k, group in enumerate(names):
                if a.group and group not in a.group:
                    continue
                words = a.only_emitters.split(",") if a.only_emitters else group_words(gltf, group, groups[group])
                remove_old(folder, "group", group)
                render(gltf, os.path.join(folder, out_name("group", spp, group)), spp, pass_spp,
                       a.seed if a.seed is not None else 10 + k, a.threads, a.bounces, words)
            continue
        bounces = a.bounces if a.bounces is not None else (1 if a.kind == "direct" else None)
        remove_old(folder, a.kind)
        render(gltf, os.path.join(folder, out_name(a.kind, spp)), spp, pass_spp,
               a.seed if a.seed is not None else SEED[a.kind], a.threads, bounces, alpha=a.kind == "alpha")


if __name__ == "__main__":
    main()
