#!/usr/bin/env python3
"""Solve a BAL problem with Ceres, through pycolmap's C++ bundle adjuster.

    ceres_bal.py FILE --solver {DENSE_SCHUR,SPARSE_SCHUR,ITERATIVE_SCHUR} --threads {1,2}
                 [--preconditioner {SCHUR_JACOBI,CLUSTER_JACOBI}] [--max-iterations N]

Prints one JSON line:
    {"initial_cost", "final_cost", "iterations", "time_s", "wall_solve_s", "solver", "threads", ...}
with time_s = Ceres's own Summary::total_time_in_seconds (preprocessing + minimizer +
postprocessing) and wall_solve_s = wall time of the solve() call around it.

How the BAL model is mapped onto COLMAP:
  * one RADIAL camera (f, cx, cy, k1, k2) per image, cx = cy = 0 held fixed (SubsetManifold),
    f, k1, k2 optimized: COLMAP's RADIAL is u·f·(1 + k1 r² + k2 r⁴) + c, the BAL model exactly;
  * BAL looks down −z, COLMAP down +z: with F = diag(1, −1, −1), R' = F·R, t' = F·t and the
    observation becomes (u, −v); residuals are the same numbers up to the sign of v, so the
    cost ½Σr² is identical (checked at run time: see "check_*" fields);
  * the pose is a unit quaternion + translation (EigenQuaternionManifold × R³), so the local
    parameterization differs from BAL's angle-axis; the model and the cost do not;
  * squared loss, no gauge fixing (BundleAdjustmentGauge.UNSPECIFIED): all 9 camera and
    3 point parameters are free, as in Ceres's own bundle_adjuster example;
  * the cost function is COLMAP's C++ ReprojErrorCostFunctor (autodiff), not a Python callback.

Ceres settings (must match what pingcal is run with): LEVENBERG_MARQUARDT trust region,
linear solver as chosen, num_threads as chosen, function_tolerance = gradient_tolerance =
parameter_tolerance = 1e-10, max_num_iterations = 100 (default), everything else Ceres's
defaults (initial_trust_region_radius 1e4, min_relative_decrease 1e-3, jacobi_scaling on,
dense LA = Eigen, sparse LA = SuiteSparse, Schur ordering chosen by Ceres).
COLMAP's own overrides are switched off: auto_select_solver_type = False,
min_num_residuals_for_cpu_multi_threading = 0.
"""
import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import make_bal  # noqa: E402  (BAL reader and numpy cost; no pycolmap needed there)

TOLERANCES = {"function_tolerance": 1e-10, "gradient_tolerance": 1e-10, "parameter_tolerance": 1e-10}
F = np.diag([1.0, -1.0, -1.0])


def rotmat_to_quat_xyzw(R):
    """(n,3,3) rotation matrices -> (n,4) unit quaternions x, y, z, w (Shepperd)."""
    R = np.asarray(R).reshape(-1, 3, 3)
    q = np.empty((len(R), 4))
    for i, M in enumerate(R):
        tr = np.trace(M)
        if tr > 0:
            s = 2.0 * np.sqrt(tr + 1.0)
            w, x, y, z = 0.25 * s, (M[2, 1] - M[1, 2]) / s, (M[0, 2] - M[2, 0]) / s, (M[1, 0] - M[0, 1]) / s
        elif M[0, 0] > M[1, 1] and M[0, 0] > M[2, 2]:
            s = 2.0 * np.sqrt(1.0 + M[0, 0] - M[1, 1] - M[2, 2])
            w, x, y, z = (M[2, 1] - M[1, 2]) / s, 0.25 * s, (M[0, 1] + M[1, 0]) / s, (M[0, 2] + M[2, 0]) / s
        elif M[1, 1] > M[2, 2]:
            s = 2.0 * np.sqrt(1.0 + M[1, 1] - M[0, 0] - M[2, 2])
            w, x, y, z = (M[0, 2] - M[2, 0]) / s, (M[0, 1] + M[1, 0]) / s, 0.25 * s, (M[1, 2] + M[2, 1]) / s
        else:
            s = 2.0 * np.sqrt(1.0 + M[2, 2] - M[0, 0] - M[1, 1])
            w, x, y, z = (M[1, 0] - M[0, 1]) / s, (M[0, 2] + M[2, 0]) / s, (M[1, 2] + M[2, 1]) / s, 0.25 * s
        v = np.array([x, y, z, w])
        q[i] = v / np.linalg.norm(v)
    return q


