#!/usr/bin/env python3
"""Render a Nimbus-convention glTF scene with Cycles 5.0 (`pip install bpy==5.0.1`, Python 3.11) for the peer
benchmark (issue 15).

    python3 benches/peers/cycles_render.py SCENE.gltf OUT.exr --spp N --res W [--threads T] [--seed S] [--guiding]

The scene is imported with Blender's own glTF importer; then every convention is set to match Nimbus and
`../shared/tools/gltf2mitsuba.py`:
- materials: Lambert (metallic 0, KHR_materials_specular 0) -> Diffuse BSDF of the base colour (factor x texture);
  metal (metallic 1) -> Glossy (GGX, single scattering, the glTF roughness: alpha = roughness^2; roughness 0 is the
  mirror), exactly the glTF metal for base colour 1 (the Glossy BSDF has no Fresnel term); transmission -> Glass
  (GGX, roughness 0) of the ior, or Transparent at ior 1;
  emission (factor x strength, x emissiveTexture) -> Emission, one-sided like glTF's;
- media: material extras `nimbus_medium` -> Volume Scatter (sigma_s, g) + Volume Absorption (sigma_a); node extras
  `nimbus_volume` -> a Blender volume object of the VDB under that node, with Volume Scatter + Absorption of
  density_scale x grid and the albedo;
- lights: KHR_lights_punctual at photometric / 683 (or radiometric by scene extras), point and spot as Blender watts
  (4 pi x W/sr), sun in W/m^2, all with zero size; scene extras `nimbus_environment` -> the world;
- render: CPU, `--spp` samples without adaptive sampling, denoising or clamping, a 1-pixel box filter, max bounces
  from scene extras `max_bounces`;
- `--guiding` (issue 34): Cycles' path guiding (Intel Open PGL) on, surface and volume guiding both, every other
  guiding setting at Blender's default (training samples 128, parallax-aware von Mises-Fisher mixtures, RIS
  directional sampling, deterministic guiding). Guiding trains on the render's own first samples, which count
  toward the image, so the time includes the training, as Nimbus's does.

Prints one `RESULT {json}` line; `render_s` is the `bpy.ops.render.render` call alone (Cycles' scene sync and BVH
build included, the glTF import not), `render_cpu_s` the CPU time of all the process's threads during that call.
"""
import argparse
import json
import math
import os
import sys
import time


def material_settings(g):
    return {m.get("name"): m for m in g.get("materials", [])}


def set_diffuse_like(mat, gm, nt):
    """rebuild a node tree as Nimbus reads the glTF material"""
    import bpy  # noqa: F401
    pbr = gm.get("pbrMetallicRoughness", {})
    ext = gm.get("extensions", {})
    base = pbr.get("baseColorFactor", [1, 1, 1, 1])[:3]
    metallic = pbr.get("metallicFactor", 1.0)
    rough = pbr.get("roughnessFactor", 1.0)
    trans = ext.get("KHR_materials_transmission", {}).get("transmissionFactor", 0.0)
    ior = ext.get("KHR_materials_ior", {}).get("ior", 1.5)
    principled = next((n for n in nt.nodes if n.type == "BSDF_PRINCIPLED"), None)
    # the importer's image nodes (base colour and emission) are reused through the Principled inputs they feed
    base_link = emission_link = None
    if principled is not None:
        for link in nt.links:
            if link.to_node == principled and link.to_socket.name == "Base Color":
                base_link = link.from_socket
            if link.to_node == principled and link.to_socket.name == "Emission Color":
                emission_link = link.from_socket
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    if trans > 0:
        if abs(ior - 1.0) < 1e-6:
            surf = nt.nodes.new("ShaderNodeBsdfTransparent")
        else:
            surf = nt.nodes.new("ShaderNodeBsdfGlass")
            surf.distribution = "GGX"   # Blender 4+ has no "SHARP"; GGX at roughness 0 is the smooth interface
            surf.inputs["IOR"].default_value = ior
            surf.inputs["Roughness"].default_value = 0.0
    elif metallic >= 1:
        # single-scattering GGX of alpha = roughness^2 (Blender squares its roughness input); at roughness 0 the
        # perfect mirror. The Glossy BSDF has no Fresnel term: the glTF metal's only for base colour 1.
        surf = nt.nodes.new("ShaderNodeBsdfGlossy")
        surf.distribution = "GGX"
        surf.inputs["Roughness"].default_value = max(rough, 0.0)
        surf.inputs["Color"].default_value = list(base) + [1]
    else:
        surf = nt.nodes.new("ShaderNodeBsdfDiffuse")
        surf.inputs["Color"].default_value = list(base) + [1]
        if base_link is not None:
            nt.links.new(base_link, surf.inputs["Color"])
    strength = ext.get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
    emissive = [c * strength for c in gm.get("emissiveFactor", [0, 0, 0])]
    shader = surf
    if max(emissive) > 0:
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Color"].default_value = list(emissive) + [1]
        em.inputs["Strength"].default_value = 1.0
        if emission_link is not None:
            em.inputs["Strength"].default_value = strength
            nt.links.new(emission_link, em.inputs["Color"])
        # glTF emission leaves the front face only: mix with nothing on back faces
        geo = nt.nodes.new("ShaderNodeNewGeometry")
        mix = nt.nodes.new("ShaderNodeMixShader")
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(surf.outputs[0], add.inputs[0])
        nt.links.new(em.outputs[0], add.inputs[1])
        nt.links.new(geo.outputs["Backfacing"], mix.inputs[0])
        nt.links.new(add.outputs[0], mix.inputs[1])
        nt.links.new(surf.outputs[0], mix.inputs[2])
        shader = mix
    nt.links.new(shader.outputs[0], out.inputs["Surface"])
    medium = gm.get("extras", {}).get("nimbus_medium")
    if medium is not None:
        vol = volume_shader(nt, medium.get("sigma_s", [0, 0, 0]), medium.get("sigma_a", [0, 0, 0]),
                            medium.get("anisotropy", 0.0), None)
        nt.links.new(vol.outputs[0], out.inputs["Volume"])
    if principled is not None:
        nt.nodes.remove(principled)


