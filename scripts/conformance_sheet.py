#!/usr/bin/env python3
"""Contact sheets for judging conformance renders by eye: each model's render beside its reference screenshot,
several models per sheet, with the model's name and the render's figures (mean sRGB, seconds) under each pair.

It reads the rows that `scripts/conformance_extra.py --json ROWS.json` writes. A model's screenshot is looked
for in the folder above its scene file (the Khronos sample-asset layout: Models/NAME/glTF/NAME.gltf beside
Models/NAME/screenshot/screenshot.{png,jpg,gif}).

    scripts/conformance_sheet.py ROWS.json --out /tmp/sheets [--per-sheet 8] [--size 200]

Needs Pillow (`pip install --user pillow`).
"""

import argparse
import json
import os

from PIL import Image, ImageDraw

SCREENSHOT_NAMES = ("screenshot.png", "screenshot.jpg", "screenshot.jpeg", "screenshot.gif")


def screenshot_of(scene):
    """The reference screenshot of a scene file in the Khronos layout, or None."""
    model_dir = os.path.dirname(os.path.dirname(scene))
    for name in SCREENSHOT_NAMES:
        path = os.path.join(model_dir, "screenshot", name)
        if os.path.isfile(path):
            return path
    return None


def fitted(path, size):
    """The image at path scaled to fit a size x size box (first frame of a GIF), on a grey tile; a labelled
    grey tile when there is none."""
    tile = Image.new("RGB", (size, size), (64, 64, 64))
    if path is None:
        ImageDraw.Draw(tile).text((8, size // 2), "none", fill=(255, 80, 80))
        return tile
    image = Image.open(path).convert("RGB")
    image.thumbnail((size, size))
    tile.paste(image, ((size - image.width) // 2, (size - image.height) // 2))
    return tile


def caption(row):
    """The line under a pair: name, then the render's figures or its error."""
    if row.get("mean") is None:
        return f"{row['name']}: {row['notes'][:40]}"
    return f"{row['name']}  mean {row['mean']:.0f}  {row['seconds']:.1f}s"


def sheet(rows, size, columns):
    """One sheet: pairs (render left, screenshot right) in `columns` pairs per line."""
    label = 14
    lines = (len(rows) + columns - 1) // columns
    canvas = Image.new("RGB", (columns * (2 * size + 8), lines * (size + label + 6)), (20, 20, 20))
    draw = ImageDraw.Draw(canvas)
    for index, row in enumerate(rows):
        x = (index % columns) * (2 * size + 8)
        y = (index // columns) * (size + label + 6)
        canvas.paste(fitted(row.get("png"), size), (x, y))
        canvas.paste(fitted(screenshot_of(row["scene"]), size), (x + size, y))
        draw.text((x + 2, y + size + 1), caption(row), fill=(255, 255, 255))
    return canvas


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rows", help="the JSON rows written by conformance_extra.py --json")
    parser.add_argument("--out", default="/tmp/conformance-sheets")
    parser.add_argument("--per-sheet", type=int, default=8)
    parser.add_argument("--columns", type=int, default=2, help="pairs per line")
    parser.add_argument("--size", type=int, default=200, help="pixels per image")
    args = parser.parse_args()
    with open(args.rows) as f:
        rows = json.load(f)
    os.makedirs(args.out, exist_ok=True)
    for start in range(0, len(rows), args.per_sheet):
        path = os.path.join(args.out, f"sheet{start // args.per_sheet + 1:02}.png")
        sheet(rows[start : start + args.per_sheet], args.size, args.columns).save(path)
        print(path)


if __name__ == "__main__":
    main()
