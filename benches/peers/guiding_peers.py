#!/usr/bin/env python3
"""Path guiding at equal time against Cycles 5.0 with guiding (issue 34), run by hand after `cargo build --release`
(never in CI).

    python3 benches/peers/guiding_peers.py render [--scenes backlit,doorgap,baffle] [--res 128]
                                                  [--ladder 8,16,32,64,128] [--equal-spp 64] [--ref-spp 1024]
                                                  [--threads 2] [--renderers nimbus-off,nimbus-on,cycles-on,cycles-off]
                                                  [--nimbus PATH] [--out DIR]
    python3 benches/peers/guiding_peers.py report [--scenes ...]

Run with the Python that has Mitsuba 3 (the references, and reading EXRs); Cycles runs in `$CYCLES_PYTHON` (Python
3.11 with `bpy==5.0.1`), as in `run.py`. The renderers: `nimbus-off` (`--guiding off`), `nimbus-on` (`--guiding
on`), `cycles-on` (`cycles_render.py --guiding`: Cycles' path guiding, surface and volume, Blender's default
training) and `cycles-off`.

`render`, per scene (`run.py`'s SCENES):
1. The Mitsuba 3 reference of `run.py` (cached in `benches/peers/out/reference/`; its per-pixel standard error
   from 16 independent passes).
2. The ladder: every renderer at every `--ladder` spp, one after the other (interleaved), seed 1.
3. Equal time (unless `--equal-spp 0`): T is `nimbus-off`'s CPU time at `--equal-spp` on the ladder; every
   renderer is rendered once more (seed 2) at the spp that its ladder's line t = a + b spp (least squares, CPU
   seconds) gives for T.
Time is CPU time (all threads: the machine this was written for is shared, and under load the wall clock
measures the waiting); wall seconds are kept beside it. Nimbus's is the whole process (load, BVH, training,
render, EXR writing), Cycles' its render call alone (its scene sync, BVH and guiding training included, the
Python import and glTF translation not), which favours Cycles, as in `run.py`. MSE is over all pixels and
channels against the reference, minus the reference's own variance (the mean of its squared standard error).

`report` writes, from the saved results (`benches/peers/out/guiding/results_<scene>.json`), the error-against-time
charts `docs/performance/guiding_<scene>.png`, the equal-time pictures `docs/performance/guiding_<scene>_equal.png`
and the tables between the `generated:guiding-peers` markers of `docs/performance.md`. Beside each MSE the tables
give the render's variance estimated from its renderer's own renders of seeds 1 and 2 (`variances`): it is free of
any bias of a translation (a peer's MSE includes its differences of convention), but, from two images per figure,
it is noisier than the MSE, most where the images have fireflies.
"""
import argparse
import json
import os
import resource
import sys

import numpy as np

import run as peers

OUT = os.path.join(peers.OUT, "guiding")
DOCS = os.path.join(peers.ROOT, "docs")
BEGIN, END = "<!-- generated:guiding-peers -->", "<!-- /generated:guiding-peers -->"
LABELS = {"nimbus-off": "Nimbus, unguided", "nimbus-on": "Nimbus, guided", "cycles-on": "Cycles, guided",
          "cycles-off": "Cycles, unguided"}
COLOURS = {"nimbus-off": "tab:blue", "nimbus-on": "tab:cyan", "cycles-on": "tab:green", "cycles-off": "tab:olive"}


def child_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def render(renderer, scene, out, spp, a, seed):
    """one render; returns its CPU seconds, its wall seconds (both as `run.py` counts time) and the guiding
    training's seconds or the peer's version"""
    kind, guiding = renderer.split("-")
    if kind == "nimbus":
        cpu = child_cpu()
        _, wall = peers.run([a.nimbus, "render", scene, "-o", out, "--spp", str(spp), "--width", str(a.res),
                             "--threads", str(a.threads), "--seed", str(seed), "--guiding", guiding,
                             "--stats", out.replace(".exr", ".json")])
        stats = json.load(open(out.replace(".exr", ".json")))
        return {"wall_s": wall, "cpu_s": child_cpu() - cpu, "training_s": stats["guiding"]["training_seconds"]}
    python = os.environ.get("CYCLES_PYTHON", sys.executable)
    stdout, _ = peers.run([python, os.path.join(peers.PEERS_DIR, "cycles_render.py"), scene, out, "--spp", str(spp),
                           "--res", str(a.res), "--threads", str(a.threads), "--seed", str(seed)]
                          + (["--guiding"] if guiding == "on" else []))
    r = peers.peer_result(stdout)
    return {"wall_s": r["render_s"], "cpu_s": r["render_cpu_s"], "peer": r["peer"]}


