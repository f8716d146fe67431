#!/usr/bin/env python3
"""Decodes a Nimbus EXR's CryptoObject masks with PyPI's cryptomatte-api (a decoder written by others from the
specification) and compares each with its exact coverage.

    python3 tests/cryptomatte/decode_check.py FILE.exr EXACT_DIR NAME...

EXACT_DIR/NAME.f32 holds the exact per-pixel coverage of object NAME (little-endian float32, row-major from the
top row). Prints each mask's mean absolute error and exits non-zero when one is 0.02 or more, when a name is
missing from the manifest, or when the masks of a pixel sum to more than 1. Run by tests/suite/cryptomatte.rs.
"""
import os
import sys

import numpy as np
import cryptomatte_api

LIMIT = 0.02


def main():
    exr, exact_dir, names = sys.argv[1], sys.argv[2], sys.argv[3:]
    mattes = cryptomatte_api.Cryptomatte.load(exr)
    kinds = {m.metadata().name(): m for m in mattes}
    if "CryptoObject" not in kinds:
        sys.exit(f"no CryptoObject in {exr}: found {sorted(kinds)}")
    matte = kinds["CryptoObject"]
    manifest = matte.metadata().manifest()
    total = None
    failed = False
    for name in names:
        if not manifest.contains(name):
            print(f"{name}: not in the manifest")
            failed = True
            continue
        mask = np.asarray(matte.mask(name), dtype=np.float64).reshape(matte.height(), matte.width())
        exact = np.fromfile(os.path.join(exact_dir, name + ".f32"), "<f4").astype(np.float64)
        exact = exact.reshape(mask.shape)
        mae = float(np.abs(mask - exact).mean())
        print(f"{name}: cryptomatte-api mask, mean absolute error {mae:.4f} against the exact coverage")
        failed |= mae >= LIMIT
        total = mask if total is None else total + mask
    if total is not None and total.max() > 1.0 + 1e-5:
        print(f"masks of one pixel sum to {total.max():.6f} > 1")
        failed = True
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
