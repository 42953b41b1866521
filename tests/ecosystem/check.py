"""Checks pingcal's outputs for other ecosystems with each ecosystem's own code.

    python check.py CHECK RESULTS_DIR [PROBE_JSON | PROJECT_TOML]

CHECK is one of opencv, stereo, transforms, ros, urdf, head, kalibr, chain, camera_info, lrf_model.
RESULTS_DIR holds results.json and ros/, opencv/, kalibr/ as `pingcal calibrate` wrote
them; the third argument is, for opencv, kalibr and camera_info, PROBE_JSON (3D points in
the LRF frame and pingcal's own projection of them; the rays of pingcal's model through a
grid of every image, 8 px apart as the exported files' loss figures, and pingcal's own
projection of them), for lrf_model the project.toml whose `[lrf] scans` made cloud.ply. Every
expected value is rebuilt here from results.json's photogrammetric numbers (R, t, opk_deg)
and docs/formats.md's axes, not from the converted blocks. Prints one line `CHECK: name=max_error
...` and exits 1 when a bound is exceeded.
"""

import json
import re
import shlex
import sys
import types
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

# p_opencv = C p_photogrammetric = (X, -Z, Y) (docs/formats.md)
C = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])

failures = []
figures = []


def bound(name, value, limit):
    figures.append(f"{name}={value:.3g}")
    if not value <= limit:
        failures.append(f"{name} = {value:.3g} > {limit:g}")


def results(d):
    return json.loads((d / "results.json").read_text())


def ros_expected(r):
    """The tf of the extrinsic: rotation and translation (m) in the OpenCV frame."""
    e = r["extrinsic"]
    return C @ np.array(e["rotation"]), C @ np.array(e["translation_mm"]) / 1000.0


def cv_camera(path):
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    if not fs.isOpened():
        raise SystemExit(f"{path}: OpenCV cannot open it")
    return fs


def check_opencv(d, probe):
    """cv2.projectPoints with each camera's YAML and results.json's OpenCV extrinsic
    against pingcal's projection of the same LRF points."""
    import cv2

    r = results(d)
    p = json.loads(Path(probe).read_text())
    e = r["extrinsic"]["opencv"]
    rig = r["bundle"]["rig"]
    for cam in p["cameras"]:
        fs = cv_camera(d / "opencv" / f"camera_{cam['id']}.yaml")
        k = fs.getNode("camera_matrix").mat()
        dist = fs.getNode("distortion_coefficients").mat()
        size = (int(fs.getNode("image_width").real()), int(fs.getNode("image_height").real()))
        assert fs.getNode("camera_name").string() == cam["id"]
        model = fs.getNode("camera_model").string()
        assert model in ("pinhole", "fisheye"), model
        assert size == (cam["width"], cam["height"]), (size, cam)
        rot, t = np.array(e["rotation"]), np.array(e["translation_mm"])
        if cam["id"] != r["conventions"]["main_camera"]:
            rr = np.array(rig["opencv"]["rotation"])
            rot, t = rr @ rot, rr @ t + np.array(rig["opencv"]["translation_mm"])
        rvec, _ = cv2.Rodrigues(rot)
        pts = np.array(cam["lrf_points_mm"], dtype=np.float64)
        if model == "fisheye":
            uv, _ = cv2.fisheye.projectPoints(pts.reshape(-1, 1, 3), rvec, t.reshape(3, 1), k, dist)
        else:
            uv, _ = cv2.projectPoints(pts, rvec, t, k, dist)
        err = np.abs(uv.reshape(-1, 2) - np.array(cam["pingcal_px"])).max()
        # what the file loses against pingcal's model, as its comment states, plus 0.02 px
        losses = stated_losses((d / "opencv" / f"camera_{cam['id']}.yaml").read_text())
        bound(f"projectPoints_{model}_{cam['id']}_px", err, 0.02 + (losses[0][0] if losses else 0.0))


