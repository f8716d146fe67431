#!/usr/bin/env python3
"""Checks the generated assets (pure Python; VDB statistics too when run with Debian's /usr/bin/python3, which has
pyopenvdb). Exits non-zero on the first class of problem found, after listing them all.

Run from the repository root:  python3 assets/check_assets.py [FILE.gltf|FILE.glb ...]
  (default: assets/*.gltf, assets/*.glb, tests/scenes/*.gltf; then assets/cloud.vdb and tests/scenes/*.vdb)

Per glTF file: buffers decode and match byteLength; every bufferView lies inside its buffer; every accessor lies
inside its view (count, component size, byteOffset) and declares a min/max equal to its float32 data; indices are
below the vertex count; normals have unit length; meshes whose material declares a medium (nimbus_medium or
KHR_materials_volume) are closed and consistently wound, with outward normals (positive signed volume);
index-matched boundaries have transmission 1, ior 1, roughness 0, metallic 0; nimbus_volume files exist.
"""
import base64
import glob
import json
import math
import os
import struct
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
COMP = {5120: ("b", 1), 5121: ("B", 1), 5122: ("h", 2), 5123: ("H", 2), 5125: ("I", 4), 5126: ("f", 4)}
NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
problems = []


def bad(path, msg):
    problems.append(f"{path}: {msg}")
    print(f"  PROBLEM {msg}")


def load(path):
    data = open(path, "rb").read()
    if path.endswith(".glb"):
        magic, version, total = struct.unpack_from("<III", data, 0)
        assert magic == 0x46546C67 and version == 2 and total == len(data), "GLB header"
        jlen, jtype = struct.unpack_from("<II", data, 12)
        assert jtype == 0x4E4F534A
        g = json.loads(data[20:20 + jlen])
        bufs = []
        off = 20 + jlen
        if off < len(data):
            blen, btype = struct.unpack_from("<II", data, off)
            assert btype == 0x004E4942
            bufs.append(data[off + 8:off + 8 + blen])
        return g, bufs
    g = json.loads(data)
    bufs = []
    for b in g.get("buffers", []):
        uri = b["uri"]
        if uri.startswith("data:"):
            bufs.append(base64.b64decode(uri.split(",", 1)[1]))
        else:
            bufs.append(open(os.path.join(os.path.dirname(path), uri), "rb").read())
    return g, bufs


def read_accessor(path, g, bufs, i):
    a = g["accessors"][i]
    v = g["bufferViews"][a["bufferView"]]
    fmt, size = COMP[a["componentType"]]
    nc = NCOMP[a["type"]]
    off = v.get("byteOffset", 0) + a.get("byteOffset", 0)
    stride = v.get("byteStride", size * nc)
    need = a.get("byteOffset", 0) + (a["count"] - 1) * stride + size * nc
    if need > v["byteLength"]:
        bad(path, f"accessor {i} needs {need} bytes of view {a['bufferView']} ({v['byteLength']})")
        return None
    buf = bufs[v["buffer"]]
    out = [struct.unpack_from("<%d%s" % (nc, fmt), buf, off + k * stride) for k in range(a["count"])]
    if "min" in a or "max" in a:
        for key, fn in (("min", min), ("max", max)):
            want = [fn(e[c] for e in out) for c in range(nc)]
            got = [struct.unpack("<f", struct.pack("<f", x))[0] if fmt == "f" else x for x in a.get(key, want)]
            if got != want:
                bad(path, f"accessor {i} {key} {a.get(key)} != data {want}")
    return out


