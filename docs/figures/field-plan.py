#!/usr/bin/env python3
"""Draws docs/figures/field-plan.svg from a simulated project's truth.json (seed 3):
the room corner seen from above, the targets on the floor (wall targets at the walls' foot),
the balls, and each station's left camera with its viewing direction.

    pingcal simulate --out /tmp/field --seed 3
    python3 docs/figures/field-plan.py /tmp/field/truth.json docs/figures/field-plan.svg
"""
import json
import sys

truth = json.load(open(sys.argv[1]))
S, M = 0.2, 40.0  # px per mm, margin px
W = 2500 * S + 2 * M


def xy(p):  # world mm -> svg px (x right, world y up the page)
    return M + p[0] * S, W - M - p[1] * S


out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W:.0f}" height="{W + 45:.0f}" '
       f'font-family="Helvetica, Arial, sans-serif" font-size="11">',
       f'<rect width="100%" height="100%" fill="white"/>']
x0, y0 = xy((0, 0))
x1, y1 = xy((2500, 2500))
out.append(f'<rect x="{x0}" y="{y1}" width="{x1 - x0}" height="{y0 - y1}" fill="#f4f1ea" stroke="#bbb"/>')
out.append(f'<line x1="{x0}" y1="{y0}" x2="{x1}" y2="{y0}" stroke="black" stroke-width="4"/>')
out.append(f'<line x1="{x0}" y1="{y0}" x2="{x0}" y2="{y1}" stroke="black" stroke-width="4"/>')
out.append(f'<text x="{(x0 + x1) / 2}" y="{y0 + 16}" text-anchor="middle">wall 1 (targets up to 2 m high)</text>')
out.append(f'<text x="{x0 - 8}" y="{(y0 + y1) / 2}" text-anchor="middle" '
           f'transform="rotate(-90 {x0 - 8} {(y0 + y1) / 2})">wall 2</text>')
for t in truth["targets"]:
    px, py = xy(t["world_mm"])
    if t["surface"] == "floor":
        fill = "#c0392b" if t["kind"] == "coded" else "#555"
        out.append(f'<circle cx="{px:.1f}" cy="{py:.1f}" r="{4 if t["kind"] == "coded" else 2.5}" fill="{fill}"/>')
    else:
        out.append(f'<circle cx="{px:.1f}" cy="{py:.1f}" r="2" fill="#999"/>')
for b in truth["balls"]:
    px, py = xy(b["world_mm"])
    out.append(f'<circle cx="{px:.1f}" cy="{py:.1f}" r="5" fill="white" stroke="#2471a3" stroke-width="2"/>')
    out.append(f'<text x="{px + 6:.1f}" y="{py - 4:.1f}" fill="#2471a3" font-size="9">{b["id"]}{" (check)" if b["check"] else ""}</text>')
for im in truth["images"]:
    if im["camera"] != "left":
        continue
    pose = im.get("camera_from_world") or im["world_to_camera"]  # the old key, before
    r = pose["rotation"]
    t = pose["translation_mm"]
    c = [-sum(r[k][i] * t[k] for k in range(3)) for i in range(3)]  # centre = -R^T t
    fwd = r[1]  # the camera's Y (optical axis) in the world
    px, py = xy(c)
    qx, qy = xy((c[0] + 300 * fwd[0], c[1] + 300 * fwd[1]))
    main = im["station"] == "S00"
    col = "#117a65" if main else "#7d3c98"
    out.append(f'<line x1="{px:.1f}" y1="{py:.1f}" x2="{qx:.1f}" y2="{qy:.1f}" stroke="{col}" stroke-width="2"/>')
    out.append(f'<rect x="{px - 5:.1f}" y="{py - 5:.1f}" width="10" height="10" fill="{col}"/>')
    out.append(f'<text x="{px + 8:.1f}" y="{py + 12:.1f}" fill="{col}">{im["station"]}, {c[2] / 1000:.2f} m{" (main: the LRF scans here)" if main else ""}</text>')
out.append(f'<text x="{M}" y="{W + 14:.0f}">Seen from above, the floor 2.5 × 2.5 m. Red: coded floor targets; grey: plain and wall targets;</text>')
out.append(f'<text x="{M}" y="{W + 30:.0f}">blue rings: balls on stems; squares: camera stations (left camera), their height and viewing direction.</text>')
out.append("</svg>")
open(sys.argv[2], "w").write("\n".join(out) + "\n")
