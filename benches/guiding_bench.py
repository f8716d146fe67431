#!/usr/bin/env python3
"""Path guiding against no guiding (issue 34), run by hand after `cargo build --release` (never in CI).

    python3 benches/guiding_bench.py render [--out DIR] [--scenes backlit,doorgap,baffle] [--res 128] [--spp 64]
                                            [--ref-spp 4096] [--rounds 3] [--threads 2] [--nimbus PATH]
                                            [--variants off,on,roulette]
    python3 benches/guiding_bench.py table [--out DIR]

`render` needs only Python (it can run on another machine: copy the binary and the scenes there, bring DIR
back); `table` reads the EXRs with NumPy and PyPI's OpenEXR.

1. Per scene (`benches/peers/scenes/NAME.gltf`), a reference: `nimbus render --guiding off` at `--ref-spp` with a
   seed of its own. It is Nimbus's own image, so the table compares Nimbus's variants with one another only (their
   relative efficiency), not with other renderers. Its own noise (the mean of its `variance` layer, the variance
   of each pixel's mean) is subtracted from every MSE.
2. `--rounds` rounds, each with its own seed, interleaved: unguided (`--guiding off`), guided with guided Russian
   roulette and splitting (`--guiding on --guided-roulette`) and guided with classic Russian roulette (`--guiding
   on`), all at `--spp` (`--variants` renders some of them: `off`, `roulette`, `on`). MSE is over all pixels and channels of the beauty; efficiency =
   1 / (MSE x seconds), seconds being the renderer's `render_seconds` (training included).
3. `table` prints, per scene, one row per variant: seconds, MSE, efficiency against unguided, and the work per
   camera sample: rays (camera + bounce + shadow), extra paths from splitting, and density lookups (all media).
"""
import argparse
import glob
import json
import os
import subprocess
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VARIANTS = {
    "unguided": ["--guiding", "off"],
    "guided, classic roulette": ["--guiding", "on"],
    "guided, guided roulette and splitting": ["--guiding", "on", "--guided-roulette"],
}
# `--variants` names, in the order of VARIANTS.
VARIANT_NAMES = ["off", "on", "roulette"]


def render(nimbus, scene, out, a, spp, seed, extra):
    args = [nimbus, "render", scene, "-o", out, "--width", str(a.res), "--height", str(a.res), "--seed", str(seed),
            "--threads", str(a.threads), "--spp", str(spp), "--stats", out + ".json"] + extra
    subprocess.run(args, check=True, capture_output=True)


def render_all(a):
    os.makedirs(a.out, exist_ok=True)
    nimbus = a.nimbus or os.path.join(ROOT, "target", "release", "nimbus")
    for name in a.scenes.split(","):
        scene = os.path.join(ROOT, "benches", "peers", "scenes", name + ".gltf")
        ref = os.path.join(a.out, f"{name}_reference.exr")
        if not os.path.exists(ref):
            start = time.time()
            render(nimbus, scene, ref, a, a.ref_spp, 7777, ["--guiding", "off"])
            print(f"{name}: reference {a.ref_spp} spp in {time.time() - start:.1f} s", flush=True)
        for r in range(a.rounds):
            for v, (label, extra) in enumerate(VARIANTS.items()):
                if VARIANT_NAMES[v] not in a.variants.split(","):
                    continue
                out = os.path.join(a.out, f"{name}_v{v}_r{r}.exr")
                render(nimbus, scene, out, a, a.spp, 100 + r, extra)
                secs = json.load(open(out + ".json"))["render_seconds"]
                print(f"{name}: round {r} {label}: {secs:.2f} s", flush=True)


def read(path, channels="RGB"):
    import Imath
    import numpy as np
    import OpenEXR
    f = OpenEXR.InputFile(path)
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    pt = Imath.PixelType(Imath.PixelType.FLOAT)
    return np.stack([np.frombuffer(f.channel(c, pt), np.float32).reshape(h, w) for c in channels], -1).astype(
        np.float64)


def table(a):
    import numpy as np
    import OpenEXR
    for ref_path in sorted(glob.glob(os.path.join(a.out, "*_reference.exr"))):
        name = os.path.basename(ref_path)[: -len("_reference.exr")]
        ref = read(ref_path)
        names = sorted(n for n in OpenEXR.InputFile(ref_path).header()["channels"] if n.startswith("variance."))
        ref_var = float(np.mean(read(ref_path, names)))
        ref_stats = json.load(open(ref_path + ".json"))
        print(f"\n{name} at {ref.shape[1]}x{ref.shape[0]}, reference {ref_stats['samples_per_pixel']} spp unguided "
              f"(its variance {ref_var:.3e} subtracted), {ref_stats['threads']} threads")
        print("| render | spp | seconds (training) | MSE | efficiency vs unguided | rays / sample "
              "| split paths / sample | density lookups / sample |")
        print("|---|---|---|---|---|---|---|---|")
        base = None
        for v, label in enumerate(VARIANTS):
            runs = sorted(glob.glob(os.path.join(a.out, f"{name}_v{v}_r*.exr")))
            if not runs:
                continue
            stats = [json.load(open(p + ".json")) for p in runs]
            mse = np.mean([np.mean((read(p) - ref) ** 2) - ref_var for p in runs])
            seconds = np.mean([s["render_seconds"] for s in stats])
            training = np.mean([s["guiding"]["training_seconds"] for s in stats])
            spp = stats[0]["samples_per_pixel"]
            samples = spp * stats[0]["width"] * stats[0]["height"]
            rays = np.mean([s["rays"]["camera"] + s["rays"]["bounce"] + s["rays"]["shadow"] for s in stats])
            split = np.mean([s["rays"]["split"] for s in stats])
            lookups = np.mean([sum(m["density_lookups"] for m in s["media"]) for s in stats])
            eff = 1.0 / (mse * seconds)
            base = base or eff
            print(f"| {label} | {spp} | {seconds:.2f} ({training:.2f}) | {mse:.3e} | {eff / base:.2f}x "
                  f"| {rays / samples:.1f} | {split / samples:.2f} | {lookups / samples:.0f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("command", choices=["render", "table"])
    ap.add_argument("--out", default=os.path.join(ROOT, "benches", "guiding_out"))
    ap.add_argument("--scenes", default="backlit,doorgap,baffle")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--nimbus", help="the nimbus binary (default: target/release/nimbus)")
    ap.add_argument("--variants", default=",".join(VARIANT_NAMES), help="which variants to render")
    a = ap.parse_args()
    render_all(a) if a.command == "render" else table(a)


if __name__ == "__main__":
    main()
