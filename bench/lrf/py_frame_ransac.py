"""pyransac3d on simulated lidar frames of one large sphere (issue 15's 100k-point frame).

pyransac3d's Sphere.fit finds the one sphere with the most inliers; in a frame whose floor and
wall hold most points that is seldom the ball, so the found sphere's inliers are removed and
the search repeated (up to 10 times) until a sphere of radius 250–350 mm comes out.
Reported per frame: time, and the centre error against truth.json.

    python py_frame_ransac.py DATASET_DIR     (from `pingcal simulate --kind sphere-calib`)
"""
import json
import os
import sys
import time

import numpy as np
import pyransac3d as pyrsc

d = sys.argv[1]
truth = json.load(open(os.path.join(d, "truth.json")))
for fr in truth["frames"]:
    pts = np.loadtxt(os.path.join(d, fr["cloud"]))[:, :3] * 1000.0
    c_true = np.array(fr["centre_lidar_mm"])
    rest = pts.copy()
    found = None
    t0 = time.perf_counter()
    for _ in range(10):
        c, r, inl = pyrsc.Sphere().fit(rest, thresh=20.0, maxIteration=1000)
        if len(inl) == 0:
            break
        if 250.0 < r < 350.0:
            found = np.asarray(c)
            break
        rest = np.delete(rest, inl, axis=0)
    dt = time.perf_counter() - t0
    err = np.linalg.norm(found - c_true) if found is not None else float("nan")
    print(f"pyransac3d {fr['id']}: {len(pts)} points, {dt:.2f} s, centre error {err:.1f} mm")
