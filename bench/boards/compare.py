"""pingcal's chessboard corners beside OpenCV's on the real sample photographs
(bench/boards/README.md). Reads pingcal's corners (JSON of crates/targets/examples/
board_corners) and the reference opencv-chessboard.json (bench/boards/opencv.py); prints
the Markdown tables of the README. Not in CI.

    target/bench-venv/bin/python bench/boards/compare.py PINGCAL_JSON [DATA_DIR]
"""
import json
import os
import sys

import cv2
import numpy as np

COLS, ROWS, SQUARE = 9, 6, 25.0
here = os.path.dirname(os.path.abspath(__file__))
ours = {r["image"]: r for r in json.load(open(sys.argv[1]))}
data = sys.argv[2] if len(sys.argv) > 2 else os.path.join(here, "../../../shared/data/opencv-chessboard")
ref = json.load(open(os.path.join(here, "opencv-chessboard.json")))
crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)

sets = {"SB (NORMALIZE+EXHAUSTIVE+ACCURACY)": {}, "SB (default flags)": {},
        "cornerSubPix 11x11 on SB": {}, "cornerSubPix 15x15 on SB": {}, "pingcal": {}}
for r in ref["images"]:
    name = r["image"]
    grey = cv2.imread(os.path.join(data, name), cv2.IMREAD_GRAYSCALE)
    if r["found"]:
        sb = np.array(r["corners"], np.float32)
        sets["SB (NORMALIZE+EXHAUSTIVE+ACCURACY)"][name] = sb
        for half, key in ((5, "cornerSubPix 11x11 on SB"), (7, "cornerSubPix 15x15 on SB")):
            sets[key][name] = cv2.cornerSubPix(grey, sb.reshape(-1, 1, 2).copy(), (half, half), (-1, -1), crit).reshape(-1, 2)
    ok, c = cv2.findChessboardCornersSB(grey, (COLS, ROWS))
    if ok:
        sets["SB (default flags)"][name] = c.reshape(-1, 2)
    if ours[name]["found"]:
        sets["pingcal"][name] = np.array(ours[name]["corners"])[:, :2]


def distance(a, b):
    common = sorted(set(a) & set(b))
    d = np.concatenate([np.linalg.norm(a[n] - b[n], axis=1) for n in common]) if common else np.array([np.nan])
    return len(common), np.sqrt(np.mean(d ** 2)), np.max(d)


def calibrate(corners, camera, flags, full=False):
    views = [v.astype(np.float32).reshape(-1, 1, 2) for n, v in sorted(corners.items()) if n.startswith(camera)]
    obj = np.zeros((COLS * ROWS, 3), np.float32)
    obj[:, :2] = np.mgrid[0:COLS, 0:ROWS].T.reshape(-1, 2) * SQUARE
    rms, k, dist, _, _ = cv2.calibrateCamera([obj] * len(views), views, (640, 480), np.eye(3), None, flags=flags)
    if full:
        return {"views": len(views), "rms_px": float(rms), "fx": float(k[0, 0]), "fy": float(k[1, 1]),
                "cx": float(k[0, 2]), "cy": float(k[1, 2]), "dist_k1_k2_p1_p2_k3": [float(x) for x in dist.ravel()[:5]]}
    return len(views), rms, k[0, 0], k[1, 1]


print(f"OpenCV {cv2.__version__}\n")
print("| corners | boards found (of 26) | RMS to SB (px) | max to SB (px) | RMS to cornerSubPix 15x15 (px) |")
print("|---|---|---|---|---|")
sb = sets["SB (NORMALIZE+EXHAUSTIVE+ACCURACY)"]
sub = sets["cornerSubPix 15x15 on SB"]
for key, s in sets.items():
    n, rms, mx = distance(s, sb)
    _, rms2, _ = distance(s, sub)
    print(f"| {key} | {len(s)} | {rms:.3f} | {mx:.3f} | {rms2:.3f} |")
print()
print("cv2.calibrateCamera (k1 k2 p1 p2 k3) on each set of corners, only the images SB (ACCURACY) finds:")
print()
print("| corners | camera | views | fx | fy | RMS (px) |")
print("|---|---|---|---|---|---|")
for key in ("SB (NORMALIZE+EXHAUSTIVE+ACCURACY)", "cornerSubPix 15x15 on SB", "pingcal"):
    s = {n: v for n, v in sets[key].items() if n in sb}
    for cam in ("left", "right"):
        views, rms, fx, fy = calibrate(s, cam, 0)
        print(f"| {key} | {cam} | {views} | {fx:.2f} | {fy:.2f} | {rms:.4f} |")
print()
print("pingcal's σ per corner (px, per coordinate): median %.3f" % np.median(
    np.concatenate([np.array(r["corners"])[:, 2] for r in ours.values() if r["found"]])))
print("pingcal's detection time per image (ms, 1 thread, this machine): median %.1f" % np.median([r["ms"] for r in ours.values()]))

# cv2.calibrateCamera on pingcal's corners (the images SB finds): OpenCV's adjustment of the
# same measurements as pingcal's, for the Rust test of the self-calibration.
on_ours = {n: v for n, v in sets["pingcal"].items() if n in sb}
doc = {"what": "cv2.calibrateCamera (flags 0) on pingcal's chessboard corners of the images "
               "findChessboardCornersSB finds; OpenCV's output, made by bench/boards/compare.py",
       "opencv": cv2.__version__,
       "calibrations": {cam: calibrate(on_ours, cam, 0, full=True) for cam in ("left", "right")}}
with open(os.path.join(here, "opencv-on-pingcal-corners.json"), "w") as f:
    json.dump(doc, f, indent=1)
    f.write("\n")
