#!/usr/bin/env python3
"""Measures Open Image Denoise on Nimbus renders: the figures and pictures of docs/denoising.md.

For every scene of ../shared/validation (128x128, --max-depth from its extras.max_bounces, as tests/suite/validation.rs
renders them) and for the bundled demo (128x72, against tests/denoise/reference_demo_128.exr), it renders with
`nimbus render --denoise` at 4, 16 and 64 spp and raw at 256 and 1024 spp, and measures the relative MSE
(mean over pixels and channels of (x - ref)^2 / (ref^2 + 1e-2)) of the raw beauty and of the `denoised` layer
against the Mitsuba 3 reference. The spp a raw render needs to match the denoised 16-spp error is read off the raw
curve (log-log interpolation between the measured spp; beyond 1024, extrapolated as 1/spp).

With --pyoidn SITE_PACKAGES (where PyPI's pyoidn is installed), each denoised frame is also denoised by pyoidn's
direct bindings twice: with noisy auxiliaries (cleanAux off, what Nimbus did before its prefiltering was added) and
with OIDN's clean-aux prefiltering (an RT filter over the albedo alone and over the normal alone, then cleanAux
on), which is what Nimbus does now (tests/denoise.rs checks the two agree bit for bit).

With --old-nimbus (a build from before media wrote first-collision albedo and normal auxiliaries), the scenes with
media are also rendered by it (same seed, so the same beauty: checked) and denoised by `nimbus denoise`, which
measures what the media auxiliaries change.

    python3 scripts/denoise_measure.py --nimbus target/debug/nimbus [--old-nimbus OLD] [--out DIR]
        [--shared ../shared] [--docs docs/denoising]

Needs numpy, OpenEXR (Imath) and Pillow. Writes DIR/results.json, prints the markdown tables, and with --docs
writes the demo's pictures (raw, denoised, reference, difference) as PNG.
"""
import argparse, json, math, os, subprocess, sys

import numpy as np
import OpenEXR, Imath

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MEDIA_SCENES = {"demo", "scattering-box", "point-in-medium", "smoke-sun"}


def read_exr(path, prefix=""):
    f = OpenEXR.InputFile(path)
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    names = [f"{prefix}{c}" for c in "RGB"] if prefix != "normal." else [f"normal.{c}" for c in "XYZ"]
    out = np.stack([np.frombuffer(f.channel(n, Imath.PixelType(Imath.PixelType.FLOAT)), np.float32).reshape(h, w)
                    for n in names], axis=-1)
    f.close()
    return out.astype(np.float64)


def read_exr_has(path, channel):
    f = OpenEXR.InputFile(path)
    has = channel in f.header()["channels"]
    f.close()
    return has


def rel_mse(x, ref):
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 1e-2)))


REUSE = False


