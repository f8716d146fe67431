"""Authors the USD test stages of tests/suite/usd_loader.rs with Pixar's own USD library, and the same Cornell box as
glTF (for the USD-vs-glTF render comparison).

    python3 -m venv /work/usdvenv && /work/usdvenv/bin/pip install usd-core   # 26.x
    /work/usdvenv/bin/python tests/usd/make_stages.py

Writes, next to this script:
- cornell.usda / cornell.usdc: a Y-up, metre Cornell box (5 walls, two boxes, 6 quads each), a RectLight under the
  ceiling, UsdPreviewSurface materials bound with material:binding, and a camera;
- cornell.gltf: the same box, with the same metallic-roughness mapping (metallic 0, roughness as authored, glTF's
  default specular layer) and the RectLight as an emissive quad facing down;
- override.usda: references cornell.usda, recolours the red wall's material blue and moves the tall box;
- cornell.usdz: cornell.usdc packaged by UsdUtils;
- textured.usda + checker.png: a quad whose UsdPreviewSurface diffuseColor reads a 2x2 PNG through UsdUVTexture,
  with faceVarying primvars:st;
- volume.usda: a Z-up stage in centimetres with a Volume prim whose field:density and field:temperature point at
  OpenVDBAsset prims reading ../../assets/cloud.vdb, with nimbus: attributes.
"""
import os
import struct
import sys
import zlib

from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, UsdUtils, UsdVol

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "assets"))
from gltf_writer import GltfBuilder  # noqa: E402

# (name, colour, roughness)
MATERIALS = [("White", (0.73, 0.73, 0.73), 0.9), ("Red", (0.65, 0.05, 0.05), 0.9), ("Green", (0.12, 0.45, 0.15), 0.9)]
# Each wall: name, material, corners counter-clockwise seen from inside the box.
WALLS = [
    ("Floor", "White", [(-1, 0, 1), (1, 0, 1), (1, 0, -1), (-1, 0, -1)]),
    ("Ceiling", "White", [(-1, 2, -1), (1, 2, -1), (1, 2, 1), (-1, 2, 1)]),
    ("Back", "White", [(-1, 0, -1), (1, 0, -1), (1, 2, -1), (-1, 2, -1)]),
    ("Left", "Red", [(-1, 0, 1), (-1, 0, -1), (-1, 2, -1), (-1, 2, 1)]),
    ("Right", "Green", [(1, 0, -1), (1, 0, 1), (1, 2, 1), (1, 2, -1)]),
]
# Boxes: name, half extents, translate, rotateY (degrees)
BOXES = [("ShortBox", (0.3, 0.3, 0.3), (0.35, 0.3, 0.3), -17.0), ("TallBox", (0.3, 0.6, 0.3), (-0.35, 0.6, -0.3), 17.0)]
LIGHT = dict(width=0.5, height=0.4, y=1.98, intensity=12.0, color=(1.0, 0.85, 0.7))
CAMERA = dict(eye=(0.0, 1.0, 3.6), focal=35.0, aperture=24.0)  # square film: yfov = 2 atan(12 / 35)


def box_quads(h):
    """6 faces, corners CCW seen from outside, of the box [-h, h] centred at the origin"""
    x, y, z = h
    return [
        [(x, -y, z), (x, -y, -z), (x, y, -z), (x, y, z)],
        [(-x, -y, -z), (-x, -y, z), (-x, y, z), (-x, y, -z)],
        [(-x, y, z), (x, y, z), (x, y, -z), (-x, y, -z)],
        [(-x, -y, -z), (x, -y, -z), (x, -y, z), (-x, -y, z)],
        [(-x, -y, z), (x, -y, z), (x, y, z), (-x, y, z)],
        [(x, -y, -z), (-x, -y, -z), (-x, y, -z), (x, y, -z)],
    ]


def usd_mesh(stage, path, quads, material):
    mesh = UsdGeom.Mesh.Define(stage, path)
    pts = [p for q in quads for p in q]
    mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    mesh.CreateFaceVertexCountsAttr([4] * len(quads))
    mesh.CreateFaceVertexIndicesAttr(list(range(len(pts))))
    mesh.CreateSubdivisionSchemeAttr("none")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    return mesh


def cornell_stage(path):
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    mats = {}
    for name, rgb, rough in MATERIALS:
        mat = UsdShade.Material.Define(stage, "/World/Materials/" + name)
        shader = UsdShade.Shader.Define(stage, "/World/Materials/%s/Surface" % name)
        shader.CreateIdAttr("UsdPreviewSurface")
        shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*rgb))
        shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(rough)
        shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
        mat.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
        mats[name] = mat
    for name, mat, corners in WALLS:
        usd_mesh(stage, "/World/Walls/" + name, [corners], mats[mat])
    for name, h, t, ry in BOXES:
        xf = UsdGeom.Xform.Define(stage, "/World/" + name)
        xf.AddTranslateOp().Set(Gf.Vec3d(*t))
        xf.AddRotateYOp().Set(ry)
        usd_mesh(stage, "/World/%s/Geom" % name, box_quads(h), mats["White"])
    light = UsdLux.RectLight.Define(stage, "/World/Light")
    light.CreateWidthAttr(LIGHT["width"])
    light.CreateHeightAttr(LIGHT["height"])
    light.CreateIntensityAttr(LIGHT["intensity"] / 2.0)
    light.CreateExposureAttr(1.0)  # x 2: the same radiance as intensity LIGHT["intensity"]
    light.CreateColorAttr(Gf.Vec3f(*LIGHT["color"]))
    light.AddTranslateOp().Set(Gf.Vec3d(0.0, LIGHT["y"], 0.0))
    light.AddRotateXOp().Set(-90.0)  # the light's -Z (its emitting side) points down
    cam = UsdGeom.Camera.Define(stage, "/World/Camera")
    cam.CreateFocalLengthAttr(CAMERA["focal"])
    cam.CreateHorizontalApertureAttr(CAMERA["aperture"])
    cam.CreateVerticalApertureAttr(CAMERA["aperture"])
    cam.AddTranslateOp().Set(Gf.Vec3d(*CAMERA["eye"]))
    return stage


