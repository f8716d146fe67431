"""Authors tests/usd/sequence.usdc with Pixar's own USD library: a Volume whose field:density OpenVDBAsset names
a VDB sequence through a time-sampled filePath (UsdVol's way): grid.0001.vdb at time code 1, grid.0003.vdb at 3.
The files are relative to the stage; tests/suite/shots.rs copies the stage beside such a sequence. The binary crate
format is used because openusd 0.6's text parser does not read asset-valued time samples.

    python3 -m venv /work/usdvenv && /work/usdvenv/bin/pip install usd-core
    /work/usdvenv/bin/python tests/usd/make_sequence_stage.py
"""
import os

from pxr import Sdf, Usd, UsdVol

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    path = os.path.join(HERE, "sequence.usdc")
    stage = Usd.Stage.CreateNew(path)
    stage.SetTimeCodesPerSecond(24)
    stage.SetFramesPerSecond(24)
    world = stage.DefinePrim("/World", "Xform")
    stage.SetDefaultPrim(world)
    volume = UsdVol.Volume.Define(stage, "/World/Smoke")
    asset = UsdVol.OpenVDBAsset.Define(stage, "/World/Smoke/density")
    asset.CreateFieldNameAttr("density")
    file_path = asset.CreateFilePathAttr()
    file_path.Set(Sdf.AssetPath("grid.0001.vdb"), 1.0)
    file_path.Set(Sdf.AssetPath("grid.0003.vdb"), 3.0)
    volume.CreateFieldRelationship("density", asset.GetPath())
    stage.GetRootLayer().Save()
    print("wrote", path)


if __name__ == "__main__":
    main()
