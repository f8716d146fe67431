#!/usr/bin/env python3
"""Denoises the beauty of a `nimbus render --denoise` EXR with pyoidn (OIDN's own Python bindings) the way OIDN's
documentation recommends for noisy auxiliary images: an RT filter over the albedo alone and over the normal
alone, then the beauty (HDR) with the cleaned auxiliaries and cleanAux on. Prints the largest absolute difference
from the file's `denoised` layer, and that of OIDN's noisy-auxiliary mode, which Nimbus must not match.

Usage: pyoidn_check.py FILE.exr   (with pyoidn, numpy and OpenEXR importable)"""

import sys

import Imath
import numpy as np
import OpenEXR
import pyoidn


def read(f, names, low, high):
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    planes = [np.frombuffer(f.channel(n, Imath.PixelType(Imath.PixelType.FLOAT)), np.float32).reshape(h, w)
              for n in names]
    image = np.stack(planes, axis=-1)
    return np.ascontiguousarray(np.clip(np.nan_to_num(image, nan=0.0, posinf=0.0, neginf=0.0), low, high))


def main():
    f = OpenEXR.InputFile(sys.argv[1])
    color = read(f, ["R", "G", "B"], 0.0, np.finfo(np.float32).max)
    albedo = read(f, ["albedo.R", "albedo.G", "albedo.B"], 0.0, 1.0)
    normal = read(f, ["normal.X", "normal.Y", "normal.Z"], -1.0, 1.0)
    ours = read(f, ["denoised.R", "denoised.G", "denoised.B"], -np.inf, np.inf)
    device = pyoidn.Device()
    device.commit()

    def run(images, flags):
        out = np.zeros_like(color)
        f = pyoidn.Filter(device, "RT")
        for name, image in images.items():
            f.set_image(name, image, pyoidn.OIDN_FORMAT_FLOAT3)
        f.set_image(pyoidn.OIDN_IMAGE_OUTPUT, out, pyoidn.OIDN_FORMAT_FLOAT3)
        for name, value in flags.items():
            f.set_bool(name, value)
        f.commit()
        f.execute()
        f.release()
        return out

    clean = run({"color": color, "albedo": run({"albedo": albedo}, {}), "normal": run({"normal": normal}, {})},
                {"hdr": True, "cleanAux": True})
    noisy = run({"color": color, "albedo": albedo, "normal": normal}, {"hdr": True})
    print(f"prefiltered {float(np.abs(ours - clean).max())} noisy {float(np.abs(ours - noisy).max())}")


if __name__ == "__main__":
    main()
