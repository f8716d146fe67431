#!/usr/bin/env python3
"""Path guiding against no guiding (issue 34), run by hand after `cargo build --release` (never in CI).

    python3 benches/guiding_bench.py [--scene benches/peers/scenes/backlit.gltf] [--res 128] [--spp 64]
                                     [--ref-spp 2048] [--rounds 3] [--threads 2]

1. A reference: `nimbus render --guiding off` at `--ref-spp` with a seed of its own, cached in
   `benches/guiding_out/` by the scene file's hash, res and spp; its own noise (the mean of its `variance` layer,
   the variance of each pixel's mean) is subtracted from every MSE.
2. `--rounds` rounds, each with its own seed, interleaved: unguided at `--spp`, guided at `--spp` (equal spp;
   the guided time includes its training), and guided with `--time-limit` equal to the unguided render's seconds
   (equal time). MSE is over all pixels and channels of the beauty; efficiency = 1 / (MSE x seconds), seconds
   being the renderer's `render_seconds` (training included).
3. The bundled demo, unguided and guided at the same spp: the cost of guiding where auto leaves it off.

Prints one table; numbers are what docs/reference.md quotes.
"""
import argparse
import hashlib
import json
import os
import subprocess

import numpy as np
import OpenEXR
import Imath

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NIMBUS = os.path.join(ROOT, "target", "release", "nimbus")
OUT = os.path.join(ROOT, "benches", "guiding_out")


def read(path, channels="RGB"):
    f = OpenEXR.InputFile(path)
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    pt = Imath.PixelType(Imath.PixelType.FLOAT)
    return np.stack([np.frombuffer(f.channel(c, pt), np.float32).reshape(h, w) for c in channels], -1).astype(
        np.float64)


def render(scene, out, res, spp, seed, guiding, threads, time_limit=None):
    args = [NIMBUS, "render", "-o", out, "--width", str(res), "--height", str(res), "--seed", str(seed),
            "--threads", str(threads), "--guiding", guiding, "--stats", out + ".json"]
    if scene:
        args.insert(2, scene)
    args += ["--time-limit", f"{time_limit:.3f}"] if time_limit else ["--spp", str(spp)]
    subprocess.run(args, check=True, capture_output=True)
    return json.load(open(out + ".json"))


def variance_channels(path):
    """names of the variance layer's channels in the EXR (the variance of each pixel's mean)"""
    names = OpenEXR.InputFile(path).header()["channels"].keys()
    return [n for n in sorted(names) if n.startswith("variance.")]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="benches/peers/scenes/backlit.gltf")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--ref-spp", type=int, default=2048)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args()
    os.makedirs(OUT, exist_ok=True)
    scene = os.path.join(ROOT, a.scene)
    digest = hashlib.sha256(open(scene, "rb").read()).hexdigest()[:12]
    ref_path = os.path.join(OUT, f"reference_{a.res}_{a.ref_spp}_{digest}.exr")
    if not os.path.exists(ref_path):
        print(f"reference: {a.ref_spp} spp unguided ...", flush=True)
        render(scene, ref_path, a.res, a.ref_spp, 7777, "off", a.threads)
    ref = read(ref_path)
    ref_var = float(np.mean(read(ref_path, variance_channels(ref_path))))
    rows = {"off": [], "on": [], "on, equal time": []}
    for r in range(a.rounds):
        seed = 100 + r
        stats = render(scene, os.path.join(OUT, "off.exr"), a.res, a.spp, seed, "off", a.threads)
        rows["off"].append((stats, np.mean((read(os.path.join(OUT, "off.exr")) - ref) ** 2) - ref_var))
        stats = render(scene, os.path.join(OUT, "on.exr"), a.res, a.spp, seed, "on", a.threads)
        rows["on"].append((stats, np.mean((read(os.path.join(OUT, "on.exr")) - ref) ** 2) - ref_var))
        limit = rows["off"][-1][0]["render_seconds"]
        stats = render(scene, os.path.join(OUT, "eq.exr"), a.res, a.spp, seed, "on", a.threads, time_limit=limit)
        rows["on, equal time"].append((stats, np.mean((read(os.path.join(OUT, "eq.exr")) - ref) ** 2) - ref_var))
    base = None
    print(f"{a.scene} at {a.res}^2, {a.spp} spp, {a.threads} threads, {a.rounds} rounds; reference {a.ref_spp} spp "
          f"(its variance {ref_var:.3e} subtracted)")
    print("| render | spp | seconds (training) | MSE | efficiency vs unguided |")
    print("|---|---|---|---|---|")
    for name, runs in rows.items():
        seconds = np.mean([s["render_seconds"] for s, _ in runs])
        training = np.mean([s["guiding"]["training_seconds"] for s, _ in runs])
        spp = np.mean([s["samples_per_pixel"] for s, _ in runs])
        mse = np.mean([m for _, m in runs])
        eff = 1.0 / (mse * seconds)
        base = base or eff
        print(f"| {name} | {spp:.0f} | {seconds:.2f} ({training:.2f}) | {mse:.3e} | {eff / base:.2f}x |")
    cells = rows["on"][0][0]["guiding"]
    print(f"cache: {cells['cells']} cells, {cells['guided_cells']} guided, {cells['training_records']} records")
    demo = [render(None, os.path.join(OUT, f"demo_{g}.exr"), a.res, 16, 1, g, a.threads) for g in ("off", "on")]
    print(f"demo at {a.res}^2, 16 spp: unguided {demo[0]['render_seconds']:.2f} s, guided "
          f"{demo[1]['render_seconds']:.2f} s (training {demo[1]['guiding']['training_seconds']:.2f} s)")


if __name__ == "__main__":
    main()