def check_closed(path, name, P, idx):
    """every undirected edge used by exactly two triangles, once in each direction; signed volume > 0"""
    # weld coincident vertices (flat-shaded boxes and UV-sphere seams duplicate positions)
    key = {}
    wid = [key.setdefault(tuple(round(c, 6) for c in p), len(key)) for p in P]
    tris = [(wid[idx[t]], wid[idx[t + 1]], wid[idx[t + 2]]) for t in range(0, len(idx), 3)]
    tris = [t for t in tris if len(set(t)) == 3]         # UV-sphere poles have degenerate triangles
    directed = {}
    for a, b, c in tris:
        for e in ((a, b), (b, c), (c, a)):
            directed[e] = directed.get(e, 0) + 1
    open_edges = [e for e, n in directed.items() if n != 1 or directed.get((e[1], e[0]), 0) != 1]
    vol = 0.0
    for t in range(0, len(idx), 3):
        a, b, c = (P[idx[t + k]] for k in range(3))
        vol += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6
    if open_edges:
        bad(path, f"mesh {name} holding a medium is not closed/consistently wound ({len(open_edges)} bad edges)")
    if vol <= 0:
        bad(path, f"mesh {name} holding a medium has signed volume {vol:.4g} (inward winding)")
    return vol


def medium_of(mat):
    ex = mat.get("extras", {}).get("nimbus_medium")
    vol = mat.get("extensions", {}).get("KHR_materials_volume")
    return ex, vol


def check_gltf(path):
    print(f"{os.path.relpath(path, ROOT)} ({os.path.getsize(path)} bytes)")
    g, bufs = load(path)
    assert g["asset"]["version"] == "2.0"
    for i, (b, data) in enumerate(zip(g.get("buffers", []), bufs)):
        if len(data) < b["byteLength"]:
            bad(path, f"buffer {i} holds {len(data)} bytes < byteLength {b['byteLength']}")
    for i, v in enumerate(g.get("bufferViews", [])):
        if v.get("byteOffset", 0) + v["byteLength"] > g["buffers"][v["buffer"]]["byteLength"]:
            bad(path, f"bufferView {i} runs past its buffer")
        if v.get("byteOffset", 0) % 4:
            bad(path, f"bufferView {i} not 4-byte aligned")
    used_ext = set(g.get("extensionsUsed", []))
    for m in g.get("materials", []):
        for e in m.get("extensions", {}):
            if e not in used_ext:
                bad(path, f"material {m.get('name')} uses {e} not in extensionsUsed")
    mats = g.get("materials", [])
    summary = []
    for ni, node in enumerate(g.get("nodes", [])):
        name = node.get("name", f"node{ni}")
        nv = node.get("extras", {}).get("nimbus_volume")
        if nv is not None:
            f = os.path.join(os.path.dirname(path), nv["file"])
            if not os.path.exists(f):
                bad(path, f"node {name}: nimbus_volume file {nv['file']} missing")
            summary.append(f"node {name}: extras.nimbus_volume = {json.dumps(nv)} translation={node.get('translation')}")
        if "mesh" not in node:
            continue
        for prim in g["meshes"][node["mesh"]]["primitives"]:
            P = read_accessor(path, g, bufs, prim["attributes"]["POSITION"])
            N = read_accessor(path, g, bufs, prim["attributes"]["NORMAL"]) if "NORMAL" in prim["attributes"] else None
            idx = [x[0] for x in read_accessor(path, g, bufs, prim["indices"])]
            if P is None or idx is None:
                continue
            if len(idx) % 3 or max(idx) >= len(P):
                bad(path, f"node {name}: {len(idx)} indices, max {max(idx)} for {len(P)} vertices")
            if N is not None and any(abs(math.sqrt(sum(c * c for c in n)) - 1) > 1e-5 for n in N):
                bad(path, f"node {name}: non-unit normals")
            mat = mats[prim["material"]] if "material" in prim else {}
            nm, kv = medium_of(mat)
            if nm is not None or kv is not None:
                scale = node.get("scale", [1, 1, 1])
                vol = check_closed(path, name, P, idx) * scale[0] * scale[1] * scale[2]
                ext = mat.get("extensions", {})
                pbr = mat.get("pbrMetallicRoughness", {})
                if ext.get("KHR_materials_transmission", {}).get("transmissionFactor") != 1.0 or \
                        pbr.get("metallicFactor", 1) != 0 or pbr.get("roughnessFactor", 1) != 0:
                    bad(path, f"node {name}: medium boundary is not a smooth transmissive dielectric")
                ior = ext.get("KHR_materials_ior", {}).get("ior", 1.5)
                what = []
                if nm is not None:
                    what.append(f"extras.nimbus_medium = {json.dumps(nm)}")
                    if ior != 1.0:
                        bad(path, f"node {name}: nimbus_medium boundary ior {ior} != 1.0")
                if kv is not None:
                    c, d = kv.get("attenuationColor", [1, 1, 1]), kv.get("attenuationDistance")
                    sa = [round(-math.log(x) / d, 9) for x in c]
                    what.append(f"KHR_materials_volume = {json.dumps(kv)} (sigma_a = {sa}), ior {ior}")
                    if not kv.get("thicknessFactor", 0) > 0:
                        bad(path, f"node {name}: KHR_materials_volume thicknessFactor must be > 0")
                summary.append(f"node {name}: closed mesh, volume {vol:.4f} m^3, {len(idx) // 3} triangles; "
                               + "; ".join(what))
    ex = g["scenes"][g.get("scene", 0)].get("extras", {})
    summary.append(f"scene extras = {json.dumps(ex)}")
    if "nimbus_environment" not in ex or "max_bounces" not in ex:
        print("  note: scene extras lack nimbus_environment or max_bounces (renderer defaults apply)")
    if not any("camera" in n for n in g.get("nodes", [])):
        bad(path, "no camera node")
    lights = g.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    for L in lights:
        summary.append(f"KHR_lights_punctual {json.dumps(L)}")
    for s in summary:
        print("  " + s)


