"""Which corners are nearer the truth on the board's outer ring, SB's or pingcal's?
(bench/boards/README.md) The two detectors differ by 0.41 px RMS on the 30 corners of the
outer ring and by 0.18 px on the 24 inner ones. Neither is the truth, so each camera is
calibrated (cv2.calibrateCamera) from the inner corners alone, of one detector or the other,
and the outer ring predicted from that calibration and each view's pose: the detector whose
outer corners lie nearer the prediction is the nearer to a camera that never saw them.
Not in CI.

    target/bench-venv/bin/python bench/boards/edges.py PINGCAL_JSON
"""
import json
import os
import sys

import cv2
import numpy as np

COLS, ROWS, SQUARE = 9, 6, 25.0
here = os.path.dirname(os.path.abspath(__file__))
ref = json.load(open(os.path.join(here, "opencv-chessboard.json")))
sets = {
    "SB": {r["image"]: np.array(r["corners"], float) for r in ref["images"] if r["found"]},
    "pingcal": {r["image"]: np.array(r["corners"], float)[:, :2] for r in json.load(open(sys.argv[1])) if r["found"]},
}
board = np.array([[c * SQUARE, r * SQUARE, 0.0] for r in range(ROWS) for c in range(COLS)], np.float32)
inner = [i for i in range(COLS * ROWS) if 0 < i % COLS < COLS - 1 and 0 < i // COLS < ROWS - 1]
outer = [i for i in range(COLS * ROWS) if i not in inner]

print(f"OpenCV {cv2.__version__}\n")
print("| camera | calibrated on the inner corners of | views | RMS (px) | fx | fy | outer ring predicted: RMS to SB's (px) | to pingcal's (px) |")
print("|---|---|---|---|---|---|---|---|")
for camera in ("left", "right"):
    names = sorted(n for n in sets["SB"] if n.startswith(camera) and n in sets["pingcal"])
    for source in ("SB", "pingcal"):
        views = [sets[source][n][inner].astype(np.float32) for n in names]
        rms, k, dist, rvecs, tvecs = cv2.calibrateCamera([board[inner]] * len(views), views, (640, 480), None, None)
        to = {}
        for target in ("SB", "pingcal"):
            squared = []
            for n, r, t in zip(names, rvecs, tvecs):
                predicted, _ = cv2.projectPoints(board[outer], r, t, k, dist)
                squared.extend(((predicted.reshape(-1, 2) - sets[target][n][outer]) ** 2).sum(axis=1))
            to[target] = float(np.sqrt(np.mean(squared)))
        print(f"| {camera} | {source} | {len(names)} | {rms:.3f} | {k[0, 0]:.2f} | {k[1, 1]:.2f} | {to['SB']:.3f} | {to['pingcal']:.3f} |")