def check_stereo(d):
    """cv2.stereoRectify on stereo.yaml's cameras against its R1 R2 P1 P2 Q; E and F from
    R, T, K; R and T against results.json's rig."""
    import cv2

    r = results(d)
    rig = r["bundle"]["rig"]
    fs = cv_camera(d / "opencv" / "stereo.yaml")
    g = lambda n: fs.getNode(n).mat()
    k1, d1, k2, d2, rot, t = g("K1"), g("D1"), g("K2"), g("D2"), g("R"), g("T")
    size = (int(fs.getNode("image_width").real()), int(fs.getNode("image_height").real()))
    bound("stereo_R_vs_rig", np.abs(rot - C @ np.array(rig["rotation"]) @ C.T).max(), 1e-12)
    bound("stereo_T_vs_rig_mm", np.abs(t.ravel() - C @ np.array(rig["translation_mm"])).max(), 1e-9)
    r1, r2, p1, p2, q, _, _ = cv2.stereoRectify(k1, d1, k2, d2, size, rot, t)
    bound("stereoRectify_R1", np.abs(r1 - g("R1")).max(), 1e-9)
    bound("stereoRectify_R2", np.abs(r2 - g("R2")).max(), 1e-9)
    bound("stereoRectify_P1_px", np.abs(p1 - g("P1")).max(), 1e-6)
    bound("stereoRectify_P2_px", np.abs(p2 - g("P2")).max(), 1e-6 * abs(p2[0, 3]) + 1e-6)
    bound("stereoRectify_Q", np.abs(q - g("Q")).max(), 1e-6)
    tx = np.array([[0, -t[2, 0], t[1, 0]], [t[2, 0], 0, -t[0, 0]], [-t[1, 0], t[0, 0], 0]])
    e = tx @ rot
    f = np.linalg.inv(k2).T @ e @ np.linalg.inv(k1)
    f /= f[2, 2]
    bound("E", np.abs(e - g("E")).max(), 1e-9)
    bound("F", np.abs(f - g("F")).max() / np.abs(f).max(), 1e-9)


def check_one_transform(name, blk, rot, t_mm, opk=None):
    from scipy.spatial.transform import Rotation

    q = Rotation.from_quat(blk["quaternion_xyzw"])
    bound(f"{name}_quaternion", np.abs(q.as_matrix() - rot).max(), 1e-12)
    m = np.array(blk["matrix_4x4"])
    bound(f"{name}_4x4_R", np.abs(m[:3, :3] - rot).max(), 0.0)
    bound(f"{name}_4x4_t_mm", np.abs(m[:3, 3] - t_mm).max(), 0.0)
    bound(f"{name}_4x4_last_row", np.abs(m[3] - [0, 0, 0, 1]).max(), 0.0)
    if opk is not None:
        # R = R_omega R_phi R_kappa of passive rotations = active X(-omega) Y(-phi) Z(-kappa)
        e = Rotation.from_euler("XYZ", -np.array(opk), degrees=True)
        bound(f"{name}_opk", np.abs(e.as_matrix() - rot).max(), 1e-12)


def check_transforms(d):
    """The quaternions and 4x4 matrices through scipy.spatial.transform against results.json's
    R, t and omega phi kappa, in both frames, for every method and the rig."""
    r = results(d)
    exts = [("extrinsic", r["extrinsic"])] + [
        (f"methods_{m['method']}", m["extrinsic"]) for m in r["methods"] if m["extrinsic"]
    ]
    for name, e in exts:
        rot, t = np.array(e["rotation"]), np.array(e["translation_mm"])
        check_one_transform(name, e, rot, t, e["opk_deg"])
        check_one_transform(f"{name}_opencv", e["opencv"], C @ rot, C @ t)
        cv = e["opencv"]
        bound(f"{name}_opencv_R", np.abs(np.array(cv["rotation"]) - C @ rot).max(), 0.0)
        if e["sigma_translation_mm"]:
            s = np.array(e["sigma_translation_mm"])
            bound(f"{name}_opencv_sigma", np.abs(np.array(cv["sigma_translation_mm"]) - np.abs(C) @ s).max(), 0.0)
    rig = r["bundle"]["rig"]
    if rig:
        rot, t = np.array(rig["rotation"]), np.array(rig["translation_mm"])
        check_one_transform("rig", rig, rot, t)
        check_one_transform("rig_opencv", rig["opencv"], C @ rot @ C.T, C @ t)


