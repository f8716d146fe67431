#!/usr/bin/env python3
"""A production-size VDB (issue 33): load time and peak memory of `nimbus info` against OpenVDB's C++ reader, and
the time of a render of it.

    python3 benches/peers/vdb_production.py [--size 660] [--file /tmp/nimbus-production.vdb] [--reps 3]
                                            [--nimbus target/release/nimbus] [--cycles-python PYTHON] [--no-docs]

Run by hand from the repository root after `cargo build --release` (never in CI). Needs Debian's python3-openvdb
(on /usr/bin/python3.11), libopenvdb-dev and libboost-dev (`apt-get install -y libopenvdb-dev libboost-dev`; OpenVDB 10's
headers include Boost's), and g++.

1. Writes (unless it is there already) a deterministic `--size`^3 ball of noisy fog density with OpenVDB: at the
   default 660^3 about 150 M active voxels, a file of 0.5-0.6 GB, under /tmp (never committed). The noise is
   NumPy's PCG64 from seed 1, so the file is the same on every run.
2. Builds `vdb_load.cpp` (below, written next to the file) against libopenvdb: it opens the file with delayed
   loading off, reads every grid in full (as Nimbus does) and touches every leaf's voxel count.
3. Runs `nimbus info FILE` and the harness `--reps` times each, alternating, under `/usr/bin/time` (wall seconds,
   peak resident memory), and one `nimbus render` of the ball at 256x256 and 16 spp (wall seconds and peak
   memory of the whole process), with its time to the first pixel (`--stats` `first_pixel_seconds`, from the
   start of the render: the scene loaded).
4. With `--cycles-python` (default: `$CYCLES_PYTHON`, a Python with `bpy` 5.0.1), renders the same scene once with
   Cycles (`cycles_render.py`, same size, samples and threads): wall seconds and peak memory of the whole process,
   and the seconds of its render call alone. The image means of both renders (`oiiotool --printstats`, where installed)
   show that they render the same thing.
5. Prints the table and (unless `--no-docs`) writes it into `docs/performance.md` between the `vdb` section
   markers, which `run.py` keeps when it rewrites the page.
"""
import argparse
import json
import os
import subprocess
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DOC = os.path.join(ROOT, "docs", "performance.md")
BEGIN, END = "<!-- section:vdb -->", "<!-- /section:vdb -->"

MAKE = r"""
import numpy as np, pyopenvdb as vdb, sys
n, slab = int(sys.argv[2]), 20
rng = np.random.default_rng(1)
g = vdb.FloatGrid()
g.name = "density"
for z0 in range(0, n, slab):
    k = min(slab, n - z0)
    z = np.arange(z0, z0 + k)[:, None, None]
    y = np.arange(n)[None, :, None]
    x = np.arange(n)[None, None, :]
    r = np.sqrt((x - n / 2) ** 2 + (y - n / 2) ** 2 + (z - n / 2) ** 2) / (n / 2)
    d = np.where(r < 1, (1 - r) * rng.random((k, n, n)), 0).astype(np.float32)
    g.copyFromArray(np.ascontiguousarray(d.transpose(2, 1, 0)), ijk=(0, 0, z0), tolerance=0)
g.transform = vdb.createLinearTransform(voxelSize=1.0 / n)
vdb.write(sys.argv[1], grids=[g])
"""

HARNESS = r"""
// Reads every grid of a VDB file in full with OpenVDB (delayed loading off) and prints the active voxel count.
#include <openvdb/openvdb.h>
#include <iostream>
int main(int argc, char** argv) {
    if (argc != 2) { std::cerr << "usage: vdb_load FILE\n"; return 2; }
    openvdb::initialize();
    openvdb::io::File file(argv[1]);
    file.open(/*delayLoad=*/false);
    openvdb::GridPtrVecPtr grids = file.getGrids();
    openvdb::Index64 voxels = 0;
    for (auto& grid : *grids) voxels += grid->activeVoxelCount();
    file.close();
    std::cout << "active voxels " << voxels << "\n";
    return 0;
}
"""