def volume_shader(nt, sigma_s, sigma_a, g, density_socket):
    """Volume Scatter (coefficient = density x colour) + Volume Absorption (density x (1 - colour))"""
    scatter = nt.nodes.new("ShaderNodeVolumeScatter")
    absorb = nt.nodes.new("ShaderNodeVolumeAbsorption")
    s_max, a_max = max(sigma_s), max(sigma_a)
    scatter.inputs["Color"].default_value = [c / s_max if s_max > 0 else 0 for c in sigma_s] + [1]
    scatter.inputs["Density"].default_value = s_max
    scatter.inputs["Anisotropy"].default_value = g
    absorb.inputs["Color"].default_value = [1 - c / a_max if a_max > 0 else 1 for c in sigma_a] + [1]
    absorb.inputs["Density"].default_value = a_max
    if density_socket is not None:
        for node, k in ((scatter, s_max), (absorb, a_max)):
            scale = nt.nodes.new("ShaderNodeMath")
            scale.operation = "MULTIPLY"
            scale.inputs[1].default_value = k
            nt.links.new(density_socket, scale.inputs[0])
            nt.links.new(scale.outputs[0], node.inputs["Density"])
    add = nt.nodes.new("ShaderNodeAddShader")
    nt.links.new(scatter.outputs[0], add.inputs[0])
    nt.links.new(absorb.outputs[0], add.inputs[1])
    return add


