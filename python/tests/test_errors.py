"""Each Rust error type is a subclass of nimbus.Error, raised by a real bad input with the CLI's one-line message."""

import pytest

import nimbus
from conftest import cli_error_line, run_cli

SUBCLASSES = [nimbus.SceneError, nimbus.OutputError, nimbus.VdbError, nimbus.RegionError, nimbus.FarmError,
              nimbus.RenderError]


def test_every_error_class_derives_from_nimbus_error():
    for cls in SUBCLASSES:
        assert issubclass(cls, nimbus.Error) and cls is not nimbus.Error
    assert issubclass(nimbus.Error, Exception)


def test_a_malformed_scene_raises_scene_error_with_the_clis_message(cli, tmp_path):
    bad = tmp_path / "bad.gltf"
    bad.write_text('{"asset": {"version": "2.0"}, "nodes": [{"mesh": 7}]}')
    with pytest.raises(nimbus.SceneError) as raised:
        nimbus.load(bad)
    status, stderr = run_cli(cli, "render", bad, "-o", tmp_path / "x.exr")
    assert status != 0
    assert str(raised.value) == cli_error_line(stderr)
    assert "bad.gltf" in str(raised.value) and "\n" not in str(raised.value)


def test_a_missing_scene_raises_scene_error(tmp_path):
    with pytest.raises(nimbus.SceneError, match="nope.glb"):
        nimbus.load(tmp_path / "nope.glb")


def test_a_file_that_is_not_vdb_raises_vdb_error_with_the_clis_message(cli, tmp_path):
    bad = tmp_path / "bad.vdb"
    bad.write_bytes(b"not a vdb file at all")
    with pytest.raises(nimbus.VdbError) as raised:
        nimbus.info(bad)
    status, stderr = run_cli(cli, "info", bad)
    assert status != 0 and str(raised.value) == cli_error_line(stderr)


def test_an_unwritable_output_raises_output_error(cloud, tmp_path):
    image = nimbus.render(nimbus.load(cloud), spp=1, width=8)
    blocker = tmp_path / "a file"
    blocker.write_text("")
    with pytest.raises(nimbus.OutputError, match="a file"):
        image.write(blocker / "out.exr")


def test_a_crop_outside_the_frame_raises_region_error(cloud):
    with pytest.raises(nimbus.RegionError, match="does not fit"):
        nimbus.render(nimbus.load(cloud), spp=1, width=16, height=16, crop=(8, 8, 40, 12))


def test_parts_of_different_renders_raise_farm_error(cloud):
    scene = nimbus.load(cloud)
    a = nimbus.render(scene, spp=2, width=8, seed=1, samples=(0, 1))
    b = nimbus.render(scene, spp=2, width=8, seed=2, samples=(1, 2))
    with pytest.raises(nimbus.FarmError, match="seed"):
        nimbus.merge([a, b])


def test_an_unknown_light_group_raises_render_error(cloud):
    with pytest.raises(nimbus.RenderError, match="lg_nowhere"):
        nimbus.render(nimbus.load(cloud), spp=1, width=8, aovs="lg_nowhere")


def test_a_film_over_the_memory_budget_raises_render_error(cloud):
    scene = nimbus.load(cloud, memory_limit=64 << 20)
    with pytest.raises(nimbus.RenderError, match="memory"):
        nimbus.render(scene, spp=1, width=8000, height=8000)


def test_bad_arguments_raise_value_error(cloud):
    scene = nimbus.load(cloud)
    with pytest.raises(ValueError):
        nimbus.render(scene, spp=0)
    with pytest.raises(ValueError, match="no-such-method"):
        nimbus.load(cloud, volume_method="no-such-method")
