#!/usr/bin/env python3
"""Cycles' Cryptomatte IDs for tests/cryptomatte/ids_scene.gltf, the reference Nimbus' Cryptomatte output is checked
against.

    python3 tests/cryptomatte/make_cycles_ids.py           (pip install bpy==5.0.1 OpenEXR; Python 3.11; a few
                                                            seconds, one render thread)
    python3 tests/cryptomatte/make_cycles_ids.py --check   (no Blender: the glTF is what this script writes, the
                                                            MurmurHash3 below reproduces cycles_ids.json, and, with
                                                            OpenEXR installed, cycles_render.exr decodes to it)

What it does:
1. writes ids_scene.gltf (pure Python, deterministic, embedded base64 buffer): a camera, a directional light, a
   top-level empty `Rig` with mesh children `Crate` and `Lamp.Shade`, top-level meshes `Floor`, `Würfel`,
   `Back Wall #2` (two primitives, two materials) and `Edge Probe 4`; materials `Oak Wood` (Crate and Floor),
   `Grün` (Würfel and the wall's stripe), `Plaster`, `Lamp Shade/Fabric (v2)` and `Edge Paint 9`. Mesh names differ
   from node names (`Crate-mesh`, ...): Cryptomatte's object names are the node names. `Edge Probe 4` and
   `Edge Paint 9` are names whose MurmurHash3 has exponent bits all 1 (0xff8530c4) and all 0 (0x00326f8c), the two
   cases where the float ID's bits differ from the hash (bit 23 flipped).
2. imports it into Blender (bpy) with the glTF importer, renders 64x64 with Cycles (CPU, 4 samples, 1 thread) with
   the view layer's CryptoObject, CryptoMaterial and CryptoAsset passes (6 levels), saves the result as a
   multilayer OpenEXR twice in a temporary folder (Blender 5.0's default multi-part file, and the legacy
   single-part "interleaved" one), keeps the multi-part one as cycles_render.exr (~60 KB), and reads the EXR
   header's cryptomatte/<key>/{name,hash,conversion,manifest} attributes.
3. checks, independently of Blender: its own MurmurHash3_x86_32 of each UTF-8 name gives the manifest's hash; the
   layer keys are the first 7 hex digits of the hash of the layer name; every ID found in the rank channels'
   pixels is a manifest ID after the float conversion; every mesh object, material and asset shows in the image.
4. writes cycles_ids.json: Blender's version, the manifests as Cycles wrote them, the layer keys, the EXR's channel
   names, the name Blender gave each imported object and material and its asset (top-most parent), and the uint32
   bits of the float ID seen in the pixels for each name.
5. renders a throw-away probe scene (write_probe_gltf) with duplicate, missing, quoted and over-long names and
   records in cycles_ids.json's "probe" what Blender and Cycles made of them.
"""
import argparse
import json
import os
import re
import shutil
import struct
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "assets"))
from gltf_writer import GltfBuilder  # noqa: E402

GLTF = os.path.join(HERE, "ids_scene.gltf")
JSON = os.path.join(HERE, "cycles_ids.json")
EXR = os.path.join(HERE, "cycles_render.exr")
LAYERS = ("CryptoObject", "CryptoMaterial", "CryptoAsset")
LEVELS = 6
SIZE = 64
SAMPLES = 4


# ----------------------------------------------------------------------------------------------- MurmurHash3
def murmur3_x86_32(data, seed=0):
    """MurmurHash3_x86_32 of bytes `data` (Austin Appleby's public algorithm: 4-byte little-endian blocks mixed with
    c1/c2, rotations 15 and 13, h*5+0xe6546b64; the 1-3 byte tail; length xor; fmix32)"""
    mask = 0xFFFFFFFF
    c1, c2 = 0xCC9E2D51, 0x1B873593

    def rotl(x, r):
        return ((x << r) | (x >> (32 - r))) & mask

    def scramble(k):
        k = (k * c1) & mask
        k = rotl(k, 15)
        return (k * c2) & mask

    h = seed & mask
    n = len(data)
    whole = n - n % 4
    for i in range(0, whole, 4):
        h ^= scramble(int.from_bytes(data[i:i + 4], "little"))
        h = rotl(h, 13)
        h = (h * 5 + 0xE6546B64) & mask
    tail = data[whole:]
    if tail:
        h ^= scramble(int.from_bytes(tail, "little"))
    h ^= n
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & mask
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & mask
    h ^= h >> 16
    return h


