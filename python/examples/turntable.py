"""A turntable of the bundled cloud, notebook style: 8 frames of the cloud turning about its vertical axis,
rendered from Python to NumPy and laid out as one contact sheet (4 x 2 frames, in turning order).

    python python/examples/turntable.py [--spp 16] [--width 240] [-o turntable.png]

Each cell of a notebook would be one step below: make the frame's scene, render it, look at it
(``image`` shows itself in Jupyter through ``_repr_png_``), then stack the frames.
"""

import argparse
import json
import math
import pathlib
import tempfile

import numpy as np

import nimbus

ROOT = pathlib.Path(__file__).resolve().parents[2]
FRAMES = 8


def turned_scene(folder: pathlib.Path, degrees: float) -> nimbus.Scene:
    """The bundled scene with its cloud turned by `degrees` about the vertical axis (a glTF node rotation)."""
    gltf = json.loads((ROOT / "assets" / "cloud.gltf").read_text())
    for node in gltf["nodes"]:
        if node.get("name") == "cloud_volume":
            half = math.radians(degrees) / 2
            node["rotation"] = [0.0, math.sin(half), 0.0, math.cos(half)]
            node["extras"]["nimbus_volume"]["file"] = str(ROOT / "assets" / "cloud.vdb")
    path = folder / f"cloud_{degrees:03.0f}.gltf"
    path.write_text(json.dumps(gltf))
    return nimbus.load(path)


def contact_sheet(images, columns: int) -> np.ndarray:
    """The frames' beauty (RGB, linear) tiled row by row, with a 2-pixel black gutter."""
    h, w, _ = images[0].shape
    rows = math.ceil(len(images) / columns)
    sheet = np.zeros((rows * (h + 2) - 2, columns * (w + 2) - 2, 3), dtype=np.float32)
    for i, image in enumerate(images):
        r, c = divmod(i, columns)
        sheet[r * (h + 2):r * (h + 2) + h, c * (w + 2):c * (w + 2) + w] = image[:, :, :3]
    return sheet


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--width", type=int, default=240)
    parser.add_argument("-o", "--output", default="turntable.png")
    args = parser.parse_args()

    frames = []
    with tempfile.TemporaryDirectory(prefix="turntable-") as folder:
        for k in range(FRAMES):
            degrees = 360.0 * k / FRAMES
            scene = turned_scene(pathlib.Path(folder), degrees)
            image = nimbus.render(scene, spp=args.spp, width=args.width, seed=k,
                                  progress=lambda done, total: print(f"\rframe {k}: {done}/{total} spp", end="", flush=True))
            print(f"\rframe {k}: {degrees:5.1f} degrees, {image.stats['render_seconds']:.2f} s")
            frames.append(image.layers["beauty"])

    sheet = contact_sheet(frames, columns=4)
    # The sheet is NumPy's: an 8-bit sRGB PNG of it, and its linear values as .npy.
    out = pathlib.Path(args.output)
    np.save(out.with_suffix(".npy"), sheet)
    write_png(sheet, out)
    print(f"wrote {out} ({sheet.shape[1]}x{sheet.shape[0]}) and {out.with_suffix('.npy')} (linear RGB)")


def write_png(linear: np.ndarray, path: pathlib.Path) -> None:
    """An 8-bit sRGB PNG of linear RGB values, with the standard library's zlib (no imaging package)."""
    import struct
    import zlib

    srgb = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(np.maximum(linear, 0), 1 / 2.4) - 0.055)
    pixels = (np.clip(srgb, 0, 1) * 255 + 0.5).astype(np.uint8)
    h, w, _ = pixels.shape
    raw = b"".join(b"\x00" + pixels[y].tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    path.write_bytes(png)


if __name__ == "__main__":
    main()
