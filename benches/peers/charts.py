#!/usr/bin/env python3
"""Error-against-time charts of Nimbus's methods with Mitsuba 3 and Cycles 5.0 on the same axes (issue 15).

    python3 benches/peers/charts.py convergence   # docs/convergence.{png,svg,md,csv}: every method, the cloud
    python3 benches/peers/charts.py majorants     # docs/majorants.{png,svg,md,csv}: majorant structures, the plume
    python3 benches/peers/charts.py CHART [--budget S] [--mitsuba-ladder LIST] [--cycles-ladder LIST] [--docs-only]

Run by hand from the repository root after `cargo build --release` (never in CI; under `nice -n 10` on a shared
machine), with what `run.py` needs (Mitsuba 3, and bpy==5.0.1 for Cycles). The harness's Mitsuba reference of the
scene must be in `benches/peers/out/reference/` (`python3 benches/peers/run.py --references-only --scenes NAME`
makes it, in hours).

For the chart's scene, at the harness's 256 px and 2 threads, every render interleaved round-robin (a Nimbus method,
a Mitsuba spp, a Cycles spp, the next ...), so that the shared machine's changing load falls on every curve:
1. `nimbus converge SCENE --reference REF.exr --methods METHOD --budget S/N --threads 2` for each of the N methods,
   each rendered progressively at doubling spp; its seconds are render time (scene load and build excluded, error
   measurement excluded). The reference's `_se.exr` beside it is found, and its variance subtracted from every
   squared error.
2. Mitsuba and Cycles at each spp of their ladder, one independent render per spp, through `run.py`'s `measure`
   (box filter, one seed); their seconds are `render_s`, the render call alone (Python and Blender start-up, scene
   translation and load excluded; Mitsuba's JIT compilation and Cycles' scene sync and BVH build included).
   RMSE = sqrt(max(0, mean((x - r)^2) - mean(se_r^2))) over all pixels and channels: what converge computes.
3. One log-log chart of RMSE against seconds (png and svg), every curve and a 1/sqrt(t) guide, a CSV of every
   point, and a markdown page. Its table interpolates each curve's RMSE (log-log, as converge's summary does) at
   the common time T, the shortest final time over all curves, and gives the efficiency 1/(MSE T) relative to
   Nimbus `default` at that same T, i.e. (RMSE_default(T) / RMSE(T))^2; and the seconds each curve takes to fall
   to the chart's `equal_error` RMSE, relative to default's (the efficiency at equal error, useful where a floor
   left by the reference flattens the curves before T).

Results are kept in `benches/peers/out/charts_CHART.json`; `--docs-only` redraws the chart and page from them.
"""
import argparse
import csv
import datetime
import json
import math
import os
import subprocess
import sys
import textwrap

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import run as harness  # noqa: E402  (the peer harness: scenes, references, renders, MSE)

ALL_METHODS = ["default", "global-majorant", "grid16-majorant", "adaptive-majorant", "ratio-shadow",
               "residual-ratio-shadow", "no-media-mis"]

# What each chart shows; command-line flags override the budget and the ladders.
CHARTS = {
    "convergence": {
        "scene": "cloud", "methods": ALL_METHODS, "budget": 420, "mitsuba": [4, 16, 64, 256, 1024],
        "cycles": [4, 16, 64, 256, 1024], "equal_error": 1.5e-2,
        "title": "Every Nimbus method, Mitsuba 3 and Cycles 5.0 on the cloud",
    },
    "majorants": {
        "scene": "plume", "methods": ALL_METHODS[:4], "budget": 300, "mitsuba": [4, 16, 64, 256],
        "cycles": [4, 16, 64, 256], "equal_error": 4e-2,
        "title": "Majorant structures on the dense plume: Nimbus, Mitsuba 3 (one global majorant), "
                 "Cycles 5.0 (majorant octree)",
    },
}

PEER_NAMES = {"mitsuba": "Mitsuba 3", "cycles": "Cycles 5.0"}
PEER_SEED = 201


