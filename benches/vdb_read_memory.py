#!/usr/bin/env python3
"""Peak memory and time of reading a production-size VDB: Nimbus's reader against OpenVDB's own.

Writes a 400^3 ball of noisy fog density with OpenVDB (Debian's python3-openvdb, OpenVDB 10; about 33.5 M active
voxels, 70,575 leaves, a 135 MB file), then reads it three times each, alternating, with `nimbus info` and with
OpenVDB (`pyopenvdb.readAll`, delayed loading off so that every leaf is read, as Nimbus reads them), and prints the
peak resident memory (`/usr/bin/time`'s maximum RSS) and wall time of each, less each process's baseline (the
same program reading an 8-voxel file: the Python interpreter and OpenVDB's libraries are most of OpenVDB's).

    python3 benches/vdb_read_memory.py [--nimbus target/release/nimbus] [--python /usr/bin/python3.11]
"""
import argparse
import os
import subprocess
import tempfile

MAKE = r"""
import numpy as np, pyopenvdb as vdb, sys
n = 400
rng = np.random.default_rng(1)
g = vdb.FloatGrid()
g.name = "density"
for z0 in range(0, n, 50):
    z = np.arange(z0, z0 + 50)[:, None, None]
    y = np.arange(n)[None, :, None]
    x = np.arange(n)[None, None, :]
    r = np.sqrt((x - n / 2) ** 2 + (y - n / 2) ** 2 + (z - n / 2) ** 2) / (n / 2)
    d = np.where(r < 1, (1 - r) * rng.random((50, n, n)), 0).astype(np.float32)
    g.copyFromArray(np.ascontiguousarray(d.transpose(2, 1, 0)), ijk=(0, 0, z0), tolerance=0)
g.transform = vdb.createLinearTransform(voxelSize=0.01)
vdb.write(sys.argv[1], grids=[g])
"""

READ = "import sys, pyopenvdb as vdb; vdb.readAll(sys.argv[1])"


def peak(cmd, env=None):
    """(seconds, peak KiB) of one run of `cmd`."""
    out = subprocess.run(["/usr/bin/time", "-f", "%e %M"] + cmd, capture_output=True, text=True, env=env,
                         check=True)
    seconds, kib = out.stderr.strip().splitlines()[-1].split()
    return float(seconds), int(kib)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nimbus", default="target/release/nimbus")
    parser.add_argument("--python", default="/usr/bin/python3.11")
    args = parser.parse_args()
    tiny = os.path.join(os.path.dirname(__file__), "..", "tests", "scenes", "constant_grid.vdb")
    env = dict(os.environ, OPENVDB_DISABLE_DELAYED_LOAD="1")
    with tempfile.TemporaryDirectory() as tmp:
        big = os.path.join(tmp, "big.vdb")
        subprocess.run([args.python, "-c", MAKE, big], check=True)
        print(f"file: {os.path.getsize(big) / 1e6:.1f} MB")
        readers = {
            "nimbus info": lambda f: peak([args.nimbus, "info", f]),
            "OpenVDB readAll": lambda f: peak([args.python, "-c", READ, f], env),
        }
        base = {name: read(tiny)[1] for name, read in readers.items()}
        runs = {name: [] for name in readers}
        for _ in range(3):
            for name, read in readers.items():
                runs[name].append(read(big))
        for name, results in runs.items():
            kib = min(k for _, k in results)
            print(f"{name}: peak {kib / 1024:.0f} MiB ({(kib - base[name]) / 1024:.0f} MiB above its "
                  f"{base[name] / 1024:.0f} MiB baseline), best time {min(s for s, _ in results):.2f} s")


if __name__ == "__main__":
    main()
