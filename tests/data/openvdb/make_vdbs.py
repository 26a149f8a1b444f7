"""Writes the OpenVDB test files with OpenVDB's own Python bindings (Debian's
python3-openvdb, OpenVDB 10.0): run `python3 make_vdbs.py` in this folder.

sphere.vdb   a narrow-band level set "surface": a sphere of radius 3.1 centred at
             (4.1, 3.9, 3.05), voxel size 0.25, half width 3 voxels (float, the file's
             default compression).
fog.vdb      a fog volume "density" (float, per world unit, voxel size 0.125) of
             rho(i, j, k) = 4 * s(i/15) * s(j/15) * s(k/7) with s(t) = sin(pi t)^2 on the
             16x16x8 index box from (5, -3, 2); the same density as "density_half" stored
             as half floats; a colour grid "Cd" (vec3s) of (i/15, j/15, 0.5) on the same
             box; and a bool grid "mask" (a type mesobake does not import).
"""

import math

import numpy as np
import pyopenvdb as vdb

sphere = vdb.createLevelSetSphere(
    radius=3.1, center=(4.1, 3.9, 3.05), voxelSize=0.25, halfWidth=3.0
)
sphere.name = "surface"
vdb.write("sphere.vdb", grids=[sphere])

origin = (5, -3, 2)
shape = (16, 16, 8)
s = lambda t: math.sin(math.pi * t) ** 2
rho = np.zeros(shape, dtype=np.float32)
colour = np.zeros(shape + (3,), dtype=np.float32)
for i in range(shape[0]):
    for j in range(shape[1]):
        for k in range(shape[2]):
            rho[i, j, k] = 4.0 * s(i / 15) * s(j / 15) * s(k / 7)
            colour[i, j, k] = (i / 15, j / 15, 0.5)

transform = vdb.createLinearTransform(voxelSize=0.125)
density = vdb.FloatGrid()
density.copyFromArray(rho, ijk=origin)
density.name = "density"
density.gridClass = vdb.GridClass.FOG_VOLUME
density.transform = transform
half = density.deepCopy()
half.name = "density_half"
half.saveFloatAsHalf = True
cd = vdb.Vec3SGrid()
cd.copyFromArray(colour, ijk=origin)
cd.name = "Cd"
cd.transform = transform
mask = vdb.BoolGrid()
mask.copyFromArray(rho > 1.0, ijk=origin)
mask.name = "mask"
mask.transform = transform
vdb.write("fog.vdb", grids=[density, half, cd, mask])