def timed(cmd, env=None):
    """(wall seconds, peak resident MB) of one run of `cmd`"""
    p = subprocess.run(["/usr/bin/time", "-f", "%e %M"] + cmd, capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{p.stderr[-3000:]}")
    seconds, kib = p.stderr.strip().splitlines()[-1].split()
    return float(seconds), int(kib) / 1024


def scene(vdb_file, directory):
    """a glTF placing the ball (unit box at the origin) under a sun, over a floor, for the render"""
    path = os.path.join(directory, "production_vdb.gltf")
    gltf = {
        "asset": {"version": "2.0"}, "scene": 0,
        "scenes": [{"nodes": [0, 1, 2], "extras": {"max_bounces": 16,
                                                   "nimbus_environment": {"color": [0.3, 0.45, 0.7]}}}],
        "nodes": [{"name": "ball", "extras": {"nimbus_volume": {"file": vdb_file, "density_grid": "density",
                                                                "density_scale": 20.0, "albedo": [0.9, 0.9, 0.9]}}},
                  {"name": "camera", "camera": 0, "translation": [0.5, 0.5, 3.0]},
                  {"name": "sun", "rotation": [-0.3826834, 0.0, 0.0, 0.9238795],
                   "extensions": {"KHR_lights_punctual": {"light": 0}}}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.6, "aspectRatio": 1.0, "znear": 0.01}}],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 2000.0}]}},
        "extensionsUsed": ["KHR_lights_punctual"],
    }
    with open(path, "w") as f:
        json.dump(gltf, f)
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=660)
    ap.add_argument("--file", default="/tmp/nimbus-production.vdb")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--nimbus", default=os.path.join(ROOT, "target", "release", "nimbus"))
    ap.add_argument("--python", default="/usr/bin/python3.11")
    ap.add_argument("--cycles-python", default=os.environ.get("CYCLES_PYTHON"),
                    help="a Python with bpy for the Cycles render (default $CYCLES_PYTHON; none: no Cycles render)")
    ap.add_argument("--no-docs", action="store_true")
    a = ap.parse_args()
    if not os.path.exists(a.file):
        print(f"writing {a.file} ({a.size}^3 ball) ...", flush=True)
        subprocess.run([a.python, "-c", MAKE, a.file, str(a.size)], check=True)
    size_mb = os.path.getsize(a.file) / 1e6
    work = tempfile.mkdtemp(prefix="nimbus-vdb-")
    src, exe = os.path.join(work, "vdb_load.cpp"), os.path.join(work, "vdb_load")
    with open(src, "w") as f:
        f.write(HARNESS)
    subprocess.run(["g++", "-O2", "-std=c++17", src, "-o", exe, "-lopenvdb", "-ltbb", "-lpthread"], check=True)
    info = json.loads(subprocess.run([a.nimbus, "info", "--json", a.file], capture_output=True, text=True,
                                     check=True).stdout)
    print(json.dumps(info)[:400])
    load_before = os.getloadavg()[0]
    runs = {"nimbus info": [], "OpenVDB C++": []}
    for _ in range(a.reps):
        runs["nimbus info"].append(timed([a.nimbus, "info", a.file]))
        runs["OpenVDB C++"].append(timed([exe, a.file]))
    for name, rs in runs.items():
        print(f"{name}: best {min(s for s, _ in rs):.2f} s, peak {min(m for _, m in rs):.0f} MB  (all: {rs})")
    stats_path = os.path.join(work, "stats.json")
    render_s, render_mb = timed([a.nimbus, "render", scene(a.file, work), "-o", os.path.join(work, "r.exr"),
                                 "--width", "256", "--spp", "16", "--threads", "2", "--stats", stats_path])
    stats = json.load(open(stats_path))
    render = {"Nimbus": {"seconds": render_s, "call_s": stats["render_seconds"], "peak_mb": render_mb,
                         "mean": image_mean(os.path.join(work, "r.exr"))}}
    print(f"render: {render_s:.2f} s, peak {render_mb:.0f} MB, NaN samples {stats.get('nan_samples')}, "
          f"first pixel {stats.get('first_pixel_seconds')} s after the render's start, mean {render['Nimbus']['mean']}")
    if a.cycles_python:
        render["Cycles"] = cycles(a.cycles_python, scene(a.file, work), os.path.join(work, "cycles.exr"))
        print(f"cycles: {render['Cycles']}")
    load_after = os.getloadavg()[0]
    if not a.no_docs:
        write_section(a, size_mb, info, runs, render, stats, (load_before, load_after))


