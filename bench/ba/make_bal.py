#!/usr/bin/env python3
"""Independent generator of synthetic BAL problems, plus a numpy reader/cost of the BAL model.

Used by the benchmark's test mode (when `pingcal gen-bal` is not available) and as a
cross-check of pingcal's BAL writer/reader: `make_bal.py --check FILE` reads any BAL file
(plain or .bz2) and prints its cost under the exact BAL model, computed here with numpy
and nothing else.

BAL model (Agarwal et al. 2010), per camera 9 numbers: angle-axis R (3), t (3), f, k1, k2.
    P = R·X + t,  p = −P_xy / P_z,  predicted = f·(1 + k1|p|² + k2|p|⁴)·p
    residual = predicted − observed (pixels), cost = ½ Σ r²  (as Ceres reports it).

Scene of the generator (deliberately not the same as pingcal's, to be an independent
check): camera centres on a Fibonacci sphere of radius 4 around the origin, every camera
looking at the origin with a random roll; points uniform in the unit ball; each point is
observed by the K cameras whose centres are nearest to a random direction near the point's
own direction, so the camera graph is local (a 2-D mesh) as in a real block and the
reduced camera system is sparse. Observations get N(0, σ²) pixel noise; the stored initial
state is the truth perturbed (see --perturb), so a solver has a few LM iterations of work.
"""
import argparse
import bz2
import gzip
import sys

import numpy as np


# ----------------------------------------------------------------------------- geometry

def rodrigues(aa):
    """Angle-axis (n,3) -> rotation matrices (n,3,3); exact near zero angle."""
    aa = np.atleast_2d(np.asarray(aa, dtype=np.float64))
    theta = np.linalg.norm(aa, axis=1)
    small = theta < 1e-12
    safe = np.where(small, 1.0, theta)
    k = aa / safe[:, None]
    kx, ky, kz = k[:, 0], k[:, 1], k[:, 2]
    K = np.zeros((len(aa), 3, 3))
    K[:, 0, 1], K[:, 0, 2] = -kz, ky
    K[:, 1, 0], K[:, 1, 2] = kz, -kx
    K[:, 2, 0], K[:, 2, 1] = -ky, kx
    s = np.sin(theta)[:, None, None]
    c = (1 - np.cos(theta))[:, None, None]
    R = np.eye(3)[None] + s * K + c * (K @ K)
    # first-order form for tiny angles: R = I + [aa]x
    if small.any():
        a = aa[small]
        A = np.zeros((len(a), 3, 3))
        A[:, 0, 1], A[:, 0, 2] = -a[:, 2], a[:, 1]
        A[:, 1, 0], A[:, 1, 2] = a[:, 2], -a[:, 0]
        A[:, 2, 0], A[:, 2, 1] = -a[:, 1], a[:, 0]
        R[small] = np.eye(3)[None] + A
    return R


def rotmat_to_angle_axis(R):
    """Rotation matrices (n,3,3) -> angle-axis (n,3), robust for angles up to π."""
    R = np.asarray(R, dtype=np.float64).reshape(-1, 3, 3)
    out = np.zeros((len(R), 3))
    for i, M in enumerate(R):
        cos = np.clip((np.trace(M) - 1) / 2, -1.0, 1.0)
        w = np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])
        theta = np.arccos(cos)
        if theta < 1e-8:
            out[i] = w / 2
        elif np.pi - theta < 1e-4:
            # near π: axis from the diagonal of (R + I)/2 = k kᵀ
            B = (M + np.eye(3)) / 2
            j = int(np.argmax(np.diag(B)))
            k = B[:, j] / np.sqrt(B[j, j])
            if np.dot(k, w) < 0:
                k = -k
            out[i] = k * theta
        else:
            out[i] = w * theta / (2 * np.sin(theta))
    return out


def project(cams, pts, cam_idx, pt_idx):
    """BAL projection of pts[pt_idx] by cams[cam_idx]; cams (C,9), pts (P,3). Returns (n,2), P_z."""
    R = rodrigues(cams[:, 0:3])
    P = np.einsum("nij,nj->ni", R[cam_idx], pts[pt_idx]) + cams[cam_idx, 3:6]
    p = -P[:, 0:2] / P[:, 2:3]
    r2 = (p * p).sum(axis=1)
    f, k1, k2 = cams[cam_idx, 6], cams[cam_idx, 7], cams[cam_idx, 8]
    dist = f * (1.0 + k1 * r2 + k2 * r2 * r2)
    return p * dist[:, None], P[:, 2]