def render(nimbus, scene, out, spp, width, height, depth, denoise, seed):
    if REUSE and os.path.exists(out):
        return
    cmd = [nimbus, "render", "-o", out, "--spp", str(spp), "--width", str(width), "--height", str(height),
           "--seed", str(seed), "--exposure", "0"]
    if scene:
        cmd.insert(2, scene)
    if depth is not None:
        cmd += ["--max-depth", str(depth)]
    if denoise:
        cmd.append("--denoise")
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def spp_to_match(raw, target):
    """Smallest spp whose raw relMSE reaches `target`, interpolated log-log over the measured raw curve."""
    pts = sorted(raw.items())
    for (s0, e0), (s1, e1) in zip(pts, pts[1:]):
        if e1 <= target <= e0 and e0 > e1:
            t = (math.log(e0) - math.log(target)) / (math.log(e0) - math.log(e1))
            return math.exp(math.log(s0) + t * (math.log(s1) - math.log(s0))), False
    if target <= pts[-1][1]:
        return pts[-1][0] * pts[-1][1] / target, True  # beyond the last point: error ~ 1/spp
    return pts[0][0], False


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--nimbus", required=True)
    ap.add_argument("--old-nimbus")
    ap.add_argument("--out", default="/tmp/nimbus-denoise-measure")
    ap.add_argument("--shared", default=os.path.join(os.path.dirname(ROOT), "shared"))
    ap.add_argument("--docs")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--only")
    ap.add_argument("--pyoidn")
    ap.add_argument("--reuse", action="store_true", help="keep renders already in --out (same settings)")
    args = ap.parse_args()
    global REUSE
    REUSE = args.reuse
    os.makedirs(args.out, exist_ok=True)
    scenes = []
    vdir = os.path.join(args.shared, "validation")
    for name in sorted(os.listdir(vdir)):
        d = os.path.join(vdir, name)
        refs = [f for f in os.listdir(d) if f.startswith("reference_") and f.endswith("spp_128.exr")] \
            if os.path.isdir(d) else []
        if not refs:
            continue
        gltf = json.load(open(os.path.join(d, "scene.gltf")))
        depth = gltf["scenes"][gltf.get("scene", 0)].get("extras", {}).get("max_bounces")
        scenes.append((name, os.path.join(d, "scene.gltf"), os.path.join(d, refs[0]), 128, 128, depth))
    scenes.append(("demo", None, os.path.join(ROOT, "tests", "denoise", "reference_demo_128.exr"), 128, 72, None))
    if args.only:
        scenes = [s for s in scenes if s[0] in args.only.split(",")]
    results = {}
    for name, scene, ref_path, w, h, depth in scenes:
        ref = read_exr(ref_path)
        se_path = ref_path.replace(".exr", "_se.exr")
        floor = rel_mse(ref + read_exr(se_path), ref) if os.path.exists(se_path) else None
        r = {"raw": {}, "denoised": {}, "old_aux_denoised": {}, "reference_noise_floor": floor,
             "pyoidn_noisy_aux": {}, "pyoidn_clean_aux": {}}
        for spp in (4, 16, 64, 256, 1024):
            out = os.path.join(args.out, f"{name}_{spp}.exr")
            den = spp <= 64
            render(args.nimbus, scene, out, spp, w, h, depth, den, args.seed)
            r["raw"][spp] = rel_mse(read_exr(out), ref)
            if den:
                r["denoised"][spp] = rel_mse(read_exr(out, "denoised."), ref)
                if args.pyoidn:
                    noisy, clean = pyoidn_modes(args.pyoidn, out)
                    r["pyoidn_noisy_aux"][spp] = rel_mse(noisy, ref)
                    r["pyoidn_clean_aux"][spp] = rel_mse(clean, ref)
                if args.old_nimbus and name in MEDIA_SCENES:
                    old = os.path.join(args.out, f"{name}_{spp}_old.exr")
                    render(args.old_nimbus, scene, old, spp, w, h, depth, False, args.seed)
                    same = np.array_equal(read_exr(old), read_exr(out))
                    if not REUSE or read_exr_has(old, "denoised.R") is False:
                        subprocess.run([args.nimbus, "denoise", old, "-o", old], check=True,
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                    r["old_aux_denoised"][spp] = rel_mse(read_exr(old, "denoised."), ref)
                    r["old_same_beauty"] = same
            print(name, spp, {k: v.get(spp) for k, v in r.items() if isinstance(v, dict)}, file=sys.stderr,
                  flush=True)
        r["spp_to_match_denoised_16"], r["extrapolated"] = spp_to_match(r["raw"], r["denoised"][16])
        results[name] = r
        if args.docs and name == "demo":
            pictures(args, ref, os.path.join(args.out, "demo_16.exr"))
    json.dump(results, open(os.path.join(args.out, "results.json"), "w"), indent=1)
    print("| scene | raw 4 | denoised 4 | raw 16 | denoised 16 | raw 64 | denoised 64 | raw spp to match denoised 16 | reference noise floor |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, r in results.items():
        cells = []
        for spp in (4, 16, 64):
            cells += [f"{r['raw'][spp]:.2e}", f"{r['denoised'][spp]:.2e}"]
        m = f"{r['spp_to_match_denoised_16']:.0f}" + (" (extrapolated)" if r["extrapolated"] else "")
        fl = f"{r['reference_noise_floor']:.1e}" if r["reference_noise_floor"] is not None else "-"
        print(f"| {name} | " + " | ".join(cells) + f" | {m} | {fl} |")
    if args.pyoidn:
        print("\n| scene | Nimbus 16 (noisy aux) | pyoidn noisy aux 16 | pyoidn clean aux 16 | Nimbus 64 | pyoidn clean aux 64 |")
        print("|---|---|---|---|---|---|")
        for name, r in results.items():
            print(f"| {name} | {r['denoised'][16]:.2e} | {r['pyoidn_noisy_aux'][16]:.2e} | "
                  f"{r['pyoidn_clean_aux'][16]:.2e} | {r['denoised'][64]:.2e} | {r['pyoidn_clean_aux'][64]:.2e} |")
    if args.old_nimbus:
        print("\n| scene | denoised 4 | old aux | denoised 16 | old aux | denoised 64 | old aux | same beauty |")
        print("|---|---|---|---|---|---|---|---|")
        for name, r in results.items():
            if r["old_aux_denoised"]:
                cells = []
                for spp in (4, 16, 64):
                    cells += [f"{r['denoised'][spp]:.2e}", f"{r['old_aux_denoised'][spp]:.2e}"]
                print(f"| {name} | " + " | ".join(cells) + f" | {r.get('old_same_beauty')} |")


def pyoidn_modes(site, exr):
    """The beauty of `exr` denoised by pyoidn with noisy auxiliaries and with prefiltered (clean) ones."""
    sys.path.insert(0, site)
    import pyoidn
    color = read_exr(exr).astype(np.float32)
    albedo = np.clip(read_exr(exr, "albedo."), 0, 1).astype(np.float32)
    normal = np.clip(read_exr(exr, "normal."), -1, 1).astype(np.float32)
    device = pyoidn.Device()
    device.commit()

    def run(images, clean_aux=None, hdr=None):
        out = np.zeros_like(color)
        f = pyoidn.Filter(device, "RT")
        for name, img in images.items():
            f.set_image(name, np.ascontiguousarray(img), pyoidn.OIDN_FORMAT_FLOAT3)
        f.set_image(pyoidn.OIDN_IMAGE_OUTPUT, out, pyoidn.OIDN_FORMAT_FLOAT3)
        if hdr is not None:
            f.set_bool("hdr", hdr)
        if clean_aux is not None:
            f.set_bool("cleanAux", clean_aux)
        f.commit()
        f.execute()
        f.release()
        return out

    noisy = run({"color": color, "albedo": albedo, "normal": normal}, hdr=True)
    albedo_clean = run({"albedo": albedo})
    normal_clean = run({"normal": normal})
    clean = run({"color": color, "albedo": albedo_clean, "normal": normal_clean}, clean_aux=True, hdr=True)
    return noisy.astype(np.float64), clean.astype(np.float64)


def pictures(args, ref, exr16):
    from PIL import Image
    os.makedirs(args.docs, exist_ok=True)

    def srgb(x):
        x = np.clip(x, 0, 1)
        return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)

    def save(img, name):
        Image.fromarray((srgb(img) * 255 + 0.5).astype(np.uint8)).resize(
            (img.shape[1] * 2, img.shape[0] * 2), Image.NEAREST).save(os.path.join(args.docs, name), optimize=True)

    raw, den = read_exr(exr16), read_exr(exr16, "denoised.")
    save(raw, "demo_raw_16spp.png")
    save(den, "demo_denoised_16spp.png")
    save(ref, "demo_reference.png")
    # Differences from the reference, x4, red where brighter and blue where darker (luminance).
    for img, name in ((raw, "demo_raw_16spp_diff.png"), (den, "demo_denoised_16spp_diff.png")):
        d = (img - ref) @ np.array([0.2126, 0.7152, 0.0722]) * 4
        rgb = np.stack([np.clip(d, 0, 1), np.zeros_like(d), np.clip(-d, 0, 1)], axis=-1)
        save(rgb, name)


if __name__ == "__main__":
    main()
