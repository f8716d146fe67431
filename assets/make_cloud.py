#!/usr/bin/python3
"""Writes Nimbus's procedural OpenVDB assets (deterministic: fixed seed, same file every run):

  assets/cloud.vdb               a small cumulus-like cloud, FloatGrid "density" in [0, 1] (fog volume) and
                                 FloatGrid "temperature" (Kelvin, a small hot core of ~1000-1500 K, for flame-like
                                 emission demos); voxel size 0.02 m, about 76 x 50 x 60 voxels, the cloud ~1.5 m wide
  tests/scenes/constant_grid.vdb FloatGrid "density", exactly 1.0 on the 16^3 active voxels i, j, k in [0, 15],
                                 background 0; voxel size 0.0625 m (world voxel centres 0 .. 0.9375 m)

Needs Debian's OpenVDB Python bindings and numpy (not pip's):
    apt-get install -y python3-openvdb python3-numpy
Run from the repository root with the system interpreter (the module is `pyopenvdb`):
    /usr/bin/python3 assets/make_cloud.py

The cloud: the signed distance to a smooth union of eight spheres (a flattened base, bulging towards the top),
scaled by 1.15 and displaced by 5-octave fBm of a value noise written here in numpy (lattice values from a seeded permutation table,
quintic-smoothed trilinear interpolation), turned into density with a soft ramp 0.12 m wide at the surface and a
gentle fBm modulation inside. The cloud's base sits at y = 0 of the VDB's own space, centred on x = z = 0; the glTF
node places it. Voxels below 1e-3 are inactive (the background is 0). Files are written by OpenVDB's default
writer (header UUID made deterministic): Blosc (LZ4, byte shuffle) if the library has Blosc, else zip, with active-mask compression; float32 values.
"""
import os
import re
import sys
import uuid

import numpy as np
import pyopenvdb as vdb

SEED = 20241122
VOXEL = 0.02                   # metres per voxel
LO = (-44, -2, -36)            # index box of the dense array handed to OpenVDB (inclusive lower corner)
SHAPE = (88, 58, 72)           # x, y, z voxels (index box LO .. LO + SHAPE - 1)
SCALE = 1.15                   # the sphere layout below is in units of 1/SCALE metres
CONST_VOXEL = 0.0625


# ----------------------------------------------------------------------------------------------- value noise
class ValueNoise:
    """3D value noise in [-1, 1]: random values on the integer lattice (hashed through a seeded permutation table),
    interpolated trilinearly with quintic smoothing."""

    def __init__(self, seed):
        rng = np.random.RandomState(seed)
        self.perm = np.concatenate([rng.permutation(256)] * 2).astype(np.int64)
        self.values = rng.uniform(-1.0, 1.0, 256)

    def lattice(self, i, j, k):
        p = self.perm
        return self.values[p[p[p[i & 255] + (j & 255)] + (k & 255)]]

    def __call__(self, x, y, z):
        xi, yi, zi = np.floor(x), np.floor(y), np.floor(z)
        fx, fy, fz = x - xi, y - yi, z - zi
        xi, yi, zi = xi.astype(np.int64), yi.astype(np.int64), zi.astype(np.int64)
        s = lambda t: t * t * t * (t * (t * 6 - 15) + 10)  # noqa: E731
        u, v, w = s(fx), s(fy), s(fz)
        out = 0.0
        for dx in (0, 1):
            wx = u if dx else 1 - u
            for dy in (0, 1):
                wy = v if dy else 1 - v
                for dz in (0, 1):
                    wz = w if dz else 1 - w
                    out = out + wx * wy * wz * self.lattice(xi + dx, yi + dy, zi + dz)
        return out


def fbm(noise, x, y, z, octaves=5, lacunarity=2.03, gain=0.5):
    """fractional Brownian motion, normalised to about [-1, 1]"""
    total, amp, norm, f = 0.0, 1.0, 0.0, 1.0
    for o in range(octaves):
        # offset each octave so that lattice points of successive octaves do not line up
        total = total + amp * noise(x * f + 17.1 * o, y * f - 9.3 * o, z * f + 5.7 * o)
        norm += amp
        amp *= gain
        f *= lacunarity
    return total / norm


def smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def smooth_min(a, b, k):
    """polynomial smooth minimum (Quilez), blending over distance k"""
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b * (1 - h) + a * h - k * h * (1 - h)


# ----------------------------------------------------------------------------------------------- grids
def world_coords():
    idx = [np.arange(LO[a], LO[a] + SHAPE[a]) * VOXEL for a in range(3)]
    return np.meshgrid(*idx, indexing="ij")      # arrays indexed [i, j, k] like OpenVDB's copyFromArray


