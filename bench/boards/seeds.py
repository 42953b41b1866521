#!/usr/bin/env python3
"""A chessboard and a fixed 2D LRF over seeds (issue 51): `pingcal simulate` with a board
field (`[field] kind = "board"`), then `pingcal calibrate`, and the extrinsic against
truth.json: |Δt|, ΔR, each translation and rotation component's error over its σ, the
placements whose scan has beams on the board, the board's scale, the verdict.

    python3 bench/boards/seeds.py [--bin target/release/pingcal] [--seeds 1-10]
        [--config FILE] [--work DIR]

Without --config the default board field (8 placements). Prints one row per seed and the
RMS of error/σ per component over the seeds (within 0.7–1.4 for 10 seeds is what a correct σ
gives, about ±0.3 from sampling alone). A component held (not determined) has no σ and is
left out of the RMS.
"""
import argparse, json, math, os, sys, tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from seeds_common import rot_err_deg, simulate_and_calibrate  # noqa: E402

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default="target/release/pingcal")
    ap.add_argument("--seeds", default="1-10")
    ap.add_argument("--config")
    ap.add_argument("--work")
    a = ap.parse_args()
    lo, hi = (int(x) for x in a.seeds.split("-"))
    work = a.work or tempfile.mkdtemp(prefix="boards-")
    os.makedirs(work, exist_ok=True)
    cfg = a.config
    if not cfg:
        cfg = os.path.join(work, "board.toml")
        open(cfg, "w").write('[field]\nkind = "board"\n')
    names = ["tx", "ty", "tz", "omega", "phi", "kappa"]
    zs = {k: [] for k in names}
    worst_t, worst_r, ok, all_cut = 0.0, 0.0, 0, 0
    print("seed  |dt| mm  dR deg   z(tx ty tz)            z(omega phi kappa)   beams in scans  scale     verdict")
    for s in range(lo, hi + 1):
        p, o, r = simulate_and_calibrate(a.bin, work, s, cfg)
        if not os.path.exists(os.path.join(o, "results.json")):
            print(f"{s:4d}  failed: {r.stderr.strip().splitlines()[-1] if r.stderr.strip() else r.returncode}")
            continue
        res = json.load(open(os.path.join(o, "results.json")))
        tru = json.load(open(os.path.join(p, "truth.json")))
        e, t = res["extrinsic"], tru["extrinsic"]
        dt = [e["translation_mm"][k] - t["translation_mm"][k] for k in range(3)]
        dr = rot_err_deg(e["rotation"], t["rotation"])
        st, sr = e["sigma_translation_mm"], e["sigma_rotation_deg"]
        z = [dt[k] / st[k] if st[k] > 0 else float("nan") for k in range(3)]
        z += [(e["opk_deg"][k] - t["opk_deg"][k]) / sr[k] if sr[k] > 0 else float("nan")
              for k in range(3)]
        for k, n in enumerate(names):
            if not math.isnan(z[k]):
                zs[n].append(z[k])
        st_rows = [x for x in res["stations"] if x.get("used")]
        cut = sum(1 for x in st_rows if x.get("board_beams", 0) > 0)
        all_cut += cut == len(tru.get("placements", st_rows))
        v = res["verdict"]["status"]
        ok += v == "ok"
        nt = math.sqrt(sum(x * x for x in dt))
        worst_t, worst_r = max(worst_t, nt), max(worst_r, dr)
        scale = res.get("board_scale")
        print(f"{s:4d}  {nt:6.2f}  {dr:6.3f}   " + " ".join(f"{x:+5.2f}" for x in z[:3]) + "   "
              + " ".join(f"{x:+5.2f}" for x in z[3:]) + f"   {cut:2d} of {len(st_rows):2d}"
              + f"        {scale if scale is None else f'{scale:.4f}'}  {v}"
              + ("" if v == "ok" else f" ({'; '.join(res['verdict']['reasons'])[:200]})"))
    print(f"worst |dt| {worst_t:.2f} mm, worst dR {worst_r:.3f} deg, verdict ok {ok}, "
          f"seeds with the board's beams in every scan {all_cut}")
    print("RMS of error/sigma: " + ", ".join(
        f"{n} {math.sqrt(sum(z * z for z in v) / len(v)):.2f}" for n, v in zs.items() if v))

if __name__ == "__main__":
    main()
