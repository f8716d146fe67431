#!/usr/bin/python3
"""Writes the VDB files of Nimbus's shots and motion-blur tests (deterministic: same bytes every run).

  tests/scenes/pyro_box.vdb   the closed-form fixture of velocity blur and pyro channels, voxel 0.0625 m:
                                density  FloatGrid, 1.0 on voxels [0, 15]^3 (a 1 m box at the origin)
                                vel      Vec3SGrid, no voxels, background (2, 0, 0): 2 m/s along +x everywhere
                                v.x v.y v.z  the same velocity as three FloatGrids (backgrounds 2, 0, 0)
                                flame    FloatGrid, 1.0 on voxels [-2, 17]^3 (covers every lookup of density)
                                albedo   FloatGrid, no voxels, background 0 (an albedo factor of 0)
                                rgb_density  Vec3SGrid, (1, 2, 4) on voxels [0, 15]^3: an RGB extinction
                                rgb_strong   Vec3SGrid, (1, 10, 100) on voxels [0, 15]^3: a strongly
                                             chromatic one
                                Cd       Vec3SGrid on voxels [-2, 17]^3: ((i + 2) / 19, 0.5, 0.25) at index
                                         (i, j, k), a red ramp along x; background (1, 1, 1)
  assets/shot/shot.gltf       the animated shot over that sequence (frames 1..24 at 24 fps): the camera dollies
                              in, a red box crosses in front of the cloud, spinning, and a sun lights it
  assets/shot/cloud.NNNN.vdb  with --sequence: the bundled cloud (assets/cloud.vdb) advected over frames
                              1..24 at 24 fps by a wind of 0.4 m/s along +x and a swirl of 0.6 rad/s about the
                              vertical axis through its centre; each frame holds density, temperature and its
                              velocity grid `vel` (m/s, at the active voxels). Not committed: about 12 MB.

Advection is exact for this rigid flow: frame f's value at x is frame 1's at the point the flow carries to x
in (f - 1)/24 s (rotate back by the swirl, move back by the wind), read by trilinear interpolation of the
cloud's voxels, so there is no numerical diffusion to hide a renderer's error.

Needs Debian's OpenVDB Python bindings and numpy:  apt-get install -y python3-openvdb python3-numpy
Run from the repository root:  /usr/bin/python3 assets/make_shot.py [--sequence]
"""
import os
import sys

import numpy as np
import pyopenvdb as vdb

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltf_writer import GltfBuilder, look_rotation  # noqa: E402
from make_cloud import write_vdb  # noqa: E402  (header UUID made deterministic)

BOX_VOXEL = 0.0625
FPS = 24.0
FRAMES = range(1, 25)
WIND = np.array([0.4, 0.0, 0.0])   # m/s
SWIRL = 0.6                        # rad/s about +y


def float_grid(name, background, voxel):
    g = vdb.FloatGrid(background)
    g.name = name
    g.transform = vdb.createLinearTransform(voxelSize=voxel)
    return g


def vec3_grid(name, background, voxel):
    g = vdb.Vec3SGrid(background)
    g.name = name
    g.transform = vdb.createLinearTransform(voxelSize=voxel)
    return g


def fill(grid, lo, hi, value):
    """Sets voxels lo..hi (inclusive) on, one by one (no tiles: the plainest layout)."""
    acc = grid.getAccessor()
    for i in range(lo, hi + 1):
        for j in range(lo, hi + 1):
            for k in range(lo, hi + 1):
                acc.setValueOn((i, j, k), value)


def pyro_box(root):
    density = float_grid("density", 0.0, BOX_VOXEL)
    density.gridClass = vdb.GridClass.FOG_VOLUME
    fill(density, 0, 15, 1.0)
    vel = vec3_grid("vel", (2.0, 0.0, 0.0), BOX_VOXEL)
    parts = [float_grid(f"v.{axis}", value, BOX_VOXEL) for axis, value in zip("xyz", (2.0, 0.0, 0.0))]
    flame = float_grid("flame", 0.0, BOX_VOXEL)
    fill(flame, -2, 17, 1.0)
    albedo = float_grid("albedo", 0.0, BOX_VOXEL)
    cd = vec3_grid("Cd", (1.0, 1.0, 1.0), BOX_VOXEL)
    acc = cd.getAccessor()
    for i in range(-2, 18):
        for j in range(-2, 18):
            for k in range(-2, 18):
                acc.setValueOn((i, j, k), ((i + 2) / 19.0, 0.5, 0.25))
    rgb = vec3_grid("rgb_density", (0.0, 0.0, 0.0), BOX_VOXEL)
    rgb.gridClass = vdb.GridClass.FOG_VOLUME
    fill(rgb, 0, 15, (1.0, 2.0, 4.0))
    strong = vec3_grid("rgb_strong", (0.0, 0.0, 0.0), BOX_VOXEL)
    strong.gridClass = vdb.GridClass.FOG_VOLUME
    fill(strong, 0, 15, (1.0, 10.0, 100.0))
    out = os.path.join(root, "tests", "scenes", "pyro_box.vdb")
    write_vdb(out, [density, vel, *parts, flame, albedo, cd, rgb, strong],
              {"creator": "nimbus assets/make_shot.py"})
    print("wrote", out, os.path.getsize(out), "bytes")


def trilinear(arr, p):
    """Trilinear interpolation of arr (indexed [x, y, z], zero outside) at continuous index points p (N x 3)."""
    f = np.floor(p)
    i = f.astype(np.int64)
    t = p - f
    out = np.zeros(len(p))
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                w = (t[:, 0] if dx else 1 - t[:, 0]) * (t[:, 1] if dy else 1 - t[:, 1]) * \
                    (t[:, 2] if dz else 1 - t[:, 2])
                q = i + np.array([dx, dy, dz])
                ok = np.all((q >= 0) & (q < np.array(arr.shape)), axis=1)
                v = np.zeros(len(p))
                v[ok] = arr[q[ok, 0], q[ok, 1], q[ok, 2]]
                out += w * v
    return out


