#!/usr/bin/env python3
"""Benchmark: pingcal's bundle adjuster against Ceres (through pycolmap) on the same BAL files.

Run from the repository root:

    python3 bench/ba/run.py                       # all default sizes (~10-20 min on 2 cores)
    python3 bench/ba/run.py --sizes 50x5000       # one size
    python3 bench/ba/run.py --generator python    # test mode: BAL files from make_bal.py

For every size CxP it generates one synthetic BAL problem (`pingcal gen-bal`, or
bench/ba/make_bal.py when pingcal cannot yet, or when asked), then runs, each as its own
subprocess: `pingcal ba` with 1 and 2 threads and Ceres (ceres_bal.py) with DENSE_SCHUR and
SPARSE_SCHUR on 1 and 2 threads. Peak memory is the child's max RSS from os.wait4. It prints
one markdown table and writes it to bench/out/ba-table.md (with the raw JSON next to it).
"""
import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.abspath(os.path.join(HERE, "..", ".."))
VENV = os.path.join(REPO, "bench", ".venv-ba")
VPY = os.path.join(VENV, "bin", "python")
PINGCAL = os.path.join(REPO, "target", "release", "pingcal")
DEFAULT_SIZES = "50x5000,200x30000,600x60000,1500x120000"
TOL = 1e-10          # function, gradient and parameter tolerance on both sides
MAX_ITER = 100


def log(msg):
    print(msg, file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- processes

def run_child(cmd, threads, timeout, cwd=REPO):
    """Runs cmd; returns (exit code, stdout, stderr, wall s, peak RSS MiB) using os.wait4."""
    env = dict(os.environ)
    for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "RAYON_NUM_THREADS"):
        env[k] = str(threads)
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, stdout=out, stderr=err, cwd=cwd, env=env)
        deadline = t0 + timeout
        while True:
            pid, status, ru = os.wait4(p.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                p.kill()
                pid, status, ru = os.wait4(p.pid, 0)
                status = -9
                break
            time.sleep(0.02)
        wall = time.perf_counter() - t0
        p.returncode = 0  # reaped by wait4; keep Popen from waiting again
        code = os.waitstatus_to_exitcode(status) if status != -9 else -9
        out.seek(0)
        err.seek(0)
        return code, out.read().decode(errors="replace"), err.read().decode(errors="replace"), \
            wall, ru.ru_maxrss / 1024.0  # ru_maxrss is KiB on Linux


def last_line(text, limit=160):
    lines = [l for l in text.strip().splitlines() if l.strip()]
    return lines[-1][:limit] if lines else ""


# ----------------------------------------------------------------------------- setup

def ensure_venv():
    ok = os.path.exists(VPY) and subprocess.run(
        [VPY, "-c", "import pycolmap, numpy"], capture_output=True).returncode == 0
    if not ok:
        log("setting up the benchmark venv (bench/.venv-ba) ...")
        subprocess.run(["bash", os.path.join(HERE, "setup_venv.sh")], check=True)


BUILD_NOTE = ""


def build_pingcal(skip):
    global BUILD_NOTE
    if not skip:
        log("cargo build --release -p pingcal ...")
        env = dict(os.environ)
        env.pop("CARGO_TARGET_DIR", None)   # the default <repo>/target, where PINGCAL is
        r = subprocess.run(["cargo", "build", "--release", "-p", "pingcal"], cwd=REPO, env=env)
        if r.returncode != 0:
            log("warning: the release build of pingcal failed")
            if os.path.exists(PINGCAL):
                BUILD_NOTE = ("the release build FAILED: the binary is an older one, built " +
                              time.strftime("%Y-%m-%d %H:%M", time.localtime(os.path.getmtime(PINGCAL))))
    return os.path.exists(PINGCAL)


def pingcal_help(sub):
    try:
        r = subprocess.run([PINGCAL, sub, "--help"], capture_output=True, text=True, timeout=30)
        return r.stdout + r.stderr
    except (OSError, subprocess.TimeoutExpired):
        return ""


def parse_sizes(text):
    sizes = []
    for item in text.split(","):
        c, p = item.lower().split("x")
        sizes.append((int(c), int(p)))
    return sizes


def generate(c, p, a, use_pingcal):
    """Writes the BAL file of size c x p (reused when present); returns (path, generator)."""
    os.makedirs(a.data_dir, exist_ok=True)
    tag = f"c{c}-p{p}-k{a.obs_per_point}-n{a.noise_px:g}-s{a.seed}"
    if a.visibility != "banded":
        tag += f"-{a.visibility}"
    if use_pingcal:
        path = os.path.join(a.data_dir, f"pingcal-{tag}.bal")
        if not os.path.exists(path) or a.regen:
            cmd = [PINGCAL, "gen-bal", "--cameras", str(c), "--points", str(p),
                   "--obs-per-point", str(a.obs_per_point), "--noise-px", str(a.noise_px),
                   "--seed", str(a.seed), "--out", path + ".tmp"]
            if a.visibility != "banded":
                cmd += ["--visibility", a.visibility]
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode == 0 and os.path.exists(path + ".tmp"):
                os.replace(path + ".tmp", path)
                return path, "pingcal gen-bal"
            if a.visibility != "banded":
                raise SystemExit(f"pingcal gen-bal failed ({last_line(r.stderr)}); make_bal.py has no --visibility")
            log(f"pingcal gen-bal failed ({last_line(r.stderr)}); using make_bal.py")
        else:
            return path, "pingcal gen-bal"
    path = os.path.join(a.data_dir, f"makebal-{tag}.bal")
    if not os.path.exists(path) or a.regen:
        cmd = [VPY, os.path.join(HERE, "make_bal.py"), "--cameras", str(c), "--points", str(p),
               "--obs-per-point", str(a.obs_per_point), "--noise-px", str(a.noise_px),
               "--seed", str(a.seed), "--out", path + ".tmp"]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        os.replace(path + ".tmp", path)
    return path, "make_bal.py"


# ----------------------------------------------------------------------------- runs

def save_log(a, name, cmd, out, err):
    d = os.path.join(os.path.dirname(a.out), "ba-logs")
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name + ".log"), "w") as fh:
        fh.write("$ " + " ".join(map(shlex.quote, cmd)) + "\n" + out + ("\n--- stderr\n" + err if err else ""))


