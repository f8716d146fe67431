"""USD stages composed by Pixar's library (PyPI usd-core), then read flattened by Nimbus's own USD reader."""

import os
import pathlib
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import nimbus

from pxr import Usd  # noqa: E402  (usd-core is a test requirement: .ci/run installs it)

MODEL = """\
#usda 1.0
(
    defaultPrim = "Model"
)

def Xform "Model" (
    prepend variantSets = "color"
    variants = {
        string color = "red"
    }
)
{
    def Cube "Box"
    {
        double size = 1
    }

    variantSet "color" = {
        "red" {
            over "Box"
            {
                color3f[] primvars:displayColor = [(0.8, 0.05, 0.05)]
            }
        }
        "blue" {
            over "Box"
            {
                color3f[] primvars:displayColor = [(0.05, 0.05, 0.8)]
            }
        }
    }
}
"""

LIGHTS = """\
#usda 1.0

def DistantLight "Sun"
{
    float inputs:intensity = 3
    float3 xformOp:rotateXYZ = (-50, 30, 0)
    uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
}
"""

SHOT = """\
#usda 1.0
(
    subLayers = [
        @./lights.usda@
    ]
)

def Xform "World"
{
    def "Asset" (
        prepend references = @./model.usda@
        variants = {
            string color = "blue"
        }
    )
    {
    }
    %s
}
"""


def write_stage(folder: pathlib.Path, extra: str = "") -> pathlib.Path:
    (folder / "model.usda").write_text(MODEL)
    (folder / "lights.usda").write_text(LIGHTS)
    shot = folder / "shot.usda"
    shot.write_text(SHOT % extra)
    return shot


def box_colour(scene):
    """Mean beauty of the pixels the box covers (alpha 1 against the empty background)."""
    image = nimbus.render(scene, spp=4, width=64, height=64, seed=3)
    beauty = image.layers["beauty"]
    covered = beauty[:, :, 3] > 0.99
    assert covered.sum() > 100, "the box is in view"
    return beauty[covered][:, :3].mean(axis=0)


def test_a_stage_of_several_layers_renders_its_variant_selection(tmp_path):
    stage = Usd.Stage.Open(str(write_stage(tmp_path)))
    r, g, b = box_colour(nimbus.load_stage(stage))
    assert b > 3 * r, f"the shot selects blue: mean {r:.3f} {g:.3f} {b:.3f}"
    # A selection made in Python, on the composed stage, is what renders.
    stage.GetPrimAtPath("/World/Asset").GetVariantSet("color").SetVariantSelection("red")
    r, g, b = box_colour(nimbus.load_stage(stage))
    assert r > 3 * b, f"red selected: mean {r:.3f} {g:.3f} {b:.3f}"


def test_a_missing_reference_warns_and_the_rest_renders(tmp_path):
    missing = 'def "Prop" (\n        prepend references = @./not_here.usda@\n    )\n    {\n    }'
    shot = write_stage(tmp_path, missing)
    # USD reports the missing layer as a composition error and composes the rest.
    with pytest.warns(nimbus.NimbusWarning, match="not_here"):
        scene = nimbus.load_stage(Usd.Stage.Open(str(shot)))
    r, g, b = box_colour(scene)
    assert b > 3 * r


def test_a_time_code_reads_animated_values(tmp_path):
    (tmp_path / "anim.usda").write_text(textwrap.dedent("""\
        #usda 1.0
        (
            startTimeCode = 1
            endTimeCode = 10
        )
        def Cube "Box"
        {
            color3f[] primvars:displayColor = [(0.05, 0.05, 0.8)]
            double3 xformOp:translate.timeSamples = {
                1: (0, 0, 0),
                10: (100, 0, 0),
            }
            uniform token[] xformOpOrder = ["xformOp:translate"]
        }
        def Cube "Still"
        {
            color3f[] primvars:displayColor = [(0.8, 0.05, 0.05)]
            double3 xformOp:translate = (0, 3, 0)
            uniform token[] xformOpOrder = ["xformOp:translate"]
        }
        """))
    stage = Usd.Stage.Open(str(tmp_path / "anim.usda"))
    early = nimbus.load_stage(stage, time=1)
    late = nimbus.load_stage(stage, time=10)
    assert early.triangle_count == late.triangle_count
    a = nimbus.render(early, spp=1, width=32, height=32).layers["beauty"]
    b = nimbus.render(late, spp=1, width=32, height=32).layers["beauty"]
    assert not np.array_equal(a, b), "the box moved between the time codes"


def test_without_usd_core_load_stage_names_the_package(tmp_path):
    code = textwrap.dedent("""\
        import sys
        sys.modules["pxr"] = None  # as if usd-core were not installed
        import nimbus
        try:
            nimbus.load_stage(object())
        except ImportError as e:
            print(e)
        """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "usd-core" in out and "pip install" in out


USDWG = os.environ.get("NIMBUS_USDWG_ASSETS")


@pytest.mark.skipif(not USDWG, reason="NIMBUS_USDWG_ASSETS (a checkout of usd-wg/assets) is not set")
def test_usd_wg_teapot_scene_loads_with_a_warning():
    """teapotScene.usd: four sublayers placing ~1000 referenced teapots, whose animation-cycle layer
    (assets/teapot/teapot_animCycle.usd) is missing. Composed whole it is 39.5 M triangles, over a desktop's
    memory budget: USD's population mask keeps one ring of teapots."""
    shot = pathlib.Path(USDWG) / "intent-vfx" / "scenes" / "teapotScene.usd"
    stage = Usd.Stage.OpenMasked(str(shot), Usd.StagePopulationMask(["/Scene/ring000"]))
    with pytest.warns(nimbus.NimbusWarning, match="teapot_animCycle.usd"):
        scene = nimbus.load_stage(stage)
    assert scene.triangle_count > 100_000, "the ring of teapots is there"
    image = nimbus.render(scene, spp=2, width=64)
    assert image.layers["beauty"][:, :, 3].mean() > 0.05