def run_converge(scene, ref_path, method, budget, threads, out_dir):
    """`nimbus converge` of one method with the harness's reference; its points, from its convergence.csv"""
    cmd = [harness.NIMBUS, "converge", scene, "--reference", ref_path, "--methods", method, "--budget", f"{budget:g}",
           "--threads", str(threads), "-o", out_dir]
    print(" ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)
    with open(os.path.join(out_dir, "convergence.csv")) as f:
        return [{"spp": int(row["spp"]), "seconds": float(row["seconds"]), "rmse": float(row["rmse"])}
                for row in csv.DictReader(f)]


def run_peer(name, peer, scene, spp, a, ref, ref_var):
    """One render of `peer` at `spp`, measured by the harness"""
    r = harness.measure(name, peer, scene, spp, a, PEER_SEED, ref, ref_var)
    return {"spp": spp, "seconds": r["seconds"], "wall_s": r["wall_s"], "rmse": math.sqrt(max(r["mse"], 0.0)),
            "finite": r["finite"]}


def interleaved(queues):
    """Round-robin over the queues, so that a change of the shared machine's load falls on every curve"""
    queues = [list(q) for q in queues]
    while any(queues):
        for q in queues:
            if q:
                yield q.pop(0)


def rmse_at(points, t):
    """converge's `rmse_at`: log-log interpolation between the points around t, 1/sqrt(t) from the nearest outside"""
    pts = sorted(points, key=lambda p: p["seconds"])
    if t <= pts[0]["seconds"]:
        return pts[0]["rmse"] * math.sqrt(pts[0]["seconds"] / t), "extrapolated"
    if t >= pts[-1]["seconds"]:
        return pts[-1]["rmse"] * math.sqrt(pts[-1]["seconds"] / t), "" if t == pts[-1]["seconds"] else "extrapolated"
    b = next(i for i, p in enumerate(pts) if p["seconds"] >= t)
    pa, pb = pts[b - 1], pts[b]
    ln = lambda x: math.log(max(x, 1e-300))  # noqa: E731
    f = (ln(t) - ln(pa["seconds"])) / max(ln(pb["seconds"]) - ln(pa["seconds"]), 1e-300)
    return math.exp(ln(pa["rmse"]) + f * (ln(pb["rmse"]) - ln(pa["rmse"]))), ""


def seconds_to(points, error):
    """Seconds at which the curve first falls to `error` (log-log interpolation between the points around the
    crossing; 1/sqrt(t) back from the first point when that is already below), or None when it never does"""
    pts = sorted(points, key=lambda p: p["seconds"])
    if pts[0]["rmse"] <= error:
        return pts[0]["seconds"] * (pts[0]["rmse"] / error) ** 2, "extrapolated"
    for pa, pb in zip(pts, pts[1:]):
        if pb["rmse"] <= error < pa["rmse"]:
            f = math.log(pa["rmse"] / error) / math.log(pa["rmse"] / max(pb["rmse"], 1e-300))
            return math.exp(math.log(pa["seconds"]) + f * math.log(pb["seconds"] / pa["seconds"])), ""
    return None, "not reached"


def summary(result, error):
    """(T, rows): each curve's final point, its RMSE at the common time T and its efficiency relative to default
    there, and the seconds it takes to fall to RMSE `error` (relative to default's: the efficiency at equal error)"""
    curves = result["curves"]
    common = min(pts[-1]["seconds"] for pts in curves.values())
    base, _ = rmse_at(curves["default"], common)
    base_t, _ = seconds_to(curves["default"], error)
    rows = []
    for label, pts in curves.items():
        at, note = rmse_at(pts, common)
        t_err, t_note = seconds_to(pts, error)
        rows.append({"label": label, "spp": pts[-1]["spp"], "seconds": pts[-1]["seconds"], "rmse": pts[-1]["rmse"],
                     "rmse_at": at, "efficiency": (base / at) ** 2 if at > 0 else math.inf, "note": note,
                     "t_err": t_err, "t_note": t_note,
                     "eff_err": base_t / t_err if (t_err and base_t) else None})
    return common, rows


def draw(result, stem):
    """The log-log chart, as STEM.png and STEM.svg"""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FormatStrFormatter
    plt.rcParams["svg.hashsalt"] = "nimbus"  # stable ids, so a redraw of the same data is the same file
    fig, ax = plt.subplots(figsize=(7.5, 5), dpi=110)
    nimbus_colours = plt.get_cmap("tab10").colors
    for i, (label, pts) in enumerate(result["curves"].items()):
        xs, ys = [p["seconds"] for p in pts], [max(p["rmse"], 1e-12) for p in pts]
        if label in PEER_NAMES:
            colour = {"mitsuba": "black", "cycles": "dimgray"}[label]
            ax.loglog(xs, ys, "s--" if label == "mitsuba" else "D--", color=colour, lw=2, ms=5,
                      label=f"{PEER_NAMES[label]} (render call)")
            for p, y in zip(pts, ys):
                ax.annotate(str(p["spp"]), (p["seconds"], y), fontsize=7, xytext=(4, 2), textcoords="offset points",
                            color=colour)
        else:
            ax.loglog(xs, ys, "o-", color=nimbus_colours[i % 10], lw=2.2 if label == "default" else 1.2, ms=3,
                      label=f"Nimbus {label}")
    base = result["curves"]["default"][0]  # the first point: the furthest above any floor the reference leaves
    ts = [min(p["seconds"] for pts in result["curves"].values() for p in pts),
          max(p["seconds"] for pts in result["curves"].values() for p in pts)]
    ax.loglog(ts, [base["rmse"] * math.sqrt(base["seconds"] / t) for t in ts], ":", color="gray", lw=1,
              label="1/√t (through Nimbus default's first point)")
    ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.set_xlabel("seconds (Nimbus: render time; Mitsuba, Cycles: render call, start-up excluded)")
    ax.set_ylabel("RMSE against the Mitsuba reference (its variance subtracted)")
    ax.set_title(textwrap.fill(result["title"], 95) + f"\n{result['scene']}, {result['width']}×{result['height']}, "
                 f"{result['threads']} threads, {result['date']}", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    for ext in ("png", "svg"):
        fig.savefig(f"{stem}.{ext}", **({"metadata": {"Date": None}} if ext == "svg" else {}))
    plt.close(fig)


def write_csv(result, path):
    """Every point of every curve: curve, spp, seconds, rmse"""
    with open(path, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["curve", "spp", "seconds", "rmse"])
        for label, pts in result["curves"].items():
            for p in pts:
                w.writerow([label if label in PEER_NAMES else f"nimbus-{label}", p["spp"], f"{p['seconds']:.4f}",
                            f"{p['rmse']:.6e}"])


def load_note(result):
    """the 1-minute load average at the start and the end of the run, when recorded"""
    if "load_average" not in result:
        return ""
    return "; 1-minute load average {:.1f} at the start, {:.1f} at the end".format(*result["load_average"])


def stalls(points):
    """converge's "possible bias" test: the RMSE of the last two points fell by less than 10 % while spp doubled"""
    return len(points) >= 2 and points[-1]["spp"] >= 2 * points[-2]["spp"] and \
        points[-1]["rmse"] > 0.9 * points[-2]["rmse"]


def reference_noise_share(result):
    """Share of the reference's variance held by its 0.1 % of pixels with the largest standard errors"""
    se = harness.read_rgb(os.path.splitext(result["reference"])[0] + "_se.exr")
    v = (se * se).sum(axis=2).ravel()
    v.sort()
    return float(v[-max(1, len(v) // 1000):].sum() / max(v.sum(), 1e-300))


def write_markdown(result, name, path, error):
    common, rows = summary(result, error)
    scene_file = harness.SCENES[result["scene"]][0]
    ladders = ", ".join(f"{PEER_NAMES[p]} {','.join(str(x['spp']) for x in result['curves'][p])} spp"
                        for p in PEER_NAMES if p in result["curves"])
    lines = [f"# {result['title']}", "",
             f"Written by `python3 benches/peers/charts.py {name}` on {result['date']} (2-core machine shared with "
             f"other work, renders at nice 10{load_note(result)}). Scene `{result['scene']}` (`{scene_file}`: "
             f"{harness.SCENES[result['scene']][1]}), {result['width']}×{result['height']} px, {result['threads']} "
             f"threads, box filter. Reference: the peer harness's Mitsuba 3 render of {result['ref_spp']} spp "
             f"(`{os.path.relpath(result['reference'], harness.ROOT)}`, 16 independent passes); its own variance "
             f"(RMS standard error {math.sqrt(result['ref_var']):.4e}; {100 * reference_noise_share(result):.1f} % "
             "of its variance in the 0.1 % of pixels with the largest standard errors) is subtracted from every "
             "squared error. Where that noise is heavy-tailed the subtraction is itself noisy, and what it leaves "
             "floors every curve alike.", "",
             f"![RMSE against seconds]({name}.png)", "",
             "What the seconds are:", "",
             (f"- **Nimbus**: `nimbus converge --methods METHOD --budget {result['budget'] / len(result['methods']):g}`"
              f" per method ({result['budget']:g} s over {len(result['methods'])} methods)" if result.get("interleaved")
              else f"- **Nimbus**: one `nimbus converge --budget {result['budget']:g}` of all {len(result['methods'])}"
              " methods (the budget shared equally)") + ", one progressive render "
             "per method at doubling spp, stopped before the pass that would overrun the budget; seconds are render "
             "time at each checkpoint (scene load and build, and the error measurement, excluded).",
             f"- **Mitsuba 3** (`llvm_ad_rgb`, `volpath`) and **Cycles 5.0** (CPU): one independent render per spp "
             f"({ladders}, seed {PEER_SEED}), through `run.py`'s renderers; seconds are `render_s`, the render call "
             "alone (Python and Blender start-up, glTF translation and scene load excluded; Mitsuba's JIT "
             "compilation and Cycles' scene sync and BVH build included, which is why their first points are slow).",
             "", "Order: " + ("every render interleaved round-robin (a Nimbus method, a Mitsuba spp, a Cycles spp, "
                              "the next ...), so that the machine's changing load falls on every curve alike."
                              if result.get("interleaved") else "all Nimbus methods first, then Mitsuba's ladder, "
                              "then Cycles'; a change of the machine's load in between moves the curves apart."),
             "", f"Equal time: each curve's RMSE interpolated (log-log) at T = {common:.2f} s, the shortest final time "
             "over all curves (a curve whose points do not reach T either way is extrapolated as 1/√t from its "
             "nearest point, marked). Efficiency is 1/(MSE·T) relative to Nimbus `default` at that T, "
             "(RMSE_default(T) / RMSE(T))²; above 1 beats Nimbus default. Equal error: the seconds each curve "
             f"takes to first fall to RMSE {error:.3g} (log-log interpolation), relative to Nimbus `default`'s: the "
             "efficiency at that error, (t_default / t). \"not falling\": the last doubling of spp cut the RMSE by "
             "less than 10 % (converge's \"possible bias\" test; a floor left by the reference also does it).", "",
             f"| curve | final spp | final s | final RMSE | RMSE at {common:.2f} s | efficiency vs Nimbus default "
             f"at equal time | s to RMSE {error:.3g} | efficiency vs Nimbus default at equal error | note |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---|"]
    for r in rows:
        label = PEER_NAMES.get(r["label"], f"Nimbus `{r['label']}`")
        note = " (extrapolated)" if r["note"] else ""
        if r["t_err"] is None:
            t_err = f"> {r['seconds']:.2f} (not reached)"
            base_t, _ = seconds_to(result["curves"]["default"], error)
            eff_err = f"< {base_t / r['seconds']:.3g}×" if base_t else "n/a"
        else:
            t_err = f"{r['t_err']:.2f}" + (" (extrapolated)" if r["t_note"] else "")
            eff_err = f"{r['eff_err']:.3g}×" if r["eff_err"] else "n/a"
        lines.append(f"| {label} | {r['spp']} | {r['seconds']:.2f} | {r['rmse']:.4e} | {r['rmse_at']:.4e}{note} | "
                     f"{r['efficiency']:.3g}× | {t_err} | {eff_err} | "
                     f"{'not falling' if stalls(result['curves'][r['label']]) else ''} |")
    lines += ["", f"Every point is in [{name}.csv]({name}.csv). Regenerate (about "
              f"{result['wall_minutes']:.0f} min here): `cargo build --release && python3 benches/peers/charts.py "
              f"{name}`; `--docs-only` redraws from the saved results.", ""]
    with open(path, "w") as f:
        f.write("\n".join(lines))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("chart", choices=sorted(CHARTS))
    ap.add_argument("--budget", type=float, help="converge's render seconds over all Nimbus methods")
    ap.add_argument("--mitsuba-ladder", help="comma-separated spp (empty: no Mitsuba curve)")
    ap.add_argument("--cycles-ladder", help="comma-separated spp (empty: no Cycles curve)")
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ref-spp", type=int, default=4096, help="as run.py's (the plume's is capped at 1024 there)")
    ap.add_argument("--equal-error", type=float, help="the RMSE of the equal-error column (default: the chart's)")
    ap.add_argument("--docs-only", action="store_true", help="redraw docs/ from the saved results, render nothing")
    a = ap.parse_args()
    spec = CHARTS[a.chart]
    saved = os.path.join(harness.OUT, f"charts_{a.chart}.json")
    if a.docs_only:
        result = json.load(open(saved))
    else:
        start = datetime.datetime.now(datetime.timezone.utc)
        load_start = os.getloadavg()[0]
        name = spec["scene"]
        scene = os.path.join(harness.ROOT, harness.SCENES[name][0])
        ref_path, ref_spp = harness.reference_path(name, scene, a.res, a.ref_spp)
        if not os.path.exists(ref_path):
            sys.exit(f"{ref_path} is missing: make it with run.py --references-only --scenes {name}")
        ref, ref_var = harness.reference(name, scene, a.res, a.ref_spp, a.threads)
        budget = a.budget if a.budget is not None else spec["budget"]
        queues = [[("nimbus", m) for m in spec["methods"]]]
        for peer in PEER_NAMES:
            ladder = getattr(a, f"{peer}_ladder")
            ladder = spec[peer] if ladder is None else [int(x) for x in ladder.split(",") if x]
            queues.append([(peer, spp) for spp in ladder])
        curves = {label: [] for label in spec["methods"] + [q[0][0] for q in queues[1:] if q]}
        for who, what in interleaved(queues):
            if who == "nimbus":
                curves[what] = run_converge(scene, ref_path, what, budget / len(spec["methods"]), a.threads,
                                            os.path.join(harness.OUT, f"charts_{a.chart}_converge", what))
            else:
                curves[who].append(run_peer(name, who, scene, what, a, ref, ref_var))
        result = {"chart": a.chart, "title": spec["title"], "scene": name, "reference": ref_path,
                  "ref_spp": ref_spp, "ref_var": ref_var, "width": ref.shape[1], "height": ref.shape[0],
                  "threads": a.threads, "budget": budget, "interleaved": True,
                  "methods": spec["methods"], "curves": curves,
                  "date": start.strftime("%Y-%m-%d"), "start": start.strftime("%H:%M UTC"),
                  "load_average": [load_start, os.getloadavg()[0]],
                  "wall_minutes": (datetime.datetime.now(datetime.timezone.utc) - start).total_seconds() / 60}
        with open(saved, "w") as f:
            json.dump(result, f, indent=1)
    stem = os.path.join(harness.ROOT, "docs", a.chart)
    draw(result, stem)
    write_csv(result, stem + ".csv")
    error = a.equal_error if a.equal_error is not None else spec["equal_error"]
    write_markdown(result, a.chart, stem + ".md", error)
    common, rows = summary(result, error)
    for r in rows:
        t_err = "not reached" if r["t_err"] is None else f"{r['t_err']:.2f} s {r['t_note']}"
        print(f"{r['label']:22s} {r['spp']:5d} spp {r['seconds']:7.2f} s RMSE {r['rmse']:.4e}  at {common:.2f} s: "
              f"{r['rmse_at']:.4e} {r['note']:12s} efficiency vs default {r['efficiency']:.3g}x; "
              f"to RMSE {error:.3g}: {t_err}, {r['eff_err'] or 0:.3g}x", flush=True)


if __name__ == "__main__":
    main()