def tf_of_flags(args):
    """ROS 2 static_transform_publisher flags → (t, q, parent, child)."""
    kv = dict(zip(args[::2], args[1::2]))
    t = [float(kv[k]) for k in ("--x", "--y", "--z")]
    q = [float(kv[k]) for k in ("--qx", "--qy", "--qz", "--qw")]
    return t, q, kv["--frame-id"], kv["--child-frame-id"]


def tf_of_positional(args):
    """ROS 1 tf2_ros static_transform_publisher `x y z qx qy qz qw frame child`."""
    assert len(args) == 9, args
    return [float(a) for a in args[:3]], [float(a) for a in args[3:7]], args[7], args[8]


def command_args(path):
    words = [w for line in path.read_text().splitlines() if not line.startswith("#") for w in shlex.split(line)]
    return words[words.index("static_transform_publisher") + 1 :]


def ros2_launch_args(path):
    """Runs the ROS 2 launch file's generate_launch_description() with stand-ins for launch
    and launch_ros (which need a ROS install), and returns the Node's arguments."""
    seen = []
    launch = types.ModuleType("launch")
    launch.LaunchDescription = lambda actions: actions
    actions = types.ModuleType("launch_ros.actions")
    actions.Node = lambda **kw: seen.append(kw) or kw
    sys.modules.update({"launch": launch, "launch_ros": types.ModuleType("launch_ros"), "launch_ros.actions": actions})
    ns = {}
    exec(compile(path.read_text(), str(path), "exec"), ns)
    ns["generate_launch_description"]()
    (node,) = seen
    assert node["package"] == "tf2_ros" and node["executable"] == "static_transform_publisher", node
    return node["arguments"]


def check_ros(d):
    """The ROS 1 and ROS 2 commands and launch files, parsed as the tools parse them, against
    the extrinsic moved into the optical frame and metres here."""
    from scipy.spatial.transform import Rotation

    r = results(d)
    rot, t = ros_expected(r)
    frames = (r["conventions"]["tf_camera_frame"], r["conventions"]["tf_lrf_frame"])
    node = ET.parse(d / "ros" / "static_transform_ros1.launch").getroot().find("node")
    assert node.get("pkg") == "tf2_ros" and node.get("type") == "static_transform_publisher"
    found = {
        "ros1_command": tf_of_positional(command_args(d / "ros" / "ros1_static_transform_publisher.sh")),
        "ros2_command": tf_of_flags(command_args(d / "ros" / "ros2_static_transform_publisher.sh")),
        "ros1_launch": tf_of_positional(node.get("args").split()),
        "ros2_launch": tf_of_flags(ros2_launch_args(d / "ros" / "static_transform_ros2.launch.py")),
    }
    for name, (tt, q, parent, child) in found.items():
        assert (parent, child) == frames, (name, parent, child, frames)
        bound(f"{name}_t_m", np.abs(np.array(tt) - t).max(), 1e-12)
        bound(f"{name}_R", np.abs(Rotation.from_quat(q).as_matrix() - rot).max(), 1e-12)


def check_urdf(d):
    """The URDF parsed by urdf_parser_py; its joint's origin composed (URDF: R = Rz(yaw)
    Ry(pitch) Rx(roll)) and mapped back to the extrinsic in mm."""
    from scipy.spatial.transform import Rotation
    from urdf_parser_py.urdf import URDF

    r = results(d)
    robot = URDF.from_xml_string((d / "ros" / "laser_joint.urdf").read_text().encode())
    (joint,) = robot.joints
    assert joint.type == "fixed"
    assert (joint.parent, joint.child) == (r["conventions"]["tf_camera_frame"], r["conventions"]["tf_lrf_frame"])
    rot = Rotation.from_euler("xyz", joint.origin.rpy).as_matrix()
    xyz = np.array(joint.origin.xyz)
    e = r["extrinsic"]
    pts = np.array([[0, 0, 0], [1000, 0, 0], [0, 2000, 500], [-300, 800, 3000.0]])
    # LRF points (mm) → optical frame (m) by the joint → photogrammetric frame (mm)
    back = (C.T @ (rot @ (pts.T / 1000.0) + xyz[:, None])).T * 1000.0
    want = (np.array(e["rotation"]) @ pts.T).T + np.array(e["translation_mm"])
    bound("urdf_composed_back_m", np.abs(back - want).max() / 1000.0, 1e-9)


