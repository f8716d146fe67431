#!/usr/bin/env python3
"""Makes tests/denoise/reference_demo_128.exr: Mitsuba 3's render of the bundled demo (assets/cloud.gltf) at
128x72, the reference tests/denoise.rs measures raw and denoised 16-spp renders against.

Run once, by hand (Mitsuba 3 set up as ../shared/tools/README.md says):
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
    python3 tests/denoise/make_reference.py [--spp 8192] [--shared ../shared]
It renders through ../shared/tools/gltf2mitsuba.py (volpath, box filter, independent passes; on all cores: with
--threads 1 Mitsuba 3.9.1 twice hung in Bitmap.write after the last pass) and writes the beauty
as 16-bit half floats (small enough to commit) with the per-pixel standard error beside it (reference_demo_128_se.exr).
"""
import argparse, os, subprocess, sys

here = os.path.dirname(os.path.abspath(__file__))
root = os.path.dirname(os.path.dirname(here))
ap = argparse.ArgumentParser()
ap.add_argument("--spp", type=int, default=8192)
ap.add_argument("--shared", default=os.path.join(os.path.dirname(root), "shared"))
ap.add_argument("--threads", type=int, default=0)
args = ap.parse_args()
out = os.path.join(here, "reference_demo_128.exr")
subprocess.run([sys.executable, os.path.join(args.shared, "tools", "gltf2mitsuba.py"), "render",
                os.path.join(root, "assets", "cloud.gltf"), out, "--spp", str(args.spp), "--pass-spp", "128",
                "--res", "128", "--integrator", "volpath", "--seed", "1", "--write-se",
                "--threads", str(args.threads)], check=True)
# Half floats: the reference's own noise (its _se file) is far above half precision (about 1e-3 relative).
import numpy as np, OpenEXR, Imath  # noqa: E401 (Debian's python3-openexr, or PyPI's OpenEXR)
for path in (out, out.replace(".exr", "_se.exr")):
    f = OpenEXR.InputFile(path)
    header = f.header()
    dw = header["dataWindow"]
    size = (dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1)
    chans = {c: f.channel(c, Imath.PixelType(Imath.PixelType.FLOAT)) for c in "RGB"}
    f.close()
    half = OpenEXR.Header(*size)
    half["channels"] = {c: Imath.Channel(Imath.PixelType(Imath.PixelType.HALF)) for c in "RGB"}
    half["compression"] = Imath.Compression(Imath.Compression.ZIP_COMPRESSION)
    o = OpenEXR.OutputFile(path, half)
    o.writePixels({c: np.frombuffer(v, np.float32).astype(np.float16).tobytes() for c, v in chans.items()})
    o.close()
print("wrote", out)
