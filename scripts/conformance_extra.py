#!/usr/bin/env python3
"""Re-renders the public scene files listed in scripts/conformance_extra.tsv with a nimbus binary and prints a
Markdown table: does each file load, does it render (finishes, no NaN sample, not black), with the error or
warnings the CLI printed. Whether a render *looks right* is a judgement against each model's screenshot; the
table gives the figures to judge from, and the PNGs are kept in --out.

The files are not in this repository: fetch each listed repository at the listed commit and lay it out as
ROOT/<owner>+<name>/<path> (as docs/conformance.md describes). With --realworld DIR the scene files under
DIR (../shared/realworld) are rendered too.

    scripts/conformance_extra.py ROOT path/to/nimbus [--realworld ../shared/realworld] [--out /tmp/conf]

Python 3 standard library only.
"""

import argparse
import json
import os
import struct
import subprocess
import sys
import time
import zlib

SCENE_EXTENSIONS = (".gltf", ".glb", ".obj", ".usd", ".usda", ".usdc", ".usdz")


def read_png(path):
    """Decodes an 8-bit RGB or RGBA, non-interlaced PNG (what nimbus writes) into (width, height, channels,
    rows of bytes)."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    pos, idat, header = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
    width, height, depth, colour, _, _, interlace = header
    if depth != 8 or colour not in (2, 6) or interlace != 0:
        raise ValueError(f"{path}: unsupported PNG layout (depth {depth}, colour {colour})")
    channels = 3 if colour == 2 else 4
    raw = zlib.decompress(idat)
    stride = width * channels
    rows, previous = [], bytearray(stride)
    for y in range(height):
        start = y * (stride + 1)
        kind, line = raw[start], bytearray(raw[start + 1 : start + 1 + stride])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b = previous[i]
            c = previous[i - channels] if i >= channels else 0
            if kind == 1:
                line[i] = (line[i] + a) & 255
            elif kind == 2:
                line[i] = (line[i] + b) & 255
            elif kind == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pred) & 255
        rows.append(line)
        previous = line
    return width, height, channels, rows


def png_figures(path):
    """Mean sRGB value (0-255) over RGB, and the fraction of pixels that are not black."""
    width, height, channels, rows = read_png(path)
    total, lit = 0, 0
    for line in rows:
        for x in range(width):
            px = line[x * channels : x * channels + 3]
            total += sum(px)
            lit += 1 if max(px) > 2 else 0
    return total / (3 * width * height), lit / (width * height)


def one_line(text, limit=160):
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 1] + "…"


def render(nimbus, scene, out_dir, name, args):
    stem = name.replace("/", "-").replace(".", "_")
    exr = os.path.join(out_dir, stem + ".exr")
    stats = os.path.join(out_dir, stem + ".json")
    for p in (exr, stats, exr[:-4] + ".png"):
        if os.path.exists(p):
            os.remove(p)
    height = args.width if args.height is None else args.height
    cmd = [nimbus, "render", scene, "--width", str(args.width)] + (["--height", str(height)] if height else [])
    cmd += ["--spp", str(args.spp), "--threads", str(args.threads), "-o", exr, "--stats", stats]
    start = time.monotonic()
    try:
        run = subprocess.run(cmd, capture_output=True, text=True, timeout=args.timeout)
        code, err = run.returncode, run.stderr
    except subprocess.TimeoutExpired:
        code, err = None, f"timed out after {args.timeout} s"
    seconds = time.monotonic() - start
    lines = [l for l in err.splitlines() if l.strip() and "%" not in l and "rendering" not in l.lower()]
    row = {"name": name, "seconds": seconds, "loads": False, "renders": False, "mean": None, "lit": None,
           "nan": None, "default_env": any("has no light" in l for l in lines), "notes": "",
           "panic": "panicked" in err, "png": None}
    if code is None or code < 0:
        row["notes"] = "CRASH/TIMEOUT: " + one_line(err if code is None else f"signal {-code}")
        return row
    if code != 0:
        error = lines[-1] if lines else f"exit {code}"
        error = error.removeprefix("nimbus: error: ").replace(scene + ": ", "")
        row["notes"] = one_line(error, 400)
        row["loads"] = "triangles," in err  # failed after loading (e.g. while writing)
        return row
    row["loads"] = True
    with open(stats) as f:
        row["nan"] = json.load(f).get("nan_samples")
    row["png"] = exr[:-4] + ".png"
    row["mean"], row["lit"] = png_figures(row["png"])
    row["renders"] = row["nan"] == 0 and row["mean"] > 1.0
    warnings = [l.split("warning: ", 1)[1] for l in lines if "warning: " in l]
    row["notes"] = "; ".join(one_line(w, 200) for w in warnings[:3])
    if len(warnings) > 3:
        row["notes"] += f"; (+{len(warnings) - 3} more warnings)"
    return row


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("root", help="folder holding <owner>+<name>/<path> for every listed file")
    parser.add_argument("nimbus", help="the nimbus binary to test")
    parser.add_argument("--list", default=os.path.join(os.path.dirname(__file__), "conformance_extra.tsv"))
    parser.add_argument("--realworld", help="also render every scene file under this folder")
    parser.add_argument("--out", default="/tmp/conformance-extra", help="folder for the EXR/PNG/JSON outputs")
    parser.add_argument("--width", type=int, default=128)
    parser.add_argument("--height", type=int, help="image height (default: the width; 0: the CLI's own, from the camera's aspect ratio)")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--threads", type=int, default=0)
    parser.add_argument("--timeout", type=int, default=300, help="seconds allowed per file")
    parser.add_argument("--json", help="also write the rows (with each PNG's path) to this JSON file, for "
                        "scripts/conformance_sheet.py")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)

    jobs = []
    if args.realworld:
        for dirpath, _, files in sorted(os.walk(args.realworld)):
            for f in sorted(files):
                if f.lower().endswith(SCENE_EXTENSIONS):
                    rel = os.path.relpath(os.path.join(dirpath, f), args.realworld)
                    jobs.append(("realworld/" + rel, os.path.join(dirpath, f)))
    with open(args.list) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            name, repo, _commit, path = line.rstrip("\n").split("\t")[:4]
            jobs.append((name, os.path.join(args.root, repo.replace("/", "+"), path)))
    scene_of = dict(jobs)

    rows = []
    for name, scene in jobs:
        if not os.path.isfile(scene):
            rows.append({"name": name, "seconds": 0, "loads": False, "renders": False, "mean": None,
                         "lit": None, "nan": None, "default_env": False, "notes": f"MISSING {scene}",
                         "panic": False, "png": None})
        else:
            rows.append(render(args.nimbus, scene, args.out, name, args))
        r = rows[-1]
        print(f"{r['name']}: loads={r['loads']} renders={r['renders']} {r['seconds']:.1f}s {r['notes']}",
              file=sys.stderr)

    yes = lambda b: "yes" if b else "no"
    if args.json:
        with open(args.json, "w") as f:
            json.dump([dict(r, scene=scene_of[r["name"]]) for r in rows], f, indent=1)
    print("| file | loads | renders | panic | mean sRGB | lit px | NaN samples | default env | s | error / warnings |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        mean = "" if r["mean"] is None else f"{r['mean']:.1f}"
        lit = "" if r["lit"] is None else f"{100 * r['lit']:.0f}%"
        nan = "" if r["nan"] is None else str(r["nan"])
        notes = r["notes"].replace("|", "\\|")
        print(f"| {r['name']} | {yes(r['loads'])} | {yes(r['renders'])} | {yes(r['panic'])} | {mean} | {lit} | {nan} | "
              f"{yes(r['default_env'])} | {r['seconds']:.1f} | {notes} |")
    loads = sum(r["loads"] for r in rows)
    renders = sum(r["renders"] for r in rows)
    panics = sum(r["panic"] for r in rows)
    print(f"\n{len(rows)} files: {loads} load, {renders} render (finish, no NaN sample, not black), "
          f"{panics} panic.")


if __name__ == "__main__":
    main()
