#!/usr/bin/env python3
"""Writes issue 36's instancing case as a GLB: NODES nodes (default 2,000) drawing one grid mesh of about
TRIANGLES triangles (default 50,000), laid out on a 50-wide lattice, lit by a sun of 2,049 lx (3 W/m²).

    python3 scripts/instanced_forest.py forest.glb [--nodes 2000] [--triangles 50000]

Before instancing, loading it copied the mesh per node (2.4 GB for the defaults, refused by the memory budget);
now it is one prototype and 2,000 instances (`tests/suite/gltf_hostile.rs` builds the same file in memory)."""

import argparse
import json
import math
import struct


def grid(side):
    """A side x side vertex grid over the unit square with a gentle bump, and its triangles as u32 indices."""
    positions = []
    for j in range(side):
        for i in range(side):
            x, y = i / (side - 1), j / (side - 1)
            positions += [x, y, 0.05 * math.sin(6 * x) * math.cos(5 * y)]
    indices = []
    for j in range(side - 1):
        for i in range(side - 1):
            a = j * side + i
            indices += [a, a + 1, a + side + 1, a, a + side + 1, a + side]
    return positions, indices


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out")
    parser.add_argument("--nodes", type=int, default=2000)
    parser.add_argument("--triangles", type=int, default=50000)
    args = parser.parse_args()
    side = int(math.sqrt(args.triangles / 2)) + 1
    positions, indices = grid(side)
    pos = struct.pack(f"<{len(positions)}f", *positions)
    idx = struct.pack(f"<{len(indices)}I", *indices)
    bin_chunk = pos + idx
    xs, ys, zs = positions[0::3], positions[1::3], positions[2::3]
    nodes = [
        {
            "mesh": 0,
            "translation": [(k % 50) * 1.2, 0.0, (k // 50) * 1.2],
            "rotation": [-0.70710677, 0.0, 0.0, 0.70710677],
        }
        for k in range(args.nodes)
    ]
    nodes.append({"extensions": {"KHR_lights_punctual": {"light": 0}},
                  "rotation": [-0.5, 0.3, 0.2, 0.787]})
    doc = {
        "asset": {"version": "2.0", "generator": "nimbus scripts/instanced_forest.py"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 2049.0}]}},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(positions) // 3, "type": "VEC3",
             "min": [min(xs), min(ys), min(zs)], "max": [max(xs), max(ys), max(zs)]},
            {"bufferView": 1, "componentType": 5125, "count": len(indices), "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(pos)},
            {"buffer": 0, "byteOffset": len(pos), "byteLength": len(idx)},
        ],
        "buffers": [{"byteLength": len(bin_chunk)}],
    }
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    bin_chunk += b"\0" * (-len(bin_chunk) % 4)
    total = 12 + 8 + len(js) + 8 + len(bin_chunk)
    with open(args.out, "wb") as f:
        f.write(struct.pack("<4sII", b"glTF", 2, total))
        f.write(struct.pack("<I4s", len(js), b"JSON") + js)
        f.write(struct.pack("<I4s", len(bin_chunk), b"BIN\0") + bin_chunk)
    print(f"{args.out}: {total} bytes, {args.nodes} nodes x {len(indices) // 3} triangles")


if __name__ == "__main__":
    main()
