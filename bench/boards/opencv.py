"""OpenCV's side of the board benchmark (bench/boards/README.md).

Runs cv2.findChessboardCornersSB on every image of ../shared/data/opencv-chessboard (9x6
inner corners, 25 mm squares) and cv2.calibrateCamera on each camera's images, and writes
opencv-chessboard.json: OpenCV's output only (corners in OpenCV's order, intrinsics, RMS),
which the Rust test crates/targets/tests/boards_real.rs reads as its reference. Not in CI.

    target/bench-venv/bin/python bench/boards/opencv.py [DATA_DIR] [OUT_JSON]
"""
import json
import os
import sys

import cv2
import numpy as np

COLS, ROWS, SQUARE_MM = 9, 6, 25.0


def detect(path):
    grey = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    found, corners = cv2.findChessboardCornersSB(grey, (COLS, ROWS), flags=flags)
    size = (grey.shape[1], grey.shape[0])
    return found, (corners.reshape(-1, 2) if found else None), size


def calibrate(views, size, flags):
    obj = np.zeros((COLS * ROWS, 3), np.float32)
    obj[:, :2] = np.mgrid[0:COLS, 0:ROWS].T.reshape(-1, 2) * SQUARE_MM
    objs = [obj for _ in views]
    imgs = [v.astype(np.float32).reshape(-1, 1, 2) for v in views]
    k0 = np.eye(3)
    rms, k, dist, _, _ = cv2.calibrateCamera(objs, imgs, size, k0, None, flags=flags)
    return {
        "flags": int(flags),
        "rms_px": float(rms),
        "fx": float(k[0, 0]), "fy": float(k[1, 1]), "cx": float(k[0, 2]), "cy": float(k[1, 2]),
        "dist_k1_k2_p1_p2_k3": [float(x) for x in dist.ravel()[:5]],
    }


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    data = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "../../../shared/data/opencv-chessboard")
    out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(here, "opencv-chessboard.json")
    names = sorted(n for n in os.listdir(data) if n.endswith(".jpg"))
    images, per_camera, size = [], {"left": [], "right": []}, None
    for name in names:
        found, corners, size = detect(os.path.join(data, name))
        images.append({
            "image": name, "found": bool(found),
            "corners": None if corners is None else [[round(float(x), 4), round(float(y), 4)] for x, y in corners],
        })
        if found:
            per_camera["left" if name.startswith("left") else "right"].append(corners)
        print(f"{name}: {'found' if found else 'NOT found'}", file=sys.stderr)
    calibrations = {}
    for cam, views in per_camera.items():
        calibrations[cam] = {
            "views": len(views),
            "fix_aspect_ratio": calibrate(views, size, cv2.CALIB_FIX_ASPECT_RATIO),
            "free": calibrate(views, size, 0),
        }
    doc = {
        "what": "cv2.findChessboardCornersSB (NORMALIZE_IMAGE|EXHAUSTIVE|ACCURACY) corners and "
                "cv2.calibrateCamera on them; OpenCV's output, made by bench/boards/opencv.py",
        "opencv": cv2.__version__,
        "board": {"inner_corners": [COLS, ROWS], "square_mm": SQUARE_MM},
        "order": "OpenCV's: row-major, 9 per row, as returned",
        "rms_definition": "sqrt(sum of squared residual norms / number of corners), cv2.calibrateCamera's",
        "images": images,
        "calibrations": calibrations,
    }
    # One line per image (its corners on it): a short file and a readable diff.
    text = json.dumps({k: v for k, v in doc.items() if k != "images"}, indent=1)
    rows = ",\n  ".join(json.dumps(i) for i in images)
    text = text[:-2] + ',\n "images": [\n  ' + rows + "\n ]\n}\n"
    json.loads(text)
    with open(out, "w") as f:
        f.write(text)
    for cam, c in calibrations.items():
        for k in ("fix_aspect_ratio", "free"):
            r = c[k]
            print(f"{cam} {k}: views {c['views']} fx {r['fx']:.3f} fy {r['fy']:.3f} cx {r['cx']:.3f} cy {r['cy']:.3f} rms {r['rms_px']:.4f}")


if __name__ == "__main__":
    main()