def check_vdb(path):
    try:
        import pyopenvdb as vdb
    except ImportError:
        print(f"{os.path.relpath(path, ROOT)}: pyopenvdb not available (run with /usr/bin/python3)")
        return
    print(f"{os.path.relpath(path, ROOT)} ({os.path.getsize(path)} bytes) file metadata {vdb.readMetadata(path)}")
    for g in vdb.readAll(path)[0]:
        lo, hi = g.evalActiveVoxelBoundingBox()
        mn, mx = g.evalMinMax()
        vs = g.transform.voxelSize()
        wlo = g.transform.indexToWorld(lo)
        whi = g.transform.indexToWorld(hi)
        total = 0.0
        for it in g.citerOnValues():
            total += it.value * it.count
        print(f"  grid '{g.name}' {g.valueTypeName} class={g.gridClass} background={g.background} "
              f"active={g.activeVoxelCount()} leaves={g.leafCount()} min={mn:.6g} max={mx:.6g} "
              f"mean={total / max(1, g.activeVoxelCount()):.6g} index bbox={lo}..{hi} voxel={vs} "
              f"voxel-centre world bbox={tuple(round(c, 6) for c in wlo)}..{tuple(round(c, 6) for c in whi)} "
              f"memUsage={g.memUsage()} B")
        if g.background != 0:
            bad(path, f"grid {g.name} background {g.background} != 0")
        if g.name == "density" and not (mn >= 0 and mx <= 1):
            bad(path, f"density outside [0, 1]: {mn}..{mx}")


def main():
    files = sys.argv[1:] or sorted(glob.glob(os.path.join(ROOT, "assets", "*.gltf"))
                                   + glob.glob(os.path.join(ROOT, "assets", "*.glb"))
                                   + glob.glob(os.path.join(ROOT, "tests", "scenes", "*.gltf")))
    for f in files:
        check_gltf(f)
    if not sys.argv[1:]:
        for f in [os.path.join(ROOT, "assets", "cloud.vdb")] + sorted(glob.glob(os.path.join(ROOT, "tests", "scenes",
                                                                                             "*.vdb"))):
            check_vdb(f)
    print(f"{len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
