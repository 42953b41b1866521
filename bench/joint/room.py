#!/usr/bin/env python3
"""The mount from the room (issue 37): `pingcal lrf-mount` on simulated rooms, and the
joint adjustment's mount σ with and without the room's planes.

    python3 bench/joint/room.py [--seeds 1-10] [--bin target/release/pingcal] \
        [--work /tmp/joint-room] [--sims DIR] [--no-calibrate] [--json out.json]

For each seed: `pingcal simulate` of the paper's field (a room corner: two walls and the
floor) with the scanner off its servo axis by (10, 5, 20) mm, its scan plane tilted by 0.8°
and −0.6°, a range offset of 20 mm and no servo or range scale error; then

* `pingcal lrf-mount scans/*.csv --out mount.json`: each determined parameter's
  (estimate − truth)/σ, and whether it is within 3σ;
* unless `--no-calibrate`: `pingcal calibrate` as simulated (the room's planes in the joint
  adjustment) and with `[lrf] room_planes = false`: the σ of each estimated mount
  parameter of both.

Prints a row per seed and the tables: per parameter, in how many seeds lrf-mount's estimate
is within 3σ (the issue asks ≥ 9 of 10), its RMS z; and the joint adjustment's mean σ with
and without the planes. offset_y is the LRF frame's origin along the shaft (never
estimated); the truth's offset_y moves the frame, so it is left out of the comparison.
"""
import argparse, json, math, os, re, shutil, subprocess, sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import study  # noqa: E402

MOUNT = """[lrf]
mount_offset_mm = [10.0, 5.0, 20.0]
mount_tilt_x_deg = 0.8
mount_tilt_z_deg = -0.6
servo_scale = 0.0
range_offset_mm = 20.0
range_scale = 0.0
"""


def simulated(args, seed):
    """The simulation of `seed` (made once into --sims when given)."""
    import hashlib
    key = hashlib.sha256(MOUNT.encode()).hexdigest()[:16]
    base = args.sims or os.path.join(args.work, "sims")
    sim = os.path.join(base, f"{key}-{seed}")
    if not os.path.exists(os.path.join(sim, "truth.json")):
        os.makedirs(base, exist_ok=True)
        cfg = os.path.join(base, f"{key}.toml")
        open(cfg, "w").write(MOUNT)
        shutil.rmtree(sim, ignore_errors=True)
        subprocess.run([args.bin, "simulate", "--seed", str(seed), "--config", cfg, "--out", sim],
                       check=True, capture_output=True)
    return sim


def calibrate(args, sim, work, planes):
    shutil.rmtree(work, ignore_errors=True)
    shutil.copytree(sim, work)
    p = os.path.join(work, "project.toml")
    if not planes:
        text = open(p).read()
        text = re.sub(r"^\[lrf\]\n", "[lrf]\nroom_planes = false\n", text, count=1, flags=re.M)
        open(p, "w").write(text)
    out = os.path.join(work, "out")
    r = subprocess.run([args.bin, "calibrate", p, "--out", out, "--quiet"], capture_output=True, text=True)
    res = os.path.join(out, "results.json")
    if r.returncode not in (0, 3, 4) or not os.path.exists(res):
        return None
    return json.load(open(res))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="1-10")
    ap.add_argument("--bin", default="target/release/pingcal")
    ap.add_argument("--work", default="/tmp/joint-room")
    ap.add_argument("--sims")
    ap.add_argument("--no-calibrate", action="store_true")
    ap.add_argument("--json")
    args = ap.parse_args()
    rows = []
    for seed in study.seeds_of(args.seeds):
        sim = simulated(args, seed)
        truth = study.true_mount(json.load(open(os.path.join(sim, "truth.json"))))
        out = os.path.join(args.work, f"mount-{seed}.json")
        os.makedirs(args.work, exist_ok=True)
        subprocess.run([args.bin, "lrf-mount", *sorted(
            os.path.join(sim, "scans", f) for f in os.listdir(os.path.join(sim, "scans"))),
            "--out", out], check=True, capture_output=True)
        m = json.load(open(out))
        row = {"seed": seed, "lrf_mount": {}, "sigma0": m["sigma0"]}
        for p in m["parameters"]:
            if p["sigma"] is not None and p["name"] != "offset_y":
                z = (p["value"] - truth[p["name"]]) / p["sigma"]
                row["lrf_mount"][p["name"]] = [p["value"], p["sigma"], truth[p["name"]], z]
        if not args.no_calibrate:
            for planes in (True, False):
                r = calibrate(args, sim, os.path.join(args.work, f"cal-{seed}-{int(planes)}"), planes)
                key = "with_planes" if planes else "without_planes"
                row[key] = None if r is None else {
                    "verdict": r["verdict"]["status"],
                    "mount": {p["name"]: [p["value"], p["sigma"]] for p in r.get("lrf_mount") or []},
                }
        rows.append(row)
        zs = " ".join(f"{k}={v[3]:+.2f}" for k, v in row["lrf_mount"].items())
        print(f"seed {seed}: lrf-mount sigma0 {row['sigma0']:.3f} z: {zs}", flush=True)
    print("\nlrf-mount: (estimate − truth)/σ per parameter")
    print(f"{'parameter':<13} {'seeds':>5} {'within 3σ':>9} {'RMS z':>6} {'mean σ':>8}")
    for n in study.NAMES:
        v = [r["lrf_mount"][n] for r in rows if n in r["lrf_mount"]]
        if v:
            rms = math.sqrt(sum(x[3] ** 2 for x in v) / len(v))
            print(f"{n:<13} {len(v):>5} {sum(abs(x[3]) <= 3 for x in v):>9} {rms:>6.2f} {sum(x[1] for x in v) / len(v):>8.4f}")
    if not args.no_calibrate:
        print("\njoint adjustment: mean σ of each estimated mount parameter (units of results.json)")
        print(f"{'parameter':<13} {'with planes':>12} {'without':>12} {'ratio':>6}")
        for n in study.NAMES:
            w = [r["with_planes"]["mount"][n][1] for r in rows
                 if r.get("with_planes") and r["with_planes"]["mount"].get(n, [0, None])[1]]
            o = [r["without_planes"]["mount"][n][1] for r in rows
                 if r.get("without_planes") and r["without_planes"]["mount"].get(n, [0, None])[1]]
            if w or o:
                mw = sum(w) / len(w) if w else float("nan")
                mo = sum(o) / len(o) if o else float("nan")
                print(f"{n:<13} {mw:>12.4f} {mo:>12.4f} {mw / mo if o and w else float('nan'):>6.2f}  ({len(w)}/{len(o)} seeds estimated)")
        for key in ("with_planes", "without_planes"):
            vs = [r[key]["verdict"] for r in rows if r.get(key)]
            print(f"verdicts {key}: {dict((v, vs.count(v)) for v in sorted(set(vs)))}")
    if args.json:
        json.dump(rows, open(args.json, "w"), indent=1)


if __name__ == "__main__":
    main()