def sensor_to_optical(r, s):
    """The optical-frame joint (R, t in mm) of sensor `s` rebuilt from its photogrammetric
    camera_from_sensor: a camera's child frame is its optical frame (C R C^T, C t), the
    LRF's its own (C R, C t)."""
    e = s["camera_from_sensor"]
    rot, t = np.array(e["rotation"]), np.array(e["translation_mm"])
    return (C @ rot @ C.T if s["kind"] == "camera" else C @ rot), C @ t


def check_head(d):
    """ros/head.urdf parsed by urdf_parser_py: one fixed joint per sensor of results.json's
    sensors from the main camera's optical frame, each composed (R = Rz(yaw) Ry(pitch)
    Rx(roll)) back to the sensor's camera_from_sensor in mm; every pair's a_from_b is the
    composition of its two sensors'."""
    from scipy.spatial.transform import Rotation
    from urdf_parser_py.urdf import URDF

    r = results(d)
    conv = r["conventions"]
    robot = URDF.from_xml_string((d / "ros" / "head.urdf").read_text().encode())
    assert len(robot.joints) == len(r["sensors"]), (len(robot.joints), len(r["sensors"]))
    worst_t, worst_r = 0.0, 0.0
    first_range = next((s["id"] for s in r["sensors"] if s["kind"] != "camera"), None)
    for joint, s in zip(robot.joints, r["sensors"]):
        if s["kind"] == "camera":
            child = f"{s['id']}_optical"
        else:
            child = conv["tf_lrf_frame"] if s["id"] == first_range else s["id"]
        assert joint.type == "fixed" and (joint.parent, joint.child) == (conv["tf_camera_frame"], child), (joint.parent, joint.child)
        rot = Rotation.from_euler("xyz", joint.origin.rpy).as_matrix()
        want_r, want_t = sensor_to_optical(r, s)
        worst_r = max(worst_r, np.abs(rot - want_r).max())
        worst_t = max(worst_t, np.abs(np.array(joint.origin.xyz) - want_t / 1000.0).max())
    bound("head_urdf_R", worst_r, 1e-12)
    bound("head_urdf_t_m", worst_t, 1e-12)
    pose = {s["id"]: s["camera_from_sensor"] for s in r["sensors"]}
    kind = {s["id"]: s["kind"] for s in r["sensors"]}
    worst = 0.0
    for p in r["sensor_pairs"]:
        a, b, e = pose[p["a"]], pose[p["b"]], p["a_from_b"]
        if p["a_from_b"]["sigma_translation_mm"] is None:
            # two range sensors of separate adjustments: no cross-covariance, no σ
            assert pose[p["a"]] is not None and "camera" not in (kind[p["a"]], kind[p["b"]]), p
        ra, rb = np.array(a["rotation"]), np.array(b["rotation"])
        want = np.eye(4)
        want[:3, :3] = ra.T @ rb
        want[:3, 3] = ra.T @ (np.array(b["translation_mm"]) - np.array(a["translation_mm"]))
        worst = max(worst, np.abs(np.array(e["matrix_4x4"]) - want).max())
    bound("sensor_pairs_composed_mm", worst, 1e-9)


def check_chain(d):
    """camchain.yaml read back with PyYAML for a head of more than two cameras: cam0 the
    main (or left) camera, then every camera of results.json's sensors; each T_cn_cnm1
    (p_camn = T p_camn-1, OpenCV frames, m) rebuilt here from the sensors' photogrammetric
    camera_from_sensor."""
    import yaml

    r = results(d)
    chain = yaml.safe_load((d / "kalibr" / "camchain.yaml").read_text())
    rig = r["bundle"]["rig"]
    ids = [rig["left"], rig["right"]] if rig else [r["conventions"]["main_camera"]]
    ids += [s["id"] for s in r["sensors"] if s["kind"] == "camera" and s["id"] not in ids]
    assert sorted(chain) == sorted(f"cam{n}" for n in range(len(ids))), sorted(chain)

    def main_from(cid):
        if cid == r["conventions"]["main_camera"]:
            return np.eye(4)
        s = next(s for s in r["sensors"] if s["id"] == cid)
        m = np.eye(4)
        m[:3, :3], t = sensor_to_optical(r, s)
        m[:3, 3] = t / 1000.0
        return m

    worst = 0.0
    for n in range(1, len(ids)):
        want = np.linalg.inv(main_from(ids[n])) @ main_from(ids[n - 1])
        worst = max(worst, np.abs(np.array(chain[f"cam{n}"]["T_cn_cnm1"]) - want).max())
    bound("kalibr_chain_T_cn_cnm1", worst, 1e-9)