def run_pingcal(path, solver, threads, a, extra):
    with tempfile.TemporaryDirectory() as td:
        outj = os.path.join(td, "out.json")
        cmd = [PINGCAL, "ba", path, "--out", outj, "--threads", str(threads)]
        # "iterative/schur-jacobi/explicit": the solver, then its preconditioner and its
        # Schur product (implicit, explicit), each optional.
        name, *options = solver.split("/")
        if name != "auto":
            cmd += ["--solver", name]
        for o in options:
            cmd += ["--schur-product" if o in ("implicit", "explicit") else "--preconditioner", o]
        cmd += extra
        code, out, err, wall, rss = run_child(cmd, threads, a.timeout)
        save_log(a, f"{os.path.basename(path)}.pingcal-{solver.replace('/', '-')}-t{threads}", cmd, out, err)
        res = {"side": "pingcal", "solver": "pingcal " + solver,
               "threads": threads, "wall_s": wall,
               "peak_mib": rss, "exit": code, "cmd": " ".join(map(shlex.quote, cmd))}
        if code == 0 and os.path.exists(outj):
            with open(outj) as fh:
                res.update(json.load(fh))
            if "linear_solver" in res and solver == "auto":
                res["solver"] += f" → {res['linear_solver']}"
        else:
            res["error"] = last_line(err) or f"exit {code}"
        return res


def run_ceres(path, solver, threads, a):
    # "ITERATIVE_SCHUR/CLUSTER_JACOBI": the solver and its preconditioner.
    name, _, precond = solver.partition("/")
    cmd = [VPY, os.path.join(HERE, "ceres_bal.py"), path, "--solver", name,
           "--threads", str(threads), "--max-iterations", str(MAX_ITER)]
    if precond:
        cmd += ["--preconditioner", precond]
    if not a.check:
        cmd.append("--no-check")
    code, out, err, wall, rss = run_child(cmd, threads, a.timeout)
    save_log(a, f"{os.path.basename(path)}.ceres-{solver.replace('/', '-')}-t{threads}", cmd, out, err)
    res = {"side": "ceres", "solver": solver, "threads": threads, "wall_s": wall,
           "peak_mib": rss, "exit": code, "cmd": " ".join(map(shlex.quote, cmd))}
    try:
        res.update(json.loads(last_line(out, None)))
        res["solver"] = solver  # with its preconditioner, when one is named
    except ValueError:
        res["error"] = last_line(err) or f"exit {code}"
    return res


def best_of(runs):
    """Of repeated runs of one setting: the one with the smallest reported time."""
    good = [r for r in runs if "error" not in r]
    if not good:
        return runs[-1]
    return min(good, key=lambda r: r["time_s"])


# ----------------------------------------------------------------------------- table

def fmt_cost(x):
    return f"{x:.6e}" if x is not None else "–"


