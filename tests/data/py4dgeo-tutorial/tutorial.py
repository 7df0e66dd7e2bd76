# A py4dgeo M3C2 session written the way py4dgeo's "Basic M3C2 algorithm" tutorial
# (py4dgeo's jupyter/m3c2.ipynb) works: read two epochs, take every n-th reference point as a
# core point, run M3C2, read the uncertainty fields. Run as it is with py4dgeo installed
# (validation/make_py4dgeo_tutorial_golden.py stores its results); tests/python/
# test_compat_py4dgeo.py runs the same text with only the import line changed.
import numpy as np
import py4dgeo

epoch1, epoch2 = py4dgeo.read_from_xyz("plane_horizontal_t1.xyz", "plane_horizontal_t2.xyz")
corepoints = epoch1.cloud[::7]

# Single-scale normals, the cylinder's radius and reach.
m3c2 = py4dgeo.M3C2(
    epochs=(epoch1, epoch2),
    corepoints=corepoints,
    normal_radii=[1.5],
    cyl_radius=1.0,
    max_distance=3.0,
    registration_error=0.01,
)
distances, uncertainties = m3c2.run()
lodetection = uncertainties["lodetection"]
spread1, spread2 = uncertainties["spread1"], uncertainties["spread2"]
num_samples1, num_samples2 = uncertainties["num_samples1"], uncertainties["num_samples2"]
normals = m3c2.directions()

# The tutorial's own call: the deprecated cyl_radii, several normal radii, no max_distance.
multiscale = py4dgeo.M3C2(
    epochs=(epoch1, epoch2),
    corepoints=epoch1.cloud[::50],
    cyl_radii=(2.0,),
    normal_radii=[0.5, 1.0, 2.0],
)
ms_distances, ms_uncertainties = multiscale.run()
ms_radii = multiscale.directions_radii()

# Robust aggregation (median distances).
robust = py4dgeo.M3C2(epochs=(epoch1, epoch2), corepoints=corepoints, normal_radii=[1.5], cyl_radius=1.0,
                      max_distance=3.0, robust_aggr=True)
robust_distances, _ = robust.run()
print(f"{len(distances)} core points, median distance {np.nanmedian(distances):.4f}")