def stated_losses(text):
    """The (largest, RMS) losses in px an exported file's comments state, in order."""
    return [(float(a), float(b)) for a, b in re.findall(r"largest ([0-9.]+) px, RMS ([0-9.]+) px", text)]


def grid_of(probe, cid):
    """The probe's grid of camera `cid`: rays (OpenCV normalised, z = 1) of pingcal's
    model through every grid pixel, and pingcal's own projection of them (px)."""
    cam = next(c for c in json.loads(Path(probe).read_text())["cameras"] if c["id"] == cid)
    return np.array(cam["grid_rays_cv"], dtype=np.float64), np.array(cam["grid_pingcal_px"])


def ds_project(rays, xi, alpha, k):
    """The double-sphere projection (Usenko, Demmel, Cremers 2018; Kalibr's `ds`), written
    here from the paper: rays (N, 3) in OpenCV's frame, K's fx fy cx cy. Returns the pixels
    and the mask of rays the model projects (z > -w2 |x|)."""
    x, y, z = rays[:, 0], rays[:, 1], rays[:, 2]
    d1 = np.sqrt(x * x + y * y + z * z)
    mz = xi * d1 + z
    d2 = np.sqrt(x * x + y * y + mz * mz)
    den = alpha * d2 + (1.0 - alpha) * mz
    w1 = alpha / (1.0 - alpha) if alpha <= 0.5 else (1.0 - alpha) / alpha
    w2 = (w1 + xi) / np.sqrt(2.0 * w1 * xi + xi * xi + 1.0)
    ok = z > -w2 * d1
    uv = np.stack([k[0, 0] * x / den + k[0, 2], k[1, 1] * y / den + k[1, 2]], axis=1)
    return uv, ok


def project_form(rays, k, dist, model):
    """The rays (N, 3, OpenCV's frame) through one file's model: `pinhole` (plumb_bob,
    rational_polynomial, radtan: cv2.projectPoints), `fisheye` (OpenCV's cv::fisheye, ROS's
    and Kalibr's equidistant: cv2.fisheye.projectPoints) or `ds` (dist = [xi, alpha]).
    OpenCV's models see only rays ahead of the camera (z > 0); the pixels and the mask of
    the rays projected are returned."""
    import cv2

    dist = np.asarray(dist, dtype=np.float64)
    if model == "ds":
        uv, ok = ds_project(rays, dist[0], dist[1], k)
        return uv[ok], ok
    ok = rays[:, 2] > 1e-6
    pts = rays[ok].reshape(-1, 1, 3)
    if model == "fisheye":
        uv, _ = cv2.fisheye.projectPoints(pts, np.zeros((3, 1)), np.zeros((3, 1)), k, dist[:4])
    else:
        uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), k, dist)
    return uv.reshape(-1, 2), ok


def loss_against(rays, want_px, k, dist, model="pinhole"):
    """A file's model of the rays against pingcal's pixels: (largest, RMS, all rays seen)."""
    uv, ok = project_form(rays, k, dist, model)
    e = np.linalg.norm(uv - want_px[ok], axis=1)
    return e.max(), np.sqrt((e * e).mean()), bool(ok.all())


def within_stated(name, measured, stated):
    """The measured loss against the stated one: equal to 1e-3 px (the file rounds to 1e-4),
    and within 0.05 px or the stated loss. Where the ecosystem's code sees only a part of
    the grid (OpenCV's fisheye ahead of the camera), the part's largest loss is at most the
    stated one."""
    (mx, rms, whole), (smx, srms) = measured, stated
    bound(f"{name}_max_px", mx, max(0.05, smx + 1e-3))
    if whole:
        bound(f"{name}_stated_max_minus_measured_px", abs(mx - smx), 1e-3)
        bound(f"{name}_stated_rms_minus_measured_px", abs(rms - srms), 1e-3)
    else:
        bound(f"{name}_measured_max_beyond_stated_px", max(0.0, mx - smx), 1e-3)