def bal_cost(prob):
    """½ Σ r² of a problem dict under the BAL model."""
    pred, _ = project(prob["cams"], prob["pts"], prob["cam_idx"], prob["pt_idx"])
    r = pred - prob["obs"]
    return 0.5 * float(np.dot(r.ravel(), r.ravel()))


# ----------------------------------------------------------------------------- BAL I/O

def _open(path, mode):
    if path.endswith(".bz2"):
        return bz2.open(path, mode)
    if path.endswith(".gz"):
        return gzip.open(path, mode)
    return open(path, mode)


class BalError(ValueError):
    pass


def read_bal(path):
    """Reads a BAL file (plain, .bz2 or .gz). Raises BalError with a one-line reason."""
    with _open(path, "rb") as fh:
        data = fh.read()
    tokens = data.split()
    if len(tokens) < 3:
        raise BalError(f"{path}: header 'ncam npts nobs' missing")
    try:
        nc, npt, nobs = (int(t) for t in tokens[:3])
    except ValueError:
        raise BalError(f"{path}: line 1: header counts are not integers")
    if nc <= 0 or npt <= 0 or nobs <= 0:
        raise BalError(f"{path}: line 1: counts must be positive, got {nc} {npt} {nobs}")
    need = 3 + 4 * nobs + 9 * nc + 3 * npt
    if len(tokens) < need:
        raise BalError(f"{path}: truncated: {len(tokens)} numbers, {need} expected")
    try:
        vals = np.array(tokens[3:need], dtype=np.float64)
    except ValueError:
        raise BalError(f"{path}: a value is not a number")
    o = vals[: 4 * nobs].reshape(nobs, 4)
    cam_idx = o[:, 0].astype(np.int64)
    pt_idx = o[:, 1].astype(np.int64)
    if not np.isfinite(vals).all():
        raise BalError(f"{path}: non-finite value")
    if (cam_idx < 0).any() or (cam_idx >= nc).any() or (o[:, 0] != cam_idx).any():
        bad = int(np.nonzero((cam_idx < 0) | (cam_idx >= nc) | (o[:, 0] != cam_idx))[0][0])
        raise BalError(f"{path}: observation {bad}: camera index out of range")
    if (pt_idx < 0).any() or (pt_idx >= npt).any() or (o[:, 1] != pt_idx).any():
        bad = int(np.nonzero((pt_idx < 0) | (pt_idx >= npt) | (o[:, 1] != pt_idx))[0][0])
        raise BalError(f"{path}: observation {bad}: point index out of range")
    cams = vals[4 * nobs: 4 * nobs + 9 * nc].reshape(nc, 9).copy()
    pts = vals[4 * nobs + 9 * nc:].reshape(npt, 3).copy()
    return {"cams": cams, "pts": pts, "cam_idx": cam_idx, "pt_idx": pt_idx,
            "obs": o[:, 2:4].copy()}


def write_bal(path, prob):
    cams, pts = prob["cams"], prob["pts"]
    ci, pi, obs = prob["cam_idx"], prob["pt_idx"], prob["obs"]
    lines = [f"{len(cams)} {len(pts)} {len(obs)}"]
    lines += [f"{c} {p} {x:.17g} {y:.17g}" for c, p, (x, y) in zip(ci.tolist(), pi.tolist(), obs.tolist())]
    lines += [f"{v:.17g}" for v in cams.ravel().tolist()]
    lines += [f"{v:.17g}" for v in pts.ravel().tolist()]
    with _open(path, "wt") as fh:
        fh.write("\n".join(lines))
        fh.write("\n")


# ----------------------------------------------------------------------------- generator

