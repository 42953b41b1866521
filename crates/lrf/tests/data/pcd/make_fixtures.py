"""Writes the PCD fixtures of tests/pcd.rs with an independent writer, pypcd4 (PyPI).

Run: python3 -m venv /tmp/pcdvenv && /tmp/pcdvenv/bin/pip install pypcd4==1.5.1 &&
/tmp/pcdvenv/bin/python crates/lrf/tests/data/pcd/make_fixtures.py

One organized cloud of 5 x 4 points (metres, F8 x y z rounded to 1e-6 so that pypcd4's
ascii `%.10f` is exact to 1e-9), with two NaN points and fields to skip: an F4
intensity before x, a U4 rgb between y and z and an I2 ring after z. Saved as
ascii, binary and binary_compressed; `cloud.xyz` holds the finite points (mm) as the truth.
"""
import os
import numpy as np
from pypcd4 import PointCloud, Encoding

here = os.path.dirname(os.path.abspath(__file__))
rng = np.random.default_rng(15)
n = 20
xyz = np.round(rng.uniform(-3.0, 3.0, size=(n, 3)), 6)
xyz[7] = np.nan
xyz[13, 1] = np.nan
intensity = rng.uniform(0, 100, size=n).astype(np.float32)
rgb = rng.integers(0, 2**24, size=n).astype(np.uint32)
ring = np.arange(n, dtype=np.int16) % 4
cols = [intensity, xyz[:, 0], xyz[:, 1], rgb, xyz[:, 2], ring]
fields = ("intensity", "x", "y", "rgb", "z", "ring")
types = (np.float32, np.float64, np.float64, np.uint32, np.float64, np.int16)
pc = PointCloud.from_points(cols, fields, types)
pc.metadata.width, pc.metadata.height = 5, 4
for enc, name in [(Encoding.ASCII, "ascii"), (Encoding.BINARY, "binary"),
                  (Encoding.BINARY_COMPRESSED, "binary_compressed")]:
    pc.save(os.path.join(here, f"cloud_{name}.pcd"), encoding=enc)
with open(os.path.join(here, "cloud.xyz"), "w") as f:
    f.write("# the finite points of cloud_*.pcd, mm\n")
    for p in xyz:
        if np.all(np.isfinite(p)):
            f.write("%.6f %.6f %.6f\n" % tuple(p * 1000.0))