def check_kalibr(d, probe):
    """camchain.yaml read back with PyYAML: the radtan model (cv2.projectPoints with k3 = 0,
    Kalibr's pinhole-radtan) over the whole image against pingcal's projection, within
    the loss each camera's comment states (measured here to 1e-3 px); T_cn_cnm1 against
    the rig moved into OpenCV frames and metres here."""
    import yaml

    r = results(d)
    text = (d / "kalibr" / "camchain.yaml").read_text()
    chain = yaml.safe_load(text)
    stated = stated_losses(text)
    rig = r["bundle"]["rig"]
    ids = [rig["left"], rig["right"]] if rig else [r["conventions"]["main_camera"]]
    assert sorted(chain) == [f"cam{n}" for n in range(len(ids))], sorted(chain)
    assert len(stated) == len(ids), stated
    for n, cid in enumerate(ids):
        cam = chain[f"cam{n}"]
        o = next(c["opencv"] for c in r["cameras"] if c["id"] == cid)
        form = (cam["camera_model"], cam["distortion_model"])
        assert form in [("pinhole", "radtan"), ("pinhole", "equidistant"), ("ds", "none")], form
        assert cam["resolution"] == [o["image_width"], o["image_height"]]
        assert all(isinstance(v, float) for v in cam["intrinsics"] + cam["distortion_coeffs"])
        if form[0] == "ds":
            xi, alpha, fx, fy, cx, cy = cam["intrinsics"]
            dist, model = [xi, alpha], "ds"
        else:
            fx, fy, cx, cy = cam["intrinsics"]
            dist = cam["distortion_coeffs"] + ([0.0] if form[1] == "radtan" else [])
            model = "pinhole" if form[1] == "radtan" else "fisheye"
        k = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
        rays, px = grid_of(probe, cid)
        within_stated(f"kalibr_cam{n}_{form[0]}_{form[1]}", loss_against(rays, px, k, dist, model), stated[n])
    if rig:
        t = np.array(chain["cam1"]["T_cn_cnm1"])
        want = np.eye(4)
        want[:3, :3] = C @ np.array(rig["rotation"]) @ C.T
        want[:3, 3] = C @ np.array(rig["translation_mm"]) / 1000.0
        bound("kalibr_T_cn_cnm1", np.abs(t - want).max(), 1e-12)


def ros_matrix(info, name, rows, cols):
    """A camera_info matrix as camera_calibration_parsers reads it ({rows, cols, data})."""
    m = info[name]
    assert (m["rows"], m["cols"]) == (rows, cols) and len(m["data"]) == rows * cols, (name, m)
    return np.array(m["data"], dtype=np.float64).reshape(rows, cols)


