#!/usr/bin/env python3
"""Renders the bundled demo (assets/cloud.gltf) with Cycles 5.0 and its Open Image Denoise, for the equal-time
comparison of docs/denoising.md: the scene is built here in Blender's coordinates from the glTF's values (Blender
is Z-up: a glTF point (x, y, z) is (x, -z, y)), not imported, so that every parameter is the one Nimbus renders:

- ground: an 80 m square at y = 0, Diffuse BSDF (0.3, 0.3, 0.28);
- cloud: assets/cloud.vdb at glTF (0, 1, 0), Principled Volume with density 30 x the `density` grid, colour
  (scattering albedo) 0.95, anisotropy 0.5, absorption colour black (so sigma_t = 30 density);
- sun: a directional light of irradiance 2049 lx / 683 lm/W = 3.0 W/m^2, colour (1, 0.9, 0.75), angle 0;
- world: constant (0.35, 0.5, 0.8); camera: the glTF camera (yfov 0.5585 rad) at 128x72, box pixel filter;
- 64 bounces of every kind, no clamping, no light-tree-independent tricks: Cycles' defaults otherwise.

Usage (Python 3.11 with PyPI's bpy==5.0.1):
    python3 scripts/cycles_denoise_compare.py OUT.exr --spp N [--denoise] [--threads 2] [--seed S]
Prints the render time in seconds (Cycles' own, excluding scene set-up) as `seconds S`.
"""
import argparse, math, os, time

import bpy
from mathutils import Matrix, Quaternion, Vector

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GLTF_TO_BLENDER = Matrix(((1, 0, 0, 0), (0, 0, -1, 0), (0, 1, 0, 0), (0, 0, 0, 1)))


def gltf_matrix(translation=(0, 0, 0), rotation=(0, 0, 0, 1)):
    """A glTF node's matrix (translation, quaternion x, y, z, w) in Blender's world."""
    x, y, z, w = rotation
    m = Matrix.Translation(Vector(translation)) @ Quaternion((w, x, y, z)).to_matrix().to_4x4()
    return GLTF_TO_BLENDER @ m


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--spp", type=int, required=True)
    ap.add_argument("--denoise", action="store_true")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = args.spp
    cycles.use_adaptive_sampling = False
    cycles.seed = args.seed
    cycles.max_bounces = cycles.diffuse_bounces = cycles.glossy_bounces = 64
    cycles.transmission_bounces = cycles.volume_bounces = cycles.transparent_max_bounces = 64
    cycles.sample_clamp_direct = cycles.sample_clamp_indirect = 0.0
    cycles.pixel_filter_type = "BOX"
    cycles.filter_width = 1.0
    cycles.use_denoising = args.denoise
    if args.denoise:
        cycles.denoiser = "OPENIMAGEDENOISE"
        cycles.denoising_input_passes = "RGB_ALBEDO_NORMAL"
        cycles.denoising_prefilter = "ACCURATE"
    scene.render.threads_mode = "FIXED"
    scene.render.threads = args.threads
    scene.render.resolution_x, scene.render.resolution_y = 128, 72
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"

    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.35, 0.5, 0.8, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    scene.world = world

    bpy.ops.mesh.primitive_plane_add(size=80.0)
    ground = bpy.context.object
    ground_mat = bpy.data.materials.new("ground")
    ground_mat.use_nodes = True
    nodes = ground_mat.node_tree.nodes
    nodes.clear()
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.3, 0.3, 0.28, 1.0)
    output = nodes.new("ShaderNodeOutputMaterial")
    ground_mat.node_tree.links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])
    ground.data.materials.append(ground_mat)

    bpy.ops.object.volume_import(filepath=os.path.join(ROOT, "assets", "cloud.vdb"))
    cloud = bpy.context.object
    cloud.matrix_world = gltf_matrix(translation=(0.0, 1.0, 0.0))
    cloud_mat = bpy.data.materials.new("cloud")
    cloud_mat.use_nodes = True
    nodes = cloud_mat.node_tree.nodes
    nodes.clear()
    volume = nodes.new("ShaderNodeVolumePrincipled")
    volume.inputs["Color"].default_value = (0.95, 0.95, 0.95, 1.0)
    volume.inputs["Density"].default_value = 30.0
    volume.inputs["Density Attribute"].default_value = "density"
    volume.inputs["Anisotropy"].default_value = 0.5
    volume.inputs["Absorption Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    output = nodes.new("ShaderNodeOutputMaterial")
    cloud_mat.node_tree.links.new(volume.outputs["Volume"], output.inputs["Volume"])
    cloud.data.materials.append(cloud_mat)

    sun_data = bpy.data.lights.new("sun", type="SUN")
    sun_data.energy = 2049.0 / 683.0
    sun_data.color = (1.0, 0.9, 0.75)
    sun_data.angle = 0.0
    sun = bpy.data.objects.new("sun", sun_data)
    sun.matrix_world = gltf_matrix(rotation=(-0.4340928834740518, 0.4027244822399942, 0.22601287402018602,
                                             0.7734950165960007))
    scene.collection.objects.link(sun)

    cam_data = bpy.data.cameras.new("camera")
    cam_data.sensor_fit = "VERTICAL"
    cam_data.angle_y = 0.5585053606381855
    cam_data.clip_start = 0.01
    cam = bpy.data.objects.new("camera", cam_data)
    cam.matrix_world = gltf_matrix(translation=(0.4, 1.6, 4.2), rotation=(
        -0.047044795682958905, 0.05914453806908687, 0.0027904335008088325, 0.9971363619368319))
    scene.collection.objects.link(cam)
    scene.camera = cam

    scene.render.filepath = os.path.abspath(args.out)
    start = time.time()
    bpy.ops.render.render(write_still=True)
    print(f"seconds {time.time() - start:.3f}")


if __name__ == "__main__":
    main()