def build_reconstruction(pycolmap, prob):
    """BAL problem -> pycolmap.Reconstruction (one RADIAL camera + trivial rig/frame per image)."""
    cams, pts = prob["cams"], prob["pts"]
    ci, pi, obs = prob["cam_idx"], prob["pt_idx"], prob["obs"]
    nc = len(cams)
    R = make_bal.rodrigues(cams[:, 0:3])
    Rc = np.einsum("ij,njk->nik", F, R)            # R' = F·R
    tc = cams[:, 3:6] @ F.T                         # t' = F·t
    quats = rotmat_to_quat_xyzw(Rc)
    obs_c = obs * np.array([1.0, -1.0])             # (u, −v)
    # keypoint index of every observation inside its image
    order = np.argsort(ci, kind="stable")
    counts = np.bincount(ci, minlength=nc)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    kp_idx = np.empty(len(ci), dtype=np.int64)
    kp_idx[order] = np.arange(len(ci)) - np.repeat(starts, counts)
    extent = float(np.abs(obs).max()) if len(obs) else 1.0
    size = int(2 * extent) + 2
    rec = pycolmap.Reconstruction()
    for c in range(nc):
        f, k1, k2 = cams[c, 6:9]
        cam = pycolmap.Camera(model="RADIAL", width=size, height=size,
                              params=[f, 0.0, 0.0, k1, k2], camera_id=c + 1)
        rec.add_camera_with_trivial_rig(cam)
        sel = order[starts[c]:starts[c] + counts[c]]
        img = pycolmap.Image(name=f"cam{c}", keypoints=np.ascontiguousarray(obs_c[sel]),
                             camera_id=c + 1, image_id=c + 1)
        pose = pycolmap.Rigid3d(pycolmap.Rotation3d(quats[c]), tc[c])
        rec.add_image_with_trivial_frame(img, pose)
    # tracks: observations grouped by point
    porder = np.argsort(pi, kind="stable")
    pcounts = np.bincount(pi, minlength=len(pts))
    TE = pycolmap.TrackElement
    img_ids = (ci[porder] + 1).tolist()
    kps = kp_idx[porder].tolist()
    pos = 0
    point_ids = np.empty(len(pts), dtype=np.int64)
    for j, n in enumerate(pcounts.tolist()):
        track = pycolmap.Track([TE(img_ids[k], kps[k]) for k in range(pos, pos + n)])
        pos += n
        point_ids[j] = rec.add_point3D(pts[j], track)
    return rec, point_ids