def check_camera_info(d, probe):
    """Each ros/camera_info_<id>.yaml read with PyYAML in camera_calibration_parsers'
    layout: K, D through cv2.projectPoints over the whole image against pingcal's
    projection, within the loss its comment states; R, P those of opencv/stereo.yaml's
    rectification (P's last column in m, Tx = -fx' B) for a rig, else I and [K | 0]."""
    import yaml

    r = results(d)
    rig = r["bundle"]["rig"]
    # a fisheye pair has no stereo.yaml: OpenCV's stereoRectify takes pinhole cameras only
    rectified = rig and (d / "opencv" / "stereo.yaml").exists()
    st = cv_camera(d / "opencv" / "stereo.yaml") if rectified else None
    for c in r["cameras"]:
        cid = c["id"]
        text = (d / "ros" / f"camera_info_{cid}.yaml").read_text()
        info = yaml.safe_load(text)
        o = c["opencv"]
        assert (info["image_width"], info["image_height"]) == (o["image_width"], o["image_height"])
        n_coeffs = {"plumb_bob": 5, "rational_polynomial": 8, "equidistant": 4}
        assert info["camera_name"] == cid and info["distortion_model"] in n_coeffs, info
        model = "fisheye" if info["distortion_model"] == "equidistant" else "pinhole"
        k = ros_matrix(info, "camera_matrix", 3, 3)
        dist = ros_matrix(info, "distortion_coefficients", 1, n_coeffs[info["distortion_model"]]).ravel()
        rect, proj = ros_matrix(info, "rectification_matrix", 3, 3), ros_matrix(info, "projection_matrix", 3, 4)
        bound(f"camera_info_{cid}_K", np.abs(k - [[o["fx"], 0, o["cx"]], [0, o["fy"], o["cy"]], [0, 0, 1]]).max(), 0.0)
        rays, px = grid_of(probe, cid)
        (stated,) = stated_losses(text)
        within_stated(f"camera_info_{cid}_{info['distortion_model']}", loss_against(rays, px, k, dist, model), stated)
        if rig and not rectified:
            assert "no stereo rectification is written for this pair" in text, text[:400]
        if rectified:
            n = 1 if cid == rig["left"] else 2
            p_cv = st.getNode(f"P{n}").mat()
            bound(f"camera_info_{cid}_R", np.abs(rect - st.getNode(f"R{n}").mat()).max(), 0.0)
            bound(f"camera_info_{cid}_P_px", np.abs(proj[:, :3] - p_cv[:, :3]).max(), 0.0)
            bound(f"camera_info_{cid}_P_Tx_m", np.abs(proj[:, 3] - p_cv[:, 3] / 1000.0).max(), 1e-15)
            baseline_m = np.linalg.norm(rig["translation_mm"]) / 1000.0
            want_tx = 0.0 if n == 1 else -proj[0, 0] * baseline_m
            bound(f"camera_info_{cid}_Tx_vs_baseline_m", abs(proj[0, 3] - want_tx), 1e-9)
        else:
            bound(f"camera_info_{cid}_R", np.abs(rect - np.eye(3)).max(), 0.0)
            bound(f"camera_info_{cid}_P", np.abs(proj - np.hstack([k, np.zeros((3, 1))])).max(), 0.0)


def scan_beams(path):
    """A pingcal-scan CSV (v1 or v2) as crates/lrf/src/scan.rs reads it: per valid beam
    (range >= 20 mm, in file order) its servo angle (deg; v2: linear over the scan's beams
    from servo_deg to servo_end_deg), beam angle alpha (deg) and reported range (mm)."""
    keys, servo, alpha, rng = {}, [], [], []
    sweep = None
    for line in Path(path).read_text(encoding="utf-8-sig").splitlines():
        t = line.strip()
        if not t:
            continue
        if t.startswith("#"):
            rest = t[1:].strip()
            if rest.startswith("pingcal-scan"):
                sweep = rest.split()[1] == "v2"
            elif "=" in rest:
                a, b = rest.split("=", 1)
                keys[a.strip()] = b.strip()
            continue
        if t.startswith("stamp_s"):
            continue
        f = [v for v in t.split(",") if v.strip() != ""]
        first = float(f[1])
        last = float(f[2]) if sweep else first
        ranges = np.array([float(v) for v in f[3 if sweep else 2 :]]) * {"mm": 1.0, "cm": 10.0, "m": 1000.0}[keys.get("range_unit", "mm")]
        i = np.arange(len(ranges))
        ok = ranges >= 20.0
        at = first + (last - first) * i / max(len(ranges) - 1, 1) if last != first else np.full(len(ranges), first)
        servo.append(at[ok])
        alpha.append(float(keys["angle_min_deg"]) + i[ok] * float(keys["angle_increment_deg"]))
        rng.append(ranges[ok])
    return np.concatenate(servo), np.concatenate(alpha), np.concatenate(rng)


def ply_vertices(path):
    """cloud.ply's vertex element (binary little-endian, float x y z then uchar r g b), mm."""
    data = Path(path).read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    head = data[:end].decode().splitlines()
    assert "format binary_little_endian 1.0" in head, head[:3]
    n = int(next(h for h in head if h.startswith("element vertex")).split()[2])
    props = []
    for h in head[head.index(f"element vertex {n}") + 1 :]:
        if not h.startswith("property"):
            break
        props.append(h.split()[2])
    assert props == ["x", "y", "z", "red", "green", "blue"], props
    rec = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "u1", 3)])
    v = np.frombuffer(data, dtype=rec, count=n, offset=end)
    return np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float64)