def name_hash(name):
    return murmur3_x86_32(name.encode("utf-8"), 0)


def id_bits(h):
    """the uint32 bits of Cryptomatte's float ID of hash h: bit 23 flipped where the exponent is all 0 or all 1
    (no denormals, infinities or NaNs)"""
    exponent = (h >> 23) & 0xFF
    return h ^ (1 << 23) if exponent in (0, 255) else h


def float_to_bits(f):
    return struct.unpack("<I", struct.pack("<f", f))[0]


def layer_key(layer_name):
    return ("%08x" % name_hash(layer_name))[:7]


def self_test():
    # published MurmurHash3_x86_32 values (SMHasher's reference implementation)
    assert murmur3_x86_32(b"", 0) == 0
    assert murmur3_x86_32(b"", 1) == 0x514E28B7
    assert murmur3_x86_32(b"", 0xFFFFFFFF) == 0x81F16F39
    assert murmur3_x86_32(b"hello", 0) == 0x248BFA47
    assert murmur3_x86_32(b"The quick brown fox jumps over the lazy dog", 0) == 0x2E4FF723
    assert id_bits(0xFF8530C4) == 0xFF0530C4 and id_bits(0x00326F8C) == 0x00B26F8C
    assert id_bits(0x12345678) == 0x12345678


# ----------------------------------------------------------------------------------------------- the glTF
OBJECTS = ["Crate", "Lamp.Shade", "Floor", "Würfel", "Back Wall #2", "Edge Probe 4"]    # mesh nodes
TOP_LEVEL = ["Rig", "Floor", "Würfel", "Back Wall #2", "Edge Probe 4"]                  # + Camera, Sun


class HierarchyBuilder(GltfBuilder):
    """GltfBuilder lists every node in the scene; here only the roots, the rest hang under `children`"""
    roots = None

    def to_gltf(self, generator, extensions_used=None, scene_extras=None):
        gltf = super().to_gltf(generator, extensions_used, scene_extras)
        gltf["scenes"][0]["nodes"] = list(self.roots)
        return gltf


def box_geometry():
    """positions, normals, indices of the box [-0.5, 0.5] x [0, 1] x [-0.5, 0.5]: 6 faces x 4 vertices, flat outward
    normals, counter-clockwise seen from outside"""
    pos, nor, idx = [], [], []
    for axis in range(3):
        for sign in (1, -1):
            n = [0, 0, 0]
            n[axis] = sign
            u, v = [0, 0, 0], [0, 0, 0]           # u x v = n
            u[(axis + 1) % 3], v[(axis + 2) % 3] = sign, 1
            k = len(pos)
            for du, dv in ((-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)):
                p = [0.5 * n[i] + du * u[i] + dv * v[i] for i in range(3)]
                pos.append([p[0], p[1] + 0.5, p[2]])
                nor.append(list(n))
            idx += [k, k + 1, k + 2, k, k + 2, k + 3]
    return pos, nor, idx


