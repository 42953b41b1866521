#!/usr/bin/env python3
"""Camera models end to end: the simulated field through each lens model, several seeds.

For each model and seed: `pingcal simulate --camera-model M --seed S`, `pingcal calibrate`,
then against `truth.json` (the extrinsic as a calibration defines it, see
`true_translation`): the verdict, the check balls' mean error, the extrinsic's
translation error and its largest |error/σ| per axis, and the largest |error/σ| of the
left camera's intrinsics (the parameters the project frees). A model the pipeline handles
gives verdict ok, check errors like the photogrammetric lens's, and z-scores of a few at most.

    python3 bench/cameras/study.py [--seeds 5] [--bin target/release/pingcal] [--work /tmp/cams]

Prints one row per run and a summary per model (markdown).
"""
import argparse
import json
import math
import os
import subprocess
import sys

MODELS = ["photogrammetric", "opencv", "kannala-brandt", "double-sphere"]


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    return p.returncode, p.stderr


def true_translation(t):
    """The true extrinsic's translation in the LRF frame a calibration defines (origin on
    the servo axis at the scan plane): the truth's frame moved along the servo axis (Y) by
    the mount's offset_y, which no calibration can tell from ty: t' = t + R·(0, offset_y, 0)
    (`pingcal_sim::Truth::extrinsic_as_calibrated`, what `pingcal plan` compares with)."""
    te = t["extrinsic"]
    oy = t["lrf_mount"]["offset_mm"][1]
    return [te["translation_mm"][k] + te["rotation"][k][1] * oy for k in range(3)]


def one(binary, work, model, seed):
    d = os.path.join(work, f"{model}-{seed}")
    if not os.path.isfile(os.path.join(d, "truth.json")):
        args = [binary, "simulate", "--out", d, "--seed", str(seed)]
        if model != "photogrammetric":
            args += ["--camera-model", model]
        rc, err = run(args)
        if rc != 0:
            return {"model": model, "seed": seed, "error": err.strip().splitlines()[-1]}
    out = os.path.join(d, "study-out")
    rc, err = run([binary, "calibrate", os.path.join(d, "project.toml"), "--out", out,
                   "--quiet", "--accept-doubtful"])
    if rc != 0:
        return {"model": model, "seed": seed, "error": (err.strip().splitlines() or ["?"])[-1]}
    r = json.load(open(os.path.join(out, "results.json")))
    t = json.load(open(os.path.join(d, "truth.json")))
    e = r["extrinsic"]
    dt = [a - b for a, b in zip(e["translation_mm"], true_translation(t))]
    zt = max(abs(x) / s for x, s in zip(dt, e["sigma_translation_mm"]))
    cam, tcam = r["cameras"][0], t["cameras"][0]
    zi, worst = 0.0, ""
    # the photogrammetric model's σ's are keyed by the parameter names (c, xp, K1, ...),
    # its values by the file keys (c_mm, xp_mm, k1, ...)
    value_key = {"c": "c_mm", "xp": "xp_mm", "yp": "yp_mm"}
    for name, s in cam.get("sigma", {}).items():
        k = value_key.get(name, name if name in cam else name.lower())
        if k in tcam and k in cam and s > 0:
            z = abs(cam[k] - tcam[k]) / s
            if z > zi:
                zi, worst = z, k
    return {
        "model": model, "seed": seed, "verdict": r["verdict"]["status"],
        "check_mm": r["mean_check_error_mm"], "dt_mm": math.sqrt(sum(x * x for x in dt)),
        "z_t": zt, "z_intr": zi, "worst": worst,
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--bin", default="target/release/pingcal")
    ap.add_argument("--work", default="/tmp/pingcal-camera-study")
    ap.add_argument("--models", default=",".join(MODELS))
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    rows = []
    print("| model | seed | verdict | check mean, mm | extrinsic t error, mm | max z (t) | max z (intrinsics) |")
    print("|---|---|---|---|---|---|---|")
    for model in a.models.split(","):
        for seed in range(1, a.seeds + 1):
            r = one(a.bin, a.work, model, seed)
            rows.append(r)
            if "error" in r:
                print(f"| {model} | {seed} | error: {r['error']} | | | | |")
            else:
                print(f"| {model} | {seed} | {r['verdict']} | {r['check_mm']:.2f} | {r['dt_mm']:.2f} | "
                      f"{r['z_t']:.1f} | {r['z_intr']:.1f} ({r['worst']}) |")
            sys.stdout.flush()
    print()
    print("| model | ok | mean check, mm | mean t error, mm | median max z (intrinsics) |")
    print("|---|---|---|---|---|")
    for model in a.models.split(","):
        g = [r for r in rows if r["model"] == model and "error" not in r]
        if not g:
            print(f"| {model} | 0 | | | |")
            continue
        ok = sum(r["verdict"] == "ok" for r in g)
        zs = sorted(r["z_intr"] for r in g)
        print(f"| {model} | {ok}/{len([r for r in rows if r['model'] == model])} | "
              f"{sum(r['check_mm'] for r in g) / len(g):.2f} | {sum(r['dt_mm'] for r in g) / len(g):.2f} | "
              f"{zs[len(zs) // 2]:.1f} |")


if __name__ == "__main__":
    main()
