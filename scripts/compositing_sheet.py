#!/usr/bin/env python3
"""The pictures and figures of docs/compositing.md: a contact sheet of every layer of a Nimbus EXR, and a comp
that rebuilds the beauty from its layers.

    python3 scripts/compositing_sheet.py RENDER.exr OUT_DIR
    python3 scripts/compositing_sheet.py --catcher CATCHER.exr OUT_DIR

RENDER.exr is a render with every layer (`nimbus render --aovs all --light-groups per-light`). Writes
OUT_DIR/compositing_layers.png (one labelled tile per layer, tone-mapped for viewing), OUT_DIR/compositing_comp.png
(the beauty, the beauty rebuilt from its light-path layers, from its light groups, their differences × 10^5, and
the render over a plate by its alpha), and prints the figures of the rebuild as a markdown table.

With `--catcher`, CATCHER.exr is a transparent render whose ground is a shadow catcher: writes
OUT_DIR/compositing_catcher.png (the beauty, its alpha, the shadow_catcher layer, a plate, and the comp
`beauty + (1 − alpha) × plate × shadow_catcher`).

Needs numpy, Pillow and PyPI's OpenEXR (an independent reader of the file); the font is the repository's
assets/fonts/DejaVuSansMono.ttf.
"""
import os
import sys

import numpy as np
import OpenEXR
from PIL import Image, ImageDraw, ImageFont

HERE = os.path.dirname(os.path.abspath(__file__))
FONT = os.path.join(HERE, "..", "assets", "fonts", "DejaVuSansMono.ttf")
TILE = 256


def read(path):
    """Every channel of the file as float64 arrays (H, W), keyed by full name."""
    channels = OpenEXR.File(path, separate_channels=True).parts[0].channels
    return {name: np.asarray(c.pixels, dtype=np.float64) for name, c in channels.items()}


def rgb(channels, layer):
    """A layer's R, G, B (or X, Y, Z; or Z alone) as an (H, W, 3) array."""
    prefix = "" if layer == "" else layer + "."
    for names in (("R", "G", "B"), ("X", "Y", "Z"), ("r", "g", "b")):
        keys = [prefix + n for n in names]
        if all(k in channels for k in keys):
            return np.stack([channels[k] for k in keys], axis=-1)
    return np.repeat(channels[prefix + "Z"][..., None], 3, axis=-1)


def srgb(linear):
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def to_u8(img):
    return (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)


def id_colour(ids):
    """A stable false colour per Cryptomatte ID (the float's bits, hashed)."""
    bits = ids.astype(np.float32).view(np.uint32).astype(np.uint64)
    h = (bits * np.uint64(2654435761)) & np.uint64(0xFFFFFFFF)
    return np.stack([((h >> np.uint64(s)) & np.uint64(255)).astype(np.float64) / 255 for s in (0, 8, 16)], -1)


def view(channels, name):
    """A layer tone-mapped for the contact sheet, as an (H, W, 3) array in [0, 1]."""
    if name == "A":
        return np.repeat(channels["A"][..., None], 3, -1)
    if name.startswith("Crypto"):
        layer = name + "00"
        ids, cov = channels[layer + ".r"], channels[layer + ".g"]
        return id_colour(ids) * cov[..., None]
    data = rgb(channels, name)
    if name == "normal":
        return data * 0.5 + 0.5
    if name == "depth":
        d = data / max(data.max(), 1e-9)
        return 1 - d
    if name == "variance":
        s = np.sqrt(data)
        return s / max(np.percentile(s, 99), 1e-9)
    if name.endswith(("_direct", "_indirect")):
        # Surface light-path layers are light divided by colour (irradiance-like): exposed to their 99th
        # percentile, which the tile's label notes.
        peak = np.percentile(data, 99)
        return srgb(data * (0.8 / peak if peak > 0 else 1.0))
    return srgb(data)


def label(img, text):
    draw = ImageDraw.Draw(img)
    font = ImageFont.truetype(FONT, 12)
    draw.rectangle([0, 0, 6 + 8 * len(text), 18], fill=(0, 0, 0))
    draw.text((4, 2), text, font=font, fill=(255, 255, 255))
    return img


