"""Checks pingcal's outputs for other ecosystems with each ecosystem's own code.

    python check.py CHECK RESULTS_DIR [PROBE_JSON]

CHECK is one of opencv, stereo, transforms, ros, urdf, kalibr. RESULTS_DIR holds
results.json and ros/, opencv/, kalibr/ as `pingcal calibrate` wrote them; PROBE_JSON (for
opencv) holds 3D points in the LRF frame and pingcal's own projection of them. Every
expected value is rebuilt here from results.json's photogrammetric numbers (R, t, opk_deg)
and SPEC.md's axes, not from the converted blocks. Prints one line `CHECK: name=max_error
...` and exits 1 when a bound is exceeded.
"""

import json
import shlex
import sys
import types
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

# p_opencv = C p_photogrammetric = (X, -Z, Y) (SPEC.md)
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
        assert fs.getNode("camera_model").string() == "pinhole"
        assert size == (cam["width"], cam["height"]), (size, cam)
        rot, t = np.array(e["rotation"]), np.array(e["translation_mm"])
        if cam["id"] != r["conventions"]["main_camera"]:
            rr = np.array(rig["opencv"]["rotation"])
            rot, t = rr @ rot, rr @ t + np.array(rig["opencv"]["translation_mm"])
        rvec, _ = cv2.Rodrigues(rot)
        pts = np.array(cam["lrf_points_mm"], dtype=np.float64)
        uv, _ = cv2.projectPoints(pts, rvec, t, k, dist)
        err = np.abs(uv.reshape(-1, 2) - np.array(cam["pingcal_px"])).max()
        bound(f"projectPoints_{cam['id']}_px", err, 0.02)


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


def check_kalibr(d):
    """camchain.yaml read back with PyYAML: the intrinsics against results.json's OpenCV
    model, T_cn_cnm1 against the rig moved into OpenCV frames and metres here."""
    import yaml

    r = results(d)
    chain = yaml.safe_load((d / "kalibr" / "camchain.yaml").read_text())
    rig = r["bundle"]["rig"]
    ids = [rig["left"], rig["right"]] if rig else [r["conventions"]["main_camera"]]
    assert sorted(chain) == [f"cam{n}" for n in range(len(ids))], sorted(chain)
    for n, cid in enumerate(ids):
        cam = chain[f"cam{n}"]
        o = next(c["opencv"] for c in r["cameras"] if c["id"] == cid)
        assert cam["camera_model"] == "pinhole" and cam["distortion_model"] == "radtan"
        assert cam["resolution"] == [o["image_width"], o["image_height"]]
        assert all(isinstance(v, float) for v in cam["intrinsics"] + cam["distortion_coeffs"])
        want = [o["fx"], o["fy"], o["cx"], o["cy"]]
        bound(f"kalibr_cam{n}_intrinsics", np.abs(np.array(cam["intrinsics"]) - want).max(), 0.0)
        bound(f"kalibr_cam{n}_dist", np.abs(np.array(cam["distortion_coeffs"]) - o["dist"][:4]).max(), 0.0)
    if rig:
        t = np.array(chain["cam1"]["T_cn_cnm1"])
        want = np.eye(4)
        want[:3, :3] = C @ np.array(rig["rotation"]) @ C.T
        want[:3, 3] = C @ np.array(rig["translation_mm"]) / 1000.0
        bound("kalibr_T_cn_cnm1", np.abs(t - want).max(), 1e-12)


def main():
    check, d = sys.argv[1], Path(sys.argv[2])
    checks = {
        "opencv": lambda: check_opencv(d, sys.argv[3]),
        "stereo": lambda: check_stereo(d),
        "transforms": lambda: check_transforms(d),
        "ros": lambda: check_ros(d),
        "urdf": lambda: check_urdf(d),
        "kalibr": lambda: check_kalibr(d),
    }
    checks[check]()
    print(f"{check}: " + " ".join(figures))
    if failures:
        print(f"{check} FAILED: " + "; ".join(failures))
        sys.exit(1)


if __name__ == "__main__":
    main()