def generate(cameras, points, obs_per_point, noise_px=0.5, seed=1, perturb=1.0):
    rng = np.random.default_rng(seed)
    C, Np, K = cameras, points, min(obs_per_point, cameras)
    # camera centres on a Fibonacci sphere, radius 4
    i = np.arange(C) + 0.5
    z = 1 - 2 * i / C
    phi = i * np.pi * (3 - np.sqrt(5))
    dirs = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=1)
    centres = 4.0 * dirs
    # BAL cameras look down −z: the camera's −z axis points from the centre to the origin.
    R = np.zeros((C, 3, 3))
    for c in range(C):
        back = dirs[c]                        # camera +z axis (points away from the scene)
        tmp = np.array([0.0, 0.0, 1.0]) if abs(back[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        x = np.cross(tmp, back)
        x /= np.linalg.norm(x)
        y = np.cross(back, x)
        roll = rng.uniform(-np.pi, np.pi)
        xr = np.cos(roll) * x + np.sin(roll) * y
        yr = -np.sin(roll) * x + np.cos(roll) * y
        R[c] = np.stack([xr, yr, back])       # rows: camera axes in world frame
    t = -np.einsum("nij,nj->ni", R, centres)
    f = rng.uniform(600.0, 900.0, C)
    k1 = rng.normal(0.0, 0.05, C)
    k2 = rng.normal(0.0, 0.02, C)
    cams = np.concatenate([rotmat_to_angle_axis(R), t, f[:, None], k1[:, None], k2[:, None]], axis=1)
    # points uniform in the unit ball
    u = rng.normal(size=(Np, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    pts = u * rng.uniform(0, 1, Np)[:, None] ** (1 / 3)
    # observers: the K cameras nearest to a random direction near the point's own direction
    look = u + rng.normal(0, 0.5, (Np, 3))
    look /= np.linalg.norm(look, axis=1, keepdims=True)
    cam_idx = np.empty((Np, K), dtype=np.int64)
    chunk = 4096
    for s in range(0, Np, chunk):
        d = look[s:s + chunk] @ dirs.T               # cosine similarity
        cam_idx[s:s + chunk] = np.argpartition(-d, K - 1, axis=1)[:, :K]
    pt_idx = np.repeat(np.arange(Np), K)
    cam_idx = cam_idx.ravel()
    order = np.lexsort((pt_idx, cam_idx))          # BAL files list observations by camera
    cam_idx, pt_idx = cam_idx[order], pt_idx[order]
    true = {"cams": cams, "pts": pts, "cam_idx": cam_idx, "pt_idx": pt_idx}
    pred, pz = project(cams, pts, cam_idx, pt_idx)
    assert (pz < 0).all(), "a point is behind a camera"
    obs = pred + rng.normal(0.0, noise_px, pred.shape)
    # initial state: truth perturbed
    c0 = cams.copy()
    c0[:, 0:3] += rng.normal(0, 0.003 * perturb, (C, 3))
    c0[:, 3:6] += rng.normal(0, 0.01 * perturb, (C, 3))
    c0[:, 6] *= 1 + rng.normal(0, 0.003 * perturb, C)
    c0[:, 7] += rng.normal(0, 0.003 * perturb, C)
    c0[:, 8] += rng.normal(0, 0.001 * perturb, C)
    p0 = pts + rng.normal(0, 0.01 * perturb, pts.shape)
    prob = {"cams": c0, "pts": p0, "cam_idx": cam_idx, "pt_idx": pt_idx, "obs": obs}
    true["obs"] = obs
    return prob, true


def expected_final_cost(prob, noise_px):
    """½σ²(m − n): m residuals, n = free parameters minus the 7-dim similarity gauge."""
    m = 2 * len(prob["obs"])
    n = 9 * len(prob["cams"]) + 3 * len(prob["pts"]) - 7
    return 0.5 * noise_px ** 2 * (m - n)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cameras", type=int, default=50)
    ap.add_argument("--points", type=int, default=5000)
    ap.add_argument("--obs-per-point", type=int, default=6)
    ap.add_argument("--noise-px", type=float, default=0.5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--perturb", type=float, default=1.0, help="scale of the initial perturbation")
    ap.add_argument("--out", help="BAL file to write (.bz2 for compressed)")
    ap.add_argument("--check", metavar="FILE", help="read FILE and print its BAL cost as JSON")
    a = ap.parse_args(argv)
    import json
    if a.check:
        try:
            prob = read_bal(a.check)
        except BalError as e:
            print(f"error: {e}", file=sys.stderr)
            return 2
        print(json.dumps({"cameras": len(prob["cams"]), "points": len(prob["pts"]),
                          "observations": len(prob["obs"]), "cost": bal_cost(prob),
                          "expected_final_cost_if_sigma": expected_final_cost(prob, a.noise_px)}))
        return 0
    if not a.out:
        ap.error("--out or --check is required")
    prob, true = generate(a.cameras, a.points, a.obs_per_point, a.noise_px, a.seed, a.perturb)
    write_bal(a.out, prob)
    print(json.dumps({"out": a.out, "cameras": a.cameras, "points": a.points,
                      "observations": len(prob["obs"]), "initial_cost": bal_cost(prob),
                      "cost_at_truth": bal_cost(true),
                      "expected_final_cost": expected_final_cost(prob, a.noise_px)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