def sheet(tiles, columns):
    h, w = tiles[0][1].shape[:2]
    scale = TILE / w
    th = int(round(h * scale))
    rows = (len(tiles) + columns - 1) // columns
    out = Image.new("RGB", (columns * TILE, rows * th), (40, 40, 40))
    for k, (name, img) in enumerate(tiles):
        tile = Image.fromarray(to_u8(img)).resize((TILE, th), Image.NEAREST)
        out.paste(label(tile, name), ((k % columns) * TILE, (k // columns) * th))
    return out


def plate_of(shape):
    """A stand-in for a photographed plate: a warm ground under a pale sky, with a checker for texture."""
    h, w = shape[:2]
    yy, xx = np.mgrid[0:h, 0:w]
    sky = np.stack([0.55 + 0 * yy, 0.62 + 0 * yy, 0.70 + 0 * yy], -1) * (1 - 0.4 * yy[..., None] / h)
    ground = np.stack([0.42 + 0 * yy, 0.33 + 0 * yy, 0.24 + 0 * yy], -1)
    ground = ground * (0.85 + 0.15 * (((yy // 12) + (xx // 12)) % 2))[..., None]
    return np.where((yy > 0.42 * h)[..., None], ground, sky)


def catcher(path, out_dir):
    channels = read(path)
    beauty = rgb(channels, "")
    alpha = channels["A"][..., None]
    shadow = rgb(channels, "shadow_catcher")
    plate = plate_of(beauty.shape)
    comp = beauty + (1 - alpha) * plate * shadow
    tiles = [
        ("beauty (transparent)", srgb(beauty)),
        ("A", np.repeat(alpha, 3, -1)),
        ("shadow_catcher", srgb(shadow)),
        ("plate", srgb(plate)),
        ("beauty + (1-A) plate x shadow", srgb(comp)),
    ]
    sheet(tiles, 5).save(os.path.join(out_dir, "compositing_catcher.png"))
    in_shadow = shadow[..., 0] < 0.5
    print(f"shadow_catcher: {in_shadow.mean() * 100:.1f}% of pixels below 0.5, minimum {shadow.min():.3f}")


def main():
    if sys.argv[1] == "--catcher":
        return catcher(sys.argv[2], sys.argv[3])
    path, out_dir = sys.argv[1], sys.argv[2]
    channels = read(path)
    layers = sorted({c.rsplit(".", 1)[0] for c in channels if "." in c})
    order = ["albedo", "normal", "depth", "variance"]
    order += [l for l in layers if l.endswith(("_direct", "_indirect"))]
    order += ["emission", "environment"]
    order += [l for l in layers if l.endswith("_color")]
    order += [l for l in layers if l.startswith("lg_")]
    order += ["shadow_catcher"]
    kinds = sorted({l[:-2] for l in layers if l.startswith("Crypto")})
    names = ["beauty", "A"] + [l for l in order if l in layers] + kinds
    tiles = []
    for name in names:
        img = srgb(rgb(channels, "")) if name == "beauty" else view(channels, name)
        shown = name + " (auto exposure)" if name.endswith(("_direct", "_indirect")) else name
        tiles.append((shown, img))
    sheet(tiles, 5).save(os.path.join(out_dir, "compositing_layers.png"))

    beauty = rgb(channels, "")
    transparent_env = rgb(channels, "environment")
    total = beauty
    rebuilt = rgb(channels, "emission") + rgb(channels, "volume_direct") + rgb(channels, "volume_indirect")
    for cls in ("diffuse", "glossy", "transmission"):
        colour = rgb(channels, cls + "_color")
        rebuilt = rebuilt + (rgb(channels, cls + "_direct") + rgb(channels, cls + "_indirect")) * colour
    groups = sum(rgb(channels, l) for l in layers if l.startswith("lg_"))
    # Without --transparent the beauty holds the environment seen directly; with it, the environment layer does.
    if np.abs(beauty - rebuilt).max() > np.abs(beauty - rebuilt - transparent_env).max():
        rebuilt = rebuilt + transparent_env
    floor = 1e-2
    rel = np.abs(rebuilt - total) / np.maximum(total, floor)
    rel_groups = np.abs(groups - total) / np.maximum(total, floor)
    alpha = channels["A"][..., None]
    yy, xx = np.mgrid[0:beauty.shape[0], 0:beauty.shape[1]]
    plate = np.stack([0.15 + 0.1 * (((yy // 16) + (xx // 16)) % 2), 0.2 + 0.0 * yy, 0.28 + 0.0 * yy], -1)
    over = beauty + (1 - alpha) * plate * rgb(channels, "shadow_catcher")
    comp = [
        ("beauty", srgb(beauty)),
        ("light paths rebuilt", srgb(rebuilt)),
        ("|difference| x 1e5", srgb(np.abs(rebuilt - total) * 1e5)),
        ("light groups summed", srgb(groups)),
        ("over a plate (alpha)", srgb(over)),
    ]
    sheet(comp, 5).save(os.path.join(out_dir, "compositing_comp.png"))
    print("| rebuild | largest relative difference | mean absolute difference | beauty mean |")
    print("|---|---|---|---|")
    print(f"| Σ (direct + indirect) × color + volume + emission + environment | {rel.max():.2e} | "
          f"{np.abs(rebuilt - total).mean():.2e} | {total.mean():.4f} |")
    print(f"| Σ light groups | {rel_groups.max():.2e} | {np.abs(groups - total).mean():.2e} | {total.mean():.4f} |")
    print(f"alpha: mean {alpha.mean():.4f}, min {alpha.min():.4f}, max {alpha.max():.4f}")


if __name__ == "__main__":
    main()