def add_vdb_volume(bpy, mathutils, name, spec, parent, scene_dir):
    vol = bpy.data.volumes.new(name + "_vdb")
    vol.filepath = os.path.normpath(os.path.join(scene_dir, spec["file"]))
    vol.render.space = "WORLD"   # density per world metre, as in glTF (Blender's default scales it by the object)
    obj = bpy.data.objects.new(name + "_vdb", vol)
    bpy.context.scene.collection.objects.link(obj)
    obj.parent = parent
    obj.matrix_parent_inverse = mathutils.Matrix.Identity(4)
    # the parent empty is in Blender's Z-up frame (the importer converted it); the VDB's own index-to-world map is
    # in glTF's Y-up frame, so it is rotated into Blender's frame first: (x, y, z) -> (x, -z, y)
    obj.matrix_basis = mathutils.Matrix.Rotation(math.pi / 2, 4, "X")
    mat = bpy.data.materials.new(name + "_medium")
    mat.use_nodes = True
    nt = mat.node_tree
    for n in list(nt.nodes):
        if n.type != "OUTPUT_MATERIAL":
            nt.nodes.remove(n)
    out = nt.nodes[0]
    attr = nt.nodes.new("ShaderNodeAttribute")
    attr.attribute_name = spec.get("density_grid", "density")
    albedo = spec.get("albedo", [1, 1, 1])
    scale = spec.get("density_scale", 1.0)
    vol_shader = volume_shader(nt, [scale * a for a in albedo], [scale * (1 - a) for a in albedo],
                               spec.get("anisotropy", 0.0), attr.outputs["Fac"])
    # volume_shader normalised the coefficients by their maxima; keep the per-channel split exact
    nt.links.new(vol_shader.outputs[0], out.inputs["Volume"])
    vol.materials.append(mat)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--guiding", action="store_true", help="path guiding on (surface and volume)")
    a = ap.parse_args()
    t0 = time.perf_counter()
    import bpy
    import mathutils
    scene_path = os.path.abspath(a.scene)
    scene_dir = os.path.dirname(scene_path)
    g = json.load(open(scene_path))
    extras = g["scenes"][g.get("scene", 0)].get("extras", {})
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=scene_path, export_import_convert_lighting_mode="RAW")
    sc = bpy.context.scene
    by_name = material_settings(g)
    for mat in bpy.data.materials:
        gm = by_name.get(mat.name)
        if gm is not None and mat.use_nodes:
            set_diffuse_like(mat, gm, mat.node_tree)
    # lights: glTF photometric / 683 unless radiometric; Blender point/spot watts = 4 pi x W/sr
    radiometric = extras.get("nimbus_light_units", "photometric") == "radiometric"
    lights = g.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    for node in g["nodes"]:
        ext = node.get("extensions", {}).get("KHR_lights_punctual")
        if ext is None:
            continue
        gl = lights[ext["light"]]
        value = gl.get("intensity", 1.0) / (1.0 if radiometric else 683.0)
        obj = next(o for o in bpy.data.objects if o.type == "LIGHT" and o.data.name == gl.get("name", o.data.name)
                   and (o.name == node.get("name") or o.name.startswith(node.get("name", "\0"))))
        light = obj.data
        light.color = gl.get("color", [1, 1, 1])
        if gl["type"] == "directional":
            light.energy = value
            light.angle = 0.0
        else:
            light.energy = value * 4 * math.pi
            light.shadow_soft_size = 0.0
        if gl["type"] == "spot":
            spot = gl.get("spot", {})
            outer = spot.get("outerConeAngle", math.pi / 4)
            light.spot_size = 2 * outer
            light.spot_blend = 1.0 - spot.get("innerConeAngle", 0.0) / outer if outer > 0 else 0.0
    for i, node in enumerate(g["nodes"]):
        spec = node.get("extras", {}).get("nimbus_volume")
        if spec is not None:
            parent = bpy.data.objects[node.get("name", f"node{i}")]
            add_vdb_volume(bpy, mathutils, node.get("name", f"node{i}"), spec, parent, scene_dir)
    world = bpy.data.worlds.new("world")
    sc.world = world
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    env = extras.get("nimbus_environment", {})
    if "map" in env:
        wn = world.node_tree
        tex = wn.nodes.new("ShaderNodeTexEnvironment")
        tex.image = bpy.data.images.load(os.path.join(scene_dir, env["map"]))
        tex.interpolation = "Linear"
        mapping = wn.nodes.new("ShaderNodeMapping")
        coord = wn.nodes.new("ShaderNodeTexCoord")
        # Nimbus/Mitsuba lat-long: u = 0 looks down -Z (glTF) = +Y (Blender); Blender's u = 0 looks down -X
        mapping.inputs["Rotation"].default_value = (0.0, 0.0, -math.pi / 2)
        wn.links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
        wn.links.new(mapping.outputs[0], tex.inputs["Vector"])
        wn.links.new(tex.outputs["Color"], bg.inputs["Color"])
        bg.inputs["Strength"].default_value = env.get("intensity", 1.0)
    else:
        bg.inputs["Color"].default_value = list(env.get("color", [0, 0, 0])) + [1]
        bg.inputs["Strength"].default_value = 1.0
    sc.camera = next(o for o in bpy.data.objects if o.type == "CAMERA")
    sc.render.engine = "CYCLES"
    cy = sc.cycles
    cy.device = "CPU"
    cy.samples = a.spp
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.seed = a.seed
    cy.pixel_filter_type = "BOX"
    cy.filter_width = 1.0
    bounces = int(extras.get("max_bounces", 64))
    cy.max_bounces = bounces
    cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = cy.volume_bounces = bounces
    cy.transparent_max_bounces = 1024
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.blur_glossy = 0.0
    cy.caustics_reflective = cy.caustics_refractive = True
    cy.use_guiding = a.guiding
    cy.use_surface_guiding = cy.use_volume_guiding = a.guiding
    cam = next(n for n in g["nodes"] if "camera" in n)
    aspect = g["cameras"][cam["camera"]]["perspective"].get("aspectRatio", 1.0)
    sc.render.resolution_x = a.res
    sc.render.resolution_y = int(round(a.res / aspect))    # as gltf2mitsuba and Nimbus size the film
    sc.render.resolution_percentage = 100
    sc.render.threads_mode = "FIXED" if a.threads else "AUTO"
    if a.threads:
        sc.render.threads = a.threads
    sc.render.film_transparent = False
    sc.view_settings.view_transform = "Standard"
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.filepath = os.path.abspath(a.out)
    t1, c1 = time.perf_counter(), time.process_time()
    bpy.ops.render.render(write_still=True)
    t2, c2 = time.perf_counter(), time.process_time()
    print("RESULT " + json.dumps({"peer": f"cycles-{bpy.app.version_string}", "threads": a.threads, "spp": a.spp,
                                  "guiding": a.guiding, "load_s": t1 - t0, "render_s": t2 - t1,
                                  "render_cpu_s": c2 - c1}), flush=True)
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