def sequence(root):
    grids = {g.name: g for g in vdb.readAll(os.path.join(root, "assets", "cloud.vdb"))[0]}
    voxel = grids["density"].transform.voxelSize()[0]
    lo, hi = grids["density"].evalActiveVoxelBoundingBox()
    shape = tuple(h - l + 1 for l, h in zip(lo, hi))
    frame1 = {}
    for name in ("density", "temperature"):
        a = np.zeros(shape, np.float32)
        grids[name].copyToArray(a, ijk=lo)
        frame1[name] = a
    centre = (np.array(lo) + np.array(shape) / 2.0) * voxel          # metres, swirl axis through it
    # Output domain: the cloud's box grown by the wind's travel and the swirl's reach.
    pad = int(np.ceil((np.linalg.norm(WIND) * len(FRAMES) / FPS) / voxel)) + max(shape) // 3
    out_lo = np.array(lo) - pad
    out_shape = np.array(shape) + 2 * pad
    idx = np.stack(np.meshgrid(*(np.arange(n) for n in out_shape), indexing="ij"), -1).reshape(-1, 3)
    world = (idx + out_lo) * voxel
    os.makedirs(os.path.join(root, "assets", "shot"), exist_ok=True)
    for frame in FRAMES:
        t = (frame - 1) / FPS
        # Back along the flow: undo the wind, then the swirl (rotation by -SWIRL t about +y through centre + wind t).
        c = centre + WIND * t
        r = world - c
        a = -SWIRL * t
        rot = np.stack([np.cos(a) * r[:, 0] + np.sin(a) * r[:, 2], r[:, 1],
                        -np.sin(a) * r[:, 0] + np.cos(a) * r[:, 2]], -1)
        source = (rot + centre) / voxel - np.array(lo)
        vel = WIND + SWIRL * np.stack([r[:, 2], np.zeros(len(r)), -r[:, 0]], -1)   # omega x r, omega = +y
        out = []
        rho = trilinear(frame1["density"], source).reshape(tuple(out_shape))
        active = rho > 1e-3
        for name in ("density", "temperature"):
            v = trilinear(frame1[name], source).reshape(tuple(out_shape)) * active
            g = float_grid(name, 0.0, voxel)
            g.copyFromArray(np.ascontiguousarray(v, np.float32), ijk=tuple(int(x) for x in out_lo), tolerance=0)
            g.prune()
            out.append(g)
        v = vel.reshape(tuple(out_shape) + (3,)) * active[..., None]
        g = vec3_grid("vel", (0.0, 0.0, 0.0), voxel)
        g.copyFromArray(np.ascontiguousarray(v, np.float32), ijk=tuple(int(x) for x in out_lo),
                        tolerance=(0.0, 0.0, 0.0))
        g.prune((0.0, 0.0, 0.0))
        out.append(g)
        path = os.path.join(root, "assets", "shot", f"cloud.{frame:04d}.vdb")
        write_vdb(path, out, {"creator": "nimbus assets/make_shot.py", "frame": frame})
        print("wrote", path, os.path.getsize(path), "bytes")


def shot_scene(root):
    b = GltfBuilder()
    ground = b.lambert("ground", [0.3, 0.3, 0.28])
    b.quad("ground", [[-40, 0, 40], [40, 0, 40], [40, 0, -40], [-40, 0, -40]], ground)
    b.volume_node("smoke", {"file": "cloud.####.vdb", "missing_frame": "hold", "density_scale": 30.0,
                            "albedo": [0.95, 0.95, 0.95], "anisotropy": 0.5}, translation=[0.0, 0.5, 0.0])
    red = b.lambert("red", [0.8, 0.1, 0.08])
    box = b.box("box", [-0.15, -0.15, -0.15], [0.15, 0.15, 0.15], red, translation=[-1.6, 0.6, 0.9])
    seconds = [k / 4 for k in range(5)]
    b.animate(box, "translation", seconds, [[-1.6 + 3.2 * s, 0.6, 0.9] for s in seconds])
    b.animate(box, "rotation", seconds, [[0.0, np.sin(np.pi / 4 * k), 0.0, np.cos(np.pi / 4 * k)]
                                         for k in range(5)])
    target = [0.0, 0.85, 0.0]
    eyes = [[0.4, 1.1, 3.1], [-0.5, 1.0, 2.5]]
    cam = b.camera("camera", eye=eyes[0], target=target, yfov_deg=40.0, aspect=16 / 9)
    b.animate(cam, "translation", [0.0, 1.0], eyes)
    b.animate(cam, "rotation", [0.0, 1.0], [look_rotation([t - e for t, e in zip(target, eye)]) for eye in eyes])
    b.directional_light("sun", [-0.5, -0.6, -0.6], [1.0, 0.9, 0.75], 2049.0)
    out = os.path.join(root, "assets", "shot", "shot.gltf")
    os.makedirs(os.path.dirname(out), exist_ok=True)
    b.write(out, "nimbus assets/make_shot.py",
            scene_extras={"nimbus_environment": {"color": [0.35, 0.5, 0.8]}, "max_bounces": 64})
    print("wrote", out)


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    pyro_box(root)
    shot_scene(root)
    if "--sequence" in sys.argv[1:]:
        sequence(root)
    return 0


if __name__ == "__main__":
    sys.exit(main())