def reconstruction_to_bal(rec, prob, point_ids):
    """Reads the refined state back into BAL parameters (angle-axis, t, f, k1, k2; X)."""
    nc = len(prob["cams"])
    cams = np.empty((nc, 9))
    Rs = np.empty((nc, 3, 3))
    for c in range(nc):
        img = rec.image(c + 1)
        pose = img.cam_from_world()
        Rs[c] = F @ pose.rotation.matrix()
        cams[c, 3:6] = F @ np.asarray(pose.translation)
        prm = np.asarray(rec.camera(c + 1).params)
        cams[c, 6], cams[c, 7], cams[c, 8] = prm[0], prm[3], prm[4]
        if prm[1] != 0.0 or prm[2] != 0.0:
            raise RuntimeError("principal point moved: it must be held fixed")
    cams[:, 0:3] = make_bal.rotmat_to_angle_axis(Rs)
    pts = np.array([rec.point3D(int(i)).xyz for i in point_ids])
    return {"cams": cams, "pts": pts, "cam_idx": prob["cam_idx"], "pt_idx": prob["pt_idx"],
            "obs": prob["obs"]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("file")
    ap.add_argument("--solver", choices=["DENSE_SCHUR", "SPARSE_SCHUR", "ITERATIVE_SCHUR"],
                    default="SPARSE_SCHUR")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--preconditioner", choices=["SCHUR_JACOBI", "CLUSTER_JACOBI", "CLUSTER_TRIDIAGONAL"],
                    default="SCHUR_JACOBI", help="of ITERATIVE_SCHUR")
    ap.add_argument("--max-iterations", type=int, default=100)
    ap.add_argument("--progress", action="store_true", help="print Ceres's per-iteration log to stderr")
    ap.add_argument("--no-check", action="store_true",
                    help="skip the numpy recomputation of the initial and final cost")
    ap.add_argument("--write-solution", metavar="BAL", help="write the refined problem as BAL")
    a = ap.parse_args(argv)

    try:
        prob = make_bal.read_bal(a.file)
    except (make_bal.BalError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2

    short = np.bincount(prob["pt_idx"], minlength=len(prob["pts"])) < 2
    if short.any():
        print(f"error: {a.file}: point {int(np.nonzero(short)[0][0])} has fewer than 2 observations "
              "(COLMAP's bundle adjuster requires tracks of length >= 2)", file=sys.stderr)
        return 2

    import pycolmap
    pc = pycolmap._core.pyceres  # Ceres enums/options as compiled into pycolmap

    t0 = time.perf_counter()
    rec, point_ids = build_reconstruction(pycolmap, prob)
    t_build = time.perf_counter() - t0

    opts = pycolmap.BundleAdjustmentOptions()
    opts.refine_focal_length = True
    opts.refine_principal_point = False
    opts.refine_extra_params = True
    opts.refine_rig_from_world = True
    opts.refine_points3D = True
    opts.min_track_length = 0
    opts.print_summary = False
    ce = opts.ceres
    ce.loss_function_type = pycolmap.LossFunctionType.TRIVIAL
    ce.use_gpu = False
    ce.auto_select_solver_type = False
    ce.min_num_residuals_for_cpu_multi_threading = 0
    so = ce.solver_options
    so.minimizer_type = pc.MinimizerType.TRUST_REGION
    so.trust_region_strategy_type = pc.TrustRegionStrategyType.LEVENBERG_MARQUARDT
    so.linear_solver_type = getattr(pc.LinearSolverType, a.solver)
    if a.solver == "ITERATIVE_SCHUR":
        so.preconditioner_type = getattr(pc.PreconditionerType, a.preconditioner)
    so.num_threads = a.threads
    so.max_num_iterations = a.max_iterations
    for k, v in TOLERANCES.items():
        setattr(so, k, v)
    so.minimizer_progress_to_stdout = bool(a.progress)
    so.logging_type = (pc.LoggingType.PER_MINIMIZER_ITERATION if a.progress
                       else pc.LoggingType.SILENT)

    config = pycolmap.BundleAdjustmentConfig()
    for c in range(len(prob["cams"])):
        config.add_image(c + 1)
    config.fix_gauge(pycolmap.BundleAdjustmentGauge.UNSPECIFIED)

    t0 = time.perf_counter()
    adjuster = pycolmap.create_default_ceres_bundle_adjuster(opts, config, rec)
    t_setup = time.perf_counter() - t0
    if a.progress:
        # Ceres's progress goes to C++ stdout: keep our stdout for the JSON line only.
        saved = os.dup(1)
        os.dup2(2, 1)
    t0 = time.perf_counter()
    summary = adjuster.solve()
    wall = time.perf_counter() - t0
    if a.progress:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)
    s = summary.ceres_summary
    out = {
        "initial_cost": s.initial_cost,
        "final_cost": s.final_cost,
        # Ceres records iteration 0 (the initial evaluation) as a successful step: LM steps
        # taken = successful + unsuccessful − 1, which is what pingcal counts.
        "iterations": s.num_successful_steps + s.num_unsuccessful_steps - 1,
        "successful_steps": s.num_successful_steps - 1,
        "ceres_minimizer_iterations": s.num_successful_steps + s.num_unsuccessful_steps,
        "time_s": s.total_time_in_seconds,
        "wall_solve_s": wall,
        "solver": a.solver,
        "threads": a.threads,
        "threads_used": s.num_threads_used,
        "linear_solver_used": str(s.linear_solver_type_used).split(".")[-1],
        "termination": str(s.termination_type).split(".")[-1],
        "message": s.message,
        "linear_solver_s": s.linear_solver_time_in_seconds,
        "jacobian_eval_s": s.jacobian_evaluation_time_in_seconds,
        "residual_eval_s": s.residual_evaluation_time_in_seconds,
        "preprocessor_s": s.preprocessor_time_in_seconds,
        "build_s": t_build + t_setup,
        "cameras": len(prob["cams"]),
        "points": len(prob["pts"]),
        "observations": len(prob["obs"]),
        "num_residuals": s.num_residuals_reduced,
        "num_effective_parameters": s.num_effective_parameters_reduced,
        "ceres_version_note": "pycolmap " + pycolmap.__version__,
        "tolerances": TOLERANCES,
    }
    out["rms_px"] = float(np.sqrt(2 * s.final_cost / max(1, 2 * len(prob["obs"]))))
    if not a.no_check or a.write_solution:
        sol = reconstruction_to_bal(rec, prob, point_ids)
        if not a.no_check:
            out["check_initial_cost_numpy"] = make_bal.bal_cost(prob)
            out["check_final_cost_numpy"] = make_bal.bal_cost(sol)
        if a.write_solution:
            make_bal.write_bal(a.write_solution, sol)
    print(json.dumps(out))
    return 0 if s.IsSolutionUsable() else 1


if __name__ == "__main__":
    sys.exit(main())