def cornell_gltf(path):
    b = GltfBuilder()
    mats = {}
    for name, rgb, rough in MATERIALS:
        mats[name] = b.add_material(name, pbrMetallicRoughness={"baseColorFactor": list(rgb) + [1.0],
                                                                "metallicFactor": 0.0, "roughnessFactor": rough})
    for name, mat, corners in WALLS:
        b.quad(name, [list(c) for c in corners], mats[mat])
    import math
    for name, h, t, ry in BOXES:
        a = math.radians(ry)
        rot = [0.0, math.sin(a / 2), 0.0, math.cos(a / 2)]
        b.quads(name, [[list(c) for c in q] for q in box_quads(h)], mats["White"], translation=list(t), rotation=rot)
    w, h, y = LIGHT["width"] / 2, LIGHT["height"] / 2, LIGHT["y"]
    light = b.add_material("Light", pbrMetallicRoughness={"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0},
                           emissiveFactor=list(LIGHT["color"]),
                           extensions={"KHR_materials_emissive_strength": {"emissiveStrength": LIGHT["intensity"]},
                                       "KHR_materials_specular": {"specularFactor": 0.0}})
    b.quad("Light", [[-w, y, -h], [w, y, -h], [w, y, h], [-w, y, h]], light)  # CCW seen from below
    yfov = math.degrees(2 * math.atan(CAMERA["aperture"] / 2 / CAMERA["focal"]))
    b.camera("Camera", eye=list(CAMERA["eye"]), yfov_deg=yfov)
    b.write(path, "tests/usd/make_stages.py")


def override_stage(path):
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    world = stage.DefinePrim("/World")
    world.GetReferences().AddReference("./cornell.usda")
    stage.SetDefaultPrim(world)
    shader = UsdShade.Shader(stage.OverridePrim("/World/Materials/Red/Surface"))
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.05, 0.05, 0.65))
    tall = stage.OverridePrim("/World/TallBox")
    tall.GetAttribute("xformOp:translate").Set(Gf.Vec3d(-0.35, 0.6, -0.5))
    return stage


def volume_stage(path):
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    vol = UsdVol.Volume.Define(stage, "/World/Cloud")
    vol.AddTranslateOp().Set(Gf.Vec3d(10.0, 20.0, 30.0))
    vol.AddScaleOp().Set(Gf.Vec3f(100.0, 100.0, 100.0))
    for field in ("density", "temperature"):
        asset = UsdVol.OpenVDBAsset.Define(stage, "/World/Cloud/" + field)
        asset.CreateFilePathAttr(Sdf.AssetPath("../../assets/cloud.vdb"))
        asset.CreateFieldNameAttr(field)
        vol.CreateFieldRelationship(field, asset.GetPath())
    p = vol.GetPrim()
    p.CreateAttribute("nimbus:density_scale", Sdf.ValueTypeNames.Float).Set(8.0)
    p.CreateAttribute("nimbus:albedo", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.9, 0.8, 0.7))
    p.CreateAttribute("nimbus:anisotropy", Sdf.ValueTypeNames.Float).Set(0.6)
    p.CreateAttribute("nimbus:emission_scale", Sdf.ValueTypeNames.Float).Set(2.0)
    p.CreateAttribute("nimbus:temperature_scale", Sdf.ValueTypeNames.Float).Set(1.5)
    p.CreateAttribute("nimbus:temperature_offset", Sdf.ValueTypeNames.Float).Set(-100.0)
    return stage


def write_png(path, width, height, rgb_rows):
    """an 8-bit RGB PNG from rows of (r, g, b) tuples"""
    raw = b"".join(b"\0" + bytes(c for px in row for c in px) for row in rgb_rows)

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def textured_stage(path):
    write_png(os.path.join(HERE, "checker.png"), 2, 2, [[(255, 0, 0), (0, 255, 0)], [(0, 0, 255), (255, 255, 255)]])
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    mat = UsdShade.Material.Define(stage, "/Looks/Checker")
    surface = UsdShade.Shader.Define(stage, "/Looks/Checker/Surface")
    surface.CreateIdAttr("UsdPreviewSurface")
    tex = UsdShade.Shader.Define(stage, "/Looks/Checker/Texture")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set("./checker.png")
    tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
    rgb = tex.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(rgb)
    mat.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    mesh = usd_mesh(stage, "/Quad", [[(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]], mat)
    st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                 UsdGeom.Tokens.faceVarying)
    st.Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    return stage


def main():
    stage = cornell_stage(os.path.join(HERE, "cornell.usda"))
    stage.Save()
    stage.GetRootLayer().Export(os.path.join(HERE, "cornell.usdc"))
    UsdUtils.CreateNewUsdzPackage(os.path.join(HERE, "cornell.usdc"), os.path.join(HERE, "cornell.usdz"))
    cornell_gltf(os.path.join(HERE, "cornell.gltf"))
    for make, name in ((override_stage, "override.usda"), (volume_stage, "volume.usda"),
                       (textured_stage, "textured.usda")):
        stage = make(os.path.join(HERE, name))
        stage.Save()


if __name__ == "__main__":
    main()