def make_table(results, meta):
    hdr = ["problem (cams/points/obs)", "solver", "threads", "initial cost", "final cost",
           "rel. cost diff vs Ceres best", "iterations", "solve s", "wall s", "peak MiB",
           "time ratio pingcal/Ceres-best"]
    lines = ["| " + " | ".join(hdr) + " |", "|" + "---|" * len(hdr)]
    verdicts = []
    for size in results:
        rows = size["rows"]
        nobs = size["observations"]
        prob = f"{size['cameras']}/{size['points']}/{nobs}"
        for t in sorted({r["threads"] for r in rows}):
            ceres_ok = [r for r in rows if r["side"] == "ceres" and r["threads"] == t
                        and "error" not in r and not r.get("skipped")]
            best = min(ceres_ok, key=lambda r: r["time_s"]) if ceres_ok else None
            for r in [r for r in rows if r["threads"] == t]:
                label = r["solver"] if r["side"] == "pingcal" else f"Ceres {r['solver']}"
                if best is not None and r is best:
                    label += " (best)"
                if "error" in r:
                    lines.append(f"| {prob} | {label} | {t} | – | – | – | – | – | "
                                 f"{r['wall_s']:.1f} | {r['peak_mib']:.0f} | {r['error']} |")
                    if r["side"] == "pingcal":
                        verdicts.append(f"{prob}, {t} thread(s), {r['solver']}: failed ({r['error']})")
                    continue
                if r.get("skipped"):
                    lines.append(f"| {prob} | {label} | {t} | – | – | – | – | – | – | – | {r['skipped']} |")
                    continue
                rel = ratio = "–"
                if best is not None:
                    d = (r["final_cost"] - best["final_cost"]) / best["final_cost"]
                    rel = f"{d:+.2e}"
                    ratio = f"{r['time_s'] / best['time_s']:.2f}"
                    if r["side"] == "pingcal":
                        ratio = f"**{ratio}**"
                        ok_cost = abs(d) < 1e-4
                        ok_time = r["time_s"] < best["time_s"]
                        verdicts.append(
                            f"{prob}, {t} thread(s), {r['solver']}: cost {'OK' if ok_cost else 'DIFFERS'} "
                            f"(|rel| {abs(d):.1e} {'<' if ok_cost else '>='} 1e-4), "
                            f"time {'OK' if ok_time else 'SLOWER'} ({r['time_s']:.2f} s vs "
                            f"Ceres {best['solver']} {best['time_s']:.2f} s)")
                lines.append(
                    f"| {prob} | {label} | {t} | {fmt_cost(r['initial_cost'])} | "
                    f"{fmt_cost(r['final_cost'])} | {rel} | {r['iterations']} | "
                    f"{r['time_s']:.2f} | {r['wall_s']:.2f} | {r['peak_mib']:.0f} | {ratio} |")
    text = "\n".join(lines) + "\n"
    notes = [
        "",
        f"Generated {meta['date']} on {meta['host']} ({meta['cpus']} CPUs, load before start "
        f"{meta['load']}). Command: `{meta['command']}`.",
        f"Problems: {meta['generator']}, {meta['obs_per_point']} observations per point, "
        f"noise σ = {meta['noise_px']} px, seed {meta['seed']}.",
        f"Ceres: pycolmap {meta.get('pycolmap', '?')} (C++ COLMAP reprojection cost, RADIAL camera per image, "
        "principal point fixed), LEVENBERG_MARQUARDT, function/gradient/parameter tolerance "
        f"{TOL:g}, max {MAX_ITER} iterations, squared loss, no gauge fixing.",
        f"pingcal: `pingcal ba FILE --out OUT.json --threads T{(' ' + meta['pingcal_extra']) if meta['pingcal_extra'] else ''}`"
        + (f" (binary `{meta['pingcal_bin']}`)" if meta.get("pingcal_bin") else "")
        + (f"; {meta['pingcal_build']}" if meta.get("pingcal_build") else "") + ".",
        "solve s = time reported by the solver (Ceres: Summary::total_time_in_seconds; pingcal: "
        "time_s of its JSON); wall s = the whole child process (reading the file, building the "
        "problem, Python start-up for Ceres); peak MiB = the child's max RSS (Ceres's includes "
        "the Python interpreter, numpy and pycolmap's copy of the scene). "
        "Ceres best = the fastest Ceres setting for that size and thread count; ratio = solve s / "
        "Ceres best's solve s. Iterations = LM steps taken, accepted or not (for Ceres: successful + unsuccessful steps − 1, "
        "since Ceres counts the initial evaluation as iteration 0).",
    ]
    if meta.get("repeat", 1) > 1:
        notes.append(f"Every setting ran {meta['repeat']} times; the run with the smallest solve time is shown.")
    notes += ["", "Files (numpy's own BAL cost of each file, and ½σ²(m − n), the final cost to expect "
              "for noise σ when the model fits: m residuals, n = 9C + 3P − 7):", ""]
    for size in results:
        if "numpy_initial_cost" in size:
            notes.append(f"- {size['cameras']}/{size['points']}/{size['observations']}: "
                         f"`{os.path.relpath(size['file'], REPO)}` ({size['generator']}), initial cost "
                         f"{size['numpy_initial_cost']:.6e}, expected final ≈ {size['expected_final_cost']:.6e}")
    if verdicts:
        notes += ["", "Goal (same final cost within 1e-4, pingcal faster than Ceres's best):", ""]
        notes += [f"- {v}" for v in verdicts]
    return text + "\n".join(notes) + "\n"


