"""Where the light BVH starts to pay: the power sampler against the light BVH as the number of lights grows.

    python3 benches/light_sampler_threshold.py [--layout spread|panel] [--counts 2,3,4,8,16,64,256] [--seeds 4]
                                               [--spp 64] [--res 128]

For each count N it writes a scene (into benches/peers/out/threshold/, git-ignored): a 20 m floor with a few boxes
under N emissive triangles facing down. `spread` (the default) scatters small triangles at random over the floor
at heights 0.5-3 m, their radiances log-uniform over two decades (so both the distance and the power matter to a
good choice); `panel` tiles one 2 m square panel light 3 m above the centre with the N triangles, all equally
bright (one light cut into pieces, where a spatial choice can gain nothing). It renders
the scene with `--light-sampler power` and `--light-sampler bvh`, interleaved, with `--seeds` seeds each, and
prints per sampler the image variance (the per-pixel sample variance across the seeds, averaged over the pixels:
no reference is needed to compare two unbiased estimators of the same image) and the CPU seconds of the process,
then the BVH's efficiency 1 / (variance x seconds) relative to the power sampler's. Needs target/release/nimbus
and Python with numpy and mitsuba (which reads the EXR files, as in benches/peers/run.py).
"""
import argparse
import os
import random
import resource
import subprocess
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "assets"))
sys.path.insert(0, os.path.join(ROOT, "benches", "peers"))
from gltf_writer import GltfBuilder  # noqa: E402
from run import read_rgb  # noqa: E402

NIMBUS = os.path.join(ROOT, "target", "release", "nimbus")
OUT = os.path.join(ROOT, "benches", "peers", "out", "threshold")


def scene(count, layout, path):
    """The floor, boxes and `count` downward-facing emissive triangles laid out as `layout`, from a fixed random
    seed."""
    rng = random.Random(count)
    b = GltfBuilder()
    white = b.lambert("white", [0.7, 0.7, 0.7])
    b.quad("floor", [[-10, 0, 10], [10, 0, 10], [10, 0, -10], [-10, 0, -10]], white)
    for i in range(6):
        x, z = rng.uniform(-7, 7), rng.uniform(-7, 7)
        b.box(f"box{i}", [x - 0.5, 0, z - 0.5], [x + 0.5, rng.uniform(0.5, 2), z + 0.5], white)
    if layout == "panel":
        emitter = b.emitter("panel", [1.0, 1.0, 1.0], 20.0)
        positions = []
        for i in range(count):
            # Strips of the panel along x, each cut into two triangles (one for an odd count's last strip).
            x0, x1 = -1 + 2 * (i // 2) / ((count + 1) // 2), -1 + 2 * (i // 2 + 1) / ((count + 1) // 2)
            last_alone = count % 2 == 1 and i == count - 1
            if last_alone:
                corners = [[x0, 3, -1], [x1, 3, -1], [x1, 3, 1]]
            elif i % 2 == 0:
                corners = [[x0, 3, -1], [x1, 3, -1], [x1, 3, 1]]
            else:
                corners = [[x0, 3, -1], [x1, 3, 1], [x0, 3, 1]]
            positions += corners
        # One mesh: the scene's light sampler choice sees one emitter, as it would a modelled panel.
        b.add_mesh("panel", positions, [[0, -1, 0]] * len(positions), list(range(len(positions))), emitter)
        count = 0
    for i in range(count):
        x, y, z = rng.uniform(-9, 9), rng.uniform(0.5, 3), rng.uniform(-9, 9)
        strength = 10 ** rng.uniform(0, 2)
        emitter = b.emitter(f"light{i}", [1.0, 1.0, 1.0], strength)
        s = 0.15
        # Counter-clockwise seen from below: the emitting face looks down (-Y).
        corners = [[x - s, y, z - s], [x + s, y, z - s], [x, y, z + s]]
        b.add_mesh(f"light{i}", corners, [[0, -1, 0]] * 3, [0, 1, 2], emitter)
    b.camera("camera", eye=[0, 14, 16], target=[0, 0, 0], yfov_deg=50)
    b.write(path, "benches/light_sampler_threshold.py")


def render(path, sampler, seed, a):
    """The image and the CPU seconds (user + system) of one render."""
    out = os.path.join(OUT, f"render_{sampler}_{seed}.exr")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([NIMBUS, "render", path, "-o", out, "--spp", str(a.spp), "--width", str(a.res),
                    "--threads", "2", "--seed", str(seed), "--light-sampler", sampler],
                   check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return read_rgb(out), cpu


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--layout", choices=["spread", "panel"], default="spread")
    ap.add_argument("--counts", default="2,3,4,8,16,64,256")
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--res", type=int, default=128)
    a = ap.parse_args()
    os.makedirs(OUT, exist_ok=True)
    print("| lights | power variance | bvh variance | variance power/bvh | cpu s power | cpu s bvh | "
          "bvh efficiency / power |")
    print("|---|---|---|---|---|---|---|")
    for count in [int(c) for c in a.counts.split(",")]:
        path = os.path.join(OUT, f"{a.layout}_{count}.gltf")
        scene(count, a.layout, path)
        images = {"power": [], "bvh": []}
        seconds = {"power": 0.0, "bvh": 0.0}
        for seed in range(1, a.seeds + 1):
            for sampler in ("power", "bvh"):
                image, cpu = render(path, sampler, seed, a)
                images[sampler].append(image)
                seconds[sampler] += cpu
        var = {s: float(np.mean(np.var(np.array(images[s]), axis=0, ddof=1))) for s in images}
        ratio = var["power"] / var["bvh"]
        efficiency = ratio * seconds["power"] / seconds["bvh"]
        print(f"| {count} | {var['power']:.3e} | {var['bvh']:.3e} | {ratio:.2f} | {seconds['power']:.2f} | "
              f"{seconds['bvh']:.2f} | {efficiency:.2f} |", flush=True)


if __name__ == "__main__":
    main()
