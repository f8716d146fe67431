#!/usr/bin/env python3
"""Guided against unguided efficiency on every benchmark scene with a scattering medium (issue 34's auto rule).

For each scene: the pilot's albedo and median optical depth (`--explain` under `--guiding auto`), then per seed
four renders in the order off, on, on, off (A B B A), each under `/usr/bin/time -f "%U %S"` (CPU seconds of the
process, user + system) with `--stats`. Errors: the two-seed variance mean((x1 - x2)^2) / 2 of each variant (both
estimators unbiased, so it is the variance of one render's pixels), the per-seed mean of the `variance` layer
(the per-sample variance over n; kept for comparison only: with Owen-scrambled Sobol samples it is not the pixel
mean's error, docs/performance.md "Where guiding pays"), and where a Mitsuba reference exists the per-seed MSE
against it minus its variance. Efficiency = 1 / (error x CPU s). Run with the Mitsuba venv's Python (it reads the
EXRs with `mitsuba.Bitmap`), after copying the peers' cached references into `benches/peers/out/reference/`:

    /tmp/mi-venv/bin/python benches/guiding_auto.py --spp 128 --out /tmp/guiding-auto [SCENE_NAME | NAME=PATH ...]

Each scene prints one JSON line (also appended to OUT/results.jsonl).
"""

import argparse
import json
import os
import re
import subprocess

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VALIDATION = os.path.join(os.path.dirname(ROOT), "shared", "validation")
PEER_REFERENCES = os.path.join(ROOT, "benches", "peers", "out", "reference")

# name: (scene file, Mitsuba reference or None); the reference's `_se.exr` sits beside it
SCENES = {
    "cloud": ("assets/cloud.gltf", None),
    "cloud_mitsuba_check": ("assets/cloud_mitsuba_check.gltf", None),
    "thesis_mixed": ("assets/thesis_mixed.gltf", None),
    "backlit": ("benches/peers/scenes/backlit.gltf", os.path.join(PEER_REFERENCES, "backlit_128_512_20a9abcbac.exr")),
    "doorgap": ("benches/peers/scenes/doorgap.gltf", os.path.join(PEER_REFERENCES, "doorgap_128_1024_3d80a7f0f7.exr")),
    "glass": ("benches/peers/scenes/glass.gltf", None),
    "haze": ("benches/peers/scenes/haze.gltf", None),
    "plume": ("benches/peers/scenes/plume.gltf", None),
    "point-in-medium": (os.path.join(VALIDATION, "point-in-medium", "scene.gltf"),
                        os.path.join(VALIDATION, "point-in-medium", "reference_mitsuba_32768spp_128.exr")),
    "scattering-box": (os.path.join(VALIDATION, "scattering-box", "scene.gltf"),
                       os.path.join(VALIDATION, "scattering-box", "reference_mitsuba_4096spp_128.exr")),
    "smoke-sun": (os.path.join(VALIDATION, "smoke-sun", "scene.gltf"),
                  os.path.join(VALIDATION, "smoke-sun", "reference_mitsuba_2048spp_128.exr")),
}


def layers(path):
    """The beauty (RGB) and the variance layer of a Nimbus EXR, or the RGB of a reference."""
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    parts = dict(mi.Bitmap(path).split())
    rgb = np.array(parts["<root>"], dtype=np.float64)[:, :, :3]
    var = np.array(parts["variance"], dtype=np.float64) if "variance" in parts else None
    return rgb, var


def pilot(binary, scene):
    p = subprocess.run([binary, "render", scene, "-o", "/tmp/guiding-auto-pilot.exr", "--width", "8", "--spp", "1",
                        "--explain", "--guiding", "auto"], capture_output=True, text=True, check=True)
    line = next(l for l in p.stderr.splitlines() if "path guiding" in l)
    m = re.search(r"albedo ([0-9.]+) and median optical depth ([0-9.]+)", line)
    return (float(m.group(1)), float(m.group(2))) if m else None, line


