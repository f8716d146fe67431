"""Mitsuba 3 reference of the RGB-extinction box in tests/suite/volume_motion.rs (`an_rgb_density_box_matches_mitsuba`).

The box is pyro_box.vdb's `rgb_density` grid, (1, 2, 4) on voxels [0, 15]^3 of 0.0625 m, placed at -0.5 m (the
test's node translation), here a 3-channel grid volume padded by one zero voxel each side, whose texel centres
sit on the VDB's voxels (trilinear, as OpenVDB's BoxSampler), inside a null-BSDF cube; albedo 0.8, a constant
environment of radiance 1, the test's 4x4-pixel camera at z = 3 looking down -z with a 0.05 rad field of view.
Prints the mean of the 16 pixels per channel and its standard error over 32 independent passes.

    python3 tests/scenes/rgb_box_mitsuba.py 1,2,4 0.8 524288     (pip install mitsuba numpy; about 20 s)
"""
import sys

import mitsuba as mi
import numpy as np

mi.set_variant('scalar_rgb')
from mitsuba import ScalarTransform4f as T  # noqa: E402

ratio = [float(x) for x in sys.argv[1].split(',')]
albedo = float(sys.argv[2])
spp = int(sys.argv[3])
PASSES = 32
data = np.zeros((18, 18, 18, 3), np.float32)
data[1:17, 1:17, 1:17, :] = ratio
wmin, size = 0.0625 * -1.5 - 0.5, 18 * 0.0625
scene = mi.load_dict({
    'type': 'scene',
    'integrator': {'type': 'volpath', 'max_depth': -1, 'rr_depth': 1000},
    'env': {'type': 'constant', 'radiance': {'type': 'rgb', 'value': [1, 1, 1]}},
    'sensor': {'type': 'perspective', 'fov': float(np.degrees(0.05)), 'fov_axis': 'y',
               'to_world': T().look_at(origin=[0, 0, 3], target=[0, 0, 0], up=[0, 1, 0]),
               'film': {'type': 'hdrfilm', 'width': 4, 'height': 4, 'rfilter': {'type': 'box'}},
               'sampler': {'type': 'independent', 'sample_count': spp}},
    'box': {'type': 'cube', 'bsdf': {'type': 'null'},
            'to_world': T().translate([wmin + size / 2] * 3).scale(size / 2),
            'interior': {'type': 'heterogeneous', 'albedo': {'type': 'rgb', 'value': [albedo] * 3},
                         'sigma_t': {'type': 'gridvolume', 'grid': mi.VolumeGrid(data), 'filter_type': 'trilinear',
                                     'to_world': T().translate([wmin] * 3).scale(size)},
                         'scale': 1.0}},
})
means = np.array([np.array(mi.render(scene, seed=s, spp=spp // PASSES)).reshape(-1, 3).mean(0)
                  for s in range(PASSES)])
print('mean', means.mean(0).round(5).tolist(), 'se', (means.std(0, ddof=1) / np.sqrt(PASSES)).round(5).tolist())