def measure(name, renderer, scene, spp, a, seed, ref, ref_var):
    out = os.path.join(a.out, "renders", f"{name}_{renderer}_{spp}_{seed}.exr")
    os.makedirs(os.path.dirname(out), exist_ok=True)
    r = render(renderer, scene, out, spp, a, seed)
    img = peers.read_rgb(out)
    r.update(spp=spp, seed=seed, exr=os.path.relpath(out, peers.ROOT), mse=peers.mse(img, ref, ref_var),
             mean=img.reshape(-1, 3).mean(0).tolist(), load=os.getloadavg()[0])
    if renderer.startswith("nimbus"):
        r["mean_se"] = mean_standard_error(out)
    print(f"[{name}] {renderer:10s} spp {spp:4d} seed {seed}: CPU {r['cpu_s']:7.2f} s (wall {r['wall_s']:6.2f} s) "
          f"MSE {r['mse']:.3e}  load {r['load']:.1f}", flush=True)
    return r


def mean_standard_error(path):
    """the standard error of a Nimbus image's mean per channel, from its `variance` layer (each pixel's mean's
    variance; pixels independent)"""
    import OpenEXR
    import Imath
    f = OpenEXR.InputFile(path)
    dw = f.header()["dataWindow"]
    n = (dw.max.x - dw.min.x + 1) * (dw.max.y - dw.min.y + 1)
    pt = Imath.PixelType(Imath.PixelType.FLOAT)
    return [float(np.sqrt(np.frombuffer(f.channel(f"variance.{c}", pt), np.float32).astype(np.float64).sum()) / n)
            for c in "RGB"]


def fit_spp(points, seconds):
    """the spp at which the line t = a + b spp through the ladder's (spp, CPU seconds) reaches `seconds`"""
    spp = np.array([p["spp"] for p in points], float)
    t = np.array([p["cpu_s"] for p in points], float)
    b, a = np.polyfit(spp, t, 1)
    return max(1, int(round((seconds - a) / b))) if b > 0 else int(spp[-1])


def bench_scene(name, a):
    scene = os.path.join(peers.ROOT, peers.SCENES[name][0])
    ref, ref_var = peers.reference(name, scene, a.res, a.ref_spp, a.threads)
    ref_path, ref_spp = peers.reference_path(name, scene, a.res, a.ref_spp)
    ref_se = peers.read_rgb(ref_path.replace(".exr", "_se.exr"))
    result = {"scene": name, "res": a.res, "threads": a.threads, "ref_spp": ref_spp, "ref_var": ref_var,
              "ref_exr": os.path.relpath(ref_path, peers.ROOT), "ref_mean": ref.reshape(-1, 3).mean(0).tolist(),
              "ref_mean_se": (np.sqrt((ref_se ** 2).reshape(-1, 3).sum(0)) / (ref.shape[0] * ref.shape[1])).tolist(),
              "load_start": os.getloadavg(), "ladder": {r: [] for r in a.renderers}, "equal": {}}
    for spp in a.ladder:
        for r in a.renderers:
            result["ladder"][r].append(measure(name, r, scene, spp, a, 1, ref, ref_var))
    if not a.equal_spp:
        result["load_end"] = os.getloadavg()
        return result
    base = next(p for p in result["ladder"]["nimbus-off"] if p["spp"] == a.equal_spp)
    result["equal_seconds"] = base["cpu_s"]
    for r in a.renderers:
        spp = fit_spp(result["ladder"][r], base["cpu_s"])
        result["equal"][r] = measure(name, r, scene, spp, a, 2, ref, ref_var)
    result["load_end"] = os.getloadavg()
    return result


