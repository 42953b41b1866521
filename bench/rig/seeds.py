"""A head of three cameras and a rotating 2D LRF over seeds (issue 52), each sensor's
camera_from_sensor against the simulator's truth, and the same data calibrated a pair at a
time (the left camera with one other sensor: the right camera alone as today's stereo
head, the side camera alone, the LRF with the left camera alone) beside the joint result.

    python3 bench/rig/seeds.py [--seeds 1-10] [--config bench/rig/side-camera.toml]
                               [--binary target/release/pingcal] [--work DIR]

Per seed and sensor: |Δt| (mm), ΔR (°), each component's error over its σ (and for two
range sensors their pair's t against the truth's composition); per sensor the worst of those
and the RMS of error/σ; then per sensor the joint σ's beside the pair-alone
σ's (their ratio, ≤ 1 where the joint adjustment is no worse) and the true errors of both.
Not in CI.
"""
import argparse, json, math, os, re, sys, tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from seeds_common import rot_err_deg, simulate_and_calibrate  # noqa: E402
import subprocess  # noqa: E402


def seeds_of(text):
    a, _, b = text.partition("-")
    return range(int(a), int(b or a) + 1)


def blocks(toml):
    """The project file cut into its tables: (header, text) in order."""
    out = []
    for p in re.split(r"(?m)^(?=\[)", toml):
        head = p.split("\n", 1)[0].strip()
        if head.startswith("[cameras.") and out:  # a sub-table of the [[cameras]] before it
            out[-1] = (out[-1][0], out[-1][1] + p)
        else:
            out.append((head, p))
    return out


def without(toml, cameras, stereo=False, rig=False):
    """The project without the images (and [[cameras]] entries) of `cameras`, without
    [stereo] (stereo=True) and without [[rig.cameras]] (rig=True)."""
    out = []
    for head, text in blocks(toml):
        if stereo and head == "[stereo]":
            continue
        if rig and head == "[[rig.cameras]]":
            continue
        if head in ("[[images]]", "[[cameras]]") and any(
                re.search(rf'(?m)^(camera|id) = "{c}"$', text) for c in cameras):
            continue
        out.append(text)
    return "".join(out)