# ----------------------------------------------------------------------------- main

def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default=DEFAULT_SIZES, help=f"comma-separated CAMERASxPOINTS (default {DEFAULT_SIZES})")
    ap.add_argument("--obs-per-point", type=int, default=6)
    ap.add_argument("--noise-px", type=float, default=0.5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--solvers", default="DENSE_SCHUR,SPARSE_SCHUR,ITERATIVE_SCHUR,ITERATIVE_SCHUR/CLUSTER_JACOBI",
                    help="Ceres solvers; ITERATIVE_SCHUR takes SCHUR_JACOBI unless /PRECONDITIONER follows")
    ap.add_argument("--visibility", choices=["banded", "random"], default="banded",
                    help="which cameras see a point (pingcal gen-bal --visibility): neighbours along a "
                         "street, or any K of all cameras (a dense camera graph)")
    ap.add_argument("--pingcal-solvers", default="auto",
                    help="comma-separated values of `pingcal ba --solver` (auto, dense, sparse, "
                         "iterative), each optionally followed by /PRECONDITIONER and /PRODUCT "
                         "(iterative/schur-jacobi, iterative/cluster-jacobi/explicit, "
                         "iterative/implicit); auto passes no --solver")
    ap.add_argument("--dense-max-cameras", type=int, default=300,
                    help="skip DENSE_SCHUR (and a forced pingcal dense) above this many cameras: "
                         "the dense 9C x 9C Cholesky costs ~3 s per iteration at 600 cameras and "
                         "~40 s at 1500, never the fastest there (default 300)")
    ap.add_argument("--generator", choices=["auto", "pingcal", "python"], default="auto",
                    help="auto: pingcal gen-bal when it works, else make_bal.py; python: test mode")
    ap.add_argument("--no-pingcal", action="store_true", help="run the Ceres side only")
    ap.add_argument("--skip-build", action="store_true", help="do not run cargo build")
    ap.add_argument("--pingcal-bin", help="use this pingcal binary (no cargo build); default target/release/pingcal")
    ap.add_argument("--pingcal-args", default="", help="extra arguments for `pingcal ba`")
    ap.add_argument("--repeat", type=int, default=1, help="runs per setting; the fastest is kept")
    ap.add_argument("--timeout", type=float, default=900, help="seconds per run")
    ap.add_argument("--regen", action="store_true", help="regenerate BAL files even if present")
    ap.add_argument("--no-check", dest="check", action="store_false",
                    help="skip Ceres's numpy recomputation of the costs")
    ap.add_argument("--table-from", metavar="JSON",
                    help="only re-render the table from a ba-table.json of an earlier run")
    ap.add_argument("--data-dir", default=os.path.join(REPO, "bench", "data", "ba"))
    ap.add_argument("--out", default=os.path.join(REPO, "bench", "out", "ba-table.md"))
    a = ap.parse_args()

    global PINGCAL
    if a.table_from:
        with open(a.table_from) as fh:
            saved = json.load(fh)
        print(make_table(saved["results"], saved["meta"]))
        return 0
    t_start = time.time()
    if a.pingcal_bin:
        PINGCAL = os.path.abspath(a.pingcal_bin)
        a.skip_build = True
    load0 = " ".join(open("/proc/loadavg").read().split()[:3])
    ensure_venv()
    have_pingcal = False
    if not a.no_pingcal or a.generator == "pingcal":
        have_pingcal = build_pingcal(a.skip_build)
        if not have_pingcal:
            log("warning: target/release/pingcal is missing: Ceres side only")
    use_pingcal_gen = have_pingcal and a.generator in ("auto", "pingcal")
    run_pingcal_side = have_pingcal and not a.no_pingcal

    extra = shlex.split(a.pingcal_args)
    if run_pingcal_side:
        h = pingcal_help("ba")
        for flag, val in (("--function-tolerance", TOL), ("--gradient-tolerance", TOL),
                          ("--parameter-tolerance", TOL), ("--max-iterations", MAX_ITER)):
            if flag in h and flag not in extra:
                extra += [flag, f"{val:g}"]

    threads = [int(t) for t in a.threads.split(",")]
    solvers = [s.strip().upper() for s in a.solvers.split(",") if s.strip()]
    pyver = subprocess.run([VPY, "-c", "import pycolmap; print(pycolmap.__version__)"],
                           capture_output=True, text=True).stdout.strip()
    results = []
    generators = set()
    for c, p in parse_sizes(a.sizes):
        path, gen = generate(c, p, a, use_pingcal_gen)
        generators.add(gen)
        log(f"== {c} cameras, {p} points: {path} ({gen})")
        size = {"cameras": c, "points": p, "file": path, "generator": gen, "rows": []}
        chk = subprocess.run([VPY, os.path.join(HERE, "make_bal.py"), "--check", path,
                              "--noise-px", str(a.noise_px)], capture_output=True, text=True)
        if chk.returncode == 0:
            info = json.loads(last_line(chk.stdout, None))
            size.update(observations=info["observations"], numpy_initial_cost=info["cost"],
                        expected_final_cost=info["expected_final_cost_if_sigma"])
            size["points"] = info["points"]
        else:
            log(f"make_bal.py --check failed: {last_line(chk.stderr)}")
            size["observations"] = "?"
        for t in threads:
            for ps in (a.pingcal_solvers.split(",") if run_pingcal_side else []):
                ps = ps.strip().lower()
                if ps == "dense" and c > a.dense_max_cameras:
                    size["rows"].append({"side": "pingcal", "solver": "pingcal dense", "threads": t,
                                         "skipped": f"skipped: > {a.dense_max_cameras} cameras"})
                    continue
                r = best_of([run_pingcal(path, ps, t, a, extra) for _ in range(a.repeat)])
                size["rows"].append(r)
                log(f"   {r['solver']:24s} T={t}: " + (r.get("error") or
                    f"{r['final_cost']:.6e} in {r['iterations']} it, {r['time_s']:.2f} s, {r['peak_mib']:.0f} MiB, {r.get('termination', '')}"))
            for s in solvers:
                if s == "DENSE_SCHUR" and c > a.dense_max_cameras:
                    size["rows"].append({"side": "ceres", "solver": s, "threads": t,
                                         "skipped": f"skipped: > {a.dense_max_cameras} cameras"})
                    continue
                r = best_of([run_ceres(path, s, t, a) for _ in range(a.repeat)])
                size["rows"].append(r)
                log(f"   Ceres {s:18s} T={t}: " + (r.get("error") or
                    f"{r['final_cost']:.6e} in {r['iterations']} it, {r['time_s']:.2f} s, {r['peak_mib']:.0f} MiB"))
                if "check_initial_cost_numpy" in r:
                    d0 = abs(r["initial_cost"] - r["check_initial_cost_numpy"]) / r["check_initial_cost_numpy"]
                    d1 = abs(r["final_cost"] - r["check_final_cost_numpy"]) / r["check_final_cost_numpy"]
                    if d0 > 1e-9 or d1 > 1e-9:
                        log(f"   WARNING: Ceres cost differs from the numpy BAL cost: {d0:.1e} / {d1:.1e}")
        results.append(size)

    for size in results:       # skipped rows carry no numbers: give them the keys the table reads
        for r in size["rows"]:
            r.setdefault("wall_s", 0.0)
            r.setdefault("peak_mib", 0.0)
    meta = {"date": time.strftime("%Y-%m-%d %H:%M"), "host": os.uname().nodename,
            "cpus": os.cpu_count(), "load": load0,
            "command": "python3 bench/ba/run.py " + " ".join(map(shlex.quote, sys.argv[1:])),
            "generator": " and ".join(sorted(generators)), "obs_per_point": a.obs_per_point,
            "noise_px": a.noise_px, "seed": a.seed, "pycolmap": pyver,
            "pingcal_extra": " ".join(extra), "repeat": a.repeat,
            "pingcal_bin": os.path.relpath(PINGCAL, REPO) if run_pingcal_side else "",
            "pingcal_build": BUILD_NOTE}
    table = make_table(results, meta)
    print(table)
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, "w") as fh:
        fh.write(table)
    with open(os.path.splitext(a.out)[0] + ".json", "w") as fh:
        json.dump({"meta": meta, "results": results}, fh, indent=1)
    log(f"wrote {a.out} ({time.time() - t_start:.0f} s in all)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