def build_scene():
    b = HierarchyBuilder()
    oak = b.lambert("Oak Wood", [0.55, 0.35, 0.2])
    gruen = b.lambert("Grün", [0.1, 0.6, 0.15])
    plaster = b.lambert("Plaster", [0.8, 0.78, 0.74])
    fabric = b.lambert("Lamp Shade/Fabric (v2)", [0.9, 0.8, 0.5])
    edge_paint = b.lambert("Edge Paint 9", [0.2, 0.3, 0.8])

    floor = b.quad("Floor", [[-3, 0, 2.5], [3, 0, 2.5], [3, 0, -2], [-3, 0, -2]], oak)
    # the back wall: plaster below and above a green stripe, one mesh with two primitives
    wall = b.quad("Back Wall #2", [[-3, 0, -2], [3, 0, -2], [3, 3, -2], [-3, 3, -2]], plaster)
    stripe = b.add_geometry([[-3, 1.8, -1.98], [3, 1.8, -1.98], [3, 2.2, -1.98], [-3, 2.2, -1.98]], [[0, 0, 1]] * 4,
                            [0, 1, 2, 0, 2, 3])
    b.meshes[b.nodes[wall]["mesh"]]["primitives"].append(
        {"attributes": {"POSITION": stripe[0], "NORMAL": stripe[1]}, "indices": stripe[2], "material": gruen})
    unit_box = b.add_geometry(*box_geometry())     # [-0.5, 0.5] x [0, 1] x [-0.5, 0.5], shared by four meshes
    crate = b.mesh_from_accessors("Crate", unit_box, oak)
    shade = b.mesh_from_accessors("Lamp.Shade", unit_box, fabric, translation=[0, 1.3, 0], scale=[0.8, 0.5, 0.8])
    rig = b.add_node({"name": "Rig", "translation": [-1.6, 0, 0], "children": [crate, shade]})
    wuerfel = b.mesh_from_accessors("Würfel", unit_box, gruen, translation=[1.6, 0, 0],
                                    rotation=[0, 0.2588190451, 0, 0.9659258263])  # 30 degrees about +y
    edge = b.mesh_from_accessors("Edge Probe 4", unit_box, edge_paint, translation=[0, 0, 1.1], scale=[0.6] * 3)
    cam = b.camera("Camera", eye=[0, 2.4, 6.5], target=[0, 0.9, 0], yfov_deg=40.0)
    sun = b.directional_light("Sun", [-0.3, -1, -0.5], [1, 1, 1], 3.0 * 683)
    for m in b.meshes:                       # mesh names other than the node names
        m["name"] += "-mesh"
    b.roots = [rig, floor, wuerfel, wall, edge, cam, sun]
    names = [b.nodes[i]["name"] for i in b.roots]
    assert names[:5] == TOP_LEVEL, names
    assert sorted(b.nodes[i]["name"] for i in range(len(b.nodes)) if "mesh" in b.nodes[i]) == sorted(OBJECTS)
    return b


def write_gltf(path):
    return build_scene().write(path, "tests/cryptomatte/make_cycles_ids.py")


def expected_assets():
    return {"Crate": "Rig", "Lamp.Shade": "Rig", **{n: n for n in OBJECTS if n not in ("Crate", "Lamp.Shade")}}


PROBE_LONG = "Long " + "x" * 295                 # 300 bytes


def write_probe_gltf(path):
    """a throw-away scene (not committed) asking what Blender does with awkward names: three nodes named `Twin`
    (two top-level, one under `Group`), two materials named `Twin Mat`, a node without a name (mesh
    `Nameless-mesh`), a name with a double quote and a backslash, and a 300-byte name"""
    b = HierarchyBuilder()
    mat_a = b.lambert("Twin Mat", [0.8, 0.2, 0.2])
    mat_b = b.lambert("Twin Mat", [0.2, 0.8, 0.2])
    mat_q = b.lambert('Mat "q" \\ back', [0.2, 0.2, 0.8])
    nodes = []
    for i, (name, mat) in enumerate([("Twin", mat_a), ("Twin", mat_b), ("Twin", mat_a), (None, mat_b),
                                     ('Quote "q" \\ back', mat_q), (PROBE_LONG, mat_a)]):
        n = b.box(name or "Nameless", [-0.4, -0.4, -0.4], [0.4, 0.4, 0.4], mat, translation=[-2.75 + 1.1 * i, 0, 0])
        b.meshes[b.nodes[n]["mesh"]]["name"] = (name or "Nameless") + "-mesh"
        if name is None:
            del b.nodes[n]["name"]
        nodes.append(n)
    group = b.add_node({"name": "Group", "children": [nodes[2]]})
    cam = b.camera("Camera", eye=[0, 0, 9], target=[0, 0, 0], yfov_deg=40.0)
    b.roots = [nodes[0], nodes[1], group] + nodes[3:] + [cam]
    b.write(path, "tests/cryptomatte/make_cycles_ids.py probe")


MATERIALS = ["Oak Wood", "Grün", "Plaster", "Lamp Shade/Fabric (v2)", "Edge Paint 9"]