def calibrate(binary, toml_text, project_dir, out):
    path = os.path.join(project_dir, os.path.basename(out) + ".toml")
    with open(path, "w") as f:
        f.write(toml_text)
    r = subprocess.run([binary, "calibrate", path, "--out", out, "--quiet", "--accept-doubtful"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        return None
    return json.load(open(os.path.join(out, "results.json")))


def errors(results, truth):
    """Per sensor id: (|dt|, dR, z of t, z of opk, σ t, σ opk, dt, dopk)."""
    tr = {s["id"]: s["camera_from_sensor"] for s in truth["sensors"]}
    out = {}
    for s in results.get("sensors", []):
        e, t = s["camera_from_sensor"], tr[s["id"]]
        dt = [a - b for a, b in zip(e["translation_mm"], t["translation_mm"])]
        do = [a - b for a, b in zip(e["opk_deg"], t["opk_deg"])]
        st, so = e["sigma_translation_mm"], e["sigma_rotation_deg"]
        out[s["id"]] = (math.sqrt(sum(x * x for x in dt)), rot_err_deg(e["rotation"], t["rotation"]),
                        [d / s_ for d, s_ in zip(dt, st)], [d / s_ for d, s_ in zip(do, so)], st, so, dt, do)
    return out


def pair_errors(results, truth):
    """Per pair of range sensors (both not cameras): (a, b, z of t, |dt|, σ t) of a_from_b
    against the truth's composition."""
    tr = {s["id"]: s["camera_from_sensor"] for s in truth["sensors"]}
    kinds = {s["id"]: s["kind"] for s in results.get("sensors", [])}
    out = []
    for p in results.get("sensor_pairs", []):
        a, b = p["a"], p["b"]
        if kinds.get(a) == "camera" or kinds.get(b) == "camera" or a not in tr or b not in tr:
            continue
        ra, ta = tr[a]["rotation"], tr[a]["translation_mm"]
        tb = tr[b]["translation_mm"]
        d = [tb[k] - ta[k] for k in range(3)]
        t_true = [sum(ra[k][i] * d[k] for k in range(3)) for i in range(3)]
        e = p["a_from_b"]
        dt = [e["translation_mm"][i] - t_true[i] for i in range(3)]
        st = e["sigma_translation_mm"]
        z = [dt[i] / st[i] for i in range(3)] if st else None
        out.append((a, b, z, math.sqrt(sum(x * x for x in dt)), st))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="1-10")
    ap.add_argument("--config", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "side-camera.toml"))
    ap.add_argument("--binary", default="target/release/pingcal")
    ap.add_argument("--work", default=None)
    a = ap.parse_args()
    work = a.work or tempfile.mkdtemp(prefix="pingcal-rig-")
    joint_rows, alone_rows, pair_rows = {}, {}, {}
    print("seed  sensor  |dt| mm  dR deg   z(tx ty tz)            z(omega phi kappa)   verdict")
    for seed in seeds_of(a.seeds):
        p, o, r = simulate_and_calibrate(a.binary, work, seed, a.config)
        truth = json.load(open(os.path.join(p, "truth.json")))
        res = json.load(open(os.path.join(o, "results.json")))
        joint = errors(res, truth)
        for a_, b_, z, dtn, st in pair_errors(res, truth):
            zs = " ".join(f"{x:+.2f}" for x in z) if z else "no sigma"
            print(f"{seed:4d}  pair {a_} <- {b_}: |dt| {dtn:.3f} mm, z(t) {zs}")
            pair_rows.setdefault(f"{a_}<-{b_}", []).append((dtn, z))
        for sid, e in joint.items():
            joint_rows.setdefault(sid, []).append(e)
            z = " ".join(f"{x:+.2f}" for x in e[2]) + "   " + " ".join(f"{x:+.2f}" for x in e[3])
            print(f"{seed:4d}  {sid:6s}  {e[0]:7.3f}  {e[1]:6.4f}   {z}   {res['verdict']['status']}")
        toml = open(os.path.join(p, "project.toml")).read()
        alone = {
            "right": without(toml, ["side"], rig=True),
            "side": without(toml, ["right"], stereo=True),
            "lrf": without(toml, ["right", "side"], stereo=True, rig=True),
        }
        for sid, text in alone.items():
            out = calibrate(a.binary, text, p, os.path.join(work, f"o{seed}-{sid}-alone"))
            if out is None:
                print(f"{seed:4d}  {sid:6s}  alone: calibration failed")
                continue
            e = errors(out, truth).get(sid)
            if e:
                alone_rows.setdefault(sid, []).append(e)
    print()
    for name, rows in pair_rows.items():
        zs = [r[1] for r in rows if r[1]]
        rms = [math.sqrt(sum(z[k] ** 2 for z in zs) / len(zs)) for k in range(3)] if zs else []
        print(f"pair {name}: worst |dt| {max(r[0] for r in rows):.3f} mm, RMS error/sigma of t " + " ".join(f"{x:.2f}" for x in rms))
    print()
    print("sensor  worst |dt| mm  worst dR deg  RMS error/sigma (tx ty tz omega phi kappa)")
    for sid, rows in joint_rows.items():
        rms = [math.sqrt(sum(r[2 + k // 3][k % 3] ** 2 for r in rows) / len(rows)) for k in range(6)]
        print(f"{sid:6s}  {max(r[0] for r in rows):13.3f}  {max(r[1] for r in rows):12.4f}  " + " ".join(f"{x:.2f}" for x in rms))
    print()
    print("sensor  mean sigma t (mm), joint / alone           mean sigma opk (deg), joint / alone        RMS |dt| mm joint / alone   RMS dR deg joint / alone")
    for sid, rows in joint_rows.items():
        al = alone_rows.get(sid, [])
        if not al:
            continue
        mean = lambda rs, i, k: sum(r[i][k] for r in rs) / len(rs)  # noqa: E731
        st = " ".join(f"{mean(rows, 4, k):.4f}/{mean(al, 4, k):.4f}" for k in range(3))
        so = " ".join(f"{mean(rows, 5, k):.5f}/{mean(al, 5, k):.5f}" for k in range(3))
        rms_t = lambda rs: math.sqrt(sum(r[0] ** 2 for r in rs) / len(rs))  # noqa: E731
        rms_r = lambda rs: math.sqrt(sum(r[1] ** 2 for r in rs) / len(rs))  # noqa: E731
        print(f"{sid:6s}  {st}   {so}   {rms_t(rows):.3f} / {rms_t(al):.3f}   {rms_r(rows):.4f} / {rms_r(al):.4f}")
    print(f"\n(work folder {work})")


if __name__ == "__main__":
    main()
