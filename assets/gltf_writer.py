"""A tiny glTF 2.0 writer shared by the asset scripts (make_demo.py, make_scenes.py). Pure Python, no dependencies.

    from gltf_writer import GltfBuilder
    b = GltfBuilder()
    white = b.lambert("white", [0.73, 0.73, 0.73])
    b.quad("floor", [[-1, 0, 1], [1, 0, 1], [1, 0, -1], [-1, 0, -1]], white)
    b.camera("camera", eye=[0, 1, 4], target=[0, 1, 0])
    b.write("scene.gltf")          # .gltf: one embedded data-URI buffer; .glb: binary container

Conventions (glTF's): metres, +Y up, right-handed; a camera and a directional light look down their node's -Z.
Geometry is float32 POSITION/NORMAL and uint32 indices, one bufferView per accessor, 4-byte aligned.
"""
import base64
import json
import math
import struct


# ----------------------------------------------------------------------------------------------- vector helpers
def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def normalize(v):
    ln = math.sqrt(sum(x * x for x in v))
    return [x / ln for x in v]


def quat_from_basis(x, y, z):
    """unit quaternion [x, y, z, w] of the rotation whose matrix has columns x, y, z (orthonormal, right-handed)"""
    m00, m01, m02 = x[0], y[0], z[0]
    m10, m11, m12 = x[1], y[1], z[1]
    m20, m21, m22 = x[2], y[2], z[2]
    tr = m00 + m11 + m22
    if tr > 0:
        s = 2 * math.sqrt(1 + tr)
        q = [(m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, s / 4]
    elif m00 > m11 and m00 > m22:
        s = 2 * math.sqrt(1 + m00 - m11 - m22)
        q = [s / 4, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s]
    elif m11 > m22:
        s = 2 * math.sqrt(1 + m11 - m00 - m22)
        q = [(m01 + m10) / s, s / 4, (m12 + m21) / s, (m02 - m20) / s]
    else:
        s = 2 * math.sqrt(1 + m22 - m00 - m11)
        q = [(m02 + m20) / s, (m12 + m21) / s, s / 4, (m10 - m01) / s]
    n = math.sqrt(sum(c * c for c in q))
    return [c / n + 0.0 for c in q]          # + 0.0: no "-0.0" in the JSON


def look_rotation(forward, up=(0.0, 1.0, 0.0)):
    """quaternion turning a node so that its -Z axis points along `forward` and its +Y is as close to `up` as can be"""
    f = normalize(forward)
    if abs(sum(f[i] * up[i] for i in range(3))) > 0.999 * math.sqrt(sum(u * u for u in up)):
        up = (0.0, 0.0, -1.0) if f[1] < 0 else (0.0, 0.0, 1.0)
    right = normalize(cross(f, up))
    true_up = cross(right, f)
    return quat_from_basis(right, true_up, [-c for c in f])


# ----------------------------------------------------------------------------------------------- the builder
class GltfBuilder:
    def __init__(self):
        self.buffer = bytearray()
        self.accessors, self.views, self.meshes, self.nodes, self.materials = [], [], [], [], []
        self.cameras, self.lights = [], []
        self.animation_channels, self.animation_samplers = [], []
        self._unit_spheres = {}      # (rings, segments) -> (POSITION, NORMAL, indices) accessor indices

    # ---- raw data
    def add_view(self, data, target):
        while len(self.buffer) % 4:
            self.buffer.append(0)
        view = {"buffer": 0, "byteOffset": len(self.buffer), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        self.views.append(view)
        self.buffer.extend(data)
        return len(self.views) - 1

    def add_accessor(self, values, comps, ctype, kind, target, minmax=False):
        fmt = {5126: "f", 5125: "I"}[ctype]
        flat = [c for v in values for c in (v if comps > 1 else (v,))]
        view = self.add_view(struct.pack("<%d%s" % (len(flat), fmt), *flat), target)
        acc = {"bufferView": view, "componentType": ctype, "count": len(values), "type": kind}
        if minmax:  # of the float64 inputs: each rounds to the float32 extremum actually stored
            acc["min"] = [min(v[i] for v in values) for i in range(comps)]
            acc["max"] = [max(v[i] for v in values) for i in range(comps)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def add_geometry(self, positions, normals, indices):
        p = self.add_accessor(positions, 3, 5126, "VEC3", 34962, minmax=True)
        n = self.add_accessor(normals, 3, 5126, "VEC3", 34962)
        i = self.add_accessor(indices, 1, 5125, "SCALAR", 34963)
        return p, n, i

    def animate(self, node, path, times, values, interpolation="LINEAR"):
        """a channel of the scene's one animation: `path` (translation, rotation, scale) of `node` keyed at `times`
        (seconds) to `values` (3- or 4-vectors)"""
        t = self.add_accessor(list(times), 1, 5126, "SCALAR", None)
        self.accessors[t]["min"], self.accessors[t]["max"] = [min(times)], [max(times)]
        comps = len(values[0])
        v = self.add_accessor(values, comps, 5126, {3: "VEC3", 4: "VEC4"}[comps], None)
        self.animation_samplers.append({"input": t, "output": v, "interpolation": interpolation})
        self.animation_channels.append({"sampler": len(self.animation_samplers) - 1,
                                        "target": {"node": node, "path": path}})

    def add_node(self, node):
        self.nodes.append(node)
        return len(self.nodes) - 1

    def mesh_from_accessors(self, name, geometry, material, **node_fields):
        """a mesh (one primitive over existing accessors) and a node instancing it; returns the node index"""
        p, n, i = geometry
        self.meshes.append({"name": name, "primitives": [{"attributes": {"POSITION": p, "NORMAL": n}, "indices": i,
                                                           "material": material}]})
        return self.add_node(dict({"name": name, "mesh": len(self.meshes) - 1}, **node_fields))

    def add_mesh(self, name, positions, normals, indices, material, **node_fields):
        return self.mesh_from_accessors(name, self.add_geometry(positions, normals, indices), material,
                                        **node_fields)

    # ---- materials
    def add_material(self, name, **kw):
        self.materials.append(dict(name=name, **kw))
        return len(self.materials) - 1

    def lambert(self, name, rgb):
        """Lambertian diffuse: metallic 0 and KHR_materials_specular.specularFactor 0"""
        return self.add_material(name, pbrMetallicRoughness={"baseColorFactor": list(rgb) + [1.0],
                                                             "metallicFactor": 0.0},
                                 extensions={"KHR_materials_specular": {"specularFactor": 0.0}})

    def emitter(self, name, rgb, strength):
        """black Lambertian surface emitting rgb * strength (W m^-2 sr^-1), front (CCW) side only"""
        return self.add_material(name, pbrMetallicRoughness={"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0},
                                 emissiveFactor=list(rgb),
                                 extensions={"KHR_materials_emissive_strength": {"emissiveStrength": strength},
                                             "KHR_materials_specular": {"specularFactor": 0.0}})

    def mirror(self, name, rgb=(1.0, 1.0, 1.0)):
        return self.add_material(name, pbrMetallicRoughness={"baseColorFactor": list(rgb) + [1.0],
                                                             "metallicFactor": 1.0, "roughnessFactor": 0.0})

    def dielectric(self, name, ior=1.5, **kw):
        """smooth transmissive boundary; ior 1.0 makes it index-matched (an invisible container for a medium)"""
        ext = {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": ior}}
        ext.update(kw.pop("extensions", {}))
        return self.add_material(name, pbrMetallicRoughness={"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0.0,
                                                             "roughnessFactor": 0.0},
                                 extensions=ext, **kw)

    def medium_boundary(self, name, nimbus_medium):
        """index-matched boundary (transmission 1, ior 1.0, roughness 0, metallic 0) with extras.nimbus_medium"""
        return self.dielectric(name, ior=1.0, extras={"nimbus_medium": nimbus_medium})

    # ---- shapes
    def quad(self, name, corners, material, **node_fields):
        """corners counter-clockwise seen from the front."""
        a, b, c, d = corners
        n = normalize(cross(sub(b, a), sub(d, a)))
        return self.add_mesh(name, [a, b, c, d], [n] * 4, [0, 1, 2, 0, 2, 3], material, **node_fields)

    def cornell_walls(self, white, red, green):
        """the five walls of a Cornell box spanning [-1, 1] in x and z and [0, 2] in y, open toward +z: white floor,
        ceiling and back, red left and green right, each facing into the box"""
        s = 1.0
        self.quad("floor", [[-s, 0, s], [s, 0, s], [s, 0, -s], [-s, 0, -s]], white)
        self.quad("ceiling", [[-s, 2, -s], [s, 2, -s], [s, 2, s], [-s, 2, s]], white)
        self.quad("back", [[-s, 0, -s], [s, 0, -s], [s, 2, -s], [-s, 2, -s]], white)
        self.quad("left", [[-s, 0, s], [-s, 0, -s], [-s, 2, -s], [-s, 2, s]], red)
        self.quad("right", [[s, 0, -s], [s, 0, s], [s, 2, s], [s, 2, -s]], green)

    def quads(self, name, quad_list, material, **node_fields):
        """many quads (each: corners counter-clockwise seen from the front) in one mesh, flat normals"""
        pos, nor, idx = [], [], []
        for a, b, c, d in quad_list:
            n = normalize(cross(sub(b, a), sub(d, a)))
            k = len(pos)
            pos += [a, b, c, d]
            nor += [n] * 4
            idx += [k, k + 1, k + 2, k, k + 2, k + 3]
        return self.add_mesh(name, pos, nor, idx, material, **node_fields)

    def box(self, name, lo, hi, material, **node_fields):
        """closed axis-aligned box [lo, hi], 6 faces x 4 vertices with flat outward normals, CCW seen from outside"""
        x0, y0, z0 = lo
        x1, y1, z1 = hi
        faces = [  # (normal, corners CCW seen from outside)
            ([1, 0, 0], [[x1, y0, z1], [x1, y0, z0], [x1, y1, z0], [x1, y1, z1]]),
            ([-1, 0, 0], [[x0, y0, z0], [x0, y0, z1], [x0, y1, z1], [x0, y1, z0]]),
            ([0, 1, 0], [[x0, y1, z1], [x1, y1, z1], [x1, y1, z0], [x0, y1, z0]]),
            ([0, -1, 0], [[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]]),
            ([0, 0, 1], [[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]]),
            ([0, 0, -1], [[x1, y0, z0], [x0, y0, z0], [x0, y1, z0], [x1, y1, z0]]),
        ]
        pos, nor, idx = [], [], []
        for n, cs in faces:
            k = len(pos)
            assert normalize(cross(sub(cs[1], cs[0]), sub(cs[3], cs[0]))) == [float(c) for c in n]
            pos += cs
            nor += [n] * 4
            idx += [k, k + 1, k + 2, k, k + 2, k + 3]
        return self.add_mesh(name, pos, nor, idx, material, **node_fields)

    @staticmethod
    def sphere_geometry(center, radius, rings, segments):
        pos, nor, idx = [], [], []
        for r in range(rings + 1):
            theta = math.pi * r / rings
            for s in range(segments + 1):
                phi = 2 * math.pi * s / segments
                n = [math.sin(theta) * math.sin(phi), math.cos(theta), math.sin(theta) * math.cos(phi)]
                nor.append(n)
                pos.append([center[i] + radius * n[i] for i in range(3)])
        for r in range(rings):
            for s in range(segments):
                a = r * (segments + 1) + s
                b = a + segments + 1
                idx += [a, b, a + 1, a + 1, b, b + 1]
        return pos, nor, idx

    def sphere(self, name, center, radius, material, rings=48, segments=96):
        """a UV sphere with its own vertex data (make_demo.py's layout)"""
        return self.add_mesh(name, *self.sphere_geometry(center, radius, rings, segments), material)

    def sphere_instance(self, name, center, radius, material, rings=48, segments=96):
        """a UV sphere as a node (translation + uniform scale) over one shared unit-sphere geometry: a scene with
        many spheres stores the vertices once"""
        key = (rings, segments)
        if key not in self._unit_spheres:
            self._unit_spheres[key] = self.add_geometry(*self.sphere_geometry([0, 0, 0], 1.0, rings, segments))
        return self.mesh_from_accessors(name, self._unit_spheres[key], material, translation=list(center),
                                        scale=[radius] * 3)

    # ---- camera, lights, volumes
    def camera(self, name, eye, target=None, yfov_deg=38.0, aspect=1.0, znear=0.01, up=(0.0, 1.0, 0.0)):
        """perspective camera at eye; looking at target (None: down -Z, no rotation written)"""
        self.cameras.append({"type": "perspective", "perspective": {"yfov": math.radians(yfov_deg),
                                                                    "aspectRatio": aspect, "znear": znear}})
        node = {"name": name, "camera": len(self.cameras) - 1, "translation": list(eye)}
        if target is not None:
            node["rotation"] = look_rotation(sub(target, eye), up)
        return self.add_node(node)

    def directional_light(self, name, direction, color, intensity):
        """KHR_lights_punctual directional light shining along `direction`; intensity in lux (glTF's photometric unit: W/m^2 = lx / 683)"""
        self.lights.append({"name": name, "type": "directional", "color": list(color), "intensity": intensity})
        return self.add_node({"name": name, "rotation": look_rotation(direction),
                              "extensions": {"KHR_lights_punctual": {"light": len(self.lights) - 1}}})

    def volume_node(self, name, nimbus_volume, **node_fields):
        """a node without a mesh carrying extras.nimbus_volume (an OpenVDB grid placed by the node's transform)"""
        return self.add_node(dict({"name": name}, **node_fields, extras={"nimbus_volume": nimbus_volume}))

    # ---- output
    def extensions_in_use(self):
        used = []

        def note(d):
            for k in d.get("extensions", {}):
                if k not in used:
                    used.append(k)
        for m in self.materials:
            note(m)
        for n in self.nodes:
            note(n)
        return used

    def to_gltf(self, generator, extensions_used=None, scene_extras=None):
        while len(self.buffer) % 4:
            self.buffer.append(0)
        gltf = {
            "asset": {"version": "2.0", "generator": generator},
        }
        used = extensions_used if extensions_used is not None else self.extensions_in_use()
        if used:                                   # the schema wants at least one item when present
            gltf["extensionsUsed"] = used
        if self.lights:
            gltf["extensions"] = {"KHR_lights_punctual": {"lights": self.lights}}
        scene = {"nodes": list(range(len(self.nodes)))}
        if scene_extras:
            scene["extras"] = scene_extras
        gltf.update({
            "scene": 0,
            "scenes": [scene],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "materials": self.materials,
            "cameras": self.cameras,
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": [{"byteLength": len(self.buffer)}],
        })
        if self.animation_channels:
            gltf["animations"] = [{"name": "shot", "channels": self.animation_channels,
                                   "samplers": self.animation_samplers}]
        for k in ("meshes", "materials", "cameras", "accessors", "bufferViews"):
            if not gltf[k]:
                del gltf[k]
        if not self.buffer:
            del gltf["buffers"]
        return gltf

    def write(self, path, generator, extensions_used=None, scene_extras=None):
        """writes .glb (binary chunk) or .gltf (compact JSON, the buffer as a base64 data URI); returns bytes written"""
        gltf = self.to_gltf(generator, extensions_used, scene_extras)
        if path.endswith(".glb"):
            js = json.dumps(gltf, separators=(",", ":")).encode()
            while len(js) % 4:
                js += b" "
            total = 12 + 8 + len(js) + (8 + len(self.buffer) if self.buffer else 0)
            with open(path, "wb") as f:
                f.write(struct.pack("<III", 0x46546C67, 2, total))
                f.write(struct.pack("<II", len(js), 0x4E4F534A) + js)
                if self.buffer:
                    f.write(struct.pack("<II", len(self.buffer), 0x004E4942) + bytes(self.buffer))
            return total
        if self.buffer:
            gltf["buffers"][0]["uri"] = "data:application/octet-stream;base64," + \
                base64.b64encode(bytes(self.buffer)).decode()
        data = (json.dumps(gltf, separators=(",", ":")) + "\n").encode()
        with open(path, "wb") as f:
            f.write(data)
        return len(data)