# ----------------------------------------------------------------------------------------------- Blender
def render_with_cycles(gltf_path, out_dir, layouts=("multipart", "interleaved")):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    before_objects = set(o.name for o in bpy.data.objects)
    before_materials = set(m.name for m in bpy.data.materials)
    bpy.ops.import_scene.gltf(filepath=gltf_path)
    scene = bpy.context.scene
    imported = [o for o in bpy.data.objects if o.name not in before_objects]

    def top(o):
        while o.parent is not None:
            o = o.parent
        return o

    objects = {}
    for o in sorted(imported, key=lambda o: o.name):
        objects[o.name] = {"type": o.type, "parent": o.parent.name if o.parent else None, "asset": top(o).name,
                           "data": o.data.name if o.data is not None else None,
                           "materials": [s.material.name for s in o.material_slots if s.material]}
    materials = sorted(m.name for m in bpy.data.materials if m.name not in before_materials)
    cams = [o for o in imported if o.type == "CAMERA"]
    assert len(cams) == 1, cams
    scene.camera = cams[0]

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = SAMPLES
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.seed = 0
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 1
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    for stamp in ("date", "time", "render_time", "frame", "filename"):   # no run-to-run churn in the EXR header
        setattr(scene.render, "use_stamp_" + stamp, False)
    vl = bpy.context.view_layer
    vl.use_pass_cryptomatte_object = True
    vl.use_pass_cryptomatte_material = True
    vl.use_pass_cryptomatte_asset = True
    vl.pass_cryptomatte_depth = LEVELS
    im = scene.render.image_settings
    if hasattr(im, "media_type"):           # Blender 5.0: the container kind, then the format
        im.media_type = "MULTI_LAYER_IMAGE"
    im.file_format = "OPEN_EXR_MULTILAYER"
    im.color_depth = "32"
    im.exr_codec = "ZIP"
    bpy.ops.render.render()
    # the render result, saved twice: Blender 5.0's default multi-part EXR (one part per pass), and the legacy
    # single-part file with every channel in one part (image_settings.use_exr_interleave)
    exrs = {}
    result = bpy.data.images["Render Result"]
    for layout in layouts:
        interleave = layout == "interleaved"
        if hasattr(im, "use_exr_interleave"):
            im.use_exr_interleave = interleave
        elif interleave:
            continue
        exrs[layout] = os.path.join(out_dir, "render_%s.exr" % layout)
        result.save_render(exrs[layout], scene=scene)
        assert os.path.isfile(exrs[layout]), os.listdir(out_dir)
    return {"blender": bpy.app.version_string, "view_layer": vl.name, "objects": objects, "materials": materials,
            "exrs": exrs}


def read_exr(path):
    """({cryptomatte/... header attribute: str} from any part; {channel name: 2-D float32 array};
    [[part name, [its channel names], whether it holds cryptomatte/ attributes], ...])"""
    import OpenEXR
    header, channels, parts = {}, {}, []
    with OpenEXR.File(path, separate_channels=True) as f:
        for i, part in enumerate(f.parts):
            crypto_attributes = False
            for k, v in part.header.items():
                v = v.decode("utf-8") if isinstance(v, bytes) else v
                if k.startswith("cryptomatte/"):
                    assert header.get(k, v) == v, k
                    header[k] = v
                    crypto_attributes = True
            names = sorted(part.channels)
            parts.append([part.header.get("name", "part %d" % i), names, crypto_attributes])
            for name in names:
                channels[name] = part.channels[name].pixels.copy()
    return header, channels, parts


def channel(channels, prefix, component):
    """`prefix.component` in either case (the Cryptomatte specification names the rank channels .r .g .b .a)"""
    found = [n for n in channels if n.lower() == ("%s.%s" % (prefix, component)).lower()]
    assert len(found) == 1, (prefix, component, found)
    return channels[found[0]]


# ----------------------------------------------------------------------------------------------- checks
def check_manifest_hashes(layers):
    """every manifest hash is this file's MurmurHash3 of the UTF-8 name; returns how many"""
    n = 0
    for layer, manifest in layers.items():
        for name, hexhash in manifest.items():
            assert len(hexhash) == 8 and hexhash == hexhash.lower(), (layer, name, hexhash)
            mine = "%08x" % name_hash(name)
            assert mine == hexhash, "%s %r: Cycles %s, MurmurHash3 here %s" % (layer, name, hexhash, mine)
            n += 1
    return n


