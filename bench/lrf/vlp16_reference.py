#!/usr/bin/env python3
"""An independent reference for the sphere centres of ../shared/data/spherecalib-vlp16.

Written without any of pingcal's code or choices, to check `find_balls` on real frames
(issue 15): numpy + scipy only.

1. Detection: RANSAC over the whole frame. A hypothesis is a sphere through 4 points drawn
   within 0.7 m of each other (cKDTree), kept when its radius is 250–350 mm. Its score is
   the number of points within 25 mm of the sphere of the nominal radius (300 mm) about its
   centre, minus 10 per point more than 60 mm inside it (a solid ball has none).
   A hypothesis loses 10 per point in the cone it would shadow (seen from the sensor at the
   origin, within the angular radius of R − 60 mm) that lies beyond its centre.
2. Fit: fixed radius 300 mm, orthogonal distances, Huber loss (scale 10 mm, the VLP-16's
   range σ), on the points within 60 mm of the surface and facing the sensor; three rounds,
   each keeping the points within 3 rms of the last fit. Of the 30 best distinct
   hypotheses, the fit with the lowest rms among those with 50 points or more and a
   free radius within 10 % of 300 mm is the frame's sphere.

Writes `frame,x_mm,y_mm,z_mm,sx_mm,sy_mm,sz_mm,points,rms_mm` to stdout.

    python3 -m venv /tmp/vlp-ref && /tmp/vlp-ref/bin/pip install numpy scipy
    /tmp/vlp-ref/bin/python bench/lrf/vlp16_reference.py > crates/lrf/tests/data/vlp16_reference.csv
"""
import glob
import os
import sys

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

R = 300.0
HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "..", "..", "shared", "data", "spherecalib-vlp16", "scans")


def sphere4(p):
    a = 2.0 * (p[1:] - p[0])
    b = (p[1:] ** 2).sum(1) - (p[0] ** 2).sum()
    try:
        c = np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        return None, None
    return c, np.linalg.norm(p[0] - c)


def detect(P, rng):
    """The 30 best-scoring distinct hypotheses (centres more than R apart)."""
    rng_m = np.linalg.norm(P, axis=1)
    U = P / rng_m[:, None]
    tree = cKDTree(P)
    hyps = []
    for _ in range(20000):
        i = rng.integers(len(P))
        nb = tree.query_ball_point(P[i], 700.0)
        if len(nb) < 4:
            continue
        j = rng.choice(nb, 3, replace=False)
        c, r = sphere4(P[np.r_[i, j]])
        if c is None or not (250.0 < r < 350.0):
            continue
        cn = np.linalg.norm(c)
        if cn <= R:
            continue
        near = tree.query_ball_point(c, R + 25.0)
        d = np.linalg.norm(P[near] - c, axis=1)
        # a solid ball shadows the cone behind it: no point there may lie beyond its centre
        cosang = (U @ c) / cn
        shadow = np.sum((cosang > np.cos(np.arcsin((R - 60.0) / cn))) & (rng_m > cn))
        score = np.sum(d > R - 25.0) - 10 * np.sum(d < R - 60.0) - 10 * shadow
        hyps.append((score, c))
    hyps.sort(key=lambda h: -h[0])
    out = []
    for score, c in hyps:
        if score > 0 and all(np.linalg.norm(c - o) > R for o in out):
            out.append(c)
        if len(out) == 30:
            break
    return out


def free_radius(Q, c):
    res = least_squares(lambda x: np.linalg.norm(Q - x[:3], axis=1) - x[3], np.r_[c, R])
    return res.x[3]


def fit(P, c0):
    c = c0
    keep = None
    for _ in range(3):
        d = np.linalg.norm(P - c, axis=1)
        facing = ((P - c) * P).sum(1) < 0.0  # the side seen from the sensor at the origin
        sel = facing & (np.abs(d - R) < 60.0)
        if keep is not None:
            sel &= np.abs(d - R) < keep
        Q = P[sel]
        if len(Q) < 10:
            raise ValueError("too few points")
        res = least_squares(lambda x: np.linalg.norm(Q - x, axis=1) - R, c, loss="huber", f_scale=10.0)
        c = res.x
        rms = np.sqrt(np.mean(res.fun ** 2))
        keep = 3.0 * rms
    J = res.jac
    cov = np.linalg.inv(J.T @ J) * rms ** 2
    return c, np.sqrt(np.diag(cov)), len(Q), rms, Q


def main():
    rng = np.random.default_rng(20261202)
    print("frame,x_mm,y_mm,z_mm,sx_mm,sy_mm,sz_mm,points,rms_mm")
    for f in sorted(glob.glob(os.path.join(DATA, "*.xyz"))):
        P = np.loadtxt(f)[:, :3] * 1000.0
        # of the hypotheses, the fit with the lowest rms among those with at least 50 points
        # and a free radius within 10 % of the nominal one
        best = None
        for c0 in detect(P, rng):
            try:
                c, s, n, rms, Q = fit(P, c0)
            except (np.linalg.LinAlgError, ValueError):
                continue
            if n >= 50 and abs(free_radius(Q, c) - R) < 0.1 * R and (best is None or rms < best[3]):
                best = (c, s, n, rms)
        if best is None:
            print(f"{os.path.basename(f)[:-4]}: no sphere", file=sys.stderr)
            continue
        c, s, n, rms = best
        name = os.path.basename(f)[:-4]
        print(f"{name},{c[0]:.2f},{c[1]:.2f},{c[2]:.2f},{s[0]:.2f},{s[1]:.2f},{s[2]:.2f},{n},{rms:.2f}")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