def cloud_density(x, y, z, noise):
    spheres = [  # centre (m), radius (m): a broad base, a central tower, side lobes
        ((0.00, 0.36, 0.00), 0.36),
        ((-0.38, 0.26, 0.05), 0.26),
        ((0.40, 0.25, -0.04), 0.25),
        ((0.08, 0.30, 0.28), 0.24),
        ((-0.10, 0.28, -0.26), 0.24),
        ((0.12, 0.62, -0.02), 0.24),
        ((-0.18, 0.55, 0.06), 0.20),
        ((0.52, 0.22, 0.18), 0.15),
    ]
    d = None
    for (cx, cy, cz), r in spheres:
        di = np.sqrt((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) - r
        d = di if d is None else smooth_min(d, di, 0.08)
    freq = 1.0 / 0.22                                   # base wavelength 0.22 m
    d = d - 0.075 * fbm(noise, x * freq, y * freq, z * freq)          # cauliflower surface
    rho = smoothstep(0.0, 0.12, -d)                                   # soft edge 0.12 m wide
    rho *= 0.75 + 0.25 * fbm(noise, x * 9.0 + 31.0, y * 9.0, z * 9.0, octaves=3)   # inner wisps
    rho *= smoothstep(0.0, 0.10, y)                                   # flat-ish base at y = 0
    return np.clip(rho, 0.0, 1.0)


def core_temperature(x, y, z, noise):
    """a small hot core inside the cloud: up to ~1500 K, 0 beyond 0.28 m from (0, 0.38, 0)"""
    r = np.sqrt(x ** 2 + (y - 0.38) ** 2 + z ** 2)
    flicker = 0.85 + 0.15 * fbm(noise, x * 12.0 - 7.0, y * 12.0, z * 12.0, octaves=3)
    return 1500.0 * flicker * smoothstep(0.28, 0.08, r)


def make_grid(arr, name, lo, voxel, tolerance):
    g = vdb.FloatGrid(0.0)
    g.name = name
    g.gridClass = vdb.GridClass.FOG_VOLUME
    g.transform = vdb.createLinearTransform(voxelSize=voxel)
    g.copyFromArray(np.ascontiguousarray(arr, np.float32), ijk=lo, tolerance=tolerance)
    g.prune()
    return g


def write_vdb(path, grids, metadata):
    """vdb.write, then the file header's random UUID replaced by one derived from the file name and SEED, so that
    reruns give byte-identical files. Header: int64 magic, uint32 file version, uint32 x2 library version, uint8
    has-grid-offsets, then the UUID as 36 ASCII characters at byte 21."""
    vdb.write(path, grids=grids, metadata=metadata)
    with open(path, "r+b") as f:
        head = f.read(57)
        if head[:8] != b" BDV\0\0\0\0" or not re.fullmatch(rb"[0-9a-f-]{36}", head[21:57]):
            raise RuntimeError(f"{path}: unexpected OpenVDB header layout; UUID left as written")
        f.seek(21)
        f.write(str(uuid.uuid5(uuid.NAMESPACE_URL, f"nimbus:{os.path.basename(path)}:{SEED}")).encode())


def describe(path):
    for g in vdb.readAll(path)[0]:
        lo, hi = g.evalActiveVoxelBoundingBox()
        mn, mx = g.evalMinMax()
        print(f"  {path}: grid '{g.name}' class={g.gridClass} active={g.activeVoxelCount()} min={mn:.4g} "
              f"max={mx:.4g} bbox={lo}..{hi} voxel={g.transform.voxelSize()} mem={g.memUsage()} B")


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    noise = ValueNoise(SEED)
    x, y, z = (c / SCALE for c in world_coords())
    rho = cloud_density(x, y, z, noise)
    rho /= rho.max()                                    # peak density exactly 1
    temp = core_temperature(x, y, z, noise) * (rho > 1e-3)
    density = make_grid(rho, "density", LO, VOXEL, 1e-3)
    temperature = make_grid(temp, "temperature", LO, VOXEL, 1.0)
    cloud = os.path.join(root, "assets", "cloud.vdb")
    write_vdb(cloud, [density, temperature], {"creator": "nimbus assets/make_cloud.py", "seed": SEED})
    print("wrote", cloud, os.path.getsize(cloud), "bytes")
    describe(cloud)

    # set voxel by voxel: 8 dense leaves of 8^3 voxels (copyFromArray or prune() would fold each constant leaf
    # into an active tile of value 1; the test fixture keeps the plainest layout)
    const = vdb.FloatGrid(0.0)
    const.name = "density"
    const.gridClass = vdb.GridClass.FOG_VOLUME
    const.transform = vdb.createLinearTransform(voxelSize=CONST_VOXEL)
    acc = const.getAccessor()
    for i in range(16):
        for j in range(16):
            for k in range(16):
                acc.setValueOn((i, j, k), 1.0)
    out = os.path.join(root, "tests", "scenes", "constant_grid.vdb")
    os.makedirs(os.path.dirname(out), exist_ok=True)
    write_vdb(out, [const], {"creator": "nimbus assets/make_cloud.py"})
    print("wrote", out, os.path.getsize(out), "bytes")
    describe(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