def check():
    """no Blender: the committed glTF is this script's, and the hashes reproduce the committed manifests"""
    self_test()
    with tempfile.TemporaryDirectory() as tmp:
        p = os.path.join(tmp, "ids_scene.gltf")
        write_gltf(p)
        assert open(p, "rb").read() == open(GLTF, "rb").read(), "ids_scene.gltf differs from what this script writes"
    ref = json.load(open(JSON, encoding="utf-8"))
    n = check_manifest_hashes(ref["layers"])
    for exr_layer, key in ref["layer_keys"].items():
        assert layer_key(exr_layer) == key, (exr_layer, key)
    for layer, seen in ref["pixel_id_bits"].items():
        for name, bits in seen.items():
            assert "%08x" % id_bits(name_hash(name)) == bits, (layer, name, bits)
    if "probe" in ref:
        n += check_manifest_hashes({layer: {re.sub(r"x\{(\d+)\}", lambda m: "x" * int(m.group(1)), k): v
                                            for k, v in manifest.items()}
                                    for layer, manifest in ref["probe"]["manifests"].items()})
    print("ok: glTF reproduced; %d manifest hashes, %d layer keys and the pixel IDs reproduced" %
          (n, len(ref["layer_keys"])))
    import importlib.util
    if importlib.util.find_spec("OpenEXR") is None:
        print("(OpenEXR not installed: cycles_render.exr not decoded)")
        return
    header, channels, _ = read_exr(EXR)
    layers, layer_keys, _, _ = crypto_metadata(header)
    assert layers == ref["layers"] and layer_keys == ref["layer_keys"]
    assert decode_pixels(channels, layer_keys, layers)[0] == ref["pixel_id_bits"]
    print("ok: cycles_render.exr's manifests and decoded pixel IDs are cycles_ids.json's")


def crypto_metadata(header):
    """the header's cryptomatte/<key>/{name,hash,conversion,manifest}: ({short layer name: manifest},
    {EXR layer name: key}, {EXR layer name: [attribute names]}, {EXR layer name: raw manifest string})"""
    crypto = {}
    for k, v in header.items():
        if k.startswith("cryptomatte/"):
            _, key, field = k.split("/", 2)
            crypto.setdefault(key, {})[field] = v
    layers, layer_keys, attributes, raw = {}, {}, {}, {}
    for key, fields in sorted(crypto.items()):
        exr_layer = fields["name"]
        short = exr_layer.split(".")[-1]
        assert short in LAYERS, exr_layer
        assert fields.get("hash") == "MurmurHash3_32", fields.get("hash")
        assert fields.get("conversion") == "uint32_to_float32", fields.get("conversion")
        assert layer_key(exr_layer) == key, "layer %r: key %s, first 7 hex digits of its hash %s" % (
            exr_layer, key, layer_key(exr_layer))
        raw[exr_layer] = fields["manifest"]
        try:
            layers[short] = dict(sorted(json.loads(fields["manifest"]).items()))
        except ValueError:                 # Cycles writes names unescaped: a `"` or `\` in a name breaks the JSON
            layers[short] = None
        layer_keys[exr_layer] = key
        attributes[exr_layer] = sorted("cryptomatte/%s/%s" % (key, f) for f in fields)
    return layers, layer_keys, attributes, raw


def decode_pixels(channels, layer_keys, known_names):
    """{short layer: {name: uint32 bits of its float ID as found in the rank channels}}, {short layer: mean summed
    coverage per pixel}; every ID with coverage > 0 must be id_bits(MurmurHash3(name)) of a name in known_names"""
    pixel_id_bits, coverage = {}, {}
    for exr_layer in layer_keys:
        short = exr_layer.split(".")[-1]
        by_bits = {id_bits(name_hash(n)): n for n in known_names[short]}
        seen, unknown, total, rank_layer = {}, set(), 0.0, 0
        while any(c.lower().startswith(("%s%02d." % (exr_layer, rank_layer)).lower()) for c in channels):
            prefix = "%s%02d" % (exr_layer, rank_layer)
            r, g, b, a = (channel(channels, prefix, c) for c in "rgba")
            for ids, cov in ((r, g), (b, a)):
                for f, c in zip(ids.ravel().tolist(), cov.ravel().tolist()):
                    if c <= 0.0:
                        continue
                    total += c
                    bits = float_to_bits(f)
                    if bits in by_bits:
                        seen[by_bits[bits]] = "%08x" % bits
                    else:
                        unknown.add("%08x" % bits)
            rank_layer += 1
        assert rank_layer == (LEVELS + 1) // 2, (exr_layer, rank_layer)
        assert not unknown, "%s: pixel IDs not in the manifest: %s" % (short, sorted(unknown))
        pixel_id_bits[short] = dict(sorted(seen.items()))
        coverage[short] = round(total / next(iter(channels.values())).size, 6)
    return pixel_id_bits, coverage


