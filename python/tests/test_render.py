"""Renders from Python against the CLI's files, read back by OpenEXR's own Python binding (PyPI OpenEXR)."""

import json

import numpy as np
import OpenEXR
import pytest

import nimbus
from conftest import run_cli

# A small render of the bundled cloud (a VDB medium over a lit ground plane).
SIZE, SPP, SEED = 96, 8, 7


def read_exr(path):
    """Every channel of an EXR, by name, as OpenEXR reads it."""
    channels = OpenEXR.File(str(path), separate_channels=True).channels()
    return {name: channel.pixels for name, channel in channels.items()}


def channel_name(layer, component):
    return component if layer == "beauty" else f"{layer}.{component}"


@pytest.fixture(scope="module")
def cli_render(cli, cloud, tmp_path_factory):
    """The CLI's EXR and --stats of the reference render."""
    folder = tmp_path_factory.mktemp("cli")
    status, stderr = run_cli(cli, "render", cloud, "-o", folder / "cli.exr", "--width", SIZE, "--spp", SPP,
                             "--seed", SEED, "--stats", folder / "stats.json")
    assert status == 0, stderr
    return read_exr(folder / "cli.exr"), json.loads((folder / "stats.json").read_text())


def test_a_render_is_bit_identical_to_the_clis_exr(cloud, cli_render):
    channels, _ = cli_render
    image = nimbus.render(nimbus.load(cloud), spp=SPP, width=SIZE, seed=SEED, threads=3)
    names = {channel_name(layer, c) for layer, cs in image.components.items() for c in cs}
    assert names == set(channels), "the layers are the EXR's layers"
    for layer, array in image.layers.items():
        assert array.dtype == np.float32 and array.shape[:2] == (image.height, image.width)
        for k, component in enumerate(image.components[layer]):
            expected = channels[channel_name(layer, component)]
            assert np.array_equal(array[:, :, k], expected), f"{layer}.{component} differs from the CLI's"
    beauty = image.layers["beauty"]
    assert beauty[:, :, :3].max() > 0.05, "the cloud and its ground are lit"


def test_the_written_exr_and_stats_are_the_clis(cloud, cli_render, tmp_path):
    channels, cli_stats = cli_render
    image = nimbus.render(nimbus.load(cloud), spp=SPP, width=SIZE, seed=SEED)
    image.write(tmp_path / "py.exr")
    written = read_exr(tmp_path / "py.exr")
    assert set(written) == set(channels)
    for name, pixels in channels.items():
        assert np.array_equal(written[name], pixels), name
    assert set(image.stats) == set(cli_stats), "the --stats keys"
    for key in ("samples_per_pixel", "width", "height", "seed", "max_depth", "nan_samples", "media", "layers"):
        if key != "media":
            assert image.stats[key] == cli_stats[key], key
    assert [m["name"] for m in image.stats["media"]] == [m["name"] for m in cli_stats["media"]]


def test_guiding_is_the_clis(cloud, cli, tmp_path):
    """``guiding`` is ``--guiding``: forced on, the demo renders the CLI's ``--guiding on`` bits and its stats say
    so; off renders other bits; a name it does not know is a ValueError."""
    size, spp = 32, 9
    status, stderr = run_cli(cli, "render", cloud, "-o", tmp_path / "on.exr", "--width", size, "--spp", spp,
                             "--seed", SEED, "--guiding", "on")
    assert status == 0, stderr
    scene = nimbus.load(cloud)
    on = nimbus.render(scene, spp=spp, width=size, seed=SEED, guiding="on")
    assert on.stats["guiding"]["mode"] == "on"
    channels = read_exr(tmp_path / "on.exr")
    for k, component in enumerate(on.components["beauty"]):
        assert np.array_equal(on.layers["beauty"][:, :, k], channels[component]), component
    off = nimbus.render(scene, spp=spp, width=size, seed=SEED, guiding="off")
    assert off.stats["guiding"]["mode"] == "off"
    assert not np.array_equal(off.layers["beauty"], on.layers["beauty"])
    with pytest.raises(ValueError, match="guiding 'sometimes' is not one of auto, on, off"):
        nimbus.render(scene, spp=spp, width=size, seed=SEED, guiding="sometimes")


def test_parts_merge_into_the_whole_render_bit_for_bit(cloud, tmp_path, cli):
    scene = nimbus.load(cloud)
    whole = nimbus.render(scene, spp=SPP, width=SIZE, seed=SEED)
    first = nimbus.render(scene, spp=SPP, width=SIZE, seed=SEED, samples=(0, 3))
    assert first.is_part and first.stats["samples_per_pixel"] == 3
    # The second part comes from the CLI: parts of either merge with the other's (same scene hash).
    status, stderr = run_cli(cli, "render", cloud, "-o", tmp_path / "b.exr", "--width", SIZE, "--spp", SPP,
                             "--seed", SEED, "--samples", "3..8")
    assert status == 0, stderr
    merged = nimbus.merge([first, tmp_path / "b.exr"])
    for layer, array in whole.layers.items():
        assert np.array_equal(merged.layers[layer], array), layer
    with pytest.raises(nimbus.FarmError, match="unrendered"):
        nimbus.merge([first])


def test_a_crop_part_holds_its_window(cloud):
    part = nimbus.render(nimbus.load(cloud), spp=2, width=40, height=30, crop=(10, 5, 30, 25))
    assert part.is_part and (part.width, part.height) == (20, 20)


def test_png_preview_and_notebook_repr(cloud, tmp_path):
    image = nimbus.render(nimbus.load(cloud), spp=2, width=32)
    png = image._repr_png_()
    assert png.startswith(b"\x89PNG\r\n\x1a\n")
    image.to_png(tmp_path / "a.png", exposure=1.5)
    image.to_png(tmp_path / "b.png", exposure=None)
    assert all((tmp_path / n).read_bytes().startswith(b"\x89PNG") for n in ("a.png", "b.png"))


def test_progress_is_called_at_most_ten_times_a_second(cloud):
    import time

    calls = []
    start = time.monotonic()
    nimbus.render(nimbus.load(cloud), spp=400, width=48, progress=lambda done, total: calls.append((done, total)))
    elapsed = time.monotonic() - start
    assert calls, "progress was called"
    assert calls[-1] == (400, 400), "the last call reports the finished render"
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)
    assert len(calls) <= 10 * elapsed + 2, f"{len(calls)} calls in {elapsed:.2f} s"


def test_info_is_the_clis_json(cli, root):
    import subprocess

    vdb = root / "assets" / "cloud.vdb"
    out = subprocess.run([str(cli), "info", str(vdb), "--json"], capture_output=True, text=True, check=True)
    assert nimbus.info(vdb) == json.loads(out.stdout)