def tonemap(img):
    """linear RGB to 8-bit sRGB, exposure fixed per scene by the caller"""
    img = np.clip(img, 0, 1)
    srgb = np.where(img <= 0.0031308, 12.92 * img, 1.055 * np.power(img, 1 / 2.4) - 0.055)
    return (srgb * 255 + 0.5).astype(np.uint8)


def pictures(res, path):
    """the reference and each renderer's equal-time render side by side, cropped to the middle half of the frame
    (each crop shown at 2x, nearest pixel) and at one exposure (the reference's mean to 0.18)"""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ref = peers.read_rgb(os.path.join(peers.ROOT, res["ref_exr"]))
    scale = 0.18 / max(float(ref.mean()), 1e-12)
    panels = [(f"Mitsuba reference\n{res['ref_spp']} spp", ref)]
    for r, p in res["equal"].items():
        panels.append((f"{LABELS[r]}\n{p['spp']} spp, {p['cpu_s']:.1f} CPU s\nMSE {p['mse']:.2e}",
                       peers.read_rgb(os.path.join(peers.ROOT, p["exr"]))))
    h, w = ref.shape[:2]
    fig, axes = plt.subplots(1, len(panels), figsize=(1.45 * len(panels), 2.0), dpi=100)
    for ax, (label, img) in zip(axes, panels):
        ax.imshow(tonemap(img[h // 4: h - h // 4, w // 4: w - w // 4] * scale), interpolation="nearest")
        ax.set_title(label, fontsize=7)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def chart(res, path):
    """The scene's log-log chart of MSE against CPU seconds, one curve per renderer's spp ladder."""
    curves = [(LABELS[r], COLOURS[r], [dict(p, seconds=p["cpu_s"]) for p in pts])
              for r, pts in res["ladder"].items()]
    peers.mse_chart(curves, path, f"{res['scene']}, {res['res']}², {res['threads']} threads",
                    "CPU seconds (Nimbus: whole process; Cycles: render call)", dpi=80, small=True)


def variances(res):
    """each renderer's variance (per pixel and channel, averaged) at T and at the ladder's top, from differences
    of its renderer's own renders alone, so free of any bias of its translation. Renders with the same seed are
    correlated (guided and unguided paths share their first random numbers), so only pairs of seeds 1 and 2 are
    used: for independent X, Y of one expectation, E(X - Y)^2 = v_X + v_Y. The unguided variance is taken as
    sigma^2 / spp (independent samples), sigma^2 from its two renders; each guided render's from its difference
    with the unguided render of the other seed."""
    out = {}
    for kind in ("nimbus", "cycles"):
        on, off = f"{kind}-on", f"{kind}-off"
        if on not in res["equal"] or off not in res["equal"]:
            continue
        renders = {(r, w): p for r in (on, off) for w, p in (("top", res["ladder"][r][-1]), ("equal", res["equal"][r]))}
        img = {k: peers.read_rgb(os.path.join(peers.ROOT, p["exr"])) for k, p in renders.items()}
        n_top, n_eq = renders[off, "top"]["spp"], renders[off, "equal"]["spp"]
        sigma2 = float(np.mean((img[off, "top"] - img[off, "equal"]) ** 2)) / (1 / n_top + 1 / n_eq)
        out[off, "top"], out[off, "equal"] = sigma2 / n_top, sigma2 / n_eq
        out[on, "top"] = float(np.mean((img[on, "top"] - img[off, "equal"]) ** 2)) - out[off, "equal"]
        out[on, "equal"] = float(np.mean((img[on, "equal"] - img[off, "top"]) ** 2)) - out[off, "top"]
    return out


def table(res):
    base = res["equal"]["nimbus-off"]
    top = {r: pts[-1] for r, pts in res["ladder"].items()}
    base_eff = 1 / (top["nimbus-off"]["mse"] * top["nimbus-off"]["cpu_s"])
    spp_top = top["nimbus-off"]["spp"]
    about = peers.SCENES[res["scene"]][1].removeprefix("path guiding (issue 34): ")
    lines = [f"**{res['scene']}** ({about}): reference Mitsuba {res['ref_spp']} spp, its "
             f"variance {res['ref_var']:.2e} subtracted; equal time T = {res['equal_seconds']:.2f} CPU s; 1-minute "
             f"load average {res['load_start'][0]:.1f} at the start, {res['load_end'][0]:.1f} at the end.", "",
             f"| render | spp at T | CPU s (wall s) | MSE at T | MSE / unguided Nimbus's | variance at T | "
             f"{spp_top} spp: CPU s (wall s) | {spp_top} spp: MSE | {spp_top} spp: variance | efficiency / unguided "
             f"Nimbus's at {spp_top} spp |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    var = variances(res)
    for r, p in res["equal"].items():
        t = top[r]
        eff = 1 / (t["mse"] * t["cpu_s"]) / base_eff
        v_eq, v_top = (f"{var[r, w]:.3e}" if (r, w) in var else "–" for w in ("equal", "top"))
        lines.append(f"| {LABELS[r]} | {p['spp']} | {p['cpu_s']:.2f} ({p['wall_s']:.2f}) | {p['mse']:.3e} | "
                     f"{p['mse'] / base['mse']:.2f}× | {v_eq} | {t['cpu_s']:.2f} ({t['wall_s']:.2f}) | "
                     f"{t['mse']:.3e} | {v_top} | **{eff:.2f}×** |")
    means = [f"{LABELS[r]} {np.mean(pts[-1]['mean']):.4f}" for r, pts in res["ladder"].items()]
    lines += ["", f"Image means at {spp_top} spp (mean of RGB): reference {np.mean(res['ref_mean']):.4f}; "
              + "; ".join(means) + "."]
    for r in ("nimbus-off", "nimbus-on"):
        if r not in top:
            continue
        t = top[r]
        z = [(m - q) / np.hypot(s, e) for m, q, s, e in zip(t["mean"], res["ref_mean"], t["mean_se"],
                                                            res["ref_mean_se"])]
        lines.append(f"{LABELS[r]} against the reference, per channel, in standard errors of the difference "
                     f"of the means: {', '.join(f'{x:+.1f}' for x in z)}.")
    lines += ["", f"![{res['scene']}: MSE against time](performance/guiding_{res['scene']}.png)",
              f"![{res['scene']}: equal time](performance/guiding_{res['scene']}_equal.png)", ""]
    return lines


def report(a):
    results = [json.load(open(os.path.join(a.out, f"results_{n}.json"))) for n in a.scenes
               if os.path.exists(os.path.join(a.out, f"results_{n}.json"))]
    lines = [BEGIN, ""]
    for res in results:
        chart(res, os.path.join(DOCS, "performance", f"guiding_{res['scene']}.png"))
        pictures(res, os.path.join(DOCS, "performance", f"guiding_{res['scene']}_equal.png"))
        lines += table(res)
    lines.append(END)
    path = os.path.join(DOCS, "performance.md")
    page = open(path).read()
    if BEGIN not in page or END not in page:
        sys.exit(f"{path} has no {BEGIN} ... {END} block to fill")
    head, rest = page.split(BEGIN, 1)
    page = head + "\n".join(lines) + rest.split(END, 1)[1]
    with open(path, "w") as f:
        f.write(page)
    print("wrote", os.path.relpath(path, peers.ROOT))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("command", choices=["render", "report"])
    ap.add_argument("--scenes", default="backlit,doorgap,baffle")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--ladder", default="8,16,32,64,128")
    ap.add_argument("--equal-spp", type=int, default=64,
                    help="unguided Nimbus's spp that sets the equal time (0: the ladder alone)")
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--renderers", default="nimbus-off,nimbus-on,cycles-on,cycles-off")
    ap.add_argument("--out", default=OUT, help="where renders and results go (default benches/peers/out/guiding)")
    ap.add_argument("--nimbus", default=peers.NIMBUS, help="the nimbus binary (default: target/release/nimbus)")
    a = ap.parse_args()
    a.scenes = a.scenes.split(",")
    a.ladder = [int(x) for x in a.ladder.split(",")]
    a.renderers = a.renderers.split(",")
    if a.command == "report":
        return report(a)
    os.makedirs(a.out, exist_ok=True)
    for name in a.scenes:
        res = bench_scene(name, a)
        with open(os.path.join(a.out, f"results_{name}.json"), "w") as f:
            json.dump(res, f, indent=1)
        print(f"[{name}] saved", flush=True)


if __name__ == "__main__":
    main()