def render(binary, scene, out, mode, seed, a):
    stats = out.replace(".exr", ".json")
    timing = out.replace(".exr", ".time")
    cmd = ["/usr/bin/time", "-f", "%U %S", "-o", timing, binary, "render", scene, "-o", out, "--spp", str(a.spp),
           "--width", str(a.res), "--threads", str(a.threads), "--seed", str(seed), "--guiding", mode,
           "--stats", stats]
    subprocess.run(cmd, capture_output=True, text=True, check=True)
    user, system = open(timing).read().split()[-2:]
    s = json.load(open(stats))
    return float(user) + float(system), s


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", default=list(SCENES), help="names of SCENES, or NAME=PATH")
    ap.add_argument("--binary", default=os.path.join(ROOT, "target", "release", "nimbus"))
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--out", default="/tmp/guiding-auto")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    for name in a.scenes:
        # NAME=PATH renders a scene file of the set's (a probe), without a reference
        name, scene, ref_path = name.split("=", 1) + [None] if "=" in name else (name, *SCENES[name])
        scene = os.path.join(ROOT, scene)
        (albedo_depth, explain) = pilot(a.binary, scene)
        ref = ref_var = None
        if ref_path and os.path.exists(ref_path):
            ref, _ = layers(ref_path)
            se, _ = layers(ref_path.replace(".exr", "_se.exr"))
            ref_var = float(np.mean(se * se))
        load = [os.getloadavg()[0]]
        cpu = {m: {} for m in ("off", "on")}
        img, var, work = {m: {} for m in cpu}, {m: {} for m in cpu}, {m: {} for m in cpu}
        for seed in a.seeds:
            for mode in ("off", "on", "on", "off"):
                out = os.path.join(a.out, f"{name}_{mode}_{a.spp}_{seed}.exr")
                secs, stats = render(a.binary, scene, out, mode, seed, a)
                cpu[mode].setdefault(seed, []).append(secs)
                work[mode][seed] = {"rays": sum(stats["rays"].values()),
                                    "density_lookups": sum(m["density_lookups"] for m in stats["media"])}
                img[mode][seed], var[mode][seed] = layers(out)
        load.append(os.getloadavg()[0])
        res = {"scene": name, "spp": a.spp, "pilot": albedo_depth, "explain": explain, "load": load,
               "cpu": cpu, "work": work}
        s1, s2 = a.seeds[:2]
        for mode in cpu:
            x1, x2 = img[mode][s1], img[mode][s2]
            res[f"var2_{mode}"] = float(np.mean((x1 - x2) ** 2) / 2)
            res[f"varlayer_{mode}"] = {s: float(np.mean(var[mode][s])) for s in a.seeds}
            res[f"finite_{mode}"] = all(bool(np.isfinite(img[mode][s]).all()) for s in a.seeds)
            res[f"mean_{mode}"] = {s: img[mode][s].reshape(-1, 3).mean(0).tolist() for s in a.seeds}
            if ref is not None and ref.shape == x1.shape:
                res[f"mse_{mode}"] = {s: float(np.mean((img[mode][s] - ref) ** 2)) - ref_var for s in a.seeds}
        c = {m: float(np.mean([np.mean(v) for v in cpu[m].values()])) for m in cpu}
        res["eff_var2"] = (res["var2_off"] * c["off"]) / (res["var2_on"] * c["on"])
        res["eff_varlayer"] = {s: (res["varlayer_off"][s] * np.mean(cpu["off"][s]))
                               / (res["varlayer_on"][s] * np.mean(cpu["on"][s])) for s in a.seeds}
        if "mse_off" in res:
            res["eff_mse"] = {s: (res["mse_off"][s] * np.mean(cpu["off"][s]))
                              / (res["mse_on"][s] * np.mean(cpu["on"][s])) for s in a.seeds}
        line = json.dumps(res)
        print(line, flush=True)
        with open(os.path.join(a.out, "results.jsonl"), "a") as f:
            f.write(line + "\n")


if __name__ == "__main__":
    main()
