"""pyransac3d and Open3D sphere RANSAC on the pingcal benchmark cloud.

Neither library finds many spheres of a given radius: each run finds the one sphere with the
most inliers. To give them the same task as pingcal (all 38 mm balls in a room), the found
sphere's inliers are removed and the search repeated, 16 times, with the radius check done
afterwards (pyransac3d has no radius bounds; Open3D's segment_sphere, where present, neither).
Reported: total time and the centre error of each found sphere against the nearest true ball.
"""
import sys
import time

import numpy as np

pts = np.loadtxt(sys.argv[1])
balls = np.loadtxt(sys.argv[2])


def report(name, centres, dt):
    errs = [np.min(np.linalg.norm(balls - c, axis=1)) for c in centres]
    good = [e for e in errs if e < 19.0]
    rms = np.sqrt(np.mean(np.square(good))) if good else float("nan")
    print(f"{name}: {len(pts)} points, {dt:.2f} s, {len(good)} of {len(centres)} spheres within a radius of a true ball, rms {rms:.2f} mm")


import pyransac3d as pyrsc  # noqa: E402

rest = pts.copy()
centres = []
t0 = time.perf_counter()
for _ in range(16):
    c, r, inl = pyrsc.Sphere().fit(rest, thresh=10.0, maxIteration=1000)
    if len(inl) == 0:
        break
    if 10.0 < r < 30.0:
        centres.append(np.asarray(c))
    rest = np.delete(rest, inl, axis=0)
report("pyransac3d", centres, time.perf_counter() - t0)

try:
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    if hasattr(pc, "segment_sphere"):
        centres = []
        t0 = time.perf_counter()
        for _ in range(16):
            model, inl = pc.segment_sphere(distance_threshold=10.0, ransac_n=4, num_iterations=1000)
            if len(inl) == 0:
                break
            centres.append(np.asarray(model[:3]))
            pc = pc.select_by_index(inl, invert=True)
        report("open3d", centres, time.perf_counter() - t0)
    else:
        print(f"open3d {o3d.__version__}: no sphere RANSAC (segment_sphere) in this version")
except ImportError as e:
    print(f"open3d not available: {e}")