def lenient_manifest(text):
    """{name: hex} from a manifest whose names may hold unescaped quotes and backslashes (Cycles writes them so): a
    name runs from `{"` or `,"` to the next `":"` followed by 8 hex digits and `"` and `,` or `}`"""
    assert text.startswith("{") and text.endswith("}"), text
    found = re.findall(r'(?:^\{|,)"(.*?)":"([0-9a-f]{8})"(?=,|\}$)', text)
    assert "{" + ",".join('"%s":"%s"' % kv for kv in found) + "}" == text, text
    return dict(sorted(found))


def shorten_long_name(v):
    """the probe's 300-byte name, spelled `Long x{N}` (N: how many x Blender kept) so the JSON stays small"""
    if isinstance(v, dict):
        return {shorten_long_name(k): shorten_long_name(x) for k, x in v.items()}
    if isinstance(v, list):
        return [shorten_long_name(x) for x in v]
    if isinstance(v, str) and "x" * 40 in v:
        return re.sub("x{40,}", lambda m: "x{%d}" % len(m.group(0)), v)
    return v


def compact_json(v, depth=0):
    """JSON indented by one space a level, lists of scalars on one line"""
    pad = " " * (depth + 1)
    one_line = json.dumps(v, ensure_ascii=False, separators=(", ", ": "))
    if isinstance(v, dict) and v and not any(isinstance(x, (dict, list)) and x for x in v.values()) \
            and len(one_line) + depth < 110:
        return one_line
    if isinstance(v, dict) and v:
        items = ["%s%s: %s" % (pad, json.dumps(k, ensure_ascii=False), compact_json(x, depth + 1))
                 for k, x in v.items()]
        return "{\n" + ",\n".join(items) + "\n" + " " * depth + "}"
    if isinstance(v, list) and any(isinstance(x, (dict, list)) for x in v):
        return "[\n" + ",\n".join(pad + compact_json(x, depth + 1) for x in v) + "\n" + " " * depth + "]"
    if isinstance(v, list):
        return "[" + ", ".join(json.dumps(x, ensure_ascii=False) for x in v) + "]"
    return json.dumps(v, ensure_ascii=False)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="no Blender: check the committed files only")
    args = ap.parse_args()
    if args.check:
        return check()
    self_test()
    size = write_gltf(GLTF)
    print("wrote %s (%d bytes)" % (os.path.relpath(GLTF, REPO), size))

    exr_files = {}
    with tempfile.TemporaryDirectory() as tmp:
        bl = render_with_cycles(GLTF, tmp)
        for layout, path in bl["exrs"].items():
            exr_files[layout] = read_exr(path)
        shutil.copyfile(bl["exrs"]["multipart"], EXR)
        probe_gltf = os.path.join(tmp, "probe.gltf")
        write_probe_gltf(probe_gltf)
        pb = render_with_cycles(probe_gltf, tmp, layouts=("multipart",))
        probe = (pb, read_exr(pb["exrs"]["multipart"]))

    # the header's cryptomatte attributes, the same in both layouts
    meta = {layout: crypto_metadata(h) for layout, (h, _, _) in exr_files.items()}
    layers, layer_keys, attributes, _ = meta["multipart"]
    for layout, m in meta.items():
        assert m[:3] == meta["multipart"][:3], layout
    assert sorted(layers) == sorted(LAYERS), sorted(layers)
    n = check_manifest_hashes(layers)
    print("MurmurHash3 here reproduces all %d manifest hashes and the %d layer keys" % (n, len(layer_keys)))

    # the rank channels: every pixel's (id, coverage) pairs, the same in both layouts
    decoded = {layout: decode_pixels(ch, layer_keys, layers) for layout, (_, ch, _) in exr_files.items()}
    pixel_id_bits, coverage = decoded["multipart"]
    for layout, d in decoded.items():
        assert d == decoded["multipart"], layout
    # one pixel, spelled out: the centre pixel's rank-0 object
    obj_layer = [l for l in layer_keys if l.endswith("CryptoObject")][0]
    c = SIZE // 2
    f0 = float(channel(exr_files["multipart"][1], obj_layer + "00", "r")[c, c])
    b0 = float_to_bits(f0)
    centre = [nm for nm in layers["CryptoObject"] if id_bits(name_hash(nm)) == b0]
    assert len(centre) == 1, ("%08x" % b0, f0)
    print("centre pixel: %s00.r = %r = bits %08x -> %r" % (obj_layer, f0, b0, centre[0]))

    # what the scene should show, by the names Blender gave things
    mesh_objects = sorted(nm for nm, o in bl["objects"].items() if o["type"] == "MESH")
    assets = {nm: bl["objects"][nm]["asset"] for nm in mesh_objects}
    renamed = sorted(set(OBJECTS) ^ set(mesh_objects)) + sorted(set(MATERIALS) ^ set(bl["materials"]))
    missing = {"CryptoObject": sorted(set(mesh_objects) - set(pixel_id_bits["CryptoObject"])),
               "CryptoMaterial": sorted(set(bl["materials"]) - set(pixel_id_bits["CryptoMaterial"])),
               "CryptoAsset": sorted(set(assets.values()) - set(pixel_id_bits["CryptoAsset"]))}
    print("Blender's mesh objects:", mesh_objects)
    print("Blender's materials:", bl["materials"])
    print("assets (top-most parent):", assets)
    print("renamed by Blender:", renamed or "none")
    print("not seen in the image:", missing)
    print("summed coverage per pixel (1 where every sample hit something):", coverage)
    assert not any(missing.values()), missing
    assert not renamed and assets == expected_assets(), (renamed, assets)
    assert pixel_id_bits["CryptoAsset"].keys() == set(expected_assets().values()), pixel_id_bits["CryptoAsset"]
    manifest_vs_pixel = {}
    for short in LAYERS:
        for nm, h in layers[short].items():
            bits = "%08x" % id_bits(int(h, 16))
            if bits != h:
                manifest_vs_pixel.setdefault(short, {})[nm] = {"manifest": h, "pixel": pixel_id_bits[short].get(nm)}
    print("manifest value != float ID bits:", manifest_vs_pixel)

    layouts = {}
    for layout, (_, ch, parts) in exr_files.items():
        layouts[layout] = {
            "parts": [pn for pn, _, _ in parts] if len(parts) > 1 else len(parts),
            "cryptomatte_attributes_in_parts": [pn for pn, _, has in parts if has],
            "rank_channels": sorted(x for _, cs, _ in parts for x in cs if ".Crypto" in x)}
    out = {
        "blender": bl["blender"],
        "scene": "tests/cryptomatte/ids_scene.gltf",
        "render": {"engine": "CYCLES", "device": "CPU", "size": [SIZE, SIZE], "samples": SAMPLES,
                   "levels": LEVELS},
        "layers": layers,
        "layer_keys": layer_keys,
        "header_attributes": attributes,
        "exr_layouts": layouts,
        "pixel_id_bits": pixel_id_bits,
        "manifest_vs_pixel": manifest_vs_pixel,
        "blender_objects": bl["objects"],
        "blender_materials": bl["materials"],
        "renamed_by_blender": renamed,
    }
    pb, (ph, _, _) = probe
    players, pkeys, _, praw = crypto_metadata(ph)
    out["probe"] = {
        "about": "write_probe_gltf(): awkward glTF names (not committed); what Blender named things and the "
                 "manifests Cycles wrote",
        "gltf_nodes": ["Twin", "Twin", "Group > Twin", "(no name; mesh Nameless-mesh)", 'Quote "q" \\ back',
                       "Long + 295 x (300 bytes)"],
        "gltf_materials": ["Twin Mat", "Twin Mat", 'Mat "q" \\ back'],
        "blender_objects": {nm: {k: o[k] for k in ("type", "parent", "asset", "data", "materials")}
                            for nm, o in pb["objects"].items()},
        "blender_materials": pb["materials"],
        "manifest_is_json": {l: players[l.split(".")[-1]] is not None for l in pkeys},
        "manifests": {l.split(".")[-1]: lenient_manifest(praw[l]) for l in pkeys},
    }
    n = check_manifest_hashes(out["probe"]["manifests"])
    print("probe: MurmurHash3 here reproduces all %d manifest hashes" % n)
    out["probe"] = shorten_long_name(out["probe"])
    print("probe: Blender's objects", sorted(out["probe"]["blender_objects"]), "materials",
          out["probe"]["blender_materials"], "manifests are JSON:", out["probe"]["manifest_is_json"])
    with open(JSON, "w", encoding="utf-8") as f:
        f.write(compact_json(out) + "\n")
    print("wrote %s (%d bytes)" % (os.path.relpath(EXR, REPO), os.path.getsize(EXR)))
    print("wrote %s (%d bytes)" % (os.path.relpath(JSON, REPO), os.path.getsize(JSON)))


if __name__ == "__main__":
    main()
