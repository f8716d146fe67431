#!/usr/bin/env python3
"""Writes Nimbus's glTF scenes (pure Python; the glTF plumbing is assets/gltf_writer.py). Every file is a .gltf
with its one buffer embedded as a base64 data URI; the .vdb files they reference come from assets/make_cloud.py.

Run from the repository root:  python3 assets/make_scenes.py

  assets/cloud.gltf                 the README's demo: cloud.vdb above a Lambertian ground, warm sun, blue sky
  assets/cloud_mitsuba_check.gltf   the same cloud alone under a constant environment (for gltf2mitsuba.py)
  assets/thesis_beers_law.gltf      absorbing spheres, sigma_a 0.4 and 0.8 /m, each as KHR_materials_volume and as
                                    nimbus_medium, on a checker ground under an area light
  assets/thesis_noise_spheres.gltf  two absorption-only Perlin-noise spheres (nimbus_medium.noise), max_density 1, 3
  assets/thesis_mixed.gltf          a scattering sphere, a mirror sphere, a glass sphere and diffuse shapes
  tests/scenes/slab_homogeneous.gltf  a slab (closed box) of scattering+absorbing medium, constant environment
  tests/scenes/furnace_sphere.gltf    white furnace: albedo-1 medium sphere (sigma_s 2) under environment 1
  tests/scenes/constant_grid.gltf     constant_grid.vdb (16^3 voxels of 1.0) with density_scale 2
  tests/scenes/constant_box.gltf      the homogeneous box medium equivalent to constant_grid.gltf

Scene conventions used (see DESIGN.md): node extras.nimbus_volume {file, density_grid, density_scale, albedo,
anisotropy}; material extras.nimbus_medium {sigma_a, sigma_s, anisotropy} or {noise: {scale, max_density, seed}}
on an index-matched boundary (KHR_materials_transmission 1, KHR_materials_ior 1.0, roughness 0, metallic 0);
KHR_materials_volume (sigma_a = -ln(attenuationColor) / attenuationDistance); scene extras nimbus_environment
{color} and max_bounces. Units: metres, +Y up.
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltf_writer import GltfBuilder  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ASSETS = os.path.join(ROOT, "assets")
TESTS = os.path.join(ROOT, "tests", "scenes")
GENERATOR = "nimbus assets/make_scenes.py"

# cloud.vdb as written by make_cloud.py: voxel 0.02 m, active index bbox (-35, 1, -28)..(39, 49, 30), i.e. world
# (VDB space, voxel centres) x -0.70..0.78, y 0.02..0.98, z -0.56..0.60: the base at y ~ 0, centred near x = z = 0.
CLOUD_CENTRE = [0.04, 0.50, 0.02]
CLOUD = {"file": "cloud.vdb", "density_grid": "density", "density_scale": 30.0, "albedo": [0.95, 0.95, 0.95],
         "anisotropy": 0.5}

# constant_grid.vdb: voxel 0.0625 m, active voxels i, j, k in [0, 15], all exactly 1.0 (background 0)
CONST_VOXEL = 0.0625
CONST_N = 16
CONST_SCALE = 2.0          # density_scale: sigma_t = 2 /m where the density is 1
CONST_ALBEDO = 0.8


def written(path, n):
    print(f"wrote {os.path.relpath(path, ROOT)} {n} bytes")


# ----------------------------------------------------------------------------------------------- cloud scenes
def cloud_scene():
    b = GltfBuilder()
    ground = b.lambert("ground", [0.3, 0.3, 0.28])
    g = 40.0
    b.quad("ground", [[-g, 0, g], [g, 0, g], [g, 0, -g], [-g, 0, -g]], ground)
    # the cloud's base 1 m above the ground
    b.volume_node("cloud_volume", dict(CLOUD), translation=[0.0, 1.0, 0.0])
    # the sun ~58 degrees high, from the front right: lit side towards the camera, shadow behind-left on the ground;
    # 2049 lx is 3 W/m^2 at glTF's 683 lm/W
    b.directional_light("sun", direction=[-0.5, -1.0, -0.35], color=[1.0, 0.9, 0.75], intensity=3.0 * 683)
    b.camera("camera", eye=[0.4, 1.6, 4.2], target=[-0.1, 1.2, 0.0], yfov_deg=32, aspect=16 / 9)
    out = os.path.join(ASSETS, "cloud.gltf")
    written(out, b.write(out, GENERATOR, scene_extras={"nimbus_environment": {"color": [0.35, 0.5, 0.8]},
                                                       "max_bounces": 64}))


def cloud_mitsuba_check_scene():
    b = GltfBuilder()
    # the cloud centred on the origin; nothing else but a constant environment
    b.volume_node("cloud_volume", dict(CLOUD), translation=[-c for c in CLOUD_CENTRE])
    b.camera("camera", eye=[0.0, 0.0, 2.6], target=[0.0, 0.0, 0.0], yfov_deg=40, aspect=1.0)
    out = os.path.join(ASSETS, "cloud_mitsuba_check.gltf")
    written(out, b.write(out, GENERATOR, scene_extras={"nimbus_environment": {"color": [0.5, 0.7, 1.0]},
                                                       "max_bounces": 64}))


# ----------------------------------------------------------------------------------------------- thesis figures
def checker_ground(b, half_x=5, half_z=4, tile=1.0):
    """two Lambertian meshes of alternating 1 m tiles covering [-half_x, half_x] x [-half_z, half_z] at y = 0"""
    light_tiles, dark_tiles = [], []
    for i in range(-half_x, half_x):
        for k in range(-half_z, half_z):
            x0, x1, z0, z1 = i * tile, (i + 1) * tile, k * tile, (k + 1) * tile
            q = [[x0, 0, z1], [x1, 0, z1], [x1, 0, z0], [x0, 0, z0]]   # normal +Y
            (light_tiles if (i + k) % 2 == 0 else dark_tiles).append(q)
    b.quads("ground_light_tiles", light_tiles, b.lambert("checker_light", [0.8, 0.8, 0.8]))
    b.quads("ground_dark_tiles", dark_tiles, b.lambert("checker_dark", [0.15, 0.15, 0.15]))


def area_light(b, y=4.0, half=1.0, strength=8.0):
    """an emissive square facing down (front = CCW seen from below)"""
    m = b.emitter("area_light", [1.0, 0.95, 0.9], strength)
    b.quad("area_light", [[-half, y, -half], [half, y, -half], [half, y, half], [-half, y, half]], m)


SPHERE_RES = dict(rings=32, segments=64)   # one shared unit-sphere geometry per scene


def beers_law_scene():
    b = GltfBuilder()
    checker_ground(b)
    area_light(b)
    r = 0.75
    for x, sigma, kind in [(-2.55, 0.4, "khr_volume"), (-0.85, 0.4, "nimbus_medium"),
                           (0.85, 0.8, "khr_volume"), (2.55, 0.8, "nimbus_medium")]:
        tag = f"{sigma:g}".replace(".", "p")        # no '.' in names: Mitsuba object keys reserve it
        name = f"sphere_{kind}_sigma_a_{tag}"
        if kind == "khr_volume":
            # Beer's law from KHR_materials_volume: sigma_a = -ln(attenuationColor) / attenuationDistance
            c = math.exp(-sigma)
            mat = b.dielectric(f"beer_khr_sigma_a_{tag}", ior=1.0, extensions={"KHR_materials_volume": {
                "thicknessFactor": 2 * r, "attenuationDistance": 1.0, "attenuationColor": [c, c, c]}})
        else:
            mat = b.medium_boundary(f"beer_nimbus_sigma_a_{tag}", {"sigma_a": [sigma] * 3, "sigma_s": [0.0] * 3,
                                                              "anisotropy": 0.0})
        b.sphere_instance(name, [x, r, 0.0], r, mat, **SPHERE_RES)
    b.camera("camera", eye=[0.0, 2.2, 7.5], target=[0.0, 0.6, 0.0], yfov_deg=30, aspect=2.0)
    out = os.path.join(ASSETS, "thesis_beers_law.gltf")
    written(out, b.write(out, GENERATOR, scene_extras={"nimbus_environment": {"color": [0.2, 0.2, 0.2]},
                                                       "max_bounces": 16}))


def noise_spheres_scene():
    b = GltfBuilder()
    checker_ground(b)
    area_light(b)
    r = 1.0
    for x, dmax in [(-1.3, 1.0), (1.3, 3.0)]:
        mat = b.medium_boundary(f"perlin_noise_max_density_{dmax:g}",
                                {"noise": {"scale": 2.0, "max_density": dmax, "seed": 7}})
        b.sphere_instance(f"sphere_noise_max_density_{dmax:g}", [x, r, 0.0], r, mat, **SPHERE_RES)
    b.camera("camera", eye=[0.0, 2.0, 6.5], target=[0.0, 0.9, 0.0], yfov_deg=30, aspect=1.5)
    out = os.path.join(ASSETS, "thesis_noise_spheres.gltf")
    written(out, b.write(out, GENERATOR, scene_extras={"nimbus_environment": {"color": [0.2, 0.2, 0.2]},
                                                       "max_bounces": 16}))


def mixed_scene():
    b = GltfBuilder()
    checker_ground(b)
    area_light(b)
    smoke = b.medium_boundary("scattering_medium", {"sigma_a": [0.1, 0.1, 0.1], "sigma_s": [1.5, 1.8, 2.2],
                                                    "anisotropy": 0.3})
    b.sphere_instance("sphere_scattering_medium", [-1.8, 0.7, 0.0], 0.7, smoke, **SPHERE_RES)
    b.sphere_instance("sphere_mirror", [-0.3, 0.6, -0.9], 0.6, b.mirror("mirror"), **SPHERE_RES)
    b.sphere_instance("sphere_glass", [0.9, 0.55, 0.3], 0.55, b.dielectric("glass", ior=1.5), **SPHERE_RES)
    b.sphere_instance("sphere_diffuse_red", [2.3, 0.45, -0.6], 0.45, b.lambert("red", [0.7, 0.1, 0.08]),
                      **SPHERE_RES)
    b.box("box_diffuse_blue", [-0.6, 0.0, 0.9], [0.0, 0.6, 1.5], b.lambert("blue", [0.1, 0.2, 0.6]))
    b.box("box_diffuse_white", [1.6, 0.0, -2.2], [2.6, 1.4, -1.4], b.lambert("white", [0.75, 0.75, 0.75]))
    b.camera("camera", eye=[0.0, 2.4, 7.0], target=[0.0, 0.6, 0.0], yfov_deg=32, aspect=1.5)
    out = os.path.join(ASSETS, "thesis_mixed.gltf")
    written(out, b.write(out, GENERATOR, scene_extras={"nimbus_environment": {"color": [0.2, 0.2, 0.2]},
                                                       "max_bounces": 32}))


# ----------------------------------------------------------------------------------------------- test scenes
def slab_scene():
    b = GltfBuilder()
    mat = b.medium_boundary("slab_medium", {"sigma_a": [0.2, 0.4, 0.8], "sigma_s": [1.0, 1.0, 1.0],
                                            "anisotropy": 0.0})
    b.box("slab", [-1.0, -1.0, -0.25], [1.0, 1.0, 0.25], mat)    # 2 x 2 m, 0.5 m thick along z
    b.camera("camera", eye=[0.0, 0.0, 3.0], target=[0.0, 0.0, 0.0], yfov_deg=45, aspect=1.0)
    out = os.path.join(TESTS, "slab_homogeneous.gltf")
    written(out, b.write(out, GENERATOR, scene_extras={"nimbus_environment": {"color": [1.0, 1.0, 1.0]},
                                                       "max_bounces": 64}))


def furnace_scene():
    b = GltfBuilder()
    mat = b.medium_boundary("furnace_medium", {"sigma_a": [0.0, 0.0, 0.0], "sigma_s": [2.0, 2.0, 2.0],
                                               "anisotropy": 0.0})
    b.sphere("furnace_sphere", [0.0, 0.0, 0.0], 1.0, mat, rings=24, segments=48)
    b.camera("camera", eye=[0.0, 0.0, 3.5], target=[0.0, 0.0, 0.0], yfov_deg=40, aspect=1.0)
    out = os.path.join(TESTS, "furnace_sphere.gltf")
    # every pixel should be 1: an albedo-1 medium behind an index-matched boundary in a uniform environment
    written(out, b.write(out, GENERATOR, scene_extras={"nimbus_environment": {"color": [1.0, 1.0, 1.0]},
                                                       "max_bounces": 256}))


def constant_grid_scenes():
    # constant_grid.vdb holds 1.0 at voxels i, j, k in [0, 15]; OpenVDB's BoxSampler puts values at voxel centres
    # (index i at world i * voxel), so the trilinear density is exactly 1 on [0, 15 voxel]^3 and falls linearly to 0
    # over the next voxel spacing outside it (towards the background-0 neighbours at i = -1 and i = 16). The box
    # medium therefore covers the voxel centres, [0, 15 voxel]^3 = [0, 0.9375] m^3 in VDB space, where the two agree
    # exactly. A renderer that also integrates the ramp shell sees extra optical depth: along an axis-aligned ray
    # through the grid, tau = density_scale * 16 voxel = 2.0 instead of the box's density_scale * 15 voxel = 1.875.
    # Both scenes shift VDB space by -7.5 voxel so that the box is centred on the origin.
    lo = -(CONST_N - 1) * CONST_VOXEL / 2         # -0.46875, exact in binary
    hi = lo + (CONST_N - 1) * CONST_VOXEL         # +0.46875
    env = {"nimbus_environment": {"color": [1.0, 1.0, 1.0]}, "max_bounces": 64}

    b = GltfBuilder()
    b.volume_node("constant_grid_volume", {"file": "constant_grid.vdb", "density_grid": "density",
                                           "density_scale": CONST_SCALE, "albedo": [CONST_ALBEDO] * 3,
                                           "anisotropy": 0.0}, translation=[lo, lo, lo])
    b.camera("camera", eye=[0.0, 0.0, 3.0], target=[0.0, 0.0, 0.0], yfov_deg=30, aspect=1.0)
    out = os.path.join(TESTS, "constant_grid.gltf")
    written(out, b.write(out, GENERATOR, scene_extras=env))

    b = GltfBuilder()
    st = CONST_SCALE   # sigma_t = density_scale * 1.0
    mat = b.medium_boundary("constant_box_medium", {"sigma_a": [round(st * (1 - CONST_ALBEDO), 12)] * 3,
                                                    "sigma_s": [st * CONST_ALBEDO] * 3, "anisotropy": 0.0})
    b.box("constant_box", [lo, lo, lo], [hi, hi, hi], mat)
    b.camera("camera", eye=[0.0, 0.0, 3.0], target=[0.0, 0.0, 0.0], yfov_deg=30, aspect=1.0)
    out = os.path.join(TESTS, "constant_box.gltf")
    written(out, b.write(out, GENERATOR, scene_extras=env))


def main():
    os.makedirs(TESTS, exist_ok=True)
    cloud_scene()
    cloud_mitsuba_check_scene()
    beers_law_scene()
    noise_spheres_scene()
    mixed_scene()
    slab_scene()
    furnace_scene()
    constant_grid_scenes()


if __name__ == "__main__":
    main()