def urdf_comment_number(text, key):
    m = re.search(rf"{key} = (-?[0-9.]+(?:e-?[0-9]+)?) mm" if key == "range_offset" else rf"{key} = (-?[0-9.]+(?:e-?[0-9]+)?):", text)
    assert m, f"lrf_model.urdf states no {key}"
    return float(m.group(1))


def check_lrf_model(d, project):
    """ros/lrf_model.urdf loaded with yourdfpy (which applies its mimic joint): the servo
    joint set to each scan line's servo reading (rad), the scanner -> LRF frame transform of
    its forward kinematics applied to every valid beam at the range its comment corrects,
    against cloud.ply's vertices (the same beams in the same order) within 0.01 mm."""
    import tomllib

    import yourdfpy

    r = results(d)
    lrf = r["conventions"]["tf_lrf_frame"]
    text = (d / "ros" / "lrf_model.urdf").read_text()
    robot = yourdfpy.URDF.load(str(d / "ros" / "lrf_model.urdf"), load_meshes=False, build_collision_scene_graph=False)
    assert robot.actuated_joint_names == [f"{lrf}_servo"], robot.actuated_joint_names
    assert robot.base_link == r["conventions"]["tf_camera_frame"], robot.base_link
    ro, rs = urdf_comment_number(text, "range_offset"), urdf_comment_number(text, "range_scale")
    m = r["lrf_model"]
    bound("urdf_range_correction_vs_lrf_model", max(abs(ro - m["range_offset_mm"]), abs(rs - m["range_scale"])), 0.0)
    proj = Path(project)
    scans = tomllib.loads(proj.read_text())["lrf"]["scans"]
    beams = [scan_beams(proj.parent / s) for s in scans]
    servo, alpha, reported = (np.concatenate(x) for x in zip(*beams))
    cloud = ply_vertices(d / "cloud.ply")
    assert len(cloud) == len(servo), (len(cloud), len(servo))
    true_range = (reported - ro) / (1.0 + rs)
    local = np.stack([true_range * np.cos(np.radians(alpha)), true_range * np.sin(np.radians(alpha)), np.zeros_like(alpha)], axis=1)
    angles, inverse = np.unique(servo, return_inverse=True)
    tfs = np.empty((len(angles), 4, 4))
    for k, a in enumerate(angles):
        robot.update_cfg({f"{lrf}_servo": float(np.radians(a))})
        tfs[k] = robot.get_transform(frame_to=f"{lrf}_scanner", frame_from=lrf)
    got = np.einsum("nij,nj->ni", tfs[inverse, :3, :3], local) + tfs[inverse, :3, 3] * 1000.0
    bound(f"urdf_vs_cloud_ply_mm[{m['source']}]", np.linalg.norm(got - cloud, axis=1).max(), 0.01)
    figures.append(f"beams={len(cloud)} servo_angles={len(angles)}")
    off = np.array(m["offset_mm"])
    figures.append(f"mount_offset_mm={np.round(off, 3).tolist()} tilts_deg=({m['tilt_x_deg']:.4g},{m['tilt_z_deg']:.4g}) "
                   f"servo_zero_deg={m['servo_zero_deg']:.4g} servo_scale={m['servo_scale']:.3g} range_offset_mm={ro:.4g} range_scale={rs:.3g}")


def main():
    check, d = sys.argv[1], Path(sys.argv[2])
    checks = {
        "opencv": lambda: check_opencv(d, sys.argv[3]),
        "stereo": lambda: check_stereo(d),
        "transforms": lambda: check_transforms(d),
        "ros": lambda: check_ros(d),
        "urdf": lambda: check_urdf(d),
        "head": lambda: check_head(d),
        "chain": lambda: check_chain(d),
        "kalibr": lambda: check_kalibr(d, sys.argv[3]),
        "camera_info": lambda: check_camera_info(d, sys.argv[3]),
        "lrf_model": lambda: check_lrf_model(d, sys.argv[3]),
    }
    checks[check]()
    print(f"{check}: " + " ".join(figures))
    if failures:
        print(f"{check} FAILED: " + "; ".join(failures))
        sys.exit(1)


if __name__ == "__main__":
    main()