def cycles(python, scene_path, out):
    """Cycles' render of the scene (`cycles_render.py`, 256x256, 16 spp, 2 threads): whole-process wall seconds and
    peak MB, its render call's seconds, and the image mean"""
    cmd = ["/usr/bin/time", "-f", "%e %M", python, os.path.join(os.path.dirname(os.path.abspath(__file__)),
           "cycles_render.py"), scene_path, out, "--res", "256", "--spp", "16", "--threads", "2", "--seed", "1"]
    p = subprocess.run(cmd, capture_output=True, text=True)
    result = next((line for line in p.stdout.splitlines() if line.startswith("RESULT ")), None)
    if p.returncode != 0 or result is None:
        raise SystemExit(f"the Cycles render failed:\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}")
    seconds, kib = p.stderr.strip().splitlines()[-1].split()
    return {"seconds": float(seconds), "call_s": json.loads(result[len("RESULT "):])["render_s"],
            "peak_mb": int(kib) / 1024, "mean": image_mean(out)}


def image_mean(exr):
    """The mean of the image's R, G and B (`oiiotool --printstats`), or None without oiiotool"""
    try:
        p = subprocess.run(["oiiotool", exr, "--ch", "R,G,B", "--printstats"], capture_output=True, text=True)
    except FileNotFoundError:
        return None
    for line in p.stdout.splitlines():
        if line.strip().startswith("Stats Avg:"):
            values = [float(v) for v in line.split(":", 1)[1].split()[:3]]
            return sum(values) / len(values)
    return None


def write_section(a, size_mb, info, runs, render, stats, loads):
    best = {k: (min(s for s, _ in v), min(m for _, m in v)) for k, v in runs.items()}
    n, o = best["nimbus info"], best["OpenVDB C++"]
    lines = [BEGIN, "## Production-size VDB", "",
             f"Written by `python3 benches/peers/vdb_production.py` (issue 33): a deterministic {a.size}³ ball of "
             f"noisy fog density written by OpenVDB 10 (`python3-openvdb`), {size_mb:.0f} MB, read in full "
             f"{a.reps} times each, alternating, by `nimbus info` and by a small C++ harness against Debian's "
             "libopenvdb-dev (delayed loading off, built by the script); best wall time and least peak resident "
             "memory (`/usr/bin/time`).", "",
             "| reader | seconds | peak MB |", "|---|---|---|",
             f"| `nimbus info` | {n[0]:.2f} | {n[1]:.0f} |", f"| OpenVDB C++ | {o[0]:.2f} | {o[1]:.0f} |",
             f"| Nimbus / OpenVDB | **{n[0] / o[0]:.2f}x** | **{n[1] / o[1]:.2f}x** |", "",
             "A render of the ball (256x256, 16 spp, 2 threads, sun and sky), once by each renderer: wall seconds and "
             "peak resident memory of the whole process (reading the file, building the medium, rendering, writing "
             "the image), the seconds of the render itself (Nimbus's `--stats` `render_seconds`, Cycles' "
             "`bpy.ops.render.render` call), and the image's mean (R, G, B averaged; `oiiotool --printstats`):", "",
             "| renderer | seconds in all | render seconds | peak MB | image mean |", "|---|---|---|---|---|"]
    for name, r in render.items():
        mean = "n/a" if r["mean"] is None else f"{r['mean']:.4f}"
        lines.append(f"| {name} | {r['seconds']:.2f} | {r['call_s']:.2f} | {r['peak_mb']:.0f} | {mean} |")
    if "Cycles" in render:
        c, nb = render["Cycles"], render["Nimbus"]
        lines += ["", f"Nimbus / Cycles: **{nb['seconds'] / c['seconds']:.2f}x** the time in all, "
                      f"**{nb['call_s'] / c['call_s']:.2f}x** the render call's, **{nb['peak_mb'] / c['peak_mb']:.2f}x** "
                      "the peak memory."]
    else:
        lines += ["", "Cycles was not run (no `--cycles-python` or `$CYCLES_PYTHON`)."]
    lines += ["", f"Nimbus's first pixel came {stats['first_pixel_seconds']:.3f} s after its render's start (`--stats` "
              f"`first_pixel_seconds`). Load average (1 min) {loads[0]:.1f} before, {loads[1]:.1f} after, on 2 cores "
              "shared with other builds.", "", END]
    section = "\n".join(lines)
    text = open(DOC).read() if os.path.exists(DOC) else ""
    if BEGIN in text and END in text:
        text = text[:text.index(BEGIN)] + section + text[text.index(END) + len(END):]
    else:
        text = text.rstrip("\n") + "\n\n" + section + "\n"
    with open(DOC, "w") as f:
        f.write(text)
    print(f"wrote the VDB section of {DOC}")


if __name__ == "__main__":
    main()
